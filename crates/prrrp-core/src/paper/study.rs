//! The paper's whole study from one seed (sections 4–5): optimise the excitation,
//! simulate the robot with sensor noise, preprocess, run the four estimators, validate,
//! and sweep the sensitivity — one deterministic, serialisable result.
//!
//! It runs on the general pipeline: the robot as a chain (evaluated in closed form), the
//! run-time simulator with the controller holding the chain's base model at β0, and every
//! estimator on that base model (least squares through [`identify`]). The paper's λ of
//! each estimate is the view of its β ([`PaperLambdaView`]). The excitation (the paper's
//! quintics and sinusoids, scored on the λ regressor), the validation runs and the
//! sensitivity sweep (both per λᵢ: Tables 5 and 6) take λ, on the closed form.

use std::time::Instant;

use serde::{Deserialize, Serialize};

use nalgebra::{DVector, Dyn};

use crate::data::preprocess::{preprocess, PreprocessConfig};
use crate::data::DynDataset;
use crate::error::{PrrrpError, Result};
use crate::estimators::{
    AdalineConfig, Discretisation, DynAdaline, DynEkf, DynHopfield, DynSamples, EkfConfig,
    Estimator, HopfieldConfig, LeastSquaresConfig,
};
use crate::identification::{identify, LsSettings, Method, Rows};
use crate::models::chain::{BaseOptions, DynChain, DynChainBaseModel, SerialChain};
use crate::models::prrrp::robot::Robot;
use crate::models::prrrp::types::{Lambda, Vec5, NDOF, NPARAM};
use crate::motion::dynamics::ParameterisedModel;
use crate::motion::excitation::{optimise_excitation, ExcitationConfig, DEFAULT_EXCITATION_KNOTS};
use crate::motion::simulation::{simulate_dyn_closed_loop, DynSimulationConfig, SimulationConfig};
use crate::paper::lambda_view::PaperLambdaView;
use crate::paper::sensitivity::{sensitivity, SensitivityConfig};
use crate::validation::metrics::relative_errors_percent;
use crate::validation::{validate, ValidationConfig};

/// Names of the four methods, in the order of the paper's tables.
pub const METHODS: [&str; 4] = ["least_squares", "adaline", "hopfield", "ekf"];

/// Settings of [`run_study`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StudyConfig {
    /// Seed of everything random (default 0): the excitation's initial guess uses it, the
    /// estimation run's sensor noise uses it, the validation run's noise uses seed + 1.
    pub seed: u64,
    /// Excitation optimisation (default [`ExcitationConfig::default`]).
    pub excitation: ExcitationConfig,
    /// Controller, sampling and sensor noise of the estimation run (default
    /// [`SimulationConfig::default`]).
    pub simulation: SimulationConfig,
    /// Filtering and differentiation of the measured positions (default
    /// [`PreprocessConfig::default`]).
    pub preprocess: PreprocessConfig,
    /// λ0 (as β0 = scale·β: the view of β0 is λ0) of the iterative estimators and the
    /// controller's model, as a multiple of the true λ (default 1.3: a model 30 % too heavy, as from a rough CAD estimate; scaling
    /// every mass and inertia keeps it physical). The paper's λ0 = ones is not physical.
    pub initial_guess_scale: f64,
    /// Least squares (default [`LeastSquaresConfig::default`]).
    pub least_squares: LeastSquaresConfig,
    /// Adaline (default [`AdalineConfig::default`], normalised rule, with step size 0.05
    /// so that sensor noise averages out over the epochs).
    pub adaline: AdalineConfig,
    /// Training epochs of Adaline over the estimation data (default 20).
    pub adaline_epochs: usize,
    /// Hopfield network (default [`HopfieldConfig::default`]).
    pub hopfield: HopfieldConfig,
    /// Passes of the Hopfield network over the estimation data (default 10).
    pub hopfield_epochs: usize,
    /// Extended Kalman filter; it runs once over the raw measured positions and torques.
    /// Default: [`EkfConfig::default`] with the second-order discretisation (its O(h) bias
    /// is smaller than Euler's at 50 Hz), an initial λ uncertainty of 30 % (the size of
    /// the λ0 error, `initial_guess_scale`) and a position noise of 1e-2: the recorded
    /// torque is the controller's value at the sample instant while the 1 kHz controller
    /// changes it within the sample, and the larger R absorbs that model error. With the
    /// filter's own defaults (50 % and 1e-3) the estimate leaves the physical region
    /// within the 10 s of excitation data.
    pub ekf: EkfConfig,
    /// Validation runs (default [`ValidationConfig::default`], seed replaced by seed + 1).
    pub validation: ValidationConfig,
    /// Sensitivity sweep (default [`SensitivityConfig::default`], ±50 %, 11 points).
    pub sensitivity: SensitivityConfig,
    /// Points of each estimator's history kept for the figures (default 200).
    pub history_points: usize,
}

