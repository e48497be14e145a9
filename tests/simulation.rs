//! Simulation: energy conservation, power balance, tracking, consistency of the recorded
//! signals, and the statistics of the sensor noise.

use proptest::prelude::*;
use prrrp_core::{
    simulate_closed_loop, simulate_open_loop, ExcitationTrajectory, Lambda, PiecewiseQuintic,
    PrrrpError, PrrrpModel, Robot, SensorNoise, SimulationConfig, Sinusoid, Vec5,
};

fn reference() -> ExcitationTrajectory<4> {
    let t = [0.0, 1.0, 2.5, 4.0];
    let rq = |a: f64| {
        PiecewiseQuintic::new(
            t,
            [0.0, a, -0.5 * a, 0.3],
            [0.0, 1.0, -0.8, 0.0],
            [0.0, 2.0, 1.0, 0.0],
        )
        .unwrap()
    };
    let s = |c: f64, a: f64, w: f64| Sinusoid {
        offset: c,
        amplitude: a,
        omega: w,
        phase: -std::f64::consts::FRAC_PI_2,
    };
    ExcitationTrajectory {
        prismatic: [
            s(0.15, 0.1, 2.0 * std::f64::consts::PI / 2.0),
            s(0.05, 0.03, 3.0),
        ],
        revolute: [rq(0.8), rq(-1.2), rq(1.5)],
    }
}

fn energy(m: &PrrrpModel, l: &Lambda, q: &Vec5, qd: &Vec5) -> f64 {
    m.kinetic_energy(q, qd, l) + m.potential_energy(q, l)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// With τ = 0 and no gravity the kinetic energy is conserved. RK4 at 1 ms has a local
    /// error ~ (ω·h)⁵ with joint rates ω ≤ 4 rad/s: ~1e-12 per step, so over 2000 steps a
    /// relative drift of 1e-8 is a generous bound that a wrong mass matrix or
    /// integrator (e.g. an Euler step, drift ~ ω·h ≈ 1e-3) would break.
    #[test]
    fn energy_is_conserved_without_torque_and_gravity(
        q in prop::array::uniform5(-2.0..2.0f64),
        qd in prop::array::uniform5(-2.0..2.0f64),
    ) {
        let model = PrrrpModel { gravity: 0.0 };
        let lambda = Robot::paper().base_parameters();
        let (q0, qd0) = (Vec5::from(q), Vec5::from(qd));
        let cfg = SimulationConfig { noise: SensorNoise::none(), ..SimulationConfig::default() };
        let rec = simulate_open_loop(&model, &lambda, &q0, &qd0, &vec![Vec5::zeros(); 101], &cfg).unwrap();
        let e0 = model.kinetic_energy(&q0, &qd0, &lambda);
        for k in 0..rec.len() {
            let e = model.kinetic_energy(&rec.q[k], &rec.qd[k], &lambda);
            prop_assert!((e - e0).abs() <= 1e-8 * e0, "T drifted {e0} -> {e} at sample {k}");
        }
        // The motion is not trivial: the arm did move.
        prop_assert!((rec.q[100] - q0).norm() > 0.1);
    }
}

/// With gravity and a torque held constant over each sample (zero-order hold), the work
/// done over [t_k, t_k+1] is exactly τ_kᵀ(q_{k+1} − q_k), so
/// E_{k+1} − E_k = τ_kᵀ(q_{k+1} − q_k) with E = T + U. Only the RK4 error separates the
/// two sides: measured 2.3e-10 J per sample at h = 1 ms (joint rates up to 18 rad/s),
/// shrinking 16× per halving of h as a 4th-order method must. The bound 2e-9 J leaves a
/// 10× margin; a mass matrix inconsistent with C·q̇ or G would leave an imbalance of order
/// the work itself (≈ 0.1 J).
fn power_balance_error(substeps: usize) -> (f64, f64) {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let n = 200;
    let tau: Vec<Vec5> = (0..n)
        .map(|k| {
            let t = 0.02 * k as f64;
            Vec5::new(
                47.5 + 3.0 * (2.0 * t).sin(),
                0.3 * (1.3 * t).cos(),
                -0.1 * (2.1 * t).sin(),
                0.01 * (0.7 * t).cos(),
                -5.0 + 0.5 * (3.0 * t).sin(),
            )
        })
        .collect();
    let cfg = SimulationConfig {
        noise: SensorNoise::none(),
        substeps,
        ..SimulationConfig::default()
    };
    let rec =
        simulate_open_loop(&model, &lambda, &Vec5::zeros(), &Vec5::zeros(), &tau, &cfg).unwrap();
    let mut max_err: f64 = 0.0;
    let mut max_work: f64 = 0.0;
    for (k, tk) in tau.iter().enumerate().take(n - 1) {
        let de = energy(&model, &lambda, &rec.q[k + 1], &rec.qd[k + 1])
            - energy(&model, &lambda, &rec.q[k], &rec.qd[k]);
        let work = tk.dot(&(rec.q[k + 1] - rec.q[k]));
        max_err = max_err.max((de - work).abs());
        max_work = max_work.max(work.abs());
    }
    (max_err, max_work)
}

