//! One entry point for every estimator on a run-time chain: [`identify`] fits the base
//! parameters β of a [`DynChain`] (friction columns included) from a [`DynDataset`] by
//! least squares, weighted least squares, recursive least squares, Adaline, the Hopfield
//! network or the extended Kalman filter, and returns an [`IdentifiedModel`].
//!
//! The estimators are the library's own; this module only chooses their settings from the
//! data where the user gave none (defaults must hold on robots they were not tuned on) and
//! turns their output into a model:
//!
//! - W_b is stacked once for every method: data that do not excite every base parameter
//!   are [`PrrrpError::RankDeficient`] for every method, not a wrong online estimate
//!   (several methods on one data set share the stack through a [`FitCache`],
//!   [`identify_cached`]);
//! - RLS, Adaline and Hopfield run on column-scaled parameters ([`DynScaledModel`]), so
//!   that one step size and one initial covariance suit any robot;
//! - Adaline and Hopfield take their step from the data and halve it until the move
//!   between fixed points says the step's bias is below `parameter_tolerance` (the
//!   **stopping rule**); epochs start from an Anderson mixing of the last outputs and run
//!   on whitened parameters, so that a fixed point takes a few epochs, not thousands;
//! - the EKF starts from the least-squares β̂, with R and the residuals' correlation time
//!   measured in the data (`ekf_defaults`);
//! - σ of LS, WLS and the EKF accounts for the residuals' correlation time κ (filtered
//!   data carry ≈ rows/κ independent equations); Adaline and Hopfield give none.
//!
//! Design, derivations and measurements: docs/design/identify-methods.md.

use std::sync::{Arc, Mutex, MutexGuard};

use nalgebra::{DMatrix, DMatrixView, DVector, Dyn};
use serde_json::json;

use super::IdentifiedModel;
use crate::error::{invalid, PrrrpError, Result};
use crate::estimators::{
    AdalineConfig, AdalineRule, Discretisation, DynAdaline, DynEkf, DynHopfield, DynJointNoise,
    DynRls, DynSamples, EkfConfig, EkfMeasurement, Estimator, HopfieldConfig, LeastSquares,
    LeastSquaresConfig, ParameterJacobian, RlsConfig, StoredRegressors, MAX_STORED_REGRESSOR_BYTES,
};
use crate::models::chain::{BaseOptions, BaseParameters, DynChain, DynChainBaseModel, SerialChain};
use crate::models::prrrp::robot::Robot;
use crate::models::scaled::DynScaledModel;
use crate::models::LinearModel;
use crate::DynDataset;

/// The identification methods of [`identify`], with their settings.
#[derive(Debug, Clone, PartialEq)]
pub enum Method {
    /// Ordinary least squares (σ, %σ from the residual).
    Ls(LsSettings),
    /// Weighted least squares, per-joint noise variances estimated from the residuals.
    Wls(LsSettings),
    /// Recursive least squares, one pass over the data.
    Rls(RlsSettings),
    /// Adaline networks trained over epochs.
    Adaline(GradientSettings),
    /// The Hopfield network (Abe's formulation) trained over epochs.
    Hopfield(GradientSettings),
    /// The extended Kalman filter on [q, q̇, β], one pass over the data.
    Ekf(EkfSettings),
    /// Physically consistent least squares over the standard parameters (every link's
    /// pseudo-inertia ⪰ 0, fv, fc ≥ 0; [`crate::identify_physical`]). The model carries
    /// the standard parameters ([`IdentifiedModel::standard`]) and exports a URDF.
    Physical(PhysicalSettings),
}

/// Settings of [`Method::Physical`].
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalSettings {
    /// Prior standard parameters π₀; `None` (default): the robot's own,
    /// [`DynChain::parameters`] (a URDF's inertials, a TOML file's `inertial` and
    /// `friction`), the values a user has before identifying.
    pub prior: Option<Vec<f64>>,
    /// Weight of the ridge term towards the prior, ≥ 0 (default 0); see
    /// [`crate::PhysicalConfig::prior_weight`].
    pub prior_weight: f64,
    /// Weight γ ≥ 0 of the geometric prior, in units of the data's χ² (default
    /// [`crate::DEFAULT_DIVERGENCE_WEIGHT`]); see
    /// [`crate::PhysicalConfig::divergence_weight`].
    pub divergence_weight: f64,
    /// Weigh each joint's equations by 1/σ_j², σ_j² the residual variances that
    /// [`Method::Wls`] estimates (default `true`), as `wls` does; `false`: unit weights.
    pub weighted: bool,
    /// Rank tolerance of the least-squares solve made for cond(W_b) (default 1e-10).
    pub rank_tolerance: f64,
}

impl Default for PhysicalSettings {
    fn default() -> Self {
        Self {
            prior: None,
            prior_weight: 0.0,
            divergence_weight: crate::DEFAULT_DIVERGENCE_WEIGHT,
            weighted: true,
            rank_tolerance: LsSettings::default().rank_tolerance,
        }
    }
}

/// The names [`Method::parse`] accepts, in the order of [`Method`].
pub const METHOD_NAMES: [&str; 7] = ["ls", "wls", "rls", "adaline", "hopfield", "ekf", "physical"];

impl Method {
    /// The method by name (one of [`METHOD_NAMES`]) with default settings.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for an unknown name.
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name {
            "ls" => Self::Ls(LsSettings::default()),
            "wls" => Self::Wls(LsSettings::default()),
            "rls" => Self::Rls(RlsSettings::default()),
            "adaline" => Self::Adaline(GradientSettings::adaline()),
            "hopfield" => Self::Hopfield(GradientSettings::hopfield()),
            "ekf" => Self::Ekf(EkfSettings::default()),
            "physical" => Self::Physical(PhysicalSettings::default()),
            _ => {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("method {name:?}"),
                    value: f64::NAN,
                    reason: "unknown: use \"ls\", \"wls\", \"rls\", \"adaline\", \"hopfield\" \
                             or \"ekf\"",
                })
            }
        })
    }

    /// The method's name, as recorded in [`IdentifiedModel::method`].
    pub fn name(&self) -> &'static str {
        match self {
            Self::Ls(_) => "ls",
            Self::Wls(_) => "wls",
            Self::Rls(_) => "rls",
            Self::Adaline(_) => "adaline",
            Self::Hopfield(_) => "hopfield",
            Self::Ekf(_) => "ekf",
            Self::Physical(_) => "physical",
        }
    }

    /// Rank tolerance of the least-squares solve every method makes (for cond(W_b)).
    pub fn rank_tolerance(&self) -> f64 {
        match self {
            Self::Ls(s) | Self::Wls(s) => s.rank_tolerance,
            Self::Rls(s) => s.rank_tolerance,
            Self::Adaline(s) | Self::Hopfield(s) => s.rank_tolerance,
            Self::Ekf(s) => s.rank_tolerance,
            Self::Physical(s) => s.rank_tolerance,
        }
    }
}

/// Settings of [`Method::Ls`] and [`Method::Wls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LsSettings {
    /// Relative rank tolerance of the solve (dimensionless, default `1e-10`, as
    /// [`LeastSquaresConfig`]).
    pub rank_tolerance: f64,
}

impl Default for LsSettings {
    fn default() -> Self {
        Self {
            rank_tolerance: LeastSquaresConfig::default().rank_tolerance,
        }
    }
}

/// Settings of [`Method::Rls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsSettings {
    /// Rank tolerance of the least-squares solve for cond(W_b) (default `1e-10`).
    pub rank_tolerance: f64,
    /// Forgetting factor ν in (0, 1] (default `1.0`: the estimate is regularised batch
    /// least squares, and σ is reported; with ν < 1 it is not).
    pub forgetting: f64,
    /// Initial covariance δ of P₀ = δ·I in the units of the scaled parameters γ (N²·m²
    /// per N²·m² of torque: dimensionless with equilibrated columns; default `1e6`, a
    /// prior standard deviation of 1000 N·m on each γ_j, the RMS torque parameter j
    /// explains; within [`crate::MIN_INITIAL_COVARIANCE`]..[`crate::MAX_INITIAL_COVARIANCE`]
    /// with `scale_columns`).
    pub initial_covariance: f64,
    /// Equilibrate the columns (default `true`); without, δ is in the units of β².
    pub scale_columns: bool,
}

impl Default for RlsSettings {
    fn default() -> Self {
        Self {
            rank_tolerance: LeastSquaresConfig::default().rank_tolerance,
            forgetting: 1.0,
            initial_covariance: 1e6,
            scale_columns: true,
        }
    }
}

/// Settings of [`Method::Adaline`] and [`Method::Hopfield`] (the gradient methods).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GradientSettings {
    /// Rank tolerance of the least-squares solve for cond(W_b) (default `1e-10`).
    pub rank_tolerance: f64,
    /// Adaline's update rule (default [`AdalineRule::Delta`], eq. 11; ignored by the
    /// Hopfield network). As the step shrinks, the delta rule's epochs converge to the
    /// ordinary least-squares solution, while the normalised rule's converge to least
    /// squares weighted by 1/‖x_i‖² (its update divides by the row norm), which gives the
    /// rows of a slow, weakly exciting stretch of the data the largest weight and their
    /// noise with it: on the paper's arm that left λ̂ 3–7 % off where least squares was
    /// within 0.6 %.
    pub rule: AdalineRule,
    /// Initial step μ, dimensionless in (0, 2) (default `0.5`): the normalised rule's
    /// step, or the delta rule's learning rate times max_i‖x_i‖², or the Hopfield gain
    /// times max_k‖Φ_k‖_F². Outside (0, 2) is [`PrrrpError::InvalidParameter`] (unstable).
    pub step_size: f64,
    /// The delta rule's learning rate γ_lr itself (units of 1/x²), overriding
    /// `step_size`; γ_lr·max_i‖x_i‖² ≥ 2 on the data is [`PrrrpError::InvalidParameter`].
    pub learning_rate: Option<f64>,
    /// The Hopfield bound c (units of γ, or of β without scaling): estimates live in
    /// (−c, c). Default: 4·max|γ̂_LS| of the least-squares solve (floored at the RMS
    /// torque), which leaves the gain c² − γ² within 6 % of c² for every parameter.
    pub bound: Option<f64>,
    /// Most epochs (passes over the data), default `3000`: the cap of the stopping rule.
    /// A run that reaches it without meeting the tolerances below is reported as not
    /// converged ([`IdentifiedModel::converged`] = false), not as a result.
    pub max_epochs: usize,
    /// Most step halvings in all (default `24`: a final step no smaller than μ·2⁻²⁴). At
    /// each fixed point whose bias still left (from its move from the previous step's
    /// fixed point, see [`identify`]) is not below `parameter_tolerance`, the step is cut
    /// by the power of 2 predicted to bring it there; a run that uses them all without
    /// meeting it is reported as not converged.
    pub halvings: usize,
    /// Tolerance on the relative change of the estimate still to come (dimensionless,
    /// default `1e-5`): the change per epoch δ = max_j |γ_j − γ_j⁻| / max(|γ_j|,
    /// 1e-3·max_i|γ_i|, 0.01·σ_j/tol) over the column-scaled parameters γ (γ⁻: one epoch
    /// earlier; σ_j least squares' standard deviation of γ_j, so that changes below 1 %
    /// of what the data resolve count as none), extrapolated geometrically, δ·r/(1 − r)
    /// with r the ratio of the last two δ.
    pub parameter_tolerance: f64,
    /// Tolerance on the relative change of the epoch's RMS equation error (dimensionless,
    /// default `1e-6`): |e − e⁻| / e.
    pub error_tolerance: f64,
    /// Equilibrate the columns (default `true`).
    pub scale_columns: bool,
    /// Whiten the parameters (default `true`; implies equilibrated columns): the networks
    /// run on γ with β = D·T·γ, T from the data so that the regressor's columns are
    /// orthogonal ([`DynScaledModel::whitened`]). Without it a gradient method needs
    /// ≈ cond(W·D)² epochs: on gentle trajectories (cond ≈ 100) far beyond any cap.
    pub whiten: bool,
}

