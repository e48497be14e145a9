//! Closed-loop (computed torque + PD) and open-loop simulation of a robot with RK4,
//! sampled at a fixed rate, with seeded Gaussian sensor noise on the recorded positions,
//! torques and (optionally) velocities.
//!
//! One implementation for every robot: [`simulate_dyn_closed_loop`] and
//! [`simulate_dyn_open_loop`] take any [`Dynamics`] (a [`crate::DynChain`] with its
//! friction, a [`ParameterisedModel`]) with n joints known at run time and return a
//! [`DynSimulationRecord`]. The paper arm's [`simulate_closed_loop`] and
//! [`simulate_open_loop`] are those functions on the closed-form model at λ, with the
//! arm's [`Vec5`] record.
//!
//! Per step nothing is allocated: the buffers of [`Rk4Integrator`] and
//! [`DynComputedTorque`] are sized once, and the record's columns are reserved for the
//! whole run before it starts.

use rand::rngs::ChaCha8Rng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::data::dataset::Dataset;
use crate::data::preprocess::{preprocess, PreprocessConfig};
use crate::data::{preprocess_log, DynDataset, LogConfig, LogReport};
use crate::error::{check_joints, check_lens, invalid, PrrrpError, Result};
use crate::models::chain::{cholesky_in_place, cholesky_solve};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{Lambda, Vec5, NDOF};
use crate::motion::dynamics::{Dynamics, ParameterisedModel};
use crate::motion::trajectory::{DynTrajectory, JointTrajectory, TrajectoryPoint};

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
        DynSimulationConfig::from(self).validate(NDOF)
    }
}

/// Standard deviations of the Gaussian sensor noise of a robot with n joints (units of
/// each joint: m or rad; m/s or rad/s; N or N·m). Zero entries record that signal exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct DynSensorNoise {
    /// Position noise std per joint (n entries).
    pub q_std: Vec<f64>,
    /// Velocity noise std per joint when velocities are measured too (n entries), `None`
    /// when they are not (most robots log positions and torques only).
    pub qd_std: Option<Vec<f64>>,
    /// Generalised-force noise std per joint (n entries).
    pub tau_std: Vec<f64>,
}

impl DynSensorNoise {
    /// No noise on q and τ, velocities not measured.
    pub fn none(n: usize) -> Self {
        Self {
            q_std: vec![0.0; n],
            qd_std: None,
            tau_std: vec![0.0; n],
        }
    }

    /// The same std for every joint: `q_std` on positions, `tau_std` on torques.
    pub fn uniform(n: usize, q_std: f64, tau_std: f64) -> Self {
        Self {
            q_std: vec![q_std; n],
            qd_std: None,
            tau_std: vec![tau_std; n],
        }
    }
}

impl From<&SensorNoise> for DynSensorNoise {
    fn from(s: &SensorNoise) -> Self {
        Self {
            q_std: s.q_std.as_slice().to_vec(),
            qd_std: None,
            tau_std: s.tau_std.as_slice().to_vec(),
        }
    }
}

/// Settings of the simulators of a robot with n joints. [`DynSimulationConfig::new`] gives
/// documented defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct DynSimulationConfig {
    /// Output sampling period, s (the record's rate is 1/dt).
    pub dt: f64,
    /// RK4 steps per output sample. The controller runs at every internal step
    /// h = dt/substeps and holds its torque over it.
    pub substeps: usize,
    /// Proportional gains of the PD loop per joint, 1/s² (n entries).
    pub kp: Vec<f64>,
    /// Derivative gains of the PD loop per joint, 1/s (n entries).
    pub kd: Vec<f64>,
    /// Sensor noise.
    pub noise: DynSensorNoise,
    /// Seed of the noise generator (ChaCha8).
    pub seed: u64,
}

impl DynSimulationConfig {
    /// Defaults for n joints: 100 Hz record (dt = 0.01 s), 10 RK4 steps per sample (a
    /// 1 kHz controller), kp = 400 1/s² and kd = 40 1/s (critically damped at 20 rad/s),
    /// no sensor noise (its size depends on the robot's sensors: set it), seed 0.
    pub fn new(n: usize) -> Self {
        Self {
            dt: 0.01,
            substeps: 10,
            kp: vec![400.0; n],
            kd: vec![40.0; n],
            noise: DynSensorNoise::none(n),
            seed: 0,
        }
    }

    /// Checks the settings for a robot of `n` joints.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-finite or non-positive dt, zero
    /// substeps, a negative or non-finite gain or noise std (naming the joint), or an
    /// internal step too long for the gains; [`PrrrpError::ShapeMismatch`] for a gain or
    /// noise vector without n entries.
    pub fn validate(&self, n: usize) -> Result<()> {
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(invalid("dt", self.dt, "must be finite and > 0 s"));
        }
        if self.substeps == 0 {
            return Err(invalid("substeps", 0.0, "must be at least 1"));
        }
        let mut vectors = vec![
            ("kp", self.kp.as_slice()),
            ("kd", self.kd.as_slice()),
            ("noise.q_std", self.noise.q_std.as_slice()),
            ("noise.tau_std", self.noise.tau_std.as_slice()),
        ];
        if let Some(v) = &self.noise.qd_std {
            vectors.push(("noise.qd_std", v.as_slice()));
        }
        for (name, v) in vectors {
            check_joints(name, v.len(), n)?;
            for (j, &x) in v.iter().enumerate() {
                if !(x.is_finite() && x >= 0.0) {
                    return Err(invalid(
                        format!("{name}[{j}] (joint {})", j + 1),
                        x,
                        "must be finite and >= 0",
                    ));
                }
            }
        }
        // The feedback acts through a torque held over each internal step h; the
        // discrete loop is well damped only for kd·h ≤ 1 and kp·h² ≤ 1.
        let h = self.dt / self.substeps as f64;
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        let worst = (max(&self.kd) * h).max(max(&self.kp) * h * h);
        if worst > 1.0 {
            return Err(invalid(
                "substeps",
                self.substeps as f64,
                "the internal step dt/substeps is too long for the PD gains \
                 (need kd·h <= 1 and kp·h² <= 1): increase substeps or lower the gains",
            ));
        }
        Ok(())
    }
}

