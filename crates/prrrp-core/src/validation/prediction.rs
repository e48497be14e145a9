//! Validation of identified parameters (paper section 5.1, Table 5) and the measures the
//! field uses next to it: open-loop torque prediction and relative parameter error.
//!
//! The paper re-simulates the robot with each estimated λ̂ on reference trajectories that
//! were not used for estimation and compares the joint trajectories with those of the
//! true robot (RMS, RSD, AI, eqs. 45–47). Under a tracking controller those trajectories
//! barely depend on λ̂ (the paper's indices are all ≈ 0 / 1), so we also predict the
//! measured torques with Φ·λ̂, which separates good from bad estimates.
//!
//! For any robot, [`validate_torque_prediction`] (a [`Dynamics`] model: a chain, a base
//! model at β̂) and [`validate_identified_model`] (an [`IdentifiedModel`]) predict the
//! torques of a [`DynDataset`] the model was not fitted on and report RMS, RSD and the
//! agreement index per joint ([`TorqueValidation`]). The paper arm's functions run
//! through the same prediction loop and per-joint indices.

use nalgebra::Dim;

use crate::data::{Dataset, DatasetOf, DynDataset};
use crate::error::{PrrrpError, Result};
use crate::identification::IdentifiedModel;
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{Lambda, Vec5, NDOF};
use crate::motion::dynamics::{Dynamics, ParameterisedModel};
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
    let plant = ParameterisedModel::new(*model, *lambda)?;
    let mut ws = plant.workspace();
    let flat = predict_with(data, |q, qd, qdd, tau| {
        plant.inverse_dynamics_into(&mut ws, q, qd, qdd, tau)
    })?;
    let predicted: Vec<Vec5> = flat
        .chunks_exact(NDOF)
        .map(Vec5::from_column_slice)
        .collect();
    let n = data.len().max(1) as f64;
    let mut rms = [0.0; NDOF];
    let mut relative_percent = [0.0; NDOF];
    for j in 0..NDOF {
        let (mut se, mut ss) = (0.0, 0.0);
        for (p, m) in predicted.iter().zip(data.samples().tau()) {
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
    let flat = |v: &[Vec5]| -> Vec<f64> { v.iter().flat_map(|x| x.iter().copied()).collect() };
    let v = per_joint_indices(NDOF, &flat(observed), &flat(predicted))?;
    let mut out = [ErrorIndices {
        rms: 0.0,
        rsd: 0.0,
        ai: 1.0,
    }; NDOF];
    out.copy_from_slice(&v);
    Ok(out)
}

/// RMS, RSD and AI ([`error_indices`]) of each of `n` joints between two flat row-major
/// (samples × n) series: joint j's column is entries j, j + n, j + 2n, ….
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if the lengths differ or are not multiples of n; the
/// errors of [`error_indices`], with the joint named for an undefined RSD (a column
/// observed as identically zero but predicted otherwise).
pub fn per_joint_indices(
    n: usize,
    observed: &[f64],
    predicted: &[f64],
) -> Result<Vec<ErrorIndices>> {
    if n == 0 || observed.len() % n != 0 || predicted.len() != observed.len() {
        return Err(PrrrpError::ShapeMismatch {
            what: "predicted".into(),
            expected: format!(
                "{} values, rows of n = {n} joints (as observed)",
                observed.len()
            ),
            got: format!("{} values", predicted.len()),
        });
    }
    let column =
        |v: &[f64], j: usize| -> Vec<f64> { v.iter().skip(j).step_by(n).copied().collect() };
    (0..n)
        .map(|j| {
            error_indices(&column(observed, j), &column(predicted, j)).map_err(|e| match e {
                PrrrpError::InvalidParameter { value, reason, .. } => {
                    PrrrpError::InvalidParameter {
                        field: format!("observed[{j}] (joint {})", j + 1),
                        value,
                        reason,
                    }
                }
                other => other,
            })
        })
        .collect()
}

/// Predicted torques of every sample of `data` (flat row-major samples × n) by `predict`,
/// which writes τ̂(q, q̇, q̈) into its last argument without allocating.
fn predict_with<N: Dim>(
    data: &DatasetOf<N>,
    mut predict: impl FnMut(&[f64], &[f64], &[f64], &mut [f64]) -> Result<()>,
) -> Result<Vec<f64>> {
    let n = data.dof();
    let mut out = vec![0.0; n * data.len()];
    for (k, tau) in out.chunks_exact_mut(n).enumerate() {
        if k % 4096 == 0 {
            crate::interrupt::check("torque prediction")?;
        }
        predict(data.q_row(k), data.qd_row(k), data.qdd_row(k), tau).map_err(|e| match e {
            PrrrpError::NonFinite { what, .. } => PrrrpError::NonFinite { what, row: Some(k) },
            other => other,
        })?;
    }
    Ok(out)
}

/// Torque-prediction validation of a model of a robot with n joints on a data set it was
/// not fitted on ([`validate_torque_prediction`], [`validate_identified_model`]).
#[derive(Debug, Clone, PartialEq)]
pub struct TorqueValidation {
    dof: usize,
    /// RMS (N, N·m), RSD (dimensionless) and agreement index of measured against predicted
    /// torque, per joint (paper eqs. 45–47; perfect prediction: 0, 0, 1).
    pub indices: Vec<ErrorIndices>,
    /// The predicted torques τ̂(q, q̇, q̈), flat row-major (samples × n).
    pub predicted: Vec<f64>,
}

impl TorqueValidation {
    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.dof
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.predicted.len() / self.dof.max(1)
    }

    /// True if there are no samples (never, for a report from a valid data set).
    pub fn is_empty(&self) -> bool {
        self.predicted.is_empty()
    }

    /// RMS of τ − τ̂ per joint (N, N·m).
    pub fn rms(&self) -> Vec<f64> {
        self.indices.iter().map(|e| e.rms).collect()
    }

    /// RSD ‖τ − τ̂‖/‖τ‖ per joint (dimensionless; ×100 for the relative error in %).
    pub fn rsd(&self) -> Vec<f64> {
        self.indices.iter().map(|e| e.rsd).collect()
    }

    /// Willmott's agreement index per joint, in [0, 1].
    pub fn agreement_index(&self) -> Vec<f64> {
        self.indices.iter().map(|e| e.ai).collect()
    }
}

