//! The online identifier against physics: torques from the chain's recursive Newton–Euler
//! inverse dynamics (with a payload added to the tip link's inertial parameters, the
//! way a gripped part changes the arm), noisy like a real log; never against the
//! identifier's own regressor.

mod dyn_support;

use dyn_support::{panda_like, DynFourier};
use prrrp_core::*;
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

struct Log {
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    tau: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
}

/// A 2.5 kg part, centre of mass 8 cm out along the tip's z, a little off-axis.
fn part() -> [f64; 10] {
    inertial_parameters(2.5, [0.02, -0.03, 0.08], [4e-3, 0.0, 4e-3, 0.0, 0.0, 3e-3])
}

/// `chain` with `pi` added to its tip link.
fn loaded(chain: &DynChain, pi: &[f64; 10]) -> DynChain {
    let mut inertial = chain.inertial().to_vec();
    let n = inertial.len();
    for k in 0..10 {
        inertial[n - 1][k] += pi[k];
    }
    chain.clone().with_inertial(inertial).unwrap()
}

/// `dur` s at `rate` Hz of a seeded Fourier motion of `chain`, the arm becoming `with`
/// (e.g. [`loaded`]) at `grip` s (if any); noise σ (rad, N·m) on q and τ (seeded).
fn log(
    chain: &DynChain,
    with: &DynChain,
    seed: u64,
    dur: f64,
    rate: f64,
    grip: Option<f64>,
    noise: (f64, f64),
) -> Log {
    let f = DynFourier::seeded(seed, chain.dof(), 1.0);
    let mut rng = StdRng::seed_from_u64(seed + 100);
    let (nq, nt) = (
        Normal::new(0.0, noise.0).unwrap(),
        Normal::new(0.0, noise.1).unwrap(),
    );
    let mut out = Log {
        t: vec![],
        q: vec![],
        tau: vec![],
        qd: vec![],
        qdd: vec![],
    };
    for k in 0..(dur * rate) as usize {
        let t = k as f64 / rate;
        let [q, qd, qdd] = f.eval(t);
        let c = if grip.is_some_and(|g| t >= g) {
            with
        } else {
            chain
        };
        let tau = c
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .unwrap();
        out.t.push(t);
        out.q
            .push(q.iter().map(|v| v + nq.sample(&mut rng)).collect());
        out.tau
            .push(tau.iter().map(|v| v + nt.sample(&mut rng)).collect());
        out.qd.push(qd.as_slice().to_vec());
        out.qdd.push(qdd.as_slice().to_vec());
    }
    out
}

/// Per joint: RMS of the model's torque error on `val` over the RMS torque.
fn rel_error(m: &IdentifiedModel, val: &Log) -> Vec<f64> {
    let n = val.q[0].len();
    let (mut e, mut r) = (vec![0.0; n], vec![0.0; n]);
    for k in 0..val.t.len() {
        let tp = m.predict(&val.q[k], &val.qd[k], &val.qdd[k]).unwrap();
        for j in 0..n {
            e[j] += (tp[j] - val.tau[k][j]).powi(2);
            r[j] += val.tau[k][j].powi(2);
        }
    }
    (0..n).map(|j| (e[j] / r[j]).sqrt()).collect()
}

/// The Panda-like arm, its base parameters and [`prior_model`] of it.
fn panda_with_prior() -> (DynChain, BaseParameters, IdentifiedModel) {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let prior = prior_model(&chain, &base);
    (chain, base, prior)
}

fn prior_model(chain: &DynChain, base: &BaseParameters) -> IdentifiedModel {
    let un = log(chain, chain, 11, 20.0, 200.0, None, (1e-5, 0.05));
    let flat = |v: &Vec<Vec<f64>>| v.iter().flatten().copied().collect::<Vec<f64>>();
    let ds = DynDataset::new(
        chain.dof(),
        un.t.clone(),
        flat(&un.q),
        flat(&un.qd),
        flat(&un.qdd),
        flat(&un.tau),
    )
    .unwrap();
    identify(
        chain,
        base,
        &ds,
        &Method::parse("wls").unwrap(),
        serde_json::json!({}),
    )
    .unwrap()
}

/// What one run over a log with a part gripped at `grip` gives: the times of detected
/// changes, the per-joint error on `val` 3 s after the grip and at the end, the payload.
struct Tracked {
    changes: Vec<f64>,
    after3: Vec<f64>,
    end: Vec<f64>,
    payload: Option<serde_json::Value>,
}

fn track(method: OnlineMethod, payload: bool) -> Tracked {
    let (chain, base, prior) = panda_with_prior();
    let grip = GRIP;
    let gripped = loaded(&chain, &part());
    let lg = log(&chain, &gripped, 5, 24.0, 500.0, Some(grip), (1e-5, 0.05));
    let val = log(&chain, &gripped, 21, 10.0, 100.0, Some(0.0), (0.0, 0.0));
    let cfg = OnlineConfig {
        method,
        payload,
        ..Default::default()
    };
    let mut id = if payload {
        OnlineIdentifier::with_prior(&prior, cfg).unwrap()
    } else {
        OnlineIdentifier::new(&chain, &base, cfg).unwrap()
    };
    let out = follow(&mut id, &lg, &val);
    eprintln!(
        "{method:?} payload={payload}: changes at {:?}\n  +3 s {:.4?}\n  end {:.4?}\n  payload mass {:?} ± {:?}",
        out.changes,
        out.after3,
        out.end,
        out.payload.as_ref().map(|p| p["mass"].clone()),
        out.payload.as_ref().map(|p| p["mass_sigma"].clone()),
    );
    out
}

