//! Validation of identified parameters (paper section 5.1, Table 5) and the measures the
//! field uses next to it: open-loop torque prediction and relative parameter error.
//!
//! The paper re-simulates the robot with each estimated λ̂ on reference trajectories that
//! were not used for estimation and compares the joint trajectories with those of the
//! true robot (RMS, RSD, AI, eqs. 45–47). Under a tracking controller those trajectories
//! barely depend on λ̂ (the paper's indices are all ≈ 0 / 1), so we also predict the
//! measured torques with Φ·λ̂, which separates good from bad estimates.

use crate::data::dataset::Dataset;
use crate::error::{PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{Lambda, Vec5, NDOF};
use crate::motion::simulation::{simulate_closed_loop, SimulationConfig, SimulationRecord};
use crate::motion::trajectory::{JointTrajectory, Sinusoid};
use crate::validation::metrics::{error_indices, ErrorIndices};

/// The default validation reference: one sinusoid per joint, with periods (5, 4, 3.5, 3,
/// 2.5 s) and shapes unlike the excitation's piecewise quintics, inside the default joint
/// limits ([`crate::JointLimits::default`]): d1 ∈ [0.05, 0.25] m, θ2..θ4 within ±1.4 rad,
/// d5 ∈ [0.02, 0.08] m, peak speeds ≤ 2.5 rad/s. Each starts at rest (phase −π/2).
pub fn default_validation_reference() -> [Sinusoid; NDOF] {
    let s = |offset: f64, amplitude: f64, period: f64| Sinusoid {
        offset,
        amplitude,
        omega: 2.0 * std::f64::consts::PI / period,
        phase: -std::f64::consts::FRAC_PI_2,
    };
    [
        s(0.15, 0.1, 5.0),
        s(0.2, 1.2, 4.0),
        s(-0.3, 1.1, 3.5),
        s(0.1, 1.2, 3.0),
        s(0.05, 0.03, 2.5),
    ]
}

/// Settings of [`validate`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidationConfig {
    /// The validation reference (default [`default_validation_reference`]).
    pub reference: [Sinusoid; NDOF],
    /// Length of the validation run, s (default 10).
    pub duration: f64,
    /// Controller, sampling and sensor noise of the runs (default
    /// [`SimulationConfig::default`], with the seed replaced by [`ValidationConfig::seed`]).
    pub simulation: SimulationConfig,
    /// Seed of the sensor noise of the validation run (default 1, unlike the excitation's).
    pub seed: u64,
}

impl Default for ValidationConfig {
    fn default() -> Self {
        Self {
            reference: default_validation_reference(),
            duration: 10.0,
            simulation: SimulationConfig::default(),
            seed: 1,
        }
    }
}

/// Torque prediction of an estimate on measured data.
#[derive(Debug, Clone, PartialEq)]
pub struct TorquePrediction {
    /// RMS of τ_measured − Φ·λ̂ per joint (N, N·m).
    pub rms: [f64; NDOF],
    /// The same relative to the RMS of the measured torque, per joint, %.
    pub relative_percent: [f64; NDOF],
    /// The predicted torques Φ(q, q̇, q̈)·λ̂ per sample.
    pub predicted: Vec<Vec5>,
}

/// Predicts the torques of `data` with Φ(q, q̇, q̈)·λ̂ and compares them with `data.tau()`.
///
/// # Errors
/// [`PrrrpError::NonFinite`] for a NaN λ̂.
pub fn torque_prediction(
    model: &PrrrpModel,
    data: &Dataset,
    lambda: &Lambda,
) -> Result<TorquePrediction> {
    if !lambda.iter().all(|x| x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "lambda".into(),
            row: None,
        });
    }
    let predicted: Vec<Vec5> = (0..data.len())
        .map(|k| model.inverse_dynamics(&data.q()[k], &data.qd()[k], &data.qdd()[k], lambda))
        .collect();
    let n = data.len().max(1) as f64;
    let mut rms = [0.0; NDOF];
    let mut relative_percent = [0.0; NDOF];
    for j in 0..NDOF {
        let (mut se, mut ss) = (0.0, 0.0);
        for (p, m) in predicted.iter().zip(data.tau()) {
            se += (m[j] - p[j]).powi(2);
            ss += m[j] * m[j];
        }
        rms[j] = (se / n).sqrt();
        // A joint with no measured torque at all has no relative error: report 0 when the
        // prediction is exact as well, else 100 % (the whole prediction is error).
        relative_percent[j] = if ss > 0.0 {
            100.0 * (se / ss).sqrt()
        } else if se == 0.0 {
            0.0
        } else {
            100.0
        };
    }
    Ok(TorquePrediction {
        rms,
        relative_percent,
        predicted,
    })
}

