//! Per-sample steps of the online estimators and batch least squares over 5000 samples
//! (building W included). Data: the seeded excitation and closed-loop records of the
//! tests; estimators warmed up before timing; setup outside the timed closure.
//!
//! `chain7_*`: the same estimators at run-time sizes on a Panda-like 7R chain with
//! viscous, Coulomb and offset friction (`DynChain::new`, 64 base parameters, EKF state of
//! 78), exact records of a Fourier excitation.

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;
#[path = "../tests/est_support/mod.rs"]
mod est_support;

use criterion::{criterion_group, criterion_main, Criterion};
use dyn_support::{base_model, exact_record, panda_like, DynFourier};
use est_support::{closed_loop, excitation, paper, DT};
use prrrp_core::nalgebra::allocator::Allocator;
use prrrp_core::nalgebra::{DVector, DefaultAllocator, Dim};
use prrrp_core::{
    least_squares, Adaline, AdalineConfig, AdalineRule, Discretisation, DynAdaline, DynEkf,
    DynHopfield, DynScaledModel, EkfConfig, Estimator, Hopfield, HopfieldConfig, Lambda,
    LeastSquares, LeastSquaresConfig, PrrrpEkf, Rls, RlsConfig, SamplesOf,
};
use std::hint::black_box;

/// Times `step` over the samples of `ds` in turn (1000 samples = whole periods of the
/// excitation, so wrapping around is continuous), at compile-time or run-time sizes.
fn bench_steps<N: Dim, P: Dim, E: Estimator<N, P>>(
    c: &mut Criterion,
    name: &str,
    est: &mut E,
    ds: SamplesOf<'_, N>,
) where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    est.run(&ds).unwrap();
    let n = ds.len();
    let mut k = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            // A compare instead of `%`: an integer division would cost ~10 ns per call.
            k += 1;
            if k == n {
                k = 0;
            }
            black_box(est.step(black_box(ds.sample(k))).unwrap()[0])
        })
    });
}

fn estimators(c: &mut Criterion) {
    let (model, lambda) = paper();
    let excite = excitation(1000, 1);

    let mut ekf = PrrrpEkf::new(model, lambda * 1.2, EkfConfig::default()).unwrap();
    bench_steps(
        c,
        "ekf_step",
        &mut ekf,
        closed_loop(1000, 1, 5, DT).dataset(),
    );

    let mut hn = Hopfield::new(model, Lambda::zeros(), HopfieldConfig::default()).unwrap();
    bench_steps(c, "hopfield_step", &mut hn, excite.dataset());

    let mut ad = Adaline::new(model, Lambda::zeros(), AdalineConfig::default()).unwrap();
    bench_steps(c, "adaline_step_normalised", &mut ad, excite.dataset());
    let delta = AdalineConfig {
        rule: AdalineRule::Delta,
        ..Default::default()
    };
    let mut ad = Adaline::new(model, Lambda::zeros(), delta).unwrap();
    bench_steps(c, "adaline_step_delta", &mut ad, excite.dataset());

    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    bench_steps(c, "rls_step", &mut rls, excite.dataset());

    // Building W included; the solver's buffers are reused (its intended use), and the
    // one-shot function pays for allocating W on every call.
    let big = excitation(5000, 2);
    let cfg = LeastSquaresConfig::default();
    let mut solver = LeastSquares::new(cfg).unwrap();
    c.bench_function("least_squares_5000", |b| {
        b.iter(|| black_box(solver.solve(&model, black_box(&big.dataset())).unwrap()))
    });
    c.bench_function("least_squares_5000_oneshot", |b| {
        b.iter(|| black_box(least_squares(&model, black_box(&big.dataset()), &cfg).unwrap()))
    });
}

fn chain7(c: &mut Criterion) {
    let chain = panda_like();
    let model = base_model(&chain);
    let beta = model.chain_base_values().clone();
    let b = model.count();
    // 1000 samples at 10 ms: one period of the excitation, so wrapping around is smooth.
    let data = exact_record(&chain, &DynFourier::seeded(5, 7, 0.5), 1000, 0.01);

    let cfg = EkfConfig {
        dt: 0.01,
        discretisation: Discretisation::SecondOrder,
        initial_parameter_rel_std: 0.05,
        initial_parameter_min_std: 1e-6,
        ..Default::default()
    };
    let mut ekf = DynEkf::new(model.clone(), &beta * 1.02, cfg).unwrap();
    bench_steps(c, "chain7_ekf_step", &mut ekf, data.samples());

    // Adaline and Hopfield on the column-equilibrated model, as they are meant to be used
    // (see ScaledModel); Hopfield sized as in chain_estimators.rs (c·dt·N·B).
    let scaled = DynScaledModel::equilibrated(model.clone(), &data.samples()).unwrap();
    let bound = 100.0;
    let hcfg = HopfieldConfig {
        bound,
        beta: bound * 0.01 * (7 * b) as f64,
        dt: 0.01,
        ..Default::default()
    };
    let mut hn = DynHopfield::new(scaled.clone(), DVector::zeros(b), hcfg).unwrap();
    bench_steps(c, "chain7_hopfield_step", &mut hn, data.samples());
    let mut ad = DynAdaline::new(scaled, DVector::zeros(b), AdalineConfig::default()).unwrap();
    bench_steps(c, "chain7_adaline_step", &mut ad, data.samples());

    let big = exact_record(&chain, &DynFourier::seeded(11, 7, 1.0), 2000, 0.01);
    let mut solver = LeastSquares::new(LeastSquaresConfig::default()).unwrap();
    c.bench_function("chain7_least_squares_2000", |bch| {
        bch.iter(|| black_box(solver.solve(&model, black_box(&big.samples())).unwrap()))
    });
}

criterion_group!(benches, estimators, chain7);
criterion_main!(benches);