const GRIP: f64 = 12.0;

/// `id` over the whole of `lg`: the times of its change alarms and its model's errors on
/// `val` 3 s after the grip and at the end (and its payload, in payload mode).
fn follow(id: &mut OnlineIdentifier, lg: &Log, val: &Log) -> Tracked {
    let mut after3 = None;
    let mut changes = vec![];
    for k in 0..lg.t.len() {
        let u = id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
        if u.change {
            changes.push(lg.t[k]);
        }
        if after3.is_none() && lg.t[k] >= GRIP + 3.0 {
            after3 = Some(id.estimate().unwrap());
        }
    }
    Tracked {
        changes,
        after3: rel_error(&after3.unwrap(), val),
        end: rel_error(&id.estimate().unwrap(), val),
        payload: id.payload_summary(),
    }
}

/// The grip is detected within a second of it and never before.
fn detected(r: &Tracked) {
    assert!(
        r.changes.iter().any(|&t| (GRIP..GRIP + 1.0).contains(&t)),
        "grip not detected: {:?}",
        r.changes
    );
    assert!(
        r.changes.iter().all(|&t| t >= GRIP),
        "false alarm before the grip: {:?}",
        r.changes
    );
}

fn below(errors: &[f64], bar: f64, what: &str) {
    for (j, e) in errors.iter().enumerate() {
        assert!(*e < bar, "{what}: joint {j}: {e} (bar {bar})");
    }
}

fn mass_within_5_percent(r: &Tracked) {
    let p = r.payload.as_ref().unwrap();
    let (m, s) = (
        p["mass"].as_f64().unwrap(),
        p["mass_sigma"].as_f64().unwrap(),
    );
    assert!((m / part()[0] - 1.0).abs() < 0.05, "mass {m}");
    assert!(s > 0.0 && s < 0.1 * part()[0], "σ {s}");
    assert_eq!(p["physical"], true);
}

/// Payload mode, RLS, on a prior of the bare arm (weighted least squares on another
/// log): a 2.5 kg part gripped 12 s into 24 s of a 500 Hz log (RNEA torques of the arm
/// with the part added to its tip link, sensor noise 0.05 N·m) is detected; 3 s after
/// the grip and at the end the model predicts a different loaded motion within 15 % and
/// 3 % of each joint's RMS torque (the bars of issue 28); the mass is within 5 %.
#[test]
fn payload_mode_rls_tracks_a_gripped_part() {
    tracks_a_gripped_part(OnlineMethod::Rls, true);
}

/// The bars of issue 28 with `method` on the gripped part, in payload mode (`payload`,
/// where the mass is checked too) or for the whole arm (see the tests).
fn tracks_a_gripped_part(method: OnlineMethod, payload: bool) {
    let r = track(method, payload);
    detected(&r);
    below(&r.after3, 0.15, &format!("{method:?}: 3 s after the grip"));
    below(&r.end, 0.03, &format!("{method:?}: at the end"));
    if payload {
        mass_within_5_percent(&r);
    }
}

/// As above with payload mode's EKF (a Kalman filter on the payload's parameters whose
/// measurement is the residual of the prior arm, `online/payload_ekf.rs`): the same
/// bars. The joint-state EKF it replaced ended at 0.026 kg on this log.
#[test]
fn payload_mode_ekf_tracks_a_gripped_part() {
    tracks_a_gripped_part(OnlineMethod::Ekf, true);
}

/// Payload mode with `method` on the arm of `prior` over the whole of `lg`.
fn payload_run(prior: &IdentifiedModel, method: OnlineMethod, lg: &Log) -> OnlineIdentifier {
    let cfg = OnlineConfig {
        method,
        payload: true,
        ..Default::default()
    };
    let mut id = OnlineIdentifier::with_prior(prior, cfg).unwrap();
    for k in 0..lg.t.len() {
        id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
    }
    id
}

/// An empty gripper stays empty: on 10 s of the bare arm, payload mode (RLS and the EKF)
/// ends below 25 g (1 % of the part) and physical; projecting the filter's own state onto
/// the rigid bodies would rectify the noise at π = 0 and ratchet the mass up.
#[test]
fn payload_mode_without_a_payload_stays_empty() {
    let (chain, _, prior) = panda_with_prior();
    let lg = log(&chain, &chain, 41, 10.0, 500.0, None, (1e-5, 0.05));
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        let id = payload_run(&prior, method, &lg);
        let m = id.parameters()[0];
        eprintln!(
            "{method:?}: empty gripper, mass {m} ± {}",
            id.sigma().unwrap()[0]
        );
        assert!((0.0..0.025).contains(&m), "{method:?}: mass {m}");
    }
}

/// The whole arm from no knowledge (RLS from β = 0; the EKF after 2 s of RLS): the grip
/// is detected and the model at the end predicts the loaded motion within 3 %.
#[test]
fn full_model_follows_a_gripped_part() {
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        let r = track(method, false);
        detected(&r);
        below(&r.end, 0.03, &format!("{method:?} at the end"));
    }
}

/// The whole arm from no knowledge, RLS, on a log of `chain` (seed `seed`, 24 s at 500 Hz,
/// noise 1e-5 rad and 0.05 N·m) that becomes `with` at 12 s: the detected changes and the
/// per-joint errors on a motion of `with` (another seed) 3 s after the change and at the
/// end.
fn whole_arm_rls(chain: &DynChain, with: &DynChain, seed: u64) -> Tracked {
    whole_arm(chain, with, seed, OnlineMethod::Rls, None)
}

