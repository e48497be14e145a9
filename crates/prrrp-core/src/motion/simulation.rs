//! Closed-loop (computed torque + PD) and open-loop simulation of the arm with RK4, sampled
//! at a fixed rate, with seeded Gaussian sensor noise on the recorded positions and
//! torques.

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::data::dataset::Dataset;
use crate::data::preprocess::{preprocess, PreprocessConfig};
use crate::error::{PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{Lambda, Vec5, NDOF};
use crate::motion::trajectory::{JointTrajectory, TrajectoryPoint};

/// Standard deviations of the Gaussian noise added to the recorded ("measured") positions
/// and generalised forces, per joint [d1, θ2, θ3, θ4, d5].
///
/// Defaults, and why they are realistic for an arm of this size:
/// - positions: 1e-5 m for d1, d5 and 1e-4 rad for θ2..θ4. A 4096-line incremental
///   encoder read in quadrature (16384 counts/rev) has a step of 3.8e-4 rad, i.e. a
///   quantisation noise of 3.8e-4/√12 ≈ 1.1e-4 rad; a linear axis with a 1 µm-class
///   scale or a 5 mm-lead screw with such an encoder reads to about 1e-5 m.
/// - generalised forces: 0.5 N for F1, 0.03 N·m for τ2, 0.015 N·m for τ3, 0.007 N·m for
///   τ4 and 0.05 N for F5, about 1 % of each joint's peak on the default optimised
///   excitation (measured over seeds 0–2: F1 ≈ 47.8 N, mostly holding the arm up;
///   τ2 2.1–3.2 N·m; τ3 1.3–1.5 N·m; τ4 0.5–0.9 N·m; F5 ≈ 5.1 N): the usual accuracy of
///   torques estimated from motor currents.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorNoise {
    /// Position noise std (m, rad).
    pub q_std: Vec5,
    /// Generalised-force noise std (N, N·m).
    pub tau_std: Vec5,
}

impl Default for SensorNoise {
    fn default() -> Self {
        Self {
            q_std: Vec5::new(1e-5, 1e-4, 1e-4, 1e-4, 1e-5),
            tau_std: Vec5::new(0.5, 0.03, 0.015, 0.007, 0.05),
        }
    }
}

impl SensorNoise {
    /// No noise: measured equals true.
    pub fn none() -> Self {
        Self {
            q_std: Vec5::zeros(),
            tau_std: Vec5::zeros(),
        }
    }
}

/// Settings of the simulators. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulationConfig {
    /// Output sampling period, s (default 0.02, the paper's).
    pub dt: f64,
    /// RK4 steps per output sample (default 20, so the internal step is 1 ms). The
    /// controller runs at every internal step and holds its torque over it (1 kHz).
    pub substeps: usize,
    /// Proportional gains of the PD loop, 1/s² (default 400 = (20 rad/s)²).
    pub kp: Vec5,
    /// Derivative gains of the PD loop, 1/s (default 40 = 2·1·20, critically damped).
    pub kd: Vec5,
    /// Sensor noise (default [`SensorNoise::default`]).
    pub noise: SensorNoise,
    /// Seed of the noise generator (ChaCha8; default 0).
    pub seed: u64,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            dt: 0.02,
            substeps: 20,
            kp: Vec5::repeat(400.0),
            kd: Vec5::repeat(40.0),
            noise: SensorNoise::default(),
            seed: 0,
        }
    }
}

impl SimulationConfig {
    fn validate(&self) -> Result<()> {
        let bad = |field: String, value: f64, reason: &'static str| PrrrpError::InvalidParameter {
            field,
            value,
            reason,
        };
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(bad("dt".into(), self.dt, "must be finite and > 0 s"));
        }
        if self.substeps == 0 {
            return Err(bad("substeps".into(), 0.0, "must be at least 1"));
        }
        for (name, v) in [
            ("kp", &self.kp),
            ("kd", &self.kd),
            ("noise.q_std", &self.noise.q_std),
            ("noise.tau_std", &self.noise.tau_std),
        ] {
            for j in 0..NDOF {
                if !(v[j].is_finite() && v[j] >= 0.0) {
                    return Err(bad(
                        format!("{name}[{j}] (joint {})", j + 1),
                        v[j],
                        "must be finite and >= 0",
                    ));
                }
            }
        }
        // The feedback acts through a torque held over each internal step h; the
        // discrete loop is well damped only for kd·h ≤ 1 and kp·h² ≤ 1.
        let h = self.dt / self.substeps as f64;
        let worst = (self.kd.max() * h).max(self.kp.max() * h * h);
        if worst > 1.0 {
            return Err(bad(
                "substeps".into(),
                self.substeps as f64,
                "the internal step dt/substeps is too long for the PD gains \
                 (need kd·h <= 1 and kp·h² <= 1): increase substeps or lower the gains",
            ));
        }
        Ok(())
    }
}