impl Default for StudyConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            excitation: ExcitationConfig::default(),
            simulation: SimulationConfig::default(),
            preprocess: PreprocessConfig::default(),
            initial_guess_scale: 1.3,
            least_squares: LeastSquaresConfig::default(),
            adaline: AdalineConfig {
                step_size: 0.05,
                ..AdalineConfig::default()
            },
            adaline_epochs: 20,
            hopfield: HopfieldConfig::default(),
            hopfield_epochs: 10,
            ekf: EkfConfig {
                discretisation: Discretisation::SecondOrder,
                initial_parameter_rel_std: 0.3,
                position_noise: 1e-2,
                ..EkfConfig::default()
            },
            validation: ValidationConfig::default(),
            sensitivity: SensitivityConfig::default(),
            history_points: 200,
        }
    }
}

/// Excitation summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationSummary {
    /// cond(W) of the initial guess.
    pub cond_initial: f64,
    /// cond(W) of the optimised trajectory.
    pub cond_final: f64,
    /// Cost evaluations.
    pub evaluations: usize,
    /// Whether every joint limit holds.
    pub limits_satisfied: bool,
    /// Samples in W.
    pub samples: usize,
    /// Horizon, s.
    pub duration: f64,
}

/// The estimation run (paper Fig. 3).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EstimationData {
    /// Time, s.
    pub t: Vec<f64>,
    /// Reference positions.
    pub q_ref: Vec<[f64; NDOF]>,
    /// True positions.
    pub q: Vec<[f64; NDOF]>,
    /// Measured positions.
    pub q_measured: Vec<[f64; NDOF]>,
    /// Measured generalised forces.
    pub tau_measured: Vec<[f64; NDOF]>,
}

/// The evolution of an iterative estimate (paper Figs. 5 and 6).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct History {
    /// Time of each point, s (estimation time, over all passes; for Adaline the epoch).
    pub t: Vec<f64>,
    /// λ̂ at each point.
    pub lambda: Vec<[f64; NPARAM]>,
}

/// One method's estimate (paper Table 4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodEstimate {
    /// One of [`METHODS`].
    pub method: String,
    /// λ̂: the paper's view ([`PaperLambdaView`]) of `beta`.
    pub lambda: [f64; NPARAM],
    /// β̂: the estimate of the paper robot's base parameters (names in
    /// [`StudyResult::base_names`]), what every method identifies.
    #[serde(default)]
    pub beta: Vec<f64>,
    /// |λ̂ − λ|/|λ|, %.
    pub relative_error_percent: Vec<f64>,
    /// Least squares only: σ_i.
    pub std: Option<[f64; NPARAM]>,
    /// Least squares only: %σ_i.
    pub rsd_percent: Option<[f64; NPARAM]>,
    /// Least squares only: cond(W).
    pub cond: Option<f64>,
    /// Least squares only: residual variance σ².
    pub sigma2: Option<f64>,
    /// Iterative methods: history of λ̂.
    pub history: Option<History>,
    /// Wall time of the method, s.
    pub seconds: f64,
    /// Why the method failed, if it did (its λ is then λ0 and its other fields empty);
    /// one failing estimator does not stop the study.
    pub error: Option<String>,
}