impl From<&SimulationConfig> for DynSimulationConfig {
    fn from(c: &SimulationConfig) -> Self {
        Self {
            dt: c.dt,
            substeps: c.substeps,
            kp: c.kp.as_slice().to_vec(),
            kd: c.kd.as_slice().to_vec(),
            noise: DynSensorNoise::from(&c.noise),
            seed: c.seed,
        }
    }
}

/// The PD law of computed-torque control, per joint: the commanded acceleration
/// v = q̈_r + Kd·(q̇_r − q̇) + Kp·(q_r − q). Slices of equal length n (checked by the
/// callers once).
#[inline(always)]
fn pd_acceleration(
    kp: &[f64],
    kd: &[f64],
    (q_r, qd_r, qdd_r): (&[f64], &[f64], &[f64]),
    q: &[f64],
    qd: &[f64],
    v: &mut [f64],
) {
    for j in 0..v.len() {
        v[j] = qdd_r[j] + kd[j] * (qd_r[j] - qd[j]) + kp[j] * (q_r[j] - q[j]);
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
        let mut v = Vec5::zeros();
        pd_acceleration(
            self.kp.as_slice(),
            self.kd.as_slice(),
            (r.q.as_slice(), r.qd.as_slice(), r.qdd.as_slice()),
            q.as_slice(),
            qd.as_slice(),
            v.as_mut_slice(),
        );
        self.model.inverse_dynamics(q, qd, &v, &self.lambda)
    }
}

/// Computed-torque control of a robot with n joints through any [`Dynamics`] model of it
/// (the controller's model: the true robot, an identified one, a deliberately wrong one):
/// τ = ID_ctrl(q, q̇, q̈_r + Kd·(q̇_r − q̇) + Kp·(q_r − q)), friction compensation
/// included when the controller's model has friction.
///
/// Coulomb terms with the exact sign ([`Dynamics::exact_coulomb_into`]) are compensated
/// as feed-forward from the **reference** velocity, fc_j·sgn(q̇_r,j), the usual practice
/// (Armstrong-Hélouvry et al. 1994): compensating at the measured velocity is a relay fed
/// back through a one-step delay, which chatters about q̇ = 0, and a joint held at rest
/// gets no compensation at all, so the PD loop alone must build up fc_j of torque — an
/// error of fc_j/(M_jj·kp): 6.7 rad for a 1.5e-4 kg·m² wrist with fc = 0.4 N·m at
/// kp = 400 s⁻². Smoothed Coulomb terms and the others are evaluated at the measured
/// state. Buffers are sized once by
/// [`DynComputedTorque::new`]; [`DynComputedTorque::torque_into`] allocates nothing.
#[derive(Debug, Clone)]
pub struct DynComputedTorque<'c, C: Dynamics + ?Sized> {
    controller: &'c C,
    ws: C::Workspace,
    kp: Vec<f64>,
    kd: Vec<f64>,
    v: Vec<f64>,
    /// The controller model's exact Coulomb magnitudes (all 0: none).
    fc: Vec<f64>,
}

impl<'c, C: Dynamics + ?Sized> DynComputedTorque<'c, C> {
    /// A controller with the model `controller` and gains `kp` (1/s²), `kd` (1/s), n each.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if a gain vector does not have n entries,
    /// [`PrrrpError::InvalidParameter`] for a negative or non-finite gain.
    pub fn new(controller: &'c C, kp: &[f64], kd: &[f64]) -> Result<Self> {
        let n = controller.dof();
        for (name, v) in [("kp", kp), ("kd", kd)] {
            check_joints(name, v.len(), n)?;
            if let Some(j) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("{name}[{j}] (joint {})", j + 1),
                    value: v[j],
                    reason: "must be finite and >= 0",
                });
            }
        }
        let mut fc = vec![0.0; n];
        controller.exact_coulomb_into(&mut fc);
        Ok(Self {
            controller,
            ws: controller.workspace(),
            kp: kp.to_vec(),
            kd: kd.to_vec(),
            v: vec![0.0; n],
            fc,
        })
    }

    /// The torque (N, N·m) for the reference (q_r, q̇_r, q̈_r) at state (q, q̇), into
    /// `tau`; every slice has n entries.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a slice without n entries.
    #[inline]
    pub fn torque_into(
        &mut self,
        reference: (&[f64], &[f64], &[f64]),
        q: &[f64],
        qd: &[f64],
        tau: &mut [f64],
    ) -> Result<()> {
        let n = self.v.len();
        for (name, len) in [
            ("q_ref", reference.0.len()),
            ("qd_ref", reference.1.len()),
            ("qdd_ref", reference.2.len()),
            ("q", q.len()),
            ("qd", qd.len()),
        ] {
            check_joints(name, len, n)?;
        }
        pd_acceleration(&self.kp, &self.kd, reference, q, qd, &mut self.v);
        self.controller
            .inverse_dynamics_into(&mut self.ws, q, qd, &self.v, tau)?;
        // Exact Coulomb terms are compensated at the reference velocity's sign.
        for j in 0..n {
            if self.fc[j] > 0.0 {
                tau[j] += self.fc[j] * (sgn(reference.1[j]) - sgn(qd[j]));
            }
        }
        Ok(())
    }
}

/// Scratch entries per joint that [`rk4_step_into`] needs.
pub const RK4_SCRATCH_PER_JOINT: usize = 5;

