//! Long runs of the online identifier over a replayed log with jumps, as `benches/online.rs`
//! replays one period over and over: every method keeps running and stays sane. The bench
//! found the whole-arm RLS's first tip opening (the payload prior added to the covariance)
//! losing definiteness after 46 673 rows; the CI's short runs had not.

mod dyn_support;

use dyn_support::{panda_like, truth_prior, DynFourier};
use prrrp_core::*;

const RATE: f64 = 1000.0;

/// One period of the replay: `len` rows at 1 kHz of a seeded Fourier motion (fundamental
/// 10 s, so a period shorter than 10 s jumps at each wrap), the bare arm's torques and the
/// loaded arm's (a 2 kg part at the tip), noise-free; the noise is added per row.
struct Replay {
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
    tau: [Vec<Vec<f64>>; 2],
}

fn replay(chain: &DynChain, len: usize) -> Replay {
    let mut inertial = chain.inertial().to_vec();
    let pi = inertial_parameters(2.0, [0.01, 0.0, 0.06], [3e-3, 0.0, 3e-3, 0.0, 0.0, 2e-3]);
    for k in 0..10 {
        inertial[6][k] += pi[k];
    }
    let with = chain.clone().with_inertial(inertial).unwrap();
    let f = DynFourier::seeded(5, 7, 0.5);
    let mut out = Replay {
        q: vec![],
        qd: vec![],
        qdd: vec![],
        tau: [vec![], vec![]],
    };
    for k in 0..len {
        let [q, qd, qdd] = f.eval(k as f64 / RATE);
        for (c, tau) in [chain, &with].into_iter().zip(out.tau.iter_mut()) {
            tau.push(
                c.inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
                    .unwrap(),
            );
        }
        out.q.push(q.as_slice().to_vec());
        out.qd.push(qd.as_slice().to_vec());
        out.qdd.push(qdd.as_slice().to_vec());
    }
    out
}

/// What a long run gives: the alarms, and per joint the RMS error, relative to the RMS
/// torque, over one period of the replay (the arm as it is at the end): of the model at
/// the end on the exact motion (methods with a model to save: RLS, EKF) or of the
/// one-step-ahead predictions over the last period (every method).
struct Run {
    changes: usize,
    one_step: Vec<f64>,
    model: Option<Vec<f64>>,
}

/// `rows` rows of `rp` replayed cyclically with increasing time stamps, the part held on
/// every other wrap when `grip` (a grip or release at each wrap, plus the jump of the
/// motion), deterministic noise of ~0.03 N·m (the bench's).
fn run(id: &mut OnlineIdentifier, rp: &Replay, rows: usize, grip: bool) -> Result<Run> {
    let len = rp.q.len();
    let n = rp.q[0].len();
    let held = |k: usize| usize::from(grip && (k / len) % 2 == 1);
    let (mut e, mut r) = (vec![0.0; n], vec![0.0; n]);
    let mut changes = 0;
    let mut tau = vec![0.0; n];
    for k in 0..rows {
        let i = k % len;
        let truth = &rp.tau[held(k)][i];
        for j in 0..n {
            tau[j] = truth[j] + 0.03 * ((i * 7 + j) as f64 * 2.1).sin();
        }
        let u = id.update(k as f64 / RATE, &rp.q[i], &tau, None)?;
        changes += usize::from(u.change);
        if !u.estimate.iter().all(|v| v.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "estimate".into(),
                row: Some(k),
            });
        }
        if k + len >= rows {
            for j in 0..n {
                e[j] += (u.prediction[j] - truth[j]).powi(2);
                r[j] += truth[j].powi(2);
            }
        }
    }
    let one_step = (0..n).map(|j| (e[j] / r[j]).sqrt()).collect();
    let model = match id.config().method {
        OnlineMethod::Rls | OnlineMethod::Ekf => {
            let m = id.estimate()?;
            let tau = &rp.tau[held(rows - 1)];
            let (mut e, mut r) = (vec![0.0; n], vec![0.0; n]);
            for (i, t) in tau.iter().enumerate() {
                let p = m.predict(&rp.q[i], &rp.qd[i], &rp.qdd[i])?;
                for j in 0..n {
                    e[j] += (p[j] - t[j]).powi(2);
                    r[j] += t[j].powi(2);
                }
            }
            Some((0..n).map(|j| (e[j] / r[j]).sqrt()).collect())
        }
        _ => None,
    };
    Ok(Run {
        changes,
        one_step,
        model,
    })
}

