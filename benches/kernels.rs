//! Per-sample model kernels of the PRRRP arm: regressor Φ(q, q̇, q̈), inverse dynamics,
//! forward dynamics and its analytic derivatives (the part of an EKF step spent in the
//! model). Inputs: 1024 seeded random states, cycled; setup outside the timed closure.

use criterion::{criterion_group, criterion_main, Criterion};
use prrrp_core::{Robot, Vec5};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;

struct State {
    q: Vec5,
    qd: Vec5,
    qdd: Vec5,
    tau: Vec5,
}

/// A power of two, so that cycling through the states costs a mask, not a division.
const STATES: usize = 1024;

fn states() -> Vec<State> {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let mut rng = StdRng::seed_from_u64(42);
    let mut v = |s: f64| Vec5::from_fn(|_, _| s * (2.0 * rng.random::<f64>() - 1.0));
    (0..STATES)
        .map(|_| {
            let (q, qd, qdd) = (v(3.0), v(2.0), v(5.0));
            let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
            State { q, qd, qdd, tau }
        })
        .collect()
}

fn kernels(c: &mut Criterion) {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let s = states();
    let mut k = 0;
    c.bench_function("regressor", |b| {
        b.iter(|| {
            k = (k + 1) % STATES;
            let x = &s[k];
            black_box(model.regressor(black_box(&x.q), &x.qd, &x.qdd))
        })
    });
    c.bench_function("inverse_dynamics", |b| {
        b.iter(|| {
            k = (k + 1) % STATES;
            let x = &s[k];
            black_box(model.inverse_dynamics(black_box(&x.q), &x.qd, &x.qdd, &lambda))
        })
    });
    c.bench_function("forward_dynamics", |b| {
        b.iter(|| {
            k = (k + 1) % STATES;
            let x = &s[k];
            black_box(model.forward_dynamics(black_box(&x.q), &x.qd, &x.tau, &lambda))
        })
    });
    c.bench_function("forward_derivatives", |b| {
        b.iter(|| {
            k = (k + 1) % STATES;
            let x = &s[k];
            black_box(model.forward_derivatives(black_box(&x.q), &x.qd, &x.tau, &lambda))
        })
    });
}

criterion_group!(benches, kernels);
criterion_main!(benches);
