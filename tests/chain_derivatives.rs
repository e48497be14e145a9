//! The exact derivatives of the forward dynamics of `DynChainBaseModel` (tangent-linear
//! Newton–Euler, `forward_derivatives_into`) against central finite differences of its own
//! forward dynamics, q̈(q, q̇, τ, β), on random states: the PUMA 560 (standard DH, link
//! frames off the joint axes) and the Panda-like 7R arm (modified DH), both with viscous,
//! smoothed-Coulomb and offset friction, and the PRRRP chain (prismatic joints).
//!
//! The finite differences use only the forward dynamics (mass matrix and bias by the
//! primal recursions), never the derivative kernel, and a Richardson extrapolation so that
//! their truncation error (O(h⁴)) stays far below the tolerance.

#[path = "dyn_support/mod.rs"]
mod dyn_support;

use dyn_support::{base_model, with_smoothed_friction};
use prrrp_core::nalgebra::{DMatrix, DVector, Dyn};
use prrrp_core::{
    DynBaseWorkspace, DynChain, DynChainBaseModel, ForwardDerivativesOf, LinearModel, SerialChain,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn with_friction(chain: DynChain) -> DynChain {
    let n = chain.dof();
    let params = (0..n)
        .map(|j| {
            [
                0.3 + 0.1 * j as f64,
                0.5,
                if j % 2 == 0 { 0.1 } else { -0.07 },
            ]
        })
        .collect();
    with_smoothed_friction(chain, 0.05, params)
}

/// Forward dynamics at x = [q, q̇] with one entry moved by `dx`.
fn qdd_at(
    m: &DynChainBaseModel,
    q: &DVector<f64>,
    qd: &DVector<f64>,
    tau: &DVector<f64>,
    beta: &DVector<f64>,
    (which, k, dx): (usize, usize, f64),
) -> DVector<f64> {
    let (mut q, mut qd, mut beta) = (q.clone(), qd.clone(), beta.clone());
    match which {
        0 => q[k] += dx,
        1 => qd[k] += dx,
        _ => beta[k] += dx,
    }
    let mut ws = m.workspace();
    let mut out = DVector::zeros(q.len());
    m.forward_dynamics_into(&mut ws, &q, &qd, tau, &beta, &mut out)
        .unwrap();
    out
}

/// Richardson-extrapolated central difference: (4·D(h/2) − D(h))/3, error O(h⁴).
fn central(f: impl Fn(f64) -> DVector<f64>, h: f64) -> DVector<f64> {
    let d = |h: f64| (f(h) - f(-h)) / (2.0 * h);
    (d(h / 2.0) * 4.0 - d(h)) / 3.0
}

/// n numbers drawn uniformly in [−`limit`, `limit`).
fn uniform(rng: &mut StdRng, n: usize, limit: f64) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.random_range(-limit..limit))
}

/// A random state: q and q̇ in [−2, 2), and τ or q̈ in [−5, 5) (drawn in that order).
fn random_state(rng: &mut StdRng, n: usize) -> [DVector<f64>; 3] {
    [2.0, 2.0, 5.0].map(|limit| uniform(rng, n, limit))
}

/// The base model of `chain` with its true β, a workspace and a derivative buffer.
fn setup(
    chain: &DynChain,
) -> (
    DynChainBaseModel,
    DVector<f64>,
    DynBaseWorkspace,
    ForwardDerivativesOf<Dyn, Dyn>,
) {
    let m = base_model(chain);
    let beta = m.chain_base_values().clone();
    let ws = m.workspace();
    let fd = ForwardDerivativesOf::<Dyn, Dyn>::zeros(Dyn(chain.dof()), Dyn(m.count()));
    (m, beta, ws, fd)
}

/// Parameters a little off `beta` (each within ±5 %; the EKF evaluates at estimates).
fn near(beta: &DVector<f64>, rng: &mut StdRng) -> DVector<f64> {
    beta.map(|v| v * rng.random_range(0.95..1.05))
}

fn check_chain(name: &str, chain: &DynChain, seed: u64) {
    let (m, beta_true, mut ws, mut fd) = setup(chain);
    let (n, b) = (chain.dof(), m.count());
    let mut rng = StdRng::seed_from_u64(seed);
    for trial in 0..8 {
        let [q, qd, tau] = random_state(&mut rng, n);
        let beta = near(&beta_true, &mut rng);
        m.forward_derivatives_into(&mut ws, &q, &qd, &tau, &beta, &mut fd)
            .unwrap();
        let qdd = qdd_at(&m, &q, &qd, &tau, &beta, (0, 0, 0.0));
        assert!(
            (&fd.qdd - &qdd).amax() <= 1e-12 * (1.0 + qdd.amax()),
            "{name} trial {trial}: q̈"
        );
        let blocks: [(&str, usize, &DMatrix<f64>, usize); 3] = [
            ("dq̈/dq", 0, &fd.dqdd_dq, n),
            ("dq̈/dq̇", 1, &fd.dqdd_dqd, n),
            ("dq̈/dβ", 2, &fd.dqdd_dlambda, b),
        ];
        for (what, which, got, cols) in blocks {
            let scale = got.amax().max(1.0);
            for k in 0..cols {
                let h = if which == 2 {
                    1e-3 * beta[k].abs().max(1e-4)
                } else {
                    1e-3
                };
                let want = central(|dx| qdd_at(&m, &q, &qd, &tau, &beta, (which, k, dx)), h);
                let err = (got.column(k) - &want).amax();
                assert!(
                    err <= 1e-7 * scale,
                    "{name} trial {trial}: {what} column {k}: error {err:e} (scale {scale:e})\n\
                     got {}\nwant {}",
                    got.column(k).transpose(),
                    want.transpose()
                );
            }
        }
    }
}