/// Validation of one estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodValidation {
    /// Name of the method that produced the estimate.
    pub method: String,
    /// The estimate λ̂.
    pub lambda: Lambda,
    /// Joint positions of the robot simulated with λ̂ on the validation reference.
    pub q: Vec<Vec5>,
    /// RMS, RSD and AI of the positions against the true robot's, per joint (Table 5).
    pub indices: [ErrorIndices; NDOF],
    /// Torque prediction on the true robot's measured validation torques.
    pub torque: TorquePrediction,
    /// |λ̂ − λ| / |λ| per parameter, %, when the true λ is known.
    pub relative_error_percent: Option<Vec<f64>>,
}

/// Result of [`validate`].
#[derive(Debug, Clone, PartialEq)]
pub struct ValidationReport {
    /// The true robot's validation run (reference, true and measured signals).
    pub truth: SimulationRecord,
    /// One entry per estimate, in the order given.
    pub methods: Vec<MethodValidation>,
}

/// Validates estimates λ̂ on the validation reference of `config`.
///
/// The true robot (`true_lambda`) and, for each estimate, the robot model with λ̂ follow
/// the reference under the **same** computed-torque controller (model `controller_lambda`,
/// gains of `config.simulation`); their joint trajectories are compared with
/// RMS/RSD/AI. The torques of each λ̂ are predicted with Φ·λ̂ on the true robot's
/// noise-free validation states and compared with its measured torques.
/// `known_truth` (usually `Some(true_lambda)`) adds the relative parameter errors.
///
/// # Errors
/// Those of [`simulate_closed_loop`] (e.g. [`PrrrpError::NotPositiveDefinite`] for a
/// non-physical λ̂, [`PrrrpError::Diverged`]) and of the error indices.
pub fn validate(
    model: &PrrrpModel,
    true_lambda: &Lambda,
    controller_lambda: &Lambda,
    estimates: &[(String, Lambda)],
    known_truth: Option<&Lambda>,
    config: &ValidationConfig,
) -> Result<ValidationReport> {
    let sim = SimulationConfig {
        seed: config.seed,
        ..config.simulation
    };
    let reference: &dyn JointTrajectory = &config.reference;
    let truth = simulate_closed_loop(
        model,
        true_lambda,
        controller_lambda,
        reference,
        config.duration,
        &sim,
    )?;
    let measured = Dataset::new(
        truth.t.clone(),
        truth.q.clone(),
        truth.qd.clone(),
        truth.qdd.clone(),
        truth.tau_measured.clone(),
    )?;
    let mut methods = Vec::with_capacity(estimates.len());
    for (name, lambda) in estimates {
        let noiseless = SimulationConfig {
            noise: crate::motion::simulation::SensorNoise::none(),
            ..sim
        };
        let run = simulate_closed_loop(
            model,
            lambda,
            controller_lambda,
            reference,
            config.duration,
            &noiseless,
        )?;
        let indices = joint_indices(&truth.q, &run.q)?;
        let torque = torque_prediction(model, &measured, lambda)?;
        let relative_error_percent = known_truth.map(|t| {
            crate::validation::metrics::relative_errors_percent(lambda.as_slice(), t.as_slice())
        });
        methods.push(MethodValidation {
            method: name.clone(),
            lambda: *lambda,
            q: run.q,
            indices,
            torque,
            relative_error_percent,
        });
    }
    Ok(ValidationReport { truth, methods })
}

/// RMS, RSD and AI per joint between two sampled joint trajectories.
///
/// # Errors
/// As [`error_indices`].
pub fn joint_indices(observed: &[Vec5], predicted: &[Vec5]) -> Result<[ErrorIndices; NDOF]> {
    let mut out = [ErrorIndices {
        rms: 0.0,
        rsd: 0.0,
        ai: 1.0,
    }; NDOF];
    for (j, slot) in out.iter_mut().enumerate() {
        let o: Vec<f64> = observed.iter().map(|v| v[j]).collect();
        let p: Vec<f64> = predicted.iter().map(|v| v[j]).collect();
        *slot = error_indices(&o, &p)?;
    }
    Ok(out)
}