/// As [`whole_arm_rls`] with `method`, from `prior` (a model of `chain`) if given.
fn whole_arm(
    chain: &DynChain,
    with: &DynChain,
    seed: u64,
    method: OnlineMethod,
    prior: Option<&IdentifiedModel>,
) -> Tracked {
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let lg = log(chain, with, seed, 24.0, 500.0, Some(GRIP), (1e-5, 0.05));
    let val = log(chain, with, seed + 16, 10.0, 100.0, Some(0.0), (0.0, 0.0));
    let cfg = OnlineConfig {
        method,
        ..Default::default()
    };
    let mut id = match prior {
        Some(p) => OnlineIdentifier::with_prior(p, cfg).unwrap(),
        None => OnlineIdentifier::new(chain, &base, cfg).unwrap(),
    };
    let out = follow(&mut id, &lg, &val);
    eprintln!(
        "whole-arm {method:?}, prior {}, seed {seed}: changes at {:?}\n  +3 s {:.4?}\n  end {:.4?}",
        prior.is_some(),
        out.changes,
        out.after3,
        out.end
    );
    out
}

/// Not a check: the table of the issue's numbers over arms, seeds, methods, with and
/// without a prior (`cargo test --release --test online survey -- --ignored --nocapture`;
/// `SURVEY="panda-like ekf"` keeps the arms it names, and only the EKF with "ekf").
#[test]
#[ignore = "a survey, prints a table"]
fn survey() {
    let panda = panda_like();
    let puma = SerialChain::puma560().to_dyn();
    let three = dyn_support::three_joint_urdf();
    let mut rows = vec![];
    let only = std::env::var("SURVEY").unwrap_or_default();
    for (name, chain, seeds) in [
        ("panda-like", &panda, vec![5, 6, 7, 8]),
        ("puma560", &puma, vec![5, 6]),
        ("three-joint", &three, vec![5, 6]),
    ] {
        if !only.is_empty() && !only.contains(name) {
            continue;
        }
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let prior = prior_model(chain, &base);
        let with = loaded(chain, &part());
        for seed in seeds {
            for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
                if only.contains("ekf") && method == OnlineMethod::Rls {
                    continue;
                }
                for p in [None, Some(&prior)] {
                    let r = whole_arm(chain, &with, seed, method, p);
                    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
                    let true_alarms = r
                        .changes
                        .iter()
                        .filter(|&&t| (GRIP..GRIP + 1.0).contains(&t))
                        .count();
                    let first = r.changes.iter().find(|&&t| t >= GRIP).map(|t| t - GRIP);
                    rows.push(format!(
                        "| {name} | {seed} | {} | {} | {:.1} % | {:.2} % | {true_alarms} | {} | {:?} |",
                        method.name(),
                        if p.is_some() { "prior" } else { "none" },
                        100.0 * max(&r.after3),
                        100.0 * max(&r.end),
                        r.changes.len() - true_alarms,
                        first.map(|d| (d * 1e3).round() / 1e3),
                    ));
                }
            }
        }
    }
    eprintln!("| arm | seed | method | prior | 3 s after (worst joint) | end | alarms in [grip, grip+1) | other alarms | first after grip (s) |");
    for r in rows {
        eprintln!("{r}");
    }
}

/// The defaults are not tuned to the Panda-like arm: on the PUMA 560 (6R, its wrist links
/// 0.09–0.82 kg, so the 2.5 kg part dominates the wrist) and on the three-joint URDF
/// fixture (tilted axes, a prismatic joint), two logs each, the whole-arm RLS from no
/// knowledge ends within 3 % after the grip (the rule before, every direction opened at
/// once: 20–31 % at the end on the PUMA's wrist). Not asserted: 3 s after the grip the
/// PUMA's wrist is still 22–36 % off (docs/design/online.md).
#[test]
fn full_model_rls_follows_a_grip_on_other_arms() {
    let puma = SerialChain::puma560().to_dyn();
    let three = dyn_support::three_joint_urdf();
    for chain in [&puma, &three] {
        for seed in [5, 6] {
            let r = whole_arm_rls(chain, &loaded(chain, &part()), seed);
            detected(&r);
            below(
                &r.end,
                0.03,
                &format!("{} joints, seed {seed}, at the end", chain.dof()),
            );
        }
    }
}

/// After a confirmed opening the whole-arm RLS from a prior may be far off for a while,
/// and its errors keep the change test firing. A look whose opening is dropped used to
/// return the estimator to its state at the alarm, throwing away the rows its unopened copy
/// had learned from: on the PUMA 560 (seed 5) look followed look and the estimate stayed
/// 410 % off on the wrist from 13 to 16 s, 3 s after the grip. The unopened copy now
/// replaces an estimator it predicted clearly better (`guard::Verdict::Resume`).
#[test]
fn dropped_looks_do_not_freeze_the_estimate() {
    let puma = SerialChain::puma560().to_dyn();
    let base = puma.base_parameters(&BaseOptions::default()).unwrap();
    let prior = prior_model(&puma, &base);
    let with = loaded(&puma, &part());
    for seed in [5, 6] {
        let r = whole_arm(&puma, &with, seed, OnlineMethod::Rls, Some(&prior));
        detected(&r);
        below(
            &r.after3,
            0.15,
            &format!("PUMA 560, seed {seed}, 3 s after"),
        );
        below(&r.end, 0.03, &format!("PUMA 560, seed {seed}, at the end"));
    }
}

