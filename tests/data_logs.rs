//! Real-log preprocessing for n joints (`preprocess_log`) and the run-time-n data set
//! (`DynDataset`): an analytic 7-joint trajectory logged on a jittery clock with
//! repeated rows and torque offsets, against its exact derivatives with an error
//! budget computed from the filter and the sampling; the 5-joint path against an
//! independent copy of the fixed-size implementation.

use std::f64::consts::PI;

use prrrp_core::{
    central_differences, preprocess, preprocess_log, ButterworthLowPass, Dataset, DynDataset,
    LogConfig, LogReport, PreprocessConfig, PrrrpError, Vec5,
};
use rand::{rngs::ChaCha8Rng, RngExt, SeedableRng};

const N: usize = 7;
/// Harmonics per joint: (amplitude, ω rad/s, phase). Frequencies 0.2–1.5 Hz, the band of
/// an identification trajectory.
const FREQS_HZ: [f64; 3] = [0.2, 0.7, 1.5];

fn harmonics(j: usize) -> [(f64, f64, f64); 3] {
    let mut h = [(0.0, 0.0, 0.0); 3];
    for (i, f) in FREQS_HZ.iter().enumerate() {
        let a = 0.3 / (1.0 + i as f64) * (1.0 + 0.1 * j as f64);
        h[i] = (a, 2.0 * PI * f, 0.4 * j as f64 + 1.1 * i as f64);
    }
    h
}

/// r-th derivative of Σ a·sin(ωt + φ).
fn deriv(h: &[(f64, f64, f64); 3], r: i32, t: f64) -> f64 {
    h.iter()
        .map(|&(a, w, p)| a * w.powi(r) * (w * t + p + 0.5 * PI * r as f64).sin())
        .sum()
}

/// Σ a·ω^r: a bound on |x^(r)| over all t.
fn deriv_max(h: &[(f64, f64, f64); 3], r: i32) -> f64 {
    h.iter().map(|&(a, w, _)| a * w.powi(r)).sum()
}

/// Torque of joint j: a smooth signal plus a constant sensor offset.
fn tau_harmonics(j: usize) -> [(f64, f64, f64); 3] {
    harmonics(j).map(|(a, w, p)| (20.0 * a, w, p + 0.3))
}
fn tau_offset(j: usize) -> f64 {
    1.5 - 0.4 * j as f64
}

/// |H(f)|² of the zero-phase Butterworth (pre-warped bilinear design) at rate fs.
fn butterworth_power(f: f64, fc: f64, fs: f64, order: usize) -> f64 {
    let r = (PI * f / fs).tan() / (PI * fc / fs).tan();
    1.0 / (1.0 + r.powi(2 * order as i32))
}

/// A log as a real logger writes it.
struct Log {
    t: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    tau: Vec<f64>,
    /// Rows dropped for a repeated time stamp (exact repeats and conflicting ones).
    repeats: usize,
    conflicting: usize,
    /// Steps between distinct time stamps, s.
    steps: Vec<f64>,
}