/// One classical Runge–Kutta step of length `h` (s) of q̈ = FD(q, q̇, τ) with τ held
/// constant, updating (q, q̇) in place. `scratch` holds at least
/// [`RK4_SCRATCH_PER_JOINT`]·n values. Allocation-free.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] for slices of the wrong length; the errors of
/// [`Dynamics::forward_dynamics_into`] (e.g. [`PrrrpError::NotPositiveDefinite`]);
/// [`PrrrpError::SimulationDiverged`] if an intermediate stage state is NaN/∞ (with
/// `sample` 0 and `time` 0: the simulators fill in where the step was).
#[inline]
pub fn rk4_step_into<D: Dynamics + ?Sized>(
    plant: &D,
    ws: &mut D::Workspace,
    scratch: &mut [f64],
    q: &mut [f64],
    qd: &mut [f64],
    tau: &[f64],
    h: f64,
) -> Result<()> {
    let n = plant.dof();
    check_joints("q", q.len(), n)?;
    check_joints("qd", qd.len(), n)?;
    check_joints("tau", tau.len(), n)?;
    if scratch.len() < RK4_SCRATCH_PER_JOINT * n {
        return Err(PrrrpError::ShapeMismatch {
            what: "rk4 scratch".into(),
            expected: format!(
                "at least {} entries (5 per joint)",
                RK4_SCRATCH_PER_JOINT * n
            ),
            got: format!("{} entries", scratch.len()),
        });
    }
    rk4_core(scratch, q, qd, h, |q, qd, a| {
        plant.forward_dynamics_into(ws, q, qd, tau, a)
    })
}

/// The classical Runge–Kutta step of q̈ = `accel`(q, q̇) over `h`, on slices of one
/// length n (checked by the callers) with 5·n scratch values.
#[inline]
fn rk4_core(
    scratch: &mut [f64],
    q: &mut [f64],
    qd: &mut [f64],
    h: f64,
    mut accel: impl FnMut(&[f64], &[f64], &mut [f64]) -> Result<()>,
) -> Result<()> {
    let n = q.len();
    let (a, rest) = scratch.split_at_mut(n);
    let (sa, rest) = rest.split_at_mut(n);
    let (qs, rest) = rest.split_at_mut(n);
    let (v, rest) = rest.split_at_mut(n);
    let sq = &mut rest[..n];
    let (half, sixth) = (0.5 * h, h / 6.0);
    // A stage state that overflowed is a blow-up of the integration, not a property of the
    // model at that state (its mass matrix at NaN would fail as "not positive definite").
    let stage_diverged = |qs: &[f64], v: &[f64]| -> Result<()> {
        for (signal, x) in [("q", qs), ("qd", v)] {
            if let Some(joint) = x.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::SimulationDiverged {
                    sample: 0,
                    time: 0.0,
                    joint,
                    signal,
                });
            }
        }
        Ok(())
    };
    // Stage sums are accumulated in the order (x1 + 2·x2) + 2·x3 + x4 of the textbook
    // formula, so the result does not depend on how the stages are stored.
    accel(q, qd, a)?;
    for j in 0..n {
        sa[j] = a[j];
        qs[j] = q[j] + half * qd[j];
        v[j] = qd[j] + half * a[j];
        sq[j] = qd[j] + 2.0 * v[j];
    }
    // Stages 2 and 3 differ only in how far (`c`, s) the next stage state lies and in
    // the weight `w` of its velocity in the position sum.
    for (c, w) in [(half, 2.0), (h, 1.0)] {
        stage_diverged(qs, v)?;
        accel(qs, v, a)?;
        for j in 0..n {
            sa[j] += 2.0 * a[j];
            qs[j] = q[j] + c * v[j];
            v[j] = qd[j] + c * a[j];
            sq[j] += w * v[j];
        }
    }
    stage_diverged(qs, v)?;
    accel(qs, v, a)?;
    for j in 0..n {
        sa[j] += a[j];
        q[j] += sixth * sq[j];
        qd[j] += sixth * sa[j];
    }
    Ok(())
}

/// One classical Runge–Kutta step of length `h` (s) of q̈ = M⁻¹(τ − C·q̇ − G) with τ held
/// constant; returns (q, q̇) at t + h. Allocation-free ([`rk4_step_into`] on the
/// closed-form model with stack buffers).
///
/// # Errors
/// [`PrrrpError::NonFinite`] naming a NaN or infinite entry of q, q̇ or τ;
/// [`PrrrpError::InvalidParameter`] for a step `h` that is not finite;
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
    // Bad inputs, not a blow-up: a NaN q read as a non-physical mass matrix, a NaN step
    // as a diverged simulation.
    crate::models::prrrp::dynamics::check_finite_state(q, qd, tau)?;
    if !h.is_finite() {
        return Err(PrrrpError::InvalidParameter {
            field: "h".into(),
            value: h,
            reason: "the RK4 step must be finite (s)",
        });
    }
    let plant = ParameterisedModel::new(*model, *lambda)?;
    let mut ws = plant.workspace();
    let mut scratch = [0.0; RK4_SCRATCH_PER_JOINT * NDOF];
    let (mut q, mut qd) = (*q, *qd);
    rk4_step_into(
        &plant,
        &mut ws,
        &mut scratch,
        q.as_mut_slice(),
        qd.as_mut_slice(),
        tau.as_slice(),
        h,
    )?;
    Ok((q, qd))
}

