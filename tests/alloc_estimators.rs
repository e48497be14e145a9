//! Every estimator's `step` allocates nothing after construction and a warm-up step
//! (a counting global allocator; the count is per thread, so parallel tests do not
//! interfere).

mod alloc_support;
mod dyn_support;
mod est_support;

use alloc_support::allocations;
use dyn_support::{base_model, exact_record, panda_like, DynFourier, DynRecord};
use est_support::{closed_loop, excitation, paper, DT};
use prrrp_core::nalgebra::allocator::Allocator;
use prrrp_core::nalgebra::{DVector, DefaultAllocator, Dim};
use prrrp_core::{
    Adaline, AdalineConfig, AdalineRule, Discretisation, DynAdaline, DynChainBaseModel, DynEkf,
    DynHopfield, DynRls, EkfConfig, EkfMeasurement, Estimator, Hopfield, HopfieldConfig, Lambda,
    PrrrpEkf, Rls, RlsConfig, SamplesOf,
};
use std::ops::IndexMut;

/// Steps `est` over samples 1.. of `ds` after a warm-up on sample 0 and returns the
/// number of allocations during the measured steps; compile-time and run-time sizes alike.
fn count<N: Dim, P: Dim, E: Estimator<N, P>>(est: &mut E, ds: &SamplesOf<'_, N>) -> usize
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    est.step(ds.sample(0)).unwrap();
    let before = allocations();
    for k in 1..ds.len() {
        est.step(ds.sample(k)).unwrap();
    }
    allocations() - before
}

/// Marks joint 1's position as missing in every 13th sample from sample 10, so that the
/// EKF's skipped-update path runs too.
fn drop_positions<V: IndexMut<usize, Output = f64>>(q: &mut [V]) {
    for k in (10..q.len()).step_by(13) {
        q[k][1] = f64::NAN;
    }
}

/// `base` with each of the four measurement × discretisation combinations.
fn ekf_variants(base: EkfConfig) -> Vec<EkfConfig> {
    let mut out = Vec::new();
    for measurement in [
        EkfMeasurement::Positions,
        EkfMeasurement::PositionsVelocities,
    ] {
        for discretisation in [Discretisation::Euler, Discretisation::SecondOrder] {
            out.push(EkfConfig {
                measurement,
                discretisation,
                ..base
            });
        }
    }
    out
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
    let ds = data.dataset();
    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    assert_eq!(count(&mut rls, &ds), 0, "RLS");
    let forgetting = RlsConfig {
        forgetting: 0.98,
        ..Default::default()
    };
    let mut rls = Rls::new(model, Lambda::zeros(), forgetting).unwrap();
    assert_eq!(count(&mut rls, &ds), 0, "RLS with forgetting");
    for rule in [AdalineRule::Normalised, AdalineRule::Delta] {
        let cfg = AdalineConfig {
            rule,
            ..Default::default()
        };
        let mut ad = Adaline::new(model, Lambda::zeros(), cfg).unwrap();
        assert_eq!(count(&mut ad, &ds), 0, "Adaline {rule:?}");
    }
    // Default gains (one sub-step) and high gains (several sub-steps per sample).
    for beta in [100.0, 5.0] {
        let cfg = HopfieldConfig {
            beta,
            ..Default::default()
        };
        let mut hn = Hopfield::new(model, Lambda::zeros(), cfg).unwrap();
        assert_eq!(count(&mut hn, &ds), 0, "Hopfield β = {beta}");
    }
}

#[test]
fn ekf_does_not_allocate() {
    let (model, lambda) = paper();
    let mut data = closed_loop(300, 1, 5, DT);
    drop_positions(&mut data.q);
    let ds = data.dataset();
    for cfg in ekf_variants(EkfConfig::default()) {
        let name = format!("EKF {:?} {:?}", cfg.measurement, cfg.discretisation);
        let mut ekf = PrrrpEkf::new(model, lambda * 1.2, cfg).unwrap();
        assert_eq!(count(&mut ekf, &ds), 0, "{name}");
    }
}

/// The Panda-like 7R chain with friction (64 base parameters) and an exact record.
fn panda_model_and_data(samples: usize) -> (DynChainBaseModel, DynRecord) {
    let chain = panda_like();
    let model = base_model(&chain);
    let data = exact_record(&chain, &DynFourier::seeded(5, 7, 0.5), samples, DT);
    (model, data)
}

#[test]
fn run_time_inverse_model_estimators_do_not_allocate() {
    let (model, data) = panda_model_and_data(200);
    let ds = data.samples();
    let b = model.count();
    let zeros = DVector::zeros(b);
    for forgetting in [1.0, 0.98] {
        let cfg = RlsConfig {
            forgetting,
            ..Default::default()
        };
        let mut rls = DynRls::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count(&mut rls, &ds), 0, "DynRls ν = {forgetting}");
    }
    for rule in [AdalineRule::Normalised, AdalineRule::Delta] {
        let cfg = AdalineConfig {
            rule,
            learning_rate: 1e-4,
            ..Default::default()
        };
        let mut ad = DynAdaline::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count(&mut ad, &ds), 0, "DynAdaline {rule:?}");
    }
    for beta in [100.0, 5.0] {
        let cfg = HopfieldConfig {
            beta,
            max_substeps: 10_000,
            ..Default::default()
        };
        let mut hn = DynHopfield::new(model.clone(), zeros.clone(), cfg).unwrap();
        assert_eq!(count(&mut hn, &ds), 0, "DynHopfield β = {beta}");
        assert!(hn.substeps() > 0);
    }
}

#[test]
fn run_time_ekf_does_not_allocate() {
    let (model, mut data) = panda_model_and_data(200);
    let beta = model.chain_base_values().clone();
    drop_positions(&mut data.q);
    let ds = data.samples();
    for cfg in ekf_variants(EkfConfig {
        initial_parameter_rel_std: 0.05,
        initial_parameter_min_std: 1e-6,
        ..Default::default()
    }) {
        let name = format!("DynEkf {:?} {:?}", cfg.measurement, cfg.discretisation);
        let mut ekf = DynEkf::new(model.clone(), &beta * 1.02, cfg).unwrap();
        assert_eq!(count(&mut ekf, &ds), 0, "{name}");
        assert!(ekf.skipped_updates() > 0, "{name}");
    }
}
