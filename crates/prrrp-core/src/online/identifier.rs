//! [`OnlineIdentifier`]: identification while the arm runs, one raw sample at a time.

use nalgebra::{DMatrix, DVector};
use serde_json::json;

use super::coulomb_search::{CoulombSearch, Scores, ONLINE_COULOMB_SCALES};
use super::cutoff::CutoffChoice;
use super::detector::{ChangeDetection, ChangeDetector, ErrorCorrelation};
use super::guard::{ChangeGuard, Verdict};
use super::kinematics::{CausalKinematics, CausalLowPass};
use super::payload::{project, summary_json, PAYLOAD_PARAMS};
use super::payload_ekf::PayloadEkf;
use super::tip::{Look, TipOpening};
use super::tracked::{TrackedModel, TrackedWorkspace};
use crate::bounds::{check_factor, check_initial_covariance, MAX_MAGNITUDE};
use crate::error::{invalid, PrrrpError, Result};
use crate::estimators::{
    base_feasibility, AdalineConfig, AdalineRule, Discretisation, DynAdaline, DynEkf, DynHopfield,
    DynRls, DynSamples, EkfConfig, EkfMeasurement, Estimator, Forgetting, HopfieldConfig,
    ParameterJacobian, PhysicalConfig, RlsConfig, SampleOf,
};
use crate::identification::IdentifiedModel;
use crate::models::chain::{BaseParameters, DynChain, FrictionModel};
use crate::models::scaled::DynScaledModel;
use crate::models::LinearModel;

/// The online methods of [`OnlineIdentifier`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnlineMethod {
    /// Recursive least squares, joint-weighted, with optional (directional) forgetting.
    #[default]
    Rls,
    /// The extended Kalman filter on [q, q̇, θ] (the paper's), started inside the
    /// physical region; in payload mode a Kalman filter on the payload's parameters alone,
    /// measuring the joint forces the prior arm does not explain.
    Ekf,
    /// Adaline networks (normalised delta rule, one step per sample).
    Adaline,
    /// The Hopfield network (one Euler step per sample).
    Hopfield,
}

/// The names [`OnlineMethod::parse`] accepts.
pub const ONLINE_METHOD_NAMES: [&str; 4] = ["rls", "ekf", "adaline", "hopfield"];

impl OnlineMethod {
    /// The method by name (one of [`ONLINE_METHOD_NAMES`]).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for an unknown name.
    pub fn parse(name: &str) -> Result<Self> {
        Ok(match name {
            "rls" => Self::Rls,
            "ekf" => Self::Ekf,
            "adaline" => Self::Adaline,
            "hopfield" => Self::Hopfield,
            _ => {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("online method {name:?}"),
                    value: f64::NAN,
                    reason: "unknown: use \"rls\", \"ekf\", \"adaline\" or \"hopfield\"",
                })
            }
        })
    }

    /// The method's name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Rls => "rls",
            Self::Ekf => "ekf",
            Self::Adaline => "adaline",
            Self::Hopfield => "hopfield",
        }
    }
}

/// Settings of [`OnlineIdentifier`] (SI units). Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineConfig {
    /// The method (default [`OnlineMethod::Rls`]).
    pub method: OnlineMethod,
    /// Track only the 10 inertial parameters of a payload at the tip link, on the arm of
    /// the prior model (default `false`; needs [`OnlineIdentifier::with_prior`]).
    pub payload: bool,
    /// Memory T of forgetting, s: data older than T weigh less than 1/e (factor
    /// ν = exp(−Δt/T) per sample). `None` (default): no forgetting; the change detection
    /// still follows jumps. RLS and EKF only.
    pub forgetting: Option<f64>,
    /// Directional forgetting for RLS (default `true`): discount only the information
    /// along the excited directions, so that unexcited ones do not blow up
    /// ([`Forgetting`]); `false`: exponential. The EKF forgets exponentially, through a
    /// random walk of the parameters of variance (1/ν − 1)·P_θθ per sample.
    pub directional: bool,
    /// Bandwidth of the causal velocity and acceleration estimates, Hz (default `10.0`,
    /// the batch preprocessing's cut-off; see the `kinematics` module). With
    /// `auto_cutoff`, the highest the regression's low-pass uses.
    pub cutoff_hz: f64,
    /// Lower the regression's low-pass once, after 1 s of filtered rows, to where the
    /// sensor noise of the log's positions (or measured velocities) leaves its
    /// accelerations within a tenth of their RMS (default `true`; `cutoff` module docs).
    /// The chosen cut-off is then `cutoff_hz` in [`OnlineIdentifier::settings_json`], and
    /// the one-step-ahead prediction's tracker moves to it (`prediction_cutoff_hz`). The
    /// whole-arm EKF's low-pass stays (its filter measures q and q̇); only its tracker
    /// moves. Payload mode's EKF measures joint forces and has it.
    pub auto_cutoff: bool,
    /// Change detection on the one-step-ahead torque errors (default on); `None`: off.
    pub change_detection: Option<ChangeDetection>,
    /// Factor on the parameter variances when a change is detected (default `1e3`: the
    /// data before the change keep a thousandth of their weight), capped at the initial
    /// (prior) variances. Whole-arm RLS (and the EKF's RLS warm-up) first opens only the
    /// directions a payload at the tip link moves the base parameters (by this factor on
    /// their variance given the rest of the arm, capped at the payload prior
    /// `payload_mass_std`, `payload_size`), and every direction when the errors have not
    /// come back to their level before the change over the `noise_window` after the
    /// first `holdoff`, or the change is flagged again meanwhile (the first alarm within
    /// a `holdoff` of a change confirmed along the tip that the tip explained opens along
    /// the tip again: it still sees the errors of the estimator before the change).
    pub open_factor: f64,
    /// RLS initial covariance δ of the equilibrated parameters (N²·m² per unit weighted
    /// error², default `1e6`: a prior σ of 1000 N·m on the torque each parameter
    /// explains; within [`crate::MIN_INITIAL_COVARIANCE`]..[`crate::MAX_INITIAL_COVARIANCE`])
    /// when no prior covariance is given.
    pub initial_covariance: f64,
    /// Width of the prior from a prior model's covariance (default `3.0`: P₀ = 3²·Σ_prior;
    /// [`crate::MIN_FACTOR`] to [`crate::MAX_FACTOR`]).
    pub prior_width: f64,
    /// Payload mode: prior standard deviation of the payload mass, kg (default `10.0`;
    /// [`crate::MIN_FACTOR`] to [`crate::MAX_FACTOR`]).
    pub payload_mass_std: f64,
    /// Payload mode: size of the payload, m (default `0.2`): prior σ of the first
    /// moments `payload_mass_std`·size, of the inertia `payload_mass_std`·size²
    /// ([`crate::MIN_FACTOR`] to [`crate::MAX_FACTOR`]).
    pub payload_size: f64,
    /// EKF without a prior: seconds of RLS before the filter starts from its estimate
    /// (default `2.0`; then also until M(q, θ̂) has been positive definite for 0.5 s).
    pub ekf_warmup: f64,
    /// EKF: factor on the measurement noise R of the positions (1e-3 rad or m) and
    /// velocities (1e-2 rad/s or m/s) (default `1.0`). Not used in payload mode, whose
    /// filter measures joint forces with the running noise levels. [`crate::MIN_FACTOR`] to
    /// [`crate::MAX_FACTOR`].
    pub ekf_noise: f64,
    /// Adaline's normalised step, Hopfield's gain as a fraction of its stability limit
    /// (dimensionless in (0, 2), default `0.5`).
    pub step_size: f64,
    /// Seed of the random states the parameters are equilibrated on (default `0`).
    pub seed: u64,
    /// From no knowledge: choose the Coulomb speed scale v_s online among
    /// [`super::ONLINE_COULOMB_SCALES`] and the robot's own ([`CoulombSearch`]; default
    /// `None`: the robot's own). Not with a prior model, which carries its scale.
    pub coulomb_search: Option<CoulombSearch>,
}

/// Rows in a row, each a step longer than half a cut-off period, from which `update`
/// refuses the next: the rows' rate is below twice the cut-off.
const GAPS_REFUSED: usize = 100;

impl Default for OnlineConfig {
    fn default() -> Self {
        Self {
            method: OnlineMethod::Rls,
            payload: false,
            forgetting: None,
            directional: true,
            cutoff_hz: crate::DEFAULT_LOG_CUTOFF_HZ,
            auto_cutoff: true,
            change_detection: Some(ChangeDetection::default()),
            open_factor: 1e3,
            initial_covariance: 1e6,
            prior_width: 3.0,
            payload_mass_std: 10.0,
            payload_size: 0.2,
            ekf_warmup: 2.0,
            ekf_noise: 1.0,
            step_size: 0.5,
            seed: 0,
            coulomb_search: None,
        }
    }
}

impl OnlineConfig {
    fn validate(&self) -> Result<()> {
        let positive = [
            ("cutoff_hz", self.cutoff_hz),
            ("initial_covariance", self.initial_covariance),
            ("prior_width", self.prior_width),
            ("payload_mass_std", self.payload_mass_std),
            ("payload_size", self.payload_size),
            ("ekf_noise", self.ekf_noise),
            ("open_factor", self.open_factor),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(name, v, "must be finite and > 0"));
            }
        }
        // Squared into covariances: a width of 1e300 made P₀ infinite, and the prior's
        // covariance was dropped for the flat δ (no prior) without a word.
        for (name, v) in [
            ("prior_width", self.prior_width),
            ("ekf_noise", self.ekf_noise),
            ("payload_mass_std", self.payload_mass_std),
            ("payload_size", self.payload_size),
        ] {
            check_factor(name, v)?;
        }
        check_initial_covariance(self.initial_covariance)?;
        if !(self.ekf_warmup.is_finite() && self.ekf_warmup >= 0.0) {
            return Err(invalid(
                "ekf_warmup",
                self.ekf_warmup,
                "must be finite and >= 0 s",
            ));
        }
        if let Some(t) = self.forgetting {
            if !(t.is_finite() && t > 0.0) {
                return Err(invalid(
                    "forgetting",
                    t,
                    "the memory must be finite and > 0 s",
                ));
            }
        }
        if let Some(c) = &self.coulomb_search {
            c.validate()?;
        }
        if !(self.step_size > 0.0 && self.step_size < 2.0) {
            return Err(invalid("step_size", self.step_size, "must be in (0, 2)"));
        }
        if let Some(c) = &self.change_detection {
            for (name, v) in [
                ("change_detection.window", c.window),
                ("change_detection.noise_window", c.noise_window),
                ("change_detection.threshold", c.threshold),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(invalid(name, v, "must be finite and > 0"));
                }
            }
            for (name, v) in [
                ("change_detection.holdoff", c.holdoff),
                ("change_detection.warmup", c.warmup),
            ] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(invalid(name, v, "must be finite and >= 0 s"));
                }
            }
        }
        Ok(())
    }
}

/// What one [`OnlineIdentifier::update`] returns, borrowed from the identifier.
#[derive(Debug, Clone, Copy)]
pub struct OnlineUpdate<'a> {
    /// The one-step-ahead prediction τ̂ of this row's joint forces (N·m or N), from the
    /// estimate before the row and this row's causal q, q̇, q̈.
    pub prediction: &'a [f64],
    /// The estimate after the row: the base parameters β̂ (SI units of their
    /// combinations), or in payload mode the payload's π̂ = [m, m·cx, m·cy, m·cz, Ixx,
    /// Ixy, Iyy, Ixz, Iyz, Izz] in the tip link's frame, inertia about its origin (kg,
    /// kg·m, kg·m²).
    pub estimate: &'a [f64],
    /// Standard deviation of each entry of `estimate`, where the method has one (RLS,
    /// EKF): the filter's own, which assumes white equation errors of the running joint
    /// noise levels, times √κ, κ the errors' running correlation time in samples (the
    /// regression data are low-passed, so their errors are not white; κ ≥ 1, estimated
    /// by batch means over 0.5 s blocks).
    pub sigma: Option<&'a [f64]>,
    /// Whether a change of the dynamics was detected at this row (the covariance was
    /// opened).
    pub change: bool,
    /// Whether the row updated the estimate (not: a repeated time stamp, or the causal
    /// derivatives still converging after the start or a gap).
    pub updated: bool,
}

/// The estimator behind an [`OnlineIdentifier`].
#[derive(Debug, Clone)]
enum Engine {
    Rls(Box<DynRls<DynScaledModel<TrackedModel>>>),
    Adaline(Box<DynAdaline<DynScaledModel<TrackedModel>>>),
    Hopfield(Box<DynHopfield<DynScaledModel<TrackedModel>>>),
    Ekf(Box<EkfEngine>),
    /// Payload mode's EKF: on the payload's parameters alone (`payload_ekf`).
    PayloadEkf(Box<PayloadEkf>),
}