impl GradientSettings {
    /// Defaults for Adaline.
    pub fn adaline() -> Self {
        Self {
            rank_tolerance: LeastSquaresConfig::default().rank_tolerance,
            rule: AdalineRule::Delta,
            step_size: 0.5,
            learning_rate: None,
            bound: None,
            max_epochs: 3000,
            halvings: 24,
            parameter_tolerance: 1e-5,
            error_tolerance: 1e-6,
            scale_columns: true,
            whiten: true,
        }
    }

    /// Defaults for the Hopfield network (the same as Adaline's).
    pub fn hopfield() -> Self {
        Self::adaline()
    }
}

impl Default for GradientSettings {
    fn default() -> Self {
        Self::adaline()
    }
}

/// Where the EKF starts.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum EkfStart {
    /// The joint-weighted least-squares estimate on the same data (default), or the
    /// physically consistent one ([`EkfStart::Physical`]) when M(q, β̂_LS) is not positive
    /// definite at some sample of the data: the filter must start inside the region where
    /// its forward dynamics exist (ordinary least squares, the default before, left the
    /// wrist inertias of a UR10 and an SO-100 stand-in log negative, so that the filter
    /// stopped at sample 0).
    #[default]
    LeastSquares,
    /// The physically consistent estimate ([`crate::identify_physical`], every link a
    /// rigid body) on the same data, with the prior covariance of least squares.
    Physical,
    /// The chain's own parameters (its CAD / URDF inertials and friction).
    Prior,
    /// Given β₀ (one entry per base parameter).
    Given(Vec<f64>),
}

/// Settings of [`Method::Ekf`].
#[derive(Debug, Clone, PartialEq)]
pub struct EkfSettings {
    /// Rank tolerance of the least-squares solve (default `1e-10`).
    pub rank_tolerance: f64,
    /// Initial β₀ (default [`EkfStart::LeastSquares`]).
    pub initial: EkfStart,
    /// Sample period, s (default: the median time step of the data).
    pub dt: Option<f64>,
    /// The filter's settings; `dt` is replaced by the one above. Defaults: measured
    /// positions and velocities, second-order discretisation, the rest as
    /// [`EkfConfig::default`] except a prior relative uncertainty of 0.1 on β₀ (it
    /// starts from a fit, not a guess) floored at 1e-3 of max|β₀|, and no random walk of
    /// the parameters (they are constant over a recording).
    pub config: EkfConfig,
    /// Take the measurement noise R of each joint's position and velocity from their
    /// third differences in the data (default `false`: on exact positions it makes R so
    /// small that the filter fits the torque noise, and it did not reduce the error on
    /// filtered noisy data either; module `ekf_defaults`), replacing
    /// `config.position_noise` and `config.velocity_noise` (giving either from Python
    /// turns this off). The process noise on q̇ is h²·M⁻¹·diag(σ²)·M⁻ᵀ from the
    /// least-squares residual variances σ² (and (h²/2)² of it on q), added to
    /// `config.process_position_noise` and `config.process_velocity_noise` (0 here).
    pub noise_from_data: bool,
    /// Take M of the process noise Q_q̇ = h²·M⁻¹·diag(σ²)·M⁻ᵀ at every sample and the
    /// current λ̂ (default `true`) instead of once at the first sample and β₀: with a
    /// fixed Q the filter prefers the λ with the smallest M⁻¹ (torque noise biases the
    /// inertias up); scaled with M⁻¹(λ̂) the weighted innovation is the torque error.
    pub process_noise_at_estimate: bool,
    /// Width w of the prior when starting from least squares (default `3.0`): P₀ of β is
    /// w²·(Σ_k Y_kᵀ·Σ⁻¹·Y_k)⁻¹, the covariance of the joint-variance weighted fit on the
    /// same data (Σ = diag of the least-squares residual variances), instead of the
    /// diagonal `config.initial_parameter_rel_std`. It tells the filter which
    /// combinations of β the data determine and how well, in every parameter's own units
    /// (a relative or absolute floor mixes kg, kg·m and kg·m²): a 10 % diagonal prior
    /// let poorly excited small parameters wander out of the physical region in the first
    /// second of gentle data. The data then count 1/w² twice (the prior's information is
    /// 1/w² of theirs), so the reported covariance is multiplied by 1 + 1/w². `0` or a
    /// start other than least squares or the physical estimate keeps the diagonal prior.
    /// Smaller widths let the filter move less from its start (the command line's
    /// `--ekf-prior-width`).
    pub least_squares_prior_width: f64,
    /// Multiply the reported parameter covariance by the correlation time κ ≥ 1 (samples)
    /// of the least-squares torque residuals (default `true`): the filter assumes white
    /// noise, and low-pass filtered data are not.
    pub correlation_correction: bool,
    /// Take the filter's time update linearly implicit where the dynamics are stiff at
    /// the sample period (default `true`; [`crate::DynEkf::set_stiff_handling`]): friction
    /// over a light wrist made the explicit step diverge within a few dozen samples.
    pub stiff_handling: bool,
}

impl Default for EkfSettings {
    fn default() -> Self {
        Self {
            rank_tolerance: LeastSquaresConfig::default().rank_tolerance,
            initial: EkfStart::LeastSquares,
            dt: None,
            noise_from_data: false,
            process_noise_at_estimate: true,
            least_squares_prior_width: 3.0,
            correlation_correction: true,
            stiff_handling: true,
            config: EkfConfig {
                measurement: EkfMeasurement::PositionsVelocities,
                discretisation: Discretisation::Midpoint,
                initial_parameter_rel_std: 0.1,
                process_parameter_noise: 0.0,
                // Taken from the data (`noise_from_data`); these add to it.
                process_position_noise: 0.0,
                process_velocity_noise: 0.0,
                initial_parameter_min_std: 0.0,
                parameter_jacobian: ParameterJacobian::DataAcceleration,
                ..EkfConfig::default()
            },
        }
    }
}

/// The data as owned run-time vectors (the estimators' sample type).
pub(crate) struct Rows {
    pub(crate) q: Vec<DVector<f64>>,
    pub(crate) qd: Vec<DVector<f64>>,
    pub(crate) qdd: Vec<DVector<f64>>,
    pub(crate) tau: Vec<DVector<f64>>,
}

impl Rows {
    pub(crate) fn new(data: &DynDataset) -> Self {
        let n = data.dof();
        let rows = |flat: &[f64]| -> Vec<DVector<f64>> {
            flat.chunks_exact(n)
                .map(DVector::from_column_slice)
                .collect()
        };
        Self {
            q: rows(data.q()),
            qd: rows(data.qd()),
            qdd: rows(data.qdd()),
            tau: rows(data.tau()),
        }
    }

    pub(crate) fn samples(&self) -> Result<DynSamples<'_>> {
        DynSamples::new(&self.q, &self.qd, &self.qdd, &self.tau)
    }
}

/// Identifies the base parameters of `chain` in the analysis `base` from `data` by
/// `method` (see the module docs for the defaults each method takes from the data). The
/// model records β̂, σ and %σ where the method gives them, cond(W_b), the per-joint
/// residual RMS on `data`, the method, its settings as used (JSON, including the values
/// chosen from the data) and `preprocessing` as given.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if the data's joint count or the analysis do not fit the
/// chain; [`PrrrpError::TooFewSamples`] for fewer equations than base parameters + 1;
/// [`PrrrpError::RankDeficient`] for data that do not excite every base parameter;
/// [`PrrrpError::InvalidParameter`] for a setting out of range (an unstable step size
/// among them); [`PrrrpError::Diverged`] when an online estimator blows up (the EKF leaving
/// the physical region); [`PrrrpError::Interrupted`] after [`crate::request_stop`].
pub fn identify(
    chain: &DynChain,
    base: &BaseParameters,
    data: &DynDataset,
    method: &Method,
    preprocessing: serde_json::Value,
) -> Result<IdentifiedModel> {
    identify_cached(
        chain,
        base,
        data,
        method,
        preprocessing,
        &FitCache::default(),
    )
}

