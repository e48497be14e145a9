//! `OnlineIdentifier::update` allocates nothing after construction (a counting global
//! allocator; the count is per thread, so parallel tests do not interfere): every
//! method, the payload mode, with forgetting and change detection, over a log whose
//! payload changes mid-run (so that the covariance opening runs too).

mod alloc_support;
mod dyn_support;

use alloc_support::allocations;
use dyn_support::{panda_like, DynFourier};
use prrrp_core::{
    identify, inertial_parameters, BaseOptions, CoulombSearch, DynDataset, Method, OnlineConfig,
    OnlineIdentifier, OnlineMethod,
};

#[test]
fn update_allocates_nothing() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let f = DynFourier::seeded(5, 7, 1.0);
    let mut inertial = chain.inertial().to_vec();
    let pi = inertial_parameters(2.0, [0.0, 0.0, 0.05], [3e-3, 0.0, 3e-3, 0.0, 0.0, 2e-3]);
    for k in 0..10 {
        inertial[6][k] += pi[k];
    }
    let with = chain.clone().with_inertial(inertial).unwrap();
    let rate = 500.0;
    let rows: Vec<_> = (0..(8.0 * rate) as usize)
        .map(|k| {
            let t = k as f64 / rate;
            let [q, qd, qdd] = f.eval(t);
            let c = if t >= 5.0 { &with } else { &chain };
            let tau = c
                .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
                .unwrap();
            // A slight deterministic noise so that the noise levels are not at the floor.
            let tau: Vec<f64> = tau
                .iter()
                .enumerate()
                .map(|(j, v)| v + 0.02 * ((k * 7 + j) as f64 * 1.3).sin())
                .collect();
            (t, q.as_slice().to_vec(), tau, qd.as_slice().to_vec())
        })
        .collect();
    let flat = |i: usize| -> Vec<f64> {
        rows.iter()
            .take(2000)
            .flat_map(|r| match i {
                0 => r.1.clone(),
                1 => r.3.clone(),
                _ => r.2.clone(),
            })
            .collect()
    };
    let qdd: Vec<f64> = (0..2000)
        .flat_map(|k| f.eval(k as f64 / rate)[2].as_slice().to_vec())
        .collect();
    let t: Vec<f64> = rows.iter().take(2000).map(|r| r.0).collect();
    let ds = DynDataset::new(7, t, flat(0), flat(1), qdd, flat(2)).unwrap();
    let prior = identify(
        &chain,
        &base,
        &ds,
        &Method::parse("wls").unwrap(),
        serde_json::json!({}),
    )
    .unwrap();
    let cases = [
        (OnlineMethod::Rls, false, Some(1.0), true),
        (OnlineMethod::Rls, false, Some(1.0), false),
        (OnlineMethod::Ekf, false, Some(5.0), true),
        (OnlineMethod::Adaline, false, None, true),
        (OnlineMethod::Hopfield, false, None, true),
        (OnlineMethod::Rls, true, None, true),
        (OnlineMethod::Ekf, true, None, true),
        (OnlineMethod::Ekf, true, Some(5.0), true),
    ];
    for (method, payload, forgetting, directional) in cases {
        for velocities in [false, true] {
            let cfg = OnlineConfig {
                method,
                payload,
                forgetting,
                directional,
                ..Default::default()
            };
            let mut id = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
            let qd = |r: &(f64, Vec<f64>, Vec<f64>, Vec<f64>)| velocities.then(|| r.3.clone());
            // Warm-up: the first rows size nothing, but the causal filters get ready.
            for r in rows.iter().take(200) {
                id.update(r.0, &r.1, &r.2, qd(r).as_deref()).unwrap();
            }
            let inputs: Vec<_> = rows.iter().skip(200).map(|r| (r, qd(r))).collect();
            let before = allocations();
            let mut changes = 0;
            for (r, v) in &inputs {
                let u = id.update(r.0, &r.1, &r.2, v.as_deref()).unwrap();
                changes += u.change as usize;
            }
            let n = allocations() - before;
            assert_eq!(
                n, 0,
                "{method:?} payload={payload} forgetting={forgetting:?} velocities={velocities}: \
                 {n} allocations ({changes} changes)"
            );
        }
    }
    // From no knowledge with the online choice of the Coulomb scale: the candidates' rows,
    // the scoring and the hand-over at the choice (3 s, inside the timed rows).
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        let cfg = OnlineConfig {
            method,
            coulomb_search: Some(CoulombSearch { from: 1.0, at: 3.0 }),
            ..Default::default()
        };
        let mut id = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        for r in rows.iter().take(200) {
            id.update(r.0, &r.1, &r.2, None).unwrap();
        }
        let before = allocations();
        for r in rows.iter().skip(200) {
            id.update(r.0, &r.1, &r.2, None).unwrap();
        }
        let n = allocations() - before;
        assert_eq!(
            n, 0,
            "{method:?} with the Coulomb scale search: {n} allocations"
        );
        let chosen = &id.settings_json()["coulomb_search"]["chosen"];
        assert!(chosen.is_number(), "no choice was made: {chosen}");
    }
}