/// The EKF and what it needs between samples.
#[derive(Debug, Clone)]
struct EkfEngine {
    /// The warm-up estimator (no prior): RLS until the filter can start from its estimate.
    rls: DynRls<DynScaledModel<TrackedModel>>,
    ekf: DynEkf<TrackedModel>,
    running: bool,
    /// Time the warm-up estimate has kept M(q, θ̂) positive definite, s.
    definite_for: f64,
    warm_for: f64,
    restarts: usize,
    /// The previous row (the filter steps one row behind, so that it knows the period
    /// and the torque at the end of it).
    prev: [DVector<f64>; 4],
    has_prev: bool,
    held: DVector<f64>,
    /// diag(M⁻¹·Σ·M⁻ᵀ) per joint (units of q̈²), refreshed every `Q_REFRESH` samples.
    qdd_var: DVector<f64>,
    minv: DMatrix<f64>,
    f0: DVector<f64>,
    f1: DVector<f64>,
    tau_j: DVector<f64>,
    qn: DVector<f64>,
    since_q: usize,
    ws: TrackedWorkspace,
    /// Initial parameter variances of the running filter (θ units), the cap of the
    /// opening.
    p0_diag: DVector<f64>,
    /// P×P scratch of the hand-over to the warm-up after a change (γ units).
    handover: DMatrix<f64>,
    /// The running filter's estimate (θ units) at its last two marks, [`MARK_PERIOD`]
    /// apart: a restart goes back to the older one.
    marks: [DVector<f64>; 2],
    /// Filter time since the newer mark, s.
    mark_age: f64,
    /// The parameter covariance the running filter started with (θ units).
    p_start: DMatrix<f64>,
}

/// Filter time between two marks of its estimate, s. A filter that fails has often taken
/// wild steps just before (an xArm 7 stand-in at 100 Hz: one step from 31 % to 81 % off,
/// the next one failed), so it restarts from an estimate 0.5–1 s older.
const MARK_PERIOD: f64 = 0.5;

/// Samples between two refreshes of the EKF's process noise (its M⁻¹ costs N + 1
/// forward dynamics).
const Q_REFRESH: usize = 16;

/// Block length of the errors' correlation estimate, s: several cut-off periods.
const CORRELATION_BLOCK: f64 = 0.5;
/// Memory of the correlation estimate, s (at least the noise levels' `noise_window`).
const CORRELATION_MEMORY: f64 = 10.0;

/// Smallest forgetting factor ν per row: below it P/ν leaves the range of f64 within a
/// few rows.
const MIN_FORGETTING_FACTOR: f64 = 1e-12;

/// Positions and velocities R of the EKF before `ekf_noise` (as `identify`'s defaults).
const EKF_POSITION_NOISE: f64 = 1e-3;
const EKF_VELOCITY_NOISE: f64 = 1e-2;

/// Identification while the arm runs (see the module docs of `online`).
///
/// ```
/// use prrrp_core::{BaseOptions, OnlineConfig, OnlineIdentifier, SerialChain};
/// let chain = SerialChain::puma560().to_dyn();
/// let base = chain.base_parameters(&BaseOptions::default())?;
/// let mut id = OnlineIdentifier::new(&chain, &base, OnlineConfig::default())?;
/// for k in 0..2000 {
///     let t = k as f64 * 1e-3;
///     let q: Vec<f64> = (0..6).map(|j| (t * (1.0 + j as f64)).sin()).collect();
///     let qd: Vec<f64> = (0..6).map(|j| (1.0 + j as f64) * (t * (1.0 + j as f64)).cos()).collect();
///     let qdd: Vec<f64> = (0..6).map(|j| -(1.0 + j as f64).powi(2) * (t * (1.0 + j as f64)).sin()).collect();
///     let tau = chain.inverse_dynamics(&q, &qd, &qdd)?;
///     let step = id.update(t, &q, &tau, None)?;
///     assert_eq!(step.prediction.len(), 6);
/// }
/// let model = id.estimate()?;            // an IdentifiedModel, as `identify` returns
/// assert_eq!(model.beta.len(), base.count());
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone)]
pub struct OnlineIdentifier {
    config: OnlineConfig,
    chain: DynChain,
    base: BaseParameters,
    prior: Option<IdentifiedModel>,
    model: TrackedModel,
    mws: TrackedWorkspace,
    /// θ = D·γ for the scaled engines (RLS, Adaline, Hopfield, the EKF's warm-up).
    scale: DVector<f64>,
    engine: Engine,
    /// Zero-lag q̇, q̈ at each row for the one-step-ahead prediction.
    kin: CausalKinematics,
    /// The regression data: q, q̇, q̈ and τ through one causal low-pass.
    lp: CausalLowPass,
    /// The low-pass's cut-off from the sensor noise (`auto_cutoff`).
    cutoff: Option<CutoffChoice>,
    detector: Option<ChangeDetector>,
    /// Running noise variance per joint when change detection is off.
    noise: ChangeDetector,
    /// The errors' correlation time, the factor on the filters' own variances.
    correlation: ErrorCorrelation,
    n: usize,
    /// Variance cap of the opening (θ units); for the arm's scale s in payload mode 0
    /// (never opened).
    cap: DVector<f64>,
    /// Whole-arm modes: the opening along the tip link's directions and its second look
    /// (`None` in payload mode, or for a chain without tip link columns).
    tip: Option<TipOpening>,
    q: DVector<f64>,
    qd: DVector<f64>,
    qdd: DVector<f64>,
    tau: DVector<f64>,
    pred: DVector<f64>,
    /// The filtered row (regression data) and its a-priori prediction.
    qf: DVector<f64>,
    vf: DVector<f64>,
    af: DVector<f64>,
    tf: DVector<f64>,
    predf: DVector<f64>,
    /// The regressed forces: τ_f, less the arm's in payload mode.
    tr: DVector<f64>,
    resid: Vec<f64>,
    /// The regressor of the filtered row (θ units) and the variance the estimate's
    /// uncertainty adds to each joint's a-priori error (units of τ²), for the change test.
    phi: DMatrix<f64>,
    model_var: Vec<f64>,
    floor: Vec<f64>,
    tau_max: Vec<f64>,
    /// Whether any torque channel has delivered (read other than exactly 0) yet.
    delivering: bool,
    weights: DVector<f64>,
    theta: DVector<f64>,
    /// EKF from a prior whose M(q, θ) is not positive definite: the largest relative
    /// change of a base parameter in its physical projection, where the filter started.
    projected: Option<f64>,
    gamma: DVector<f64>,
    open: DVector<f64>,
    out_estimate: Vec<f64>,
    out_sigma: Vec<f64>,
    has_sigma: bool,
    t_prev: Option<f64>,
    /// The look after an alarm (`guard`): the opened estimator beside the kept one.
    guard: ChangeGuard,
    /// The look pending opened along the tip link only.
    tip_look: bool,
    /// The pending look re-opened along the tip right after a confirmed change.
    fresh_look: bool,
    /// Dropped looks along the tip in a row (each within two hold-offs of the last) whose
    /// kept estimator stayed above the alarm level, and when the last one ended (s).
    high_drops: u32,
    last_drop: f64,
    /// When the last look confirmed a change (s), and its opened copy's mean Σ_j e_j²/σ_j²
    /// per joint over the scored rows (∞ unless it was a first opening along the tip).
    last_confirm: (f64, f64),
    /// During a look, the opened copy of an RLS engine (or of the EKF's warm-up) and an
    /// unopened one, both taking the rows while the engine waits.
    opened_rls: Option<Box<[DynRls<DynScaledModel<TrackedModel>>; 2]>>,
    /// The same for payload mode's EKF.
    opened_payload: Option<Box<[PayloadEkf; 2]>>,
    /// The opened and the unopened copy's a-priori errors of the row (units of τ).
    e_opened: Vec<f64>,
    e_kept: Vec<f64>,
    rows: usize,
    updates: usize,
    repeated: usize,
    /// Rows in a row whose step was longer than the low-pass's longest (each restarted it).
    gaps: usize,
    changes: usize,
    /// The online choice of the Coulomb scale (`coulomb_search`): the other candidates
    /// until the choice, then its record.
    search: Option<Box<Search>>,
}

/// The candidates of [`CoulombSearch`] beside the identifier (candidate 0) and their
/// scores.
#[derive(Debug, Clone)]
struct Search {
    others: Vec<OnlineIdentifier>,
    /// For a method other than the RLS, one whole-arm RLS per candidate scale (the own
    /// first) whose one-step-ahead errors are scored instead of the candidates' own: the
    /// scale is a choice of model, and an EKF's errors over the window also carry its
    /// filter's start, restarts and looks (on a UR5 stand-in one EKF candidate scored
    /// e^50 times worse than its neighbours and the choice fell on 0.001 rad/s, 4.8 %
    /// off at the end; the RLS ranked the scales as their end errors do). Empty for
    /// the RLS.
    scorers: Vec<OnlineIdentifier>,
    scores: Scores,
    /// Each other candidate's (change, updated) of the last row.
    flags: Vec<(bool, bool)>,
    chosen: Option<usize>,
}

impl OnlineIdentifier {
    /// An identifier of the base parameters of `chain` in the analysis `base`, starting
    /// from no knowledge (RLS from θ = 0 with an uninformative covariance; the EKF after
    /// an RLS warm-up).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a setting out of range or payload mode
    /// without a prior; [`PrrrpError::ShapeMismatch`] if `base` is not an analysis of
    /// `chain`.
    pub fn new(chain: &DynChain, base: &BaseParameters, config: OnlineConfig) -> Result<Self> {
        if config.payload {
            return Err(invalid(
                "payload",
                f64::NAN,
                "payload mode tracks a load on a known arm: give the arm's model \
                 (OnlineIdentifier::with_prior)",
            ));
        }
        Self::build(chain, base, None, config)
    }

    /// An identifier that starts from the identified model `prior` (its robot, base
    /// analysis, β̂ and covariance): of the base parameters, or in payload mode
    /// (`config.payload`) of a payload at the tip link on the arm β̂ of `prior` (starting
    /// from no payload).
    ///
    /// # Errors
    /// As [`OnlineIdentifier::new`], and the errors of rebuilding the prior's robot.
    pub fn with_prior(prior: &IdentifiedModel, config: OnlineConfig) -> Result<Self> {
        let chain = prior.chain()?;
        let base = base_of(prior, &chain)?;
        Self::build(&chain, &base, Some(prior.clone()), config)
    }