/// [`identify`] taking the least-squares stack of W_b and its solve from `cache`, built
/// there by the first method that needs it: several methods on one data set build W_b
/// at most once unweighted (ls, rls, adaline, hopfield, physical with
/// `weighted = false`) and once weighted (wls, ekf, physical) per rank tolerance. The
/// model is the one [`identify`] gives, bit for bit.
///
/// # Errors
/// As [`identify`], and [`PrrrpError::InvalidParameter`] for a `cache` filled from other
/// data, another chain or another base analysis.
pub fn identify_cached(
    chain: &DynChain,
    base: &BaseParameters,
    data: &DynDataset,
    method: &Method,
    preprocessing: serde_json::Value,
    cache: &FitCache,
) -> Result<IdentifiedModel> {
    // The one-pass methods (ls, wls) never polled: a raised stop flag let them run.
    crate::interrupt::check("identification")?;
    let n = chain.dof();
    data.check_dof(n, "the robot's")?;
    let model = chain.base_model(base)?;
    let b = model.count();
    if let Method::Ekf(s) = method {
        check_given_start(&s.initial, b)?;
    }
    // One equation more than unknowns, so that the residual variance is defined.
    let needed = (b + 1).div_ceil(n);
    if data.len() < needed {
        return Err(PrrrpError::TooFewSamples {
            needed,
            got: data.len(),
        });
    }
    let rows = Rows::new(data);
    let samples = rows.samples()?;
    cache.check_inputs(Fingerprint::of(&model, data)?)?;
    let config = LeastSquaresConfig {
        rank_tolerance: method.rank_tolerance(),
    };
    // The physical fit takes its joint weights from the same weighted solve as wls; the
    // EKF starts from the weighted fit (see `EkfStart::LeastSquares`).
    let weighted = match method {
        Method::Wls(_) | Method::Ekf(_) => true,
        Method::Physical(s) => s.weighted,
        _ => false,
    };
    // The solver keeps the stacked base regressor W of the data, from which the
    // covariance, the residuals and the model's residual RMS below are products instead of
    // a regressor per sample each; it is only read from here on, so methods share it.
    let shared = cache.fit(weighted, config, || {
        let mut stack = LeastSquares::new(config)?;
        let ls = if weighted {
            stack.solve_weighted(&model, &samples, DynJointNoise::Estimated)?
        } else {
            stack.solve(&model, &samples)?
        };
        Ok(SharedFit { stack, ls })
    })?;
    let (stack, ls) = (&shared.stack, &shared.ls);
    let mut standard: Option<Vec<f64>> = None;
    // The least-squares covariance from the residuals (see `ls_covariance`).
    let cov = match method {
        Method::Ls(_) | Method::Wls(_) => {
            let weights: Vec<f64> = match method {
                Method::Wls(_) => ls.joint_variances.iter().map(|v| 1.0 / v).collect(),
                _ => vec![1.0; n],
            };
            Some(ls_covariance(
                &model, &samples, &ls.lambda, &weights, stack,
            )?)
        }
        _ => None,
    };
    let sandwich_sigma: Vec<f64> = match cov.as_ref().and_then(|c| c.covariance.as_ref()) {
        Some(c) => c.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect(),
        // A singular WᵀW cannot happen after a full-rank solve; keep the solver's own σ
        // should round-off say otherwise.
        None => ls.std_dev.iter().copied().collect(),
    };
    let fit = match method {
        Method::Ls(s) | Method::Wls(s) => {
            let (covariance, variances, kappas) = match cov {
                Some(c) => (c.covariance, c.variances, c.kappas),
                None => (None, Vec::new(), Vec::new()),
            };
            Fit {
                beta: ls.lambda.clone(),
                sigma: Some(sandwich_sigma),
                covariance: covariance.map(RawCovariance::Scaled),
                settings: json!({
                    "rank_tolerance": s.rank_tolerance,
                    "covariance": "sandwich: per-joint residual variances and correlation times",
                    "joint_residual_variances": variances,
                    "correlation_time_samples": kappas,
                }),
                converged: true,
                epochs: None,
            }
        }
        Method::Rls(s) => rls(&model, &samples, s)?,
        Method::Adaline(s) => gradient(
            &model,
            &samples,
            s,
            false,
            &ls.lambda,
            ls.std_dev.as_slice(),
            ls_rms(ls),
            MAX_STORED_REGRESSOR_BYTES,
        )?,
        Method::Hopfield(s) => gradient(
            &model,
            &samples,
            s,
            true,
            &ls.lambda,
            ls.std_dev.as_slice(),
            ls_rms(ls),
            MAX_STORED_REGRESSOR_BYTES,
        )?,
        Method::Ekf(s) => {
            let run = |s: &EkfSettings| {
                ekf(
                    &model,
                    base,
                    data,
                    &samples,
                    s,
                    &ls.lambda,
                    ls.joint_variances.as_slice(),
                    stack,
                )
            };
            match run(s) {
                // The midpoint state is extrapolated half a period with the start's q̈; on
                // a λ̂ near the edge of the physical region M can lose definiteness there
                // first, or the covariance lose definiteness (seen on 7-joint arms at
                // 100 Hz, not understood yet). The second-order update, whose
                // bias is O(h) instead of O(h²), is then used and the settings say so.
                Err(PrrrpError::Diverged { .. } | PrrrpError::NotPositiveDefinite { .. })
                    if s.config.discretisation == Discretisation::Midpoint =>
                {
                    let mut fallback = s.clone();
                    fallback.config.discretisation = Discretisation::SecondOrder;
                    let mut fit = run(&fallback)?;
                    fit.settings["midpoint_diverged"] = json!(true);
                    fit
                }
                r => r?,
            }
        }
        Method::Physical(s) => {
            let joint_weights: Option<Vec<f64>> = s
                .weighted
                .then(|| ls.joint_variances.iter().map(|v| 1.0 / v).collect());
            // One unit of χ² for the divergence: the weighted residual variance of the
            // least-squares fit times the residuals' correlation time, so that a low-pass
            // filtered log's rows/κ independent equations are what the prior is weighed
            // against (as `ls_covariance` counts them for σ).
            let moments = joint_moments(&model, &samples, &ls.lambda, stack)?;
            let unit = (0..n)
                .map(|j| {
                    let w = joint_weights.as_ref().map_or(1.0, |w| w[j]);
                    w * moments.variances[j] * moments.kappas[j]
                })
                .sum::<f64>()
                / n as f64;
            let config = crate::PhysicalConfig {
                prior: Some(s.prior.clone().unwrap_or_else(|| chain.parameters())),
                prior_weight: s.prior_weight,
                divergence_weight: s.divergence_weight,
                noise_variance: (unit.is_finite() && unit > 0.0).then_some(unit),
                joint_weights: joint_weights.clone(),
                ..Default::default()
            };
            let est = crate::identify_physical(
                chain,
                data.q(),
                data.qd(),
                data.qdd(),
                data.tau(),
                &config,
            )?;
            standard = Some(est.parameters.clone());
            let failing: Vec<usize> = est
                .feasibility
                .links
                .iter()
                .enumerate()
                .filter(|(_, l)| !l.consistent)
                .map(|(i, _)| i + 1)
                .collect();
            Fit {
                beta: DVector::from_vec(base.base_values(&est.parameters)?),
                sigma: None,
                covariance: None,
                settings: json!({
                    "prior": match &s.prior {
                        None => json!("robot"),
                        Some(p) => json!(p),
                    },
                    "prior_weight": s.prior_weight,
                    "divergence_weight": s.divergence_weight,
                    "residual_variance": est.residual_variance,
                    "correlation_time_samples": moments.kappas,
                    "weighted": s.weighted,
                    "joint_weights": joint_weights,
                    "rank_tolerance": s.rank_tolerance,
                    "iterations": est.iterations,
                    "residual_increase_percent": est.residual_increase_percent,
                    "non_physical_links": failing,
                }),
                converged: true,
                epochs: None,
            }
        }
    };
    let mut out = IdentifiedModel::new(
        chain,
        base,
        fit.beta.iter().copied().collect(),
        None,
        None,
        Some(ls.cond),
        vec![0.0; n],
        method.name(),
        fit.settings,
        preprocessing,
    )?;
    out.standard = standard;
    out.converged = fit.converged;
    out.epochs = fit.epochs;
    let (sse, rms) = match stack.residuals_at(&out.beta) {
        Some(r) => joint_residuals(&r, n),
        None => residuals(
            &out.predict(data.q(), data.qd(), data.qdd())?,
            data.tau(),
            n,
        ),
    };
    out.residual_rms = rms;
    let sigma = match (fit.sigma, &fit.covariance) {
        (Some(s), Some(RawCovariance::Scaled(p))) => {
            out.covariance = Some(p.transpose().iter().copied().collect());
            Some(s)
        }
        (Some(s), _) => Some(s),
        (None, Some(RawCovariance::Unscaled(p))) => {
            // σ̂² from the residual of the final estimate, as least squares does.
            let dof = (n * data.len()).saturating_sub(b).max(1) as f64;
            let s2 = sse / dof;
            out.covariance = Some(p.transpose().iter().map(|v| v * s2).collect());
            Some(
                p.diagonal()
                    .iter()
                    .map(|v| (v.max(0.0) * s2).sqrt())
                    .collect(),
            )
        }
        (None, Some(RawCovariance::Scaled(p))) => {
            out.covariance = Some(p.transpose().iter().copied().collect());
            Some(p.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect())
        }
        (None, None) => None,
    };
    if let Some(sigma) = sigma {
        out.rsd_percent = Some(
            sigma
                .iter()
                .zip(&out.beta)
                .map(|(s, b): (&f64, &f64)| (*b != 0.0).then(|| 100.0 * s / b.abs()))
                .collect(),
        );
        out.sigma = Some(sigma);
    }
    out.actuators = out.actuator_estimates();
    out.validate()?;
    Ok(out)
}

/// [`identify`] for the paper's PRRRP arm: the robot as its equivalent chain
/// ([`SerialChain::from_robot`], the same dynamics as the closed form) with its numerical
/// base-parameter analysis (9 base parameters of the 10-per-link model: the paper's λ1–λ5,
/// λ8, m4·lc4 + m5·l4, of which the paper's λ6 and λ7 are l2 and l3 times, and two lateral
/// first moments that are 0 for this robot), so that the saved model predicts on its
/// own.
///
/// # Errors
/// As [`identify`], and [`PrrrpError::InvalidParameter`] for a robot that fails
/// [`Robot::validate`].
pub fn identify_robot(
    robot: &Robot,
    data: &DynDataset,
    method: &Method,
    preprocessing: serde_json::Value,
) -> Result<IdentifiedModel> {
    identify_robot_cached(robot, data, method, preprocessing, &FitCache::default())
}

/// [`identify_robot`] sharing the least-squares work through `cache`, as
/// [`identify_cached`].
///
/// # Errors
/// As [`identify_robot`] and [`identify_cached`].
pub fn identify_robot_cached(
    robot: &Robot,
    data: &DynDataset,
    method: &Method,
    preprocessing: serde_json::Value,
    cache: &FitCache,
) -> Result<IdentifiedModel> {
    let chain = SerialChain::from_robot(robot)?.to_dyn();
    let base = chain.base_parameters(&BaseOptions::default())?;
    identify_cached(&chain, &base, data, method, preprocessing, cache)
}

