//! The online identifier (exploration).

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

/// `dur` s at `rate` Hz; `load` (from `t_load` on) added to the tip link.
fn log(
    chain: &DynChain,
    seed: u64,
    dur: f64,
    rate: f64,
    load: Option<(f64, [f64; 10])>,
    noise: (f64, f64),
) -> Log {
    let f = DynFourier::seeded(seed, chain.dof(), 1.0);
    let mut rng = StdRng::seed_from_u64(seed + 100);
    let (nq, nt) = (
        Normal::new(0.0, noise.0).unwrap(),
        Normal::new(0.0, noise.1).unwrap(),
    );
    let loaded = load.map(|(_, pi)| {
        let mut inertial = chain.inertial().to_vec();
        let n = inertial.len();
        for k in 0..10 {
            inertial[n - 1][k] += pi[k];
        }
        chain.clone().with_inertial(inertial).unwrap()
    });
    let mut out = Log {
        t: vec![],
        q: vec![],
        tau: vec![],
        qd: vec![],
        qdd: vec![],
    };
    let samples = (dur * rate) as usize;
    for k in 0..samples {
        let t = k as f64 / rate;
        let [q, qd, qdd] = f.eval(t);
        let c = match (&loaded, load) {
            (Some(l), Some((t0, _))) if t >= t0 => l,
            _ => chain,
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

fn rel_rms(pred: &[Vec<f64>], meas: &[Vec<f64>], range: std::ops::Range<usize>) -> Vec<f64> {
    let n = pred[0].len();
    (0..n)
        .map(|j| {
            let (mut e, mut r) = (0.0, 0.0);
            for k in range.clone() {
                e += (pred[k][j] - meas[k][j]).powi(2);
                r += meas[k][j].powi(2);
            }
            (e / r).sqrt()
        })
        .collect()
}

#[test]
fn explore_rls_and_ekf() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let lg = log(&chain, 3, 30.0, 1000.0, None, (1e-5, 0.05));
    for method in [OnlineMethod::Rls, OnlineMethod::Ekf] {
        let cfg = OnlineConfig {
            method,
            ..Default::default()
        };
        let mut id = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        let mut preds = vec![];
        let t0 = std::time::Instant::now();
        for k in 0..lg.t.len() {
            let u = id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
            preds.push(u.prediction.to_vec());
        }
        let el = t0.elapsed();
        let m = id.estimate().unwrap();
        eprintln!(
            "{method:?}: {:?} per sample; running {}; counts {:?}; settings {}",
            el / lg.t.len() as u32,
            id.ekf_running(),
            id.counts(),
            m.settings
        );
        eprintln!(
            "  rel rms last 5 s {:?}",
            rel_rms(&preds, &lg.tau, 25000..30000)
                .iter()
                .map(|v| format!("{:.3}", v))
                .collect::<Vec<_>>()
        );
        // Batch prediction with the final model on truth states.
        let truth = chain.base_model(&base).unwrap();
        let tb = truth.chain_base_values();
        let mut worst: f64 = 0.0;
        for (i, (b, t)) in m.beta.iter().zip(tb.iter()).enumerate() {
            let s = m.sigma.as_ref().map_or(f64::NAN, |s| s[i]);
            worst = worst.max((b - t).abs() / s);
        }
        eprintln!("  worst |err|/σ {worst:.2}");
        // The final model against the exact torques at the true states, per joint, in
        // units of the noise; and the noise floor as relative RMS.
        let (mut e, mut r) = (vec![0.0; 7], vec![0.0; 7]);
        for k in 20000..30000 {
            let tp = m.predict(&lg.q[k], &lg.qd[k], &lg.qdd[k]).unwrap();
            let tt = chain
                .inverse_dynamics(&lg.q[k], &lg.qd[k], &lg.qdd[k])
                .unwrap();
            for j in 0..7 {
                e[j] += (tp[j] - tt[j]).powi(2);
                r[j] += tt[j].powi(2);
            }
        }
        eprintln!(
            "  model error / noise {:?}",
            e.iter()
                .map(|v| format!("{:.3}", (v / 10000.0).sqrt() / 0.05))
                .collect::<Vec<_>>()
        );
        eprintln!(
            "  noise floor rel {:?}",
            r.iter()
                .map(|v| format!("{:.3}", 0.05 / (v / 10000.0).sqrt()))
                .collect::<Vec<_>>()
        );
    }
}

#[test]
fn explore_kinematics() {
    let chain = panda_like();
    let lg = log(&chain, 3, 30.0, 1000.0, None, (1e-5, 0.05));
    let mut k = CausalKinematics::new(7, 10.0, false);
    let (mut v, mut a) = (vec![0.0; 7], vec![0.0; 7]);
    let (mut ev, mut ea, mut rv, mut ra) = (vec![0.0; 7], vec![0.0; 7], vec![0.0; 7], vec![0.0; 7]);
    let mut etau = vec![0.0; 7];
    for i in 0..lg.t.len() {
        let dt = if i == 0 { 0.0 } else { lg.t[i] - lg.t[i - 1] };
        k.update(dt, &lg.q[i], None, &mut v, &mut a);
        if i > 1000 {
            let tt = chain
                .inverse_dynamics(&lg.q[i], &lg.qd[i], &lg.qdd[i])
                .unwrap();
            let te = chain.inverse_dynamics(&lg.q[i], &v, &a).unwrap();
            for j in 0..7 {
                ev[j] += (v[j] - lg.qd[i][j]).powi(2);
                ea[j] += (a[j] - lg.qdd[i][j]).powi(2);
                rv[j] += lg.qd[i][j].powi(2);
                ra[j] += lg.qdd[i][j].powi(2);
                etau[j] += (te[j] - tt[j]).powi(2);
            }
        }
    }
    let m = (lg.t.len() - 1001) as f64;
    eprintln!(
        "qd rel {:?}",
        (0..7)
            .map(|j| format!("{:.2e}", (ev[j] / rv[j]).sqrt()))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "qdd rel {:?}",
        (0..7)
            .map(|j| format!("{:.2e}", (ea[j] / ra[j]).sqrt()))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "qdd rms {:?}",
        (0..7)
            .map(|j| format!("{:.2e}", (ea[j] / m).sqrt()))
            .collect::<Vec<_>>()
    );
    eprintln!(
        "tau err rms {:?}",
        (0..7)
            .map(|j| format!("{:.2e}", (etau[j] / m).sqrt()))
            .collect::<Vec<_>>()
    );
}

fn validate(m: &IdentifiedModel, val: &Log) -> Vec<f64> {
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

#[test]
fn explore_payload() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let pay = inertial_parameters(2.5, [0.02, -0.03, 0.08], [4e-3, 0.0, 4e-3, 0.0, 0.0, 3e-3]);
    let noise = (1e-5, 0.05);
    // Prior: batch WLS on an unloaded log.
    let un = log(&chain, 11, 20.0, 200.0, None, noise);
    let flat = |v: &Vec<Vec<f64>>| v.iter().flatten().copied().collect::<Vec<f64>>();
    let ds = DynDataset::new(
        7,
        un.t.clone(),
        flat(&un.q),
        flat(&un.qd),
        flat(&un.qdd),
        flat(&un.tau),
    )
    .unwrap();
    let prior = identify(
        &chain,
        &base,
        &ds,
        &Method::parse("wls").unwrap(),
        serde_json::json!({}),
    )
    .unwrap();
    let lg = log(&chain, 5, 30.0, 1000.0, Some((10.0, pay)), noise);
    let val = log(&chain, 21, 10.0, 200.0, Some((0.0, pay)), (0.0, 0.0));
    for (method, payload) in [
        (OnlineMethod::Rls, false),
        (OnlineMethod::Ekf, false),
        (OnlineMethod::Rls, true),
        (OnlineMethod::Ekf, true),
    ] {
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
        let mut at3 = None;
        let mut changes = vec![];
        for k in 0..lg.t.len() {
            let u = id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
            if u.change {
                changes.push(lg.t[k]);
            }
            if at3.is_none() && lg.t[k] >= 13.0 {
                at3 = Some(id.estimate().unwrap());
            }
        }
        let m = id.estimate().unwrap();
        let fmt = |v: Vec<f64>| v.iter().map(|x| format!("{:.3}", x)).collect::<Vec<_>>();
        eprintln!("{method:?} payload {payload}: changes at {changes:?}");
        eprintln!("  +3 s {:?}", fmt(validate(at3.as_ref().unwrap(), &val)));
        eprintln!("  end  {:?}", fmt(validate(&m, &val)));
        if let Some(p) = &m.payload {
            eprintln!(
                "  payload {:?} sigma {:?}",
                p.summary().mass,
                p.summary().mass_sigma
            );
        }
    }
}

#[test]
fn explore_payload_debug() {
    let chain = panda_like();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let noise = (1e-5, 0.05);
    let un = log(&chain, 11, 20.0, 200.0, None, noise);
    let flat = |v: &Vec<Vec<f64>>| v.iter().flatten().copied().collect::<Vec<f64>>();
    let ds = DynDataset::new(
        7,
        un.t.clone(),
        flat(&un.q),
        flat(&un.qd),
        flat(&un.qdd),
        flat(&un.tau),
    )
    .unwrap();
    let prior = identify(
        &chain,
        &base,
        &ds,
        &Method::parse("wls").unwrap(),
        serde_json::json!({}),
    )
    .unwrap();
    let lg = log(&chain, 5, 4.0, 1000.0, None, noise);
    let cfg = OnlineConfig {
        method: OnlineMethod::Rls,
        payload: true,
        ..Default::default()
    };
    let mut id = OnlineIdentifier::with_prior(&prior, cfg).unwrap();
    for k in 0..lg.t.len() {
        let u = id.update(lg.t[k], &lg.q[k], &lg.tau[k], None).unwrap();
        if k % 200 == 0 || (u.updated && k < 400 && k % 20 == 0) {
            eprintln!(
                "{k} upd {} est {:?} sig {:?} pred-err {:?}",
                u.updated,
                &u.estimate[..4],
                u.sigma.map(|s| s[0]),
                u.prediction
                    .iter()
                    .zip(&lg.tau[k])
                    .map(|(a, b)| format!("{:.2}", a - b))
                    .collect::<Vec<_>>()
            );
        }
    }
}