/// 10 s of the 7-joint trajectory on a 1 kHz clock whose steps are drawn from a seeded
/// RNG: 97 % in 0.7–1.3 ms, 3 % in 1.3–8.8 ms, with one step of exactly 8.8 ms and one
/// of exactly 0.7 ms; about 5 % of the rows repeated exactly, and 3 repeated time
/// stamps carrying different values (a logger overwriting a sample).
fn jittered_log(seed: u64) -> Log {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut log = Log {
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
        tau: Vec::new(),
        repeats: 0,
        conflicting: 0,
        steps: Vec::new(),
    };
    let push = |log: &mut Log, t: f64, bump: f64| {
        log.t.push(t);
        for j in 0..N {
            let (h, th) = (harmonics(j), tau_harmonics(j));
            log.q.push(deriv(&h, 0, t) + bump);
            log.qd.push(deriv(&h, 1, t));
            log.tau.push(deriv(&th, 0, t) + tau_offset(j));
        }
    };
    let mut t = 0.0;
    let mut row = 0;
    while t < 10.0 {
        push(&mut log, t, 0.0);
        if rng.random::<f64>() < 0.05 {
            push(&mut log, t, 0.0);
            log.repeats += 1;
        }
        if row % 3001 == 1000 {
            push(&mut log, t, 0.1);
            log.repeats += 1;
            log.conflicting += 1;
        }
        let step = match row {
            5000 => 8.8e-3,
            5001 => 0.7e-3,
            _ if rng.random::<f64>() < 0.03 => rng.random_range(1.3e-3..8.8e-3),
            _ => rng.random_range(0.7e-3..1.3e-3),
        };
        log.steps.push(step);
        t += step;
        row += 1;
    }
    log.steps.pop();
    // The steps as the log holds them (after rounding of the running sum).
    let mut distinct = log.t.clone();
    distinct.dedup();
    log.steps = distinct.windows(2).map(|w| w[1] - w[0]).collect();
    log
}

/// The zero-phase filter's impulse response g (per sample, centred at index `half`) and
/// its central first and second differences g1 = δg/(2h), g2 = δ²g/h²: the linear maps
/// from an error in the grid samples to the error in q, q̇, q̈.
fn kernels(filter: &ButterworthLowPass, h: f64, half: usize) -> [Vec<f64>; 3] {
    let mut x = vec![0.0; 2 * half + 1];
    x[half] = 1.0;
    let g = filter.filtfilt(&x);
    let mut g1 = vec![0.0; g.len()];
    let mut g2 = vec![0.0; g.len()];
    for k in 1..g.len() - 1 {
        g1[k] = (g[k + 1] - g[k - 1]) / (2.0 * h);
        g2[k] = (g[k + 1] - 2.0 * g[k] + g[k - 1]) / (h * h);
    }
    [g, g1, g2]
}

/// Σ_i |kernel(i)|·env(k − i): the triangle-inequality bound on the filtered and
/// differentiated interpolation error at grid sample k, for a pointwise envelope `env`.
fn convolve_abs(kernel: &[f64], env: &[f64], k: usize) -> f64 {
    let half = kernel.len() / 2;
    kernel
        .iter()
        .enumerate()
        .filter_map(|(i, g)| {
            let idx = (k + half).checked_sub(i)?;
            env.get(idx).map(|e| g.abs() * e)
        })
        .sum()
}

/// Worst errors of the output against the analytic values, per joint: q, q̇, q̈, τ.
fn errors(d: &DynDataset) -> Vec<[f64; 4]> {
    (0..N)
        .map(|j| {
            let (h, th) = (harmonics(j), tau_harmonics(j));
            let mut e = [0.0f64; 4];
            for k in 0..d.len() {
                let t = d.t()[k];
                e[0] = e[0].max((d.q_row(k)[j] - deriv(&h, 0, t)).abs());
                e[1] = e[1].max((d.qd_row(k)[j] - deriv(&h, 1, t)).abs());
                e[2] = e[2].max((d.qdd_row(k)[j] - deriv(&h, 2, t)).abs());
                e[3] = e[3].max((d.tau_row(k)[j] - deriv(&th, 0, t) - tau_offset(j)).abs());
            }
            e
        })
        .collect()
}