/// The least-squares work that several [`identify_cached`] calls on one data set share:
/// the stacked base regressor W_b and its solve, one per weighting (ordinary or
/// joint-weighted) and rank tolerance, each built by the first call that needs it (a
/// second thread asking meanwhile waits for it). A failed build (rank deficient,
/// interrupted, ...) is not kept: the next call tries again and reports its own error.
///
/// A cache belongs to one data set, chain and base analysis: the first call records a
/// fingerprint of them (joint count, samples, base parameters, a checksum of q, q̇, q̈, τ
/// and of the base regressor at a fixed state) and a call with other inputs is refused.
/// It holds up to two copies of W_b (8·samples·joints·base parameters bytes each) until
/// dropped.
#[derive(Debug, Default)]
pub struct FitCache {
    inputs: Mutex<Option<Fingerprint>>,
    /// (weighted, rank tolerance bits) → the fit, behind its own lock so that building one
    /// does not hold up the other.
    fits: Mutex<Vec<FitSlot>>,
}

type FitSlot = ((bool, u64), Arc<Mutex<Option<Arc<SharedFit>>>>);

/// A solver holding the stacked W_b of the data and its solve's report.
#[derive(Debug)]
struct SharedFit {
    stack: LeastSquares,
    ls: crate::DynLeastSquaresReport,
}

/// What a [`FitCache`]'s contents depend on, beyond the weighting and rank tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Fingerprint {
    dof: usize,
    samples: usize,
    base: usize,
    data: u64,
    model: u64,
}

/// FNV-1a over 64-bit words: a checksum that any change of a value changes (not a
/// defence against crafted collisions, which a caller has no reason to make).
fn fnv(mut h: u64, words: impl IntoIterator<Item = u64>) -> u64 {
    for w in words {
        h = (h ^ w).wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

impl Fingerprint {
    fn of(model: &DynChainBaseModel, data: &DynDataset) -> Result<Self> {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let mut h = FNV_OFFSET;
        for v in [data.q(), data.qd(), data.qdd(), data.tau()] {
            h = fnv(h, v.iter().map(|x| x.to_bits()));
        }
        // The regressor at a fixed state of moderate speeds (inside the Coulomb
        // smoothing of any friction model, outside of it for the faster joints) tells
        // chains, friction models and base analyses apart.
        let n = model.dof();
        let state = |a: f64, b: f64| DVector::from_fn(n, |j, _| a + b * j as f64);
        let (q, qd, qdd) = (state(0.3, 0.41), state(0.01, -0.13), state(1.1, -0.37));
        let mut ws = model.workspace();
        let mut phi = DMatrix::zeros(n, model.count());
        model.regressor_into(&mut ws, &q, &qd, &qdd, &mut phi)?;
        Ok(Self {
            dof: n,
            samples: data.len(),
            base: model.count(),
            data: h,
            model: fnv(FNV_OFFSET, bits(phi.as_slice())),
        })
    }
}

/// A lock's contents even after a panic while it was held: every value stored under
/// these locks is complete (a fit is stored only once built).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl FitCache {
    /// An empty cache (the first [`identify_cached`] call fills it).
    pub fn new() -> Self {
        Self::default()
    }

    /// How many least-squares stacks (W_b with its solve) the cache holds: at most one
    /// per weighting and rank tolerance asked for.
    pub fn stacks(&self) -> usize {
        lock(&self.fits)
            .iter()
            .filter(|(_, slot)| lock(slot).is_some())
            .count()
    }

    fn check_inputs(&self, fingerprint: Fingerprint) -> Result<()> {
        let mut inputs = lock(&self.inputs);
        match *inputs {
            None => {
                *inputs = Some(fingerprint);
                Ok(())
            }
            Some(f) if f == fingerprint => Ok(()),
            Some(_) => Err(PrrrpError::InvalidParameter {
                field: "cache".into(),
                value: f64::NAN,
                reason: "holds the fit of other data, another robot or another base \
                         analysis: use one FitCache per data set",
            }),
        }
    }

    /// The fit of this weighting and tolerance, built by `build` if not there yet.
    fn fit(
        &self,
        weighted: bool,
        config: LeastSquaresConfig,
        build: impl FnOnce() -> Result<SharedFit>,
    ) -> Result<Arc<SharedFit>> {
        let key = (weighted, config.rank_tolerance.to_bits());
        let slot = {
            let mut fits = lock(&self.fits);
            match fits.iter().find(|(k, _)| *k == key) {
                Some((_, slot)) => Arc::clone(slot),
                None => {
                    let slot = Arc::new(Mutex::new(None));
                    fits.push((key, Arc::clone(&slot)));
                    slot
                }
            }
        };
        let mut fit = lock(&slot);
        if let Some(f) = fit.as_ref() {
            return Ok(Arc::clone(f));
        }
        let built = Arc::new(build()?);
        *fit = Some(Arc::clone(&built));
        Ok(built)
    }
}

enum RawCovariance {
    /// A covariance to be multiplied by the residual variance σ̂² (RLS's P).
    Unscaled(DMatrix<f64>),
    /// A covariance as it is (the EKF's).
    Scaled(DMatrix<f64>),
}

struct Fit {
    beta: DVector<f64>,
    sigma: Option<Vec<f64>>,
    covariance: Option<RawCovariance>,
    settings: serde_json::Value,
    /// See [`IdentifiedModel::converged`].
    converged: bool,
    /// Epochs of the gradient methods.
    epochs: Option<usize>,
}

/// RMS residual of an ordinary least-squares fit over all equations.
fn ls_rms(ls: &crate::DynLeastSquaresReport) -> f64 {
    let rows = (ls.samples * ls.joint_variances.len()) as f64;
    (ls.sigma2 * (rows - ls.lambda.len() as f64).max(0.0) / rows).sqrt()
}

/// Covariance of a (weighted) least-squares β̂ and what it was built from.
struct LsCovariance {
    covariance: Option<DMatrix<f64>>,
    /// Residual variance of each joint's equations (units of τ_j²).
    variances: Vec<f64>,
    /// Correlation time κ_j ≥ 1 of each joint's residuals (samples).
    kappas: Vec<f64>,
}

/// Per-joint Gram matrices W_jᵀ·W_j of the base regressor, and the variance s_j² and
/// correlation time κ_j (samples) of each joint's residuals τ_j − W_j·β.
struct JointMoments {
    grams: Vec<DMatrix<f64>>,
    variances: Vec<f64>,
    kappas: Vec<f64>,
}

fn joint_moments(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    beta: &DVector<f64>,
    stack: &LeastSquares,
) -> Result<JointMoments> {
    let (n, b, m) = (model.dof(), model.count(), samples.len());
    // The residual degrees of freedom shared equally among the joints, as the solver does.
    let dof = (m as f64 - b as f64 / n as f64).max(1.0);
    // From the solver's stacked W when it holds the unscaled one (the normal-equations
    // path): the Gram matrices it already has, the residuals one product.
    if let (Some(grams), Some(r)) = (stack.joint_grams(), stack.residuals_at(beta.as_slice())) {
        let grams = grams
            .iter()
            .map(|g| DMatrix::from_fn(b, b, |i, k| g[(i, k)]))
            .collect();
        let (variances, kappas) = r
            .chunks_exact(m)
            .map(|rj| {
                let var = rj.iter().map(|v| v * v).sum::<f64>() / dof;
                (var, super::ekf_defaults::correlation_time(rj, 1))
            })
            .unzip();
        return Ok(JointMoments {
            grams,
            variances,
            kappas,
        });
    }
    joint_moments_per_sample(model, samples, beta)
}

/// [`joint_moments`] with the regressor of every sample (when the solver went through QR
/// and no longer holds the unscaled W).
fn joint_moments_per_sample(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    beta: &DVector<f64>,
) -> Result<JointMoments> {
    let (n, b, m) = (model.dof(), model.count(), samples.len());
    let dof = (m as f64 - b as f64 / n as f64).max(1.0);
    let mut ws = model.workspace();
    let mut phi = DMatrix::zeros(n, b);
    let mut grams = vec![DMatrix::<f64>::zeros(b, b); n];
    let mut r = vec![0.0; n * m];
    for (k, smp) in samples.iter().enumerate() {
        if k % 1024 == 0 {
            crate::interrupt::check("identify")?;
        }
        model.regressor_into(&mut ws, smp.q, smp.qd, smp.qdd, &mut phi)?;
        for (j, g) in grams.iter_mut().enumerate() {
            let row = phi.row(j);
            g.ger(1.0, &row.transpose(), &row.transpose(), 1.0);
        }
        let res = smp.tau - &phi * beta;
        r[k * n..(k + 1) * n].copy_from_slice(res.as_slice());
    }
    let mut variances = Vec::with_capacity(n);
    let mut kappas = Vec::with_capacity(n);
    for j in 0..n {
        let rj: Vec<f64> = (0..m).map(|k| r[k * n + j]).collect();
        variances.push(rj.iter().map(|v| v * v).sum::<f64>() / dof);
        kappas.push(super::ekf_defaults::correlation_time(&rj, 1));
    }
    Ok(JointMoments {
        grams,
        variances,
        kappas,
    })
}

/// The covariance of β̂ = A⁻¹·Σ_j w_j·W_jᵀ·τ_j (A = Σ_j w_j·W_jᵀ·W_j, joint weights w_j: 1
/// for least squares, 1/σ_j² for weighted) under what the residuals show: each joint's
/// own variance s_j² and correlation time κ_j (samples, see `ekf_defaults`), i.e. the
/// sandwich A⁻¹·(Σ_j w_j²·κ_j·s_j²·W_jᵀ·W_j)·A⁻¹. Why not σ̂²·(WᵀW)⁻¹: the joints of an
/// arm differ in noise by decades (N on a prismatic base, mN·m at a wrist), and one pooled
/// σ̂² made the wrist's σ tens of times larger than its error and the base's smaller;
/// low-pass filtered data have residuals correlated over κ samples, leaving ≈ rows/κ
/// independent equations. With white residuals of equal variance it is σ̂²·(WᵀW)⁻¹.
fn ls_covariance(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    beta: &DVector<f64>,
    weights: &[f64],
    stack: &LeastSquares,
) -> Result<LsCovariance> {
    let (n, b) = (model.dof(), model.count());
    let JointMoments {
        grams,
        variances,
        kappas,
    } = joint_moments(model, samples, beta, stack)?;
    let mut a = DMatrix::zeros(b, b);
    let mut meat = DMatrix::zeros(b, b);
    for j in 0..n {
        a += &grams[j] * weights[j];
        meat += &grams[j] * (weights[j] * weights[j] * kappas[j] * variances[j]);
    }
    let covariance = a
        .cholesky()
        .map(|c| {
            let ai = c.inverse();
            &ai * meat * &ai
        })
        .filter(|c| c.iter().all(|v| v.is_finite()));
    Ok(LsCovariance {
        covariance,
        variances,
        kappas,
    })
}

/// Covariance (Σ_k Y_kᵀ·Σ⁻¹·Y_k)⁻¹ of the joint-variance weighted least-squares β̂ with
/// Σ = diag(`joint_var`) (torque units squared), or `None` when the information matrix is
/// not numerically positive definite or a variance is not positive.
fn weighted_covariance(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    joint_var: &[f64],
    stack: &LeastSquares,
) -> Result<Option<DMatrix<f64>>> {
    let (n, b) = (model.dof(), model.count());
    if joint_var.len() != n || !joint_var.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Ok(None);
    }
    let inv_sd: Vec<f64> = joint_var.iter().map(|v| 1.0 / v.sqrt()).collect();
    if let Some(grams) = stack.joint_grams() {
        // Σ_k Y_kᵀ·Σ⁻¹·Y_k = Σ_j W_jᵀW_j/σ_j².
        let mut info = DMatrix::zeros(b, b);
        for (g, f) in grams.iter().zip(&inv_sd) {
            info += DMatrix::from_fn(b, b, |i, k| g[(i, k)]) * (f * f);
        }
        return Ok(info
            .cholesky()
            .map(|c| c.inverse())
            .filter(|c| c.iter().all(|v| v.is_finite())));
    }
    let mut ws = model.workspace();
    let mut phi = DMatrix::zeros(n, b);
    let mut info = DMatrix::zeros(b, b);
    for (k, s) in samples.iter().enumerate() {
        if k % 1024 == 0 {
            crate::interrupt::check("identify")?;
        }
        model.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)?;
        for (i, f) in inv_sd.iter().enumerate() {
            phi.row_mut(i).scale_mut(*f);
        }
        info.gemm_tr(1.0, &phi, &phi, 1.0);
    }
    Ok(info
        .cholesky()
        .map(|c| c.inverse())
        .filter(|c| c.iter().all(|v| v.is_finite())))
}

