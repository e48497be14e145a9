//! Recursive least squares, Adaline and Hopfield network: accuracy on noise-free
//! excitation data after their documented samples or epochs, the structure of the paper's
//! Adaline networks, divergence detection, the Hopfield box and stability, bad input.

mod est_support;

use est_support::{add_noise, excitation, line, paper, rel_errors, Noise};
use proptest::prelude::*;
use prrrp_core::nalgebra::SVector;
use prrrp_core::{
    least_squares, Adaline, AdalineConfig, AdalineRule, Estimator, Hopfield, HopfieldConfig,
    Lambda, LeastSquaresConfig, PrrrpError, Rls, RlsConfig, Sample, Vec5,
};

/// 20 s of excitation at 50 Hz.
const SAMPLES: usize = 1000;

#[test]
fn rls_matches_batch_least_squares() {
    let (model, lambda) = paper();
    let data = excitation(SAMPLES, 1);
    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    rls.run(&data.dataset()).unwrap();
    let (max, e) = rel_errors(rls.estimate(), &lambda);
    eprintln!("RLS noise-free after {SAMPLES} samples: {}", line(&e));
    assert!(max < 1e-6, "{max}");
    assert_eq!(rls.samples(), SAMPLES);

    // On noisy data RLS (δ large, ν = 1) is batch least squares up to the tiny prior.
    let (noisy, _) = add_noise(&data, Noise::realistic(), 3);
    let batch = least_squares(&model, &noisy.dataset(), &LeastSquaresConfig::default()).unwrap();
    rls.reset();
    rls.run(&noisy.dataset()).unwrap();
    let d = (rls.estimate() - batch.lambda)
        .component_div(&batch.std_dev)
        .amax();
    assert!(d < 1e-3, "RLS vs batch, in batch σ: {d}");
    // P is symmetric and its scale matches (WᵀW)⁻¹: σ²·diag(P) ≈ σ_i².
    let p = rls.covariance();
    assert_eq!(*p, p.transpose());
    for i in 0..8 {
        let sd = (batch.sigma2 * p[(i, i)]).sqrt();
        assert!((sd / batch.std_dev[i] - 1.0).abs() < 1e-3);
    }
}

#[test]
fn rls_with_forgetting_tracks_a_parameter_change() {
    let (model, lambda) = paper();
    let data = excitation(2 * SAMPLES, 2);
    // The payload (λ8 = m5) doubles halfway.
    let mut changed = lambda;
    changed[7] *= 2.0;
    let mut tau = data.tau.clone();
    for (k, t) in tau.iter_mut().enumerate().skip(SAMPLES) {
        *t = model.inverse_dynamics(&data.q[k], &data.qd[k], &data.qdd[k], &changed);
    }
    let ds = prrrp_core::Samples::new(&data.q, &data.qd, &data.qdd, &tau).unwrap();
    let cfg = RlsConfig {
        forgetting: 0.99,
        ..Default::default()
    };
    let mut forget = Rls::new(model, Lambda::zeros(), cfg).unwrap();
    let mut keep = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    forget.run(&ds).unwrap();
    keep.run(&ds).unwrap();
    assert!((forget.estimate()[7] / changed[7] - 1.0).abs() < 1e-3);
    // Without forgetting the estimate averages the two halves.
    assert!((keep.estimate()[7] / changed[7] - 1.0).abs() > 0.1);
}

/// Normalised Adaline: 1 % after 2 epochs; delta rule (γ = 5e-3): 1 % after 15 epochs.
#[test]
fn adaline_recovers_lambda_after_documented_epochs() {
    let (model, lambda) = paper();
    let data = excitation(SAMPLES, 1);
    for (rule, epochs) in [(AdalineRule::Normalised, 2), (AdalineRule::Delta, 15)] {
        let cfg = AdalineConfig {
            rule,
            ..Default::default()
        };
        let mut ad = Adaline::new(model, Lambda::zeros(), cfg).unwrap();
        let rep = ad.train(&data.dataset(), epochs).unwrap();
        let (max, e) = rel_errors(ad.estimate(), &lambda);
        eprintln!("Adaline {rule:?} after {epochs} epochs: {}", line(&e));
        assert!(max < 0.01, "{rule:?}: {max}");
        assert_eq!(rep.rms_error.len(), epochs);
        // The a-priori error decreases from epoch to epoch.
        assert!(rep.rms_error.windows(2).all(|w| w[1] < w[0]));
        assert_eq!(ad.samples(), epochs * SAMPLES);
    }
}

/// The two networks of eq. 40: the force rows (F1, F5) train only λ1 and λ8, the planar
/// rows (τ2, τ3, τ4) only λ2..λ7.
#[test]
fn adaline_networks_are_those_of_eq_40() {
    let (model, _) = paper();
    let data = excitation(50, 3);
    let only = |rows: [bool; 5]| {
        let mut ad = Adaline::new(model, Lambda::zeros(), AdalineConfig::default()).unwrap();
        for k in 0..data.len() {
            let tau = Vec5::from_fn(|j, _| if rows[j] { data.tau[k][j] } else { 0.0 });
            ad.step(Sample::new(&data.q[k], &data.qd[k], &data.qdd[k], &tau))
                .unwrap();
        }
        *ad.estimate()
    };
    let net1 = only([true, false, false, false, true]);
    let net2 = only([false, true, true, true, false]);
    for i in 0..8 {
        let in_net1 = i == 0 || i == 7;
        assert_eq!(net1[i] != 0.0, in_net1, "network 1, λ{}", i + 1);
        assert_eq!(net2[i] != 0.0, !in_net1, "network 2, λ{}", i + 1);
    }
}