/// The issue's bars for the whole arm relearned from no knowledge by RLS and by the EKF
/// (the part gripped at 12 s of 24 s, as above): 3 s after the grip the model predicts a
/// different loaded motion within 15 % of each joint's RMS torque, at the end within 3 %.
/// RLS's first opening after the change is along the tip link's directions; opening every
/// direction at once (the earlier rule) left three joints 18–21 % off 3 s after the grip.
/// After the alarm the running EKF hands over to its torque-regression warm-up (from its
/// own estimate and covariance, opened along the tip) and restarts from it; opened in
/// place instead, it was 202 % off 3 s after this grip.
#[test]
fn full_model_meets_the_issue_bars_after_a_grip() {
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        tracks_a_gripped_part(method, false);
    }
}

/// `chain` with joint 3's viscous and Coulomb friction four times as large (a dragging
/// brake).
fn friction_jump(chain: &DynChain) -> DynChain {
    let mut params = chain.friction_params().to_vec();
    params[2][0] *= 4.0;
    params[2][1] *= 4.0;
    chain
        .clone()
        .with_friction(chain.friction(), params)
        .unwrap()
}

/// A jump that is not a payload (joint 3's viscous and Coulomb friction four times as
/// large at 12 s, a dragging brake) is still followed by the whole-arm RLS: the opening
/// along the tip link's directions cannot explain it, a later look opens every direction,
/// and the model at the end predicts the changed arm within 3 % (the median over six
/// motions; none beyond 5 %). On one seed the end error moves by up to ±0.4 % with
/// anything that changes which rows the estimator takes after the opening (20 seeds,
/// with and without `guard::Verdict::Resume`: paired differences −0.38…+0.37 %, median
/// 0); seed 5 alone, the earlier form of this test, sat at 2.96 %.
#[test]
fn full_model_follows_a_friction_jump() {
    let chain = panda_like();
    let changed = friction_jump(&chain);
    let mut worst = vec![];
    for seed in 5..=10 {
        let r = whole_arm_rls(&chain, &changed, seed);
        assert!(
            r.changes.iter().all(|&t| t >= GRIP) && !r.changes.is_empty(),
            "seed {seed}: changes at {:?}",
            r.changes
        );
        below(&r.end, 0.05, &format!("seed {seed}, at the end"));
        worst.push(r.end.iter().copied().fold(0.0, f64::max));
    }
    worst.sort_by(f64::total_cmp);
    let median = 0.5 * (worst[2] + worst[3]);
    assert!(
        median < 0.03,
        "median of the worst joints {median} (bar 0.03)"
    );
}

/// A change the openings along the tip cannot explain, which the old rule never followed:
/// on seed 12 of the friction jump above every alarm opened along the tip again, 21 looks
/// were dropped in a row at 11–150 times the noise, and the model ended 74 % off. After
/// three such looks in a row the next alarm opens every direction
/// (`identifier::PERSISTENT_DROPS`). (Seed 11 is still missed: its three dropped looks
/// were not all above the alarm level; docs/design/online.md.)
#[test]
fn a_change_the_tip_does_not_explain_is_opened_in_every_direction() {
    let chain = panda_like();
    let changed = friction_jump(&chain);
    let r = whole_arm_rls(&chain, &changed, 12);
    assert!(
        r.changes.iter().all(|&t| t >= GRIP) && !r.changes.is_empty(),
        "changes at {:?}",
        r.changes
    );
    below(&r.end, 0.03, "seed 12, at the end");
}

/// A change of the link before the tip (the part clamped to link 6 instead of the tip
/// link 7) is detected, partly explained by the tip's directions, and caught by the second
/// look: the model at the end predicts the changed arm within 3 %. (A shorter look, over
/// the second hold-off with a 3× threshold, also catches this one; it does not catch the
/// part on link 5, docs/design/online.md.)
#[test]
fn full_model_follows_a_change_of_the_link_before_the_tip() {
    let chain = panda_like();
    let mut inertial = chain.inertial().to_vec();
    let pi = part();
    for k in 0..10 {
        inertial[5][k] += pi[k];
    }
    let changed = chain.clone().with_inertial(inertial).unwrap();
    let r = whole_arm_rls(&chain, &changed, 5);
    detected(&r);
    below(&r.end, 0.03, "at the end");
}

/// Changing the samples after row k0 changes nothing before it: predictions, estimates
/// and σ of rows < k0 are bit for bit those of the unchanged log (and the change does
/// show after k0, so the comparison can fail).
#[test]
fn future_samples_do_not_change_past_estimates() {
    let (chain, _, prior) = panda_with_prior();
    let a = log(&chain, &chain, 7, 4.0, 500.0, None, (1e-5, 0.05));
    let k0 = 1200;
    let mut b_tau = a.tau.clone();
    let mut b_q = a.q.clone();
    for k in k0..a.t.len() {
        for j in 0..7 {
            b_tau[k][j] += 3.0 * (k as f64 * 0.01 + j as f64).sin();
            b_q[k][j] += 1e-3;
        }
    }
    for (method, payload) in [
        (OnlineMethod::Rls, false),
        (OnlineMethod::Ekf, false),
        (OnlineMethod::Ekf, true),
    ] {
        let cfg = OnlineConfig {
            method,
            payload,
            ..Default::default()
        };
        let mut ia = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
        let mut ib = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
        let mut differs_after = false;
        for k in 0..a.t.len() {
            let ua = ia.update(a.t[k], &a.q[k], &a.tau[k], None).unwrap();
            let (pa, ea, sa) = (
                ua.prediction.to_vec(),
                ua.estimate.to_vec(),
                ua.sigma.map(|s| s.to_vec()),
            );
            let ub = ib.update(a.t[k], &b_q[k], &b_tau[k], None).unwrap();
            if k < k0 {
                assert_eq!(pa, ub.prediction, "{method:?} row {k}");
                assert_eq!(ea, ub.estimate, "{method:?} row {k}");
                assert_eq!(sa.as_deref(), ub.sigma, "{method:?} row {k}");
            } else if ea != ub.estimate {
                differs_after = true;
            }
        }
        assert!(
            differs_after,
            "{method:?}: the altered future changed nothing"
        );
    }
}

