//! Per-sample steps of the online estimators and batch least squares over 5000 samples
//! (building W included). Data: the seeded excitation and closed-loop records of the
//! tests; estimators warmed up before timing; setup outside the timed closure.

#[path = "../tests/est_support/mod.rs"]
mod est_support;

use criterion::{criterion_group, criterion_main, Criterion};
use est_support::{closed_loop, excitation, paper, DT};
use prrrp_core::{
    least_squares, Adaline, AdalineConfig, AdalineRule, EkfConfig, Estimator, Hopfield,
    HopfieldConfig, Lambda, LeastSquares, LeastSquaresConfig, PrrrpEkf, Rls, RlsConfig,
};
use std::hint::black_box;

/// Times `step` over the samples of `data` in turn (1000 samples = two periods of the
/// excitation, so wrapping around is continuous).
fn bench_steps<E: Estimator<prrrp_core::nalgebra::U5, prrrp_core::nalgebra::U8>>(
    c: &mut Criterion,
    name: &str,
    est: &mut E,
    data: &est_support::Data,
) {
    let ds = data.dataset();
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
    bench_steps(c, "ekf_step", &mut ekf, &closed_loop(1000, 1, 5, DT));

    let mut hn = Hopfield::new(model, Lambda::zeros(), HopfieldConfig::default()).unwrap();
    bench_steps(c, "hopfield_step", &mut hn, &excite);

    let mut ad = Adaline::new(model, Lambda::zeros(), AdalineConfig::default()).unwrap();
    bench_steps(c, "adaline_step_normalised", &mut ad, &excite);
    let delta = AdalineConfig {
        rule: AdalineRule::Delta,
        ..Default::default()
    };
    let mut ad = Adaline::new(model, Lambda::zeros(), delta).unwrap();
    bench_steps(c, "adaline_step_delta", &mut ad, &excite);

    let mut rls = Rls::new(model, Lambda::zeros(), RlsConfig::default()).unwrap();
    bench_steps(c, "rls_step", &mut rls, &excite);

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

criterion_group!(benches, estimators);
criterion_main!(benches);