#[test]
fn adaline_divergence_is_detected() {
    let (model, _) = paper();
    let data = excitation(SAMPLES, 1);
    // γ·‖Φ_1‖² ≈ 0.05·190 ≫ 2: the force network blows up.
    let cfg = AdalineConfig {
        rule: AdalineRule::Delta,
        learning_rate: 0.05,
        ..Default::default()
    };
    let mut ad = Adaline::new(model, Lambda::zeros(), cfg).unwrap();
    match ad.train(&data.dataset(), 1) {
        Err(PrrrpError::Diverged { what, at, .. }) => {
            assert_eq!(what, "Adaline");
            assert!(at < 100, "detected late: {at}");
        }
        other => panic!("{other:?}"),
    }
    let bad = AdalineConfig {
        step_size: 2.5,
        ..Default::default()
    };
    assert!(matches!(
        Adaline::new(model, Lambda::zeros(), bad),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}

/// Hopfield (c = 10, β = 100, one Euler sub-step per sample at 50 Hz): 1 % after 30
/// epochs of 20 s.
#[test]
fn hopfield_recovers_lambda_after_documented_epochs() {
    let (model, lambda) = paper();
    let data = excitation(SAMPLES, 1);
    let mut hn = Hopfield::new(model, Lambda::zeros(), HopfieldConfig::default()).unwrap();
    let rep = hn.train(&data.dataset(), 30).unwrap();
    let (max, e) = rel_errors(hn.estimate(), &lambda);
    eprintln!(
        "Hopfield after 30 epochs ({} sub-steps): {}",
        hn.substeps(),
        line(&e)
    );
    assert!(max < 0.01, "{max}");
    assert!(rep.rms_error.last().unwrap() < &rep.rms_error[0]);
}

/// With gains that need sub-steps, the integration stays stable and still converges; a
/// sub-step cap that is too low is a typed error.
#[test]
fn hopfield_substeps_when_needed() {
    let (model, lambda) = paper();
    let data = excitation(SAMPLES, 1);
    let cfg = HopfieldConfig {
        beta: 5.0,
        ..Default::default()
    };
    let mut hn = Hopfield::new(model, Lambda::zeros(), cfg).unwrap();
    hn.train(&data.dataset(), 5).unwrap();
    assert!(hn.substeps() > 5 * SAMPLES as u64 * 5, "{}", hn.substeps());
    let (max, _) = rel_errors(hn.estimate(), &lambda);
    assert!(max < 0.01, "{max}");

    let capped = HopfieldConfig {
        beta: 5.0,
        max_substeps: 2,
        ..Default::default()
    };
    let mut hn = Hopfield::new(model, Lambda::zeros(), capped).unwrap();
    assert!(matches!(
        hn.step(data.dataset().sample(0)),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::with_cases(64) })]

    /// Whatever the data (here: random states and torques far from any consistent
    /// model), every Hopfield estimate stays inside (−c, c) and finite.
    #[test]
    fn hopfield_stays_inside_the_box(
        q in prop::array::uniform5(-3.0f64..3.0),
        qd in prop::array::uniform5(-5.0f64..5.0),
        qdd in prop::array::uniform5(-20.0f64..20.0),
        tau in prop::array::uniform5(-500.0f64..500.0),
        c in 0.5f64..20.0,
    ) {
        let (model, _) = paper();
        let cfg = HopfieldConfig { bound: c, beta: 1.0, max_substeps: 100_000, ..Default::default() };
        let mut hn = Hopfield::new(model, Lambda::zeros(), cfg).unwrap();
        let (q, qd, qdd, tau) = (Vec5::from(q), Vec5::from(qd), Vec5::from(qdd), Vec5::from(tau));
        for _ in 0..20 {
            let l = *hn.step(Sample::new(&q, &qd, &qdd, &tau)).unwrap();
            prop_assert!(l.iter().all(|v| v.is_finite() && v.abs() < c));
        }
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let (model, lambda) = paper();
    let mut data = excitation(20, 1);
    data.qdd[5][0] = f64::NAN;
    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    let mut ad = Adaline::new(model, Lambda::zeros(), AdalineConfig::default()).unwrap();
    let mut hn = Hopfield::new(model, Lambda::zeros(), HopfieldConfig::default()).unwrap();
    for err in [
        rls.run(&data.dataset()).unwrap_err(),
        ad.run(&data.dataset()).unwrap_err(),
        hn.run(&data.dataset()).unwrap_err(),
    ] {
        assert_eq!(
            err,
            PrrrpError::NonFinite {
                what: "qdd".into(),
                row: Some(5)
            }
        );
    }
    let bad_rls = RlsConfig {
        forgetting: 1.5,
        ..Default::default()
    };
    assert!(Rls::new(model, lambda, bad_rls).is_err());
    // λ₀ outside the Hopfield box.
    let mut l0 = Lambda::zeros();
    l0[0] = 10.0;
    assert!(matches!(
        Hopfield::new(model, l0, HopfieldConfig::default()),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // Reset returns to λ₀.
    let mut rls = Rls::new(model, SVector::repeat(0.5), RlsConfig::default()).unwrap();
    let clean = excitation(20, 1);
    rls.run(&clean.dataset()).unwrap();
    rls.reset();
    assert_eq!(*rls.estimate(), SVector::<f64, 8>::repeat(0.5));
    assert_eq!(rls.samples(), 0);
}