/// Irregular time stamps (0.5 to 3 ms) and repeated rows: a repeated row predicts and
/// changes nothing; the estimate still predicts a held-out motion within 3 %.
#[test]
fn repeated_rows_and_irregular_clocks() {
    let (chain, _, prior) = panda_with_prior();
    let f = DynFourier::seeded(9, 7, 1.0);
    let mut id = OnlineIdentifier::with_prior(&prior, OnlineConfig::default()).unwrap();
    let mut t = 0.0;
    let mut rng = StdRng::seed_from_u64(3);
    let jitter = rand_distr::Uniform::new(0.5e-3, 3e-3).unwrap();
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut repeats = 0;
    while t < 6.0 {
        let [q, qd, qdd] = f.eval(t);
        let tau: Vec<f64> = chain
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .unwrap()
            .iter()
            .map(|v| v + noise.sample(&mut rng))
            .collect();
        let u = id.update(t, q.as_slice(), &tau, None).unwrap();
        let after = u.estimate.to_vec();
        if (t * 1000.0) as usize % 7 == 3 {
            let again = id.update(t, q.as_slice(), &tau, None).unwrap();
            assert!(!again.updated);
            assert_eq!(again.estimate, after.as_slice());
            repeats += 1;
        }
        t += jitter.sample(&mut rng);
    }
    assert!(repeats > 0);
    assert_eq!(id.counts().2, repeats);
    let m = id.estimate().unwrap();
    let val = log(&chain, &chain, 21, 5.0, 100.0, None, (0.0, 0.0));
    for (j, e) in rel_error(&m, &val).iter().enumerate() {
        assert!(*e < 0.03, "joint {j}: {e}");
    }
}

/// Directional forgetting keeps what unexcited directions knew; exponential forgetting
/// blows their covariance up (P/νᵏ): 5 s of full excitation, then 15 s in which only
/// the first joint moves.
#[test]
fn directional_forgetting_does_not_wind_up() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let f = DynFourier::seeded(4, 7, 1.0);
    let rate = 500.0;
    let switch = 5.0;
    let [q_hold, _, _] = f.eval(switch);
    let mut growth = vec![];
    for directional in [true, false] {
        let cfg = OnlineConfig {
            forgetting: Some(2.0),
            directional,
            change_detection: None,
            ..Default::default()
        };
        let mut id = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        let mut at_switch = vec![];
        for k in 0..(20.0 * rate) as usize {
            let t = k as f64 / rate;
            let [mut q, mut qd, mut qdd] = f.eval(t);
            if t >= switch {
                for j in 1..7 {
                    q[j] = q_hold[j];
                    qd[j] = 0.0;
                    qdd[j] = 0.0;
                }
            }
            let tau = chain
                .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
                .unwrap();
            let u = id.update(t, q.as_slice(), &tau, None).unwrap();
            if at_switch.is_empty() && t >= switch {
                at_switch = u.sigma.unwrap().to_vec();
            }
        }
        let end = id.sigma().unwrap();
        let g = end
            .iter()
            .zip(&at_switch)
            .map(|(e, s)| e / s)
            .fold(0.0, f64::max);
        eprintln!("directional={directional}: largest σ growth ×{g:.3e}");
        growth.push(g);
    }
    // A direction nothing excites for 15 s with a memory T = 2 s: its variance grows by
    // exp(15/T), σ by exp(15/(2T)) ≈ 42 under exponential forgetting; directional
    // forgetting leaves it as it was.
    assert!(growth[0] < 3.0, "directional: σ grew ×{}", growth[0]);
    assert!(growth[1] > 10.0, "exponential: σ grew only ×{}", growth[1]);
}

/// The EKF from a least-squares prior runs from sample 0 (no divergence, no fall-back
/// to the warm-up) and predicts a held-out motion within 3 % of each joint's RMS torque
/// (the bar of `prrrp track`'s model).
#[test]
fn ekf_from_a_least_squares_prior_starts_at_once() {
    let (chain, _, prior) = panda_with_prior();
    let lg = log(&chain, &chain, 8, 6.0, 500.0, None, (1e-5, 0.05));
    let cfg = OnlineConfig {
        method: OnlineMethod::Ekf,
        ..Default::default()
    };
    let mut id = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
    assert!(id.ekf_running());
    for k in 0..lg.t.len() {
        id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
        assert!(id.ekf_running(), "left the filter at row {k}");
    }
    let m = id.estimate().unwrap();
    assert_eq!(m.settings["ekf_restarts"], 0);
    let val = log(&chain, &chain, 21, 5.0, 100.0, None, (0.0, 0.0));
    let (e, e0) = (rel_error(&m, &val), rel_error(&prior, &val));
    eprintln!("ekf {e:.4?}\nprior {e0:.4?}");
    for (j, e) in e.iter().enumerate() {
        assert!(*e < 0.03, "joint {j}: {e} (prior {})", e0[j]);
    }
}