/// Sum of squared residuals and the per-joint RMS of joint-major residuals (entry i·m + k
/// is joint i of sample k).
fn joint_residuals(r: &[f64], n: usize) -> (f64, Vec<f64>) {
    let m = r.len() / n.max(1);
    let per: Vec<f64> = r
        .chunks_exact(m.max(1))
        .map(|rj| rj.iter().map(|v| v * v).sum::<f64>())
        .collect();
    let sse = per.iter().sum();
    (
        sse,
        per.iter().map(|s| (s / m.max(1) as f64).sqrt()).collect(),
    )
}

/// Sum of squared residuals and the per-joint RMS.
fn residuals(predicted: &[f64], tau: &[f64], n: usize) -> (f64, Vec<f64>) {
    let samples = (tau.len() / n).max(1) as f64;
    let mut per = vec![0.0; n];
    for (k, (p, t)) in predicted.iter().zip(tau).enumerate() {
        per[k % n] += (p - t) * (p - t);
    }
    let sse = per.iter().sum();
    (sse, per.iter().map(|s| (s / samples).sqrt()).collect())
}

/// The model the online methods run on: whitened, equilibrated or as it is.
fn scaled(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    equilibrate: bool,
    whiten: bool,
) -> Result<DynScaledModel<DynChainBaseModel>> {
    if whiten {
        DynScaledModel::whitened(model.clone(), samples)
    } else if equilibrate {
        DynScaledModel::equilibrated(model.clone(), samples)
    } else {
        DynScaledModel::new(model.clone(), DVector::repeat(model.count(), 1.0))
    }
}

fn rls(model: &DynChainBaseModel, samples: &DynSamples<'_>, s: &RlsSettings) -> Result<Fit> {
    // On unscaled columns δ is in β² units, whose scale is the robot's: not bounded.
    if s.scale_columns {
        crate::bounds::check_initial_covariance(s.initial_covariance)?;
    }
    let sm = scaled(model, samples, s.scale_columns, false)?;
    let cfg = RlsConfig {
        forgetting: s.forgetting,
        initial_covariance: s.initial_covariance,
    };
    let mut est = DynRls::new(sm.clone(), DVector::zeros(model.count()), cfg)?;
    let gamma = est.run(samples)?;
    let d = sm.scale();
    let beta = sm.to_model(&gamma);
    // P in β units: D·P_γ·D.
    let covariance = (s.forgetting == 1.0).then(|| {
        let p = est.covariance();
        RawCovariance::Unscaled(DMatrix::from_fn(d.len(), d.len(), |i, j| {
            p[(i, j)] * d[i] * d[j]
        }))
    });
    Ok(Fit {
        beta,
        sigma: None,
        covariance,
        settings: json!({
            "forgetting": s.forgetting,
            "initial_covariance": s.initial_covariance,
            "scale_columns": s.scale_columns,
            "rank_tolerance": s.rank_tolerance,
        }),
        converged: true,
        epochs: None,
    })
}

/// Largest squared norm of a regressor row and of a whole per-sample regressor of `m`
/// along the data, from the stored regressors when there are.
fn regressor_peaks<M: LinearModel<Dyn, Dyn>>(
    m: &M,
    samples: &DynSamples<'_>,
    stored: Option<&StoredRegressors<Dyn, Dyn>>,
) -> Result<(f64, f64)> {
    let mut peaks = (0.0f64, 0.0f64);
    let mut add = |phi: DMatrixView<'_, f64>| {
        for r in phi.row_iter() {
            peaks.0 = peaks.0.max(r.norm_squared());
        }
        peaks.1 = peaks.1.max(phi.norm_squared());
    };
    if let Some(st) = stored {
        (0..st.len()).for_each(|k| add(st.regressor(k)));
        return Ok(peaks);
    }
    let (n, p) = m.dims();
    let mut ws = m.workspace();
    let mut phi = DMatrix::zeros(n.0, p.0);
    for (k, s) in samples.iter().enumerate() {
        if k % 1024 == 0 {
            crate::interrupt::check("identify")?;
        }
        m.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)?;
        add(phi.as_view());
    }
    Ok(peaks)
}

/// The regressors of the network's model on the data, built once for every epoch, or
/// `None` when they would take more than `max_bytes` ([`MAX_STORED_REGRESSOR_BYTES`] in
/// [`identify`]; each epoch then builds them per sample: the same numbers, slower).
fn store_regressors<M: LinearModel<Dyn, Dyn>>(
    m: &M,
    samples: &DynSamples<'_>,
    max_bytes: usize,
) -> Result<Option<StoredRegressors<Dyn, Dyn>>> {
    let (n, p) = m.dims();
    let fits = StoredRegressors::<Dyn, Dyn>::bytes(n.0, p.0, samples.len())
        .is_some_and(|b| b <= max_bytes);
    if !fits {
        return Ok(None);
    }
    StoredRegressors::new(m, samples, max_bytes).map(Some)
}

/// What the epoch loop did.
struct Training {
    epochs: usize,
    halvings: usize,
    final_step: f64,
    rms: Vec<f64>,
    converged: bool,
    /// The last epoch's relative changes of the estimate and of the equation error.
    parameter_change: f64,
    error_change: f64,
    /// The estimated remaining step-size bias of the last fixed point (relative, as
    /// [`relative_change`]).
    bias: f64,
}

/// Relative change of the estimate from `prev` to `g`: max_j |g_j − prev_j| / s_j with
/// s_j = max(|g_j|, 1e-3·max_i|g_i|, 0.01·σ_j/tol): a parameter near zero is measured
/// against the scale of the others rather than against itself, and a change below 1 % of
/// least squares' standard deviation σ_j of that parameter (what the data can resolve)
/// counts as none.
fn relative_change(g: &DVector<f64>, prev: &DVector<f64>, sigma: &[f64], tol: f64) -> f64 {
    let floor = 1e-3 * g.amax();
    g.iter()
        .zip(prev.iter())
        .zip(sigma)
        .map(|((a, b), s)| {
            let scale = a.abs().max(floor).max(0.01 * s / tol);
            (a - b).abs() / scale.max(f64::MIN_POSITIVE)
        })
        .fold(0.0, f64::max)
}