fn report(data: &DynDataset, predicted: Vec<f64>) -> Result<TorqueValidation> {
    let indices = per_joint_indices(data.dof(), data.tau(), &predicted)?;
    Ok(TorqueValidation {
        dof: data.dof(),
        indices,
        predicted,
    })
}

/// Predicts the torques of `data` with the inverse dynamics of `model` (e.g. a
/// [`crate::DynChain`] with its parameters, or [`ParameterisedModel`] of a
/// [`crate::DynChainBaseModel`] at identified β̂) and compares them with the measured
/// torques of `data`, per joint.
///
/// ```
/// use prrrp_core::{validate_torque_prediction, DynDataset, SerialChain};
/// let puma = SerialChain::puma560().to_dyn();
/// let rows = 20;
/// let t: Vec<f64> = (0..rows).map(|k| 0.01 * k as f64).collect();
/// let q: Vec<f64> = (0..rows * 6).map(|i| (0.1 * i as f64).sin()).collect();
/// let (qd, qdd) = (vec![0.3; rows * 6], vec![-0.2; rows * 6]);
/// let tau = (0..rows)
///     .flat_map(|k| {
///         let r = 6 * k..6 * k + 6;
///         puma.inverse_dynamics(&q[r.clone()], &qd[r.clone()], &qdd[r]).unwrap()
///     })
///     .collect();
/// let data = DynDataset::new(6, t, q, qd, qdd, tau)?;
/// let v = validate_torque_prediction(&puma, &data)?;
/// assert!(v.rms().iter().all(|&r| r < 1e-12));
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if the data's joint count is not the model's; the
/// errors of the model's inverse dynamics and of [`per_joint_indices`].
pub fn validate_torque_prediction<D: Dynamics + ?Sized>(
    model: &D,
    data: &DynDataset,
) -> Result<TorqueValidation> {
    data.check_dof(model.dof(), "the model's")?;
    let mut ws = model.workspace();
    let predicted = predict_with(data, |q, qd, qdd, tau| {
        model.inverse_dynamics_into(&mut ws, q, qd, qdd, tau)
    })?;
    report(data, predicted)
}

/// Predicts the torques of `data` with an identified model (τ̂ = Y_b·β̂, through its
/// [`crate::Predictor`]) and compares them with the measured torques of `data`, per
/// joint.
///
/// # Errors
/// As [`validate_torque_prediction`] and [`IdentifiedModel::predictor`].
pub fn validate_identified_model(
    model: &IdentifiedModel,
    data: &DynDataset,
) -> Result<TorqueValidation> {
    let mut p = model.predictor()?;
    data.check_dof(p.chain().dof(), "the model's")?;
    let predicted = predict_with(data, |q, qd, qdd, tau| p.predict_into(q, qd, qdd, tau))?;
    report(data, predicted)
}