/// Validation of one method (paper Table 5 and Fig. 7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodValidationSummary {
    /// One of [`METHODS`].
    pub method: String,
    /// Positions of the robot simulated with λ̂.
    pub q: Vec<[f64; NDOF]>,
    /// RMS per joint (m, rad).
    pub rms: [f64; NDOF],
    /// RSD per joint.
    pub rsd: [f64; NDOF],
    /// Agreement index per joint.
    pub ai: [f64; NDOF],
    /// Torque-prediction RMS per joint (N, N·m).
    pub torque_rms: [f64; NDOF],
    /// Torque-prediction error relative to the measured torque's RMS, per joint, %.
    pub torque_relative_percent: [f64; NDOF],
}

/// Validation runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationSummary {
    /// Time, s.
    pub t: Vec<f64>,
    /// Validation reference.
    pub q_ref: Vec<[f64; NDOF]>,
    /// The true robot's positions.
    pub q_true: Vec<[f64; NDOF]>,
    /// One entry per method.
    pub methods: Vec<MethodValidationSummary>,
}

/// Sensitivity sweep (paper Table 6 and Fig. 8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SensitivitySummary {
    /// Scale factors applied to each λᵢ.
    pub factors: Vec<f64>,
    /// [min, max] of each λᵢ.
    pub ranges: Vec<[f64; 2]>,
    /// `rms[i][k][j]`, `None` where the varied λ is not physical.
    pub rms: Vec<Vec<Option<[f64; NDOF]>>>,
}

/// Wall time of each stage, s.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Timings {
    /// Excitation optimisation.
    pub excitation: f64,
    /// Closed-loop simulation of the estimation run.
    pub simulation: f64,
    /// Filtering and differentiation.
    pub preprocessing: f64,
    /// Least squares.
    pub least_squares: f64,
    /// Adaline (all epochs).
    pub adaline: f64,
    /// Hopfield (all passes).
    pub hopfield: f64,
    /// Extended Kalman filter.
    pub ekf: f64,
    /// Validation runs.
    pub validation: f64,
    /// Sensitivity sweep.
    pub sensitivity: f64,
    /// Whole study.
    pub total: f64,
}

/// Everything the study produces; serialised with stable field names (schema version 1,
/// documented in `docs/results-schema.md`; `base_names`, `beta_truth` and each estimate's
/// `beta` were added within version 1 and default to empty when absent).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyResult {
    /// Version of the field layout (1).
    pub schema_version: u32,
    /// Seed of the study.
    pub seed: u64,
    /// True λ of the simulated robot.
    pub truth: [f64; NPARAM],
    /// λ0 of the iterative estimators and the controller.
    pub initial_guess: [f64; NPARAM],
    /// Names of the base parameters β of the paper robot's chain ([`DynChain::paper`]),
    /// which the methods identify.
    #[serde(default)]
    pub base_names: Vec<String>,
    /// True β of the simulated robot (the λ view of it is `truth`).
    #[serde(default)]
    pub beta_truth: Vec<f64>,
    /// Excitation summary.
    pub excitation: ExcitationSummary,
    /// The estimation run.
    pub estimation_data: EstimationData,
    /// One estimate per method, in the order of [`METHODS`].
    pub estimates: Vec<MethodEstimate>,
    /// Validation.
    pub validation: ValidationSummary,
    /// Sensitivity.
    pub sensitivity: SensitivitySummary,
    /// Stage timings.
    pub timings_s: Timings,
}

impl StudyResult {
    /// The result as JSON text.
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] if a value is NaN or infinite (JSON cannot hold it).
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string(self).map_err(|e| PrrrpError::NonFinite {
            what: format!("study result ({e})"),
            row: None,
        })
    }

    /// Parses a result written by [`StudyResult::to_json`].
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if the text is not a schema-1 study result.
    pub fn from_json(text: &str) -> Result<Self> {
        serde_json::from_str(text).map_err(|_| PrrrpError::InvalidParameter {
            field: "json".into(),
            value: f64::NAN,
            reason: "not a prrrp study result (schema_version 1)",
        })
    }
}