/// `rows` rows of the replay through `method` (whole arm from no knowledge for RLS,
/// Adaline and Hopfield, from the true arm's prior for the EKF; `payload` mode on it):
/// no error, finite estimates at every row, one-step-ahead predictions over the last
/// period better than no model (`one_step` on, below the RMS torque) and the model at the
/// end (RLS, EKF) within `model_bar` of each joint's RMS torque.
fn long_run(
    method: OnlineMethod,
    payload: bool,
    rows: usize,
    period: usize,
    grip: bool,
    one_step: bool,
    model_bar: f64,
) {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let rp = replay(&chain, period);
    let cfg = OnlineConfig {
        method,
        payload,
        ..Default::default()
    };
    let mut id = if payload || method == OnlineMethod::Ekf {
        OnlineIdentifier::with_prior(&truth_prior(&chain, &base, 0.03), cfg).unwrap()
    } else {
        OnlineIdentifier::new(&chain, &base, cfg).unwrap()
    };
    let what = format!("{method:?} payload={payload}");
    let r = run(&mut id, &rp, rows, grip).unwrap_or_else(|e| panic!("{what}: {e}"));
    eprintln!(
        "{what}: {} alarms, one-step {:.4?}, model {:.4?}",
        r.changes, r.one_step, r.model
    );
    if one_step {
        for (j, e) in r.one_step.iter().enumerate() {
            assert!(*e < 1.0, "{what}: one-step joint {j}: {e}");
        }
    }
    for (j, e) in r.model.iter().flatten().enumerate() {
        assert!(
            *e < model_bar,
            "{what}: model joint {j}: {e} (bar {model_bar})"
        );
    }
}

/// Rows of the CI runs: past row 46 673, where the reverted tip opening diverged.
const ROWS: usize = 50_000;

/// The bench's log (one 10 s period of continuous motion, replayed): the false alarms of
/// its filtered-away deterministic noise (12–30 in 50 s) open the covariance again and
/// again, so the model at the end is only required to beat no model (measured at 50 000
/// rows, worst joint: whole-arm RLS 40 %, which keeps relearning after each alarm, and
/// 320 % at 60 000 rows with the rule before, every direction at once; whole-arm EKF 11 %;
/// payload RLS 0.3 %; payload EKF 48 %, an alarm shortly before the end).
fn bench_log(method: OnlineMethod, payload: bool) {
    long_run(method, payload, ROWS, 10_000, false, true, 1.0);
}

#[test]
fn whole_arm_rls_runs_long() {
    bench_log(OnlineMethod::Rls, false);
}

#[test]
fn whole_arm_ekf_runs_long() {
    bench_log(OnlineMethod::Ekf, false);
}

#[test]
fn adaline_runs_long() {
    bench_log(OnlineMethod::Adaline, false);
}

#[test]
fn hopfield_runs_long() {
    bench_log(OnlineMethod::Hopfield, false);
}

#[test]
fn payload_rls_runs_long() {
    bench_log(OnlineMethod::Rls, true);
}

#[test]
fn payload_ekf_runs_long() {
    bench_log(OnlineMethod::Ekf, true);
}

/// 200 000 rows with the 2 kg part gripped or released at every wrap (every 10 s), every
/// method: no error, finite, the model at the end better than no model. (The one-step
/// predictions are not checked: each release or grip makes a transient.)
#[test]
#[ignore = "nightly: 200 000 rows per method, about a minute in a debug build"]
fn every_method_runs_long_with_grips() {
    for (method, payload) in [
        (OnlineMethod::Rls, false),
        (OnlineMethod::Ekf, false),
        (OnlineMethod::Adaline, false),
        (OnlineMethod::Hopfield, false),
        (OnlineMethod::Rls, true),
        (OnlineMethod::Ekf, true),
    ] {
        long_run(method, payload, 200_000, 10_000, true, false, 1.0);
    }
}
