//! Simulation of any robot (a run-time chain: the PUMA 560, a URDF fixture, the Panda of
//! `example-robot-data`), checked against physics: computed torque with the exact model
//! tracks the reference, the recorded torque is the inverse dynamics of the recorded state,
//! the open-loop energy balance d(T + V)/dt = q̇ᵀτ holds to the integrator's order, the
//! sensor noise has the configured statistics, and runs are reproducible from the seed.

mod dyn_support;

use dyn_support::{base_model, fourier, robots_dir, three_joint_urdf, with_smoothed_friction};
use prrrp_core::{
    simulate_dyn_closed_loop, simulate_dyn_open_loop, validate_torque_prediction, DynChain,
    DynSampledTrajectory, DynSensorNoise, DynSimulationConfig, DynTrajectory, ParameterisedModel,
    PrrrpError, SerialChain, Sinusoid, UrdfOptions,
};

/// PUMA 560 with viscous, smoothed-Coulomb and offset friction on every joint, sized to
/// each joint's inertia: the wrist's links have inertias of 4e-5 to 2e-3 kg·m², and a
/// friction slope (fv + fc/v_s) over the inertia is a pole the integrator must resolve
/// (RK4 needs |λ|·h < 2.8).
fn puma() -> DynChain {
    with_smoothed_friction(
        SerialChain::puma560().to_dyn(),
        0.1,
        vec![
            [1.0, 0.4, 0.05],
            [1.0, 0.4, 0.05],
            [0.5, 0.2, 0.02],
            [0.005, 0.002, 0.001],
            [0.005, 0.002, 0.001],
            [0.002, 0.001, 0.0005],
        ],
    )
}

fn noiseless(n: usize) -> DynSimulationConfig {
    DynSimulationConfig::new(n)
}

fn with_substeps(n: usize, substeps: usize) -> DynSimulationConfig {
    DynSimulationConfig {
        substeps,
        ..DynSimulationConfig::new(n)
    }
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Checks, for any chain: τ = ID(q, q̇, q̈) of every sample, no noise without noise
/// settings; returns the tracking error of exact-model computed torque at `substeps` RK4
/// steps per 10 ms sample.
fn exact_tracking(
    chain: &DynChain,
    reference: &dyn DynTrajectory,
    duration: f64,
    substeps: usize,
) -> f64 {
    let n = chain.dof();
    let cfg = with_substeps(n, substeps);
    let rec = simulate_dyn_closed_loop(chain, chain, reference, duration, &cfg).unwrap();
    assert_eq!(rec.dof(), n);
    assert_eq!(rec.len(), (duration / 0.01).round() as usize + 1);
    let mut ws = chain.workspace();
    let mut tau = vec![0.0; n];
    for k in 0..rec.len() {
        let r = n * k..n * k + n;
        chain
            .inverse_dynamics_into(
                &mut ws,
                &rec.q[r.clone()],
                &rec.qd[r.clone()],
                &rec.qdd[r.clone()],
                &mut tau,
            )
            .unwrap();
        let scale = 1.0
            + rec.tau[r.clone()]
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            max_abs_diff(&tau, &rec.tau[r.clone()]) < 1e-9 * scale,
            "sample {k}: ID(q, qd, qdd) {tau:?} vs recorded {:?}",
            &rec.tau[r]
        );
    }
    assert_eq!(rec.q_measured, rec.q);
    assert_eq!(rec.tau_measured, rec.tau);
    assert!(rec.qd_measured.is_none());
    // The data set views carry the same numbers.
    let data = rec.true_dataset().unwrap();
    assert_eq!((data.len(), data.dof()), (rec.len(), n));
    assert_eq!(data.tau(), rec.tau.as_slice());
    max_abs_diff(&rec.q, &rec.q_ref)
}