/// A least-squares prior whose M(q, θ) is not positive definite (a PUMA 560's light
/// wrist from weighted least squares: indefinite at every row of the log) starts the
/// filter from its physically consistent projection: the filter runs from sample 0 to
/// the end without a fall-back to the warm-up (it used to fail at its first step and run
/// the RLS warm-up for the next 11–16 s), the start is recorded, and the estimate
/// predicts a held-out motion as well as the prior does.
#[test]
fn ekf_from_a_non_physical_prior_starts_from_its_projection() {
    let chain = SerialChain::puma560().to_dyn();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let prior = prior_model(&chain, &base);
    let lg = log(&chain, &chain, 8, 6.0, 500.0, None, (1e-5, 0.05));
    let cfg = OnlineConfig {
        method: OnlineMethod::Ekf,
        ..Default::default()
    };
    let mut id = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
    for k in 0..lg.t.len() {
        id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
        assert!(id.ekf_running(), "left the filter at row {k}");
    }
    let m = id.estimate().unwrap();
    assert_eq!(m.settings["ekf_restarts"], 0);
    let change = m.settings["ekf_start"]["max_relative_change"]
        .as_f64()
        .unwrap();
    assert!(change > 0.0, "{change}");
    let val = log(&chain, &chain, 21, 5.0, 100.0, None, (0.0, 0.0));
    let (e, e0) = (rel_error(&m, &val), rel_error(&prior, &val));
    let n = chain.dof();
    let rms: Vec<f64> = (0..n)
        .map(|j| (val.tau.iter().map(|t| t[j] * t[j]).sum::<f64>() / val.t.len() as f64).sqrt())
        .collect();
    eprintln!("ekf {e:.4?}\nprior {e0:.4?}\nrms {rms:.4?}\nchange {change}");
    for j in 0..n {
        let err = e[j] * rms[j];
        assert!(
            err < 0.03 * rms[j] || err < 0.05,
            "joint {j}: {err} N·m of {}",
            rms[j]
        );
    }
}