/// Error budget per joint for q, q̇, q̈, τ, computed from the filter, the grid and the
/// log's time stamps, never from the output:
/// - filter: Σ a·ω^r·(1 − |H(f)|²) for each harmonic;
/// - central differences (differentiated path): Σ a·ω·(1 − sinc(ωh)) for q̇ and
///   Σ a·ω²·(1 − sinc²(ωh/2)) for q̈, their exact effect on a sinusoid;
/// - linear interpolation: |x_lin − x| ≤ max|ẍ|·(t − t_a)(t_b − t)/2 at a grid time t
///   between log rows a, b; that envelope through |g|, |g1|, |g2| (triangle inequality);
/// - edges: the point reflection used to pad flips x'' at each end, a jump of at most
///   2·max|x''| that decays with the slowest pole, exp(−2π·fc·sin(π/8)·trim); 4× for the
///   overshoot and the two passes (as in tests/preprocess.rs), divided by (2π·fc) per
///   derivative order fewer than 2.
///
/// `measured` selects the measured-velocity path: q̇ is then the filtered (interpolated)
/// measurement and q̈ its central difference.
fn budget(gains: [f64; 3], rep: &LogReport, j: usize, measured: bool) -> [f64; 4] {
    let (h_q, h_tau) = (harmonics(j), tau_harmonics(j));
    let (fs, fc) = (rep.rate_hz, rep.cutoff_hz);
    let dt = 1.0 / fs;
    let filt = |h: &[(f64, f64, f64); 3], r: i32| -> f64 {
        h.iter()
            .map(|&(a, w, _)| a * w.powi(r) * (1.0 - butterworth_power(w / (2.0 * PI), fc, fs, 4)))
            .sum()
    };
    let sinc = |x: f64| x.sin() / x;
    let diff1: f64 = h_q
        .iter()
        .map(|&(a, w, _)| a * w * (1.0 - sinc(w * dt)))
        .sum();
    let diff2: f64 = h_q
        .iter()
        .map(|&(a, w, _)| a * w * w * (1.0 - sinc(0.5 * w * dt).powi(2)))
        .sum();
    let decay = (-2.0 * PI * fc * (PI / 8.0).sin() * rep.trim_s).exp();
    let wc = 2.0 * PI * fc;
    let edge = |x2max: f64, r: i32| 8.0 * x2max * decay * wc.powi(r - 2);

    let [iq, i1, i2] = gains;
    let (q2, q3, tau2) = (deriv_max(&h_q, 2), deriv_max(&h_q, 3), deriv_max(&h_tau, 2));
    let b_q = filt(&h_q, 0) + q2 * iq + edge(q2, 0);
    let b_tau = filt(&h_tau, 0) + tau2 * iq + edge(tau2, 0);
    if measured {
        // q̇ is a filtered signal itself (its second derivative is q⁽³⁾); q̈ its central
        // difference, error Σ a·ω²·(1 − sinc(ωh)).
        let diff: f64 = h_q
            .iter()
            .map(|&(a, w, _)| a * w * w * (1.0 - sinc(w * dt)))
            .sum();
        [
            b_q,
            filt(&h_q, 1) + q3 * iq + edge(q3, 0),
            filt(&h_q, 2) + diff + q3 * i1 + edge(q3, 1),
            b_tau,
        ]
    } else {
        [
            b_q,
            filt(&h_q, 1) + diff1 + q2 * i1 + edge(q2, 1),
            filt(&h_q, 2) + diff2 + q2 * i2 + edge(q2, 2),
            b_tau,
        ]
    }
}

/// The interpolation envelope (t − t_a)(t_b − t)/2 on the grid, through |g|, |g1|, |g2|:
/// per unit of max|ẍ|, the worst interpolation error left in x, ẋ, ẍ over the output
/// samples. The kernels are cut at ±0.6 s, where the 10 Hz response has decayed below
/// 1e-6 of its peak.
fn interpolation_gains(log: &Log, d: &DynDataset, rep: &LogReport) -> [f64; 3] {
    let fs = rep.rate_hz;
    let dt = 1.0 / fs;
    let mut distinct = log.t.clone();
    distinct.dedup();
    let t0 = distinct[0];
    let m = ((distinct[distinct.len() - 1] - t0) * fs).floor() as usize + 1;
    let mut env = vec![0.0; m];
    let mut p = 0;
    for (i, e) in env.iter_mut().enumerate() {
        let tg = t0 + i as f64 * dt;
        while p + 2 < distinct.len() && distinct[p + 1] <= tg {
            p += 1;
        }
        *e = ((tg - distinct[p]) * (distinct[p + 1] - tg)).max(0.0) / 2.0;
    }
    let filter = ButterworthLowPass::new(4, rep.cutoff_hz, fs).unwrap();
    let half = (0.6 * fs) as usize;
    let kernels = kernels(&filter, dt, half);
    let mut out = [0.0f64; 3];
    for k in 0..d.len() {
        let gi = ((d.t()[k] - t0) * fs).round() as usize;
        for (o, g) in out.iter_mut().zip(&kernels) {
            *o = o.max(convolve_abs(g, &env, gi));
        }
    }
    out
}

