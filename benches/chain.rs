//! Per-sample cost of the generic chain: inverse dynamics (RNEA), regressor, mass matrix
//! (CRBA) and forward dynamics, for the PRRRP arm as a chain (against its closed form;
//! also its compile-time base-parameter model: regressor, inverse and forward dynamics,
//! derivatives), for the 6R PUMA 560, and for the URDF robots of `example-robot-data`
//! (Panda, UR5, Kinova Gen2) when that package is installed (the test venv has it; set
//! `PRRRP_ROBOTS_DIR` to its `robots` folder elsewhere). Inputs are built outside the
//! timed closures.

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use dyn_support::robots_dir;
use prrrp_core::nalgebra::{DMatrix, DVector, SMatrix, SVector};
use prrrp_core::{
    BaseOptions, DynChain, LinearDynamics, LinearModel, Robot, SerialChain, UrdfOptions,
};
use std::hint::black_box;
use std::time::Duration;

fn state<const N: usize>() -> [SVector<f64, N>; 3] {
    let v = |s: f64| SVector::<f64, N>::from_fn(|i, _| (s * (i + 1) as f64).sin());
    [v(0.7), v(1.3), v(2.1)]
}

/// Times `{prefix}inverse_dynamics` and the regressor (as `regressor`) of `chain` at
/// [`state`], and with `forward` also `{prefix}mass_matrix` and `{prefix}forward_dynamics`.
fn chain_benches<const N: usize, const P: usize>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    prefix: &str,
    regressor: &str,
    chain: &SerialChain<N>,
    forward: bool,
) {
    let [q, qd, qdd] = state::<N>();
    g.bench_function(format!("{prefix}inverse_dynamics"), |b| {
        b.iter(|| chain.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    g.bench_function(regressor, |b| {
        b.iter(|| -> SMatrix<f64, N, P> {
            chain.regressor(black_box(&q), black_box(&qd), black_box(&qdd))
        })
    });
    if !forward {
        return;
    }
    let tau = chain.inverse_dynamics(&q, &qd, &qdd);
    g.bench_function(format!("{prefix}mass_matrix"), |b| {
        b.iter(|| chain.mass_matrix(black_box(&q)))
    });
    g.bench_function(format!("{prefix}forward_dynamics"), |b| {
        b.iter(|| chain.forward_dynamics(black_box(&q), black_box(&qd), black_box(&tau)))
    });
}

fn prrrp(c: &mut Criterion) {
    let chain = SerialChain::paper();
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    let bm = chain.base_model::<9>(&base).expect("9");
    let beta = bm.chain_base_values();
    let [q, qd, qdd] = state::<5>();
    let tau = chain.inverse_dynamics(&q, &qd, &qdd);
    let mut g = c.benchmark_group("prrrp");
    chain_benches::<5, 50>(&mut g, "chain_", "chain_regressor_5x50", &chain, true);
    g.bench_function("chain_base_regressor_5x9", |b| {
        b.iter(|| bm.regressor(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    g.bench_function("base_model_forward_dynamics", |b| {
        b.iter(|| bm.forward_dynamics(black_box(&q), black_box(&qd), black_box(&tau), &beta))
    });
    g.bench_function("base_model_inverse_dynamics", |b| {
        b.iter(|| bm.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd), &beta))
    });
    g.bench_function("base_model_forward_derivatives", |b| {
        b.iter(|| bm.forward_derivatives(black_box(&q), black_box(&qd), black_box(&tau), &beta))
    });
    g.bench_function("closed_form_inverse_dynamics", |b| {
        b.iter(|| model.inverse_dynamics(black_box(&q), black_box(&qd), black_box(&qdd), &lambda))
    });
    g.bench_function("closed_form_regressor_5x8", |b| {
        b.iter(|| model.regressor(black_box(&q), black_box(&qd), black_box(&qdd)))
    });
    g.finish();
}

/// The paper's arm as a chain in closed form (`closed_*`, what `SerialChain::paper()` and
/// `DynChain::paper()` evaluate) against the same chain by the recursive algorithms
/// (`recursive_*`): compile-time chain and base model, and the run-time chain, workspace
/// and base model the command line and the estimators use.
fn paper_closed_form(c: &mut Criterion) {
    let mut g = c.benchmark_group("paper_chain");
    let [q, qd, qdd] = state::<5>();
    let (sq, sqd, sqdd) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
    let (dq, dqd, dqdd) = (
        DVector::from_column_slice(sq),
        DVector::from_column_slice(sqd),
        DVector::from_column_slice(sqdd),
    );
    for (name, chain) in [
        ("closed", SerialChain::paper()),
        ("recursive", SerialChain::paper().recursive()),
    ] {
        chain_benches::<5, 50>(
            &mut g,
            &format!("{name}_"),
            &format!("{name}_regressor_5x50"),
            &chain,
            true,
        );
        let base = chain
            .base_parameters(&BaseOptions::default())
            .expect("analysis");
        let bm = chain.base_model::<9>(&base).expect("9");
        g.bench_function(format!("{name}_base_regressor_5x9"), |b| {
            b.iter(|| bm.regressor(black_box(&q), black_box(&qd), black_box(&qdd)))
        });
        let dynamic = chain.to_dyn();
        let mut ws = dynamic.workspace();
        let mut tau = vec![0.0; 5];
        g.bench_function(format!("{name}_dyn_inverse_dynamics_into"), |b| {
            b.iter(|| {
                dynamic.inverse_dynamics_into(
                    &mut ws,
                    black_box(sq),
                    black_box(sqd),
                    black_box(sqdd),
                    &mut tau,
                )
            })
        });
        let dm = dynamic.base_model(&base).expect("same chain");
        let mut dws = dm.workspace();
        let mut phi = DMatrix::zeros(5, base.count());
        g.bench_function(format!("{name}_dyn_base_regressor_into"), |b| {
            b.iter(|| {
                dm.regressor_into(
                    &mut dws,
                    black_box(&dq),
                    black_box(&dqd),
                    black_box(&dqdd),
                    &mut phi,
                )
            })
        });
        let beta = dm.chain_base_values().clone();
        let mut out = DVector::zeros(5);
        g.bench_function(format!("{name}_dyn_base_inverse_dynamics_into"), |b| {
            b.iter(|| {
                dm.inverse_dynamics_into(
                    &mut dws,
                    black_box(&dq),
                    black_box(&dqd),
                    black_box(&dqdd),
                    &beta,
                    &mut out,
                )
            })
        });
    }
    g.finish();
}

fn puma(c: &mut Criterion) {
    let chain = SerialChain::puma560();
    let mut g = c.benchmark_group("puma560");
    chain_benches::<6, 60>(&mut g, "", "regressor_6x60", &chain, true);
    g.finish();
    let mut g = c.benchmark_group("puma560_batch");
    g.sample_size(10);
    g.bench_function("base_parameters", |b| {
        b.iter(|| chain.base_parameters(&BaseOptions::default()))
    });
    g.finish();
}

fn urdf_group<const N: usize, const P: usize>(c: &mut Criterion, name: &str, chain: &DynChain) {
    let fixed = chain.to_fixed::<N>().expect("joint count");
    let [q, qd, qdd] = state::<N>();
    let mut ws = chain.workspace();
    let mut tau = vec![0.0; N];
    let mut y = vec![0.0; N * chain.num_params()];
    let mut g = c.benchmark_group(name);
    chain_benches::<N, P>(&mut g, "", "regressor", &fixed, false);
    let x = || black_box([q.as_slice(), qd.as_slice(), qdd.as_slice()]);
    g.bench_function("dyn_inverse_dynamics_into", |b| {
        b.iter(|| {
            let [q, qd, qdd] = x();
            chain.inverse_dynamics_into(&mut ws, q, qd, qdd, &mut tau)
        })
    });
    g.bench_function("dyn_regressor_into", |b| {
        b.iter(|| {
            let [q, qd, qdd] = x();
            chain.regressor_row_major_into(&mut ws, q, qd, qdd, &mut y)
        })
    });
    g.finish();
}

fn urdf_robots(c: &mut Criterion) {
    let Some(dir) = robots_dir() else {
        eprintln!("example-robot-data not found: URDF benchmarks skipped");
        return;
    };
    let load = |rel: &str, tip: Option<&str>| {
        let opts = UrdfOptions {
            tip: tip.map(String::from),
            ..UrdfOptions::default()
        };
        DynChain::from_urdf_file(dir.join(rel), &opts).expect("example-robot-data URDF")
    };
    let panda = load("panda_description/urdf/panda.urdf", Some("panda_link8"));
    urdf_group::<7, 70>(c, "urdf_panda", &panda);
    let ur5 = load("ur_description/urdf/ur5_robot.urdf", None);
    urdf_group::<6, 60>(c, "urdf_ur5", &ur5);
    let kinova = load("kinova_description/robots/kinova.urdf", None);
    urdf_group::<6, 60>(c, "urdf_kinova", &kinova);
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = prrrp, paper_closed_form, puma, urdf_robots
}
criterion_main!(benches);
