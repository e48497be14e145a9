//! Payload identification and drive gains against the physics: data of the PUMA 560 made
//! by recursive Newton–Euler with the payload added to the tip link's inertials (a path
//! that never forms the regressor), a known arm, and currents τ/K.

use prrrp_core::{
    identify, identify_drive_gains, identify_payload, inertial_parameters, project_physical,
    BaseOptions, DriveGainSettings, DynChain, DynDataset, FrictionModel, IdentifiedModel,
    LsSettings, Method, Payload, PayloadSettings, PrrrpError, SerialChain,
};
use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const N: usize = 6;

fn puma() -> DynChain {
    SerialChain::puma560()
        .to_dyn()
        .with_friction(FrictionModel::all(), vec![[0.3, 0.8, -0.1]; N])
        .unwrap()
}

/// The chain with the payload rigidly merged into its last link.
fn loaded_chain(chain: &DynChain, payload: &[f64; 10]) -> DynChain {
    let mut inertial = chain.inertial().to_vec();
    for (a, b) in inertial[N - 1].iter_mut().zip(payload) {
        *a += b;
    }
    chain.clone().with_inertial(inertial).unwrap()
}

/// A smooth multi-sine trajectory with exact derivatives and the chain's torques.
fn run(chain: &DynChain, samples: usize, phase: f64) -> DynDataset {
    let (mut t, mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![], vec![]);
    for k in 0..samples {
        let time = k as f64 * 0.01;
        t.push(time);
        let (mut qs, mut qds, mut qdds) = ([0.0; N], [0.0; N], [0.0; N]);
        for j in 0..N {
            for h in 1..=3 {
                let w = 2.0 * std::f64::consts::PI * 0.2 * h as f64 * (1.0 + 0.07 * j as f64);
                let a = 0.6 / h as f64;
                let ph = phase + 1.3 * j as f64 + 0.7 * h as f64;
                qs[j] += a * (w * time + ph).sin();
                qds[j] += a * w * (w * time + ph).cos();
                qdds[j] -= a * w * w * (w * time + ph).sin();
            }
        }
        tau.extend(chain.inverse_dynamics(&qs, &qds, &qdds).unwrap());
        q.extend(qs);
        qd.extend(qds);
        qdd.extend(qdds);
    }
    DynDataset::new(N, t, q, qd, qdd, tau).unwrap()
}

fn arm_model(chain: &DynChain, data: &DynDataset) -> IdentifiedModel {
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let ls = Method::Wls(LsSettings::default());
    identify(chain, &base, data, &ls, serde_json::Value::Null).unwrap()
}

fn truth() -> [f64; 10] {
    inertial_parameters(
        2.8,
        [0.03, -0.02, 0.08],
        [0.009, 0.0005, 0.008, -0.0003, 0.0002, 0.006],
    )
}

#[test]
fn payload_of_exact_data_is_recovered_and_predicts() {
    let chain = puma();
    let arm = arm_model(&chain, &run(&chain, 1500, 0.0));
    let truth = truth();
    let loaded = run(&loaded_chain(&chain, &truth), 1500, 0.0);
    let model = identify_payload(&arm, &loaded, &PayloadSettings::default()).unwrap();
    let p = model.payload.as_ref().unwrap();
    for (k, (a, b)) in p.parameters.iter().zip(&truth).enumerate() {
        assert!((a - b).abs() < 1e-6 * (1.0 + b.abs()), "π[{k}]: {a} vs {b}");
    }
    assert!(p.identifiable.mass && p.identifiable.com.iter().all(|x| *x));
    // The arm + payload model predicts the loaded arm, also after a JSON round trip.
    let back = IdentifiedModel::from_json(&model.to_json().unwrap()).unwrap();
    let pred = back.predict(loaded.q(), loaded.qd(), loaded.qdd()).unwrap();
    let worst = pred
        .iter()
        .zip(loaded.tau())
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-6, "{worst}");
    // A given mass: the rest is fitted, the mass is the one given.
    let s = PayloadSettings {
        mass: Some(2.8),
        ..Default::default()
    };
    let fixed = identify_payload(&arm, &loaded, &s).unwrap();
    let p = fixed.payload.unwrap();
    assert_eq!(p.parameters[0], 2.8);
    assert!(p.mass_given && (p.com.unwrap()[2] - 0.08).abs() < 1e-6);
}