fn check_report(log: &Log, d: &DynDataset, rep: &LogReport) {
    assert_eq!(rep.rows_in, log.t.len());
    assert_eq!(rep.repeated_rows, log.repeats);
    assert_eq!(rep.conflicting_repeats, log.conflicting);
    assert_eq!(rep.rows_out, d.len());
    // The median step computed here independently (upper middle for an even count).
    let mut s = log.steps.clone();
    s.sort_by(f64::total_cmp);
    let median = s[s.len() / 2];
    assert_eq!(rep.median_rate_hz, 1.0 / median);
    assert_eq!(rep.rate_hz, rep.median_rate_hz);
    assert!(rep.resampled);
    let largest = s[s.len() - 1];
    assert_eq!(rep.largest_gap_s, largest);
    assert!((largest - 8.8e-3).abs() < 1e-12);
    // Default cut-off min(10 Hz, f/10) = 10 Hz at ~1 kHz; trim 3 cut-off periods.
    assert_eq!(rep.cutoff_hz, 10.0);
    assert_eq!(rep.trim_samples, (3.0 * rep.rate_hz / 10.0).ceil() as usize);
    assert_eq!(rep.decimation, 1);
    // A uniform grid at the reported rate.
    for w in d.t().windows(2) {
        assert!((w[1] - w[0] - 1.0 / rep.rate_hz).abs() < 1e-9);
    }
}

#[test]
fn seven_joint_jittered_log_matches_the_analytic_derivatives() {
    let log = jittered_log(7);
    let frac = log.repeats as f64 / log.t.len() as f64;
    assert!((0.04..0.06).contains(&frac), "repeated fraction {frac}");
    let (d, rep) =
        preprocess_log(&log.t, &log.q, &log.tau, None, N, &LogConfig::default()).unwrap();
    assert_eq!(d.dof(), N);
    assert!(!rep.measured_velocity);
    check_report(&log, &d, &rep);
    let errs = errors(&d);
    let gains = interpolation_gains(&log, &d, &rep);
    eprintln!("interpolation gains |g|, |g1|, |g2| * envelope: {gains:?}");
    for (j, e) in errs.iter().enumerate() {
        let b = budget(gains, &rep, j, false);
        eprintln!("joint {j}: errors q, q̇, q̈, τ = {e:?}, bounds {b:?}");
        for (c, name) in ["q", "qd", "qdd", "tau"].iter().enumerate() {
            assert!(
                e[c] <= b[c],
                "joint {j} {name}: error {} > bound {}",
                e[c],
                b[c]
            );
        }
        // The bounds say something: q̈ within 2 % of its amplitude; τ within 0.01 N·m,
        // a tenth of the smallest offset, so the offsets pass unchanged.
        let h = harmonics(j);
        assert!(b[2] < 0.02 * deriv_max(&h, 2), "q̈ bound {} too loose", b[2]);
        assert!(b[3] < 0.01, "τ bound {}", b[3]);
    }
}