    fn build(
        chain: &DynChain,
        base: &BaseParameters,
        prior: Option<IdentifiedModel>,
        config: OnlineConfig,
    ) -> Result<Self> {
        config.validate()?;
        let n = chain.dof();
        let bm = chain.base_model(base)?;
        let b = bm.count();
        let model = match (&prior, config.payload) {
            (Some(p), true) => {
                TrackedModel::payload(bm, base, DVector::from_column_slice(&p.beta))?
            }
            _ => TrackedModel::Full(bm),
        };
        let p = model.dims().1 .0;
        let states = random_states(chain, config.seed);
        let samples = DynSamples::new(&states[0], &states[1], &states[2], &states[3])?;
        let scaled = DynScaledModel::equilibrated(model.clone(), &samples)?;
        let scale = scaled.scale().clone();

        // The start θ₀ and its covariance (θ units), and the opening's cap.
        let w2 = config.prior_width * config.prior_width;
        let mut theta0 = DVector::zeros(p);
        let mut p0: Option<DMatrix<f64>> = None;
        let mut cap = DVector::from_fn(p, |i, _| scale[i] * scale[i] * config.initial_covariance);
        if config.payload {
            let var = DVector::from_row_slice(&payload_prior_variances(&config));
            cap.copy_from(&var);
            p0 = Some(DMatrix::from_diagonal(&var));
        } else if let Some(pr) = &prior {
            theta0.copy_from_slice(&pr.beta);
            if let Some(c) = &pr.covariance {
                let c = DMatrix::from_row_slice(b, b, c) * w2;
                let c = (&c + c.transpose()) * 0.5;
                if c.clone().cholesky().is_some() {
                    p0 = Some(c);
                }
            }
        }
        // A prior whose M(q, θ) is not positive definite cannot start the filter: its first
        // step fails, and the RLS warm-up it falls back to stays near the prior (its
        // covariance is the prior's) and hands back only when M happens to be definite.
        // Least squares often gives such a prior for light links: a PUMA 560's wrist from
        // weighted least squares was indefinite at every row of a log, and its filter ran
        // 11–16 s of warm-up instead. The filter starts from the nearest physically
        // consistent base parameters (`base_feasibility`), each link a rigid body.
        let mut projected = None;
        if config.method == OnlineMethod::Ekf
            && !config.payload
            && prior.is_some()
            && !definite_on(&model, &states, &theta0)?
        {
            let f = base_feasibility(base, theta0.as_slice(), &PhysicalConfig::default())?;
            let physical = DVector::from_vec(base.base_values(&f.parameters)?);
            if definite_on(&model, &states, &physical)? {
                projected = Some(f.max_relative_mismatch);
                theta0 = physical;
            }
        }
        let gamma0 = theta0.component_div(&scale);
        let p0_gamma = p0
            .as_ref()
            .map(|c| DMatrix::from_fn(p, p, |i, j| c[(i, j)] / (scale[i] * scale[j])));
        let rls_cfg = RlsConfig {
            forgetting: 1.0,
            initial_covariance: config.initial_covariance,
        };
        let make_rls = || -> Result<DynRls<DynScaledModel<TrackedModel>>> {
            let mut r = DynRls::new(scaled.clone(), gamma0.clone(), rls_cfg)?;
            if let Some(c) = &p0_gamma {
                r.set_initial_covariance(c)?;
            }
            Ok(r)
        };
        let engine = match config.method {
            OnlineMethod::Rls => Engine::Rls(Box::new(make_rls()?)),
            OnlineMethod::Adaline => {
                let cfg = AdalineConfig {
                    rule: AdalineRule::Normalised,
                    step_size: config.step_size,
                    ..AdalineConfig::default()
                };
                Engine::Adaline(Box::new(DynAdaline::new(
                    scaled.clone(),
                    gamma0.clone(),
                    cfg,
                )?))
            }
            OnlineMethod::Hopfield => {
                let cfg = hopfield_config(&scaled, &samples, chain, &gamma0, config.step_size)?;
                Engine::Hopfield(Box::new(DynHopfield::new(
                    scaled.clone(),
                    gamma0.clone(),
                    cfg,
                )?))
            }
            OnlineMethod::Ekf if config.payload => {
                Engine::PayloadEkf(Box::new(PayloadEkf::new(&model, &cap)))
            }
            OnlineMethod::Ekf => {
                let cfg = EkfConfig {
                    dt: 1e-3,
                    measurement: EkfMeasurement::PositionsVelocities,
                    discretisation: Discretisation::SecondOrder,
                    position_noise: EKF_POSITION_NOISE * config.ekf_noise,
                    velocity_noise: EKF_VELOCITY_NOISE * config.ekf_noise,
                    process_position_noise: 0.0,
                    process_velocity_noise: 0.0,
                    process_parameter_noise: 0.0,
                    initial_parameter_rel_std: 0.1,
                    initial_parameter_min_std: 1e-6,
                    parameter_jacobian: ParameterJacobian::DataAcceleration,
                    ..EkfConfig::default()
                };
                let mut ekf = DynEkf::new(model.clone(), theta0.clone(), cfg)?;
                ekf.set_stiff_handling(true);
                let s = 2 * n + p;
                let mut e = EkfEngine {
                    rls: make_rls()?,
                    ekf,
                    running: false,
                    definite_for: 0.0,
                    warm_for: 0.0,
                    restarts: 0,
                    prev: [
                        DVector::zeros(n),
                        DVector::zeros(n),
                        DVector::zeros(n),
                        DVector::zeros(n),
                    ],
                    has_prev: false,
                    held: DVector::zeros(n),
                    qdd_var: DVector::zeros(n),
                    minv: DMatrix::zeros(n, n),
                    f0: DVector::zeros(n),
                    f1: DVector::zeros(n),
                    tau_j: DVector::zeros(n),
                    qn: DVector::zeros(s),
                    since_q: 0,
                    ws: model.workspace(),
                    p0_diag: DVector::zeros(p),
                    handover: DMatrix::zeros(p, p),
                    marks: [theta0.clone(), theta0.clone()],
                    mark_age: 0.0,
                    p_start: DMatrix::zeros(p, p),
                };
                // With a prior (or in payload mode) the filter starts at once.
                if prior.is_some() {
                    let p0 = match &p0 {
                        Some(c) => c.clone(),
                        None => DMatrix::from_diagonal(&DVector::from_fn(p, |i, _| {
                            (0.1 * theta0[i].abs())
                                .max(1e-6 * theta0.amax())
                                .max(1e-12)
                                .powi(2)
                        })),
                    };
                    e.start(&theta0, &p0, n)?;
                }
                Engine::Ekf(Box::new(e))
            }
        };
        let (opened_rls, opened_payload) = match &engine {
            Engine::Rls(r) => (Some(Box::new([(**r).clone(), (**r).clone()])), None),
            Engine::Ekf(e) => (Some(Box::new([e.rls.clone(), e.rls.clone()])), None),
            Engine::PayloadEkf(e) => (None, Some(Box::new([(**e).clone(), (**e).clone()]))),
            Engine::Adaline(_) | Engine::Hopfield(_) => (None, None),
        };
        let tip = if config.payload {
            None
        } else {
            TipOpening::new(base, n, &scale, payload_prior_variances(&config))
        };
        let detection = config.change_detection;
        let init_sd = prior
            .as_ref()
            .filter(|p| p.residual_rms.iter().all(|v| *v > 0.0))
            .map(|p| p.residual_rms.clone());
        let noise_cfg = ChangeDetection {
            threshold: f64::INFINITY,
            ..detection.unwrap_or_default()
        };
        // The whole-arm EKF's filter measures q and q̇, not q̈: the choice's reason for its
        // low-pass is its warm-up's alone. With its low-pass lowered, from the wls prior of
        // example-robot-data's xArm 7 and UR5 at 100 Hz, the filter took a wild step after
        // a restart and ended 31 and 20 % off (5.3 and 3.8 % at 10 Hz), while every RLS
        // ended within 0.25 points of the batch fit's error (docs/design/online.md, "The
        // cut-off from the sensor noise").
        let mut out = Self {
            config,
            chain: chain.clone(),
            base: base.clone(),
            prior,
            mws: model.workspace(),
            model,
            scale,
            engine,
            kin: CausalKinematics::new(n, config.cutoff_hz, false)?,
            lp: CausalLowPass::new(n, config.cutoff_hz, false)?,
            cutoff: config
                .auto_cutoff
                .then(|| CutoffChoice::new(n, config.cutoff_hz)),
            qf: DVector::zeros(n),
            vf: DVector::zeros(n),
            af: DVector::zeros(n),
            tf: DVector::zeros(n),
            predf: DVector::zeros(n),
            tr: DVector::zeros(n),
            detector: detection
                .map(|d| ChangeDetector::new(n, d, init_sd.as_deref()))
                .transpose()?,
            noise: ChangeDetector::new(n, noise_cfg, init_sd.as_deref())?,
            correlation: {
                let w = detection.unwrap_or_default().noise_window;
                ErrorCorrelation::new(n, CORRELATION_BLOCK, CORRELATION_MEMORY.max(w))
            },
            n,
            cap,
            tip,
            q: DVector::zeros(n),
            qd: DVector::zeros(n),
            qdd: DVector::zeros(n),
            tau: DVector::zeros(n),
            pred: DVector::zeros(n),
            resid: vec![0.0; n],
            phi: DMatrix::zeros(n, p),
            model_var: vec![0.0; n],
            floor: vec![0.0; n],
            tau_max: vec![0.0; n],
            delivering: false,
            weights: DVector::zeros(n),
            theta: theta0,
            projected,
            gamma: DVector::zeros(p),
            open: DVector::zeros(p),
            out_estimate: vec![0.0; if config.payload { PAYLOAD_PARAMS } else { b }],
            out_sigma: vec![0.0; if config.payload { PAYLOAD_PARAMS } else { b }],
            has_sigma: false,
            t_prev: None,
            guard: ChangeGuard::default(),
            tip_look: false,
            fresh_look: false,
            high_drops: 0,
            last_drop: f64::NEG_INFINITY,
            last_confirm: (f64::NEG_INFINITY, f64::INFINITY),
            opened_rls,
            opened_payload,
            e_opened: vec![0.0; n],
            e_kept: vec![0.0; n],
            rows: 0,
            updates: 0,
            repeated: 0,
            gaps: 0,
            changes: 0,
            search: None,
        };
        out.refresh_outputs();
        if let Some(search) = config.coulomb_search {
            out.search = Self::candidates(chain, base, config, search, out.prior.is_some())?;
        }
        Ok(out)
    }

    /// The other candidates of the Coulomb scale search (`None` for a robot without a
    /// Coulomb term: nothing to choose).
    fn candidates(
        chain: &DynChain,
        base: &BaseParameters,
        config: OnlineConfig,
        search: CoulombSearch,
        prior: bool,
    ) -> Result<Option<Box<Search>>> {
        if prior {
            return Err(invalid(
                "coulomb_search",
                f64::NAN,
                "a prior model carries its Coulomb scale (chosen by identify); search \
                 only from no knowledge",
            ));
        }
        let friction = chain.friction();
        if !friction.coulomb {
            return Ok(None);
        }
        let own = friction.coulomb_smoothing;
        let mut scales = vec![own];
        scales.extend(ONLINE_COULOMB_SCALES.iter().filter(|v| **v != own));
        let single = OnlineConfig {
            coulomb_search: None,
            ..config
        };
        let with_scale = |v: f64| {
            let model = FrictionModel {
                coulomb_smoothing: v,
                ..friction
            };
            chain
                .clone()
                .with_friction(model, chain.friction_params().to_vec())
        };
        let others = scales[1..]
            .iter()
            .map(|v| Self::build(&with_scale(*v)?, base, None, single))
            .collect::<Result<Vec<_>>>()?;
        let scorers = if config.method == OnlineMethod::Rls {
            Vec::new()
        } else {
            let rls = OnlineConfig {
                method: OnlineMethod::Rls,
                ..single
            };
            scales
                .iter()
                .map(|v| Self::build(&with_scale(*v)?, base, None, rls))
                .collect::<Result<Vec<_>>>()?
        };
        Ok(Some(Box::new(Search {
            flags: vec![(false, false); others.len()],
            others,
            scorers,
            scores: Scores::new(search, scales, chain.dof()),
            chosen: None,
        })))
    }

    /// The settings.
    pub fn config(&self) -> &OnlineConfig {
        &self.config
    }

    /// The robot (as the estimates are expressed in it).
    pub fn chain(&self) -> &DynChain {
        &self.chain
    }

    /// The base-parameter analysis.
    pub fn base(&self) -> &BaseParameters {
        &self.base
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.n
    }

    /// Names of the estimated parameters: the base parameters' (named after their first
    /// standard parameter), or in payload mode the payload's `m, mx, my, mz, Ixx, …`.
    pub fn parameter_names(&self) -> Vec<String> {
        if self.config.payload {
            crate::models::chain::INERTIAL_PARAMETER_NAMES
                .iter()
                .map(|s| s.to_string())
                .collect()
        } else {
            self.base
                .independent
                .iter()
                .map(|&j| self.base.names[j].clone())
                .collect()
        }
    }

    /// The current estimate (see [`OnlineUpdate::estimate`]).
    pub fn parameters(&self) -> &[f64] {
        &self.out_estimate
    }

    /// Standard deviation of the current estimate, where the method has one.
    pub fn sigma(&self) -> Option<&[f64]> {
        self.has_sigma.then_some(self.out_sigma.as_slice())
    }

    /// Rows consumed, rows that updated the estimate, repeated rows, detected changes.
    pub fn counts(&self) -> (usize, usize, usize, usize) {
        (self.rows, self.updates, self.repeated, self.changes)
    }

    /// Alarms whose look dropped the opening (the estimator before them predicted as
    /// well: false alarms, see `guard`).
    pub fn dropped_alarms(&self) -> usize {
        self.guard.reverted()
    }

    /// The running noise level (RMS of the one-step-ahead errors that passed the change
    /// test) of each joint, N·m or N.
    pub fn noise_rms(&self) -> Vec<f64> {
        self.variances().iter().map(|v| v.sqrt()).collect()
    }

    fn variances(&self) -> &[f64] {
        match &self.detector {
            Some(d) => d.variances(),
            None => self.noise.variances(),
        }
    }

    /// Whether the EKF is running (false during its RLS warm-up, and for other methods).
    pub fn ekf_running(&self) -> bool {
        matches!(&self.engine, Engine::Ekf(e) if e.running)
            || matches!(&self.engine, Engine::PayloadEkf(_))
    }