/// Bad input is a typed error and leaves the state as it was.
#[test]
fn bad_input_is_refused() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let bad = |cfg: OnlineConfig| OnlineIdentifier::new(&chain, &base, cfg);
    for cfg in [
        OnlineConfig {
            forgetting: Some(0.0),
            ..Default::default()
        },
        OnlineConfig {
            forgetting: Some(f64::NAN),
            ..Default::default()
        },
        OnlineConfig {
            step_size: 2.0,
            method: OnlineMethod::Adaline,
            ..Default::default()
        },
        OnlineConfig {
            cutoff_hz: -1.0,
            ..Default::default()
        },
        OnlineConfig {
            ekf_noise: 0.0,
            ..Default::default()
        },
        OnlineConfig {
            payload: true,
            ..Default::default()
        },
        OnlineConfig {
            initial_covariance: 1e12,
            ..Default::default()
        },
        // Squared into covariances: 1e300 overflowed, 1e-300 underflowed.
        OnlineConfig {
            prior_width: 1e300,
            ..Default::default()
        },
        OnlineConfig {
            ekf_noise: 1e-300,
            method: OnlineMethod::Ekf,
            ..Default::default()
        },
    ] {
        assert!(
            matches!(bad(cfg), Err(PrrrpError::InvalidParameter { .. })),
            "{cfg:?}"
        );
    }
    let mut id = OnlineIdentifier::new(&chain, &base, OnlineConfig::default()).unwrap();
    let q = [0.1; 7];
    let tau = [1.0; 7];
    id.update(0.0, &q, &tau, None).unwrap();
    let mut nan = q;
    nan[3] = f64::NAN;
    assert!(matches!(
        id.update(0.001, &nan, &tau, None),
        Err(PrrrpError::NonFinite { .. })
    ));
    assert!(matches!(
        id.update(
            0.001,
            &q,
            &[1.0, f64::INFINITY, 0.0, 0.0, 0.0, 0.0, 0.0],
            None
        ),
        Err(PrrrpError::NonFinite { .. })
    ));
    assert!(matches!(
        id.update(f64::NAN, &q, &tau, None),
        Err(PrrrpError::NonFinite { .. })
    ));
    assert!(matches!(
        id.update(0.001, &q[..6], &tau, None),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        id.update(0.001, &q, &tau, Some(&q)),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        id.update(-1.0, &q, &tau, None),
        Err(PrrrpError::NonIncreasingTime { .. })
    ));
    // Finite but absurd (a unit slip): refused, naming the value, before its squares
    // overflow the noise levels.
    let mut huge = tau;
    huge[5] = -1e300;
    match id.update(0.001, &q, &huge, None) {
        Err(e @ PrrrpError::InvalidParameter { .. }) => {
            let text = e.to_string();
            assert!(text.contains("-1e300 for `tau[5] at row 1`"), "{text}");
        }
        other => panic!("{other:?}"),
    }
    // A time stamp of 1e300 s was taken, and every later row was "before" it.
    match id.update(1e300, &q, &tau, None) {
        Err(e @ PrrrpError::InvalidParameter { .. }) => {
            assert!(e.to_string().contains("`t at row 1`"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    id.update(0.001, &q, &tau, None).unwrap();
    // Only the first row and that one counted.
    assert_eq!(id.counts().0, 2);
    // A memory that forgets everything between two rows 1 ms apart (ν = exp(−1000)):
    // refused at the row, before it changes anything; a gap that restarts the filters
    // (no regression across it) is not refused.
    let cfg = OnlineConfig {
        forgetting: Some(1e-6),
        ..Default::default()
    };
    let mut id = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
    id.update(0.0, &q, &tau, None).unwrap();
    id.update(10.0, &q, &tau, None).unwrap();
    assert!(matches!(
        id.update(10.001, &q, &tau, None),
        Err(PrrrpError::InvalidParameter { field, .. }) if field == "forgetting"
    ));
    assert_eq!(id.counts().0, 2);
    // Rows at 5 Hz, below twice the default 10 Hz cut-off: each restarts the filtering,
    // so nothing would ever be learned. Single gaps are taken (above); 100 in a row are
    // refused, naming the cut-off, before the row changes anything.
    let mut id = OnlineIdentifier::new(&chain, &base, OnlineConfig::default()).unwrap();
    let mut refused = None;
    for k in 0..200 {
        let t = k as f64 * 0.2;
        let qk = q.map(|v| v + (0.3 * t).sin());
        match id.update(t, &qk, &tau, None) {
            Ok(_) => {}
            Err(PrrrpError::InvalidParameter { field, .. }) if field == "cutoff_hz" => {
                refused = Some(k);
                break;
            }
            Err(e) => panic!("{e:?}"),
        }
    }
    assert_eq!(refused, Some(100));
    assert_eq!(id.counts(), (100, 0, 0, 0));
}

/// Ten logs of the part held from the start (independent motions and sensor noise, 10 s
/// at 500 Hz) through payload mode with `method`: per log the estimate at the end and
/// its σ.
fn ten_payload_logs(method: OnlineMethod) -> Vec<([f64; 10], [f64; 10])> {
    let (chain, _, prior) = panda_with_prior();
    let gripped = loaded(&chain, &part());
    (0..10)
        .map(|seed| {
            let lg = log(
                &chain,
                &gripped,
                30 + seed,
                10.0,
                500.0,
                Some(0.0),
                (1e-5, 0.05),
            );
            let id = payload_run(&prior, method, &lg);
            let mut e = [0.0; 10];
            let mut s = [0.0; 10];
            e.copy_from_slice(id.parameters());
            s.copy_from_slice(id.sigma().unwrap());
            (e, s)
        })
        .collect()
}

/// RMS over the logs of the normalised errors (π̂ − π)/σ̂: of the mass, and over all ten
/// parameters.
fn rms_z(runs: &[([f64; 10], [f64; 10])]) -> (f64, f64) {
    let truth = part();
    let mut z2 = [0.0; 10];
    for (e, s) in runs {
        for i in 0..10 {
            z2[i] += ((e[i] - truth[i]) / s[i]).powi(2) / runs.len() as f64;
        }
    }
    (z2[0].sqrt(), (z2.iter().sum::<f64>() / 10.0).sqrt())
}

/// The σ the identifier reports is one a user can act on: over ten logs of a part held
/// from the start (independent motions and sensor noise), the RMS of the normalised
/// errors (π̂ − π)/σ̂ of payload-mode RLS at the end is about 1 for the mass and over
/// all ten parameters. The filter's own σ, which treats the low-passed errors as white,
/// gave 3.7 for the mass and 3.3 over all (σ about 3.5× too small).
#[test]
fn payload_sigma_matches_the_spread_of_the_estimates() {
    let (mass, all) = rms_z(&ten_payload_logs(OnlineMethod::Rls));
    eprintln!("RMS normalised error: mass {mass:.2}, all parameters {all:.2}");
    // Ten samples of z²: the RMS of ten standard normals lies in [0.5, 1.6] with
    // probability > 99 %; wider bounds for the mass alone (one parameter).
    assert!(
        (0.5..=1.6).contains(&all),
        "RMS z over all parameters {all}"
    );
    assert!((0.4..=2.0).contains(&mass), "RMS z of the mass {mass}");
}

/// Payload mode's EKF on the same ten logs: the mass within 5 % and the centre of mass
/// within 5 mm (of 8.8 cm) on every one, and its σ honest (RMS of (π̂ − π)/σ̂ over the
/// ten logs in [0.5, 2], over all parameters and for the mass). The joint-state EKF
/// ended between 0.05 and 2.49 kg on these logs.
#[test]
fn payload_mode_ekf_finds_the_mass_on_ten_logs() {
    let runs = ten_payload_logs(OnlineMethod::Ekf);
    let truth = part();
    let c_true: Vec<f64> = (1..4).map(|k| truth[k] / truth[0]).collect();
    for (seed, (e, s)) in runs.iter().enumerate() {
        let dc = (1..4)
            .map(|k| (e[k] / e[0] - c_true[k - 1]).powi(2))
            .sum::<f64>()
            .sqrt();
        eprintln!(
            "log {seed}: mass {:.4} ± {:.4} kg, COM off by {:.2} mm",
            e[0],
            s[0],
            dc * 1e3
        );
        assert!(
            (e[0] / truth[0] - 1.0).abs() < 0.05,
            "log {seed}: mass {}",
            e[0]
        );
        assert!(dc < 5e-3, "log {seed}: COM off by {dc} m");
    }
    let (mass, all) = rms_z(&runs);
    eprintln!("EKF RMS normalised error: mass {mass:.2}, all parameters {all:.2}");
    assert!(
        (0.5..=2.0).contains(&all),
        "RMS z over all parameters {all}"
    );
    assert!((0.5..=2.0).contains(&mass), "RMS z of the mass {mass}");
}

/// `chain` with its Coulomb friction smoothed at `v_s` rad/s.
fn with_coulomb_scale(chain: &DynChain, v_s: f64) -> DynChain {
    let model = FrictionModel {
        coulomb_smoothing: v_s,
        ..chain.friction()
    };
    chain
        .clone()
        .with_friction(model, chain.friction_params().to_vec())
        .unwrap()
}

/// The Panda-like arm (exact sign), its base analysis, the arm with Coulomb friction
/// smoothed at `v_s` rad/s, and settings with the default Coulomb scale search.
fn coulomb_search_case(v_s: f64) -> (DynChain, BaseParameters, DynChain, OnlineConfig) {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let truth = with_coulomb_scale(&chain, v_s);
    let cfg = OnlineConfig {
        coulomb_search: Some(CoulombSearch::default()),
        ..Default::default()
    };
    (chain, base, truth, cfg)
}

/// From no knowledge, the robot given with the exact sign while the arm's Coulomb friction
/// turns over within 0.032 rad/s (a candidate): the online search picks it, and from the
/// choice on its estimates are bit for bit those of an identifier given that scale from the
/// start (the chosen candidate has seen every row). The model at the end predicts the arm
/// better than the exact sign's.
#[test]
fn the_coulomb_scale_is_chosen_online() {
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        coulomb_scale_chosen_online(method);
    }
}

/// [`the_coulomb_scale_is_chosen_online`] for one method (the EKF's candidates are
/// ranked by RLS scorers, its estimates are the chosen EKF's).
fn coulomb_scale_chosen_online(method: OnlineMethod) {
    let v_s = 0.032;
    assert!(ONLINE_COULOMB_SCALES.contains(&v_s));
    let (chain, base, truth, search) = coulomb_search_case(v_s);
    let lg = log(&truth, &truth, 21, 14.0, 500.0, None, (1e-5, 0.05));
    let val = log(&truth, &truth, 37, 10.0, 100.0, None, (0.0, 0.0));
    let plain = OnlineConfig {
        method,
        ..Default::default()
    };
    let search = OnlineConfig { method, ..search };
    let mut id = OnlineIdentifier::new(&chain, &base, search).unwrap();
    let mut own = OnlineIdentifier::new(&chain, &base, plain).unwrap();
    let mut matched = OnlineIdentifier::new(&truth, &base, plain).unwrap();
    let mut same_before = 0;
    for k in 0..lg.t.len() {
        let (t, q, tau) = (lg.t[k], &lg.q[k], &lg.tau[k]);
        let u = id.update(t, q, tau, None).unwrap().estimate.to_vec();
        let o = own.update(t, q, tau, None).unwrap().estimate.to_vec();
        let m = matched.update(t, q, tau, None).unwrap().estimate.to_vec();
        if t < 10.0 {
            // Before the choice: the robot's own scale.
            assert_eq!(u, o, "row {k}");
            same_before += 1;
        } else {
            assert_eq!(u, m, "row {k}: not the matched identifier's estimate");
        }
    }
    assert!(same_before > 4000);
    let s = id.settings_json();
    assert_eq!(s["coulomb_search"]["chosen"], serde_json::json!(v_s), "{s}");
    assert_eq!(s["coulomb_scale"], serde_json::json!(v_s));
    let (e_id, e_own) = (
        rel_error(&id.estimate().unwrap(), &val),
        rel_error(&own.estimate().unwrap(), &val),
    );
    eprintln!("{method:?} end: chosen {e_id:.4?}\n     exact sign {e_own:.4?}");
    let worst = |e: &[f64]| e.iter().cloned().fold(0.0, f64::max);
    assert!(worst(&e_id) < 0.5 * worst(&e_own), "{e_id:?} vs {e_own:?}");
}

/// The search is causal too: altering rows from 3 s (before the choice) or 11 s (after
/// it) changes no estimate before them; a prior model with a search is refused.
#[test]
fn the_coulomb_scale_search_is_causal() {
    let (chain, base, truth, cfg) = coulomb_search_case(0.01);
    let a = log(&truth, &truth, 5, 12.0, 250.0, None, (1e-5, 0.05));
    for k0 in [750, 2750] {
        let mut ia = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        let mut ib = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        let mut differs_after = false;
        for k in 0..a.t.len() {
            let mut tau = a.tau[k].clone();
            if k >= k0 {
                tau.iter_mut()
                    .enumerate()
                    .for_each(|(j, v)| *v += 3.0 * (k as f64 * 0.01 + j as f64).sin());
            }
            let ua = ia.update(a.t[k], &a.q[k], &a.tau[k], None).unwrap();
            let (pa, ea) = (ua.prediction.to_vec(), ua.estimate.to_vec());
            let ub = ib.update(a.t[k], &a.q[k], &tau, None).unwrap();
            if k < k0 {
                assert_eq!(pa, ub.prediction, "k0 {k0}, row {k}");
                assert_eq!(ea, ub.estimate, "k0 {k0}, row {k}");
            } else if ea != ub.estimate {
                differs_after = true;
            }
        }
        assert!(differs_after, "k0 {k0}: the altered future changed nothing");
    }
    let (_, _, prior) = panda_with_prior();
    assert!(matches!(
        OnlineIdentifier::with_prior(&prior, cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}
