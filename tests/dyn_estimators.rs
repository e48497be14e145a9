//! The estimators at run-time sizes: `DynChainBaseModel` (a `DynChain` seen through its
//! base parameters, N and B known only at run time) with `DynRls`, `DynAdaline`,
//! `DynHopfield`, `DynEkf` and least squares — the same code as the compile-time PRRRP
//! and `ChainBaseModel<N, B>` path, instantiated at `Dyn`.
//!
//! Two robots: the PUMA 560 (`SerialChain::puma560().to_dyn()`, 36 base parameters, the
//! closed-loop record of `chain_estimators.rs` on its excitation seed 6), and a Panda-like
//! 7R chain with viscous, smoothed-Coulomb and offset friction on every joint
//! (`dyn_support::panda_like`, exact τ = inverse dynamics). Truth: β = K·π of the
//! chains' standard parameters; data noise-free.
//!
//! "One implementation" is checked by running the `Dyn` and the `Const<N>` instantiation
//! on the same data: they must give the same estimates (to round-off of a few ulps; the
//! code paths are the same functions, only the buffer types differ).
mod chain_support;
mod dyn_support;

use std::sync::OnceLock;

use chain_support::{
    errors, puma_adaline_config, puma_base_model, puma_hopfield_config, puma_reference, simulate,
    smallest_nonzero, Run, SimConfig,
};
use dyn_support::{base_model, exact_record, panda_like, DynFourier, DynRecord};
use prrrp_core::nalgebra::{DMatrix, DVector, SVector};
use prrrp_core::{
    least_squares, Adaline, AdalineConfig, BaseOptions, BaseParameters, ChainBaseModel,
    Discretisation, DynAdaline, DynChainBaseModel, DynEkf, DynHopfield, DynRls, DynSample,
    DynSamples, DynScaledModel, Ekf, EkfConfig, Estimator, ForwardDerivativesOf, Hopfield,
    HopfieldConfig, LeastSquaresConfig, LinearModel, PrrrpError, Rls, RlsConfig, ScaledModel,
    SerialChain,
};

const B: usize = 36;
const DT: f64 = 0.01;
type Beta = SVector<f64, B>;

struct Fixture {
    chain: SerialChain<6>,
    model: ChainBaseModel<6, B>,
    dmodel: DynChainBaseModel,
    base: BaseParameters,
    run: Run<6>,
    rec: DynRecord,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let (chain, base, model) = puma_base_model::<B>();
        let dchain = chain.to_dyn();
        let dbase = dchain
            .base_parameters(&BaseOptions::default())
            .expect("analysis");
        assert_eq!(dbase.independent, base.independent);
        let dmodel = dchain.base_model(&dbase).expect("layout");
        // The excitation chosen in chain_estimators.rs (best cond of 8 seeds).
        let run = simulate(&chain, &puma_reference(6), &SimConfig::default());
        let r = &run.record;
        let rec = DynRecord::from_fixed(&r.q, &r.qd, &r.qdd, &r.tau);
        Fixture {
            chain,
            model,
            dmodel,
            base,
            run,
            rec,
        }
    })
}

fn truth() -> DVector<f64> {
    fixture().dmodel.chain_base_values().clone()
}