fn arr(v: &Vec5) -> [f64; NDOF] {
    [v[0], v[1], v[2], v[3], v[4]]
}

fn arr8(v: &Lambda) -> [f64; NPARAM] {
    let mut a = [0.0; NPARAM];
    a.copy_from_slice(v.as_slice());
    a
}

fn rows(v: &[Vec5]) -> Vec<[f64; NDOF]> {
    v.iter().map(arr).collect()
}

/// Progress callback of [`run_study`]: (stage, done, total).
pub type StudyProgress<'a> = &'a (dyn Fn(&str, usize, usize) + Sync);

/// Runs the whole study on `robot` (the "true" robot to identify) through the general
/// pipeline: the robot as a chain ([`SerialChain::from_robot`], evaluated in closed form
/// for the paper's geometry), simulated under computed-torque control by its base model
/// at λ0, each method identifying the chain's base parameters β, and the paper's λ as the
/// view of β ([`PaperLambdaView`]). Deterministic for a given configuration; the
/// estimators and the sensitivity points run in parallel.
///
/// # Errors
/// Any stage's error (an infeasible excitation, a non-physical robot, a diverging
/// estimator, …), unchanged; [`PrrrpError::InvalidParameter`] for a robot whose chain has
/// no λ view (gravity other than the paper's).
pub fn run_study(
    robot: &Robot,
    config: &StudyConfig,
    progress: StudyProgress<'_>,
) -> Result<StudyResult> {
    robot.validate()?;
    if !(config.initial_guess_scale.is_finite() && config.initial_guess_scale > 0.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "initial_guess_scale".into(),
            value: config.initial_guess_scale,
            reason: "must be finite and > 0 (λ0 = scale·λ must stay physical)",
        });
    }
    let start = Instant::now();
    let mut timings = Timings::default();
    let model = robot.model();
    let truth = robot.base_parameters();
    let lambda0 = truth * config.initial_guess_scale;
    // The robot as a chain and its base model: what every stage below runs on. Scaling
    // every mass and inertia by the same factor scales β and λ alike, so β0 is λ0's.
    let chain = SerialChain::from_robot(robot)?.to_dyn();
    let base = chain.base_parameters(&BaseOptions::default())?;
    let base_model = chain.base_model(&base)?;
    let view = PaperLambdaView::new(&base_model, robot.gravity)?;
    let beta_truth = base_model.chain_base_values().clone();
    let beta0 = &beta_truth * config.initial_guess_scale;

    // 1. Excitation (the paper's trajectory family, scored on its λ regressor).
    let t0 = Instant::now();
    let exc_cfg = ExcitationConfig {
        seed: config.seed,
        ..config.excitation
    };
    let exc = optimise_excitation::<DEFAULT_EXCITATION_KNOTS>(&model, &exc_cfg, |p| {
        progress("excitation", p.evaluations, p.max_evaluations)
    })?;
    timings.excitation = t0.elapsed().as_secs_f64();

    // 2. Estimation run: the true chain under a controller holding the rough model β0.
    let t0 = Instant::now();
    let sim_cfg = SimulationConfig {
        seed: config.seed,
        ..config.simulation
    };
    let controller = ParameterisedModel::new(base_model.clone(), beta0.clone())?;
    let rec = simulate_dyn_closed_loop(
        &chain,
        &controller,
        &exc.trajectory,
        exc_cfg.duration,
        &DynSimulationConfig::from(&sim_cfg),
    )?;
    timings.simulation = t0.elapsed().as_secs_f64();
    progress("simulation", 1, 1);
    let q_measured = rows5(&rec.q_measured);
    let tau_measured = rows5(&rec.tau_measured);

    // 3. Preprocessing of the measured signals.
    let t0 = Instant::now();
    let data = DynDataset::from(preprocess(
        &rec.t,
        &q_measured,
        &tau_measured,
        &config.preprocess,
    )?);
    timings.preprocessing = t0.elapsed().as_secs_f64();
    progress("preprocessing", 1, 1);

    // 4. The four estimators, in parallel.
    let data_rows = Rows::new(&data);
    let samples = data_rows.samples()?;
    let raw_data = raw_rows(&rec.q_measured, &rec.tau_measured, NDOF);
    let raw = raw_data.samples()?;
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tick = || {
        progress(
            "estimators",
            done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
            4,
        )
    };
    let est = Estimation {
        chain: &chain,
        base: &base,
        model: &base_model,
        view: &view,
        data: &data,
        samples: &samples,
        beta0: &beta0,
        config,
    };
    // Each worker runs under the caller's stop flag and counts itself done.
    let flag = crate::interrupt::current();
    let worker = |run: &dyn Fn() -> Result<MethodEstimate>| {
        crate::interrupt::within(flag.clone(), || {
            let r = run();
            tick();
            r
        })
    };
    let (ls, ad, hn, ekf) = std::thread::scope(|s| {
        let ls = s.spawn(|| worker(&|| est.least_squares()));
        let ad = s.spawn(|| worker(&|| est.adaline()));
        let hn = s.spawn(|| worker(&|| est.hopfield()));
        let ekf = est.ekf(&raw, sim_cfg.dt);
        tick();
        (join(ls), join(ad), join(hn), ekf)
    });
    let mut estimates: Vec<MethodEstimate> = [ls, ad, hn, ekf]
        .into_iter()
        .zip(METHODS)
        .map(|(r, name)| {
            r.unwrap_or_else(|e| MethodEstimate {
                lambda: arr8(&lambda0),
                beta: beta0.as_slice().to_vec(),
                error: Some(e.to_string()),
                ..empty(name)
            })
        })
        .collect();
    for e in &mut estimates {
        e.relative_error_percent = relative_errors_percent(&e.lambda, truth.as_slice());
    }
    timings.least_squares = estimates[0].seconds;
    timings.adaline = estimates[1].seconds;
    timings.hopfield = estimates[2].seconds;
    timings.ekf = estimates[3].seconds;

    // 5. Validation on other references, same controller for every model.
    let t0 = Instant::now();
    let val_cfg = ValidationConfig {
        seed: config.seed + 1,
        ..config.validation
    };
    let named: Vec<(String, Lambda)> = estimates
        .iter()
        .map(|e| (e.method.clone(), Lambda::from(e.lambda)))
        .collect();
    let report = validate(&model, &truth, &lambda0, &named, Some(&truth), &val_cfg)?;
    timings.validation = t0.elapsed().as_secs_f64();
    progress("validation", 1, 1);
    let validation = ValidationSummary {
        t: report.truth.t.clone(),
        q_ref: rows(&report.truth.q_ref),
        q_true: rows(&report.truth.q),
        methods: report
            .methods
            .iter()
            .map(|m| MethodValidationSummary {
                method: m.method.clone(),
                q: rows(&m.q),
                rms: m.indices.map(|i| i.rms),
                rsd: m.indices.map(|i| i.rsd),
                ai: m.indices.map(|i| i.ai),
                torque_rms: m.torque.rms,
                torque_relative_percent: m.torque.relative_percent,
            })
            .collect(),
    };

    // 6. Sensitivity around the truth, on the validation reference.
    let t0 = Instant::now();
    let sens_cfg = SensitivityConfig {
        validation: val_cfg,
        ..config.sensitivity
    };
    let sens = sensitivity(&model, &truth, &sens_cfg, &|d, n| {
        progress("sensitivity", d, n)
    })?;
    timings.sensitivity = t0.elapsed().as_secs_f64();

    timings.total = start.elapsed().as_secs_f64();
    Ok(StudyResult {
        schema_version: 1,
        seed: config.seed,
        truth: arr8(&truth),
        initial_guess: arr8(&lambda0),
        base_names: base
            .independent
            .iter()
            .map(|&i| base.names[i].clone())
            .collect(),
        beta_truth: beta_truth.as_slice().to_vec(),
        excitation: ExcitationSummary {
            cond_initial: exc.cond_initial,
            cond_final: exc.cond_final,
            evaluations: exc.evaluations,
            limits_satisfied: exc.limits_satisfied,
            samples: exc.samples,
            duration: exc_cfg.duration,
        },
        estimation_data: EstimationData {
            t: rec.t.clone(),
            q_ref: flat_rows(&rec.q_ref),
            q: flat_rows(&rec.q),
            q_measured: rows(&q_measured),
            tau_measured: rows(&tau_measured),
        },
        estimates,
        validation,
        sensitivity: SensitivitySummary {
            factors: sens.factors,
            ranges: sens.ranges.iter().map(|&(a, b)| [a, b]).collect(),
            rms: sens.rms,
        },
        timings_s: timings,
    })
}