/// With the exact model the only tracking error is the controller's zero-order hold over
/// one step h: the commanded acceleration lags the reference by ≈ jerk·h/2, so the error
/// is first order in h and goes to 0 with it. Returns the error at h = 1 ms after
/// checking that halving h halves it.
fn tracking_converges(chain: &DynChain, reference: &dyn DynTrajectory, duration: f64) -> f64 {
    let e1 = exact_tracking(chain, reference, duration, 10);
    let e2 = exact_tracking(chain, reference, duration, 20);
    let ratio = e2 / e1;
    assert!(
        (0.4..0.6).contains(&ratio),
        "tracking error {e1:.3e} -> {e2:.3e} when h halves: not first order in h"
    );
    e1
}

/// Computed torque with the exact model (friction included) starting on the reference:
/// only the 1 ms zero-order hold of the controller separates robot and reference
/// (≈ jerk·h² ~ 1e-6 rad). A 30 % wrong controller model tracks much worse but stays
/// close under the PD loop.
#[test]
fn puma_exact_model_tracks_and_wrong_model_does_not() {
    let chain = puma();
    let reference = fourier(6, 1.0);
    let err = tracking_converges(&chain, &reference, 5.0);
    assert!(err < 1e-3, "tracking error {err} rad");

    let wrong_inertial: Vec<[f64; 10]> = chain
        .inertial()
        .iter()
        .map(|p| p.map(|x| 0.7 * x))
        .collect();
    let wrong = chain.clone().with_inertial(wrong_inertial).unwrap();
    let rec = simulate_dyn_closed_loop(&chain, &wrong, &reference, 5.0, &noiseless(6)).unwrap();
    let err_wrong = max_abs_diff(&rec.q, &rec.q_ref);
    assert!(
        err_wrong > 10.0 * err && err_wrong < 0.1,
        "wrong-model error {err_wrong} vs exact {err}"
    );
    eprintln!(
        "PUMA tracking error: exact model {err:.2e} rad, 30 % wrong model {err_wrong:.2e} rad"
    );
}

/// The controller may be a base-parameter model at β (what an identification returns):
/// at the true β it tracks exactly like the full chain.
#[test]
fn base_model_controller_at_true_beta_equals_chain_controller() {
    let chain = puma();
    let model = base_model(&chain);
    let beta = model.chain_base_values().clone();
    let ctrl = ParameterisedModel::new(model, beta).unwrap();
    let reference = fourier(6, 0.8);
    let a = simulate_dyn_closed_loop(&chain, &ctrl, &reference, 2.0, &noiseless(6)).unwrap();
    let b = simulate_dyn_closed_loop(&chain, &chain, &reference, 2.0, &noiseless(6)).unwrap();
    let d = max_abs_diff(&a.tau, &b.tau);
    assert!(d < 1e-8, "controller torques differ by {d}");
}

