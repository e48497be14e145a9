//! `identify` with every method on a run-time chain with friction: the Panda-like 7R arm
//! of `dyn_support` (viscous, smoothed-Coulomb and offset friction on every joint), data on
//! an analytic Fourier excitation with τ the chain's exact inverse dynamics (plus Gaussian
//! sensor noise where said). Truth: β = K·π of the chain's own parameters.
//!
//! Bounds come from the noise, not from the estimators' printed output: least squares must
//! cover its error with its reported σ (4.5σ on every parameter: 64 parameters, a 1e-5
//! two-sided tail each); the online methods must predict held-out torques (another
//! trajectory, noise-free) about as well as least squares, whose prediction error is itself
//! the noise times √(B/rows).
mod dyn_support;

use std::sync::OnceLock;

use dyn_support::{exact_record, method_with_epochs, panda_like, DynFourier};
use prrrp_core::{
    identify, identify_robot, BaseOptions, BaseParameters, DynChain, DynDataset, EkfSettings,
    EkfStart, GradientSettings, IdentifiedModel, Method, PrrrpError, Robot, SerialChain,
    METHOD_NAMES,
};

const DT: f64 = 0.01;
const NOISE: f64 = 0.05;

struct Fixture {
    chain: DynChain,
    base: BaseParameters,
    truth: Vec<f64>,
    exact: DynDataset,
    noisy: DynDataset,
    held_out: DynDataset,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let chain = panda_like();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let truth = base.base_values(&chain.parameters()).unwrap();
        let rec = exact_record(&chain, &DynFourier::seeded(11, 7, 1.0), 1000, DT);
        let val = exact_record(&chain, &DynFourier::seeded(12, 7, 1.0), 500, DT);
        Fixture {
            exact: rec.dataset(DT, 0.0, 0),
            noisy: rec.dataset(DT, NOISE, 7),
            held_out: val.dataset(DT, 0.0, 0),
            chain,
            base,
            truth,
        }
    })
}

/// RMS over all joints and samples of the model's torque error on `data`.
fn torque_rms(m: &IdentifiedModel, data: &DynDataset) -> f64 {
    let p = m.predict(data.q(), data.qd(), data.qdd()).unwrap();
    let se: f64 = p
        .iter()
        .zip(data.tau())
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    (se / p.len() as f64).sqrt()
}

/// RMS torque of a data set.
fn tau_rms(d: &DynDataset) -> f64 {
    let s: f64 = d.tau().iter().map(|t| t * t).sum();
    (s / d.tau().len() as f64).sqrt()
}

/// ‖β̂ − β‖ / ‖β‖.
fn param_error(beta: &[f64], truth: &[f64]) -> f64 {
    let d: f64 = beta.iter().zip(truth).map(|(a, b)| (a - b) * (a - b)).sum();
    let t: f64 = truth.iter().map(|b| b * b).sum();
    (d / t).sqrt()
}

/// Settings that keep each test within a few seconds: fewer epochs than the defaults.
fn method(name: &str) -> Method {
    method_with_epochs(name, 60)
}