    /// Consumes one raw sample: time `t` (s, not decreasing), positions `q` (rad, m),
    /// joint forces `tau` (N·m, N) and optionally measured velocities `qd` (rad/s, m/s;
    /// give them at every sample or never). Causal: only this and earlier samples are
    /// used. A row with the previous row's time stamp is a repeat: it gets a prediction
    /// and changes nothing. Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for vectors without one entry per joint, or
    /// velocities given at some samples and not others; [`PrrrpError::NonFinite`] for
    /// NaN/∞ (the sample is refused and the state left as it was);
    /// [`PrrrpError::InvalidParameter`] for a value of 1e100 or more in magnitude (refused
    /// alike); [`PrrrpError::NonIncreasingTime`] for a time stamp before the previous one;
    /// [`PrrrpError::Diverged`] when the estimator fails (the identifier should then be
    /// rebuilt).
    pub fn update(
        &mut self,
        t: f64,
        q: &[f64],
        tau: &[f64],
        qd: Option<&[f64]>,
    ) -> Result<OnlineUpdate<'_>> {
        let (mut change, mut updated) = self.consume(t, q, tau, qd)?;
        if self.search.as_ref().is_some_and(|s| s.chosen.is_none()) {
            (change, updated) = self.search_row(t, q, tau, qd, (change, updated));
        }
        Ok(OnlineUpdate {
            prediction: self.pred.as_slice(),
            estimate: &self.out_estimate,
            sigma: self.has_sigma.then_some(self.out_sigma.as_slice()),
            change,
            updated,
        })
    }

    /// The other candidates of the Coulomb scale search take the row (which this
    /// identifier has taken, with `flags`), their one-step-ahead errors are scored, and at
    /// the end of the window the best takes this identifier's place. Returns the
    /// (change, updated) flags of the identifier after the row. Allocation-free.
    fn search_row(
        &mut self,
        t: f64,
        q: &[f64],
        tau: &[f64],
        qd: Option<&[f64]>,
        flags: (bool, bool),
    ) -> (bool, bool) {
        let Some(mut s) = self.search.take() else {
            return flags;
        };
        let elapsed = s.scores.elapsed(t);
        let scored = flags.1 && s.scores.scored(elapsed);
        for (c, o) in s.others.iter_mut().enumerate() {
            match o.consume(t, q, tau, qd) {
                Ok(f) => {
                    s.flags[c] = f;
                    if scored && s.scorers.is_empty() {
                        s.scores.add(c + 1, tau, o.pred.as_slice());
                    }
                }
                // The row was valid for this identifier: the candidate itself failed.
                Err(_) => s.scores.fail(c + 1),
            }
        }
        if s.scorers.is_empty() {
            if scored {
                s.scores.add(0, tau, self.pred.as_slice());
            }
        } else {
            for (c, o) in s.scorers.iter_mut().enumerate() {
                match o.consume(t, q, tau, qd) {
                    Ok(_) if scored => s.scores.add(c, tau, o.pred.as_slice()),
                    Ok(_) => {}
                    Err(_) => s.scores.fail(c),
                }
            }
        }
        if scored {
            s.scores.row();
        }
        let mut out = flags;
        if elapsed >= s.scores.search.at {
            let best = s.scores.best();
            if best > 0 {
                std::mem::swap(self, &mut s.others[best - 1]);
                out = s.flags[best - 1];
            }
            self.config.coulomb_search = Some(s.scores.search);
            s.others.clear();
            s.scorers.clear();
            s.chosen = Some(best);
        }
        self.search = Some(s);
        out
    }

    /// [`OnlineIdentifier::update`] without the Coulomb scale search: the row's (change,
    /// updated) flags.
    fn consume(
        &mut self,
        t: f64,
        q: &[f64],
        tau: &[f64],
        qd: Option<&[f64]>,
    ) -> Result<(bool, bool)> {
        let n = self.n;
        for (what, v) in [("q", q), ("tau", tau)] {
            if v.len() != n {
                return Err(crate::estimators::len_mismatch(what, n, v.len()));
            }
        }
        if let Some(v) = qd {
            if v.len() != n {
                return Err(crate::estimators::len_mismatch("qd", n, v.len()));
            }
        }
        if self.rows == 0 {
            self.kin = CausalKinematics::new(n, self.config.cutoff_hz, qd.is_some())?;
            self.lp = CausalLowPass::new(n, self.config.cutoff_hz, qd.is_some())?;
            if let Some(c) = &mut self.cutoff {
                c.measured_velocity(qd.is_some());
            }
        } else if qd.is_some() != self.kin.measured_velocity() {
            return Err(PrrrpError::ShapeMismatch {
                what: "qd".into(),
                expected: if self.kin.measured_velocity() {
                    "measured velocities at every sample (the first had them)".into()
                } else {
                    "no velocities (the first sample had none)".into()
                },
                got: "a sample that differs".into(),
            });
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !t.is_finite() || !finite(q) || !finite(tau) || !qd.map_or(true, finite) {
            let what = if !t.is_finite() {
                "t"
            } else if !finite(q) {
                "q"
            } else if !finite(tau) {
                "tau"
            } else {
                "qd"
            };
            return Err(PrrrpError::NonFinite {
                what: what.into(),
                row: Some(self.rows),
            });
        }
        // Finite but absurd: a torque of 1e300 N·m went through every row and its squares
        // left the noise levels infinite, the weights 0 and the estimate unmoved, and only
        // `estimate` failed, on a quantity the user never gave.
        for (name, v) in [("q", q), ("tau", tau), ("qd", qd.unwrap_or(&[]))] {
            if let Some((j, x)) = v.iter().enumerate().find(|(_, x)| x.abs() >= MAX_MAGNITUDE) {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("{name}[{j}] at row {}", self.rows),
                    value: *x,
                    reason: "no joint turns, moves or pushes 1e100 (rad, m, N·m, N) or more; \
                             check the log's units",
                });
            }
        }
        // A time stamp of 1e300 s was taken, and every later row was then "before" it.
        if t.abs() >= MAX_MAGNITUDE {
            return Err(PrrrpError::InvalidParameter {
                field: format!("t at row {}", self.rows),
                value: t,
                reason: "no clock reads 1e100 s or more; check the log's units",
            });
        }
        let dt = match self.t_prev {
            Some(tp) if t < tp => return Err(PrrrpError::NonIncreasingTime { row: self.rows }),
            Some(tp) => t - tp,
            None => 0.0,
        };
        // A row the regression takes (no gap that restarts the filters) with a forgetting
        // factor ν = exp(−dt/T) of 0 to the last digit would fail inside the estimator,
        // with the state half updated: refused here, before anything changes.
        if let Some(tc) = self.config.forgetting {
            if dt > 0.0 && dt <= self.kin.max_gap() && (-dt / tc).exp() < MIN_FORGETTING_FACTOR {
                return Err(invalid(
                    "forgetting",
                    tc,
                    "this memory (s) forgets everything between two rows (ν = exp(−dt/T) \
                     underflows): give one that spans many rows",
                ));
            }
        }
        // Every row a gap: the cut-off is not below the Nyquist frequency of the rows, each
        // restarts the filtering and nothing is ever learned (a 10 Hz log at the default
        // cut-off took every row and returned the start, silently).
        let gap = self.t_prev.is_some() && dt > self.lp.max_gap();
        if gap && self.gaps + 1 >= GAPS_REFUSED {
            return Err(PrrrpError::InvalidParameter {
                field: "cutoff_hz".into(),
                value: self.config.cutoff_hz,
                reason: "(with auto_cutoff, the default it starts from) is not below the \
                         Nyquist frequency of the rows, so every row restarts the causal \
                         filtering and nothing is learned: give a cutoff_hz below half the \
                         rows' rate (Hz)",
            });
        }
        let repeat = self.t_prev.is_some() && dt == 0.0;
        if !repeat {
            self.gaps = if gap { self.gaps + 1 } else { 0 };
        }
        self.rows += 1;
        self.q.copy_from_slice(q);
        self.tau.copy_from_slice(tau);
        let mut change = false;
        let mut updated = false;
        if repeat {
            self.repeated += 1;
        } else {
            self.kin
                .update(dt, q, qd, self.qd.as_mut_slice(), self.qdd.as_mut_slice())?;
            // Rows before any torque channel delivers (all exactly 0: a sensor not yet
            // streaming, or zeroed) are not regression data, and the first torques restart
            // the low-pass: filtered through the step from 0, they were fitted by the
            // estimator from no knowledge, which never recovered (10⁴ % off at the end).
            let silent = !self.delivering;
            for (m, t) in self.tau_max.iter_mut().zip(tau) {
                *m = m.max(t.abs());
                self.delivering |= *m > 0.0;
            }
            if silent && self.rows > 1 && self.delivering {
                self.lp.reset();
            }
            if let Some(c) = &mut self.cutoff {
                c.sample(t, qd.unwrap_or(q));
            }
            self.lp.update(
                dt,
                q,
                tau,
                qd,
                self.qf.as_mut_slice(),
                self.vf.as_mut_slice(),
                self.af.as_mut_slice(),
                self.tf.as_mut_slice(),
            )?;
            self.t_prev = Some(t);
        }
        // The prediction with the estimate before this row.
        self.model.inverse_dynamics_into(
            &mut self.mws,
            &self.q,
            &self.qd,
            &self.qdd,
            &self.theta,
            &mut self.pred,
        )?;
        if !repeat && self.lp.ready() && self.delivering {
            // The change test and the noise levels (the regression's weights) on the
            // filtered equation errors, with the estimate before this row.
            self.model.inverse_dynamics_into(
                &mut self.mws,
                &self.qf,
                &self.vf,
                &self.af,
                &self.theta,
                &mut self.predf,
            )?;
            for j in 0..n {
                self.resid[j] = self.tf[j] - self.predf[j];
                // Variances below (1e-6 of the largest force)² are round-off, not noise.
                self.floor[j] = (1e-6 * self.tau_max[j]).powi(2).max(1e-300);
            }
            if self.detector.is_some() {
                self.model_variances()?;
            }
            if let Some(d) = &mut self.detector {
                d.hold(self.guard.active());
                change = d.update(dt, &self.resid, &self.floor, &self.model_var)?;
            } else {
                self.noise
                    .update(dt, &self.resid, &self.floor, &self.model_var)?;
            }
            let (var, settled) = match &self.detector {
                Some(d) => (d.variances(), d.settled()),
                None => (self.noise.variances(), self.noise.settled()),
            };
            if settled {
                self.correlation.update(dt, &self.resid, var, &self.floor);
            }
            if change {
                // A method with a covariance opens a copy and looks (`guard`); the change
                // is reported when the look confirms it.
                change = !self.begin_look()?;
                if change {
                    self.changes += 1;
                }
            } else {
                self.second_look(dt)?;
            }
            match self.step_engine(dt).and_then(|()| self.look_row(dt)) {
                Ok(confirmed) => change |= confirmed,
                Err(err) => self.recover_warmup(err)?,
            }
            updated = true;
            self.updates += 1;
            self.choose_cutoff(dt)?;
        } else if !repeat {
            // No regression across a restart of the derivatives: the EKF must not step
            // over the gap either.
            if let Engine::Ekf(e) = &mut self.engine {
                e.has_prev = false;
            }
        }
        Ok((change, updated))
    }

    /// A whole-arm EKF whose filter, warm-up RLS or look's copy failed on this row goes
    /// back to the warm-up from where the filter was 0.5–1 s before
    /// (`EkfEngine::restart`); the warm-up a look opened is gone with it. Any other error
    /// is returned. The warm-up starts from
    /// the filter's covariance, which its own steps can leave indefinite by more than
    /// round-off: on a UR10 stand-in at 100 Hz (1 kg gripped) the warm-up's second opening
    /// after the grip met φᵀ·P·φ < −1/w 0.3 s later, and `prrrp track` stopped there with
    /// "recursive least squares diverged". Allocation-free.
    fn recover_warmup(&mut self, err: PrrrpError) -> Result<()> {
        let Engine::Ekf(e) = &mut self.engine else {
            return Err(err);
        };
        if !matches!(
            err,
            PrrrpError::Diverged { .. } | PrrrpError::NotPositiveDefinite { .. }
        ) {
            return Err(err);
        }
        e.restart(&mut self.theta, &self.scale, &mut self.gamma)?;
        self.guard.cancel();
        if let Some(tip) = &mut self.tip {
            tip.cancel();
        }
        self.after_step()
    }

    /// Takes the filtered row's accelerations into the cut-off's choice and, when it is
    /// made and lower, restarts the low-pass and the prediction's tracker there: no
    /// regression until they have settled, as after a gap. Allocation-free.
    fn choose_cutoff(&mut self, dt: f64) -> Result<()> {
        let Some(c) = &mut self.cutoff else {
            return Ok(());
        };
        c.filtered(dt, self.af.as_slice());
        if let Some(hz) = c.decide() {
            if hz < 0.95 * self.config.cutoff_hz {
                // All but the whole-arm EKF (see `build`).
                if self.config.method != OnlineMethod::Ekf || self.config.payload {
                    self.config.cutoff_hz = hz;
                    self.lp.set_cutoff(hz)?;
                }
                // The one-step-ahead prediction's tracker too, whose q̈ noise grows with
                // ω_c alike: on the Z1 of `cutoff`'s docs the predictions of the last 20 %
                // of the rows went from 134 / 4.5 / 14 / 12 % off on joints 1–4 to 31 /
                // 1.0 / 4.2 / 5.8 % (the model itself 0.9–2 % off on joints 2–4).
                self.kin.set_cutoff(hz)?;
            }
        }
        Ok(())
    }

    /// `model_var`: per joint κ·φ_jᵀ·P·φ_j at the filtered row, the variance of the
    /// a-priori error the estimate's own covariance P (before the row) predicts beyond the
    /// noise, κ the errors' correlation factor (P assumes white errors, see
    /// [`OnlineUpdate::sigma`]); zeros for the methods without a covariance.
    /// Allocation-free.
    fn model_variances(&mut self) -> Result<()> {
        self.model_var.fill(0.0);
        let unit = match &self.engine {
            Engine::Rls(_) => false,
            Engine::Ekf(e) if !e.running => false,
            // The running joint-state filter learns θ from its q, q̇ innovations, not from
            // these torque errors (its information per sample is bounded by the velocity
            // noise): a wide P_θθ after an opening silenced the re-alarm that re-opens it,
            // and it ended 38–70 % off on the three of four Panda-like logs (from no
            // knowledge) that end within 3 % with the noise-only test. It keeps that test.
            Engine::Ekf(_) => return Ok(()),
            Engine::PayloadEkf(_) => true,
            Engine::Adaline(_) | Engine::Hopfield(_) => return Ok(()),
        };
        self.model
            .regressor_into(&mut self.mws, &self.qf, &self.vf, &self.af, &mut self.phi)?;
        // The RLS runs on γ = θ/scale: its regressor columns are φ_θ·scale.
        if !unit {
            for (c, s) in self.scale.iter().enumerate() {
                self.phi.column_mut(c).scale_mut(*s);
            }
        }
        let (phi, out) = (&self.phi, &mut self.model_var);
        match &mut self.engine {
            Engine::Rls(r) => r.row_variances(phi, out)?,
            Engine::Ekf(e) => e.rls.row_variances(phi, out)?,
            Engine::PayloadEkf(e) => quad_rows(phi, out, |i, j| e.covariance(i, j)),
            Engine::Adaline(_) | Engine::Hopfield(_) => {}
        }
        let kappa = self.correlation.factor();
        for v in &mut self.model_var {
            *v *= kappa;
        }
        Ok(())
    }

    /// One estimator step with this row (kinematics ready).
    fn step_engine(&mut self, dt: f64) -> Result<()> {
        let (nu, forgetting) = self.forgetting(dt);
        for j in 0..self.n {
            let v = match &self.detector {
                Some(d) => d.variances()[j],
                None => self.noise.variances()[j],
            };
            // A joint whose torque has been exactly 0 in every row so far, while others
            // deliver (a dead channel), has no scale for its noise (its floor is 0 too):
            // weighted 1/1e-300, its equation would overflow the estimator. It is left
            // out until its torque moves.
            self.weights[j] = if self.tau_max[j] > 0.0 {
                1.0 / v.max(self.floor[j])
            } else {
                0.0
            };
        }
        // The inverse-model estimators regress τ − τ_arm in payload mode (the model is
        // affine there, see `tracked`).
        self.model
            .arm_torque_into(&mut self.mws, &self.qf, &self.vf, &self.af, &mut self.tr)?;
        self.tr.neg_mut();
        self.tr += &self.tf;
        let sample = SampleOf::new(&self.qf, &self.vf, &self.af, &self.tr);
        // During a look the estimator waits and is what the identifier reports (`guard`):
        // its rows are a change or a spike the model cannot explain, and taking a spike in
        // (weighted by the small noise level) moved the estimate: 23 % off on the UR5's
        // wrist after a 60 ms, 2 N·m spike 0.2 s before the end of the log, 1.6 % without
        // the spike or frozen. Two copies, one opened, take the rows instead. The running
        // EKF goes on (it follows q and q̇).
        let frozen = self.guard.active();
        match &mut self.engine {
            Engine::Rls(_) | Engine::PayloadEkf(_) if frozen => {}
            Engine::Rls(r) => {
                r.update_weighted(sample, &self.weights, forgetting)?;
            }
            Engine::Adaline(a) => {
                a.step(sample)?;
            }
            Engine::Hopfield(h) => {
                h.step(sample)?;
            }
            Engine::PayloadEkf(e) => {
                e.update(
                    &self.model,
                    &self.qf,
                    &self.vf,
                    &self.af,
                    &self.tr,
                    &self.weights,
                    dt,
                    nu,
                )?;
            }
            Engine::Ekf(e) => {
                if !e.running {
                    if !frozen {
                        e.rls.update_weighted(sample, &self.weights, forgetting)?;
                    }
                    e.warm_for += dt;
                    self.gamma.copy_from(e.rls.estimate());
                    self.theta.copy_from(&self.gamma);
                    self.theta.component_mul_assign(&self.scale);
                    // M(q, θ̂) at this sample: the filter may start from θ̂ once it has
                    // been positive definite for a while.
                    let ok = self
                        .model
                        .forward_dynamics_into(
                            &mut e.ws,
                            &self.qf,
                            &self.vf,
                            &self.tf,
                            &self.theta,
                            &mut e.f0,
                        )
                        .is_ok();
                    e.definite_for = if ok { e.definite_for + dt } else { 0.0 };
                    // Not during a look: the opened copy would then outlive its kept twin.
                    if e.warm_for >= self.config.ekf_warmup
                        && e.definite_for >= 0.5
                        && !self.guard.active()
                    {
                        // P₀ is the warm-up's own covariance, not widened by
                        // `prior_width` (a prior from another log): the filter goes on with
                        // the same data. Widened 3², its q, q̇ innovations (10⁴ times less
                        // information per row than the torque regression, and biased by
                        // what the model misses) pulled θ̂ from 2 % to 30–96 % off within
                        // seconds on the UR5 stand-in (docs/design/online.md).
                        let c = e.rls.covariance();
                        let p = self.theta.len();
                        let s = &self.scale;
                        let p0 = DMatrix::from_fn(p, p, |i, j| {
                            let v = c[(i, j)] * s[i] * s[j];
                            if i == j {
                                v.max(1e-300)
                            } else {
                                v
                            }
                        });
                        let p0 = (&p0 + p0.transpose()) * 0.5;
                        let theta = self.theta.clone();
                        match e.start(&theta, &p0, self.n) {
                            Err(PrrrpError::NotPositiveDefinite { .. }) => {
                                // Semidefinite only to round-off (a parameter the warm-up
                                // never had uncertainty on, directions its updates drove
                                // to 0; seen after two changes on an xArm 7 stand-in):
                                // floored, or else the warm-up goes on and the start is
                                // tried again later, never an error of the row.
                                let started = floored_covariance(e.rls.covariance(), &self.scale)
                                    .is_some_and(|p0| e.start(&theta, &p0, self.n).is_ok());
                                if !started {
                                    e.definite_for = 0.0;
                                }
                            }
                            other => other?,
                        }
                    }
                } else {
                    let var = match &self.detector {
                        Some(d) => d.variances(),
                        None => self.noise.variances(),
                    };
                    // A failure (out of the region where the filter's dynamics exist
                    // even after its own safeguards) goes back to the warm-up in
                    // `recover_warmup`.
                    e.step(&self.model, dt, &self.tf, var, nu)?;
                }
                if e.running {
                    e.keep(&self.qf, &self.vf, &self.af, &self.tf);
                }
            }
        }
        self.after_step()
    }

    /// Reads the estimate back, projects a payload onto the rigid bodies, refreshes the
    /// outputs.
    fn after_step(&mut self) -> Result<()> {
        match &self.engine {
            Engine::Rls(r) => self.gamma.copy_from(r.estimate()),
            Engine::Adaline(a) => self.gamma.copy_from(a.estimate()),
            Engine::Hopfield(h) => self.gamma.copy_from(h.estimate()),
            Engine::PayloadEkf(e) => {
                self.gamma.copy_from(e.estimate());
                self.gamma.component_div_assign(&self.scale);
            }
            Engine::Ekf(e) if !e.running => self.gamma.copy_from(e.rls.estimate()),
            Engine::Ekf(e) => {
                self.theta.copy_from(e.ekf.estimate());
                self.gamma.copy_from(&self.theta);
                self.gamma.component_div_assign(&self.scale);
            }
        }
        if !matches!(&self.engine, Engine::Ekf(e) if e.running) {
            for i in 0..self.theta.len() {
                self.theta[i] = self.gamma[i] * self.scale[i];
            }
        }
        if self.config.payload {
            // The output (and the predictions) is the nearest rigid body; the estimator
            // keeps its own unconstrained estimate. Writing the projection back into it
            // rectified the noise of every update at an empty gripper (π = 0 is the apex
            // of the cone of rigid bodies): the mass ratcheted up to 1.5 kg in 3 s of a
            // log without any payload.
            let mut pi = [0.0; PAYLOAD_PARAMS];
            pi.copy_from_slice(self.theta.as_slice());
            if project(&mut pi) {
                self.theta.copy_from_slice(&pi);
            }
        }
        self.refresh_outputs();
        Ok(())
    }

    /// The outputs (estimate, σ) from θ and the engine's covariance.
    fn refresh_outputs(&mut self) {
        self.out_estimate.copy_from_slice(self.theta.as_slice());
        self.has_sigma = true;
        match &self.engine {
            Engine::Rls(r) => {
                let c = r.covariance();
                for (k, v) in self.out_sigma.iter_mut().enumerate() {
                    let i = k;
                    *v = c[(i, i)].max(0.0).sqrt() * self.scale[i];
                }
            }
            Engine::Ekf(e) if !e.running => {
                let c = e.rls.covariance();
                for (k, v) in self.out_sigma.iter_mut().enumerate() {
                    let i = k;
                    *v = c[(i, i)].max(0.0).sqrt() * self.scale[i];
                }
            }
            Engine::PayloadEkf(e) => {
                for (k, v) in self.out_sigma.iter_mut().enumerate() {
                    *v = e.covariance(k, k).max(0.0).sqrt();
                }
            }
            Engine::Ekf(e) => {
                let p = e.ekf.covariance();
                let o = 2 * self.n;
                for (k, v) in self.out_sigma.iter_mut().enumerate() {
                    let i = o + k;
                    *v = p[(i, i)].max(0.0).sqrt();
                }
            }
            Engine::Adaline(_) | Engine::Hopfield(_) => self.has_sigma = false,
        }
        let inflate = self.correlation.factor().sqrt();
        for v in &mut self.out_sigma {
            *v *= inflate;
        }
    }

    /// The forgetting factor ν of a row `dt` s after the previous one, and its kind.
    fn forgetting(&self, dt: f64) -> (f64, Forgetting) {
        let nu = self.config.forgetting.map_or(1.0, |tc| (-dt / tc).exp());
        let f = if nu == 1.0 {
            Forgetting::None
        } else if self.config.directional {
            Forgetting::Directional(nu)
        } else {
            Forgetting::Exponential(nu)
        };
        (nu, f)
    }

    /// After an alarm: a copy of the estimator is opened and the look starts (`guard`);
    /// the estimator itself goes on unopened until the look confirms the change. The
    /// copy of a whole-arm RLS (or of the EKF's warm-up) opens along the tip link first
    /// (`open_rls`); the running EKF's copy is its RLS warm-up, started from the filter's
    /// estimate and P_θθ and opened the same way (`EkfEngine::warmup_from_filter`): the
    /// filter learns θ only from its q, q̇ innovations, too slowly to follow a grip
    /// (docs/design/online.md). `false` for the methods without a covariance (nothing to
    /// open). Allocation-free.
    fn begin_look(&mut self) -> Result<bool> {
        let Some(d) = &self.detector else {
            return Ok(false);
        };
        let var = d.variances();
        let k = self.config.open_factor;
        let scaled = (&self.cap, &self.scale);
        // Every direction after `PERSISTENT_DROPS` dropped tip looks, for the alarm that
        // follows them (the errors still up).
        let now = self.t_prev.unwrap_or(0.0);
        let escalate = self.high_drops >= PERSISTENT_DROPS
            && self
                .config
                .change_detection
                .is_some_and(|c| now - self.last_drop <= 2.0 * c.holdoff);
        // The first alarm within a hold-off of a change confirmed along the tip, whose
        // opened copy predicted the look's scored rows within the alarm level, opens along
        // the tip again instead of every direction: it fires at the first row the
        // hold-off allows, on a fast mean that still holds the errors of the estimator
        // that waited through the look, not those of the copy that replaced it. Opening
        // every direction there left the RLS 7.7 % off (median) 3 s after a grip on the
        // UR5 stand-ins, 3.1 % now (docs/design/online.md, "The alarm after a confirmed
        // grip").
        let (confirmed, opened_level) = self.last_confirm;
        let fresh = self
            .config
            .change_detection
            .is_some_and(|c| now - confirmed < c.holdoff && opened_level <= c.threshold);
        let tip = match &mut self.tip {
            Some(t) if escalate => {
                self.high_drops = 0;
                t.cancel();
                None
            }
            t => t.as_mut(),
        };
        self.tip_look = false;
        self.fresh_look = fresh;
        match &mut self.engine {
            Engine::Rls(r) => {
                let Some([o, kept]) = self.opened_rls.as_deref_mut() else {
                    return Ok(false);
                };
                kept.copy_state_from(r);
                o.copy_state_from(r);
                self.tip_look = open_rls(o, tip, fresh, var, k, scaled, &mut self.open)?;
            }
            Engine::Ekf(e) if !e.running => {
                let Some([o, kept]) = self.opened_rls.as_deref_mut() else {
                    return Ok(false);
                };
                kept.copy_state_from(&e.rls);
                o.copy_state_from(&e.rls);
                self.tip_look = open_rls(o, tip, fresh, var, k, scaled, &mut self.open)?;
            }
            Engine::Ekf(e) => {
                e.warmup_from_filter(self.n, &self.theta, &self.scale, &mut self.gamma)?;
                if let Some([_, kept]) = self.opened_rls.as_deref_mut() {
                    kept.copy_state_from(&e.rls);
                }
                self.tip_look = open_rls(&mut e.rls, tip, fresh, var, k, scaled, &mut self.open)?;
            }
            Engine::PayloadEkf(e) => {
                let Some([o, kept]) = self.opened_payload.as_deref_mut() else {
                    return Ok(false);
                };
                kept.copy_state_from(e);
                o.copy_state_from(e);
                // The cap is the prior variance, 1 in the filter's units.
                for i in 0..self.open.len() {
                    self.open[i] = opening(k, 1.0, o.relative_variance(i));
                }
                o.scale_covariance(&self.open);
            }
            Engine::Adaline(_) | Engine::Hopfield(_) => return Ok(false),
        }
        self.guard.begin();
        Ok(true)
    }

    /// One row of a pending look: the opened copy takes the row, and both estimators'
    /// a-priori errors are scored (`guard`). On a confirmation the copy replaces the
    /// estimator (the running EKF hands over to its opened warm-up) and `true` is returned
    /// (the change is reported at this row); on a revert the copy is dropped.
    /// Allocation-free.
    fn look_row(&mut self, dt: f64) -> Result<bool> {
        if !self.guard.active() {
            return Ok(false);
        }
        let (nu, forgetting) = self.forgetting(dt);
        let sample = SampleOf::new(&self.qf, &self.vf, &self.af, &self.tr);
        let (rls, payload) = (
            self.opened_rls.as_deref_mut(),
            self.opened_payload.as_deref_mut(),
        );
        // Both copies take the row. The running EKF's warm-up (from the filter's estimate)
        // is its opened copy and an unopened copy of it the kept one: scored against the
        // filter's own innovations, the warm-up won after each restart and the filter
        // handed over again and again (arms 0-7 of test_online_realistic.py, 3 s after a
        // grip: worst 27.7 % against 23.3 % now, median 16.7 % against 7.2 %).
        let (w, tr) = (&self.weights, &self.tr);
        let (e_kept, e_opened) = (&mut self.e_kept, &mut self.e_opened);
        let errors = |pred: &DVector<f64>, out: &mut Vec<f64>| {
            for (j, o) in out.iter_mut().enumerate() {
                *o = tr[j] - pred[j];
            }
        };
        match (&mut self.engine, rls, payload) {
            (Engine::Ekf(e), rls, _) if e.running => {
                e.rls.update_weighted(sample, w, forgetting)?;
                errors(e.rls.prediction(), e_opened);
                match rls {
                    Some([_, k]) => {
                        k.update_weighted(sample, w, forgetting)?;
                        errors(k.prediction(), e_kept);
                    }
                    None => e_kept.copy_from_slice(&self.resid),
                }
            }
            (Engine::Rls(_) | Engine::Ekf(_), Some([o, k]), _) => {
                o.update_weighted(sample, w, forgetting)?;
                errors(o.prediction(), e_opened);
                k.update_weighted(sample, w, forgetting)?;
                errors(k.prediction(), e_kept);
            }
            (Engine::PayloadEkf(_), _, Some([o, k])) => {
                let (q, qd, qdd) = (&self.qf, &self.vf, &self.af);
                o.update(&self.model, q, qd, qdd, tr, w, dt, nu)?;
                errors(o.prediction(), e_opened);
                k.update(&self.model, q, qd, qdd, tr, w, dt, nu)?;
                errors(k.prediction(), e_kept);
            }
            _ => {
                self.guard.cancel();
                return Ok(false);
            }
        }
        let (Some(d), Some(c)) = (&self.detector, self.config.change_detection) else {
            return Ok(false);
        };
        // The estimator that waits (all but the running EKF, which goes on) predicts each
        // row with the estimate the identifier reports: its errors are `resid`.
        let waits = !matches!(&self.engine, Engine::Ekf(e) if e.running);
        let verdict = self.guard.row(
            dt,
            self.t_prev.unwrap_or(0.0),
            &self.e_kept,
            &self.e_opened,
            waits.then_some(self.resid.as_slice()),
            d.variances(),
            &self.floor,
            c.holdoff,
            c.holdoff + c.noise_window,
        );
        let (rls, payload) = (self.opened_rls.as_deref(), self.opened_payload.as_deref());
        match verdict {
            Verdict::Wait => Ok(false),
            Verdict::Revert => {
                // The estimator resumes as it was at the alarm (it waited). Looks along the
                // tip dropped in a row while the kept estimator stayed above the alarm level
                // are a change the tip does not explain: the next alarm opens every
                // direction (`PERSISTENT_DROPS`).
                let level = self.guard.kept_level(self.n);
                let t = self.t_prev.unwrap_or(0.0);
                if self.tip_look && level > c.threshold {
                    self.high_drops = if t - self.last_drop <= 2.0 * c.holdoff {
                        self.high_drops + 1
                    } else {
                        1
                    };
                    self.last_drop = t;
                } else {
                    self.high_drops = 0;
                }
                if let Some(tip) = &mut self.tip {
                    tip.cancel();
                }
                Ok(false)
            }
            Verdict::Resume => {
                self.high_drops = 0;
                // The unopened copy took the look's rows as the estimator would have.
                // Reverting to the estimate of the alarm instead threw them away, and
                // while the errors stayed up alarm followed alarm: a PUMA 560 whose
                // estimate an opening had left 410 % off on the wrist stayed frozen there
                // for 3 s of dropped looks (tests/online.rs).
                match (&mut self.engine, rls, payload) {
                    (Engine::Ekf(e), Some([_, k]), _) if !e.running => e.rls.copy_state_from(k),
                    (Engine::Rls(r), Some([_, k]), _) => r.copy_state_from(k),
                    (Engine::PayloadEkf(e), _, Some([_, k])) => e.copy_state_from(k),
                    _ => {}
                }
                if let Some(tip) = &mut self.tip {
                    tip.cancel();
                }
                self.after_step()?;
                Ok(false)
            }
            Verdict::Confirm => {
                self.high_drops = 0;
                self.last_confirm = (
                    self.t_prev.unwrap_or(0.0),
                    if self.fresh_look || !self.tip_look {
                        f64::INFINITY
                    } else {
                        self.guard.opened_level(self.n)
                    },
                );
                match (&mut self.engine, rls, payload) {
                    (Engine::Ekf(e), _, _) if e.running => e.hand_to_warmup(),
                    (Engine::Ekf(e), Some([o, _]), _) => e.rls.copy_state_from(o),
                    (Engine::Rls(r), Some([o, _]), _) => r.copy_state_from(o),
                    (Engine::PayloadEkf(e), _, Some([o, _])) => e.copy_state_from(o),
                    _ => {}
                }
                self.changes += 1;
                self.after_step()?;
                Ok(true)
            }
        }
    }

    /// The second look after an opening along the tip (`tip::TipOpening::row`): every
    /// direction is opened when the errors have stayed up.
    fn second_look(&mut self, dt: f64) -> Result<()> {
        let (Some(tip), Some(d), Some(c)) =
            (&mut self.tip, &self.detector, self.config.change_detection)
        else {
            return Ok(());
        };
        let look = tip.row(
            dt,
            &self.resid,
            &self.floor,
            d.last(),
            d.settled(),
            c.holdoff,
            c.noise_window,
        );
        if look == Look::OpenAll {
            self.open_covariance()?;
        }
        Ok(())
    }

    /// Opens the covariance after a detected change: each parameter variance times
    /// `open_factor`, at most up to its cap (a congruence, so P stays positive
    /// semidefinite).
    fn open_covariance(&mut self) -> Result<()> {
        let k = self.config.open_factor;
        match &mut self.engine {
            Engine::Rls(r) => {
                let c = r.covariance();
                for i in 0..self.open.len() {
                    let cap = self.cap[i] / (self.scale[i] * self.scale[i]);
                    self.open[i] = opening(k, cap, c[(i, i)]);
                }
                r.scale_covariance(&self.open)?;
            }
            Engine::Ekf(e) if e.running => {
                let p = e.ekf.covariance();
                let o = 2 * self.n;
                for i in 0..self.open.len() {
                    let cap = self.cap[i].max(e.p0_diag[i]);
                    self.open[i] = opening(k, cap, p[(o + i, o + i)]);
                }
                e.ekf.scale_parameter_covariance(&self.open)?;
            }
            Engine::PayloadEkf(e) => {
                // The cap is the prior variance, 1 in the filter's units.
                for i in 0..self.open.len() {
                    self.open[i] = opening(k, 1.0, e.relative_variance(i));
                }
                e.scale_covariance(&self.open);
            }
            Engine::Ekf(e) => {
                let c = e.rls.covariance();
                for i in 0..self.open.len() {
                    let cap = self.cap[i] / (self.scale[i] * self.scale[i]);
                    self.open[i] = opening(k, cap, c[(i, i)]);
                }
                e.rls.scale_covariance(&self.open)?;
            }
            Engine::Adaline(_) | Engine::Hopfield(_) => {}
        }
        Ok(())
    }

    /// The current estimate as an [`IdentifiedModel`] (allocates): the base parameters
    /// with σ and covariance where the method has them, the running joint noise as
    /// `residual_rms`, method and settings (`"online": true`); in payload mode the prior's
    /// arm carrying the payload: β̂ = β_arm + K_tip·π̂ (the payload is the tip link's
    /// extra mass, so the arm with it is an arm of other base parameters), with
    /// [`OnlineIdentifier::payload_summary`] under `preprocessing.payload`.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] (field `estimate after N rows`) when no row has
    /// updated the estimate and there is no prior: the starting parameters are zeros, not
    /// a model (it was returned, with every torque predicted 0); as [`IdentifiedModel::new`]
    /// otherwise (e.g. a non-finite estimate).
    pub fn estimate(&self) -> Result<IdentifiedModel> {
        if self.updates == 0 && self.prior.is_none() {
            return Err(PrrrpError::InvalidParameter {
                field: format!("estimate after {} rows", self.rows),
                value: 0.0,
                reason: "no row has updated it yet (the causal filtering settles first, and \
                         rows without torque teach nothing); with no prior there is no model \
                         to give: feed more rows, or start from a prior",
            });
        }
        let cov_theta = self.covariance_theta();
        if let (TrackedModel::Payload { arm, k_tip, .. }, Some(prior)) = (&self.model, &self.prior)
        {
            // The arm with the payload is the arm's base parameters plus K_tip·π: a model
            // that predicts (and saves) like any other; its covariance adds the
            // payload's, K_tip·Σ_π·K_tipᵀ, to the prior's.
            let b = arm.len();
            let mut beta = DVector::zeros(b);
            self.model.beta_into(&self.theta, &mut beta);
            let mut cov = match &prior.covariance {
                Some(c) => DMatrix::from_row_slice(b, b, c),
                None => DMatrix::zeros(b, b),
            };
            if let Some(c) = &cov_theta {
                cov += k_tip * c * k_tip.transpose();
            }
            let cov = (&cov + cov.transpose()) * 0.5;
            let has_cov = prior.covariance.is_some() || cov_theta.is_some();
            let sigma = has_cov.then(|| (0..b).map(|i| cov[(i, i)].max(0.0).sqrt()).collect());
            let mut model = IdentifiedModel::new(
                &self.chain,
                &self.base,
                beta.as_slice().to_vec(),
                sigma,
                has_cov.then(|| cov.transpose().iter().copied().collect()),
                prior.cond,
                self.noise_rms(),
                self.config.method.name(),
                self.settings_json(),
                self.preprocessing_json(true),
            )?;
            model.robot = prior.robot.clone();
            return Ok(model);
        }
        let sigma = self.has_sigma.then(|| self.out_sigma.clone());
        let cov = cov_theta.map(|c| {
            let c = (&c + c.transpose()) * 0.5;
            c.transpose().iter().copied().collect::<Vec<f64>>()
        });
        IdentifiedModel::new(
            &self.chain,
            &self.base,
            self.out_estimate.clone(),
            sigma,
            cov,
            self.prior.as_ref().and_then(|p| p.cond),
            self.noise_rms(),
            self.config.method.name(),
            self.settings_json(),
            self.preprocessing_json(false),
        )
    }

    /// What a model from [`OnlineIdentifier::estimate`] records as its preprocessing:
    /// causal filtering of `rows` rows, and in payload mode the payload's summary.
    fn preprocessing_json(&self, with_payload: bool) -> serde_json::Value {
        let mut v = json!({
            "online": true,
            "causal_cutoff_hz": self.config.cutoff_hz,
            "rows": self.rows,
            "repeated_rows": self.repeated,
            "changes": self.changes,
            "dropped_alarms": self.guard.reverted(),
        });
        if with_payload {
            v["payload"] = json!(self.payload_summary());
        }
        v
    }

    /// In payload mode, the payload as load data (what `payload.json` holds, the shared
    /// [`crate::Payload`]'s JSON): `mass` (kg), `com` (m, in the tip link's frame),
    /// `inertia` about the centre of mass ([Ixx, Ixy, Iyy, Ixz, Iyz, Izz], kg·m², tip
    /// link axes), each with its σ, the 10 parameters π and their covariance, and
    /// `physical`; `None` outside payload mode. Allocates.
    pub fn payload_summary(&self) -> Option<serde_json::Value> {
        if !self.config.payload {
            return None;
        }
        let mut pi = [0.0; PAYLOAD_PARAMS];
        pi.copy_from_slice(self.theta.as_slice());
        let cov = self.covariance_theta().map(|c| {
            let c = (&c + c.transpose()) * 0.5;
            c.transpose().iter().copied().collect::<Vec<f64>>()
        });
        let link = self.chain.meta().links.last().cloned().unwrap_or_default();
        let mut v = summary_json(&link, self.n, &pi, cov);
        v["identification"] = json!({"method": self.config.method.name(), "online": true});
        Some(v)
    }

    /// The covariance of θ (θ units), where the method has one: the filter's own times
    /// the errors' correlation time κ (see [`OnlineUpdate::sigma`]).
    fn covariance_theta(&self) -> Option<DMatrix<f64>> {
        let p = self.theta.len();
        let s = &self.scale;
        let k = self.correlation.factor();
        let s = &(s * k.sqrt());
        match &self.engine {
            Engine::Rls(r) => {
                let c = r.covariance();
                Some(DMatrix::from_fn(p, p, |i, j| c[(i, j)] * s[i] * s[j]))
            }
            Engine::Ekf(e) if !e.running => {
                let c = e.rls.covariance();
                Some(DMatrix::from_fn(p, p, |i, j| c[(i, j)] * s[i] * s[j]))
            }
            Engine::Ekf(e) => {
                let o = 2 * self.n;
                Some(e.ekf.covariance().view((o, o), (p, p)).clone_owned() * k)
            }
            Engine::PayloadEkf(e) => Some(DMatrix::from_fn(p, p, |i, j| e.covariance(i, j) * k)),
            _ => None,
        }
    }

    /// The settings as JSON (recorded in [`IdentifiedModel::settings`]).
    pub fn settings_json(&self) -> serde_json::Value {
        let c = &self.config;
        let mut v = json!({
            "online": true,
            "method": c.method.name(),
            "payload": c.payload,
            "forgetting_s": c.forgetting,
            "forgetting": match (c.forgetting, c.directional, c.method) {
                (None, _, _) => "none",
                (Some(_), true, OnlineMethod::Rls) => "directional",
                _ => "exponential",
            },
            "cutoff_hz": c.cutoff_hz,
            "auto_cutoff": c.auto_cutoff,
            "prediction_cutoff_hz": self.kin.cutoff_hz(),
            "change_detection": c.change_detection.is_some(),
            "open_factor": c.open_factor,
            "prior_width": c.prior_width,
            "detected_changes": self.changes,
            "rows": self.rows,
            "updates": self.updates,
            "repeated_rows": self.repeated,
            "prior": self.prior.is_some(),
        });
        if let Some(d) = &c.change_detection {
            v["change_threshold"] = json!(d.threshold);
            v["change_window_s"] = json!(d.window);
            v["noise_window_s"] = json!(d.noise_window);
        }
        if let Engine::PayloadEkf(_) = &self.engine {
            v["ekf_state"] = json!("payload parameters (measurement: the residual of the arm)");
            v["payload_drift_per_sqrt_s"] = json!(super::payload_ekf::PAYLOAD_DRIFT);
        }
        if let Engine::Ekf(e) = &self.engine {
            v["ekf_running"] = json!(e.running);
            v["ekf_restarts"] = json!(e.restarts);
            if let Some(m) = self.projected {
                v["ekf_start"] = json!({
                    "from": "the physically consistent projection of the prior (its mass \
                             matrix was not positive definite)",
                    "max_relative_change": m,
                });
            }
            v["ekf_noise"] = json!(c.ekf_noise);
            v["ekf_warmup_s"] = json!(c.ekf_warmup);
            v["stiff_steps"] = json!(e.ekf.stiff_steps());
            v["damped_updates"] = json!(e.ekf.damped_updates());
            v["anchored_updates"] = json!(e.ekf.anchored_updates());
        }
        if let Some(cut) = &self.cutoff {
            v["cutoff_choice"] = cut.report();
        }
        v["sigma_correlation_factor"] = json!(self.correlation.factor());
        v["coulomb_scale"] = json!(self.chain.friction().coulomb_smoothing);
        if let Some(s) = &self.search {
            v["coulomb_search"] = s.scores.report(s.chosen);
            // Whose one-step-ahead errors ranked the scales (`Search::scorers`).
            v["coulomb_search"]["scored_by"] = json!("rls");
        }
        v
    }
}