/// A URDF chain (tilted axes, a prismatic joint, merged bodies) follows sinusoids and a
/// trajectory sampled from arrays.
#[test]
fn urdf_fixture_follows_sinusoids_and_sampled_trajectory() {
    let chain = three_joint_urdf();
    let sines: Vec<Sinusoid> = (0..3)
        .map(|j| Sinusoid {
            offset: 0.02 * j as f64,
            amplitude: 0.05 + 0.1 * j as f64,
            omega: 2.0 + j as f64,
            phase: -std::f64::consts::FRAC_PI_2,
        })
        .collect();
    let err = tracking_converges(&chain, &sines, 3.0);
    assert!(err < 1e-3, "sinusoid tracking error {err}");

    // The same motion as samples at 50 Hz: between samples the quintic interpolation is
    // exact to O(dt⁶·q⁽⁶⁾), so the robot tracks the sinusoid itself to ~1e-6.
    let rows = 151;
    let t: Vec<f64> = (0..rows).map(|k| 0.02 * k as f64).collect();
    let (mut q, mut qd, mut qdd) = (
        vec![0.0; 3 * rows],
        vec![0.0; 3 * rows],
        vec![0.0; 3 * rows],
    );
    for (k, &tk) in t.iter().enumerate() {
        let r = 3 * k..3 * k + 3;
        sines.eval_into(tk, &mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r]);
    }
    let sampled = DynSampledTrajectory::new(3, t, q, qd, qdd).unwrap();
    let rec = simulate_dyn_closed_loop(&chain, &chain, &sampled, 3.0, &noiseless(3)).unwrap();
    let (mut qs, mut v, mut a) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    let mut worst: f64 = 0.0;
    for k in 0..rec.len() {
        sines.eval_into(rec.t[k], &mut qs, &mut v, &mut a);
        worst = worst.max(max_abs_diff(&qs, &rec.q[3 * k..3 * k + 3]));
    }
    assert!(worst < 1e-3, "sampled-reference tracking error {worst}");
    // Past the end of the samples is refused.
    assert!(matches!(
        simulate_dyn_closed_loop(&chain, &chain, &sampled, 3.5, &noiseless(3)),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}

/// Gauss–Legendre nodes and weights on [0, 1] (8 points, exact for degree 15).
const GL8: [(f64, f64); 8] = [
    (0.019855071751231912, 0.05061426814518853),
    (0.10166676129318664, 0.11119051722668721),
    (0.2372337950418355, 0.15685332293894344),
    (0.4082826787521751, 0.18134189168918083),
    (0.5917173212478248, 0.18134189168918083),
    (0.7627662049581645, 0.15685332293894344),
    (0.8983332387068134, 0.11119051722668721),
    (0.9801449282487681, 0.05061426814518853),
];

/// Largest per-sample imbalance |ΔT + ΔV − τᵀΔq| (J) and the largest work (J) of a PUMA
/// without friction under a piecewise-constant torque. T = ½q̇ᵀM(q)q̇ from the mass
/// matrix; ΔV = ∫G(q)·dq along the straight segment between consecutive samples (G is a
/// gradient, so the path does not matter), by 8-point Gauss–Legendre. With the torque
/// held over each sample the work is exactly τ_kᵀ(q_{k+1} − q_k).
fn energy_balance(substeps: usize) -> (f64, f64) {
    let chain = SerialChain::puma560().to_dyn();
    let n = 6;
    let samples = 150;
    let mut ws = chain.workspace();
    let q0 = vec![0.1, -0.4, 0.3, 0.0, 0.5, -0.2];
    let mut g = vec![0.0; n];
    chain.gravity_torques_into(&mut ws, &q0, &mut g).unwrap();
    // Gravity compensation at the start plus sinusoidal torques.
    let tau: Vec<f64> = (0..samples)
        .flat_map(|k| {
            let t = 0.02 * k as f64;
            let g = g.clone();
            // Amplitudes scaled to the links' inertias (the wrist's are ~1e-4 kg·m²).
            let amp = [2.0, 2.0, 0.5, 0.005, 0.005, 0.001];
            (0..n).map(move |j| g[j] + amp[j] * ((1.0 + 0.3 * j as f64) * t).sin())
        })
        .collect();
    let cfg = DynSimulationConfig {
        dt: 0.02,
        substeps,
        ..DynSimulationConfig::new(n)
    };
    let rec = simulate_dyn_open_loop(&chain, &q0, &vec![0.0; n], &tau, &cfg).unwrap();
    let mut m = vec![0.0; n * n];
    let mut kinetic = |q: &[f64], qd: &[f64]| {
        chain.mass_matrix_into(&mut ws, q, &mut m).unwrap();
        let mut e = 0.0;
        for i in 0..n {
            for j in 0..n {
                e += 0.5 * qd[i] * m[i * n + j] * qd[j];
            }
        }
        e
    };
    let mut ws2 = chain.workspace();
    let (mut max_err, mut max_work) = (0.0f64, 0.0f64);
    for k in 0..samples - 1 {
        let (a, b) = (n * k..n * k + n, n * k + n..n * k + 2 * n);
        let (qa, qb) = (&rec.q[a.clone()], &rec.q[b.clone()]);
        let dq: Vec<f64> = qb.iter().zip(qa).map(|(x, y)| x - y).collect();
        let mut dv = 0.0;
        let mut qs = vec![0.0; n];
        for (s, w) in GL8 {
            for j in 0..n {
                qs[j] = qa[j] + s * dq[j];
            }
            chain.gravity_torques_into(&mut ws2, &qs, &mut g).unwrap();
            dv += w * g.iter().zip(&dq).map(|(x, y)| x * y).sum::<f64>();
        }
        let dt_kin = kinetic(qb, &rec.qd[b]) - kinetic(qa, &rec.qd[a.clone()]);
        let work: f64 = tau[a].iter().zip(&dq).map(|(x, y)| x * y).sum();
        max_err = max_err.max((dt_kin + dv - work).abs());
        max_work = max_work.max(work.abs());
    }
    (max_err, max_work)
}

#[test]
fn open_loop_energy_balance_holds_to_fourth_order() {
    let (err, work) = energy_balance(20);
    let (err_half, _) = energy_balance(40);
    eprintln!("PUMA energy balance: {err:.2e} J at h = 1 ms, {err_half:.2e} J at 0.5 ms (work {work:.2e} J)");
    assert!(work > 1e-2, "the torques did no work: {work} J");
    // Measured: 5.9e-8 J per sample at h = 1 ms and 3.7e-9 J at 0.5 ms (16×: RK4's
    // fourth order), with up to 2.7 J of work per sample. A mass matrix inconsistent with
    // the bias forces or gravity would leave an imbalance of the order of the work.
    assert!(err < 1e-6, "energy balance off by {err} J (work {work} J)");
    assert!(
        err_half < err / 8.0,
        "not fourth order: {err} -> {err_half}"
    );
}

/// Noise on q, q̇ and τ with per-joint σ: sample std within 4 standard errors of σ, mean
/// near 0; same seed → same record; another seed → other noise, same true motion.
#[test]
fn noise_has_configured_statistics_and_is_seeded() {
    let chain = puma();
    let n = 6;
    let reference = fourier(n, 0.5);
    let cfg = DynSimulationConfig {
        noise: DynSensorNoise {
            q_std: (0..n).map(|j| 1e-4 * (j + 1) as f64).collect(),
            qd_std: Some((0..n).map(|j| 1e-3 * (j + 1) as f64).collect()),
            tau_std: (0..n).map(|j| 0.05 * (j + 1) as f64).collect(),
        },
        seed: 7,
        ..DynSimulationConfig::new(n)
    };
    let rec = simulate_dyn_closed_loop(&chain, &chain, &reference, 8.0, &cfg).unwrap();
    let samples = rec.len() as f64;
    let qd_measured = rec.qd_measured.clone().expect("velocities measured");
    for (meas, truth, std) in [
        (&rec.q_measured, &rec.q, &cfg.noise.q_std),
        (&qd_measured, &rec.qd, cfg.noise.qd_std.as_ref().unwrap()),
        (&rec.tau_measured, &rec.tau, &cfg.noise.tau_std),
    ] {
        for (j, &sigma) in std.iter().enumerate() {
            let e: Vec<f64> = meas
                .iter()
                .zip(truth)
                .skip(j)
                .step_by(n)
                .map(|(m, t)| m - t)
                .collect();
            let mean = e.iter().sum::<f64>() / samples;
            let sd = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (samples - 1.0)).sqrt();
            // 801 samples: the sample std has a relative spread 1/√(2·801) = 2.5 %, the
            // mean σ/√801 = 0.035σ.
            assert!(
                (sd / sigma - 1.0).abs() < 0.1,
                "joint {j}: std {sd} vs {sigma}"
            );
            assert!(mean.abs() < 0.15 * sigma, "joint {j}: mean {mean}");
        }
    }
    let again = simulate_dyn_closed_loop(&chain, &chain, &reference, 8.0, &cfg).unwrap();
    assert_eq!(rec, again);
    let other = simulate_dyn_closed_loop(
        &chain,
        &chain,
        &reference,
        8.0,
        &DynSimulationConfig {
            seed: 8,
            ..cfg.clone()
        },
    )
    .unwrap();
    assert_ne!(rec.q_measured, other.q_measured);
    assert_eq!(rec.q, other.q);
    // The measured record becomes an identification data set by the log pipeline.
    let (data, report) = rec.measured_dataset(&Default::default()).unwrap();
    assert_eq!(data.dof(), n);
    assert!(report.measured_velocity);
}