/// Computed-torque control with PD feedback:
/// τ = M̂(q)·(q̈_r + Kd·(q̇_r − q̇) + Kp·(q_r − q)) + Ĉ(q, q̇)·q̇ + Ĝ,
/// where M̂, Ĉ, Ĝ use the controller's parameters `lambda` (which may differ from the
/// robot's, to simulate a wrong model).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComputedTorque {
    /// The controller's model (gravity).
    pub model: PrrrpModel,
    /// The controller's base parameters λ̂.
    pub lambda: Lambda,
    /// Proportional gains, 1/s².
    pub kp: Vec5,
    /// Derivative gains, 1/s.
    pub kd: Vec5,
}

impl ComputedTorque {
    /// The generalised force for the reference point `r` at state (q, q̇) (N, N·m).
    /// Allocation-free.
    #[inline]
    pub fn torque(&self, r: &TrajectoryPoint, q: &Vec5, qd: &Vec5) -> Vec5 {
        let v = r.qdd + self.kd.component_mul(&(r.qd - qd)) + self.kp.component_mul(&(r.q - q));
        self.model.inverse_dynamics(q, qd, &v, &self.lambda)
    }
}

/// One classical Runge–Kutta step of length `h` (s) of q̈ = M⁻¹(τ − C·q̇ − G) with τ held
/// constant; returns (q, q̇) at t + h. Allocation-free.
///
/// # Errors
/// [`PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite at a stage.
#[inline]
pub fn rk4_step(
    model: &PrrrpModel,
    lambda: &Lambda,
    q: &Vec5,
    qd: &Vec5,
    tau: &Vec5,
    h: f64,
) -> Result<(Vec5, Vec5)> {
    let f = |q: &Vec5, qd: &Vec5| model.forward_dynamics(q, qd, tau, lambda);
    let a1 = f(q, qd)?;
    let (q2, v2) = (q + 0.5 * h * qd, qd + 0.5 * h * a1);
    let a2 = f(&q2, &v2)?;
    let (q3, v3) = (q + 0.5 * h * v2, qd + 0.5 * h * a2);
    let a3 = f(&q3, &v3)?;
    let (q4, v4) = (q + h * v3, qd + h * a3);
    let a4 = f(&q4, &v4)?;
    Ok((
        q + h / 6.0 * (qd + 2.0 * v2 + 2.0 * v3 + v4),
        qd + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
    ))
}

/// What a simulation recorded at each output sample t_k = k·dt.
///
/// The true signals are consistent: `tau[k]` = inverse dynamics(`q[k]`, `qd[k]`, `qdd[k]`) with
/// the robot's λ. The measured ones carry the configured sensor noise.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimulationRecord {
    /// Time stamps, s.
    pub t: Vec<f64>,
    /// Reference positions (empty for open-loop runs).
    pub q_ref: Vec<Vec5>,
    /// Reference velocities (empty for open-loop runs).
    pub qd_ref: Vec<Vec5>,
    /// Reference accelerations (empty for open-loop runs).
    pub qdd_ref: Vec<Vec5>,
    /// True positions (m, rad).
    pub q: Vec<Vec5>,
    /// True velocities (m/s, rad/s).
    pub qd: Vec<Vec5>,
    /// True accelerations at the sample instant, under the torque applied from it
    /// (m/s², rad/s²).
    pub qdd: Vec<Vec5>,
    /// Generalised forces applied from the sample instant (N, N·m).
    pub tau: Vec<Vec5>,
    /// Measured positions: `q` plus Gaussian noise.
    pub q_measured: Vec<Vec5>,
    /// Measured generalised forces: `tau` plus Gaussian noise.
    pub tau_measured: Vec<Vec5>,
}

impl SimulationRecord {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The noise-free signals (t, q, q̇, q̈, τ) as a validated [`Dataset`].
    ///
    /// # Errors
    /// As [`Dataset::new`] (e.g. too few samples).
    pub fn true_dataset(&self) -> Result<Dataset> {
        Dataset::new(
            self.t.clone(),
            self.q.clone(),
            self.qd.clone(),
            self.qdd.clone(),
            self.tau.clone(),
        )
    }

    /// The measured signals (noisy q and τ) turned into a [`Dataset`] by [`preprocess`]:
    /// what an estimator sees on a real robot.
    ///
    /// # Errors
    /// As [`preprocess`].
    pub fn measured_dataset(&self, config: &PreprocessConfig) -> Result<Dataset> {
        preprocess(&self.t, &self.q_measured, &self.tau_measured, config)
    }