fn run(name: &str, data: &DynDataset) -> IdentifiedModel {
    let f = fixture();
    let t0 = std::time::Instant::now();
    let m = identify(
        &f.chain,
        &f.base,
        data,
        &method(name),
        serde_json::json!({}),
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"));
    println!(
        "{name:>8}: param error {:.2e}, held-out torque RMS {:.2e} N·m, cond {:.1}, {:.2} s, \
         settings {}",
        param_error(&m.beta, &f.truth),
        torque_rms(&m, &f.held_out),
        m.cond.unwrap(),
        t0.elapsed().as_secs_f64(),
        m.settings
    );
    assert_eq!(m.method, name);
    assert_eq!(m.beta.len(), f.truth.len());
    m
}

/// Noise-free data: least squares and RLS recover β (1e-8 relative, RLS within its
/// regularisation bias); every method predicts held-out torques to a small fraction of
/// their RMS.
#[test]
fn every_method_on_exact_data() {
    let f = fixture();
    let tau_rms = tau_rms(&f.held_out);
    for name in METHOD_NAMES {
        let m = run(name, &f.exact);
        let e = torque_rms(&m, &f.held_out);
        match name {
            "ls" | "wls" => assert!(param_error(&m.beta, &f.truth) < 1e-8),
            "rls" => assert!(param_error(&m.beta, &f.truth) < 1e-5),
            // The EKF's zero-order hold of τ misses the torque's variation within a
            // sample (bias ≈ 0.3 % of the RMS torque here); the gradient methods converge
            // in the poorly excited directions of W_b at a rate set by cond² of the
            // scaled W_b, and 60 epochs bring them to a few % (see the module docs).
            "ekf" => assert!(e < 0.01 * tau_rms, "{name}: {e} vs τ RMS {tau_rms}"),
            _ => assert!(e < 0.1 * tau_rms, "{name}: {e} vs τ RMS {tau_rms}"),
        }
        let sigma = m.sigma.is_some();
        assert_eq!(
            sigma,
            matches!(name, "ls" | "wls" | "rls" | "ekf"),
            "{name}"
        );
        assert_eq!(m.rsd_percent.is_some(), sigma);
    }
}

/// Noisy torques (σ = 0.05 N·m): LS, WLS and RLS cover their error with 4.5σ; every online
/// method predicts held-out torques within 0.5·NOISE of least squares' error (which is
/// itself ≈ NOISE·√(B/rows) ≈ 0.015 N·m).
#[test]
fn every_method_on_noisy_data() {
    let f = fixture();
    let ls = run("ls", &f.noisy);
    let e_ls = torque_rms(&ls, &f.held_out);
    for name in METHOD_NAMES {
        let m = if name == "ls" {
            ls.clone()
        } else {
            run(name, &f.noisy)
        };
        if let Some(sigma) = &m.sigma {
            if name != "ekf" {
                for (i, ((b, t), s)) in m.beta.iter().zip(&f.truth).zip(sigma).enumerate() {
                    assert!((b - t).abs() <= 4.5 * s, "{name} β{i}: {b} vs {t} ± {s}");
                }
            }
        }
        let e = torque_rms(&m, &f.held_out);
        if matches!(name, "adaline" | "hopfield") {
            // Epoch-limited (see every_method_on_exact_data): far from converged.
            assert!(e < 0.1 * tau_rms(&f.held_out), "{name}: {e}");
            continue;
        }
        if name == "ekf" {
            // τ is the filter's input: its noise enters the state and the estimate moves
            // off its least-squares start (measured: ≈ 8× LS's error, still below the
            // sensor noise).
            assert!(e <= 1.5 * NOISE, "{name}: {e} vs LS {e_ls}");
            continue;
        } else {
            assert!(e <= e_ls + 0.1 * NOISE, "{name}: {e} vs LS {e_ls}");
        }
        // The residual on the identification data is the noise.
        for r in &m.residual_rms {
            assert!(*r < 1.5 * NOISE, "{name}: residual {r}");
        }
    }
}

/// The residual RMS a model reports is that of its own prediction (the chain's full
/// regressor per sample) on the identification data, whichever way identify computed it.
#[test]
fn residual_rms_is_the_models_own_prediction_error() {
    let f = fixture();
    let n = f.noisy.dof();
    for name in ["ls", "wls", "rls", "ekf"] {
        let m = run(name, &f.noisy);
        let p = m.predict(f.noisy.q(), f.noisy.qd(), f.noisy.qdd()).unwrap();
        let rows = f.noisy.len() as f64;
        for j in 0..n {
            let se: f64 = (0..f.noisy.len())
                .map(|k| (p[k * n + j] - f.noisy.tau()[k * n + j]).powi(2))
                .sum();
            let want = (se / rows).sqrt();
            let got = m.residual_rms[j];
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "{name} joint {j}: {got} vs {want}"
            );
        }
    }
}

/// Every method's model survives JSON and predicts the same after it.
#[test]
fn json_round_trip_of_every_method() {
    let f = fixture();
    for name in METHOD_NAMES {
        let m = identify(
            &f.chain,
            &f.base,
            &f.noisy,
            &method(name),
            serde_json::json!({}),
        )
        .unwrap();
        let back = IdentifiedModel::from_json(&m.to_json().unwrap()).unwrap();
        assert_eq!(back, m, "{name}");
        let v = &f.held_out;
        assert_eq!(
            back.predict(v.q(), v.qd(), v.qdd()).unwrap(),
            m.predict(v.q(), v.qd(), v.qdd()).unwrap()
        );
    }
}

/// The paper's arm through its chain form: least squares recovers the 9 base parameters
/// of exact data, and the saved model predicts the closed-form dynamics on its own.
#[test]
fn the_paper_arm_identifies_through_its_chain() {
    let robot = Robot::paper();
    let chain = SerialChain::from_robot(&robot).unwrap().to_dyn();
    let rec = exact_record(&chain, &DynFourier::seeded(5, 5, 0.5), 400, 0.02);
    let data = rec.dataset(DT, 0.0, 0);
    for name in ["ls", "wls", "rls"] {
        let m = identify_robot(&robot, &data, &method(name), serde_json::json!({})).unwrap();
        let back = IdentifiedModel::from_json(&m.to_json().unwrap()).unwrap();
        let model = robot.model();
        let lambda = robot.base_parameters();
        let p = back.predict(data.q(), data.qd(), data.qdd()).unwrap();
        let mut worst = 0.0f64;
        for k in 0..data.len() {
            let v = |s: &[f64]| prrrp_core::Vec5::from_column_slice(&s[5 * k..5 * k + 5]);
            let tau = prrrp_core::LinearDynamics::inverse_dynamics(
                &model,
                &v(data.q()),
                &v(data.qd()),
                &v(data.qdd()),
                &lambda,
            );
            for i in 0..5 {
                worst = worst.max((p[5 * k + i] - tau[i]).abs() / (1.0 + tau[i].abs()));
            }
        }
        println!(
            "paper arm, {name}: {} base parameters, worst torque error {worst:.1e}",
            m.beta.len()
        );
        assert_eq!(m.beta.len(), 9);
        assert!(worst < 1e-8, "{name}: {worst}");
    }
}

