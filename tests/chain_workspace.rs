//! The allocation-free `*_into` methods of `DynChain` with a `DynWorkspace`: identities of
//! the equations of motion (M·q̈ + h = τ, h at q̇ = 0 is gravity, Y·π = τ, Y_b·β = τ) and
//! agreement with the fixed-size chain, on the PUMA 560 with friction.

mod seeded_support;

use prrrp_core::nalgebra::SVector;
use prrrp_core::{BaseOptions, DynChain, FrictionModel, PrrrpError, SerialChain};

const N: usize = 6;

/// Seeded states from a small LCG (independent of the library's sampler).
fn states(seed: u64, count: usize) -> Vec<[[f64; N]; 3]> {
    let mut u = seeded_support::lcg(seed);
    let mut next = move || u() * 6.0 - 3.0;
    (0..count)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| next())))
        .collect()
}

fn close(a: &[f64], b: &[f64], rel: f64) {
    let scale = b.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= rel * scale, "entry {i}: {x} vs {y}");
    }
    assert_eq!(a.len(), b.len());
}

fn puma_with_friction() -> SerialChain<N> {
    let fp = [
        [4.9, 0.8, 0.1],
        [8.4, 1.2, -0.2],
        [4.0, 0.6, 0.05],
        [0.5, 0.2, 0.0],
        [0.5, 0.1, 0.01],
        [0.4, 0.1, -0.02],
    ];
    SerialChain::puma560()
        .with_friction(FrictionModel::all(), fp)
        .expect("valid friction")
}

#[test]
fn into_methods_satisfy_the_equations_of_motion() {
    let fixed = puma_with_friction();
    let chain: DynChain = fixed.to_dyn();
    let mut ws = chain.workspace();
    let p = chain.num_params();
    let pi = chain.parameters();
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    let beta = base.base_values(&pi).expect("length p");
    let b = base.count();
    for [q, qd, qdd] in states(11, 25) {
        let mut tau = [0.0; N];
        chain
            .inverse_dynamics_into(&mut ws, &q, &qd, &qdd, &mut tau)
            .unwrap();
        let sv = |x: &[f64; N]| SVector::<f64, N>::from_column_slice(x);
        close(
            &tau,
            fixed
                .inverse_dynamics(&sv(&q), &sv(&qd), &sv(&qdd))
                .as_slice(),
            0.0,
        );

        let mut m = vec![0.0; N * N];
        chain.mass_matrix_into(&mut ws, &q, &mut m).unwrap();
        close(&m, fixed.mass_matrix(&sv(&q)).as_slice(), 0.0);

        let mut h = [0.0; N];
        chain
            .nonlinear_effects_into(&mut ws, &q, &qd, &mut h)
            .unwrap();
        // τ = M·q̈ + h.
        let mqdd: Vec<f64> = (0..N)
            .map(|i| (0..N).map(|k| m[i * N + k] * qdd[k]).sum::<f64>() + h[i])
            .collect();
        close(&mqdd, &tau, 1e-12);

        // G = h at q̇ = 0 without the friction offsets (the only friction left at q̇ = 0).
        let mut g = [0.0; N];
        chain.gravity_torques_into(&mut ws, &q, &mut g).unwrap();
        let mut h0 = [0.0; N];
        chain
            .nonlinear_effects_into(&mut ws, &q, &[0.0; N], &mut h0)
            .unwrap();
        let offsets: Vec<f64> = (0..N).map(|j| h0[j] - g[j]).collect();
        let want: Vec<f64> = chain.friction_params().iter().map(|f| f[2]).collect();
        close(&offsets, &want, 1e-12);

        let mut back = [0.0; N];
        chain
            .forward_dynamics_into(&mut ws, &q, &qd, &tau, &mut back)
            .unwrap();
        close(&back, &qdd, 1e-8);

        let mut y = vec![0.0; N * p];
        chain
            .regressor_row_major_into(&mut ws, &q, &qd, &qdd, &mut y)
            .unwrap();
        let ypi: Vec<f64> = (0..N)
            .map(|i| (0..p).map(|j| y[i * p + j] * pi[j]).sum())
            .collect();
        close(&ypi, &tau, 1e-12);
        // Row-major here, column-major in `DynChain::regressor`.
        let yc = chain.regressor(&q, &qd, &qdd).unwrap();
        for i in 0..N {
            for j in 0..p {
                assert_eq!(y[i * p + j], yc[(i, j)]);
            }
        }

        let mut yb = vec![0.0; N * b];
        chain
            .base_regressor_row_major_into(&mut ws, &base, &q, &qd, &qdd, &mut yb)
            .unwrap();
        let yb_beta: Vec<f64> = (0..N)
            .map(|i| (0..b).map(|r| yb[i * b + r] * beta[r]).sum())
            .collect();
        close(&yb_beta, &tau, 1e-9);

        // The allocating forms agree.
        close(&chain.nonlinear_effects(&q, &qd).unwrap(), &h, 0.0);
        close(&chain.gravity_torques(&q).unwrap(), &g, 0.0);
    }
}

#[test]
fn wrong_sizes_are_typed_errors() {
    let chain = SerialChain::puma560().to_dyn();
    let other = SerialChain::paper().to_dyn();
    let mut ws = chain.workspace();
    let mut wrong_ws = other.workspace();
    let z = [0.0; N];
    let mut out = [0.0; N];
    assert!(matches!(
        chain.inverse_dynamics_into(&mut wrong_ws, &z, &z, &z, &mut out),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        chain.inverse_dynamics_into(&mut ws, &z[..5], &z, &z, &mut out),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let mut small = vec![0.0; 5];
    assert!(matches!(
        chain.mass_matrix_into(&mut ws, &z, &mut small),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        chain.regressor_row_major_into(&mut ws, &z, &z, &z, &mut small),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let base_other = other
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    assert!(matches!(
        chain.base_regressor_row_major_into(&mut ws, &base_other, &z, &z, &z, &mut small),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    // Massless links: M is singular.
    let massless = DynChain::from_joints(chain.joints().to_vec()).unwrap();
    let mut mws = massless.workspace();
    assert!(matches!(
        massless.forward_dynamics_into(&mut mws, &z, &z, &z, &mut out),
        Err(PrrrpError::NotPositiveDefinite { .. })
    ));
}