/// max |a − b| / max |b|.
fn rel_diff(a: &[f64], b: &[f64]) -> f64 {
    let scale = b
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

fn dvec<const D: usize>(v: &SVector<f64, D>) -> DVector<f64> {
    DVector::from_column_slice(v.as_slice())
}

/// The run-time model is the compile-time one: same regressor, inverse and forward
/// dynamics and derivatives at the PUMA's states, at the true β and at 1.2·β (the same
/// recursions on slices, so equal to a few ulps).
#[test]
fn dyn_base_model_equals_fixed_model() {
    let f = fixture();
    let m = &f.dmodel;
    let (n, b) = m.dims();
    assert_eq!((n.0, b.0), (6, B));
    let beta_s: Beta = f.model.chain_base_values();
    assert!(rel_diff(m.chain_base_values().as_slice(), beta_s.as_slice()) == 0.0);
    let mut ws = m.workspace();
    let mut phi = DMatrix::zeros(6, B);
    let mut tau = DVector::zeros(6);
    let mut qdd = DVector::zeros(6);
    let mut fd = ForwardDerivativesOf::zeros(n, b);
    let r = &f.run.record;
    let mut worst = 0.0f64;
    for k in (0..r.len()).step_by(97) {
        let (q, qd, a, t) = (&f.rec.q[k], &f.rec.qd[k], &f.rec.qdd[k], &f.rec.tau[k]);
        for scale in [1.0, 1.2] {
            let bs = beta_s * scale;
            let bd = dvec(&bs);
            // Run-time kernels into their buffers, the compile-time model on the same sample.
            m.regressor_into(&mut ws, q, qd, a, &mut phi).unwrap();
            m.inverse_dynamics_into(&mut ws, q, qd, a, &bd, &mut tau)
                .unwrap();
            m.forward_dynamics_into(&mut ws, q, qd, t, &bd, &mut qdd)
                .unwrap();
            m.forward_derivatives_into(&mut ws, q, qd, t, &bd, &mut fd)
                .unwrap();
            let (qs, qds, qdds, ts) = (&r.q[k], &r.qd[k], &r.qdd[k], &r.tau[k]);
            let fm = &f.model;
            let phi_s = prrrp_core::LinearDynamics::regressor(fm, qs, qds, qdds);
            let tau_s = prrrp_core::LinearDynamics::inverse_dynamics(fm, qs, qds, qdds, &bs);
            let qdd_s = prrrp_core::LinearDynamics::forward_dynamics(fm, qs, qds, ts, &bs).unwrap();
            let fd_s =
                prrrp_core::LinearDynamics::forward_derivatives(fm, qs, qds, ts, &bs).unwrap();
            for (got, want) in [
                (phi.as_slice(), phi_s.as_slice()),
                (tau.as_slice(), tau_s.as_slice()),
                (qdd.as_slice(), qdd_s.as_slice()),
                (fd.dqdd_dq.as_slice(), fd_s.dqdd_dq.as_slice()),
                (fd.dqdd_dqd.as_slice(), fd_s.dqdd_dqd.as_slice()),
                (fd.dqdd_dlambda.as_slice(), fd_s.dqdd_dlambda.as_slice()),
            ] {
                worst = worst.max(rel_diff(got, want));
            }
            // τ = Φ_b·β: the O(n) recursion on the equivalent chain is the regressor's.
            let lin = &phi * &bd;
            assert!(rel_diff(lin.as_slice(), tau.as_slice()) < 1e-12);
        }
    }
    println!("Dyn vs Const<6> base model: worst relative difference {worst:.1e}");
    assert!(worst <= 1e-14, "{worst}");
}

/// The Panda-like chain with friction: the base model reproduces the chain's inverse
/// dynamics at the true β (friction, smoothed Coulomb sign included), and the EKF's
/// derivatives agree with central differences of the run-time forward dynamics (steps
/// 1e-5 rad, 1e-5 rad/s and 1e-6·(1 + |β_j|); truncation and round-off of the outer
/// differences ≈ 1e-8 relative, so 1e-6 leaves margin; ∂q̈/∂β is exact in the model, ∂q̈/∂q
/// and ∂q̈/∂q̇ are central differences of Newton–Euler inside it, ≈ 1e-10).
#[test]
fn panda_like_base_model_dynamics_and_derivatives() {
    let chain = panda_like();
    let m = base_model(&chain);
    let beta = m.chain_base_values().clone();
    let (n, b) = m.dims();
    println!("Panda-like: {} joints, {} base parameters", n.0, b.0);
    assert_eq!(n.0, 7);
    let mut ws = m.workspace();
    let reference = DynFourier::seeded(3, 7, 1.0);
    let mut tau = DVector::zeros(7);
    let mut fd = ForwardDerivativesOf::zeros(n, b);
    let (mut plus, mut minus) = (DVector::zeros(7), DVector::zeros(7));
    for k in 0..5 {
        let [q, qd, qdd] = reference.eval(1.3 * k as f64);
        m.inverse_dynamics_into(&mut ws, &q, &qd, &qdd, &beta, &mut tau)
            .unwrap();
        let truth = chain
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .unwrap();
        assert!(rel_diff(tau.as_slice(), &truth) < 1e-12);
        m.forward_derivatives_into(&mut ws, &q, &qd, &tau, &beta, &mut fd)
            .unwrap();
        assert!(rel_diff(fd.qdd.as_slice(), qdd.as_slice()) < 1e-9);
        // Central differences in one argument of q̈(q, q̇, τ, β) at a time.
        let point = [&q, &qd, &beta];
        for (arg, want, what) in [
            (0, &fd.dqdd_dq, "∂q̈/∂q"),
            (1, &fd.dqdd_dqd, "∂q̈/∂q̇"),
            (2, &fd.dqdd_dlambda, "∂q̈/∂β"),
        ] {
            let mut num = DMatrix::zeros(7, want.ncols());
            for j in 0..want.ncols() {
                let h = if arg == 2 {
                    1e-6 * (1.0 + beta[j].abs())
                } else {
                    1e-5
                };
                for (step, out) in [(h, &mut plus), (-h, &mut minus)] {
                    let mut x = point.map(|v| v.clone());
                    x[arg][j] += step;
                    m.forward_dynamics_into(&mut ws, &x[0], &x[1], &tau, &x[2], out)
                        .unwrap();
                }
                num.set_column(j, &((&plus - &minus) / (2.0 * h)));
            }
            let d = rel_diff(want.as_slice(), num.as_slice());
            println!("sample {k}: {what} vs central differences: {d:.1e}");
            assert!(d < 1e-6, "{what}: {d}");
        }
    }
}

/// Least squares at run-time sizes on the noise-free PUMA record: every nonzero base
/// parameter to 1e-8 relative and the zero ones to 1e-8 of the smallest nonzero (cond(W_b)
/// ≈ 113 times round-off leaves ≈ 1e-13); the `Const<6>, Const<36>` solve of the same data
/// gives the same estimate.
#[test]
fn least_squares_dyn_recovers_puma_and_equals_fixed() {
    let f = fixture();
    let beta = truth();
    let cfg = LeastSquaresConfig::default();
    let ls = least_squares(&f.dmodel, &f.rec.samples(), &cfg).expect("full rank");
    let (rel, abs) = errors(ls.lambda.as_slice(), beta.as_slice());
    println!(
        "Dyn LS (PUMA): worst rel {rel:.2e}, abs on zero β {abs:.2e}, cond {:.1}",
        ls.cond
    );
    assert!(rel < 1e-8);
    assert!(abs < 1e-8 * smallest_nonzero(beta.as_slice()));
    let fixed = least_squares(&f.model, &f.run.record.samples(), &cfg).expect("full rank");
    let d = rel_diff(ls.lambda.as_slice(), fixed.lambda.as_slice());
    println!("Dyn vs Const LS: {d:.1e}");
    assert!(d <= 1e-14, "{d}");
    assert_eq!(ls.std_dev.len(), B);
    assert!((ls.cond / fixed.cond - 1.0).abs() < 1e-12);
}

/// Least squares on the Panda-like 7R chain with viscous, Coulomb (smoothed) and offset
/// friction: 2000 exact samples at 10 ms; every nonzero base parameter (friction ones
/// included) to 1e-8 relative.
#[test]
fn least_squares_dyn_recovers_panda_like_with_friction() {
    let chain = panda_like();
    let m = base_model(&chain);
    let beta = m.chain_base_values().clone();
    let rec = exact_record(&chain, &DynFourier::seeded(11, 7, 1.0), 2000, DT);
    let ls = least_squares(&m, &rec.samples(), &LeastSquaresConfig::default()).expect("rank");
    let (rel, abs) = errors(ls.lambda.as_slice(), beta.as_slice());
    println!(
        "Dyn LS (Panda-like, {} base parameters): worst rel {rel:.2e}, abs on zero β \
         {abs:.2e}, cond {:.1}",
        beta.len(),
        ls.cond
    );
    assert!(rel < 1e-8);
    assert!(abs < 1e-8 * smallest_nonzero(beta.as_slice()));
}

/// RLS, one pass from β₀ = 0: the same estimate at both sizes, and within the bound
/// ‖β‖/(δ·σmin²(W_b)) of the regularised batch solution (see chain_estimators.rs).
#[test]
fn rls_dyn_equals_fixed_and_meets_the_bound() {
    let f = fixture();
    let beta = truth();
    let cfg = RlsConfig::default();
    let mut d = DynRls::new(f.dmodel.clone(), DVector::zeros(B), cfg).unwrap();
    let est = d.run(&f.rec.samples()).unwrap();
    let mut s = Rls::new(f.model, Beta::zeros(), cfg).unwrap();
    let est_s = s.run(&f.run.record.samples()).unwrap();
    let diff = rel_diff(est.as_slice(), est_s.as_slice());
    let ls = least_squares(&f.dmodel, &f.rec.samples(), &LeastSquaresConfig::default()).unwrap();
    let smin = ls.singular_values[B - 1];
    let bound = beta.norm() / (cfg.initial_covariance * smin * smin);
    let worst = (&est - &beta).amax();
    println!("Dyn RLS: |error| {worst:.2e} ≤ {bound:.2e}; Dyn vs Const {diff:.1e}");
    assert!(diff <= 1e-14, "{diff}");
    assert!(worst <= bound);
}

/// Adaline (normalised, μ = 0.5) and the Hopfield network on the column-equilibrated
/// run-time model, with the settings and the 150 epochs of chain_estimators.rs, where the
/// compile-time path reaches 1e-3 relative on every nonzero base parameter (see the
/// reasoning there); the `Dyn` estimates equal the `Const` ones.
#[test]
fn adaline_and_hopfield_dyn_equal_fixed_and_converge() {
    let f = fixture();
    let beta = truth();
    let data = f.rec.samples();
    let sdata = f.run.record.samples();
    let dm = DynScaledModel::equilibrated(f.dmodel.clone(), &data).unwrap();
    let sm = ScaledModel::equilibrated(f.model, &sdata).unwrap();
    assert!(rel_diff(dm.scale().as_slice(), sm.scale().as_slice()) <= 1e-15);
    // The `Dyn` estimate γ̂ (scaled units) of `name` against the `Const` one, and β̂ = D·γ̂
    // against the truth.
    let check = |name: &str, gamma: &DVector<f64>, gamma_s: &Beta| {
        let est = dm.to_model(gamma);
        let diff = rel_diff(gamma.as_slice(), gamma_s.as_slice());
        let (rel, abs) = errors(est.as_slice(), beta.as_slice());
        println!("Dyn {name}: worst rel {rel:.2e}, abs {abs:.2e}; Dyn vs Const {diff:.1e}");
        assert!(diff <= 1e-12, "{name}: {diff}");
        assert!(rel < 1e-3, "{name}: {rel}");
        assert!(
            abs < 1e-3 * smallest_nonzero(beta.as_slice()),
            "{name}: {abs}"
        );
    };

    let cfg = puma_adaline_config();
    let mut ad = DynAdaline::new(dm.clone(), DVector::zeros(B), cfg).unwrap();
    ad.train(&data, 150).unwrap();
    let mut ad_s = Adaline::new(sm, Beta::zeros(), cfg).unwrap();
    ad_s.train(&sdata, 150).unwrap();
    check("Adaline", ad.estimate(), ad_s.estimate());

    let cfg = puma_hopfield_config(B, DT);
    let mut hn = DynHopfield::new(dm.clone(), DVector::zeros(B), cfg).unwrap();
    hn.train(&data, 150).unwrap();
    let mut hn_s = Hopfield::new(sm, Beta::zeros(), cfg).unwrap();
    hn_s.train(&sdata, 150).unwrap();
    assert_eq!(hn.substeps(), hn_s.substeps());
    check("Hopfield", hn.estimate(), hn_s.estimate());
}

/// The whitened model (λ = D·T·γ, `DynScaledModel::whitened`) on the PUMA's record: its
/// stacked regressor has orthogonal unit-RMS columns (ΓᵀΓ = rows·1, cond 1, where the
/// equilibrated one's cond is far above 1); it is the inner model at λ = D·T·γ (Φ_γ·γ =
/// inverse dynamics, forward dynamics inverts it, ∂q̈/∂γ against central differences);
/// and Adaline's delta rule on it reaches least squares in a few tens of epochs, where
/// the equilibrated model leaves it far away after as many.
#[test]
fn whitened_model_is_orthogonal_and_speeds_up_the_gradient_methods() {
    let f = fixture();
    let data = f.rec.samples();
    let wm = DynScaledModel::whitened(f.dmodel.clone(), &data).unwrap();
    let em = DynScaledModel::equilibrated(f.dmodel.clone(), &data).unwrap();
    assert!(wm.is_whitened());
    let gram = |m: &DynScaledModel<DynChainBaseModel>| {
        let mut ws = m.workspace();
        let mut phi = DMatrix::zeros(6, B);
        let mut g = DMatrix::<f64>::zeros(B, B);
        for s in data.iter() {
            m.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)
                .unwrap();
            g += phi.transpose() * &phi;
        }
        g / (6 * data.len()) as f64
    };
    let g = gram(&wm);
    assert!((&g - DMatrix::<f64>::identity(B, B)).amax() < 1e-9, "{}", g);
    let ev = gram(&em).symmetric_eigenvalues();
    let cond_equilibrated = (ev.max() / ev.min()).sqrt();
    assert!(cond_equilibrated > 10.0, "{cond_equilibrated}");

    let beta = truth();
    let gamma = wm.from_model(&beta);
    assert!((wm.to_model(&gamma) - &beta).amax() < 1e-10 * beta.amax());
    let mut ws = wm.workspace();
    let mut ws_in = f.dmodel.workspace();
    let mut phi = DMatrix::zeros(6, B);
    let (mut tau, mut tau_in, mut qdd) = (DVector::zeros(6), DVector::zeros(6), DVector::zeros(6));
    let mut d =
        ForwardDerivativesOf::zeros(prrrp_core::nalgebra::Dyn(6), prrrp_core::nalgebra::Dyn(B));
    for s in data.iter().step_by(97) {
        wm.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)
            .unwrap();
        wm.inverse_dynamics_into(&mut ws, s.q, s.qd, s.qdd, &gamma, &mut tau)
            .unwrap();
        f.dmodel
            .inverse_dynamics_into(&mut ws_in, s.q, s.qd, s.qdd, &beta, &mut tau_in)
            .unwrap();
        let scale = tau_in.amax().max(1.0);
        assert!((&phi * &gamma - &tau_in).amax() < 1e-9 * scale);
        assert!((&tau - &tau_in).amax() < 1e-9 * scale);
        wm.forward_dynamics_into(&mut ws, s.q, s.qd, &tau, &gamma, &mut qdd)
            .unwrap();
        assert!((&qdd - s.qdd).amax() < 1e-7 * s.qdd.amax().max(1.0));
        wm.forward_derivatives_into(&mut ws, s.q, s.qd, &tau, &gamma, &mut d)
            .unwrap();
        for j in [0, B / 2, B - 1] {
            // Whitened directions mix many parameters, so q̈ is strongly curved along
            // them: the central difference's O(h²) error is 1.5e-5 of the derivative
            // at this h, 10⁴ times more at 100·h, as O(h²) predicts.
            let h = 1e-8 * gamma.amax();
            let (mut gp, mut gm) = (gamma.clone(), gamma.clone());
            gp[j] += h;
            gm[j] -= h;
            let (mut ap, mut am) = (DVector::zeros(6), DVector::zeros(6));
            wm.forward_dynamics_into(&mut ws, s.q, s.qd, &tau, &gp, &mut ap)
                .unwrap();
            wm.forward_dynamics_into(&mut ws, s.q, s.qd, &tau, &gm, &mut am)
                .unwrap();
            let num = (ap - am) / (2.0 * h);
            let col = d.dqdd_dlambda.column(j);
            assert!(
                (&num - col).amax() < 1e-4 * num.amax().max(1e-6),
                "column {j}: {} vs {}",
                num.amax(),
                (&num - col).amax()
            );
        }
    }

    // The delta rule (μ = 0.5 per max row norm²) for 30 epochs on each model.
    let ls = least_squares(&f.dmodel, &data, &LeastSquaresConfig::default()).unwrap();
    let distance = |m: &DynScaledModel<DynChainBaseModel>| {
        let mut ws = m.workspace();
        let mut phi = DMatrix::zeros(6, B);
        let peak = data
            .iter()
            .map(|s| {
                m.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)
                    .unwrap();
                phi.row_iter().map(|r| r.norm_squared()).fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        let cfg = AdalineConfig {
            rule: prrrp_core::AdalineRule::Delta,
            learning_rate: 0.5 / peak,
            ..Default::default()
        };
        let mut ad = DynAdaline::new(m.clone(), DVector::zeros(B), cfg).unwrap();
        ad.train(&data, 30).unwrap();
        (m.to_model(ad.estimate()) - &ls.lambda).amax() / ls.lambda.amax()
    };
    let (dw, de) = (distance(&wm), distance(&em));
    println!("Adaline after 30 epochs: whitened {dw:.2e}, equilibrated {de:.2e} (relative to LS)");
    assert!(dw < 1e-3, "{dw}");
    assert!(de > 10.0 * dw, "{de} vs {dw}");
}