    fn with_capacity(n: usize, closed_loop: bool) -> Self {
        let v = || Vec::with_capacity(n);
        let r = || {
            if closed_loop {
                Vec::with_capacity(n)
            } else {
                Vec::new()
            }
        };
        Self {
            t: Vec::with_capacity(n),
            q_ref: r(),
            qd_ref: r(),
            qdd_ref: r(),
            q: v(),
            qd: v(),
            qdd: v(),
            tau: v(),
            q_measured: v(),
            tau_measured: v(),
        }
    }
}

/// Seeded per-joint Gaussian noise.
struct Noise {
    rng: ChaCha8Rng,
    q: [Normal<f64>; NDOF],
    tau: [Normal<f64>; NDOF],
}

impl Noise {
    fn new(cfg: &SensorNoise, seed: u64) -> Result<Self> {
        let normal = |s: f64| {
            Normal::new(0.0, s).map_err(|_| PrrrpError::InvalidParameter {
                field: "noise".into(),
                value: s,
                reason: "noise standard deviations must be finite and >= 0",
            })
        };
        let mut q = [normal(0.0)?; NDOF];
        let mut tau = [normal(0.0)?; NDOF];
        for j in 0..NDOF {
            q[j] = normal(cfg.q_std[j])?;
            tau[j] = normal(cfg.tau_std[j])?;
        }
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            q,
            tau,
        })
    }

    fn sample(&mut self, q: &Vec5, tau: &Vec5) -> (Vec5, Vec5) {
        let mut qm = *q;
        let mut tm = *tau;
        for j in 0..NDOF {
            qm[j] += self.q[j].sample(&mut self.rng);
        }
        for j in 0..NDOF {
            tm[j] += self.tau[j].sample(&mut self.rng);
        }
        (qm, tm)
    }
}

fn check_lambda(name: &str, l: &Lambda) -> Result<()> {
    if let Some(i) = l.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: format!("{name}[{i}]"),
            row: None,
        });
    }
    Ok(())
}

fn check_state(name: &str, v: &Vec5) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(PrrrpError::NonFinite {
            what: name.into(),
            row: None,
        })
    }
}

/// Largest number of RK4 steps (samples × substeps) of one simulation: 2·10⁸, about a
/// minute of computing; more is refused rather than left to run for hours.
pub const MAX_INTEGRATION_STEPS: f64 = 2e8;

fn check_steps(samples: usize, substeps: usize) -> Result<()> {
    let steps = samples as f64 * substeps as f64;
    if steps > MAX_INTEGRATION_STEPS {
        return Err(PrrrpError::InvalidParameter {
            field: "substeps".into(),
            value: substeps as f64,
            reason: "samples × substeps exceeds MAX_INTEGRATION_STEPS (2e8 RK4 steps): \
                     lower substeps or shorten the run",
        });
    }
    Ok(())
}

fn diverged(at: usize) -> PrrrpError {
    PrrrpError::Diverged {
        what: "simulation",
        at,
        hint: "the state became NaN/∞; check the torques, gains and parameters, or \
               increase substeps",
    }
}

