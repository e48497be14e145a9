//! Per-sample cost of `OnlineIdentifier::update` on a Panda-like 7R chain with viscous,
//! Coulomb and offset friction (64 base parameters): one raw row in (t, q, τ), causal
//! filtering, the one-step-ahead prediction, the change test and the estimator's update
//! all included. Rows of a seeded Fourier motion at 1 kHz with torque noise, one period
//! (10 s) precomputed and replayed with increasing time stamps; each identifier warmed up
//! over one period before timing. Target (issue 28): ≤ 20 µs per sample for RLS and EKF.

#[path = "../tests/dyn_support/mod.rs"]
mod dyn_support;

use criterion::{criterion_group, criterion_main, Criterion};
use dyn_support::{panda_like, DynFourier};
use prrrp_core::{BaseOptions, IdentifiedModel, OnlineConfig, OnlineIdentifier, OnlineMethod};
use std::hint::black_box;

const RATE: f64 = 1000.0;
const ROWS: usize = 10_000;

fn online(c: &mut Criterion) {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let model = chain.base_model(&base).unwrap();
    let f = DynFourier::seeded(5, 7, 0.5);
    let rows: Vec<(Vec<f64>, Vec<f64>)> = (0..ROWS)
        .map(|k| {
            let t = k as f64 / RATE;
            let [q, qd, qdd] = f.eval(t);
            let tau = chain
                .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
                .unwrap();
            // Deterministic "noise" of ~0.03 N·m, so that the noise levels are realistic.
            let tau = tau
                .iter()
                .enumerate()
                .map(|(j, v)| v + 0.03 * ((k * 7 + j) as f64 * 2.1).sin())
                .collect();
            (q.as_slice().to_vec(), tau)
        })
        .collect();
    let truth = model.chain_base_values().as_slice().to_vec();
    let b = truth.len();
    let cov: Vec<f64> = (0..b * b)
        .map(|i| {
            if i % (b + 1) == 0 {
                (0.05 * truth[i / b].abs()).max(1e-4).powi(2)
            } else {
                0.0
            }
        })
        .collect();
    let prior = IdentifiedModel::new(
        &chain,
        &base,
        truth,
        None,
        Some(cov),
        None,
        vec![0.03; 7],
        "manual",
        serde_json::json!({}),
        serde_json::json!({}),
    )
    .unwrap();
    for (name, method, payload) in [
        ("online7_rls_update", OnlineMethod::Rls, false),
        ("online7_ekf_update", OnlineMethod::Ekf, false),
        ("online7_rls_payload_update", OnlineMethod::Rls, true),
        ("online7_ekf_payload_update", OnlineMethod::Ekf, true),
    ] {
        let cfg = OnlineConfig {
            method,
            payload,
            ..Default::default()
        };
        let mut id = if method == OnlineMethod::Rls && !payload {
            OnlineIdentifier::new(&chain, &base, cfg).unwrap()
        } else {
            OnlineIdentifier::with_prior(&prior, cfg).unwrap()
        };
        let mut k = 0usize;
        let mut feed = |id: &mut OnlineIdentifier| {
            let (q, tau) = &rows[k % ROWS];
            let t = k as f64 / RATE;
            k += 1;
            id.update(black_box(t), black_box(q), black_box(tau), None)
                .unwrap()
                .prediction[0]
        };
        for _ in 0..ROWS {
            feed(&mut id);
        }
        c.bench_function(name, |bch| bch.iter(|| black_box(feed(&mut id))));
    }
}

criterion_group!(benches, online);
criterion_main!(benches);
