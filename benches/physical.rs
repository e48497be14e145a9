//! Physically consistent identification of the Panda-like 7R arm (viscous, Coulomb and
//! offset friction: 91 standard parameters) on 2000 noisy samples of a Fourier
//! excitation (τ noise σ = 0.5 N·m, seeded). Setup outside the timed closures.
//!
//! - `chain7_physical_2000`: the whole call, from samples to estimate (regressor
//!   stacking, QR of the data, base-parameter analysis, interior-point solve).
//! - `chain7_physical_2000_solve`: the solve alone on a prebuilt [`PhysicalProblem`].

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;

use criterion::{criterion_group, criterion_main, Criterion};
use dyn_support::{exact_record, panda_like, DynFourier};
use prrrp_core::{identify_physical, PhysicalConfig, PhysicalProblem};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::hint::black_box;

fn physical(c: &mut Criterion) {
    let chain = panda_like();
    let rec = exact_record(&chain, &DynFourier::seeded(21, 7, 1.0), 2000, 0.01);
    let flat = |v: &[prrrp_core::nalgebra::DVector<f64>]| -> Vec<f64> {
        v.iter().flat_map(|x| x.iter().copied()).collect()
    };
    let (q, qd, qdd, mut tau) = (flat(&rec.q), flat(&rec.qd), flat(&rec.qdd), flat(&rec.tau));
    let mut rng = StdRng::seed_from_u64(1);
    let noise = Normal::new(0.0, 0.5).unwrap();
    for t in &mut tau {
        *t += noise.sample(&mut rng);
    }
    let cfg = PhysicalConfig::default();
    let mut group = c.benchmark_group("physical");
    group.sample_size(10);
    group.bench_function("chain7_physical_2000", |b| {
        b.iter(|| {
            black_box(identify_physical(&chain, &q, &qd, &qdd, &tau, &cfg).unwrap());
        })
    });
    let problem = PhysicalProblem::new(&chain, &q, &qd, &qdd, &tau, &cfg).unwrap();
    group.bench_function("chain7_physical_2000_solve", |b| {
        b.iter(|| black_box(problem.solve(&cfg).unwrap()))
    });
    group.finish();
}

criterion_group!(benches, physical);
criterion_main!(benches);