/// `out[j]` = φ_jᵀ·C·φ_j (≥ 0) for each row φ_j of `phi`, C symmetric given by its entries
/// `cov(i, j)` (each off-diagonal pair read once).
fn quad_rows(phi: &DMatrix<f64>, out: &mut [f64], cov: impl Fn(usize, usize) -> f64) {
    let p = phi.ncols();
    for (j, v) in out.iter_mut().enumerate() {
        let mut acc = 0.0;
        for b in 0..p {
            let fb = phi[(j, b)];
            if fb == 0.0 {
                continue;
            }
            let mut col = 0.5 * cov(b, b) * fb;
            for a in b + 1..p {
                col += cov(a, b) * phi[(j, a)];
            }
            acc += 2.0 * fb * col;
        }
        *v = acc.max(0.0);
    }
}

/// The tip opening of a whole-arm RLS (or the EKF's warm-up) by `k`, noise variances
/// `var`; `false` if it could not be prepared (the caller opens every direction).
fn open_rls_tip(
    rls: &mut DynRls<DynScaledModel<TrackedModel>>,
    tip: &mut TipOpening,
    k: f64,
    var: &[f64],
) -> Result<bool> {
    if tip.prepare(rls.covariance(), k, var) {
        rls.add_covariance(tip.increment())?;
        Ok(true)
    } else {
        Ok(false)
    }
}