/// Trains over epochs with step μ (dimensionless) until the stopping rule holds.
///
/// Each epoch starts from the Anderson mixing of the previous epochs at the same step
/// (see [`identify`]); the change δ_k between the iterates an epoch starts from
/// ([`relative_change`]) shrinks geometrically (superlinearly once the history spans the
/// parameters) with a ratio r = δ_k/δ_k−1, and δ_k·r/(1 − r) bounds what is left to move
/// (a small δ_k alone is not enough: a small step moves little per epoch however far
/// the fixed point is). The fixed point of a step is reached when that remaining change
/// is below `parameter_tolerance` and the relative change of e below `error_tolerance`.
/// Its bias is ∝ μ, so the move from the previous step's fixed point estimates it: below
/// `parameter_tolerance` the run has converged, otherwise μ is cut by the power of 2
/// that the linear bias predicts to suffice (at least one halving, at most `halvings` in
/// all; then `converged = false`); only the move over a single halving confirms. Exact data: converged once floor and e are both
/// below 1e-9 of the RMS torque. `max_epochs` caps the run (`converged = false`).
/// `make(μ, γ₀)` builds an estimator, `epoch` trains it once over the data.
#[allow(clippy::too_many_arguments)]
fn anneal<E: Estimator<Dyn, Dyn>>(
    s: &GradientSettings,
    p: usize,
    floor: f64,
    sigma: &[f64],
    tau_rms: f64,
    make: impl Fn(f64, DVector<f64>) -> Result<E>,
    epoch: impl Fn(&mut E) -> Result<f64>,
) -> Result<(DVector<f64>, Training)> {
    if s.max_epochs == 0 {
        return Err(invalid("max_epochs", 0.0, "must be at least 1"));
    }
    for (name, v) in [
        ("parameter_tolerance", s.parameter_tolerance),
        ("error_tolerance", s.error_tolerance),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(name, v, "must be finite and > 0"));
        }
    }
    let mut mu = s.step_size;
    let mut est = make(mu, DVector::zeros(p))?;
    let mut rms = Vec::with_capacity(s.max_epochs.min(4096));
    let mut halvings = 0;
    // The iterate x each epoch starts from, and the history of the Anderson mixing:
    // differences of the epochs' outputs E(x) and of their residuals f = E(x) − x.
    let mut x = est.estimate().clone();
    let mut last: Option<(DVector<f64>, DVector<f64>)> = None;
    let (mut dgs, mut dfs): (Vec<DVector<f64>>, Vec<DVector<f64>>) = (Vec::new(), Vec::new());
    let mut prev_e = f64::NAN;
    let mut prev_step = f64::INFINITY;
    // The fixed point of the previous step size and that step, once reached.
    let mut level: Option<(DVector<f64>, f64)> = None;
    let mut last_cut = 0;
    let (mut converged, mut dg, mut de) = (false, f64::INFINITY, f64::INFINITY);
    let mut bias = f64::INFINITY;
    while rms.len() < s.max_epochs {
        let e = epoch(&mut est)?;
        rms.push(e);
        let gx = est.estimate().clone();
        let f = &gx - &x;
        if let Some((g0, f0)) = &last {
            dgs.push(&gx - g0);
            dfs.push(&f - f0);
            if dfs.len() > p {
                dgs.remove(0);
                dfs.remove(0);
            }
        }
        // Anderson mixing: the combination of the recent epochs whose residual is least
        // (for an affine epoch map with a full history, its fixed point).
        let mut next = gx.clone();
        if !dfs.is_empty() {
            let df = DMatrix::from_columns(&dfs);
            let tol = 1e-12 * f.amax().max(1e-300);
            if let Some(c) = crate::linalg::svd(df).and_then(|s| s.solve(&f, tol).ok()) {
                next -= DMatrix::from_columns(&dgs) * c;
            }
        }
        last = Some((gx.clone(), f));
        let step = relative_change(&next, &x, sigma, s.parameter_tolerance);
        // Geometric extrapolation: with a contraction ratio r = δ_k/δ_k−1 < 1 the estimate
        // still has Σ_{i≥1} δ_k·rⁱ = δ_k·r/(1 − r) to move; r ≥ 1 is no convergence yet.
        let ratio = step / prev_step;
        dg = if prev_step.is_finite() && ratio < 1.0 {
            step * ratio / (1.0 - ratio)
        } else {
            f64::INFINITY
        };
        prev_step = step;
        de = (e - prev_e).abs() / e.max(f64::MIN_POSITIVE);
        prev_e = e;
        // Exact data (a zero floor): nothing is left to learn once e is at round-off.
        // With noise, the a-priori error of a moving estimate can dip below the floor
        // of a fixed one, so e ≤ floor is no convergence test there.
        if floor <= 1e-9 * tau_rms && e <= 1e-9 * tau_rms {
            converged = true;
            bias = 0.0;
            break;
        }
        let at_fixed_point = dg < s.parameter_tolerance && de < s.error_tolerance;
        if at_fixed_point {
            // Its bias is B·μ to first order (measured on the paper's arm: it halves with
            // each halving), so the move from the previous step μ₀'s fixed point,
            // B·(μ₀ − μ), times μ/(μ₀ − μ) is what this fixed point is still off.
            let mut cut = 1;
            if let Some((l, mu_prev)) = &level {
                bias = relative_change(&gx, l, sigma, s.parameter_tolerance) * mu / (mu_prev - mu);
                // The halvings that bring B·μ below the tolerance, at once (the next
                // fixed point checks the prediction).
                cut = (bias / s.parameter_tolerance).log2().ceil().max(1.0) as usize;
            }
            // Only a single halving confirms: over a longer cut the bias need not be
            // linear yet (at 1000 Hz it first falls more slowly), and a small move there
            // was seen to hide 0.3 σ of bias.
            if bias < s.parameter_tolerance && last_cut == 1 {
                converged = true;
                break;
            }
            if halvings == s.halvings {
                break;
            }
            let cut = cut.min(s.halvings - halvings);
            last_cut = cut;
            level = Some((gx.clone(), mu));
            halvings += cut;
            mu *= 0.5f64.powi(cut as i32);
            next = gx;
            last = None;
            dgs.clear();
            dfs.clear();
            // The next epoch's change is that of a new step: not a convergence test.
            prev_e = f64::NAN;
            prev_step = f64::INFINITY;
        }
        // A mixed iterate the network cannot start from (outside the Hopfield box) is
        // replaced by the epoch's own output.
        est = match make(mu, next.clone()) {
            Ok(est) => {
                x = next;
                est
            }
            Err(_) => {
                x = last.as_ref().map_or(next, |(g, _)| g.clone());
                dgs.clear();
                dfs.clear();
                make(mu, x.clone())?
            }
        };
    }
    Ok((
        est.estimate().clone(),
        Training {
            epochs: rms.len(),
            bias,
            halvings,
            final_step: mu,
            rms,
            converged,
            parameter_change: dg,
            error_change: de,
        },
    ))
}

/// Adaline (`hopfield` false) or the Hopfield network trained by [`anneal`], on
/// regressors stored once when they take at most `max_stored_bytes`.
#[allow(clippy::too_many_arguments)]
fn gradient(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    s: &GradientSettings,
    hopfield: bool,
    beta_ls: &DVector<f64>,
    sigma_ls: &[f64],
    floor: f64,
    max_stored_bytes: usize,
) -> Result<Fit> {
    let sm = scaled(model, samples, s.scale_columns, s.whiten)?;
    // Least squares' σ in the network's parameters γ (for the stopping rule): D⁻¹·σ_β
    // for γ = D⁻¹·β; for whitened γ, whose regressor Γ has ΓᵀΓ = rows·1, Cov(γ̂) =
    // σ²·(ΓᵀΓ)⁻¹ = σ²/rows·1 with σ the residual RMS `floor`.
    let rows = (samples.len() * model.dof()) as f64;
    let sigma: Vec<f64> = if sm.is_whitened() {
        vec![floor / rows.sqrt(); model.count()]
    } else {
        sigma_ls
            .iter()
            .zip(sm.scale().iter())
            .map(|(s, d)| s / d)
            .collect()
    };
    let tau_rms = (samples.tau().iter().map(|t| t.norm_squared()).sum::<f64>()
        / (samples.len() * samples.tau()[0].len()) as f64)
        .sqrt();
    let p = model.count();
    let stored = store_regressors(&sm, samples, max_stored_bytes)?;
    let (row_peak, frob_peak) = regressor_peaks(&sm, samples, stored.as_ref())?;
    let mut settings = json!({
        "stored_regressors": stored.is_some(),
        "scale_columns": s.scale_columns || sm.is_whitened(),
        "whiten": sm.is_whitened(),
        "max_epochs": s.max_epochs,
        "halvings": s.halvings,
        "rank_tolerance": s.rank_tolerance,
    });
    let mu0 = match (hopfield, s.rule, s.learning_rate) {
        (false, AdalineRule::Delta, Some(lr)) => {
            if !(lr.is_finite() && lr > 0.0) {
                return Err(invalid("learning_rate", lr, "must be finite and > 0"));
            }
            if lr * row_peak >= 2.0 {
                return Err(invalid(
                    "learning_rate",
                    lr,
                    "is unstable on these data: learning_rate·max‖x_i‖² ≥ 2 over the \
                     (scaled) regressor rows; lower it or give step_size in (0, 2) instead",
                ));
            }
            lr * row_peak
        }
        _ => s.step_size,
    };
    if !(mu0 > 0.0 && mu0 < 2.0) {
        return Err(invalid(
            "step_size",
            mu0,
            "must be in (0, 2): larger steps make the gradient update unstable",
        ));
    }
    // A step of 1e-300 moved nothing, and the unchanged weights met the stopping rule
    // ("converged").
    if mu0 < crate::bounds::MIN_FACTOR {
        return Err(invalid(
            "step_size",
            mu0,
            "is below MIN_FACTOR (1e-6) (learning_rate·max‖x_i‖² over the scaled regressor \
             rows, or step_size): the weights would not move; raise it",
        ));
    }
    let s = GradientSettings {
        step_size: mu0,
        ..*s
    };
    let (gamma, training) = if hopfield {
        let c = match s.bound {
            Some(c) => c,
            None => {
                let g = sm.from_model(beta_ls);
                (4.0 * g.amax()).max(tau_rms).max(f64::MIN_POSITIVE)
            }
        };
        settings["bound"] = json!(c);
        if frob_peak.is_nan() || frob_peak <= 0.0 {
            return Err(invalid(
                "regressor",
                frob_peak,
                "is zero along the whole of the data",
            ));
        }
        // A fictitious unit time per sample; the slope β sets the gain so that one Euler
        // step per sample has h·(c/β)·max‖Φ‖_F² = μ ≤ 1 (the estimator sub-steps above).
        let make = |mu: f64, g0: DVector<f64>| {
            let cfg = HopfieldConfig {
                bound: c,
                beta: c * frob_peak / mu,
                dt: 1.0,
                stability_limit: 1.0,
                max_substeps: 64,
            };
            DynHopfield::new(sm.clone(), g0, cfg)
        };
        anneal(&s, p, floor, &sigma, tau_rms, make, |e| {
            // `train_stored` computes what `train` does, to the bit.
            let report = match &stored {
                Some(st) => e.train_stored(st, 1)?,
                None => e.train(samples, 1)?,
            };
            Ok(report.rms_error[0])
        })?
    } else {
        let rule = s.rule;
        settings["rule"] = json!(match rule {
            AdalineRule::Normalised => "normalised",
            AdalineRule::Delta => "delta",
        });
        let make = |mu: f64, g0: DVector<f64>| {
            let cfg = AdalineConfig {
                rule,
                learning_rate: mu / row_peak.max(f64::MIN_POSITIVE),
                step_size: mu,
                ..AdalineConfig::default()
            };
            DynAdaline::new(sm.clone(), g0, cfg)
        };
        if rule == AdalineRule::Delta {
            settings["learning_rate"] = json!(mu0 / row_peak);
        }
        anneal(&s, p, floor, &sigma, tau_rms, make, |e| {
            // `train_stored` computes what `train` does, to the bit.
            let report = match &stored {
                Some(st) => e.train_stored(st, 1)?,
                None => e.train(samples, 1)?,
            };
            Ok(report.rms_error[0])
        })?
    };
    settings["step_size"] = json!(mu0);
    settings["epochs"] = json!(training.epochs);
    settings["step_halvings"] = json!(training.halvings);
    settings["final_step_size"] = json!(training.final_step);
    settings["final_rms_error"] = json!(training.rms.last().copied().unwrap_or(0.0));
    settings["parameter_tolerance"] = json!(s.parameter_tolerance);
    // The scale of "no change" (the solver's pooled least-squares σ, see the module docs).
    settings["stopping_scale"] = json!(sigma_ls);
    settings["error_tolerance"] = json!(s.error_tolerance);
    settings["final_parameter_change"] = json!(finite_or_null(training.parameter_change));
    settings["final_error_change"] = json!(finite_or_null(training.error_change));
    settings["step_bias"] = json!(finite_or_null(training.bias));
    Ok(Fit {
        beta: sm.to_model(&gamma),
        sigma: None,
        covariance: None,
        settings,
        converged: training.converged,
        epochs: Some(training.epochs),
    })
}