/// The validation of a perfect model on noiseless simulated data: RMS 0, RSD 0, AI 1;
/// of a wrong one: clearly worse.
#[test]
fn torque_validation_of_simulated_data() {
    let chain = puma();
    let rec =
        simulate_dyn_closed_loop(&chain, &chain, &fourier(6, 1.0), 4.0, &noiseless(6)).unwrap();
    let data = rec.true_dataset().unwrap();
    let v = validate_torque_prediction(&chain, &data).unwrap();
    for e in &v.indices {
        assert!(
            e.rms < 1e-9 && e.rsd < 1e-9 && (1.0 - e.ai) < 1e-12,
            "{e:?}"
        );
    }
    let wrong = chain
        .clone()
        .with_inertial(
            chain
                .inertial()
                .iter()
                .map(|p| p.map(|x| 1.2 * x))
                .collect(),
        )
        .unwrap();
    let w = validate_torque_prediction(&wrong, &data).unwrap();
    // 20 % heavier links: every joint's prediction is off (the wrist's by ~1e-5 N·m).
    assert!(
        w.indices.iter().all(|e| e.rms > 1e-6 && e.ai < 1.0 - 1e-9),
        "{:?}",
        w.indices
    );
    // Joint-count mismatch is a typed error.
    let three = three_joint_urdf();
    assert!(matches!(
        validate_torque_prediction(&three, &data),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}

#[test]
fn bad_inputs_are_typed_errors() {
    let chain = puma();
    let reference = fourier(6, 1.0);
    let three = fourier(3, 1.0);
    let cfg = noiseless(6);
    let e = simulate_dyn_closed_loop(&chain, &chain, &three, 1.0, &cfg).unwrap_err();
    assert!(
        matches!(e, PrrrpError::ShapeMismatch { ref what, .. } if what == "reference"),
        "{e}"
    );
    let short = DynSimulationConfig {
        kp: vec![400.0; 5],
        ..noiseless(6)
    };
    assert!(matches!(
        simulate_dyn_closed_loop(&chain, &chain, &reference, 1.0, &short),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    for dt in [0.0, -0.01, f64::NAN, f64::INFINITY] {
        let bad = DynSimulationConfig { dt, ..noiseless(6) };
        assert!(matches!(
            simulate_dyn_closed_loop(&chain, &chain, &reference, 1.0, &bad),
            Err(PrrrpError::InvalidParameter { ref field, .. }) if field == "dt"
        ));
    }
    let mut neg = noiseless(6);
    neg.noise.tau_std[2] = -1.0;
    assert!(matches!(
        simulate_dyn_closed_loop(&chain, &chain, &reference, 1.0, &neg),
        Err(PrrrpError::InvalidParameter { ref field, .. }) if field.contains("joint 3")
    ));
    for d in [f64::NAN, -1.0, 1e12] {
        assert!(simulate_dyn_closed_loop(&chain, &chain, &reference, d, &cfg).is_err());
    }
    // Too many RK4 steps are refused before anything runs.
    let fine = DynSimulationConfig {
        dt: 0.1,
        substeps: 100_000_000,
        ..noiseless(6)
    };
    assert!(matches!(
        simulate_dyn_closed_loop(&chain, &chain, &reference, 10.0, &fine),
        Err(PrrrpError::InvalidParameter { ref field, .. }) if field == "substeps"
    ));
    // Open loop: a NaN torque row, a wrong row length, and a blow-up that names the
    // joint and time.
    let mut tau = vec![0.0; 6 * 10];
    tau[6 * 4 + 2] = f64::NAN;
    assert_eq!(
        simulate_dyn_open_loop(&chain, &[0.0; 6], &[0.0; 6], &tau, &cfg).unwrap_err(),
        PrrrpError::NonFinite {
            what: "tau".into(),
            row: Some(4)
        }
    );
    assert!(matches!(
        simulate_dyn_open_loop(&chain, &[0.0; 6], &[0.0; 6], &[0.0; 7], &cfg),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let huge = vec![1e200; 6 * 50];
    match simulate_dyn_open_loop(&chain, &[0.0; 6], &[0.0; 6], &huge, &cfg) {
        Err(PrrrpError::SimulationDiverged {
            sample,
            time,
            joint,
            ..
        }) => {
            assert!(
                joint < 6 && time > 0.0 && sample >= 1,
                "{sample} {time} {joint}"
            );
            assert!(time <= 0.01 * sample as f64 + 1e-12);
        }
        other => panic!("expected a divergence error, got {other:?}"),
    }
}

/// The Panda of `example-robot-data` with friction tracks a Fourier excitation with its
/// exact model, and its recorded torques are its inverse dynamics.
#[test]
fn panda_urdf_tracks_with_exact_model() {
    let Some(dir) = robots_dir() else {
        eprintln!("example-robot-data not found (set PRRRP_ROBOTS_DIR): Panda test skipped");
        return;
    };
    let opts = UrdfOptions {
        tip: Some("panda_link8".into()),
        ..UrdfOptions::default()
    };
    let panda = with_smoothed_friction(
        DynChain::from_urdf_file(dir.join("panda_description/urdf/panda.urdf"), &opts).unwrap(),
        0.1,
        vec![
            [0.6, 0.4, 0.05],
            [0.6, 0.4, 0.05],
            [0.6, 0.4, 0.05],
            [0.6, 0.4, 0.05],
            [0.1, 0.05, 0.01],
            [0.1, 0.05, 0.01],
            [0.02, 0.01, 0.005],
        ],
    );
    let err = tracking_converges(&panda, &fourier(7, 0.5), 5.0);
    assert!(err < 1e-3, "Panda tracking error {err}");
    eprintln!("Panda tracking error with the exact model: {err:.2e} rad");
}

/// The slice interface of a parameterised model (what the simulators call) checks every
/// length, naming the first wrong slice (the inputs in order, then the output), and hands
/// the values to the model unchanged: its τ is the model's own inverse dynamics, and its
/// forward dynamics inverts that τ (forward ∘ inverse = identity).
#[test]
fn parameterised_model_slices_reach_the_model_unchanged() {
    use prrrp_core::{Dynamics, Robot, Vec5};
    let robot = Robot::paper();
    let model = robot.model();
    let lam = robot.base_parameters();
    let plant = ParameterisedModel::new(model, lam).unwrap();
    let mut ws = plant.workspace();
    let what = |r: Result<(), PrrrpError>| match r {
        Err(PrrrpError::ShapeMismatch { what, .. }) => what,
        other => panic!("expected a shape mismatch, got {other:?}"),
    };
    let (ok, short, mut out) = ([0.1; 5], [0.1; 4], [0.0; 5]);
    let id = plant.inverse_dynamics_into(&mut ws, &ok, &short, &short, &mut out);
    assert_eq!(what(id), "qd");
    let id = plant.inverse_dynamics_into(&mut ws, &ok, &ok, &ok, &mut [0.0; 4]);
    assert_eq!(what(id), "tau");
    let fd = plant.forward_dynamics_into(&mut ws, &ok, &ok, &short, &mut out);
    assert_eq!(what(fd), "tau");
    let fd = plant.forward_dynamics_into(&mut ws, &ok, &ok, &ok, &mut [0.0; 6]);
    assert_eq!(what(fd), "qdd");

    let q = Vec5::new(0.3, -0.4, 0.9, 1.2, 0.05);
    let qd = Vec5::new(0.2, 1.1, -0.7, 0.5, -0.3);
    let qdd = Vec5::new(-1.5, 0.8, 2.0, -0.6, 0.9);
    let mut tau = [0.0; 5];
    let (qs, qds, qdds) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
    plant
        .inverse_dynamics_into(&mut ws, qs, qds, qdds, &mut tau)
        .unwrap();
    assert_eq!(
        &tau[..],
        model.inverse_dynamics(&q, &qd, &qdd, &lam).as_slice()
    );
    let mut back = [0.0; 5];
    plant
        .forward_dynamics_into(&mut ws, qs, qds, &tau, &mut back)
        .unwrap();
    for (b, a) in back.iter().zip(qdd.iter()) {
        assert!(
            (b - a).abs() < 1e-9 * (1.0 + a.abs()),
            "{back:?} vs {qdd:?}"
        );
    }
}