/// Rows of 5 of a flat run-time record column.
fn rows5(flat: &[f64]) -> Vec<Vec5> {
    flat.chunks_exact(NDOF)
        .map(Vec5::from_column_slice)
        .collect()
}

fn flat_rows(flat: &[f64]) -> Vec<[f64; NDOF]> {
    rows(&rows5(flat))
}

/// The raw measured positions `q` and torques `tau` (flat, n per sample) as estimator
/// rows, q̇ and q̈ zero: the EKF reads positions and torques only.
fn raw_rows(q: &[f64], tau: &[f64], n: usize) -> Rows {
    let col = |flat: &[f64]| -> Vec<DVector<f64>> {
        flat.chunks_exact(n)
            .map(DVector::from_column_slice)
            .collect()
    };
    let q = col(q);
    Rows {
        qd: vec![DVector::zeros(n); q.len()],
        qdd: vec![DVector::zeros(n); q.len()],
        q,
        tau: col(tau),
    }
}

fn join<T>(h: std::thread::ScopedJoinHandle<'_, Result<T>>) -> Result<T> {
    h.join().unwrap_or(Err(PrrrpError::Diverged {
        what: "estimator thread",
        at: 0,
        hint: "an estimator panicked; this is a bug, please report it",
    }))
}

fn empty(method: &str) -> MethodEstimate {
    MethodEstimate {
        method: method.into(),
        lambda: [0.0; NPARAM],
        beta: vec![],
        relative_error_percent: vec![],
        std: None,
        rsd_percent: None,
        cond: None,
        sigma2: None,
        history: None,
        seconds: 0.0,
        error: None,
    }
}