/// RK4 integration of one [`Dynamics`] with its buffers sized once
/// ([`Rk4Integrator::new`]); [`Rk4Integrator::step`] allocates nothing.
///
/// # Coulomb friction with the exact sign
///
/// A plant whose [`Dynamics::exact_coulomb_into`] reports Coulomb terms fc_j·sgn(q̇_j) is
/// integrated as the set-valued law those terms are (stick–slip, as in Karnopp's and
/// Leine's event-driven treatment), not as a jump that RK4 would step across:
/// - A joint with q̇_j ≠ 0 slips: its Coulomb torque is fc_j·sgn(q̇_j), **frozen over the
///   step**, so that every RK4 stage sees the same smooth right-hand side.
/// - Where a slipping joint's velocity reaches zero inside a step, the step is cut there
///   (the crossing time is found by regula falsi on the RK4 solution to 1e-10 of the step)
///   and the joint's velocity set to exactly 0.
/// - A joint at q̇_j = 0 sticks (q̈_j = 0, its friction the torque that holds it) while
///   that torque stays within ±fc_j; past it, it slips towards the net force. Several
///   joints at rest are held together; the most overloaded is released first. The test
///   runs at the start of every step and after every cut: the controller's torque, which
///   is what usually breaks a joint loose, only changes there.
///
/// The step then stays fourth order between events, and the friction torque never
/// chatters: no smoothing width to choose, whatever the joint's inertia (a 1.5e-4 kg·m²
/// wrist with fc = 0.4 N·m is a slope of 10⁷ s⁻¹ for a smoothed sign of 0.01 rad/s width,
/// beyond any explicit step). At most 4·n + 4 cuts are made in one step; the rest of
/// such a step keeps its modes (no real motion comes near that).
#[derive(Debug, Clone)]
pub struct Rk4Integrator<'p, P: Dynamics + ?Sized> {
    plant: &'p P,
    ws: P::Workspace,
    scratch: Vec<f64>,
    stick: Option<StickSlip>,
}

/// Buffers and modes of the stick–slip treatment (see [`Rk4Integrator`]).
#[derive(Debug, Clone)]
struct StickSlip {
    /// Exact Coulomb magnitude per joint (0: none).
    fc: Vec<f64>,
    /// Frozen sign of each joint's Coulomb torque: ±1 slipping, 0 stuck or none.
    mode: Vec<f64>,
    /// Stuck joints, in joint order.
    stuck: Vec<usize>,
    tau_eff: Vec<f64>,
    /// M⁻¹ columns of the stuck joints (n each).
    cols: Vec<f64>,
    /// (M⁻¹) restricted to the stuck joints, then its Cholesky factor.
    gram: Vec<f64>,
    /// The friction torques that hold the stuck joints.
    hold: Vec<f64>,
    /// The state at the start of the current (sub)step and the velocity at its end.
    q0: Vec<f64>,
    qd0: Vec<f64>,
    qd1: Vec<f64>,
}

#[inline(always)]
fn sgn(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

impl StickSlip {
    fn new(fc: Vec<f64>) -> Self {
        let n = fc.len();
        Self {
            fc,
            mode: vec![0.0; n],
            stuck: Vec::with_capacity(n),
            tau_eff: vec![0.0; n],
            cols: vec![0.0; n * n],
            gram: vec![0.0; n * n],
            hold: vec![0.0; n],
            q0: vec![0.0; n],
            qd0: vec![0.0; n],
            qd1: vec![0.0; n],
        }
    }
}

/// One step's dynamics in its frozen stick–slip modes: the plant with its workspace, the
/// torque held over the step and the modes' buffers.
struct Frozen<'a, P: Dynamics + ?Sized> {
    plant: &'a P,
    ws: &'a mut P::Workspace,
    tau: &'a [f64],
    st: &'a mut StickSlip,
}

impl<P: Dynamics + ?Sized> Frozen<'_, P> {
    /// q̈ in the frozen modes at a (stage) state. The plant's dynamics apply
    /// fc_j·sgn(q̇_j) at the stage's own velocity; the torque is corrected so that the
    /// frozen sign acts instead, and the stuck joints are held by their friction.
    fn accel(&mut self, q: &[f64], qd: &[f64], a: &mut [f64]) -> Result<()> {
        self.free_accel(q, qd, a)?;
        if self.st.stuck.is_empty() {
            return Ok(());
        }
        self.hold_torques(q, qd, a)?;
        let st = &*self.st;
        let n = a.len();
        for (c, &h) in st.hold[..st.stuck.len()].iter().enumerate() {
            for (x, m) in a.iter_mut().zip(&st.cols[c * n..(c + 1) * n]) {
                *x -= m * h;
            }
        }
        for &j in &st.stuck {
            a[j] = 0.0;
        }
        Ok(())
    }

    /// q̈ with the slipping joints' frozen signs and no friction on the stuck ones.
    fn free_accel(&mut self, q: &[f64], qd: &[f64], a: &mut [f64]) -> Result<()> {
        let (st, tau) = (&mut *self.st, self.tau);
        for j in 0..tau.len() {
            st.tau_eff[j] = tau[j] + st.fc[j] * (sgn(qd[j]) - st.mode[j]);
        }
        self.plant
            .forward_dynamics_into(self.ws, q, qd, &st.tau_eff, a)
    }

    /// The friction torques τ_h that keep the stuck joints S at rest, from the free
    /// acceleration `a0`: (M⁻¹)_SS·τ_h = a0_S, with the columns M⁻¹·e_j from the forward
    /// dynamics (affine in τ). Fills `cols` and `hold`.
    fn hold_torques(&mut self, q: &[f64], qd: &[f64], a0: &[f64]) -> Result<()> {
        let st = &mut *self.st;
        let n = a0.len();
        let k = st.stuck.len();
        for (c, &j) in st.stuck.iter().enumerate() {
            // A unit of the joint's own friction scale keeps the difference well above
            // the round-off of a0.
            let unit = st.fc[j].max(1.0);
            st.tau_eff[j] += unit;
            let col = &mut st.cols[c * n..(c + 1) * n];
            self.plant
                .forward_dynamics_into(self.ws, q, qd, &st.tau_eff, col)?;
            st.tau_eff[j] -= unit;
            for (x, a) in col.iter_mut().zip(a0) {
                *x = (*x - a) / unit;
            }
        }
        for (r, &i) in st.stuck.iter().enumerate() {
            for c in 0..k {
                st.gram[r + k * c] = st.cols[c * n + i];
            }
            st.hold[r] = a0[i];
        }
        cholesky_in_place(&mut st.gram[..k * k], k)?;
        cholesky_solve(&st.gram[..k * k], k, &mut st.hold[..k]);
        Ok(())
    }

    /// The modes at the start of a step: slipping joints take their velocity's sign;
    /// joints at rest stick unless holding them needs more than fc_j, in which case the
    /// most overloaded one slips towards its net force, and the rest are tested again.
    fn set_modes(&mut self, q: &[f64], qd: &[f64], a: &mut [f64]) -> Result<()> {
        let st = &mut *self.st;
        st.stuck.clear();
        for (j, &v) in qd.iter().enumerate() {
            st.mode[j] = if st.fc[j] > 0.0 { sgn(v) } else { 0.0 };
            if st.fc[j] > 0.0 && v == 0.0 {
                st.stuck.push(j);
            }
        }
        while !self.st.stuck.is_empty() {
            self.free_accel(q, qd, a)?;
            self.hold_torques(q, qd, a)?;
            let st = &mut *self.st;
            let mut worst: Option<(usize, f64)> = None;
            for (r, &j) in st.stuck.iter().enumerate() {
                let load = st.hold[r].abs() / st.fc[j];
                if load > 1.0 && worst.map_or(true, |(_, w)| load > w) {
                    worst = Some((r, load));
                }
            }
            let Some((r, _)) = worst else { break };
            let j = st.stuck.remove(r);
            st.mode[j] = sgn(st.hold[r]);
        }
        Ok(())
    }
}