#[test]
fn measured_velocities_give_a_velocity_at_least_as_accurate() {
    let log = jittered_log(11);
    let cfg = LogConfig::default();
    let (dd, _) = preprocess_log(&log.t, &log.q, &log.tau, None, N, &cfg).unwrap();
    let (dm, rep) = preprocess_log(&log.t, &log.q, &log.tau, Some(&log.qd), N, &cfg).unwrap();
    assert!(rep.measured_velocity);
    check_report(&log, &dm, &rep);
    assert_eq!(dm.t(), dd.t());
    // The positions do not depend on where q̇ comes from.
    assert_eq!(dm.q(), dd.q());
    let (ed, em) = (errors(&dd), errors(&dm));
    let gains = interpolation_gains(&log, &dm, &rep);
    for j in 0..N {
        let b = budget(gains, &rep, j, true);
        eprintln!(
            "joint {j}: q̇ error measured {:.2e} vs differentiated {:.2e} (bound {:.2e}); \
             q̈ {:.2e} (bound {:.2e})",
            em[j][1], ed[j][1], b[1], em[j][2], b[2]
        );
        assert!(em[j][1] <= ed[j][1], "joint {j}");
        assert!(em[j][1] <= b[1] && em[j][2] <= b[2], "joint {j}");
    }
}

#[test]
fn time_running_backwards_names_the_row() {
    let log = jittered_log(3);
    // Row 4321 of the log (repeats included) goes back by half a step.
    let mut t = log.t.clone();
    let k = 4321;
    t[k] = t[k - 1] - 0.5e-3;
    assert_eq!(
        preprocess_log(&t, &log.q, &log.tau, None, N, &LogConfig::default()),
        Err(PrrrpError::NonIncreasingTime { row: k })
    );
}

/// The fixed-size implementation as it was before the shared core, in terms of the
/// public `central_differences` and `ButterworthLowPass`: the independent reference.
fn reference_preprocess(t: &[f64], q: &[Vec5], tau: &[Vec5], fc: f64, decimate: usize) -> Dataset {
    let n = t.len();
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let fs = 1.0 / dt;
    let filter = ButterworthLowPass::new(4, fc, fs).unwrap();
    let filt = |x: &[Vec5]| -> Vec<Vec5> {
        let mut out = vec![Vec5::zeros(); x.len()];
        for j in 0..5 {
            let col: Vec<f64> = x.iter().map(|v| v[j]).collect();
            for (o, f) in out.iter_mut().zip(filter.filtfilt(&col)) {
                o[j] = f;
            }
        }
        out
    };
    let (qf, tauf) = (filt(q), filt(tau));
    let (qd, qdd) = central_differences(&qf, dt);
    let trim = ((3.0 * fs / fc).ceil() as usize).max(1);
    let keep: Vec<usize> = (trim..n - trim).step_by(decimate).collect();
    Dataset::new(
        keep.iter().map(|&k| t[k]).collect(),
        keep.iter().map(|&k| qf[k]).collect(),
        keep.iter().map(|&k| qd[k - 1]).collect(),
        keep.iter().map(|&k| qdd[k - 1]).collect(),
        keep.iter().map(|&k| tauf[k]).collect(),
    )
    .unwrap()
}

#[test]
fn five_joints_on_uniform_data_equal_preprocess_bit_for_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let dt = 0.02;
    let rows = 600;
    let t: Vec<f64> = (0..rows).map(|k| dt * k as f64).collect();
    let q: Vec<Vec5> = t
        .iter()
        .map(|&t| Vec5::from_fn(|j, _| (1.3 * t + j as f64).sin() + 1e-3 * rng.random::<f64>()))
        .collect();
    let tau: Vec<Vec5> = t
        .iter()
        .map(|&t| Vec5::from_fn(|j, _| 3.0 * (0.7 * t).cos() + j as f64 + rng.random::<f64>()))
        .collect();
    let flat = |c: &[Vec5]| -> Vec<f64> { c.iter().flat_map(|v| v.iter().copied()).collect() };
    for (decimate, to_hz) in [(1, None), (2, Some(25.0))] {
        let pre = preprocess(
            &t,
            &q,
            &tau,
            &PreprocessConfig {
                decimate,
                ..PreprocessConfig::default()
            },
        )
        .unwrap();
        assert_eq!(pre, reference_preprocess(&t, &q, &tau, 5.0, decimate));
        let cfg = LogConfig {
            cutoff_hz: Some(5.0),
            decimate_to_hz: to_hz,
            min_samples: Dataset::MIN_SAMPLES,
            ..LogConfig::default()
        };
        let (d, rep) = preprocess_log(&t, &flat(&q), &flat(&tau), None, 5, &cfg).unwrap();
        assert!(!rep.resampled);
        assert_eq!(rep.decimation, decimate);
        assert_eq!(d.t()[0], t[rep.trim_samples]);
        assert_eq!(d, DynDataset::from(&pre));
        assert_eq!(Dataset::try_from(&d).unwrap(), pre);
    }
}