/// What the study's estimators share: the chain and its base analysis and model, the λ
/// view, the preprocessed data, the rough initial guess β0 and the study's settings (each
/// estimator reads its own).
struct Estimation<'a> {
    chain: &'a DynChain,
    base: &'a crate::models::chain::BaseParameters,
    model: &'a DynChainBaseModel,
    view: &'a PaperLambdaView,
    data: &'a DynDataset,
    samples: &'a DynSamples<'a>,
    beta0: &'a DVector<f64>,
    config: &'a StudyConfig,
}

impl Estimation<'_> {
    /// The preprocessing as an identified model records it.
    fn preprocessing(&self) -> serde_json::Value {
        let p = &self.config.preprocess;
        serde_json::json!({
            "cutoff_hz": p.cutoff_hz,
            "order": p.order,
            "filter_torque": p.filter_torque,
            "trim_samples": p.trim,
            "decimate": p.decimate,
        })
    }

    /// Least squares through [`identify`]: σ from its covariance, seen through the view.
    fn least_squares(&self) -> Result<MethodEstimate> {
        let t0 = Instant::now();
        let method = Method::Ls(LsSettings {
            rank_tolerance: self.config.least_squares.rank_tolerance,
        });
        let m = identify(
            self.chain,
            self.base,
            self.data,
            &method,
            self.preprocessing(),
        )?;
        let lambda = self.view.lambda(&m.beta)?;
        let std = match &m.covariance {
            Some(c) => Some(self.view.sigma(c)?),
            None => None,
        };
        let rsd_percent = std.map(|s| std::array::from_fn(|i| 100.0 * s[i] / lambda[i].abs()));
        // σ² of the residual: the model's per-joint residual RMS over the equations left
        // after the fitted parameters.
        let equations = (self.data.len() * self.data.dof()) as f64;
        let sse: f64 = m.residual_rms.iter().map(|r| r * r).sum::<f64>() * self.data.len() as f64;
        Ok(MethodEstimate {
            lambda,
            beta: m.beta.clone(),
            std,
            rsd_percent,
            cond: m.cond,
            sigma2: Some(sse / (equations - m.beta.len() as f64).max(1.0)),
            seconds: t0.elapsed().as_secs_f64(),
            ..empty(METHODS[0])
        })
    }

    fn adaline(&self) -> Result<MethodEstimate> {
        let t0 = Instant::now();
        let mut net = DynAdaline::new(self.model.clone(), self.beta0.clone(), self.config.adaline)?;
        let mut history = History {
            t: vec![0.0],
            lambda: vec![self.view.lambda(self.beta0.as_slice())?],
        };
        for epoch in 0..self.config.adaline_epochs {
            net.train(self.samples, 1)?;
            history.t.push((epoch + 1) as f64);
            history
                .lambda
                .push(self.view.lambda(net.estimate().as_slice())?);
        }
        self.online_estimate(METHODS[1], t0, net.estimate(), history)
    }

    fn hopfield(&self) -> Result<MethodEstimate> {
        let t0 = Instant::now();
        let hcfg: HopfieldConfig = self.config.hopfield;
        let mut net = DynHopfield::new(self.model.clone(), self.beta0.clone(), hcfg)?;
        let history =
            self.run_online(&mut net, self.samples, self.config.hopfield_epochs, hcfg.dt)?;
        self.online_estimate(METHODS[2], t0, net.estimate(), history)
    }

    /// The EKF on the raw measured positions `raw` (sampled every `dt` s), not on the
    /// preprocessed data.
    fn ekf(&self, raw: &DynSamples<'_>, dt: f64) -> Result<MethodEstimate> {
        let t0 = Instant::now();
        let mut ekf = DynEkf::new(self.model.clone(), self.beta0.clone(), self.config.ekf)?;
        let history = self.run_online(&mut ekf, raw, 1, dt)?;
        self.online_estimate(METHODS[3], t0, ekf.estimate(), history)
    }

    /// The estimate β̂ `method` ended at, with its λ view and history, timed from `t0`.
    fn online_estimate(
        &self,
        method: &str,
        t0: Instant,
        beta: &DVector<f64>,
        history: History,
    ) -> Result<MethodEstimate> {
        Ok(MethodEstimate {
            lambda: self.view.lambda(beta.as_slice())?,
            beta: beta.as_slice().to_vec(),
            history: Some(history),
            seconds: t0.elapsed().as_secs_f64(),
            ..empty(method)
        })
    }

    /// Runs an online estimator over `passes` passes of `data`, keeping about
    /// `history_points` snapshots of λ̂ against estimation time (sample index × dt).
    fn run_online<E: Estimator<Dyn, Dyn>>(
        &self,
        est: &mut E,
        data: &DynSamples<'_>,
        passes: usize,
        dt: f64,
    ) -> Result<History> {
        let total = passes * data.len();
        let every = (total / self.config.history_points.max(1)).max(1);
        let mut history = History {
            t: vec![0.0],
            lambda: vec![self.view.lambda(est.estimate().as_slice())?],
        };
        let mut k = 0;
        for _ in 0..passes {
            for i in 0..data.len() {
                est.step(data.sample(i))
                    .map_err(|e| crate::estimators::with_row(e, i))?;
                k += 1;
                if k % every == 0 || k == total {
                    history.t.push(k as f64 * dt);
                    history
                        .lambda
                        .push(self.view.lambda(est.estimate().as_slice())?);
                }
            }
        }
        Ok(history)
    }
}