impl<'p, P: Dynamics + ?Sized> Rk4Integrator<'p, P> {
    /// Buffers for `plant` (and for its stick–slip treatment when it has Coulomb terms
    /// with the exact sign).
    pub fn new(plant: &'p P) -> Self {
        let n = plant.dof();
        let mut fc = vec![0.0; n];
        let stick = plant
            .exact_coulomb_into(&mut fc)
            .then(|| StickSlip::new(fc));
        Self {
            plant,
            ws: plant.workspace(),
            scratch: vec![0.0; RK4_SCRATCH_PER_JOINT * n],
            stick,
        }
    }

    /// One RK4 step of length `h` (s) under the torque `tau` held constant, updating
    /// (q, q̇) in place: [`rk4_step_into`], with the stick–slip events of exact Coulomb
    /// terms handled as the type's docs say.
    ///
    /// # Errors
    /// As [`rk4_step_into`].
    #[inline]
    pub fn step(&mut self, q: &mut [f64], qd: &mut [f64], tau: &[f64], h: f64) -> Result<()> {
        let Some(stick) = self.stick.as_mut() else {
            return rk4_step_into(self.plant, &mut self.ws, &mut self.scratch, q, qd, tau, h);
        };
        let n = self.plant.dof();
        check_joints("q", q.len(), n)?;
        check_joints("qd", qd.len(), n)?;
        check_joints("tau", tau.len(), n)?;
        let scratch = &mut self.scratch;
        let mut fz = Frozen {
            plant: self.plant,
            ws: &mut self.ws,
            tau,
            st: stick,
        };
        let mut left = h;
        for cut in 0..=4 * n + 4 {
            fz.set_modes(q, qd, &mut scratch[..n])?;
            fz.st.q0.copy_from_slice(q);
            fz.st.qd0.copy_from_slice(qd);
            let mut run = |fz: &mut Frozen<'_, P>, q: &mut [f64], qd: &mut [f64], dt: f64| {
                q.copy_from_slice(&fz.st.q0);
                qd.copy_from_slice(&fz.st.qd0);
                rk4_core(scratch, q, qd, dt, |q, qd, a| fz.accel(q, qd, a))
            };
            run(&mut fz, q, qd, left)?;
            if cut == 4 * n + 4 {
                break;
            }
            fz.st.qd1.copy_from_slice(qd);
            // The earliest zero crossing of a joint that slipped from the start.
            let mut first: Option<(usize, f64)> = None;
            for j in 0..n {
                let s = fz.st.mode[j];
                if s == 0.0 || s * fz.st.qd0[j] <= 0.0 || s * fz.st.qd1[j] > 0.0 {
                    continue;
                }
                let (mut lo, mut hi) = (0.0, left);
                let (mut f_lo, mut f_hi) = (s * fz.st.qd0[j], s * fz.st.qd1[j]);
                let mut side = 0i8;
                for _ in 0..60 {
                    if hi - lo <= 1e-10 * h {
                        break;
                    }
                    // Illinois variant of regula falsi: halves the weight of an end that
                    // stays, so convergence is superlinear from both sides.
                    let mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
                    let mid = if mid > lo && mid < hi {
                        mid
                    } else {
                        0.5 * (lo + hi)
                    };
                    run(&mut fz, q, qd, mid)?;
                    let f = s * qd[j];
                    if f > 0.0 {
                        (lo, f_lo) = (mid, f);
                        if side == 1 {
                            f_hi *= 0.5;
                        }
                        side = 1;
                    } else {
                        (hi, f_hi) = (mid, f);
                        if side == -1 {
                            f_lo *= 0.5;
                        }
                        side = -1;
                    }
                }
                if first.map_or(true, |(_, t)| hi < t) {
                    first = Some((j, hi));
                }
            }
            let Some((j, t)) = first else {
                // `run` may have left a trial state: the full step is the answer.
                run(&mut fz, q, qd, left)?;
                return Ok(());
            };
            run(&mut fz, q, qd, t)?;
            qd[j] = 0.0;
            left -= t;
            if left <= 1e-10 * h {
                return Ok(());
            }
        }
        Ok(())
    }

    /// The acceleration q̈ = FD(q, q̇, τ) into `qdd`; with exact Coulomb terms, that of
    /// the stick–slip modes at this state (a stuck joint's q̈ is 0).
    ///
    /// # Errors
    /// As [`Dynamics::forward_dynamics_into`].
    #[inline]
    pub fn acceleration_into(
        &mut self,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        match self.stick.as_mut() {
            None => self
                .plant
                .forward_dynamics_into(&mut self.ws, q, qd, tau, qdd),
            Some(stick) => {
                let n = self.plant.dof();
                check_joints("q", q.len(), n)?;
                check_joints("qd", qd.len(), n)?;
                check_joints("tau", tau.len(), n)?;
                check_joints("qdd", qdd.len(), n)?;
                let mut fz = Frozen {
                    plant: self.plant,
                    ws: &mut self.ws,
                    tau,
                    st: stick,
                };
                fz.set_modes(q, qd, qdd)?;
                fz.accel(q, qd, qdd)
            }
        }
    }
}