/// Bad input: typed errors that say what to fix.
#[test]
fn bad_input_is_a_typed_error() {
    let f = fixture();
    let ls = Method::parse("ls").unwrap();
    // Every method's error on `data`, with the method's name.
    let every_method = |data: &DynDataset| {
        METHOD_NAMES.map(|name| {
            let m = method(name);
            let e = identify(&f.chain, &f.base, data, &m, serde_json::json!({})).unwrap_err();
            (name, e)
        })
    };
    // The error of method `m` on the exact data.
    let exact_error =
        |m: &Method| identify(&f.chain, &f.base, &f.exact, m, serde_json::json!({})).unwrap_err();
    // Wrong joint count.
    let puma = SerialChain::puma560().to_dyn();
    let pbase = puma.base_parameters(&BaseOptions::default()).unwrap();
    let e = identify(&puma, &pbase, &f.exact, &ls, serde_json::json!({})).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    // Too few samples: 9 samples × 7 joints = 63 equations for 64 base parameters.
    let r = 0..7 * 9;
    let few = DynDataset::with_min_samples(
        7,
        1,
        f.exact.t()[..9].to_vec(),
        f.exact.q()[r.clone()].to_vec(),
        f.exact.qd()[r.clone()].to_vec(),
        f.exact.qdd()[r.clone()].to_vec(),
        f.exact.tau()[r].to_vec(),
    )
    .unwrap();
    for (name, e) in every_method(&few) {
        assert!(matches!(e, PrrrpError::TooFewSamples { .. }), "{name}: {e}");
    }
    // NaN never reaches identify: the data set refuses it, naming joint and row.
    let mut q = f.exact.q().to_vec();
    q[7 * 3 + 2] = f64::NAN;
    let e = DynDataset::new(
        7,
        f.exact.t().to_vec(),
        q,
        f.exact.qd().to_vec(),
        f.exact.qdd().to_vec(),
        f.exact.tau().to_vec(),
    )
    .unwrap_err();
    assert!(
        matches!(e, PrrrpError::NonFinite { row: Some(3), .. }),
        "{e}"
    );
    // Unknown method.
    let e = Method::parse("magic").unwrap_err();
    assert!(e.to_string().contains("unknown"), "{e}");
    // Unstable step sizes.
    for m in [
        Method::Adaline(GradientSettings {
            step_size: 2.5,
            ..GradientSettings::adaline()
        }),
        Method::Hopfield(GradientSettings {
            step_size: 2.0,
            ..GradientSettings::hopfield()
        }),
        Method::Adaline(GradientSettings {
            rule: prrrp_core::AdalineRule::Delta,
            learning_rate: Some(10.0),
            ..GradientSettings::adaline()
        }),
    ] {
        let e = exact_error(&m);
        assert!(matches!(e, PrrrpError::InvalidParameter { .. }), "{e}");
        println!("{e}");
    }
    // Steps too small to move the weights: 1e-300 reported "converged" on its unchanged
    // start.
    for m in [
        Method::Adaline(GradientSettings {
            rule: prrrp_core::AdalineRule::Delta,
            learning_rate: Some(1e-300),
            ..GradientSettings::adaline()
        }),
        Method::Hopfield(GradientSettings {
            step_size: 1e-300,
            ..GradientSettings::hopfield()
        }),
    ] {
        let e = exact_error(&m);
        assert!(e.to_string().contains("MIN_FACTOR"), "{e}");
    }
    // Data at rest excite no inertia: rank deficient for every method.
    let z = vec![0.0; f.exact.q().len()];
    let rest = DynDataset::new(
        7,
        f.exact.t().to_vec(),
        z.clone(),
        z.clone(),
        z,
        f.exact.tau().to_vec(),
    )
    .unwrap();
    for (name, e) in every_method(&rest) {
        assert!(matches!(e, PrrrpError::RankDeficient { .. }), "{name}: {e}");
    }
    // An EKF β0 of the wrong length; an EKF from −β (not a physical mass matrix) diverges.
    let ekf_from = |beta0: Vec<f64>| {
        exact_error(&Method::Ekf(EkfSettings {
            initial: EkfStart::Given(beta0),
            ..EkfSettings::default()
        }))
    };
    let e = ekf_from(vec![1.0; 3]);
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    let e = ekf_from(f.truth.iter().map(|b| -b).collect());
    assert!(matches!(e, PrrrpError::Diverged { .. }), "{e}");
    // Prior widths squared to inf or to a zero variance; NaN.
    for w in [1e300, 1e-300, -1.0, f64::NAN] {
        let e = exact_error(&Method::Ekf(EkfSettings {
            least_squares_prior_width: w,
            ..EkfSettings::default()
        }));
        assert!(
            matches!(&e, PrrrpError::InvalidParameter { field, .. } if field == "least_squares_prior_width"),
            "{w}: {e}"
        );
    }
}