/// The PUMA under computed torque held over each 10 ms sample (the EKF's zero-order-hold
/// input model), integrated by RK4 at 1 ms with the run-time model at the true β.
fn zoh_record(m: &DynChainBaseModel, samples: usize) -> DynRecord {
    let beta = m.chain_base_values();
    let mut ws = m.workspace();
    let reference = puma_reference(6);
    let [q0, v0, _] = reference.eval(0.0);
    let (mut q, mut v) = (dvec(&q0), dvec(&v0));
    let (kp, kd) = (400.0, 40.0);
    let mut rec = DynRecord::default();
    let mut acc = DVector::zeros(6);
    let mut tau = DVector::zeros(6);
    for k in 0..samples {
        let [qr, vr, ar] = reference.eval(k as f64 * DT);
        let a = dvec(&ar) + (dvec(&qr) - &q) * kp + (dvec(&vr) - &v) * kd;
        m.inverse_dynamics_into(&mut ws, &q, &v, &a, beta, &mut tau)
            .unwrap();
        m.forward_dynamics_into(&mut ws, &q, &v, &tau, beta, &mut acc)
            .unwrap();
        rec.q.push(q.clone());
        rec.qd.push(v.clone());
        rec.qdd.push(acc.clone());
        rec.tau.push(tau.clone());
        let h = DT / 10.0;
        for _ in 0..10 {
            let mut f = |q: &DVector<f64>, v: &DVector<f64>| {
                let mut a = DVector::zeros(6);
                m.forward_dynamics_into(&mut ws, q, v, &tau, beta, &mut a)
                    .unwrap();
                (v.clone(), a)
            };
            let (k1q, k1v) = f(&q, &v);
            let (k2q, k2v) = f(&(&q + &k1q * (h / 2.0)), &(&v + &k1v * (h / 2.0)));
            let (k3q, k3v) = f(&(&q + &k2q * (h / 2.0)), &(&v + &k2v * (h / 2.0)));
            let (k4q, k4v) = f(&(&q + &k3q * h), &(&v + &k3v * h));
            q += (k1q + k2q * 2.0 + k3q * 2.0 + k4q) * (h / 6.0);
            v += (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (h / 6.0);
        }
    }
    rec
}

/// RMS over all joints and samples of the torque prediction error of `est`, relative to
/// the RMS torque.
fn prediction_error(m: &DynChainBaseModel, est: &DVector<f64>, rec: &DynRecord) -> f64 {
    let mut ws = m.workspace();
    let mut tau = DVector::zeros(6);
    let (mut se, mut st) = (0.0, 0.0);
    for k in 0..rec.len() {
        m.inverse_dynamics_into(&mut ws, &rec.q[k], &rec.qd[k], &rec.qdd[k], est, &mut tau)
            .unwrap();
        se += (&tau - &rec.tau[k]).norm_squared();
        st += rec.tau[k].norm_squared();
    }
    (se / st).sqrt()
}

/// The EKF (positions measured, second-order discretisation, 10 ms) from λ₀ = 1.2·β on
/// 1500 samples of the PUMA under held torques: the run-time and the compile-time filter
/// give the same estimate (to 1e-9 of ‖β‖∞: the same arithmetic, FMA in both), and it
/// moves towards the truth — the torque prediction error of the final estimate on the
/// record is at most half that of λ₀ (20 %), the filter's job being to remove the model
/// error it starts with.
#[test]
fn ekf_dyn_equals_fixed_and_moves_towards_truth() {
    let f = fixture();
    let beta = truth();
    let rec = zoh_record(&f.dmodel, 1500);
    let cfg = EkfConfig {
        dt: DT,
        discretisation: Discretisation::SecondOrder,
        // The prior: λ₀ is 20 % off, so a relative σ of 25 % covers it; the structurally
        // zero β_i are 0 in λ₀ too, and the floor sits below the smallest nonzero
        // (Izz6 = 4e-5 kg·m²) so that the filter cannot push the wrist's tiny inertias
        // out of the physical region.
        initial_parameter_rel_std: 0.25,
        initial_parameter_min_std: 1e-6,
        ..Default::default()
    };
    let lambda0 = &beta * 1.2;
    let mut ekf = DynEkf::new(f.dmodel.clone(), lambda0.clone(), cfg).unwrap();
    let est = ekf.run(&rec.samples()).unwrap();
    let beta_s: Beta = f.model.chain_base_values();
    let mut ekf_s = Ekf::<_, 6, B, 48>::new(f.model, beta_s * 1.2, cfg).unwrap();
    let fixed = |col: &[DVector<f64>]| -> Vec<SVector<f64, 6>> {
        col.iter()
            .map(|v| SVector::from_column_slice(v.as_slice()))
            .collect()
    };
    let (q, qd, qdd, tau) = (
        fixed(&rec.q),
        fixed(&rec.qd),
        fixed(&rec.qdd),
        fixed(&rec.tau),
    );
    let est_s = ekf_s
        .run(&prrrp_core::Samples::new(&q, &qd, &qdd, &tau).unwrap())
        .unwrap();
    let diff = rel_diff(est.as_slice(), est_s.as_slice());
    let e0 = prediction_error(&f.dmodel, &lambda0, &rec);
    let e1 = prediction_error(&f.dmodel, &est, &rec);
    println!(
        "Dyn EKF: torque prediction error {e0:.3} (λ0) → {e1:.4}; damped {}, Dyn vs Const \
         {diff:.1e}",
        ekf.damped_updates()
    );
    assert!(diff <= 1e-9, "{diff}");
    assert!(e1 <= 0.5 * e0, "{e1} vs {e0}");
}

/// Bad input at run-time sizes: typed errors that say what to fix, never a panic.
#[test]
fn bad_input_is_a_typed_error_at_run_time_sizes() {
    let f = fixture();
    let m = &f.dmodel;
    // λ₀ of the wrong length, for every estimator.
    let short = DVector::zeros(B - 1);
    assert!(matches!(
        DynRls::new(m.clone(), short.clone(), RlsConfig::default()),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        DynAdaline::new(m.clone(), short.clone(), AdalineConfig::default()),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        DynHopfield::new(m.clone(), short.clone(), HopfieldConfig::default()),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        DynEkf::new(m.clone(), short, EkfConfig::default()),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    // A compile-time S that is not 2N + P.
    let beta_s: Beta = f.model.chain_base_values();
    assert!(matches!(
        Ekf::<_, 6, B, 47>::new(f.model, beta_s, EkfConfig::default()),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    // A sample with the wrong joint count.
    let mut rls = DynRls::new(m.clone(), DVector::zeros(B), RlsConfig::default()).unwrap();
    let five = DVector::zeros(5);
    let six = DVector::zeros(6);
    let e = rls
        .step(DynSample::new(&five, &six, &six, &six))
        .unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    println!("{e}");
    let mut ekf = DynEkf::new(m.clone(), truth(), EkfConfig::default()).unwrap();
    assert!(matches!(
        ekf.step(DynSample::new(&six, &six, &six, &five)),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    // Samples of unequal vector lengths.
    let qs = vec![six.clone(), five.clone()];
    let e = DynSamples::new(&qs, &qs, &qs, &qs).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    // NaN.
    let mut nan = six.clone();
    nan[2] = f64::NAN;
    assert!(matches!(
        rls.step(DynSample::new(&six, &nan, &six, &six)),
        Err(PrrrpError::NonFinite { .. })
    ));
    // Too few samples, rank-deficient data.
    let cfg = LeastSquaresConfig::default();
    let few = DynRecord {
        q: f.rec.q[..6].to_vec(),
        qd: f.rec.qd[..6].to_vec(),
        qdd: f.rec.qdd[..6].to_vec(),
        tau: f.rec.tau[..6].to_vec(),
    };
    assert!(matches!(
        least_squares(m, &few.samples(), &cfg),
        Err(PrrrpError::TooFewSamples { .. })
    ));
    let same = DynRecord {
        q: vec![f.rec.q[0].clone(); 50],
        qd: vec![f.rec.qd[0].clone(); 50],
        qdd: vec![f.rec.qdd[0].clone(); 50],
        tau: vec![f.rec.tau[0].clone(); 50],
    };
    assert!(matches!(
        least_squares(m, &same.samples(), &cfg),
        Err(PrrrpError::RankDeficient { .. })
    ));
    // An unstable step size.
    let unstable = AdalineConfig {
        step_size: 2.5,
        ..Default::default()
    };
    assert!(matches!(
        DynAdaline::new(m.clone(), DVector::zeros(B), unstable),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // A diverging EKF: λ₀ = −β makes M(q, λ₀) negative definite.
    let mut ekf = DynEkf::new(m.clone(), -truth(), EkfConfig::default()).unwrap();
    let s = f.rec.samples();
    let e = ekf.step(s.sample(0)).unwrap_err();
    assert!(matches!(e, PrrrpError::Diverged { .. }), "{e}");
    println!("{e}");
    // A base-parameter analysis of another chain.
    let other = panda_like()
        .base_parameters(&BaseOptions::default())
        .unwrap();
    assert!(matches!(
        f.chain.to_dyn().base_model(&other),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    // Model calls with wrong sizes or a workspace of another model.
    let mut ws = m.workspace();
    let mut phi = DMatrix::zeros(6, B - 1);
    assert!(matches!(
        m.regressor_into(&mut ws, &six, &six, &six, &mut phi),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let panda = panda_like();
    let pm = panda.base_model(&other).unwrap();
    let mut pws = pm.workspace();
    let mut phi = DMatrix::zeros(6, B);
    assert!(matches!(
        m.regressor_into(&mut pws, &six, &six, &six, &mut phi),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let _ = &f.base;
}

/// The EKF's time update on a damped rotor, against its exact solution. One revolute
/// joint about the vertical (no gravity torque), inertia I about the axis, viscous
/// friction fv, no torque: q̇(t) = q̇₀·e^(−r·t) and q(t) = q₀ + q̇₀·(1 − e^(−r·t))/r with
/// r = fv/I. Where h·r passes the stiffness limit the filter (stiff handling on, as
/// `identify` runs it) takes its linearly implicit step; up to h·r = 2, where the explicit
/// midpoint step is still stable, that step must predict q and q̇ at least as well as the
/// explicit one, and beyond, where the explicit step grows the mode, it must stay bounded
/// (|q̇⁺| ≤ |q̇|). (That the switch does not bias the slow modes an estimate rests on is
/// checked end to end in `python/tests/test_identify_methods.py`.)
#[test]
fn ekf_time_update_on_a_damped_rotor_matches_its_exact_decay() {
    use prrrp_core::{inertial_parameters, DhConvention, DhRow, DynChain, FrictionModel};
    let (inertia, fv) = (0.02, 0.5);
    let r = fv / inertia;
    let chain = DynChain::new(
        vec![DhRow {
            kind: prrrp_core::JointKind::Revolute,
            theta: 0.0,
            d: 0.0,
            a: 0.0,
            alpha: 0.0,
        }],
        DhConvention::Modified,
    )
    .unwrap()
    .with_inertial(vec![inertial_parameters(
        1.0,
        [0.0; 3],
        [inertia, 0.0, inertia, 0.0, 0.0, inertia],
    )])
    .unwrap()
    .with_friction(
        FrictionModel {
            viscous: true,
            ..FrictionModel::default()
        },
        vec![[fv, 0.0, 0.0]],
    )
    .unwrap();
    let model = base_model(&chain);
    let beta = model.chain_base_values().clone();
    // (q, q̇) after one prediction from the state the first step left.
    let predict = |h: f64, stiff_handling: bool| {
        let cfg = EkfConfig {
            dt: h,
            measurement: prrrp_core::EkfMeasurement::PositionsVelocities,
            ..Default::default()
        };
        let mut ekf = DynEkf::new(model.clone(), beta.clone(), cfg).unwrap();
        ekf.set_stiff_handling(stiff_handling);
        let (q, qd) = (DVector::from_element(1, 0.3), DVector::from_element(1, 2.0));
        // No q̈ (NaN): the filter linearises at its own prediction.
        let (zero, nan) = (DVector::zeros(1), DVector::from_element(1, f64::NAN));
        ekf.step(DynSample::new(&q, &qd, &nan, &zero)).unwrap();
        let x1 = ekf.state().clone();
        ekf.step(DynSample::new(&nan, &nan, &nan, &zero)).unwrap();
        let x2 = ekf.state().clone();
        let decay = (-r * h).exp();
        let exact = (x1[0] + x1[1] * (1.0 - decay) / r, x1[1] * decay);
        (x1[1], x2[0] - exact.0, x2[1] - exact.1, ekf.stiff_steps())
    };
    for hr in [1.2, 1.5, 1.9] {
        let h = hr / r;
        let (_, eq_on, ev_on, steps) = predict(h, true);
        let (_, eq_off, ev_off, _) = predict(h, false);
        println!(
            "h·r = {hr}: stiff steps {steps}; errors q {eq_on:.2e} (explicit {eq_off:.2e}), \
             q̇ {ev_on:.2e} (explicit {ev_off:.2e})"
        );
        assert!(steps > 0, "h·r = {hr}: the stiff step was not taken");
        assert!(
            eq_on.abs() <= eq_off.abs(),
            "h·r = {hr}: q {eq_on} vs {eq_off}"
        );
        assert!(
            ev_on.abs() <= ev_off.abs(),
            "h·r = {hr}: q̇ {ev_on} vs {ev_off}"
        );
    }
    for hr in [3.0, 30.0] {
        let (v1, _, ev, _) = predict(hr / r, true);
        let v2 = ev + v1 * (-hr).exp();
        println!("h·r = {hr}: q̇ {v1:.3} → {v2:.3}");
        assert!(v2.abs() <= v1.abs(), "h·r = {hr}: {v1} → {v2}");
    }
}