/// What a simulation of a robot with n joints recorded at each output sample
/// t_k = k·dt. Joint columns are flat and row-major (samples × n, numpy's layout):
/// sample k of `q` is `q[k·n..(k+1)·n]`.
///
/// The true signals are consistent: `tau` at sample k equals the inverse dynamics of the
/// simulated robot at (`q`, `qd`, `qdd`) of sample k. The measured ones carry the
/// configured sensor noise.
#[derive(Debug, Clone, PartialEq)]
pub struct DynSimulationRecord {
    dof: usize,
    /// Time stamps, s.
    pub t: Vec<f64>,
    /// Reference positions (empty for open-loop runs).
    pub q_ref: Vec<f64>,
    /// Reference velocities (empty for open-loop runs).
    pub qd_ref: Vec<f64>,
    /// Reference accelerations (empty for open-loop runs).
    pub qdd_ref: Vec<f64>,
    /// True positions (m, rad).
    pub q: Vec<f64>,
    /// True velocities (m/s, rad/s).
    pub qd: Vec<f64>,
    /// True accelerations at the sample instant, under the torque applied from it
    /// (m/s², rad/s²).
    pub qdd: Vec<f64>,
    /// Generalised forces applied from the sample instant (N, N·m).
    pub tau: Vec<f64>,
    /// Measured positions: `q` plus Gaussian noise.
    pub q_measured: Vec<f64>,
    /// Measured velocities (`qd` plus Gaussian noise) when the noise configuration
    /// measures them ([`DynSensorNoise::qd_std`]), else `None`.
    pub qd_measured: Option<Vec<f64>>,
    /// Measured generalised forces: `tau` plus Gaussian noise.
    pub tau_measured: Vec<f64>,
}

impl DynSimulationRecord {
    fn with_capacity(n: usize, samples: usize, closed_loop: bool, qd_measured: bool) -> Self {
        let v = || Vec::with_capacity(n * samples);
        let r = || {
            if closed_loop {
                Vec::with_capacity(n * samples)
            } else {
                Vec::new()
            }
        };
        Self {
            dof: n,
            t: Vec::with_capacity(samples),
            q_ref: r(),
            qd_ref: r(),
            qdd_ref: r(),
            q: v(),
            qd: v(),
            qdd: v(),
            tau: v(),
            q_measured: v(),
            qd_measured: qd_measured.then(v),
            tau_measured: v(),
        }
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True if nothing was recorded.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// The noise-free signals (t, q, q̇, q̈, τ) as a [`DynDataset`].
    ///
    /// # Errors
    /// As [`DynDataset::new`] (e.g. fewer than [`DynDataset::DEFAULT_MIN_SAMPLES`]
    /// samples).
    pub fn true_dataset(&self) -> Result<DynDataset> {
        DynDataset::new(
            self.dof,
            self.t.clone(),
            self.q.clone(),
            self.qd.clone(),
            self.qdd.clone(),
            self.tau.clone(),
        )
    }

    /// The measured signals (noisy q, τ and, if measured, q̇) turned into a
    /// [`DynDataset`] by [`preprocess_log`] (zero-phase filtering, differentiation,
    /// trimming as `config` says): what an estimator sees on a real robot.
    ///
    /// # Errors
    /// As [`preprocess_log`].
    pub fn measured_dataset(&self, config: &LogConfig) -> Result<(DynDataset, LogReport)> {
        preprocess_log(
            &self.t,
            &self.q_measured,
            &self.tau_measured,
            self.qd_measured.as_deref(),
            self.dof,
            config,
        )
    }
}

/// Seeded per-joint Gaussian noise. Draws q (n values), then q̇ (n, only when measured),
/// then τ (n) at each sample, so that a configuration without velocity noise gives the
/// same stream as before velocity noise existed.
struct Noise {
    rng: ChaCha8Rng,
    q: Vec<Normal<f64>>,
    qd: Option<Vec<Normal<f64>>>,
    tau: Vec<Normal<f64>>,
}

impl Noise {
    fn new(cfg: &DynSensorNoise, seed: u64) -> Result<Self> {
        let normal = |s: f64| {
            Normal::new(0.0, s).map_err(|_| PrrrpError::InvalidParameter {
                field: "noise".into(),
                value: s,
                reason: "noise standard deviations must be finite and >= 0",
            })
        };
        let all = |v: &[f64]| v.iter().map(|&s| normal(s)).collect::<Result<Vec<_>>>();
        Ok(Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            q: all(&cfg.q_std)?,
            qd: cfg.qd_std.as_deref().map(all).transpose()?,
            tau: all(&cfg.tau_std)?,
        })
    }

    /// Appends the noisy q, q̇ and τ of one sample to the record (capacity reserved).
    fn record(&mut self, rec: &mut DynSimulationRecord, q: &[f64], qd: &[f64], tau: &[f64]) {
        for (d, x) in self.q.iter().zip(q) {
            rec.q_measured.push(x + d.sample(&mut self.rng));
        }
        if let (Some(dists), Some(out)) = (&self.qd, rec.qd_measured.as_mut()) {
            for (d, x) in dists.iter().zip(qd) {
                out.push(x + d.sample(&mut self.rng));
            }
        }
        for (d, x) in self.tau.iter().zip(tau) {
            rec.tau_measured.push(x + d.sample(&mut self.rng));
        }
    }
}