/// A JSON number, or null for NaN/∞ (JSON has neither).
fn finite_or_null(v: f64) -> serde_json::Value {
    if v.is_finite() {
        json!(v)
    } else {
        serde_json::Value::Null
    }
}

fn c_pos2(c: &EkfConfig) -> f64 {
    c.process_position_noise.powi(2)
}

/// The first sample at which M(q, β) is not positive definite, if any (the forward
/// dynamics, which the EKF propagates with, do not exist there).
fn first_indefinite(
    model: &DynChainBaseModel,
    samples: &DynSamples<'_>,
    beta: &DVector<f64>,
) -> Result<Option<usize>> {
    let mut ws = model.workspace();
    let mut qdd = DVector::zeros(model.dof());
    for (k, smp) in samples.iter().enumerate() {
        if k % 1024 == 0 {
            crate::interrupt::check("identify")?;
        }
        match model.forward_dynamics_into(&mut ws, smp.q, smp.qd, smp.tau, beta, &mut qdd) {
            Ok(()) => {}
            Err(PrrrpError::NotPositiveDefinite { .. }) => return Ok(Some(k)),
            Err(e) => return Err(e),
        }
    }
    Ok(None)
}

/// The base values of the physically consistent estimate on `data` (every link a rigid
/// body): where the EKF starts when least squares is not physical.
fn physical_start(
    model: &DynChainBaseModel,
    base: &BaseParameters,
    data: &DynDataset,
) -> Result<DVector<f64>> {
    let est = crate::identify_physical(
        model.chain(),
        data.q(),
        data.qd(),
        data.qdd(),
        data.tau(),
        &crate::PhysicalConfig::default(),
    )?;
    Ok(DVector::from_vec(base.base_values(&est.parameters)?))
}