/// After this many looks along the tip link dropped in a row (each within two hold-offs of
/// the last, 1.5 s of errors by default) with the kept estimator above the detector's alarm
/// level, the next alarm opens every direction. A burst the model cannot explain (friction
/// at a reversal, a spike) lasts less: on the UR5 stand-ins of test_online_realistic.py,
/// whose unmodelled Stribeck friction fires 11–20 false alarms per 30 s, at most two such
/// looks came in a row. A change elsewhere persists: a Panda-like arm whose joint 3's
/// friction quadrupled dropped 21 tip looks in a row at 11–150 times the noise and ended
/// 74 % off (tests/online.rs, docs/design/online.md).
const PERSISTENT_DROPS: u32 = 3;

/// Opens an RLS (a whole-arm RLS, the EKF's warm-up, or payload mode's RLS) after an
/// alarm: along the tip link's directions first when `tip` is given and no second look is
/// pending, else (or if the tip opening cannot be prepared) every direction by `k`
/// capped at `cap` (θ units; `scale`: θ = scale ⊙ γ). `open`: a scratch of one entry per
/// parameter. Returns whether the opening was along the tip. Allocation-free.
fn open_rls(
    rls: &mut DynRls<DynScaledModel<TrackedModel>>,
    tip: Option<&mut TipOpening>,
    fresh: bool,
    var: &[f64],
    k: f64,
    (cap, scale): (&DVector<f64>, &DVector<f64>),
    open: &mut DVector<f64>,
) -> Result<bool> {
    if let Some(tip) = tip {
        if tip.looking() && !fresh {
            tip.cancel();
        } else if open_rls_tip(rls, tip, k, var)? {
            return Ok(true);
        }
    }
    let c = rls.covariance();
    for i in 0..open.len() {
        open[i] = opening(k, cap[i] / (scale[i] * scale[i]), c[(i, i)]);
    }
    rls.scale_covariance(open)?;
    Ok(false)
}