fn check_state(name: &str, v: &[f64]) -> Result<()> {
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
/// minute of computing for the paper arm; more is refused rather than left to run for
/// hours.
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

/// The divergence error of sample `k` at time `t` if q or q̇ holds a NaN/∞.
fn check_diverged(q: &[f64], qd: &[f64], k: usize, t: f64) -> Result<()> {
    for (signal, v) in [("q", q), ("qd", qd)] {
        if let Some(joint) = v.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::SimulationDiverged {
                sample: k,
                time: t,
                joint,
                signal,
            });
        }
    }
    Ok(())
}

/// A divergence inside an RK4 step, placed at the step's sample and end time.
fn at_step(e: PrrrpError, sample: usize, time: f64) -> PrrrpError {
    match e {
        PrrrpError::SimulationDiverged { joint, signal, .. } => PrrrpError::SimulationDiverged {
            sample,
            time,
            joint,
            signal,
        },
        other => other,
    }
}

fn check_dofs(n: usize, pairs: &[(&str, usize)]) -> Result<()> {
    if n == 0 {
        return Err(PrrrpError::InvalidParameter {
            field: "plant (joints)".into(),
            value: 0.0,
            reason: "the simulated robot has no joints",
        });
    }
    check_lens(pairs, n, "joints", " (the simulated robot's)")
}

/// Simulates the robot `plant` (n joints) following `reference` under computed-torque
/// control with the model `controller` ([`DynComputedTorque`], gains of `config`), from
/// t = 0 to `duration` (s), starting on the reference. RK4 with `config.substeps` steps
/// per sample; the controller updates its torque at every step.
///
/// Samples are taken at t_k = k·dt for k = 0..=⌊duration/dt⌋.
///
/// # Errors
/// - [`PrrrpError::ShapeMismatch`] if the controller, the reference or a gain/noise
///   vector does not have the plant's joint count;
/// - [`PrrrpError::InvalidParameter`] for a bad configuration (see
///   [`DynSimulationConfig::validate`]), a duration that is not finite and ≥ 0, past the
///   reference's end, or asking for more than [`crate::MAX_SAMPLES`] samples or
///   [`MAX_INTEGRATION_STEPS`] steps;
/// - [`PrrrpError::NonFinite`] for a reference that is NaN at t = 0;
/// - [`PrrrpError::NotPositiveDefinite`] if the plant's mass matrix is not positive
///   definite;
/// - [`PrrrpError::SimulationDiverged`] naming the sample, time and joint where the state
///   became NaN/∞;
/// - [`PrrrpError::Interrupted`] after [`crate::request_stop`].
pub fn simulate_dyn_closed_loop<P, C, T>(
    plant: &P,
    controller: &C,
    reference: &T,
    duration: f64,
    config: &DynSimulationConfig,
) -> Result<DynSimulationRecord>
where
    P: Dynamics + ?Sized,
    C: Dynamics + ?Sized,
    T: DynTrajectory + ?Sized,
{
    let n = plant.dof();
    check_dofs(
        n,
        &[
            ("controller", controller.dof()),
            ("reference", reference.dof()),
        ],
    )?;
    config.validate(n)?;
    if !(duration.is_finite() && duration >= 0.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "duration".into(),
            value: duration,
            reason: "must be finite and >= 0 s",
        });
    }
    let samples = crate::interrupt::check_count(
        "duration (in samples of dt)",
        (duration / config.dt + 1e-9).floor() + 1.0,
        "asks for more than MAX_SAMPLES (1e7) samples: shorten the duration or raise dt",
    )?;
    check_steps(samples, config.substeps)?;
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
    let mut ctrl = DynComputedTorque::new(controller, &config.kp, &config.kd)?;
    let mut rk = Rk4Integrator::new(plant);
    let h = config.dt / config.substeps as f64;
    let (mut q_r, mut qd_r, mut qdd_r) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    reference.eval_into(0.0, &mut q_r, &mut qd_r, &mut qdd_r);
    check_state("reference q at t = 0", &q_r)?;
    check_state("reference qd at t = 0", &qd_r)?;
    let (mut q, mut qd) = (q_r.clone(), qd_r.clone());
    let (mut tau, mut qdd) = (vec![0.0; n], vec![0.0; n]);
    let mut noise = Noise::new(&config.noise, config.seed)?;
    let mut rec =
        DynSimulationRecord::with_capacity(n, samples, true, config.noise.qd_std.is_some());
    for k in 0..samples {
        crate::interrupt::check("simulation")?;
        let t = config.dt * k as f64;
        reference.eval_into(t, &mut q_r, &mut qd_r, &mut qdd_r);
        ctrl.torque_into((&q_r, &qd_r, &qdd_r), &q, &qd, &mut tau)?;
        rk.acceleration_into(&q, &qd, &tau, &mut qdd)?;
        rec.t.push(t);
        rec.q_ref.extend_from_slice(&q_r);
        rec.qd_ref.extend_from_slice(&qd_r);
        rec.qdd_ref.extend_from_slice(&qdd_r);
        rec.q.extend_from_slice(&q);
        rec.qd.extend_from_slice(&qd);
        rec.qdd.extend_from_slice(&qdd);
        rec.tau.extend_from_slice(&tau);
        noise.record(&mut rec, &q, &qd, &tau);
        if k + 1 == samples {
            break;
        }
        for s in 0..config.substeps {
            if s > 0 {
                let ts = t + h * s as f64;
                reference.eval_into(ts, &mut q_r, &mut qd_r, &mut qdd_r);
                ctrl.torque_into((&q_r, &qd_r, &qdd_r), &q, &qd, &mut tau)?;
            }
            rk.step(&mut q, &mut qd, &tau, h)
                .map_err(|e| at_step(e, k + 1, t + h * (s + 1) as f64))?;
            // Checked at every step, so that a blow-up is reported as such with its time
            // rather than as a failure of the next step's dynamics at a NaN state.
            check_diverged(&q, &qd, k + 1, t + h * (s + 1) as f64)?;
        }
    }
    Ok(rec)
}