/// Simulates the robot with parameters `true_lambda` following `reference` under
/// [`ComputedTorque`] control with the controller's parameters `controller_lambda`, from
/// t = 0 to `duration` (s), starting on the reference.
///
/// Samples are taken at t_k = k·dt for k = 0..=⌊duration/dt⌋.
///
/// # Errors
/// - [`PrrrpError::InvalidParameter`] for a bad configuration (see
///   [`SimulationConfig`]) or a duration that is not finite and ≥ 0;
/// - [`PrrrpError::NonFinite`] for a NaN λ or a reference that is NaN at t = 0;
/// - [`PrrrpError::NotPositiveDefinite`] if the true λ gives a non-positive-definite M;
/// - [`PrrrpError::Diverged`] if the state blows up.
pub fn simulate_closed_loop<T: JointTrajectory + ?Sized>(
    model: &PrrrpModel,
    true_lambda: &Lambda,
    controller_lambda: &Lambda,
    reference: &T,
    duration: f64,
    config: &SimulationConfig,
) -> Result<SimulationRecord> {
    config.validate()?;
    check_lambda("true_lambda", true_lambda)?;
    check_lambda("controller_lambda", controller_lambda)?;
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "duration".into(),
            value: duration,
            reason: "must be finite and >= 0 s",
        });
    }
    let n = crate::interrupt::check_count(
        "duration (in samples of dt)",
        (duration / config.dt + 1e-9).floor() + 1.0,
        "asks for more than MAX_SAMPLES (1e7) samples: shorten the duration or raise dt",
    )?;
    check_steps(n, config.substeps)?;
    if let Some(end) = reference.end_time() {
        // Half a sample of slack absorbs the rounding of duration/dt.
        if duration > end + 0.5 * config.dt {
            return Err(PrrrpError::InvalidParameter {
                field: format!("duration (the reference ends at {end} s)"),
                value: duration,
                reason: "longer than the reference trajectory, which ends at its own \
                         duration (an excitation is defined on [0, duration] only): \
                         simulate at most that long or design a longer excitation",
            });
        }
    }
    let ctrl = ComputedTorque {
        model: *model,
        lambda: *controller_lambda,
        kp: config.kp,
        kd: config.kd,
    };
    let h = config.dt / config.substeps as f64;
    let start = reference.eval(0.0);
    check_state("reference q at t = 0", &start.q)?;
    check_state("reference qd at t = 0", &start.qd)?;
    let (mut q, mut qd) = (start.q, start.qd);
    let mut noise = Noise::new(&config.noise, config.seed)?;
    let mut rec = SimulationRecord::with_capacity(n, true);
    for k in 0..n {
        crate::interrupt::check("simulation")?;
        let t = config.dt * k as f64;
        let r = reference.eval(t);
        let tau = ctrl.torque(&r, &q, &qd);
        let qdd = model.forward_dynamics(&q, &qd, &tau, true_lambda)?;
        let (qm, tm) = noise.sample(&q, &tau);
        rec.t.push(t);
        rec.q_ref.push(r.q);
        rec.qd_ref.push(r.qd);
        rec.qdd_ref.push(r.qdd);
        rec.q.push(q);
        rec.qd.push(qd);
        rec.qdd.push(qdd);
        rec.tau.push(tau);
        rec.q_measured.push(qm);
        rec.tau_measured.push(tm);
        if k + 1 == n {
            break;
        }
        let mut tau_s = tau;
        for s in 0..config.substeps {
            if s > 0 {
                let ts = t + h * s as f64;
                tau_s = ctrl.torque(&reference.eval(ts), &q, &qd);
            }
            (q, qd) = rk4_step(model, true_lambda, &q, &qd, &tau_s, h)?;
        }
        if !(q.iter().chain(qd.iter()).all(|x| x.is_finite())) {
            return Err(diverged(k + 1));
        }
    }
    Ok(rec)
}

/// Simulates the robot with parameters `lambda` from (q0, q̇0) under the torque sequence
/// `tau`, each held constant over one sampling period (zero-order hold): sample k is at
/// t_k = k·dt and `tau[k]` acts on [t_k, t_{k+1}). The PD gains of `config` are unused.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] for a bad configuration; [`PrrrpError::NonFinite`]
/// naming the first NaN/∞ torque row or initial state; [`PrrrpError::NotPositiveDefinite`]
/// for a non-physical λ; [`PrrrpError::Diverged`] if the state blows up.
pub fn simulate_open_loop(
    model: &PrrrpModel,
    lambda: &Lambda,
    q0: &Vec5,
    qd0: &Vec5,
    tau: &[Vec5],
    config: &SimulationConfig,
) -> Result<SimulationRecord> {
    config.validate()?;
    check_lambda("lambda", lambda)?;
    check_state("q0", q0)?;
    check_state("qd0", qd0)?;
    if let Some(row) = tau.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
        return Err(PrrrpError::NonFinite {
            what: "tau".into(),
            row: Some(row),
        });
    }
    check_steps(tau.len(), config.substeps)?;
    let h = config.dt / config.substeps as f64;
    let (mut q, mut qd) = (*q0, *qd0);
    let mut noise = Noise::new(&config.noise, config.seed)?;
    let mut rec = SimulationRecord::with_capacity(tau.len(), false);
    for (k, tk) in tau.iter().enumerate() {
        crate::interrupt::check("simulation")?;
        let qdd = model.forward_dynamics(&q, &qd, tk, lambda)?;
        let (qm, tm) = noise.sample(&q, tk);
        rec.t.push(config.dt * k as f64);
        rec.q.push(q);
        rec.qd.push(qd);
        rec.qdd.push(qdd);
        rec.tau.push(*tk);
        rec.q_measured.push(qm);
        rec.tau_measured.push(tm);
        if k + 1 == tau.len() {
            break;
        }
        for _ in 0..config.substeps {
            (q, qd) = rk4_step(model, lambda, &q, &qd, tk, h)?;
        }
        if !(q.iter().chain(qd.iter()).all(|x| x.is_finite())) {
            return Err(diverged(k + 1));
        }
    }
    Ok(rec)
}