/// Prior variances of a payload's 10 parameters (kg², (kg·m)², (kg·m²)²): mass σ
/// `payload_mass_std`, first moments σ·size, inertia σ·size².
fn payload_prior_variances(config: &OnlineConfig) -> [f64; PAYLOAD_PARAMS] {
    let (ms, l) = (config.payload_mass_std, config.payload_size);
    let mut var = [0.0; PAYLOAD_PARAMS];
    var[0] = ms * ms;
    for v in &mut var[1..4] {
        *v = (ms * l).powi(2);
    }
    for v in &mut var[4..] {
        *v = (ms * l * l).powi(2);
    }
    var
}

/// Relative floor of [`floored_covariance`]'s eigenvalues (of the largest).
const COVARIANCE_EIGEN_FLOOR: f64 = 1e-12;

/// The parameter covariance S·C·S (θ units) of a covariance `c` in scaled units with the
/// eigenvalues of its symmetric part floored at [`COVARIANCE_EIGEN_FLOOR`] times the
/// largest: positive definite where `c` is only semidefinite, or indefinite by round-off.
/// None when `c` has no positive, finite eigenvalue. Allocates (a start, not a row).
fn floored_covariance(c: &DMatrix<f64>, scale: &DVector<f64>) -> Option<DMatrix<f64>> {
    let eig = ((c + c.transpose()) * 0.5).try_symmetric_eigen(f64::EPSILON, 0)?;
    let top = eig.eigenvalues.max();
    if !(top.is_finite() && top > 0.0) {
        return None;
    }
    let floor = COVARIANCE_EIGEN_FLOOR * top;
    let lam = eig.eigenvalues.map(|v| v.max(floor));
    let v = &eig.eigenvectors;
    let mut p0 = v * DMatrix::from_diagonal(&lam) * v.transpose();
    for j in 0..p0.ncols() {
        for i in 0..p0.nrows() {
            p0[(i, j)] *= scale[i] * scale[j];
        }
    }
    Some((&p0 + p0.transpose()) * 0.5)
}

/// The factor d (on σ) that multiplies a variance `var` by `k`, at most up to `cap`.
fn opening(k: f64, cap: f64, var: f64) -> f64 {
    // NaN-safe: a NaN variance or cap opens nothing.
    if var.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
        || cap.partial_cmp(&var) != Some(std::cmp::Ordering::Greater)
    {
        return 1.0;
    }
    (k.min(cap / var)).sqrt().max(1.0)
}

impl EkfEngine {
    /// Starts the filter at θ₀ with parameter covariance `p0` (θ units).
    fn start(&mut self, theta0: &DVector<f64>, p0: &DMatrix<f64>, n: usize) -> Result<()> {
        let p = theta0.len();
        let s = 2 * n + p;
        self.ekf.reset();
        self.ekf.set_parameter_estimate(theta0)?;
        let c = *self.ekf_config();
        let mut full = DMatrix::zeros(s, s);
        for i in 0..n {
            full[(i, i)] = c.initial_position_std.powi(2);
            full[(n + i, n + i)] = c.initial_velocity_std.powi(2);
        }
        full.view_mut((2 * n, 2 * n), (p, p)).copy_from(p0);
        let full = (&full + full.transpose()) * 0.5;
        self.ekf.set_initial_covariance(&full)?;
        self.ekf.set_parameter_anchor(theta0)?;
        self.p0_diag = p0.diagonal();
        for m in &mut self.marks {
            m.copy_from(theta0);
        }
        self.mark_age = 0.0;
        self.p_start.copy_from(p0);
        self.running = true;
        self.has_prev = false;
        self.since_q = 0;
        Ok(())
    }

    fn ekf_config(&self) -> &EkfConfig {
        self.ekf.config()
    }

    /// Stores this row for the next step.
    fn keep(
        &mut self,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        tau: &DVector<f64>,
    ) {
        self.prev[0].copy_from(q);
        self.prev[1].copy_from(qd);
        self.prev[2].copy_from(qdd);
        self.prev[3].copy_from(tau);
        self.has_prev = true;
    }

    /// The RLS warm-up, reset, from the filter's estimate θ and its parameter covariance
    /// P_θθ (so that an opening keeps what the data said of the arm); the filter goes on
    /// until [`EkfEngine::hand_to_warmup`]. After a change the filter restarts from the
    /// warm-up's estimate after `ekf_warmup`: it learns θ only from its q, q̇ innovations,
    /// far more slowly than a regression on the torques (opened in place, along the tip or
    /// in every direction, it was 33–600 % off 3 s after a grip, docs/design/online.md).
    /// Allocation-free.
    fn warmup_from_filter(
        &mut self,
        n: usize,
        theta: &DVector<f64>,
        scale: &DVector<f64>,
        gamma: &mut DVector<f64>,
    ) -> Result<()> {
        self.reset_warmup(Some(n), theta, scale, gamma)
    }

    /// The warm-up RLS reset to the estimate θ (γ = θ/scale into `gamma`) and a parameter
    /// covariance: the filter's P_θθ now (`Some(n)`, its first 2N states q and q̇) or the
    /// one it started with (`None`). Allocation-free.
    fn reset_warmup(
        &mut self,
        now: Option<usize>,
        theta: &DVector<f64>,
        scale: &DVector<f64>,
        gamma: &mut DVector<f64>,
    ) -> Result<()> {
        self.rls.reset();
        gamma.copy_from(theta);
        gamma.component_div_assign(scale);
        self.rls.set_estimate(gamma)?;
        let (src, o) = match now {
            Some(n) => (self.ekf.covariance(), 2 * n),
            None => (&self.p_start, 0),
        };
        // P_γ = P/(sᵢ·sⱼ), written as an increment of the reset covariance.
        let (p, c) = (theta.len(), self.rls.covariance());
        for j in 0..p {
            for i in 0..p {
                let v = 0.5 * (src[(o + i, o + j)] + src[(o + j, o + i)]) / (scale[i] * scale[j]);
                self.handover[(i, j)] = v - c[(i, j)];
            }
        }
        self.rls.add_covariance(&self.handover)?;
        Ok(())
    }