/// Simulates the robot `plant` (n joints) from (q0, q̇0) under the torques `tau` (flat
/// row-major, samples × n), each held constant over one sampling period (zero-order
/// hold): sample k is at t_k = k·dt and torque row k acts on [t_k, t_{k+1}). The PD gains
/// of `config` are unused.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] for q0, q̇0 or a torque table without n entries per
/// row; [`PrrrpError::InvalidParameter`] for a bad configuration;
/// [`PrrrpError::NonFinite`] naming the first NaN/∞ torque row or initial state;
/// [`PrrrpError::NotPositiveDefinite`] for a non-physical plant;
/// [`PrrrpError::SimulationDiverged`] if the state blows up;
/// [`PrrrpError::Interrupted`] after [`crate::request_stop`].
pub fn simulate_dyn_open_loop<P: Dynamics + ?Sized>(
    plant: &P,
    q0: &[f64],
    qd0: &[f64],
    tau: &[f64],
    config: &DynSimulationConfig,
) -> Result<DynSimulationRecord> {
    let n = plant.dof();
    check_dofs(n, &[])?;
    config.validate(n)?;
    check_joints("q0", q0.len(), n)?;
    check_joints("qd0", qd0.len(), n)?;
    if tau.len() % n != 0 {
        return Err(PrrrpError::ShapeMismatch {
            what: "tau".into(),
            expected: format!("rows of {n} entries (one per joint)"),
            got: format!("{} entries", tau.len()),
        });
    }
    check_state("q0", q0)?;
    check_state("qd0", qd0)?;
    if let Some(i) = tau.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "tau".into(),
            row: Some(i / n),
        });
    }
    let samples = tau.len() / n;
    crate::interrupt::check_count(
        "tau (rows)",
        samples as f64,
        "more than MAX_SAMPLES (1e7) torque rows: shorten the run",
    )?;
    check_steps(samples, config.substeps)?;
    let h = config.dt / config.substeps as f64;
    let mut rk = Rk4Integrator::new(plant);
    let (mut q, mut qd, mut qdd) = (q0.to_vec(), qd0.to_vec(), vec![0.0; n]);
    let mut noise = Noise::new(&config.noise, config.seed)?;
    let mut rec =
        DynSimulationRecord::with_capacity(n, samples, false, config.noise.qd_std.is_some());
    for (k, tk) in tau.chunks_exact(n).enumerate() {
        crate::interrupt::check("simulation")?;
        rk.acceleration_into(&q, &qd, tk, &mut qdd)?;
        rec.t.push(config.dt * k as f64);
        rec.q.extend_from_slice(&q);
        rec.qd.extend_from_slice(&qd);
        rec.qdd.extend_from_slice(&qdd);
        rec.tau.extend_from_slice(tk);
        noise.record(&mut rec, &q, &qd, tk);
        if k + 1 == samples {
            break;
        }
        let t = config.dt * k as f64;
        for s in 0..config.substeps {
            rk.step(&mut q, &mut qd, tk, h)
                .map_err(|e| at_step(e, k + 1, t + h * (s + 1) as f64))?;
            check_diverged(&q, &qd, k + 1, t + h * (s + 1) as f64)?;
        }
    }
    Ok(rec)
}

/// What a simulation of the paper arm recorded at each output sample t_k = k·dt.
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

    /// The 5-joint record of a [`DynSimulationRecord`] of the paper arm.
    fn from_dyn(r: DynSimulationRecord) -> Self {
        let rows = |v: Vec<f64>| -> Vec<Vec5> {
            v.chunks_exact(NDOF).map(Vec5::from_column_slice).collect()
        };
        Self {
            t: r.t,
            q_ref: rows(r.q_ref),
            qd_ref: rows(r.qd_ref),
            qdd_ref: rows(r.qdd_ref),
            q: rows(r.q),
            qd: rows(r.qd),
            qdd: rows(r.qdd),
            tau: rows(r.tau),
            q_measured: rows(r.q_measured),
            tau_measured: rows(r.tau_measured),
        }
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

/// The paper arm's simulations keep reporting divergence as [`PrrrpError::Diverged`] at
/// the sample index, as they always did.
fn paper_divergence(e: PrrrpError) -> PrrrpError {
    match e {
        PrrrpError::SimulationDiverged { sample, .. } => PrrrpError::Diverged {
            what: "simulation",
            at: sample,
            hint: "the state became NaN/∞; check the torques, gains and parameters, or \
                   increase substeps",
        },
        other => other,
    }
}

/// Simulates the robot with parameters `true_lambda` following `reference` under
/// [`ComputedTorque`] control with the controller's parameters `controller_lambda`, from
/// t = 0 to `duration` (s), starting on the reference: [`simulate_dyn_closed_loop`] on
/// the closed-form model.
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
    let plant = ParameterisedModel::new(*model, *true_lambda)?;
    let ctrl = ParameterisedModel::new(*model, *controller_lambda)?;
    let rec = simulate_dyn_closed_loop(
        &plant,
        &ctrl,
        reference,
        duration,
        &DynSimulationConfig::from(config),
    )
    .map_err(paper_divergence)?;
    Ok(SimulationRecord::from_dyn(rec))
}

/// Simulates the robot with parameters `lambda` from (q0, q̇0) under the torque sequence
/// `tau`, each held constant over one sampling period (zero-order hold): sample k is at
/// t_k = k·dt and `tau[k]` acts on [t_k, t_{k+1}). The PD gains of `config` are unused.
/// [`simulate_dyn_open_loop`] on the closed-form model.
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
    let plant = ParameterisedModel::new(*model, *lambda)?;
    let flat: Vec<f64> = tau.iter().flat_map(|v| v.iter().copied()).collect();
    let rec = simulate_dyn_open_loop(
        &plant,
        q0.as_slice(),
        qd0.as_slice(),
        &flat,
        &DynSimulationConfig::from(config),
    )
    .map_err(paper_divergence)?;
    Ok(SimulationRecord::from_dyn(rec))
}