#[test]
fn a_different_trajectory_and_drifted_friction_are_absorbed() {
    // Arm identified on one run, payload on a different motion whose friction offsets
    // drifted: the re-fitted friction takes the drift, the payload stays exact.
    let chain = puma();
    let arm = arm_model(&chain, &run(&chain, 1500, 0.0));
    let drifted = chain
        .clone()
        .with_friction(FrictionModel::all(), vec![[0.33, 0.9, -0.3]; N])
        .unwrap();
    let truth = truth();
    let loaded = run(&loaded_chain(&drifted, &truth), 1500, 2.0);
    let model = identify_payload(&arm, &loaded, &PayloadSettings::default()).unwrap();
    let p = model.payload.as_ref().unwrap();
    assert!((p.mass - 2.8).abs() < 1e-6, "{}", p.mass);
    // Without re-fitting friction the drift stays unexplained.
    let s = PayloadSettings {
        refit_friction: false,
        ..Default::default()
    };
    let stale = identify_payload(&arm, &loaded, &s).unwrap();
    let worst = |r: &[f64]| r.iter().fold(0.0f64, |a, b| a.max(*b));
    assert!(
        worst(&model.residual_rms) < 1e-6,
        "{:?}",
        model.residual_rms
    );
    // The offsets moved by 0.2 N·m: a stale friction model leaves about that unexplained.
    assert!(
        worst(&stale.residual_rms) > 0.05,
        "{:?}",
        stale.residual_rms
    );
}