    /// The filter stops; the warm-up RLS takes over (from its state as it is).
    fn hand_to_warmup(&mut self) {
        self.running = false;
        self.has_prev = false;
        self.warm_for = 0.0;
        self.definite_for = 0.0;
    }

    /// Back to the RLS warm-up after a failure of the filter: from its older mark (into
    /// `theta`, see [`MARK_PERIOD`]) and the covariance it started with, neither of which
    /// the steps that failed have touched. Its last estimate and covariance, or the
    /// warm-up's initial covariance, did worse: on an xArm 7 stand-in at 100 Hz
    /// (`python/tests/test_track_unseen_arm.py`) the last estimate, one wild step before
    /// the failure, left the warm-up 60 % off at the end, and the fresh RLS from the prior's
    /// widened covariance went from 4.7 % to 1600 % off within 0.1 s (the first rows of a
    /// regression that wide fit the noise along every direction the prior leaves open).
    /// Allocation-free.
    fn restart(
        &mut self,
        theta: &mut DVector<f64>,
        scale: &DVector<f64>,
        gamma: &mut DVector<f64>,
    ) -> Result<()> {
        self.restarts += 1;
        theta.copy_from(&self.marks[1]);
        self.hand_to_warmup();
        self.reset_warmup(None, theta, scale, gamma)
    }

    /// One filter step over the previous row, now that its period `dt` and the torque
    /// `tau_now` at its end are known: the interval's mean torque is the input (what
    /// moves the state to second order), the process noise is the torque noise `var`
    /// (per joint, units of τ²) through M⁻¹ (Q_q̇ = h²·M⁻¹·diag(var)·M⁻ᵀ, (h²/2)² of it on
    /// q), and forgetting ν a random walk of the parameters of variance (1/ν − 1)·P_θθ.
    fn step(
        &mut self,
        model: &TrackedModel,
        dt: f64,
        tau_now: &DVector<f64>,
        var: &[f64],
        nu: f64,
    ) -> Result<()> {
        if !self.has_prev {
            return Ok(());
        }
        let n = self.prev[0].len();
        self.ekf.set_dt(dt)?;
        self.held.copy_from(&self.prev[3]);
        self.held += tau_now;
        self.held *= 0.5;
        if self.since_q == 0 {
            let theta = self.ekf.estimate();
            let (q, qd) = (&self.prev[0], &self.prev[1]);
            // M⁻¹ column by column, exactly (q̈ is affine in τ); an indefinite M keeps the
            // last Q (the step itself then reports it).
            if model
                .forward_dynamics_into(&mut self.ws, q, qd, &self.held, theta, &mut self.f0)
                .is_ok()
            {
                for j in 0..n {
                    self.tau_j.copy_from(&self.held);
                    self.tau_j[j] += 1.0;
                    model.forward_dynamics_into(
                        &mut self.ws,
                        q,
                        qd,
                        &self.tau_j,
                        theta,
                        &mut self.f1,
                    )?;
                    for i in 0..n {
                        self.minv[(i, j)] = self.f1[i] - self.f0[i];
                    }
                }
                for i in 0..n {
                    self.qdd_var[i] = (0..n).map(|k| self.minv[(i, k)].powi(2) * var[k]).sum();
                }
            }
        }
        self.since_q = (self.since_q + 1) % Q_REFRESH;
        let h2 = dt * dt;
        for i in 0..n {
            self.qn[i] = (0.5 * h2).powi(2) * self.qdd_var[i];
            self.qn[n + i] = h2 * self.qdd_var[i];
        }
        let o = 2 * n;
        let p = self.qn.len() - o;
        let walk = 1.0 / nu - 1.0;
        {
            let cov = self.ekf.covariance();
            for i in 0..p {
                self.qn[o + i] = if walk > 0.0 {
                    walk * cov[(o + i, o + i)].max(0.0)
                } else {
                    0.0
                };
            }
        }
        self.ekf.set_process_noise(&self.qn)?;
        let sample = SampleOf::new(&self.prev[0], &self.prev[1], &self.prev[2], &self.held);
        self.ekf.step(sample)?;
        self.mark_age += dt;
        if self.mark_age >= MARK_PERIOD {
            let [newer, older] = &mut self.marks;
            std::mem::swap(newer, older);
            newer.copy_from(self.ekf.estimate());
            self.mark_age = 0.0;
        }
        Ok(())
    }
}

/// Seeded random states within the robot's limits, on which the parameters are
/// equilibrated (no data are needed, so the scaling is fixed before the first sample):
/// q uniform in the position limits (±π without), q̇ within half the speed limit (1 rad/s
/// without), q̈ within 5 rad/s², τ unused.
fn random_states(chain: &DynChain, seed: u64) -> [Vec<DVector<f64>>; 4] {
    let n = chain.dof();
    let mut s = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut uniform = |lo: f64, hi: f64| {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    };
    let info = chain.joint_info();
    let count = 256;
    let mut out: [Vec<DVector<f64>>; 4] = Default::default();
    for _ in 0..count {
        let mut q = DVector::zeros(n);
        let mut qd = DVector::zeros(n);
        let mut qdd = DVector::zeros(n);
        for j in 0..n {
            let l = info.get(j).map(|i| i.limit).unwrap_or_default();
            let (lo, hi) = if l.lower.is_finite() && l.upper.is_finite() && l.upper > l.lower {
                (l.lower, l.upper)
            } else {
                (-std::f64::consts::PI, std::f64::consts::PI)
            };
            q[j] = uniform(lo, hi);
            let v = if l.velocity.is_finite() && l.velocity > 0.0 {
                0.5 * l.velocity
            } else {
                1.0
            };
            qd[j] = uniform(-v, v);
            qdd[j] = uniform(-5.0, 5.0);
        }
        out[0].push(q);
        out[1].push(qd);
        out[2].push(qdd);
        out[3].push(DVector::zeros(n));
    }
    out
}

/// Whether M(q, θ) is positive definite at each of the random `states` (its forward
/// dynamics exist there).
fn definite_on(
    model: &TrackedModel,
    states: &[Vec<DVector<f64>>; 4],
    theta: &DVector<f64>,
) -> Result<bool> {
    let mut ws = model.workspace();
    let mut out = DVector::zeros(states[0].first().map_or(0, |q| q.len()));
    for ((q, qd), tau) in states[0].iter().zip(&states[1]).zip(&states[3]) {
        match model.forward_dynamics_into(&mut ws, q, qd, tau, theta, &mut out) {
            Ok(()) => {}
            Err(PrrrpError::NotPositiveDefinite { .. }) => return Ok(false),
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

/// Hopfield settings for online use on the equilibrated model: bound c well above the
/// torques the parameters explain, gain μ of the stability limit on the largest
/// regressor of the random states (twice it, for margin).
fn hopfield_config(
    scaled: &DynScaledModel<TrackedModel>,
    samples: &DynSamples<'_>,
    chain: &DynChain,
    gamma0: &DVector<f64>,
    mu: f64,
) -> Result<HopfieldConfig> {
    let (n, p) = scaled.dims();
    let mut ws = scaled.workspace();
    let mut phi = DMatrix::zeros(n.0, p.0);
    let mut frob: f64 = 0.0;
    for s in samples.iter() {
        scaled.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)?;
        frob = frob.max(phi.norm_squared());
    }
    let effort = chain
        .joint_info()
        .iter()
        .map(|i| i.limit.effort)
        .filter(|e| e.is_finite() && *e > 0.0)
        .fold(0.0, f64::max);
    let c = (4.0 * gamma0.amax()).max(if effort > 0.0 { 2.0 * effort } else { 1000.0 });
    Ok(HopfieldConfig {
        bound: c,
        beta: c * 2.0 * frob.max(f64::MIN_POSITIVE) / mu,
        dt: 1.0,
        stability_limit: 1.0,
        max_substeps: 64,
    })
}

/// The base-parameter analysis an identified model carries, as [`BaseParameters`] of its
/// chain.
pub(crate) fn base_of(model: &IdentifiedModel, chain: &DynChain) -> Result<BaseParameters> {
    let d = &model.base;
    let (b, p) = (d.independent.len(), d.standard_names.len());
    if chain.num_params() != p {
        return Err(PrrrpError::ShapeMismatch {
            what: "model base analysis".into(),
            expected: format!("{} standard parameters (the robot's)", chain.num_params()),
            got: format!("{p}"),
        });
    }
    let mut dependent: Vec<usize> = (0..p).filter(|j| !d.independent.contains(j)).collect();
    dependent.sort_unstable();
    Ok(BaseParameters {
        dof: chain.dof(),
        friction: chain.friction(),
        armature: d.standard_names.iter().any(|s| s.starts_with("Ia")),
        names: d.standard_names.clone(),
        independent: d.independent.clone(),
        dependent,
        unidentifiable: Vec::new(),
        map: faer::Mat::from_fn(b, p, |r, j| d.map[r * p + j]),
        combinations: d.combinations.clone(),
        pivots: Vec::new(),
        rank_tolerance: d.rank_tolerance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A covariance semidefinite to round-off, as an RLS leaves it (rank 4 of 6, one
    /// parameter it never had uncertainty on, an entry 1e-17 off symmetry), with
    /// parameter scales six decades apart: Cholesky refuses it, and the floored one is
    /// positive definite (its Cholesky factor exists in θ units) and within the floor of
    /// it in scaled units.
    #[test]
    fn floored_covariance_is_positive_definite_and_near() {
        let a = DMatrix::from_fn(6, 4, |i, j| {
            if i == 5 {
                0.0
            } else {
                ((i * 4 + j) as f64 * 0.7).sin()
            }
        });
        let mut c = &a * a.transpose();
        c[(0, 1)] += 1e-17;
        assert!(c.clone().cholesky().is_none());
        let scale = DVector::from_fn(6, |i, _| 10f64.powi(i as i32 - 3));
        let p0 = floored_covariance(&c, &scale).unwrap();
        assert!(p0.clone().cholesky().is_some());
        let top = c.symmetric_eigenvalues().max();
        for j in 0..6 {
            for i in 0..6 {
                let back = p0[(i, j)] / (scale[i] * scale[j]);
                assert!(
                    (back - c[(i, j)]).abs() <= 2.0 * COVARIANCE_EIGEN_FLOOR * top + 1e-15,
                    "({i}, {j}): {back} vs {}",
                    c[(i, j)]
                );
            }
        }
        assert!(floored_covariance(&DMatrix::zeros(3, 3), &DVector::repeat(3, 1.0)).is_none());
    }

    /// An RLS of the whole-arm EKF (here the warm-up, handed a covariance far from
    /// positive definite) that fails on a row sends the engine back to its warm-up from
    /// the filter's older mark, as a failure of the filter does: the row is taken, not
    /// refused with "recursive least squares diverged".
    #[test]
    fn a_failing_warmup_restarts_instead_of_failing_the_row() {
        use crate::test_support::puma;
        use crate::BaseOptions;
        let chain = puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let cfg = OnlineConfig {
            method: OnlineMethod::Ekf,
            ekf_warmup: 1.0,
            ..OnlineConfig::default()
        };
        let mut id = OnlineIdentifier::new(&chain, &base, cfg).unwrap();
        let row = |k: usize| {
            let t = k as f64 * 1e-3;
            // Two tones per joint, 1.5–7.7 rad/s.
            let w = |j: usize, m: usize| (1.5 + 0.4 * j as f64) * (1.0 + 1.7 * m as f64);
            let x = |j: usize, d: i32| -> f64 {
                (0..2)
                    .map(|m| {
                        let (a, ph) = (w(j, m), (j + 3 * m) as f64);
                        let s =
                            a.powi(d) * (a * t + ph + d as f64 * std::f64::consts::FRAC_PI_2).sin();
                        s / (1.0 + m as f64)
                    })
                    .sum()
            };
            let q: Vec<f64> = (0..6).map(|j| x(j, 0)).collect();
            let qd: Vec<f64> = (0..6).map(|j| x(j, 1)).collect();
            let qdd: Vec<f64> = (0..6).map(|j| x(j, 2)).collect();
            let tau = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
            (t, q, tau)
        };
        let mut k = 0;
        while !id.ekf_running() {
            let (t, q, tau) = row(k);
            id.update(t, &q, &tau, None).unwrap();
            k += 1;
            assert!(k < 20_000, "the filter never started");
        }
        for _ in 0..700 {
            let (t, q, tau) = row(k);
            id.update(t, &q, &tau, None).unwrap();
            k += 1;
        }
        let Engine::Ekf(e) = &mut id.engine else {
            unreachable!()
        };
        let mark = e.marks[1].clone();
        e.hand_to_warmup();
        let p = mark.len();
        e.rls
            .add_covariance(&DMatrix::from_diagonal_element(p, p, -1e9))
            .unwrap();
        let (t, q, tau) = row(k);
        id.update(t, &q, &tau, None).unwrap();
        assert_eq!(id.settings_json()["ekf_restarts"], 1);
        assert!(!id.ekf_running());
        let Engine::Ekf(e) = &id.engine else {
            unreachable!()
        };
        assert!(e.rls.covariance().iter().all(|v| v.is_finite()));
        // The restart's warm-up took this row from the mark.
        assert!((&id.theta - &mark).norm() <= 0.1 * mark.norm());
    }
}