#[test]
fn puma_with_friction_matches_finite_differences() {
    check_chain(
        "PUMA 560",
        &with_friction(SerialChain::puma560().to_dyn()),
        1,
    );
}

#[test]
fn panda_with_friction_matches_finite_differences() {
    check_chain("Panda-like", &dyn_support::panda_like(), 2);
}

#[test]
fn prismatic_chain_matches_finite_differences() {
    check_chain(
        "PRRRP chain",
        &with_friction(SerialChain::paper().to_dyn()),
        3,
    );
}

/// An identity independent of finite differences: without friction, ∂q̈/∂q̇ vanishes at
/// q̇ = 0 (the velocity terms are quadratic in q̇), while ∂q̈/∂q does not (gravity).
#[test]
fn velocity_derivative_vanishes_at_rest_without_friction() {
    let chain = SerialChain::puma560().to_dyn();
    let (m, beta, mut ws, mut fd) = setup(&chain);
    let n = chain.dof();
    let q = DVector::from_fn(n, |i, _| 0.3 * i as f64 - 0.5);
    let qd = DVector::zeros(n);
    let tau = DVector::from_fn(n, |i, _| (i as f64).sin());
    m.forward_derivatives_into(&mut ws, &q, &qd, &tau, &beta, &mut fd)
        .unwrap();
    assert!(fd.dqdd_dqd.amax() <= 1e-12 * fd.dqdd_dq.amax());
    assert!(fd.dqdd_dq.amax() > 1e-3);
}

/// `forward_derivatives_at_into` (one mass matrix: q̈ at τ, the derivatives at q̈_lin)
/// against what it replaces, the inverse dynamics at q̈_lin, the derivatives at that
/// torque and the forward dynamics at τ, on random states where q̈_lin and M⁻¹·(τ − bias)
/// differ (so taking the derivatives at the wrong acceleration fails): the same values to
/// round-off.
#[test]
fn derivatives_at_an_acceleration_equal_the_three_calls() {
    for (name, chain, seed) in [
        (
            "PUMA 560",
            with_friction(SerialChain::puma560().to_dyn()),
            11,
        ),
        ("Panda-like", dyn_support::panda_like(), 12),
    ] {
        let (m, beta_true, mut ws, mut got) = setup(&chain);
        let n = chain.dof();
        let mut rng = StdRng::seed_from_u64(seed);
        let mut want = got.clone();
        let mut tau_lin = DVector::zeros(n);
        for trial in 0..8 {
            let [q, qd, qdd_lin] = random_state(&mut rng, n);
            let tau = uniform(&mut rng, n, 5.0);
            let beta = near(&beta_true, &mut rng);
            m.inverse_dynamics_into(&mut ws, &q, &qd, &qdd_lin, &beta, &mut tau_lin)
                .unwrap();
            m.forward_derivatives_into(&mut ws, &q, &qd, &tau_lin, &beta, &mut want)
                .unwrap();
            m.forward_dynamics_into(&mut ws, &q, &qd, &tau, &beta, &mut want.qdd)
                .unwrap();
            m.forward_derivatives_at_into(
                &mut ws,
                &q,
                &qd,
                &qdd_lin,
                &tau,
                &beta,
                &mut tau_lin,
                &mut got,
            )
            .unwrap();
            let pairs: [(&str, &DMatrix<f64>, &DMatrix<f64>); 3] = [
                ("dq̈/dq", &got.dqdd_dq, &want.dqdd_dq),
                ("dq̈/dq̇", &got.dqdd_dqd, &want.dqdd_dqd),
                ("dq̈/dβ", &got.dqdd_dlambda, &want.dqdd_dlambda),
            ];
            for (what, g, w) in pairs {
                let err = (g - w).amax();
                assert!(
                    err <= 1e-10 * w.amax().max(1.0),
                    "{name} trial {trial}: {what}: error {err:e}"
                );
            }
            assert_eq!(got.qdd, want.qdd, "{name} trial {trial}: q̈ at τ");
        }
    }
}
