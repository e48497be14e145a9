//! The identification core of `prrrp identify` on a 6-joint, 20 000-sample log: a UR5-like
//! arm (`tests/data/ur5_like_friction.toml`: viscous, smooth Coulomb with v_s = 0.02 rad/s
//! and offset friction) following a seeded five-harmonic Fourier excitation for 40 s at
//! 500 Hz, with torque-sensor (0.05 N·m) and encoder (1e-4 rad) noise. Each step is timed
//! on the output of the step before, built outside the timed closures:
//! - `preprocess_log`: the raw log to filtered q, q̇, q̈, τ (default settings);
//! - `base_observation_matrix`: stacking the base regressor W_b of the preprocessed data;
//! - `identify_wls`: the default method, joint-weighted least squares with its σ;
//! - `coulomb_scale`: the cross-validated search of the Coulomb speed scale (defaults);
//! - `identify_adaline`, `identify_hopfield`: the gradient methods with their defaults
//!   (every epoch and step halving of the stopping rule);
//! - group `gradient_epoch_ur5_20000`: one epoch of Adaline (delta rule) and of the
//!   Hopfield network on the whitened base model, as `identify` runs them: `per_sample`
//!   builds each sample's regressor in the epoch (the online form), `stored` reads it
//!   from regressors built once.

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;

use criterion::{criterion_group, criterion_main, Criterion};
use dyn_support::DynFourier;
use nalgebra::DVector;
use prrrp_core::{
    identify, preprocess_log, select_coulomb_scale, BaseOptions, CoulombScaleConfig, DynChain,
    FrictionModel, LogConfig, Method,
};
use prrrp_core::{
    AdalineConfig, AdalineRule, DynAdaline, DynHopfield, DynSamples, DynScaledModel,
    HopfieldConfig, StoredRegressors,
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
    for name in ["adaline", "hopfield"] {
        let method = Method::parse(name).expect("method");
        g.bench_function(format!("identify_{name}"), |b| {
            b.iter(|| {
                identify(
                    &model,
                    &base,
                    black_box(&data),
                    &method,
                    serde_json::Value::Null,
                )
                .expect(name)
            })
        });
    }
    g.finish();

    // One epoch of each gradient method on the whitened base model, with the settings
    // `identify` starts from (step μ = 0.5 of the stability bound).
    let rows = |flat: &[f64]| -> Vec<DVector<f64>> {
        flat.chunks_exact(n)
            .map(DVector::from_column_slice)
            .collect()
    };
    let (q, qd, qdd, tau) = (
        rows(data.q()),
        rows(data.qd()),
        rows(data.qdd()),
        rows(data.tau()),
    );
    let samples = DynSamples::new(&q, &qd, &qdd, &tau).expect("samples");
    let bm = model.base_model(&base).expect("base model");
    let sm = DynScaledModel::whitened(bm, &samples).expect("whitened");
    let p = base.count();
    let (mut row_peak, mut frob_peak) = (0.0f64, 0.0f64);
    {
        use prrrp_core::LinearModel;
        let mut ws = sm.workspace();
        let mut phi = nalgebra::DMatrix::zeros(n, p);
        for s in samples.iter() {
            sm.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)
                .expect("regressor");
            for r in phi.row_iter() {
                row_peak = row_peak.max(r.norm_squared());
            }
            frob_peak = frob_peak.max(phi.norm_squared());
        }
    }
    let adaline_cfg = AdalineConfig {
        rule: AdalineRule::Delta,
        learning_rate: 0.5 / row_peak,
        ..AdalineConfig::default()
    };
    let hopfield_cfg = HopfieldConfig {
        bound: 1e3,
        beta: 1e3 * frob_peak / 0.5,
        dt: 1.0,
        stability_limit: 1.0,
        max_substeps: 64,
    };
    let zeros = DVector::zeros(p);
    let mut g = c.benchmark_group("gradient_epoch_ur5_20000");
    g.sample_size(10);
    g.bench_function("adaline_per_sample", |b| {
        let mut est = DynAdaline::new(sm.clone(), zeros.clone(), adaline_cfg).expect("adaline");
        b.iter(|| est.train(black_box(&samples), 1).expect("epoch"))
    });
    let stored = StoredRegressors::new(&sm, &samples, usize::MAX).expect("stored");
    g.bench_function("adaline_stored", |b| {
        let mut est = DynAdaline::new(sm.clone(), zeros.clone(), adaline_cfg).expect("adaline");
        b.iter(|| est.train_stored(black_box(&stored), 1).expect("epoch"))
    });
    g.bench_function("hopfield_stored", |b| {
        let mut est = DynHopfield::new(sm.clone(), zeros.clone(), hopfield_cfg).expect("hopfield");
        b.iter(|| est.train_stored(black_box(&stored), 1).expect("epoch"))
    });
    g.bench_function("hopfield_per_sample", |b| {
        let mut est = DynHopfield::new(sm.clone(), zeros.clone(), hopfield_cfg).expect("hopfield");
        b.iter(|| est.train(black_box(&samples), 1).expect("epoch"))
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