/// Refuses a given EKF start β₀ ([`EkfStart::Given`]) without one entry per base
/// parameter, or with an entry that is NaN, infinite or at or above
/// [`crate::MAX_MAGNITUDE`]; other starts pass. Checked before any fit: such a β₀ was
/// reported as a bad `initial_parameter_min_std` (derived from it), which it never named.
fn check_given_start(start: &EkfStart, b: usize) -> Result<()> {
    let EkfStart::Given(v) = start else {
        return Ok(());
    };
    if v.len() != b {
        return Err(PrrrpError::ShapeMismatch {
            what: "EkfStart::Given (the EKF's initial β0)".into(),
            expected: format!("{b} entries (one per base parameter)"),
            got: format!("{} entries", v.len()),
        });
    }
    if let Some((k, &x)) = v
        .iter()
        .enumerate()
        .find(|(_, x)| x.abs() >= crate::MAX_MAGNITUDE || x.is_nan())
    {
        return Err(PrrrpError::InvalidParameter {
            field: format!("EkfStart::Given[{k}]"),
            value: x,
            reason: "the EKF's initial β0 must be finite and below MAX_MAGNITUDE (1e100) in \
                     magnitude (units of each base parameter's combination)",
        });
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn ekf(
    model: &DynChainBaseModel,
    base: &BaseParameters,
    data: &DynDataset,
    samples: &DynSamples<'_>,
    s: &EkfSettings,
    beta_ls: &DVector<f64>,
    joint_var: &[f64],
    stack: &LeastSquares,
) -> Result<Fit> {
    let b = model.count();
    let mut indefinite_at = None;
    let (beta0, start) = match &s.initial {
        EkfStart::LeastSquares => {
            indefinite_at = first_indefinite(model, samples, beta_ls)?;
            match indefinite_at {
                None => (beta_ls.clone(), "ls"),
                Some(_) => (physical_start(model, base, data)?, "physical"),
            }
        }
        EkfStart::Physical => (physical_start(model, base, data)?, "physical"),
        EkfStart::Prior => (model.chain_base_values().clone(), "prior"),
        EkfStart::Given(v) => {
            check_given_start(&s.initial, b)?;
            (DVector::from_column_slice(v), "given")
        }
    };
    let dt = match s.dt {
        Some(dt) => dt,
        None => {
            let mut steps: Vec<f64> = data.t().windows(2).map(|w| w[1] - w[0]).collect();
            steps.sort_by(f64::total_cmp);
            steps[steps.len() / 2]
        }
    };
    let mut cfg = EkfConfig { dt, ..s.config };
    if cfg.initial_parameter_min_std == 0.0 {
        cfg.initial_parameter_min_std = (1e-3 * beta0.amax()).max(f64::MIN_POSITIVE);
    }
    let n = model.dof();
    // R per joint from the data's own high-frequency content (module `ekf_defaults`),
    // floored at 1e-12 of each signal's range so that exact data stay well posed.
    let range = |x: &[f64]| {
        let m = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        (1e-12 * m).max(f64::MIN_POSITIVE.sqrt())
    };
    let (r_pos, r_vel) = if s.noise_from_data {
        (
            super::ekf_defaults::third_difference_noise(data.q(), n, range(data.q())),
            super::ekf_defaults::third_difference_noise(data.qd(), n, range(data.qd())),
        )
    } else {
        (vec![cfg.position_noise; n], vec![cfg.velocity_noise; n])
    };
    let mut est = DynEkf::new(model.clone(), beta0.clone(), cfg)?;
    // The start is inside the region where M(q, β) ≻ 0 along the data (checked above, or
    // a set of rigid bodies): an estimate that drifts out at a new configuration is
    // pulled back towards it instead of stopping the filter.
    est.set_parameter_anchor(&beta0)?;
    est.set_stiff_handling(s.stiff_handling);
    let w = s.least_squares_prior_width;
    // Squared into P₀: a width of 1e300 made it infinite, and the filter started from the
    // diagonal prior without a word.
    // 0 asks for the diagonal prior.
    if w != 0.0 {
        crate::bounds::check_factor("least_squares_prior_width", w)?;
    }
    let mut prior = "diagonal";
    if w > 0.0 && matches!(s.initial, EkfStart::LeastSquares | EkfStart::Physical) {
        if let Some(cov) = weighted_covariance(model, samples, joint_var, stack)? {
            let mut p0 = est.covariance().clone();
            p0.view_mut((2 * n, 2 * n), (b, b))
                .copy_from(&(cov * (w * w)));
            // Exactly symmetric, as `set_initial_covariance` requires.
            let p0 = (&p0 + p0.transpose()) * 0.5;
            if est.set_initial_covariance(&p0).is_ok() {
                prior = "least_squares";
            }
        }
    }
    if s.noise_from_data {
        est.set_measurement_noise(
            &DVector::from_iterator(n, r_pos.iter().map(|v| v * v)),
            &DVector::from_iterator(n, r_vel.iter().map(|v| v * v)),
        )?;
    }
    // The filter holds τ_k over [t_k, t_k+1] (zero-order hold); a recording samples a
    // torque that varies within the interval, whose mean (τ_k + τ_k+1)/2 is what moves
    // the state to k+1 to second order.
    let tau = samples.tau();
    let held: Vec<DVector<f64>> = (0..tau.len())
        .map(|k| match tau.get(k + 1) {
            Some(next) => (&tau[k] + next) * 0.5,
            None => tau[k].clone(),
        })
        .collect();
    // τ is the filter's input, so torque noise δτ moves q̇ by h·M⁻¹·δτ and q by
    // h²/2·M⁻¹·δτ per step: Q_q̇,j = h²·Σ_k (M⁻¹)_jk²·σ_k² (and (h²/2)² of it on q), with
    // σ_k² the least-squares residual variance of joint k. With `noise_from_data`, M is
    // taken at each sample and the current λ̂: a Q fixed at β₀ weighs the innovations
    // h·M⁻¹(λ)·δτ by a λ-independent weight, and the filter then prefers the λ with the
    // smallest M⁻¹ (torque noise biased the inertias up by up to 37 % on gentle data);
    // scaled with M⁻¹(λ̂), the weighted innovation is the torque error δτ itself, as in
    // (weighted) least squares.
    let base_q = c_pos2(&cfg);
    let base_v = cfg.process_velocity_noise.powi(2);
    let mut qn = DVector::zeros(2 * n + b);
    for i in 0..b {
        qn[2 * n + i] = (cfg.process_parameter_noise * beta0[i].abs()).powi(2);
    }
    let mut mws = model.workspace();
    let (mut q0, mut q1, mut tau_j) = (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
    let mut minv = DMatrix::zeros(n, n);
    let mut lam = beta0.clone();
    // M⁻¹ column by column, exactly (q̈ is affine in τ): M⁻¹e_j = q̈(τ + e_j) − q̈(τ).
    let mut update_q = |q: &DVector<f64>,
                        qd: &DVector<f64>,
                        tau: &DVector<f64>,
                        lam: &DVector<f64>,
                        qn: &mut DVector<f64>|
     -> Result<()> {
        model.forward_dynamics_into(&mut mws, q, qd, tau, lam, &mut q0)?;
        for j in 0..n {
            tau_j.copy_from(tau);
            tau_j[j] += 1.0;
            model.forward_dynamics_into(&mut mws, q, qd, &tau_j, lam, &mut q1)?;
            for i in 0..n {
                minv[(i, j)] = q1[i] - q0[i];
            }
        }
        for j in 0..n {
            let torque: f64 = (0..n).map(|k| minv[(j, k)].powi(2) * joint_var[k]).sum();
            qn[j] = base_q + (0.5 * dt * dt).powi(2) * torque;
            qn[n + j] = base_v + dt * dt * torque;
        }
        Ok(())
    };
    // A β₀ whose M is not positive definite starts with the configured Q only; the
    // filter then reports the start as diverged.
    let first = (&samples.q()[0], &samples.qd()[0], &samples.tau()[0]);
    if update_q(first.0, first.1, first.2, &beta0, &mut qn).is_err() {
        for j in 0..n {
            qn[j] = base_q;
            qn[n + j] = base_v;
        }
    }
    est.set_process_noise(&qn)?;
    let held = DynSamples::new(samples.q(), samples.qd(), samples.qdd(), &held)?;
    for (k, smp) in held.iter().enumerate() {
        if k % 1024 == 0 {
            crate::interrupt::check("identify")?;
        }
        if s.process_noise_at_estimate && k > 0 {
            lam.copy_from(&est.state().rows(2 * n, b));
            // A λ̂ whose M is not positive definite keeps the last Q; the step reports it.
            if update_q(smp.q, smp.qd, smp.tau, &lam, &mut qn).is_ok() {
                est.set_process_noise(&qn)?;
            }
        }
        est.step(smp).map_err(|e| match e {
            PrrrpError::NonFinite { what, row: None } => {
                PrrrpError::NonFinite { what, row: Some(k) }
            }
            other => other,
        })?;
    }
    let beta = est.estimate().clone();
    if !beta.iter().all(|v| v.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "EKF estimate".into(),
            row: None,
        });
    }
    // The filter's P_λ is the inverse of the information it assumed: white torque noise
    // of the variances σ_j² of Q. The residuals of its estimate show each joint's actual
    // variance s_j² and correlation time κ_j, so the reported covariance is the sandwich
    // P_λ·(Σ_j κ_j·s_j²/σ_j⁴·W_jᵀW_j)·P_λ (for white residuals of the assumed variances
    // ≈ P_λ, as the filter's information is ≈ Σ_j W_jᵀW_j/σ_j²).
    let p_lambda = est.covariance().view((2 * n, 2 * n), (b, b)).clone_owned();
    let (cov, kappas) = if s.correlation_correction {
        let mom = joint_moments(model, samples, &est.estimate().clone(), stack)?;
        let mut meat = DMatrix::zeros(b, b);
        for (j, &var) in joint_var.iter().enumerate().take(n) {
            // A joint without residual (exact data) adds no noise.
            if !(var > 0.0 && mom.variances[j].is_finite()) {
                continue;
            }
            let w = 1.0 / var;
            meat += &mom.grams[j] * (w * w * mom.kappas[j] * mom.variances[j]);
        }
        let c = &p_lambda * meat * &p_lambda;
        ((&c + c.transpose()) * 0.5, mom.kappas)
    } else {
        (p_lambda, vec![1.0; n])
    };
    // The least-squares prior took its information, 1/w² of theirs, from the same data:
    // remove that double count from the reported covariance.
    let cov = if prior == "least_squares" {
        cov * (1.0 + 1.0 / (w * w))
    } else {
        cov
    };
    let c = &cfg;
    Ok(Fit {
        beta,
        sigma: None,
        covariance: Some(RawCovariance::Scaled(cov)),
        settings: json!({
            "initial": start,
            "least_squares_indefinite_at": indefinite_at,
            "dt": c.dt,
            "measurement": match c.measurement {
                EkfMeasurement::Positions => "positions",
                EkfMeasurement::PositionsVelocities => "positions_velocities",
            },
            "discretisation": match c.discretisation {
                Discretisation::Euler => "euler",
                Discretisation::SecondOrder => "second_order",
                Discretisation::Midpoint => "midpoint",
            },
            "position_noise": r_pos,
            "velocity_noise": r_vel,
            "parameter_jacobian": match c.parameter_jacobian {
                ParameterJacobian::Predicted => "predicted",
                ParameterJacobian::DataAcceleration => "data_acceleration",
            },
            "noise_from_data": s.noise_from_data,
            "process_noise_at_estimate": s.process_noise_at_estimate,
            "correlation_correction": s.correlation_correction,
            "stiff_handling": s.stiff_handling,
            "least_squares_prior_width": w,
            "prior": prior,
            "correlation_time_samples": kappas,
            "process_position_noise": c.process_position_noise,
            "process_velocity_noise": c.process_velocity_noise,
            "process_parameter_noise": c.process_parameter_noise,
            "initial_position_std": c.initial_position_std,
            "initial_velocity_std": c.initial_velocity_std,
            "initial_parameter_rel_std": c.initial_parameter_rel_std,
            "initial_parameter_min_std": c.initial_parameter_min_std,
            "init_from_first_measurement": c.init_from_first_measurement,
            "skipped_updates": est.skipped_updates(),
            "damped_updates": est.damped_updates(),
            "stiff_steps": est.stiff_steps(),
            "anchored_updates": est.anchored_updates(),
            "rank_tolerance": s.rank_tolerance,
        }),
        converged: true,
        epochs: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn puma(coupled: bool) -> DynChain {
        crate::test_support::puma(coupled)
    }

    /// Random states and torques: nothing a fit would favour.
    fn random_data(samples: usize, seed: u64) -> DynDataset {
        crate::test_support::random_data(samples, seed, |_| 2.0)
    }

    fn close(a: &DMatrix<f64>, b: &DMatrix<f64>, rel: f64) -> bool {
        (a - b).amax() <= rel * b.amax()
    }

    /// Adaline and the Hopfield network through the whole stopping rule (every epoch,
    /// halving and Anderson mixing) on stored regressors give the model that building
    /// each sample's regressor in every epoch (the fallback above the memory bound) gives,
    /// to the bit.
    #[test]
    fn gradient_methods_on_stored_regressors_equal_the_per_sample_form() {
        let chain = puma(true);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let data = random_data(400, 8);
        let rows = Rows::new(&data);
        let samples = rows.samples().unwrap();
        let ls = crate::least_squares(&model, &samples, &LeastSquaresConfig::default()).unwrap();
        for hopfield in [false, true] {
            let s = GradientSettings {
                max_epochs: 40,
                ..GradientSettings::adaline()
            };
            let fit = |cap| {
                gradient(
                    &model,
                    &samples,
                    &s,
                    hopfield,
                    &ls.lambda,
                    ls.std_dev.as_slice(),
                    ls_rms(&ls),
                    cap,
                )
                .unwrap()
            };
            let (stored, per_sample) = (fit(usize::MAX), fit(0));
            assert_eq!(stored.settings["stored_regressors"], json!(true));
            assert_eq!(per_sample.settings["stored_regressors"], json!(false));
            assert_eq!(stored.epochs, per_sample.epochs);
            assert!(stored.epochs.unwrap() > 3);
            let bits = |f: &Fit| f.beta.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&stored), bits(&per_sample), "hopfield: {hopfield}");
            for key in ["final_rms_error", "final_step_size", "step_halvings"] {
                assert_eq!(stored.settings[key], per_sample.settings[key], "{key}");
            }
        }
    }

    /// The solver itself honours a stop (the stacking of W: Ctrl-C took up to 9 s to stop
    /// wls on a 200k-row log, where only the methods' own loops polled), plainly and
    /// weighted, whoever calls it.
    #[test]
    fn the_least_squares_solver_stops_on_request() {
        let chain = puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let data = random_data(300, 3);
        let rows = Rows::new(&data);
        let samples = rows.samples().unwrap();
        let flag = crate::StopFlag::new();
        let solver = || LeastSquares::new(LeastSquaresConfig::default()).unwrap();
        assert!(flag.run(|| solver().solve(&model, &samples)).is_ok());
        flag.raise();
        let plain = flag.run(|| solver().solve(&model, &samples));
        assert!(
            matches!(plain, Err(PrrrpError::Interrupted { .. })),
            "{plain:?}"
        );
        let weighted =
            flag.run(|| solver().solve_weighted(&model, &samples, DynJointNoise::Estimated));
        assert!(
            matches!(weighted, Err(PrrrpError::Interrupted { .. })),
            "{weighted:?}"
        );
    }

    /// The Gram matrices, residual variances, correlation times and the weighted
    /// information from the solver's stacked W equal the regressor-per-sample formulas,
    /// at the fit's β and at another β (as the EKF's).
    #[test]
    fn moments_from_the_stacked_regressor_equal_the_per_sample_ones() {
        for coupled in [false, true] {
            let chain = puma(coupled);
            let base = chain.base_parameters(&BaseOptions::default()).unwrap();
            let model = chain.base_model(&base).unwrap();
            let data = random_data(800, 3);
            let rows = Rows::new(&data);
            let samples = rows.samples().unwrap();
            let mut stack = LeastSquares::new(LeastSquaresConfig::default()).unwrap();
            let ls = stack
                .solve_weighted(&model, &samples, DynJointNoise::Estimated)
                .unwrap();
            assert!(stack.used_normal_equations() && stack.joint_grams().is_some());
            let other = ls.lambda.map(|v| 1.1 * v + 0.01);
            for beta in [&ls.lambda, &other] {
                let fast = joint_moments(&model, &samples, beta, &stack).unwrap();
                let slow = joint_moments_per_sample(&model, &samples, beta).unwrap();
                for j in 0..6 {
                    assert!(close(&fast.grams[j], &slow.grams[j], 1e-12), "gram {j}");
                    let (a, b) = (fast.variances[j], slow.variances[j]);
                    assert!((a - b).abs() <= 1e-10 * b, "variance {j}: {a} vs {b}");
                    let (a, b) = (fast.kappas[j], slow.kappas[j]);
                    assert!((a - b).abs() <= 1e-8 * b, "κ {j}: {a} vs {b}");
                }
            }
            let var = ls.joint_variances.as_slice();
            let fresh = LeastSquares::new(LeastSquaresConfig::default()).unwrap();
            let fast = weighted_covariance(&model, &samples, var, &stack)
                .unwrap()
                .unwrap();
            let slow = weighted_covariance(&model, &samples, var, &fresh)
                .unwrap()
                .unwrap();
            assert!(close(&fast, &slow, 1e-9));
        }
    }

    /// A bad given EKF start is named as such, before any fit: NaN was reported as an
    /// `initial_parameter_min_std` of 2.2e-308 and 1e200 as one of 1e197.
    #[test]
    fn a_bad_given_ekf_start_is_named() {
        let chain = puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let b = base.count();
        let data = random_data(60, 4);
        for bad in [f64::NAN, 1e200, f64::NEG_INFINITY] {
            let mut start = vec![1.0; b];
            start[b - 1] = bad;
            let method = Method::Ekf(EkfSettings {
                initial: EkfStart::Given(start),
                ..EkfSettings::default()
            });
            let err = identify(&chain, &base, &data, &method, json!(null)).unwrap_err();
            let want = format!("EkfStart::Given[{}]", b - 1);
            assert!(
                matches!(&err, PrrrpError::InvalidParameter { field, .. } if *field == want),
                "{bad}: {err}"
            );
        }
        let short = Method::Ekf(EkfSettings {
            initial: EkfStart::Given(vec![1.0; b - 1]),
            ..EkfSettings::default()
        });
        let err = identify(&chain, &base, &data, &short, json!(null)).unwrap_err();
        let named = matches!(&err, PrrrpError::ShapeMismatch { what, .. }
            if what.starts_with("EkfStart::Given"));
        assert!(named, "{err}");
    }
}
