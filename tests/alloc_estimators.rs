//! Every estimator's `step` allocates nothing after construction and a warm-up step
//! (a counting global allocator; the count is per thread, so parallel tests do not
//! interfere).

mod alloc_support;
mod dyn_support;
mod est_support;

use alloc_support::allocations;
use dyn_support::{exact_record, panda_like, DynFourier, DynRecord};
use est_support::{closed_loop, excitation, paper, DT};
use prrrp_core::nalgebra::{DVector, Dyn};
use prrrp_core::{
    Adaline, AdalineConfig, AdalineRule, BaseOptions, Discretisation, DynAdaline,
    DynChainBaseModel, DynEkf, DynHopfield, DynRls, EkfConfig, EkfMeasurement, Estimator, Hopfield,
    HopfieldConfig, Lambda, PrrrpEkf, Rls, RlsConfig,
};

/// Steps `est` over samples 1.. of `data` after a warm-up on sample 0 and returns the
/// number of allocations during the measured steps.
fn count<E: Estimator<prrrp_core::nalgebra::U5, prrrp_core::nalgebra::U8>>(
    est: &mut E,
    data: &est_support::Data,
) -> usize {
    let ds = data.dataset();
    est.step(ds.sample(0)).unwrap();
    let before = allocations();
    for k in 1..ds.len() {
        est.step(ds.sample(k)).unwrap();
    }
    allocations() - before
}

#[test]
fn the_counter_sees_allocations() {
    let before = allocations();
    let v = std::hint::black_box(vec![1.0f64; 8]);
    assert!(allocations() > before);
    drop(v);
}

#[test]
fn inverse_model_estimators_do_not_allocate() {
    let (model, _) = paper();
    let data = excitation(300, 1);
    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    assert_eq!(count(&mut rls, &data), 0, "RLS");
    let forgetting = RlsConfig {
        forgetting: 0.98,
        ..Default::default()
    };
    let mut rls = Rls::new(model, Lambda::zeros(), forgetting).unwrap();
    assert_eq!(count(&mut rls, &data), 0, "RLS with forgetting");
    for rule in [AdalineRule::Normalised, AdalineRule::Delta] {
        let cfg = AdalineConfig {
            rule,
            ..Default::default()
        };
        let mut ad = Adaline::new(model, Lambda::zeros(), cfg).unwrap();
        assert_eq!(count(&mut ad, &data), 0, "Adaline {rule:?}");
    }
    // Default gains (one sub-step) and high gains (several sub-steps per sample).
    for beta in [100.0, 5.0] {
        let cfg = HopfieldConfig {
            beta,
            ..Default::default()
        };
        let mut hn = Hopfield::new(model, Lambda::zeros(), cfg).unwrap();
        assert_eq!(count(&mut hn, &data), 0, "Hopfield β = {beta}");
    }
}

#[test]
fn ekf_does_not_allocate() {
    let (model, lambda) = paper();
    let mut data = closed_loop(300, 1, 5, DT);
    // Some missing measurements exercise the skipped-update path too.
    for k in (10..300).step_by(13) {
        data.q[k][1] = f64::NAN;
    }
    for measurement in [
        EkfMeasurement::Positions,
        EkfMeasurement::PositionsVelocities,
    ] {
        for discretisation in [Discretisation::Euler, Discretisation::SecondOrder] {
            let cfg = EkfConfig {
                measurement,
                discretisation,
                ..Default::default()
            };
            let mut ekf = PrrrpEkf::new(model, lambda * 1.2, cfg).unwrap();
            assert_eq!(
                count(&mut ekf, &data),
                0,
                "EKF {measurement:?} {discretisation:?}"
            );
        }
    }
}

/// As [`count`], for a run-time-size estimator.
fn count_dyn<E: Estimator<Dyn, Dyn>>(est: &mut E, data: &DynRecord) -> usize {
    let ds = data.samples();
    est.step(ds.sample(0)).unwrap();
    let before = allocations();
    for k in 1..ds.len() {
        est.step(ds.sample(k)).unwrap();
    }
    allocations() - before
}

/// The Panda-like 7R chain with friction (64 base parameters) and an exact record.
fn panda_model_and_data(samples: usize) -> (DynChainBaseModel, DynRecord) {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let model = chain.base_model(&base).unwrap();
    let data = exact_record(&chain, &DynFourier::seeded(5, 7, 0.5), samples, DT);
    (model, data)
}

#[test]
fn run_time_inverse_model_estimators_do_not_allocate() {
    let (model, data) = panda_model_and_data(200);
    let b = model.count();
    let zeros = DVector::zeros(b);
    for forgetting in [1.0, 0.98] {
        let cfg = RlsConfig {
            forgetting,
            ..Default::default()
        };
        let mut rls = DynRls::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count_dyn(&mut rls, &data), 0, "DynRls ν = {forgetting}");
    }
    for rule in [AdalineRule::Normalised, AdalineRule::Delta] {
        let cfg = AdalineConfig {
            rule,
            learning_rate: 1e-4,
            ..Default::default()
        };
        let mut ad = DynAdaline::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count_dyn(&mut ad, &data), 0, "DynAdaline {rule:?}");
    }
    for beta in [100.0, 5.0] {
        let cfg = HopfieldConfig {
            beta,
            max_substeps: 10_000,
            ..Default::default()
        };
        let mut hn = DynHopfield::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count_dyn(&mut hn, &data), 0, "DynHopfield β = {beta}");
        assert!(hn.substeps() > 0);
    }
}

#[test]
fn run_time_ekf_does_not_allocate() {
    let (model, mut data) = panda_model_and_data(200);
    let beta = model.chain_base_values().clone();
    for k in (10..200).step_by(13) {
        data.q[k][1] = f64::NAN;
    }
    for measurement in [
        EkfMeasurement::Positions,
        EkfMeasurement::PositionsVelocities,
    ] {
        for discretisation in [Discretisation::Euler, Discretisation::SecondOrder] {
            let cfg = EkfConfig {
                measurement,
                discretisation,
                initial_parameter_rel_std: 0.05,
                initial_parameter_min_std: 1e-6,
                ..Default::default()
            };
            let mut ekf = DynEkf::new(model.clone(), &beta * 1.02, cfg).unwrap();
            assert_eq!(
                count_dyn(&mut ekf, &data),
                0,
                "DynEkf {measurement:?} {discretisation:?}"
            );
            assert!(ekf.skipped_updates() > 0);
        }
    }
}