#[test]
fn dyn_dataset_rows_conversions_and_errors() {
    let (n, rows) = (3, 20);
    let t: Vec<f64> = (0..rows).map(|k| 0.01 * k as f64).collect();
    let col = |s: f64| -> Vec<f64> { (0..n * rows).map(|i| s * i as f64).collect() };
    let d = DynDataset::new(n, t.clone(), col(1.0), col(2.0), col(3.0), col(4.0)).unwrap();
    assert_eq!((d.len(), d.dof(), d.min_samples()), (rows, n, 14));
    assert_eq!(d.q_row(2), &[6.0, 7.0, 8.0]);
    assert_eq!(d.tau_row(19), &[228.0, 232.0, 236.0]);
    assert!((d.duration() - 0.19).abs() < 1e-12);
    let s = d.slice(3..18).unwrap();
    assert_eq!(s.qd_row(0), d.qd_row(3));
    assert_eq!(s.qdd(), &d.qdd()[9..54]);
    assert!(matches!(
        d.slice(3..10),
        Err(PrrrpError::TooFewSamples { needed: 14, got: 7 })
    ));
    assert!(matches!(
        d.slice(3..21),
        Err(PrrrpError::ShapeMismatch { .. })
    ));

    let mut bad = col(1.0);
    bad[3 * 5 + 2] = f64::NAN;
    assert_eq!(
        DynDataset::new(n, t.clone(), col(1.0), col(1.0), bad, col(1.0)),
        Err(PrrrpError::NonFinite {
            what: "qdd[2] (joint 3)".into(),
            row: Some(5)
        })
    );
    assert!(matches!(
        DynDataset::new(
            n,
            t.clone(),
            col(1.0),
            col(1.0)[..59].to_vec(),
            col(1.0),
            col(1.0)
        ),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        DynDataset::new(0, t.clone(), vec![], vec![], vec![], vec![]),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let mut back = t.clone();
    back[7] = back[6];
    assert_eq!(
        DynDataset::new(n, back, col(1.0), col(1.0), col(1.0), col(1.0)),
        Err(PrrrpError::NonIncreasingTime { row: 7 })
    );
    assert!(DynDataset::with_min_samples(
        n,
        2,
        t[..2].to_vec(),
        col(1.0)[..6].to_vec(),
        col(1.0)[..6].to_vec(),
        col(1.0)[..6].to_vec(),
        col(1.0)[..6].to_vec()
    )
    .is_ok());

    // Dataset ↔ DynDataset with n = 5, and a 3-joint set is no Dataset.
    let t5: Vec<f64> = (0..10).map(|k| 0.02 * k as f64).collect();
    let v = |s: f64| -> Vec<Vec5> { (0..10).map(|k| Vec5::repeat(s * k as f64)).collect() };
    let ds = Dataset::new(t5, v(1.0), v(2.0), v(3.0), v(4.0)).unwrap();
    let dd = DynDataset::from(&ds);
    assert_eq!((dd.dof(), dd.min_samples()), (5, Dataset::MIN_SAMPLES));
    assert_eq!(dd.qd_row(4), &[8.0; 5]);
    assert_eq!(Dataset::try_from(dd).unwrap(), ds);
    assert!(matches!(
        Dataset::try_from(&d),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}

#[test]
fn bad_logs_are_typed_errors() {
    let log = jittered_log(1);
    let cfg = LogConfig::default();
    let run = |t: &[f64], q: &[f64], n: usize, cfg: &LogConfig| {
        preprocess_log(t, q, &log.tau[..q.len().min(log.tau.len())], None, n, cfg)
    };
    assert!(matches!(
        run(&log.t, &log.q, 0, &cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(matches!(
        run(&log.t, &log.q[..log.q.len() - 1], N, &cfg),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        preprocess_log(&log.t, &log.q, &log.tau, Some(&log.qd[1..]), N, &cfg),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        run(&[], &[], N, &cfg),
        Err(PrrrpError::TooFewSamples { needed: 3, got: 0 })
    ));
    let mut q = log.q.clone();
    q[N * 123 + 3] = f64::NAN;
    assert_eq!(
        run(&log.t, &q, N, &cfg),
        Err(PrrrpError::NonFinite {
            what: "q[3] (joint 4)".into(),
            row: Some(123)
        })
    );
    let mut t = log.t.clone();
    t[77] = f64::INFINITY;
    assert_eq!(
        run(&t, &log.q, N, &cfg),
        Err(PrrrpError::NonFinite {
            what: "t".into(),
            row: Some(77)
        })
    );
    // All rows at one time stamp: one sample, and the error says so (not "record a
    // longer trajectory").
    let same = vec![1.0; log.t.len()];
    let text = run(&same, &log.q, N, &cfg).unwrap_err().to_string();
    let rows = format!("its {} rows hold 1 distinct time stamp)", log.t.len());
    assert!(text.contains(&rows), "{text}");
    assert!(text.contains("give each sample its own time"), "{text}");
    // A cut-off above the Nyquist frequency of a 100 Hz log: named, not the first step
    // longer than half its period (every step is).
    let t100: Vec<f64> = (0..2000).map(|k| k as f64 * 0.01).collect();
    let q100: Vec<f64> = t100
        .iter()
        .flat_map(|t| (0..N).map(move |j| (t * (1.0 + j as f64)).sin()))
        .collect();
    let c = LogConfig {
        cutoff_hz: Some(60.0),
        ..cfg
    };
    let err = preprocess_log(&t100, &q100, &q100, None, N, &c).unwrap_err();
    assert!(
        matches!(&err, PrrrpError::InvalidParameter { field, .. } if field == "cutoff_hz"),
        "{err}"
    );
    // A cut-off whose transient needs more than 1e7 samples: the error names the cut-off
    // (it read "need at least 18446744073709551615" samples).
    let c = LogConfig {
        cutoff_hz: Some(1e-300),
        ..cfg
    };
    let err = run(&log.t, &log.q, N, &c).unwrap_err();
    assert!(
        matches!(&err, PrrrpError::InvalidParameter { field, .. } if field == "cutoff_hz"),
        "{err}"
    );
    let c = LogConfig {
        decimate_to_hz: Some(1e-300),
        ..cfg
    };
    assert!(run(&log.t, &log.q, N, &c).is_err());
    let bad_rates = [f64::NAN, -1.0, 0.0, 1e12, f64::INFINITY, 1e-300].map(|rate| LogConfig {
        rate_hz: Some(rate),
        ..cfg
    });
    for bad in bad_rates.into_iter().chain([
        // 300 Hz is not 1 kHz over a whole number; a cut-off above the output Nyquist.
        LogConfig {
            rate_hz: Some(1000.0),
            decimate_to_hz: Some(300.0),
            ..cfg
        },
        LogConfig {
            cutoff_hz: Some(30.0),
            decimate_to_hz: Some(50.0),
            ..cfg
        },
        LogConfig {
            trim_s: Some(-1.0),
            ..cfg
        },
        LogConfig {
            max_gap_s: Some(f64::NAN),
            ..cfg
        },
        LogConfig { order: 5, ..cfg },
        LogConfig {
            cutoff_hz: Some(0.0),
            ..cfg
        },
    ]) {
        assert!(
            matches!(
                run(&log.t, &log.q, N, &bad),
                Err(PrrrpError::InvalidParameter { .. })
            ),
            "{bad:?}"
        );
    }
    // A trim longer than the log.
    let c = LogConfig {
        trim_s: Some(1e300),
        ..cfg
    };
    assert!(matches!(
        run(&log.t, &log.q, N, &c),
        Err(PrrrpError::TooFewSamples { .. })
    ));
    // A 60 ms hole in the log: longer than half a 10 Hz cut-off period.
    let mut t = log.t.clone();
    let hole = 6000;
    for x in &mut t[hole..] {
        *x += 0.06;
    }
    match run(&t, &log.q, N, &cfg) {
        Err(PrrrpError::InvalidParameter { field, value, .. }) => {
            assert_eq!(field, format!("t[{hole}]"));
            assert!(value >= 0.06 - 1e-12);
        }
        other => panic!("{other:?}"),
    }
    // ... accepted when allowed, and reported.
    let c = LogConfig {
        max_gap_s: Some(f64::INFINITY),
        ..cfg
    };
    let (_, rep) = run(&t, &log.q, N, &c).unwrap();
    assert_eq!(rep.largest_gap_row, hole);
}

/// No input makes `preprocess_log` panic: random small logs with repeated, backwards,
/// extreme and non-finite time stamps and values, any joint count, and extreme settings
/// all return `Ok` or a typed error.
#[test]
fn no_input_panics() {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let times = [
        0.0,
        0.0,
        0.0,
        1e-320,
        1e-9,
        1e-3,
        1.0,
        1e300,
        -1e308,
        1e308,
        f64::NAN,
    ];
    // None (the default) half of the time, so that many logs reach the filter.
    let settings = [
        None,
        None,
        None,
        None,
        None,
        Some(1e-300),
        Some(1e-3),
        Some(1.0),
        Some(1e3),
        Some(1e300),
    ];
    for case in 0..3000 {
        let n = [1, 2, 3, 13][case % 4];
        let rows = [0, 1, 2, 3, 5, 40, 2000, 2000, 2000, 2000][rng.random_range(0..10)];
        let mut now = times[rng.random_range(0..times.len() - 1)];
        let mut t: Vec<f64> = (0..rows)
            .map(|_| {
                let x = now;
                now += rng.random_range(0.7e-3..1.3e-3);
                x
            })
            .collect();
        let mut q: Vec<f64> = (0..rows * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        // At most one defect per log, so that many logs get through to the filter.
        if rows > 1 {
            let k = rng.random_range(1..rows);
            match rng.random_range(0..6) {
                0 => t[k] = t[k - 1],
                1 => t[k] = t[k - 1] - 1e-3,
                2 => t[k] = times[rng.random_range(0..times.len())],
                3 => q[k * n] = f64::INFINITY,
                _ => {}
            }
        }
        let qd = q.clone();
        let pick = |rng: &mut ChaCha8Rng| settings[rng.random_range(0..settings.len())];
        let cfg = LogConfig {
            rate_hz: pick(&mut rng),
            cutoff_hz: pick(&mut rng),
            order: [2, 4, 8][rng.random_range(0..3)],
            trim_s: [None, Some(0.0), Some(1e300)][rng.random_range(0..3)],
            decimate_to_hz: pick(&mut rng),
            max_gap_s: [None, Some(f64::INFINITY)][rng.random_range(0..2)],
            min_samples: rng.random_range(0..20),
            ..LogConfig::default()
        };
        let with_qd = rng.random_range(0..2) == 0;
        let _ = preprocess_log(&t, &q, &q, with_qd.then_some(&qd[..]), n, &cfg);
    }
    // A joint count whose product with the rows overflows.
    assert!(matches!(
        preprocess_log(
            &[0.0, 1.0],
            &[0.0],
            &[0.0],
            None,
            usize::MAX,
            &LogConfig::default()
        ),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}
