//! The identification core of `prrrp identify` on a 6-joint, 20 000-sample log: a UR5-like
//! arm (`tests/data/ur5_like_friction.toml`: viscous, smooth Coulomb with v_s = 0.02 rad/s
//! and offset friction) following a seeded five-harmonic Fourier excitation for 40 s at
//! 500 Hz, with torque-sensor (0.05 N·m) and encoder (1e-4 rad) noise. Each step is timed
//! on the output of the step before, built outside the timed closures:
//! - `preprocess_log`: the raw log to filtered q, q̇, q̈, τ (default settings);
//! - `base_observation_matrix`: stacking the base regressor W_b of the preprocessed data;
//! - `identify_wls`: the default method, joint-weighted least squares with its σ;
//! - `coulomb_scale`: the cross-validated search of the Coulomb speed scale (defaults).

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;

use criterion::{criterion_group, criterion_main, Criterion};
use dyn_support::DynFourier;
use prrrp_core::{
    identify, preprocess_log, select_coulomb_scale, BaseOptions, CoulombScaleConfig, DynChain,
    FrictionModel, LogConfig, Method,
};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::hint::black_box;
use std::time::Duration;

/// Log rate, Hz, and length, s.
const RATE: f64 = 500.0;
const SECONDS: f64 = 40.0;

struct Log {
    t: Vec<f64>,
    q: Vec<f64>,
    tau: Vec<f64>,
}

fn ur5_like() -> DynChain {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/ur5_like_friction.toml"
    );
    let chain = DynChain::from_toml_file(path).expect("UR5-like robot file");
    let friction = FrictionModel {
        coulomb_smoothing: 0.02,
        ..FrictionModel::all()
    };
    let params = chain.friction_params().to_vec();
    chain.with_friction(friction, params).expect("friction")
}

fn log(truth: &DynChain) -> Log {
    let n = truth.dof();
    let reference = DynFourier::seeded(29, n, 1.0);
    let mut rng = StdRng::seed_from_u64(29);
    let (torque, encoder) = (
        Normal::new(0.0, 0.05).unwrap(),
        Normal::new(0.0, 1e-4).unwrap(),
    );
    let rows = (SECONDS * RATE) as usize;
    let mut log = Log {
        t: Vec::with_capacity(rows),
        q: Vec::with_capacity(rows * n),
        tau: Vec::with_capacity(rows * n),
    };
    for k in 0..rows {
        let t = k as f64 / RATE;
        let [q, qd, qdd] = reference.eval(t);
        let tau = truth
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .expect("sizes");
        log.t.push(t);
        log.q.extend(q.iter().map(|x| x + encoder.sample(&mut rng)));
        log.tau
            .extend(tau.iter().map(|x| x + torque.sample(&mut rng)));
    }
    log
}

fn identify_core(c: &mut Criterion) {
    let truth = ur5_like();
    let n = truth.dof();
    let raw = log(&truth);
    let config = LogConfig::default();
    let (data, _) = preprocess_log(&raw.t, &raw.q, &raw.tau, None, n, &config).expect("log");
    // The model identified: the robot file's friction terms with the exact sign (the
    // search's job is to find the scale).
    let model = truth
        .clone()
        .with_friction(FrictionModel::all(), truth.friction_params().to_vec())
        .expect("friction");
    let base = model
        .base_parameters(&BaseOptions::default())
        .expect("base parameters");
    let wls = Method::parse("wls").expect("wls");

    let mut g = c.benchmark_group("identify_ur5_20000");
    // Each iteration takes milliseconds to seconds: criterion's minimum of 10 samples.
    g.sample_size(10);
    g.bench_function("preprocess_log", |b| {
        b.iter(|| {
            preprocess_log(
                black_box(&raw.t),
                black_box(&raw.q),
                black_box(&raw.tau),
                None,
                n,
                &config,
            )
            .expect("log")
        })
    });
    g.bench_function("base_observation_matrix", |b| {
        b.iter(|| {
            model
                .base_observation_matrix(&base, black_box(data.q()), data.qd(), data.qdd())
                .expect("W_b")
        })
    });
    g.bench_function("identify_wls", |b| {
        b.iter(|| {
            identify(
                &model,
                &base,
                black_box(&data),
                &wls,
                serde_json::Value::Null,
            )
            .expect("wls")
        })
    });
    g.bench_function("coulomb_scale", |b| {
        b.iter(|| {
            select_coulomb_scale(
                &model,
                &base,
                black_box(&data),
                &CoulombScaleConfig::default(),
            )
            .expect("search")
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5));
    targets = identify_core
}
criterion_main!(benches);