#[test]
fn power_balance_under_piecewise_constant_torque() {
    let (err, work) = power_balance_error(20);
    assert!(work > 1e-2, "the torques did no work: {work}");
    assert!(
        err < 2e-9,
        "power balance off by {err} J (max work {work} J)"
    );
    // Fourth order: halving the step divides the error by ≈ 16 (at least 8 here).
    let (err_half, _) = power_balance_error(40);
    assert!(err_half < err / 8.0, "{err} -> {err_half}");
}

#[test]
fn recorded_signals_are_consistent_and_tracking_is_tight() {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let cfg = SimulationConfig {
        noise: SensorNoise::none(),
        ..SimulationConfig::default()
    };
    let rec = simulate_closed_loop(&model, &lambda, &lambda, &reference(), 4.0, &cfg).unwrap();
    assert_eq!(rec.len(), 201);
    assert!((rec.t[200] - 4.0).abs() < 1e-12);
    let mut err: f64 = 0.0;
    for k in 0..rec.len() {
        // The applied torque produces the recorded acceleration on the true robot.
        let tau = model.inverse_dynamics(&rec.q[k], &rec.qd[k], &rec.qdd[k], &lambda);
        assert!((tau - rec.tau[k]).amax() < 1e-9 * (1.0 + rec.tau[k].amax()));
        assert_eq!(rec.q_measured[k], rec.q[k]);
        assert_eq!(rec.tau_measured[k], rec.tau[k]);
        err = err.max((rec.q[k] - rec.q_ref[k]).amax());
    }
    // Exact model, starting on the reference: only the 1 ms zero-order hold of the
    // controller separates the robot from the reference (≈ jerk·h²).
    assert!(err < 1e-4, "tracking error {err}");

    // A controller with a 30 % wrong model tracks worse, but the PD loop keeps it close.
    let wrong = lambda * 0.7;
    let rec2 = simulate_closed_loop(&model, &lambda, &wrong, &reference(), 4.0, &cfg).unwrap();
    let err2 = (0..rec2.len())
        .map(|k| (rec2.q[k] - rec2.q_ref[k]).amax())
        .fold(0.0, f64::max);
    assert!(
        err2 > 10.0 * err && err2 < 0.05,
        "wrong-model error {err2} vs {err}"
    );
}

#[test]
fn sensor_noise_has_the_configured_statistics_and_is_seeded() {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let cfg = SimulationConfig::default();
    let rec = simulate_closed_loop(&model, &lambda, &lambda, &reference(), 4.0, &cfg).unwrap();
    let n = rec.len() as f64;
    for (meas, truth, std) in [
        (&rec.q_measured, &rec.q, cfg.noise.q_std),
        (&rec.tau_measured, &rec.tau, cfg.noise.tau_std),
    ] {
        for j in 0..5 {
            let e: Vec<f64> = meas.iter().zip(truth).map(|(m, t)| m[j] - t[j]).collect();
            let mean = e.iter().sum::<f64>() / n;
            let sd = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            // With n = 201 the sample std has a relative spread of 1/√(2n) = 5 %, the mean
            // a spread of σ/√n = 0.07σ: 4-sigma bounds.
            assert!(
                (sd / std[j] - 1.0).abs() < 0.2,
                "joint {j}: std {sd} vs {}",
                std[j]
            );
            assert!(mean.abs() < 0.3 * std[j], "joint {j}: mean {mean}");
        }
    }
    let again = simulate_closed_loop(&model, &lambda, &lambda, &reference(), 4.0, &cfg).unwrap();
    assert_eq!(rec, again);
    let other = simulate_closed_loop(
        &model,
        &lambda,
        &lambda,
        &reference(),
        4.0,
        &SimulationConfig { seed: 1, ..cfg },
    )
    .unwrap();
    assert_ne!(rec.q_measured, other.q_measured);
    assert_eq!(rec.q, other.q);
}

#[test]
fn bad_settings_are_typed_errors() {
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let r = reference();
    let bad = |cfg: SimulationConfig| simulate_closed_loop(&model, &lambda, &lambda, &r, 1.0, &cfg);
    assert!(matches!(
        bad(SimulationConfig {
            substeps: 0,
            ..Default::default()
        }),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // kd·h = 100 · 0.02 = 2 > 1: the held-torque PD loop would ring or blow up.
    assert!(matches!(
        bad(SimulationConfig {
            substeps: 1,
            kd: Vec5::repeat(100.0),
            ..Default::default()
        }),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(matches!(
        bad(SimulationConfig {
            dt: f64::NAN,
            ..Default::default()
        }),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let mut noise = SensorNoise::default();
    noise.tau_std[3] = -1.0;
    assert!(matches!(
        bad(SimulationConfig {
            noise,
            ..Default::default()
        }),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // An open-loop run from rest under `tau`.
    let from_rest = |l: &Lambda, tau: &[Vec5]| {
        let rest = Vec5::zeros();
        simulate_open_loop(&model, l, &rest, &rest, tau, &Default::default())
    };
    let mut tau = vec![Vec5::zeros(); 10];
    tau[6][2] = f64::NAN;
    assert_eq!(
        from_rest(&lambda, &tau),
        Err(PrrrpError::NonFinite {
            what: "tau".into(),
            row: Some(6)
        })
    );
    let mut l = lambda;
    l[4] = -1.0;
    assert_eq!(
        from_rest(&l, &[Vec5::zeros(); 3]),
        Err(PrrrpError::NotPositiveDefinite {
            what: "mass matrix M(q, λ)"
        })
    );
}