#[test]
fn no_motion_and_bad_settings_are_typed_errors() {
    let chain = puma();
    let arm = arm_model(&chain, &run(&chain, 600, 0.0));
    let loaded = run(&loaded_chain(&chain, &truth()), 600, 0.0);
    let s = PayloadSettings {
        mass: Some(-1.0),
        ..Default::default()
    };
    assert!(matches!(
        identify_payload(&arm, &loaded, &s),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let s = PayloadSettings {
        link: Some(N),
        ..Default::default()
    };
    assert!(identify_payload(&arm, &loaded, &s).is_err());
    // The arm at rest in one pose: the payload's mass is not seen apart from its moments.
    let rest = {
        let one = |d: &[f64]| d[..N].repeat(100);
        DynDataset::new(
            N,
            (0..100).map(|k| k as f64 * 0.01).collect(),
            one(loaded.q()),
            vec![0.0; N * 100],
            vec![0.0; N * 100],
            one(loaded.tau()),
        )
        .unwrap()
    };
    assert!(matches!(
        identify_payload(&arm, &rest, &PayloadSettings::default()),
        Err(PrrrpError::RankDeficient { .. })
    ));
}

#[test]
fn projection_keeps_a_physical_payload_and_fixes_a_broken_one() {
    let good = truth();
    let mut metric = vec![0.0; 100];
    for k in 0..10 {
        metric[k * 11] = 1.0;
    }
    assert_eq!(project_physical(&good, &metric, false).unwrap(), good);
    let mut bad = good;
    bad[9] += 0.05; // Izz far above Ixx + Iyy about the COM
    assert!(Payload::from_parameters("t", 0, bad, None).is_err());
    let fixed = project_physical(&bad, &metric, true).unwrap();
    assert!(Payload::from_parameters("t", 0, fixed, None).is_ok());
}

#[test]
fn drive_gains_of_exact_currents_are_recovered() {
    let chain = puma();
    let gains = [12.0, 13.5, 11.0, 9.0, 8.5, 10.0];
    let to_currents = |d: &DynDataset| {
        let cur = d.tau().iter().enumerate().map(|(k, t)| t / gains[k % N]);
        with_efforts(d, cur.collect())
    };
    let unloaded = to_currents(&run(&chain, 1500, 0.0));
    let loaded = to_currents(&run(&loaded_chain(&chain, &truth()), 1500, 0.0));
    let start = arm_model(&chain, &unloaded);
    let fit =
        identify_drive_gains(&start, &unloaded, &loaded, &DriveGainSettings::new(2.8)).unwrap();
    let g = fit.model.drive_gains.as_ref().unwrap();
    for (m, (a, b)) in g.values.iter().zip(&gains).enumerate() {
        assert!((a / b - 1.0).abs() < 1e-6, "K{}: {a} vs {b}", m + 1);
    }
    // The arm in torque units predicts the unloaded run's torques.
    let tau = run(&chain, 1500, 0.0);
    let pred = fit.model.predict(tau.q(), tau.qd(), tau.qdd()).unwrap();
    let worst = pred
        .iter()
        .zip(tau.tau())
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-5, "{worst}");
    assert!((fit.payload.com.unwrap()[0] - 0.03).abs() < 1e-6);
}

/// Currents τ/K of a run plus white noise of `rel` × each joint's current RMS (seeded).
fn noisy_currents(d: &DynDataset, gains: &[f64; N], rel: f64, rng: &mut ChaCha8Rng) -> DynDataset {
    let mut rms = [0.0; N];
    for (k, t) in d.tau().iter().enumerate() {
        rms[k % N] += (t / gains[k % N]).powi(2) / d.len() as f64;
    }
    let unit = Normal::new(0.0, 1.0).unwrap();
    let cur: Vec<f64> = d
        .tau()
        .iter()
        .enumerate()
        .map(|(k, t)| t / gains[k % N] + rel * rms[k % N].sqrt() * unit.sample(rng))
        .collect();
    with_efforts(d, cur)
}

/// `d` with its efforts column (torques or currents, row-major) replaced by `effort`.
fn with_efforts(d: &DynDataset, effort: Vec<f64>) -> DynDataset {
    d.with_tau(effort).unwrap()
}

#[test]
fn drive_gains_are_not_biased_by_noisy_currents() {
    // The bias check of Gautier & Briot's protocol: with the noisy currents in the
    // regressor, least squares shrinks the gains (errors in variables); the instrumental
    // variables do not. Same trajectory without and with the payload, as the protocol has.
    let chain = puma();
    let gains = [12.0, 13.5, 11.0, 9.0, 8.5, 10.0];
    let mut rng = ChaCha8Rng::seed_from_u64(27);
    let unloaded = noisy_currents(&run(&chain, 3000, 0.0), &gains, 0.3, &mut rng);
    let loaded = noisy_currents(
        &run(&loaded_chain(&chain, &truth()), 3000, 0.0),
        &gains,
        0.3,
        &mut rng,
    );
    let start = arm_model(&chain, &unloaded);
    let fit =
        identify_drive_gains(&start, &unloaded, &loaded, &DriveGainSettings::new(2.8)).unwrap();
    let g = fit.model.drive_gains.as_ref().unwrap();
    let err = |k: &[f64]| -> Vec<f64> {
        k.iter()
            .zip(&gains)
            .map(|(a, b)| 100.0 * (a / b - 1.0))
            .collect()
    };
    let (iv, naive) = (err(&g.values), err(&fit.naive_gains));
    eprintln!(
        "gain errors (%): iv {iv:.2?}, naive {naive:.2?}, σ {:.3?}",
        g.sigma
    );
    for (m, e) in iv.iter().enumerate() {
        if g.identifiable[m] {
            assert!(e.abs() < 2.0, "K{}: {e:.2} % (iv)", m + 1);
        }
    }
    // The gains the payload's weight loads (shoulder and elbow) are determined.
    assert!(
        g.identifiable[1] && g.identifiable[2],
        "{:?}",
        g.identifiable
    );
    let worst_naive = naive.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(worst_naive > 2.0, "naive least squares {naive:.2?}");
}
