//! Extended Kalman filter on the parameter-augmented state (eqs. 21–29, 41–44).
//!
//! State x = [q (N), q̇ (N), λ (P)] (S = 2N + P; 18 for PRRRP), input τ, Euler
//! discretisation (eq. 43) of ẋ = [q̇, q̈(q, q̇, τ, λ), 0] (eq. 42):
//! ```text
//! q⁺ = q + h·q̇,   q̇⁺ = q̇ + h·q̈(q, q̇, τ, λ),   λ⁺ = λ
//! ```
//! with the Jacobians of [`LinearModel::forward_derivatives_into`] (analytic for PRRRP)
//! (A = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ = −M⁻¹Φ]). The measurement is the joint positions, or
//! positions and velocities; H selects entries of x.
//!
//! The step exploits that structure (≈ S²N + SN² multiply-adds instead of 2S³; the Joseph
//! update as a sub-block expansion) and keeps the stored P exactly symmetric. Design:
//! docs/design/ekf.md; timings: docs/online-speed.md.

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OMatrix, OVector, U1};

use super::estimator::Estimator;
use super::rls::{check_initial_covariance, check_lambda0};
use super::samples::{all_finite, SampleOf};
use crate::error::{PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{NDOF, NPARAM};
use crate::models::{ForwardDerivativesOf, LinearModel};

/// State dimension of the PRRRP filter: 5 positions, 5 velocities, 8 parameters.
pub const PRRRP_EKF_STATES: usize = 2 * NDOF + NPARAM;

/// The extended Kalman filter for the PRRRP arm.
pub type PrrrpEkf = Ekf<PrrrpModel, NDOF, NPARAM, PRRRP_EKF_STATES>;

/// What the filter measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EkfMeasurement {
    /// Joint positions q (the paper's choice).
    #[default]
    Positions,
    /// Joint positions q and velocities q̇.
    PositionsVelocities,
}

/// How the continuous dynamics ẋ = [q̇, q̈, 0] are discretised over one sample period h.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Discretisation {
    /// Explicit Euler, eq. 43: q⁺ = q + h·q̇, q̇⁺ = q̇ + h·q̈ (the paper's choice). Its
    /// second difference of q is h²·q̈_k, half a sample off the true h²·(q̈_k + q̈_k+1)/2,
    /// which biases λ̂ by O(h) (≈ 1 % on the small PRRRP parameters at 50 Hz).
    #[default]
    Euler,
    /// Adds the h²/2·q̈ term to the position: q⁺ = q + h·q̇ + h²/2·q̈, q̇⁺ = q̇ + h·q̈, exact
    /// when q̈ is constant over the sample (torque held by a zero-order hold). Same cost.
    SecondOrder,
    /// Explicit midpoint (RK2) for q̇, with q̈ and the Jacobian taken at the state half a
    /// period on, x_½ = (q + h/2·q̇ + h²/8·q̈₀, q̇ + h/2·q̈₀): q̇⁺ = q̇ + h·q̈_½, q⁺ = q + h·q̇ +
    /// h²/6·(q̈₀ + 2·q̈_½). With the interval's mean torque as input, q̇⁺ − q̇ is then right
    /// to O(h³) instead of O(h²): the other two evaluate M and n at the start of the
    /// interval, half a period off, which biases λ̂ by O(h) (3 % on the wrist inertia at
    /// 50 Hz on exact data). The covariance is propagated with F = I + h·B + h²/2-terms
    /// at x_½ (as [`Discretisation::SecondOrder`]). One forward dynamics more per step.
    Midpoint,
}

/// At which acceleration the transition Jacobian A = ∂q̈/∂x is evaluated.
///
/// The parameter columns ∂q̈/∂λ = −M⁻¹·Φ(q, q̇, q̈) depend on the acceleration. At the
/// filter's own prediction q̈ = M⁻¹(τ − n) they contain the noise of the measured torque
/// τ, the filter's input, and that same noise drives the innovation (q̇ is moved by
/// h·M⁻¹·δτ): a regressor whose noise is correlated with the equation error, an
/// errors-in-variables problem whose estimate is biased (Ljung 1979, "Asymptotic
/// behavior of the extended Kalman filter as a parameter estimator"). Evaluating A at an
/// acceleration that does not contain the current torque noise, the data's q̈ (from the
/// low-pass filtered positions, or measured), is the linearised Kalman filter about that
/// nominal trajectory for the Jacobian; the state is still propagated with the
/// prediction M⁻¹(τ − n). The parameter update then solves, at its fixed point,
/// Σ (M⁻¹Φ(q̈_data))ᵀ·W·M⁻¹(τ − Φ(q̈_data)·λ) = 0, the normal equations of (weighted)
/// least squares with the data's accelerations as instrument: consistent when q̈_data
/// is independent of the torque noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ParameterJacobian {
    /// A at the filter's predicted acceleration M⁻¹(τ − n) (the textbook EKF; default of
    /// the raw filters and the paper's study).
    #[default]
    Predicted,
    /// A at the sample's q̈ (the data's acceleration): τ_lin = τ_ID(q̂, q̂̇, q̈_data, λ̂) is
    /// formed and the derivatives taken at it, then q̈ is re-predicted from the measured τ.
    /// A sample whose q̈ is NaN or ∞ falls back to [`ParameterJacobian::Predicted`]. Costs
    /// an inverse and a forward dynamics more per step. Default of `identify(.., "ekf")`.
    DataAcceleration,
}

/// Settings of [`Ekf`]. The paper's eq. 44 cannot be used as printed (λ₀ = 1 makes M
/// singular in some configurations, P₀ = ones is singular, R has 18 entries for a
/// 5-dimensional measurement); these defaults are physically sized for a robot measured
/// by encoders at 50 Hz. Full matrices can be set with [`Ekf::set_initial_covariance`],
/// [`Ekf::set_process_noise`] and [`Ekf::set_measurement_noise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfConfig {
    /// Sample period h of the discretisation, s (default `0.02`, as the paper).
    pub dt: f64,
    /// Discretisation of the dynamics (default [`Discretisation::Euler`], eq. 43).
    pub discretisation: Discretisation,
    /// Measured quantities (default [`EkfMeasurement::Positions`]).
    pub measurement: EkfMeasurement,
    /// Standard deviation of the position measurement, m or rad (default `1e-3`). R =
    /// σ²·I. Also covers what the model misses per step: with 1e-4 the filter trusts the
    /// positions so much that a start 30 % off can be driven out of the physical region.
    pub position_noise: f64,
    /// Standard deviation of the velocity measurement, m/s or rad/s (default `1e-2`);
    /// used with [`EkfMeasurement::PositionsVelocities`].
    pub velocity_noise: f64,
    /// Process noise on q per step, m or rad (default `1e-6`): the Euler position update
    /// misses h²/2·q̈; most of that is absorbed by q̇, the rest is this noise.
    pub process_position_noise: f64,
    /// Process noise on q̇ per step, m/s or rad/s (default `1e-3`): unmodelled forces
    /// and the discretisation error in q̇ (≈ h²/2·q⃛).
    pub process_velocity_noise: f64,
    /// Random-walk standard deviation of λ per step, relative to |λ₀_i| (default `1e-5`).
    /// Eq. 42 makes λ constant (0 here); a little random walk keeps the filter from
    /// freezing on an early, linearisation-biased estimate (with 0 a start 30 % off can
    /// still be 5 % off after 3000 samples) at the price of a jitter of ≈ 0.3 % at 50 Hz.
    pub process_parameter_noise: f64,
    /// Initial standard deviation of q, m or rad (default `1e-3`).
    pub initial_position_std: f64,
    /// Initial standard deviation of q̇, m/s or rad/s (default `1.0`: with positions
    /// only, the starting velocity is unknown).
    pub initial_velocity_std: f64,
    /// Initial standard deviation of λ_i relative to |λ₀_i| (dimensionless, default
    /// `0.5`: "λ₀ is a guess within ±50 %"), floored at `initial_parameter_min_std`.
    pub initial_parameter_rel_std: f64,
    /// Floor of the initial λ standard deviation, units of λ (default `1e-3`), so that a
    /// λ₀_i = 0 still gets some uncertainty.
    pub initial_parameter_min_std: f64,
    /// Take the initial q (and q̇, when measured) from the first sample instead of zero
    /// (default `true`).
    pub init_from_first_measurement: bool,
    /// At which acceleration the Jacobian is linearised (default
    /// [`ParameterJacobian::Predicted`]).
    pub parameter_jacobian: ParameterJacobian,
}

impl Default for EkfConfig {
    fn default() -> Self {
        Self {
            dt: 0.02,
            discretisation: Discretisation::Euler,
            measurement: EkfMeasurement::Positions,
            position_noise: 1e-3,
            velocity_noise: 1e-2,
            process_position_noise: 1e-6,
            process_velocity_noise: 1e-3,
            process_parameter_noise: 1e-5,
            initial_position_std: 1e-3,
            initial_velocity_std: 1.0,
            initial_parameter_rel_std: 0.5,
            initial_parameter_min_std: 1e-3,
            init_from_first_measurement: true,
            parameter_jacobian: ParameterJacobian::Predicted,
        }
    }
}

/// The extended Kalman filter for a compile-time-size model with S = 2N + P states (S is
/// checked against N and P by [`EkfOf::new`]).
pub type Ekf<M, const N: usize, const P: usize, const S: usize> =
    EkfOf<M, Const<N>, Const<P>, Const<S>>;

/// The extended Kalman filter for a run-time-size model (e.g.
/// [`crate::DynChainBaseModel`]); the state dimension 2N + P follows from the model.
pub type DynEkf<M> = EkfOf<M, Dyn, Dyn, Dyn>;

/// Extended Kalman filter with S = 2N + P states, for N joints and P parameters given as
/// nalgebra dimensions (`Const` for [`Ekf`], `Dyn` for [`DynEkf`]): one implementation for
/// both, every buffer sized at construction, `step` allocation-free.
#[derive(Debug, Clone)]
pub struct EkfOf<M, N: Dim, P: Dim, S: Dim>
where
    M: LinearModel<N, P>,
    DefaultAllocator: EkfAllocator<N, P, S>,
{
    model: M,
    ws: M::Workspace,
    config: EkfConfig,
    x: OVector<f64, S>,
    p: OMatrix<f64, S, S>,
    lambda: OVector<f64, P>,
    x0: OVector<f64, S>,
    p0: OMatrix<f64, S, S>,
    q_diag: OVector<f64, S>,
    r_pos: OVector<f64, N>,
    r_vel: OVector<f64, N>,
    initialised: bool,
    samples: usize,
    skipped: usize,
    damped: usize,
    /// Whether the last prediction was stiff (see [`EkfOf::stiff_steps`]): the next step
    /// then takes its derivatives at the start of the interval, not half a period on.
    stiff: bool,
    stiff_steps: usize,
    stiff_handling: bool,
    /// A parameter vector known to be physical (e.g. the start), which an estimate that
    /// left the region where M(q, λ̂) ≻ 0 is pulled back towards; see
    /// [`EkfOf::set_parameter_anchor`].
    anchor: Option<OVector<f64, P>>,
    anchored: usize,
    /// Whether the CPU runs the AVX2 copy of the step (detected once, at construction).
    avx2: bool,
    /// Whether P is exactly symmetric entering the time update, which then mirrors only
    /// the rows it changes (those of q and q̇), and whether P₀ is.
    p_symmetric: bool,
    p0_symmetric: bool,
    /// Whether chain-sized states ask the model for ∂q̈/∂λ in factors (off only in tests,
    /// for the reference).
    use_factors: bool,
    buf: Buffers<N, P, S>,
}

/// How [`EkfOf::damped_candidate`] forms the candidate state for a gain times α: both
/// measurement updates and their covariance factors (positions measured?, velocities),
/// or x + α·step with the step in the buffers.
#[derive(Clone, Copy)]
enum CandidateForm<'a, N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    Combined(bool, Option<&'a OVector<f64, N>>),
    Step,
}

/// The allocator bounds of [`EkfOf`] in one name (nalgebra needs one per matrix shape).
pub trait EkfAllocator<N: Dim, P: Dim, S: Dim>:
    Allocator<N>
    + Allocator<P>
    + Allocator<S>
    + Allocator<N, N>
    + Allocator<N, P>
    + Allocator<N, S>
    + Allocator<S, N>
    + Allocator<S, S>
{
}

impl<N: Dim, P: Dim, S: Dim, T> EkfAllocator<N, P, S> for T where
    T: Allocator<N>
        + Allocator<P>
        + Allocator<S>
        + Allocator<N, N>
        + Allocator<N, P>
        + Allocator<N, S>
        + Allocator<S, N>
        + Allocator<S, S>
{
}

/// Per-step scratch, sized once: the gain of one measurement update (K, P_·z, S_z) and
/// what the covariance updates need.
#[derive(Debug, Clone)]
struct Buffers<N: Dim, P: Dim, S: Dim>
where
    DefaultAllocator: EkfAllocator<N, P, S>,
{
    fd: ForwardDerivativesOf<N, P>,
    q: OVector<f64, N>,
    v: OVector<f64, N>,
    lam: OVector<f64, P>,
    /// τ_ID(q̂, q̂̇, q̈_data, λ̂) of [`ParameterJacobian::DataAcceleration`].
    tau_lin: OVector<f64, N>,
    /// q̈ at the start of the interval ([`Discretisation::Midpoint`]).
    qdd_start: OVector<f64, N>,
    /// λ before a pull towards the anchor.
    lam_prior: OVector<f64, P>,
    innovation: OVector<f64, N>,
    /// N scratch of [`step_from_factor`].
    ytmp: OVector<f64, N>,
    k: OMatrix<f64, S, N>,
    damped_k: OMatrix<f64, S, N>,
    pz: OMatrix<f64, S, N>,
    d: OMatrix<f64, S, N>,
    g: OMatrix<f64, S, N>,
    /// A = ∂q̈/∂x = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ] (N×S), contiguous.
    a: OMatrix<f64, N, S>,
    sz: OMatrix<f64, N, N>,
    /// I − h·∂q̈/∂q̇, factorised in place, of a stiff step.
    implicit: OMatrix<f64, N, N>,
    chol: OMatrix<f64, N, N>,
    linv: OMatrix<f64, N, N>,
    sinv: OMatrix<f64, N, N>,
    apa: OMatrix<f64, N, N>,
    step: OVector<f64, S>,
    candidate: OVector<f64, S>,
    /// The position update's gain, P_·z, S_z, L⁻¹, prior-to-noise ratio and innovation,
    /// kept while the velocity update's are formed (measurement of q and q̇).
    k1: OMatrix<f64, S, N>,
    pz1: OMatrix<f64, S, N>,
    sz1: OMatrix<f64, N, N>,
    linv1: OMatrix<f64, N, N>,
    prior_to_noise1: f64,
    innovation1: OVector<f64, N>,
    /// Whether `k1` holds K₁ of the current position update.
    k1_ready: bool,
    /// The prior of two sequential updates of a small state, for a retry.
    x_prior: OVector<f64, S>,
    p_prior: OMatrix<f64, S, S>,
    /// max_j (H·P·Hᵀ)_jj / R_j of the last gain: how much the update cancels.
    prior_to_noise: f64,
    /// The covariance update's factors X and Y, P ← P − X·Yᵀ, with interleaved columns:
    /// [D₁, K'₁, D₂, …] and [K'₁, P_z₁, K'₂, …] for a Joseph update, W and W for the
    /// rank-N one, one update's after the other's (S×4N each at most), for the register
    /// tiles of [`joseph_columns`] and [`joseph_upper`].
    jx: Vec<f64>,
    jy: Vec<f64>,
    /// Whether Y = X (rank-N updates only), and `jy` is not written.
    jy_is_jx: bool,
    /// Whether the derivatives came factored (chain-sized states): ∂q̈/∂λ = −M⁻¹·Φ with Φ
    /// in `fd.dqdd_dlambda` and M⁻¹ in `minv`; see [`factored_time_products`].
    factored: bool,
    minv: OMatrix<f64, N, N>,
    /// [A_q, A_v, −M⁻¹] (N×3N) of a factored step (L⁻¹ times it when stiff).
    af: Vec<f64>,
    /// P_·λ·Φᵀ (S×N); the offsets in P and Φ of Φ's non-zero columns of a tile; the
    /// scratch of Φ·G_λ and A·G (see [`factored_time_products`]).
    xg: Vec<f64>,
    nz: Vec<(usize, usize)>,
    u: Vec<f64>,
}

impl<N: Dim, P: Dim, S: Dim> Buffers<N, P, S>
where
    DefaultAllocator: EkfAllocator<N, P, S>,
{
    fn new(n: N, p: P, s: S) -> Self {
        Self {
            fd: ForwardDerivativesOf::zeros(n, p),
            q: OVector::zeros_generic(n, U1),
            v: OVector::zeros_generic(n, U1),
            lam: OVector::zeros_generic(p, U1),
            tau_lin: OVector::zeros_generic(n, U1),
            qdd_start: OVector::zeros_generic(n, U1),
            lam_prior: OVector::zeros_generic(p, U1),
            innovation: OVector::zeros_generic(n, U1),
            ytmp: OVector::zeros_generic(n, U1),
            k: OMatrix::zeros_generic(s, n),
            damped_k: OMatrix::zeros_generic(s, n),
            pz: OMatrix::zeros_generic(s, n),
            d: OMatrix::zeros_generic(s, n),
            g: OMatrix::zeros_generic(s, n),
            a: OMatrix::zeros_generic(n, s),
            sz: OMatrix::zeros_generic(n, n),
            implicit: OMatrix::zeros_generic(n, n),
            chol: OMatrix::zeros_generic(n, n),
            linv: OMatrix::zeros_generic(n, n),
            sinv: OMatrix::zeros_generic(n, n),
            apa: OMatrix::zeros_generic(n, n),
            step: OVector::zeros_generic(s, U1),
            candidate: OVector::zeros_generic(s, U1),
            k1: OMatrix::zeros_generic(s, n),
            pz1: OMatrix::zeros_generic(s, n),
            sz1: OMatrix::zeros_generic(n, n),
            linv1: OMatrix::zeros_generic(n, n),
            prior_to_noise1: 0.0,
            k1_ready: false,
            innovation1: OVector::zeros_generic(n, U1),
            x_prior: OVector::zeros_generic(s, U1),
            p_prior: OMatrix::zeros_generic(s, s),
            prior_to_noise: 0.0,
            jx: vec![0.0; 4 * s.value() * n.value()],
            jy: vec![0.0; 4 * s.value() * n.value()],
            jy_is_jx: false,
            factored: false,
            minv: OMatrix::zeros_generic(n, n),
            af: vec![0.0; 3 * n.value() * n.value()],
            xg: vec![0.0; s.value() * n.value()],
            nz: vec![(0, 0); p.value()],
            u: vec![
                0.0;
                {
                    let (n, n4) = (n.value(), n.value().div_ceil(4) * 4);
                    (TILE_ROWS * n).max(n4 + 2 * n4 * n)
                }
            ],
        }
    }
}

/// a·b + c, fused when the caller is compiled with FMA (then one rounding), plain
/// otherwise (`mul_add` without hardware FMA is a slow library call). Every kernel's
/// `FMA = true` is the copy for a CPU with AVX2 and FMA: reached from `step_avx2`, or in
/// the tests behind [`cpu_has_avx2_fma`]; some of its loops are written with AVX2
/// intrinsics (`avx2`).
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Runs `kernel::<FMA, NC>(args…)` on the column tiles of a `d`-column output, NC the
/// tile's width as a constant, with `c0` (first column) and `skip` bound for the
/// arguments: tiles of TILE_COLS columns from column 0, the last one ending at column d
/// and overlapping its predecessor by `skip` columns, which it sums again (each column's
/// sums are its own, so the same values) and does not write; fewer than TILE_COLS columns
/// take one narrower tile. Every tile of a wider output has the full width: a narrow
/// tile's accumulators did not map onto whole vector registers (a 3-column tile took
/// 2.5× the time per multiply-add of a 4-column one). A macro, not a function taking a
/// closure: a closure may be compiled out of line, without the AVX2 and FMA of
/// `step_avx2`.
macro_rules! column_tiles {
    ($d:expr, |$c0:ident, $skip:ident| $kernel:ident::<$fma:ident>($($arg:expr),* $(,)?)) => {{
        const _: () = assert!(TILE_COLS == 4, "the arms below cover widths 1..TILE_COLS");
        let d: usize = $d;
        let ($c0, $skip) = (0usize, 0usize);
        match d {
            0 => {}
            1 => $kernel::<$fma, 1>($($arg),*),
            2 => $kernel::<$fma, 2>($($arg),*),
            3 => $kernel::<$fma, 3>($($arg),*),
            _ => {
                let mut next = 0;
                while next < d {
                    let $c0 = next.min(d - TILE_COLS);
                    let $skip = next - $c0;
                    $kernel::<$fma, TILE_COLS>($($arg),*);
                    next += TILE_COLS;
                }
            }
        }
    }};
}

fn cpu_has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// How often a measurement update is retried with half the gain before the step fails.
const MAX_GAIN_HALVINGS: u32 = 10;

fn size_error(what: &str, want: String, got: String) -> PrrrpError {
    PrrrpError::ShapeMismatch {
        what: what.into(),
        expected: want,
        got,
    }
}

impl<M, N: Dim, P: Dim, S: Dim> EkfOf<M, N, P, S>
where
    M: LinearModel<N, P>,
    DefaultAllocator: EkfAllocator<N, P, S>,
{
    /// A filter starting from λ₀ with the covariances of `config`.
    ///
    /// λ₀ must make M(q, λ₀) positive definite (e.g. a CAD estimate or a least-squares
    /// solution); the filter then refines it.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite dt, noise or
    /// initial standard deviation (process noises may be 0), or a non-finite λ₀;
    /// [`PrrrpError::ShapeMismatch`] if λ₀ does not have one entry per model parameter or
    /// a compile-time S is not 2N + P.
    pub fn new(model: M, lambda0: OVector<f64, P>, config: EkfConfig) -> Result<Self> {
        let c = &config;
        let positive = [
            ("dt", c.dt),
            ("position_noise", c.position_noise),
            ("velocity_noise", c.velocity_noise),
            ("initial_position_std", c.initial_position_std),
            ("initial_velocity_std", c.initial_velocity_std),
            ("initial_parameter_min_std", c.initial_parameter_min_std),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: name.into(),
                    value: v,
                    reason: "must be finite and > 0",
                });
            }
            // Squared into P and R: 1e-300 became a variance of 0, 1e300 one of inf.
            if name != "dt" && !(v * v).is_normal() {
                return Err(PrrrpError::InvalidParameter {
                    field: name.into(),
                    value: v,
                    reason: "must be between 1e-150 and 1e150 (it is squared into a variance)",
                });
            }
        }
        let non_negative = [
            ("process_position_noise", c.process_position_noise),
            ("process_velocity_noise", c.process_velocity_noise),
            ("process_parameter_noise", c.process_parameter_noise),
            ("initial_parameter_rel_std", c.initial_parameter_rel_std),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: name.into(),
                    value: v,
                    reason: "must be finite and >= 0",
                });
            }
        }
        let (nd, pd) = model.dims();
        let (n, np) = (nd.value(), pd.value());
        check_lambda0(&lambda0, n, np)?;
        let states = 2 * n + np;
        if let Some(s) = S::try_to_usize() {
            if s != states {
                return Err(size_error(
                    "EKF state dimension S",
                    format!("2N + P = {states}"),
                    format!("{s}"),
                ));
            }
        }
        let sd = S::from_usize(states);

        let mut x0 = OVector::<f64, S>::zeros_generic(sd, U1);
        x0.as_mut_slice()[2 * n..].copy_from_slice(lambda0.as_slice());
        let mut p0_diag = OVector::<f64, S>::zeros_generic(sd, U1);
        let mut q_diag = OVector::<f64, S>::zeros_generic(sd, U1);
        for i in 0..n {
            p0_diag[i] = c.initial_position_std.powi(2);
            p0_diag[n + i] = c.initial_velocity_std.powi(2);
            q_diag[i] = c.process_position_noise.powi(2);
            q_diag[n + i] = c.process_velocity_noise.powi(2);
        }
        for i in 0..np {
            let l = lambda0[i].abs();
            p0_diag[2 * n + i] = (c.initial_parameter_rel_std * l)
                .max(c.initial_parameter_min_std)
                .powi(2);
            q_diag[2 * n + i] = (c.process_parameter_noise * l).powi(2);
        }
        let p0 = OMatrix::from_diagonal(&p0_diag);
        Ok(Self {
            ws: model.workspace(),
            model,
            config,
            x: x0.clone(),
            p: p0.clone(),
            lambda: lambda0,
            x0,
            p0,
            q_diag,
            r_pos: OVector::repeat_generic(nd, U1, c.position_noise.powi(2)),
            r_vel: OVector::repeat_generic(nd, U1, c.velocity_noise.powi(2)),
            initialised: false,
            samples: 0,
            skipped: 0,
            damped: 0,
            stiff: false,
            stiff_steps: 0,
            stiff_handling: false,
            anchor: None,
            anchored: 0,
            avx2: cpu_has_avx2_fma(),
            p_symmetric: true,
            p0_symmetric: true,
            use_factors: true,
            buf: Buffers::new(nd, pd, sd),
        })
    }

    #[inline(always)]
    fn n(&self) -> usize {
        self.r_pos.nrows()
    }

    fn check_state_shape(&self, what: &str, rows: usize, cols: usize) -> Result<()> {
        let s = self.x.nrows();
        let want_cols = if cols == 1 { 1 } else { s };
        if rows != s || cols != want_cols {
            return Err(size_error(
                what,
                format!("{s}×{want_cols} (S = 2N + P states)"),
                format!("{rows}×{cols}"),
            ));
        }
        Ok(())
    }

    /// Replaces the initial covariance P₀ (and the current one, when no sample has been
    /// consumed since construction or reset). Units: the squares of the state's.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if P₀ is not S×S, [`PrrrpError::NonFinite`] for
    /// NaN/∞, [`PrrrpError::InvalidParameter`] if P₀ is not symmetric,
    /// [`PrrrpError::NotPositiveDefinite`] if it is not positive definite.
    pub fn set_initial_covariance(&mut self, p0: &OMatrix<f64, S, S>) -> Result<()> {
        self.check_state_shape("initial covariance", p0.nrows(), p0.ncols().max(2))?;
        check_initial_covariance(p0)?;
        self.p0.copy_from(p0);
        self.p0_symmetric = *p0 == p0.transpose();
        if self.samples == 0 {
            self.p.copy_from(p0);
            self.p_symmetric = self.p0_symmetric;
        }
        Ok(())
    }

    /// Replaces the process noise Q = diag(`variances`) (squares of the state units, per
    /// step).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `variances` does not have S entries,
    /// [`PrrrpError::InvalidParameter`] for a negative or non-finite variance.
    pub fn set_process_noise(&mut self, variances: &OVector<f64, S>) -> Result<()> {
        self.check_state_shape("process noise", variances.nrows(), 1)?;
        check_variances("process noise", variances.as_slice(), true)?;
        self.q_diag.copy_from(variances);
        Ok(())
    }

    /// Replaces the measurement noise R = diag(positions, velocities) (variances, squares
    /// of m, rad, m/s, rad/s).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if a vector does not have N entries,
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite variance.
    pub fn set_measurement_noise(
        &mut self,
        positions: &OVector<f64, N>,
        velocities: &OVector<f64, N>,
    ) -> Result<()> {
        let n = self.n();
        for (what, v) in [
            ("position noise", positions),
            ("velocity noise", velocities),
        ] {
            if v.nrows() != n {
                return Err(size_error(
                    what,
                    format!("{n} entries (one per joint)"),
                    format!("{} entries", v.nrows()),
                ));
            }
        }
        check_variances("position noise", positions.as_slice(), false)?;
        check_variances("velocity noise", velocities.as_slice(), false)?;
        self.r_pos.copy_from(positions);
        self.r_vel.copy_from(velocities);
        Ok(())
    }

    /// The settings (with the period of [`EkfOf::set_dt`]).
    pub fn config(&self) -> &EkfConfig {
        &self.config
    }

    /// The state x = [q, q̇, λ] predicted for the next sample.
    pub fn state(&self) -> &OVector<f64, S> {
        &self.x
    }

    /// The state covariance P (squares of the state units).
    pub fn covariance(&self) -> &OMatrix<f64, S, S> {
        &self.p
    }

    /// Standard deviation of each λ̂_i from the diagonal of P (units of λ).
    pub fn parameter_std(&self) -> OVector<f64, P> {
        let o = 2 * self.n();
        let (_, pd) = self.model.dims();
        OVector::from_fn_generic(pd, U1, |i, _| self.p[(o + i, o + i)].max(0.0).sqrt())
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Number of measurement updates skipped because a measurement was NaN or ∞.
    pub fn skipped_updates(&self) -> usize {
        self.skipped
    }

    /// Number of samples whose measurement update had to be damped (gain halved) to keep
    /// M(q, λ̂) positive definite.
    pub fn damped_updates(&self) -> usize {
        self.damped
    }

    /// Takes the time update linearly implicit whenever the dynamics are stiff at the
    /// sample period (see [`EkfOf::stiff_steps`]); off by default, which keeps the
    /// configured explicit discretisation at every step (the paper's filter).
    /// `identify(.., "ekf")` and the online identifier turn it on.
    pub fn set_stiff_handling(&mut self, on: bool) {
        self.stiff_handling = on;
    }

    /// Number of predictions taken linearly implicit ([`EkfOf::set_stiff_handling`])
    /// because the dynamics were stiff at the
    /// sample period: h·‖∂q̈/∂q̇‖∞ + h²·‖∂q̈/∂q‖∞ above 0.5 (`STIFF_LIMIT`). Viscous and
    /// smoothed Coulomb friction over a small inertia (a light wrist, a hobby arm) decay
    /// faster than one period, and an estimate near the edge of the physical region has
    /// modes faster than the sampling; the explicit step then amplifies them each sample
    /// and the filter diverged within a few dozen samples (an SO-100 at 100 Hz). The
    /// stiff step is the linearly implicit trapezoidal step of [q, q̇] (θ = ½;
    /// stable for every damping and stiffness, second order like the explicit step), with
    /// P propagated by its exact Jacobian.
    pub fn stiff_steps(&self) -> usize {
        self.stiff_steps
    }

    /// Sets an anchor λ_a, parameters whose M(q, λ_a) is positive definite at every
    /// configuration (a physically consistent estimate, every link a rigid body). When
    /// even the smallest damped gain leaves M(q, λ̂) indefinite at a sample (the prior λ̂
    /// itself has drifted out of the region at a new configuration), λ̂ is moved along the
    /// segment towards λ_a, by halving its distance until M is positive definite, instead
    /// of failing: M is linear in λ, so the region at one q is convex and the segment
    /// reaches it. Counted by [`EkfOf::anchored_updates`]. Without an anchor (default)
    /// such a sample is [`PrrrpError::Diverged`].
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a λ_a without one entry per parameter,
    /// [`PrrrpError::InvalidParameter`] for a non-finite entry.
    pub fn set_parameter_anchor(&mut self, anchor: &OVector<f64, P>) -> Result<()> {
        let (_, pd) = self.model.dims();
        check_lambda0(anchor, self.n(), pd.value())?;
        self.anchor = Some(anchor.clone());
        Ok(())
    }

    /// Sets the period h of the next prediction, s (a log's time stamps need not be
    /// uniform). Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite h.
    pub fn set_dt(&mut self, dt: f64) -> Result<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "dt".into(),
                value: dt,
                reason: "must be finite and > 0",
            });
        }
        self.config.dt = dt;
        Ok(())
    }

    /// Scales the parameter block of P by the congruence P ← D·P·D, D = diag(1 (q, q̇),
    /// `d` (λ)), d ≥ 0: the parameter covariance P_λλ by d_i·d_j, their covariance with
    /// q and q̇ by d_i; P stays positive semidefinite. Opens the parameters after a
    /// detected change of the dynamics. Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a `d` without one entry per parameter,
    /// [`PrrrpError::InvalidParameter`] for a negative or non-finite entry.
    pub fn scale_parameter_covariance(&mut self, d: &OVector<f64, P>) -> Result<()> {
        let (o, s) = (2 * self.n(), self.x.nrows());
        if d.nrows() != s - o {
            return Err(size_error(
                "parameter scale",
                format!("{} entries", s - o),
                format!("{} entries", d.nrows()),
            ));
        }
        crate::error::check_non_negative(
            "parameter scale",
            d.as_slice(),
            "must be finite and >= 0",
        )?;
        let f = |i: usize| if i < o { 1.0 } else { d[i - o] };
        for j in 0..s {
            let fj = f(j);
            for i in 0..s {
                self.p[(i, j)] *= f(i) * fj;
            }
        }
        Ok(())
    }

    /// Replaces the parameter part λ̂ of the state (e.g. by its projection onto a
    /// constraint set such as the rigid bodies); P is kept. Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] / [`PrrrpError::InvalidParameter`] as for λ₀.
    pub fn set_parameter_estimate(&mut self, lambda: &OVector<f64, P>) -> Result<()> {
        let (_, pd) = self.model.dims();
        check_lambda0(lambda, self.n(), pd.value())?;
        let n = self.n();
        self.x.as_mut_slice()[2 * n..].copy_from_slice(lambda.as_slice());
        self.lambda.copy_from(lambda);
        Ok(())
    }

    /// Number of samples at which λ̂ was pulled towards the anchor
    /// ([`EkfOf::set_parameter_anchor`]).
    pub fn anchored_updates(&self) -> usize {
        self.anchored
    }

    /// Moves λ of the state (the candidate buffer if `candidate`) towards the anchor until
    /// the derivatives exist: λ = λ_a + 2⁻ᵏ·(λ − λ_a), k = 1, 2, …, 30, then λ_a itself.
    fn pull_to_anchor(&mut self, candidate: bool, sample: SampleOf<'_, N>) -> Result<()> {
        let n = self.n();
        let Some(anchor) = self.anchor.take() else {
            return Err(PrrrpError::NotPositiveDefinite {
                what: "mass matrix M(q, λ̂) (no anchor set)",
            });
        };
        {
            let x = if candidate {
                &self.buf.candidate
            } else {
                &self.x
            };
            self.buf
                .lam_prior
                .as_mut_slice()
                .copy_from_slice(&x.as_slice()[2 * n..]);
        }
        let mut result = Err(PrrrpError::NotPositiveDefinite {
            what: "mass matrix M(q, λ_a) of the EKF's anchor",
        });
        for k in 1..=31 {
            let s = if k == 31 { 0.0 } else { 0.5f64.powi(k) };
            {
                let x = if candidate {
                    &mut self.buf.candidate
                } else {
                    &mut self.x
                };
                let lp = &self.buf.lam_prior;
                for (i, xi) in x.as_mut_slice()[2 * n..].iter_mut().enumerate() {
                    *xi = anchor[i] + s * (lp[i] - anchor[i]);
                }
            }
            result = self.derivatives(candidate, sample);
            if result.is_ok() {
                break;
            }
        }
        self.anchor = Some(anchor);
        self.anchored += usize::from(result.is_ok());
        result
    }

    /// The body of [`Estimator::step`], inlined into a portable and an AVX2 copy.
    #[inline(always)]
    fn step_impl<const FMA: bool>(&mut self, sample: SampleOf<'_, N>) -> Result<()> {
        let n = self.n();
        sample.check_len(n)?;
        if !all_finite(sample.tau) {
            return Err(PrrrpError::NonFinite {
                what: "tau".into(),
                row: None,
            });
        }
        let with_vel = self.config.measurement == EkfMeasurement::PositionsVelocities;
        if !self.initialised {
            if self.config.init_from_first_measurement {
                if all_finite(sample.q) {
                    self.x.as_mut_slice()[..n].copy_from_slice(sample.q.as_slice());
                }
                if with_vel && all_finite(sample.qd) {
                    self.x.as_mut_slice()[n..2 * n].copy_from_slice(sample.qd.as_slice());
                }
            }
            self.initialised = true;
        }
        let q_ok = all_finite(sample.q);
        let qd_ok = with_vel && all_finite(sample.qd);
        self.skipped += usize::from(!q_ok) + usize::from(with_vel && !qd_ok);
        // A posterior λ̂ that makes M(q, λ̂) indefinite (an overshoot of a large early gain)
        // is retried with the gain halved; the Joseph form keeps P exact for that gain. On
        // final failure the filter is left at its prior.
        let mut alpha = 1.0;
        let mut attempt = 0;
        if with_vel && self.x.nrows() <= ACC_ROWS {
            // Small states (PRRRP, payload mode): two sequential updates, keeping the
            // prior to retry both (a copy of an S×S of at most 32 states).
            self.buf.x_prior.copy_from(&self.x);
            self.buf.p_prior.copy_from(&self.p);
            loop {
                if q_ok {
                    self.update::<FMA>(0, sample.q, false, alpha)?;
                }
                if qd_ok {
                    self.update::<FMA>(n, sample.qd, true, alpha)?;
                }
                match self.derivatives(false, sample) {
                    Ok(()) => break,
                    Err(e) => {
                        self.x.copy_from(&self.buf.x_prior);
                        self.p.copy_from(&self.buf.p_prior);
                        if attempt == MAX_GAIN_HALVINGS || !(q_ok || qd_ok) {
                            if self.anchor.is_none() {
                                return Err(e);
                            }
                            // The prior itself is outside at this configuration.
                            self.pull_to_anchor(false, sample).map_err(|_| e)?;
                            break;
                        }
                    }
                }
                alpha *= 0.5;
                attempt += 1;
            }
        } else if with_vel {
            // Chain-sized states: two sequential updates (positions, then velocities), formed before P is
            // touched: the velocity gain needs only the velocity columns of P after the
            // position update (S×N), so the candidate state is checked first, and P is
            // updated once, by both, in one pass (no copy of P for a retry, one pass
            // over it instead of two).
            if q_ok {
                self.position_gain::<FMA>(sample.q)?;
            }
            let qd = qd_ok.then_some(sample.qd);
            // The factors carry the gain's α: P's update needs only `cols`.
            let form = CandidateForm::Combined(q_ok, qd);
            let (update, _, k, cols) = self.damped_candidate::<FMA>(sample, q_ok || qd_ok, form)?;
            attempt = k;
            if update {
                self.subtract_factors::<FMA>(cols);
            }
        } else {
            // One update: try the candidate state before touching P.
            if q_ok {
                let s = self.x.nrows();
                // Chain-sized states form K only for a Joseph update (`update_covariance`).
                let k = s <= ACC_ROWS;
                if k {
                    self.gain::<FMA>(0, false)?;
                } else {
                    self.buf
                        .pz
                        .as_mut_slice()
                        .copy_from_slice(&self.p.as_slice()[..n * s]);
                    self.innovation_factor(0, false)?;
                }
                let b = &mut self.buf;
                for i in 0..n {
                    b.innovation[i] = sample.q[i] - self.x[i];
                }
                if k {
                    b.step.gemv(1.0, &b.k, &b.innovation, 0.0);
                } else {
                    b.step.fill(0.0);
                    step_from_factor::<FMA>(
                        b.pz.as_slice(),
                        b.linv.as_slice(),
                        b.innovation.as_mut_slice(),
                        b.ytmp.as_mut_slice(),
                        1.0,
                        b.step.as_mut_slice(),
                        n,
                        s,
                    );
                }
            } else {
                self.buf.step.fill(0.0);
            }
            let (update, a, k, _) =
                self.damped_candidate::<FMA>(sample, q_ok, CandidateForm::Step)?;
            (alpha, attempt) = (a, k);
            if update {
                self.update_covariance::<FMA>(alpha);
            }
        }
        self.damped += usize::from(attempt > 0);
        self.lambda
            .as_mut_slice()
            .copy_from_slice(&self.x.as_slice()[2 * n..]);
        self.predict::<FMA>();
        if !(all_finite(&self.x) && self.p[(0, 0)].is_finite()) {
            return Err(PrrrpError::Diverged {
                what: "extended Kalman filter",
                at: self.samples,
                hint: "the state became non-finite: check the noise covariances and λ0",
            });
        }
        self.samples += 1;
        Ok(())
    }

    /// [`Self::step_impl`] compiled for AVX2 and FMA (wider vectors for the state-long
    /// columns, fused multiply-adds in the covariance products).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn step_avx2(&mut self, sample: SampleOf<'_, N>) -> Result<()> {
        self.step_impl::<true>(sample)
    }

    /// Gain of a measurement z = x[o..o+N] + noise of variances R (H a selection), into
    /// the buffers: S_z = P_zz + R, K = P_·z·S_z⁻¹.
    #[inline(always)]
    fn gain<const FMA: bool>(&mut self, o: usize, velocity: bool) -> Result<()> {
        let (n, s) = (self.n(), self.x.nrows());
        self.buf
            .pz
            .as_mut_slice()
            .copy_from_slice(&self.p.as_slice()[o * s..(o + n) * s]);
        self.gain_from_pz::<FMA>(o, velocity)
    }

    /// [`Self::gain`] with P_·z (S×N, the columns o..o+N of P) in the buffers already.
    #[inline(always)]
    fn gain_from_pz<const FMA: bool>(&mut self, o: usize, velocity: bool) -> Result<()> {
        self.innovation_factor(o, velocity)?;
        let (n, s) = (self.n(), self.x.nrows());
        let b = &mut self.buf;
        gain_from_factor::<FMA, _, _>(b.pz.as_slice(), &b.linv, &mut b.sinv, &mut b.k, n, s);
        Ok(())
    }

    /// S_z = P_zz + R of a measurement z = x[o..o+N] + noise of variances R, with P_·z in
    /// the buffers, its Cholesky factor L, L⁻¹ and the prior-to-noise ratio; not the
    /// gain, which chain-sized states form only for a Joseph update (the state's step is
    /// P_·z·(S_z⁻¹·ν), S·N multiply-adds instead of S·N² for K, see [`step_from_factor`]).
    #[inline(always)]
    fn innovation_factor(&mut self, o: usize, velocity: bool) -> Result<()> {
        let n = self.n();
        let r = if velocity { &self.r_vel } else { &self.r_pos };
        let b = &mut self.buf;
        b.prior_to_noise = 0.0;
        for j in 0..n {
            for i in 0..n {
                b.sz[(i, j)] = b.pz[(o + i, j)];
            }
            b.prior_to_noise = b.prior_to_noise.max(b.sz[(j, j)] / r[j]);
            b.sz[(j, j)] += r[j];
        }
        if !cholesky(b.sz.as_slice(), n, b.chol.as_mut_slice()) {
            return Err(PrrrpError::NotPositiveDefinite {
                what: "EKF innovation covariance H·P·Hᵀ + R",
            });
        }
        lower_triangular_inverse(b.chol.as_slice(), n, b.linv.as_mut_slice());
        Ok(())
    }

    /// Joseph-form covariance update for the gain α·K of the buffers: with K' = α·K and
    /// D = P_·z − K'·S_z (≈ 0 for α = 1), P ← P − K'·P_z· − D·K'ᵀ. Exact for any gain, so
    /// also for a damped one.
    #[inline(always)]
    fn update_covariance<const FMA: bool>(&mut self, alpha: f64) {
        let (n, s) = (self.n(), self.x.nrows());
        let b = &mut self.buf;
        let rank_n = rank_n_form(alpha, s, b.prior_to_noise);
        if s > ACC_ROWS && !rank_n {
            // Chain-sized states leave K to the Joseph form (see `innovation_factor`).
            gain_from_factor::<FMA, _, _>(b.pz.as_slice(), &b.linv, &mut b.sinv, &mut b.k, n, s);
        }
        if alpha != 1.0 {
            b.damped_k.copy_from(&b.k);
            b.damped_k *= alpha;
        }
        if rank_n {
            // The optimal gain at a chain's size: P ← P − W·Wᵀ with W = P_·z·L⁻ᵀ (S_z =
            // L·Lᵀ), the symmetric rank-N form of P − K·S_z·Kᵀ, on the upper triangle: half
            // the multiply-adds of the Joseph form. Justified because K is not an
            // approximation here but P_·z·S_z⁻¹ formed from this same P in this step, so the
            // Joseph form's first-order insensitivity to gain errors buys nothing; the
            // rounding of the subtraction is ε·P_ii·(P_zz/R) at most (a few digits of 16
            // for prior-to-noise ratios up to RANK_N_MAX_PRIOR_TO_NOISE; beyond, e.g. on
            // exact data, the cancellation loses definiteness and the Joseph form below
            // is used). Entry (i, j) and (j, i) sum the same exact products W_im·W_jm in
            // the same order, so the upper triangle mirrored as written gives the bits of
            // whole columns ([`minus_w_wt`]) in half the multiply-adds. A damped gain keeps
            // the Joseph form below.
            w_from_pz::<FMA>(b.pz.as_slice(), b.linv.as_slice(), b.d.as_mut_slice(), n, s);
            let w = b.d.as_slice();
            joseph_upper::<FMA>(w, w, self.p.as_mut_slice(), n, s);
            return;
        }
        let k = if alpha == 1.0 { &b.k } else { &b.damped_k };
        // Whole columns (small states) leave the triangles differing by rounding.
        self.p_symmetric &= s > ACC_ROWS;
        b.d.copy_from(&b.pz);
        minus_k_sz::<FMA>(k.as_slice(), b.sz.as_slice(), b.d.as_mut_slice(), n, s);
        joseph_columns::<FMA>(
            k.as_slice(),
            b.d.as_slice(),
            b.pz.as_slice(),
            self.p.as_mut_slice(),
            n,
            s,
            (&mut b.jx, &mut b.jy),
        );
        // Whole columns: the two triangles now differ by rounding, and the prediction
        // that always follows mirrors its upper triangle, so the stored P is exactly
        // symmetric. The upper triangle (larger states) comes mirrored already: the next
        // gain and the prediction read whole columns.
    }

    /// Full measurement update (state and covariance) with the gain α·K.
    #[inline(always)]
    fn update<const FMA: bool>(
        &mut self,
        o: usize,
        z: &OVector<f64, N>,
        velocity: bool,
        alpha: f64,
    ) -> Result<()> {
        self.gain::<FMA>(o, velocity)?;
        let n = self.n();
        let b = &mut self.buf;
        for i in 0..n {
            b.innovation[i] = z[i] - self.x[o + i];
        }
        self.x.gemv(alpha, &b.k, &b.innovation, 1.0);
        self.update_covariance::<FMA>(alpha);
        Ok(())
    }

    /// Gain and innovation of the position measurement z into the `…1` buffers (the
    /// first of two sequential updates).
    #[inline(always)]
    fn position_gain<const FMA: bool>(&mut self, z: &OVector<f64, N>) -> Result<()> {
        let (n, s) = (self.n(), self.x.nrows());
        self.buf
            .pz
            .as_mut_slice()
            .copy_from_slice(&self.p.as_slice()[..n * s]);
        self.innovation_factor(0, false)?;
        let b = &mut self.buf;
        // K₁ is formed only if a Joseph update needs it (`candidate_and_factors`).
        b.k1_ready = false;
        std::mem::swap(&mut b.pz, &mut b.pz1);
        std::mem::swap(&mut b.sz, &mut b.sz1);
        std::mem::swap(&mut b.linv, &mut b.linv1);
        b.prior_to_noise1 = b.prior_to_noise;
        for i in 0..n {
            b.innovation1[i] = z[i] - self.x[i];
        }
        Ok(())
    }

    /// The candidate state after the position update with gain α·K₁ (of
    /// [`Self::position_gain`], if `positions`) and then the velocity update with α·K₂
    /// (if `velocities` are given), K₂ from the velocity columns of P after the first
    /// update; the factors of both covariance updates into `jx`, `jy` (their column
    /// count returned), P untouched.
    #[inline(always)]
    fn candidate_and_factors<const FMA: bool>(
        &mut self,
        positions: bool,
        velocities: Option<&OVector<f64, N>>,
        alpha: f64,
    ) -> Result<usize> {
        let (n, s) = (self.n(), self.x.nrows());
        let b = &mut self.buf;
        b.candidate.copy_from(&self.x);
        let mut cols = 0;
        b.jy_is_jx = true;
        if positions {
            if !rank_n_form(alpha, s, b.prior_to_noise1) && !b.k1_ready {
                gain_from_factor::<FMA, _, _>(
                    b.pz1.as_slice(),
                    &b.linv1,
                    &mut b.sinv,
                    &mut b.k1,
                    n,
                    s,
                );
                b.k1_ready = true;
            }
            b.ytmp.copy_from(&b.innovation1);
            step_from_factor::<FMA>(
                b.pz1.as_slice(),
                b.linv1.as_slice(),
                b.ytmp.as_mut_slice(),
                b.innovation.as_mut_slice(),
                alpha,
                b.candidate.as_mut_slice(),
                n,
                s,
            );
            cols = push_factors::<FMA>(
                (b.k1.as_slice(), b.pz1.as_slice(), b.sz1.as_slice()),
                rank_n_form(alpha, s, b.prior_to_noise1).then_some(b.linv1.as_slice()),
                alpha,
                (b.damped_k.as_mut_slice(), b.d.as_mut_slice()),
                (&mut b.jx, &mut b.jy, &mut b.jy_is_jx),
                0,
                (n, s),
            );
        }
        let Some(z) = velocities else {
            return Ok(cols);
        };
        // P's velocity columns after the first update, P_·v − Σ_k X_k·(Y_k)_vᵀ.
        let pv = &self.p.as_slice()[n * s..2 * n * s];
        let y = if b.jy_is_jx { &b.jx } else { &b.jy };
        minus_factor_rows::<FMA>((&b.jx, y), pv, b.pz.as_mut_slice(), cols, (n, s));
        self.innovation_factor(n, true)?;
        let b = &mut self.buf;
        if !rank_n_form(alpha, s, b.prior_to_noise) {
            gain_from_factor::<FMA, _, _>(b.pz.as_slice(), &b.linv, &mut b.sinv, &mut b.k, n, s);
        }
        for i in 0..n {
            b.innovation[i] = z[i] - b.candidate[n + i];
        }
        step_from_factor::<FMA>(
            b.pz.as_slice(),
            b.linv.as_slice(),
            b.innovation.as_mut_slice(),
            b.ytmp.as_mut_slice(),
            alpha,
            b.candidate.as_mut_slice(),
            n,
            s,
        );
        cols += push_factors::<FMA>(
            (b.k.as_slice(), b.pz.as_slice(), b.sz.as_slice()),
            rank_n_form(alpha, s, b.prior_to_noise).then_some(b.linv.as_slice()),
            alpha,
            (b.damped_k.as_mut_slice(), b.d.as_mut_slice()),
            (&mut b.jx, &mut b.jy, &mut b.jy_is_jx),
            cols,
            (n, s),
        );
        Ok(cols)
    }

    /// P ← P − X·Yᵀ with the `cols` factor columns of [`Self::candidate_and_factors`]
    /// (chain-sized states): the upper triangle in register tiles, each entry mirrored as
    /// written, so P stays exactly symmetric.
    #[inline(always)]
    fn subtract_factors<const FMA: bool>(&mut self, cols: usize) {
        let s = self.x.nrows();
        let b = &self.buf;
        let y = if b.jy_is_jx { &b.jx } else { &b.jy };
        joseph_upper::<FMA>(&b.jx, y, self.p.as_mut_slice(), cols, s);
    }

    /// The damped retry of a measurement update formed before P is touched: `form` writes
    /// the candidate state for the gain times α (and returns what the update of P will
    /// need: the factor columns of a combined update); while M(q, λ̂) is indefinite there, α is halved, up to
    /// `MAX_GAIN_HALVINGS` times, after which (or at once without an update) λ̂ is pulled
    /// towards the anchor and nothing is updated. Returns whether the update stands, its
    /// α, the halvings taken and `form`'s last value.
    #[inline(always)]
    fn damped_candidate<const FMA: bool>(
        &mut self,
        sample: SampleOf<'_, N>,
        mut update: bool,
        form: CandidateForm<'_, N>,
    ) -> Result<(bool, f64, u32, usize)> {
        let (mut alpha, mut attempt, mut out) = (1.0, 0, 0);
        loop {
            if update {
                // A method, not a closure: a closure is a function of its own, which the
                // compiler may leave out of line, compiled without the caller's AVX2 and
                // FMA (then every fused multiply-add of the factors was a library call).
                out = match form {
                    CandidateForm::Combined(q_ok, qd) => {
                        self.candidate_and_factors::<FMA>(q_ok, qd, alpha)?
                    }
                    CandidateForm::Step => {
                        let b = &mut self.buf;
                        b.candidate.copy_from(&self.x);
                        b.candidate.axpy(alpha, &b.step, 1.0);
                        0
                    }
                };
            } else {
                self.buf.candidate.copy_from(&self.x);
            }
            match self.derivatives(true, sample) {
                Ok(()) => {
                    self.x.copy_from(&self.buf.candidate);
                    break;
                }
                Err(e) if attempt == MAX_GAIN_HALVINGS || !update => {
                    if self.anchor.is_none() {
                        return Err(e);
                    }
                    // The prior itself is outside at this configuration: no update.
                    self.buf.candidate.copy_from(&self.x);
                    self.pull_to_anchor(true, sample).map_err(|_| e)?;
                    self.x.copy_from(&self.buf.candidate);
                    update = false;
                    break;
                }
                Err(_) => {
                    alpha *= 0.5;
                    attempt += 1;
                }
            }
        }
        Ok((update, alpha, attempt, out))
    }

    /// The model's forward dynamics and derivatives at the state (the candidate buffer
    /// if `candidate`, else x), into the buffers: q̈ from τ, and the Jacobian at the
    /// acceleration chosen by [`EkfConfig::parameter_jacobian`].
    #[inline(always)]
    fn derivatives(&mut self, candidate: bool, sample: SampleOf<'_, N>) -> Result<()> {
        let (tau, qdd) = (sample.tau, sample.qdd);
        let n = self.n();
        let b = &mut self.buf;
        let x = if candidate { &b.candidate } else { &self.x };
        let xs = x.as_slice();
        b.q.as_mut_slice().copy_from_slice(&xs[..n]);
        b.v.as_mut_slice().copy_from_slice(&xs[n..2 * n]);
        b.lam.as_mut_slice().copy_from_slice(&xs[2 * n..]);
        let ws = &mut self.ws;
        let mut result = Ok(());
        if self.config.discretisation == Discretisation::Midpoint && !self.stiff {
            // q̈ at the start of the interval, then the state half a period on, where the
            // derivatives (and the q̈ that moves the state) are taken.
            let h = self.config.dt;
            result =
                self.model
                    .forward_dynamics_into(ws, &b.q, &b.v, tau, &b.lam, &mut b.qdd_start);
            for i in 0..n {
                let a = b.qdd_start[i];
                b.q[i] += 0.5 * h * b.v[i] + 0.125 * h * h * a;
                b.v[i] += 0.5 * h * a;
            }
        }
        let at_data = self.config.parameter_jacobian == ParameterJacobian::DataAcceleration
            && all_finite(qdd);
        let factors = self.use_factors && xs.len() > ACC_ROWS;
        let result = result.and_then(|()| {
            // Chain-sized states take ∂q̈/∂λ in factors (see `factored_time_products`).
            b.factored = factors
                && self.model.forward_derivatives_factored_into(
                    ws,
                    &b.q,
                    &b.v,
                    at_data.then_some(qdd),
                    tau,
                    &b.lam,
                    &mut b.minv,
                    &mut b.fd,
                )?;
            if b.factored {
                Ok(())
            } else if at_data {
                // A at q̈_data (including −M⁻¹·Φ(q̂, q̂̇, q̈_data)); the state is then
                // propagated with the q̈ the measured τ produces.
                self.model.forward_derivatives_at_into(
                    ws,
                    &b.q,
                    &b.v,
                    qdd,
                    tau,
                    &b.lam,
                    &mut b.tau_lin,
                    &mut b.fd,
                )
            } else {
                self.model
                    .forward_derivatives_into(ws, &b.q, &b.v, tau, &b.lam, &mut b.fd)
            }
        });
        result.map_err(|e| match e {
            PrrrpError::NotPositiveDefinite { .. } => PrrrpError::Diverged {
                what: "extended Kalman filter",
                at: self.samples,
                hint: "M(q, λ̂) is not positive definite: the parameter estimate left the \
                           physical region; start from a better λ0, lower the initial \
                           parameter uncertainty (`prrrp identify --ekf-prior-width`) or \
                           raise the measurement noise (`--ekf-noise`)",
            },
            other => other,
        })
    }

    /// Time update with the derivatives in the buffers: x ← f(x, τ), P ← F·P·Fᵀ + Q.
    #[inline(always)]
    fn predict<const FMA: bool>(&mut self) {
        let h = self.config.dt;
        let (n, s) = (self.n(), self.x.nrows());
        let b = &mut self.buf;
        let fd = &b.fd;

        // A = ∂q̈/∂x = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ] (N×S) assembled contiguously (uniform
        // column indexing in the loops below), or [A_q, A_v, −M⁻¹] (N×3N) when the
        // derivatives came factored; then G = P·Aᵀ (S×N), skipping zero entries of A.
        let fac = b.factored;
        let nn = n * n;
        if fac {
            assemble_factored(fd, b.minv.as_slice(), &mut b.af, n);
        } else {
            assemble_a(fd, b.a.as_mut_slice(), n);
        }
        let midpoint = self.config.discretisation == Discretisation::Midpoint && !self.stiff;
        // Stiff dynamics (see `stiff_steps`): the linearly implicit θ-step of [q, q̇]
        // (θ = STIFF_THETA), whose velocity increment solves L·Δq̇ = h·(q̈ + θh·A_q·q̇) with
        // L = I − θh·A_v − θ²h²·A_q, then q⁺ = q + h·q̇ + θh·Δq̇. In the update below that
        // is A replaced by Ã = L⁻¹·[A_q, A_v + θh·A_q, A_λ], q̈ by L⁻¹·(q̈ + θh·A_q·q̇) and
        // the position coefficient c by θh: its exact Jacobian, F_vv = I + h·Ã_v etc.
        let stiffness =
            h * inf_norm(fd.dqdd_dqd.as_slice(), n) + h * h * inf_norm(fd.dqdd_dq.as_slice(), n);
        let mut stiff = self.stiff_handling && stiffness > STIFF_LIMIT;
        let th = STIFF_THETA * h;
        if stiff {
            let l = b.implicit.as_mut_slice();
            for j in 0..n {
                for i in 0..n {
                    let d = if i == j { 1.0 } else { 0.0 };
                    l[j * n + i] = d - th * fd.dqdd_dqd[(i, j)] - th * th * fd.dqdd_dq[(i, j)];
                }
            }
            let a = if fac {
                &mut b.af[..]
            } else {
                b.a.as_mut_slice()
            };
            for k in 0..nn {
                a[nn + k] += th * a[k];
            }
            for i in 0..n {
                let mut v = fd.qdd[i];
                for j in 0..n {
                    v += th * fd.dqdd_dq[(i, j)] * self.x[n + j];
                }
                b.innovation[i] = v;
            }
            // L = M⁻¹·(M + h·D + h²·K) for damping D and stiffness K that only dissipate
            // and restore; a numerically singular L keeps the explicit step.
            // With factors, L⁻¹ reaches ∂q̈/∂λ through −M⁻¹ (3N columns instead of S).
            if solve_in_place(l, n, a, b.innovation.as_mut_slice()) {
                b.fd.qdd.copy_from(&b.innovation);
                self.stiff_steps += 1;
            } else {
                if fac {
                    assemble_factored(&b.fd, b.minv.as_slice(), &mut b.af, n);
                } else {
                    assemble_a(&b.fd, b.a.as_mut_slice(), n);
                }
                stiff = false;
            }
        }
        let fd = &b.fd;
        if fac {
            factored_time_products::<FMA>(
                self.p.as_slice(),
                &b.af,
                fd.dqdd_dlambda.as_slice(),
                (&mut b.xg, &mut b.nz, &mut b.u),
                (b.g.as_mut_slice(), b.apa.as_mut_slice()),
                n,
                s,
            );
        } else {
            let a = b.a.as_slice();
            if s > ACC_ROWS {
                p_times_at_blocked::<FMA>(self.p.as_slice(), a, b.g.as_mut_slice(), n, s, s);
            } else {
                b.g.fill(0.0);
                p_times_at::<FMA>(self.p.as_slice(), a, b.g.as_mut_slice(), n, s);
            }
            b.apa.fill(0.0);
            a_times_g::<FMA>(a, b.g.as_slice(), b.apa.as_mut_slice(), n, s);
        }

        // F = I + E with E_q = [c·h·A_q, h·I + c·h·A_v, c·h·A_λ], E_v = h·A, E_λ = 0
        // (c = h/2 for the second-order position update, 0 for Euler), so
        // P ← P + EP + PEᵀ + EPEᵀ needs only P, G = P·Aᵀ and A·P·Aᵀ. Block by block on the
        // upper triangle, in an order that reads every block before it is overwritten:
        // qq, qλ, qv, vv, vλ. G_q, G_v, G_λ are the row blocks of G.
        let c = match self.config.discretisation {
            _ if stiff => STIFF_THETA * h,
            Discretisation::Euler => 0.0,
            Discretisation::SecondOrder | Discretisation::Midpoint => 0.5 * h,
        };
        let h2 = h * h;
        let (hc, h2c, h2c2) = (h * c, h2 * c, h2 * c * c);
        let gs = b.g.as_slice();
        let apa = &b.apa;
        let p = self.p.as_mut_slice();
        let at = |i: usize, j: usize| j * s + i;
        for j in 0..n {
            for i in 0..=j {
                p[at(i, j)] += h * (p[at(n + i, j)] + p[at(i, n + j)])
                    + h2 * p[at(n + i, n + j)]
                    + hc * (gs[j * s + i] + gs[i * s + j])
                    + h2c * (gs[j * s + n + i] + gs[i * s + n + j])
                    + h2c2 * apa[(i, j)];
            }
        }
        // The qλ and vλ blocks: on an exactly symmetric P their copies in the lower
        // triangle (P's q and q̇ columns, rows λ: contiguous) hold the same values, so
        // they are updated there and copied up (`mirror_lower_rows`); the upper rows
        // were strided reads and writes. Same operations on the same values: the same
        // bits.
        let lower = self.p_symmetric;
        let o = 2 * n;
        if lower {
            for i in 0..n {
                let (head, tail) = p.split_at_mut((n + i) * s);
                let qi = &mut head[i * s + o..(i + 1) * s];
                for ((x, &pv), &g) in qi.iter_mut().zip(&tail[o..s]).zip(&gs[i * s + o..]) {
                    *x += h * pv + hc * g;
                }
            }
        } else {
            for j in o..s {
                for i in 0..n {
                    p[at(i, j)] += h * p[at(n + i, j)] + hc * gs[i * s + j];
                }
            }
        }
        for j in 0..n {
            for i in 0..n {
                p[at(i, n + j)] += h * (p[at(n + i, n + j)] + gs[j * s + i])
                    + hc * gs[i * s + n + j]
                    + h2 * gs[j * s + n + i]
                    + h2c * apa[(i, j)];
            }
        }
        for j in 0..n {
            for i in 0..=j {
                p[at(n + i, n + j)] +=
                    h * (gs[i * s + n + j] + gs[j * s + n + i]) + h2 * apa[(i, j)];
            }
        }
        if lower {
            for i in 0..n {
                let vi = &mut p[(n + i) * s + o..(n + i + 1) * s];
                for (x, &g) in vi.iter_mut().zip(&gs[i * s + o..]) {
                    *x += h * g;
                }
            }
        } else {
            for j in o..s {
                for i in 0..n {
                    p[at(n + i, j)] += h * gs[i * s + j];
                }
            }
        }
        for i in 0..s {
            p[at(i, i)] += self.q_diag[i];
        }
        // Only the rows and columns of q and q̇ (and the diagonal) changed: an exactly
        // symmetric P needs only those copied (a third of the strided copies at a
        // chain's size), the qq, qq̇ and q̇q̇ blocks down, the qλ and q̇λ blocks up.
        if lower {
            mirror_upper_rows(p, s, o, o);
            mirror_lower_rows(p, s, o);
        } else {
            mirror_upper(p, s);
            self.p_symmetric = true;
        }

        self.stiff = stiff;
        let qdd = &fd.qdd;
        if midpoint && !stiff {
            // q̇ by the midpoint rule; q by h²/6·(q̈_0 + 2·q̈_½), exact for a q̈ linear in t.
            let a0 = &b.qdd_start;
            for i in 0..n {
                let (qi, vi) = (self.x[i], self.x[n + i]);
                self.x[i] = qi + h * vi + h2 / 6.0 * (a0[i] + 2.0 * qdd[i]);
                self.x[n + i] = vi + h * qdd[i];
            }
            return;
        }
        for i in 0..n {
            let (qi, vi) = (self.x[i], self.x[n + i]);
            self.x[i] = qi + h * vi + hc * qdd[i];
            self.x[n + i] = vi + h * qdd[i];
        }
    }
}

impl<M, N: Dim, P: Dim, S: Dim> Estimator<N, P> for EkfOf<M, N, P, S>
where
    M: LinearModel<N, P>,
    DefaultAllocator: EkfAllocator<N, P, S>,
{
    /// One sample k: update with the measurement (q, and q̇ if configured), then predict
    /// to k+1 with τ_k held over the period. The returned λ̂ is the posterior at k (the
    /// prediction does not change λ). A NaN or ∞ in a measurement skips that update (see
    /// [`EkfOf::skipped_updates`]); q̈ is used only by
    /// [`ParameterJacobian::DataAcceleration`]. If the posterior λ̂ makes M(q, λ̂)
    /// indefinite, the update is repeated with the gain halved, up to 10 times (see
    /// [`EkfOf::damped_updates`]).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a sample whose vectors do not have one entry per
    /// joint; [`PrrrpError::NonFinite`] for NaN/∞ in τ; [`PrrrpError::NotPositiveDefinite`]
    /// if the innovation covariance cannot be factorised; [`PrrrpError::Diverged`] if
    /// M(q, λ̂) is not positive definite even with the smallest gain (λ₀ itself not
    /// physical) — the filter is then left at its prior for this sample — or the state
    /// became non-finite.
    fn step(&mut self, sample: SampleOf<'_, N>) -> Result<&OVector<f64, P>> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set at construction only when the CPU reports AVX2 and FMA.
            unsafe { self.step_avx2(sample)? };
            return Ok(&self.lambda);
        }
        self.step_impl::<false>(sample)?;
        Ok(&self.lambda)
    }

    fn estimate(&self) -> &OVector<f64, P> {
        &self.lambda
    }

    fn reset(&mut self) {
        let n = self.n();
        self.x.copy_from(&self.x0);
        self.p.copy_from(&self.p0);
        self.p_symmetric = self.p0_symmetric;
        self.lambda
            .as_mut_slice()
            .copy_from_slice(&self.x0.as_slice()[2 * n..]);
        self.initialised = false;
        self.samples = 0;
        self.skipped = 0;
        self.damped = 0;
        self.stiff = false;
        self.stiff_steps = 0;
        self.anchored = 0;
    }
}

/// Above this h·‖∂q̈/∂q̇‖∞ + h²·‖∂q̈/∂q‖∞ the time update is linearly implicit (see
/// [`EkfOf::stiff_steps`]). The explicit step's factor on a mode decaying at rate r is
/// 1 − h·r + (h·r)²/2, which stops decaying as h·r nears 2, and on an oscillation of
/// frequency ω it grows faster as h·ω nears 1; the norm bounds those rates from above,
/// and both steps are second order (see [`STIFF_THETA`]), so switching early costs no
/// accuracy on the slow modes that carry the parameters.
pub const STIFF_LIMIT: f64 = 0.5;

/// θ of the linearly implicit step taken where the dynamics are stiff: ½, the trapezoidal
/// rule, second order like the explicit step and A-stable (its factor (1 + z/2)/(1 − z/2)
/// has modulus ≤ 1 on every decaying or oscillating mode z = h·μ). Implicit Euler (θ = 1),
/// used before, is first order: where the switch fell on the slow modes that carry the
/// parameters its O(h) bias moved the estimate by 1–3σ (the paper's arm at 50 Hz).
pub const STIFF_THETA: f64 = 0.5;

/// ‖A‖∞ (largest absolute row sum) of a column-major n×n matrix, ≥ its spectral radius.
#[inline]
fn inf_norm(a: &[f64], n: usize) -> f64 {
    (0..n)
        .map(|i| (0..n).map(|j| a[j * n + i].abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

/// A = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ] (N×S, column-major) from the derivatives.
#[inline(always)]
fn assemble_a<N: Dim, P: Dim>(fd: &ForwardDerivativesOf<N, P>, a: &mut [f64], n: usize)
where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<N, P>,
{
    let nn = n * n;
    a[..nn].copy_from_slice(fd.dqdd_dq.as_slice());
    a[nn..2 * nn].copy_from_slice(fd.dqdd_dqd.as_slice());
    a[2 * nn..].copy_from_slice(fd.dqdd_dlambda.as_slice());
}

/// [A_q, A_v, −M⁻¹] (N×3N, column-major) from factored derivatives and M⁻¹.
#[inline(always)]
fn assemble_factored<N: Dim, P: Dim>(
    fd: &ForwardDerivativesOf<N, P>,
    minv: &[f64],
    af: &mut [f64],
    n: usize,
) where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<N, P>,
{
    let nn = n * n;
    af[..nn].copy_from_slice(fd.dqdd_dq.as_slice());
    af[nn..2 * nn].copy_from_slice(fd.dqdd_dqd.as_slice());
    for (c, &m) in af[2 * nn..3 * nn].iter_mut().zip(minv) {
        *c = -m;
    }
}

/// G = P·Aᵀ (S×N) and A·G (N×N) for A = [A_q, A_v, C·Φ] given as `af` = [A_q, A_v, C]
/// (N×3N; C = −M⁻¹, or −L⁻¹·M⁻¹ in a stiff step) and Φ (N×P, column-major): G =
/// [P_·q, P_·v, P_·λ·Φᵀ]·[A_q, A_v, C]ᵀ and A·G = [A_q, A_v, C]·[G_q; G_v; Φ·G_λ]. A
/// chain's Φ is about half zeros (row j: the parameters of links ≥ j and of joint j's
/// actuator), which P_·λ·Φᵀ skips column by column; the assembled A_λ = C·Φ is dense.
/// So ≈ S·(2N² + nnz Φ + N²) multiply-adds instead of S²·N. `nz`, `xg`, `u`: scratch
/// of P offset pairs, S×N (for P_·λ·Φᵀ) and TILE_ROWS·N or n4 + 2·n4·N (n4 = N rounded
/// up to 4), whichever is larger.
#[inline(always)]
fn factored_time_products<const FMA: bool>(
    p: &[f64],
    af: &[f64],
    phi: &[f64],
    (xg, nz, u): (&mut [f64], &mut [(usize, usize)], &mut [f64]),
    (g, apa): (&mut [f64], &mut [f64]),
    n: usize,
    s: usize,
) {
    let np = s - 2 * n;
    let t = &mut xg[..n * s];
    column_tiles!(n, |c0, cskip| p_lambda_phi_t_cols::<FMA>(
        p,
        phi,
        nz,
        t,
        (n, s),
        (c0, cskip)
    ));
    // G = [P_·q, P_·v]·[A_q, A_v]ᵀ + T·Cᵀ, the sums continued over T's columns (no copy
    // of P's first 2N columns next to T).
    let t = &xg[..n * s];
    column_tiles!(n, |c0, cskip| two_source_cols::<FMA>(
        (p, t),
        af,
        g,
        (n, s),
        (c0, cskip)
    ));
    // U = Φ·G_λ and A·G = [A_q, A_v, C]·[G_q; G_v; U] (N×N each).
    if n <= TILE_ROWS {
        // In register tiles, X's columns (of Φ and [A_q, A_v, C]) N entries long: as
        // column loops, these took as long as P_·λ·Φᵀ.
        let u8 = &mut u[..TILE_ROWS * n];
        // Φ's zero columns add nothing to U (and are skipped, as a column loop did).
        let mut cnt = 0;
        for k in 0..np {
            if phi[k * n..k * n + n].iter().any(|&v| v != 0.0) {
                nz[cnt].0 = k;
                cnt += 1;
            }
        }
        let nz = &nz[..cnt];
        column_tiles!(n, |c0, cskip| small_products_cols::<FMA>(
            (phi, af, nz),
            (&*g, u8, apa),
            (n, s),
            (c0, cskip)
        ));
        return;
    }
    let n4 = n.div_ceil(4) * 4;
    let (col, rest) = u.split_at_mut(n4);
    let (uu, acc) = rest.split_at_mut(n4 * n);
    let acc = &mut acc[..n4 * n];
    uu.fill(0.0);
    for k in 0..np {
        let pc = &phi[k * n..k * n + n];
        if pc.iter().all(|&v| v == 0.0) {
            continue;
        }
        col[..n].copy_from_slice(pc);
        add_scaled_column::<FMA>(col, uu, n4, |j| g[j * s + 2 * n + k]);
    }
    acc.fill(0.0);
    for kk in 0..3 * n {
        col[..n].copy_from_slice(&af[kk * n..kk * n + n]);
        if kk < 2 * n {
            add_scaled_column::<FMA>(col, acc, n4, |j| g[j * s + kk]);
        } else {
            add_scaled_column::<FMA>(col, acc, n4, |j| uu[j * n4 + kk - 2 * n]);
        }
    }
    for (out, a) in apa.chunks_exact_mut(n).zip(acc.chunks_exact(n4)) {
        out.copy_from_slice(&a[..n]);
    }
}

/// Columns `c0 + cskip..c0 + NC` of U = Φ·G_λ into `u8` and of A·G = [A_q, A_v, C]·[G_q;
/// G_v; U] into `apa` (N×N), for N ≤ TILE_ROWS: Φ's non-zero columns listed in `nz`
/// (first of each pair), U's columns TILE_ROWS apart. The same products summed in the
/// same order as the column loops of [`factored_time_products`].
#[inline(always)]
fn small_products_cols<const FMA: bool, const NC: usize>(
    (phi, af, nz): (&[f64], &[f64], &[(usize, usize)]),
    (g, u8, apa): (&[f64], &mut [f64], &mut [f64]),
    (n, s): (usize, usize),
    (c0, cskip): (usize, usize),
) {
    const R: usize = TILE_ROWS;
    let zero = [[0.0f64; R]; NC];
    let cols = nz.iter().map(|&(k, _)| (k * n, 2 * n + k + c0 * s));
    let acc = short_tile::<FMA, NC>(zero, (phi, n), (g, s), cols);
    for (c, a) in acc.iter().enumerate() {
        if c >= cskip {
            u8[(c0 + c) * R..(c0 + c + 1) * R].copy_from_slice(a);
        }
    }
    let cols = (0..2 * n).map(|k| (k * n, k + c0 * s));
    let acc = short_tile::<FMA, NC>(zero, (af, n), (g, s), cols);
    let cols = (0..n).map(|k| ((2 * n + k) * n, c0 * R + k));
    let acc = short_tile::<FMA, NC>(acc, (af, n), (&*u8, R), cols);
    for (c, a) in acc.iter().enumerate() {
        if c >= cskip {
            apa[(c0 + c) * n..(c0 + c + 1) * n].copy_from_slice(&a[..n]);
        }
    }
}

/// [`whole_tile`] on columns of X with `rows` ≤ [`TILE_ROWS`] entries (`x` is `(x,
/// rows)`): nothing past them is read, and the tile's rows beyond them are zeros plus
/// `acc`'s.
#[inline(always)]
fn short_tile<const FMA: bool, const NC: usize>(
    acc: [[f64; TILE_ROWS]; NC],
    (x, rows): (&[f64], usize),
    (y, ys): (&[f64], usize),
    cols: impl Iterator<Item = (usize, usize)>,
) -> [[f64; TILE_ROWS]; NC] {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        // SAFETY: FMA = true only runs on a CPU with AVX2 and FMA (see `madd`).
        return unsafe { avx2::short_tile::<NC>(acc, (x, rows), (y, ys), cols) };
    }
    short_tile_portable::<FMA, NC>(acc, (x, rows), (y, ys), cols)
}

/// [`short_tile`] as plain loops (the portable copy, and the reference of the fused one).
#[inline(always)]
fn short_tile_portable<const FMA: bool, const NC: usize>(
    mut acc: [[f64; TILE_ROWS]; NC],
    (x, rows): (&[f64], usize),
    (y, ys): (&[f64], usize),
    cols: impl Iterator<Item = (usize, usize)>,
) -> [[f64; TILE_ROWS]; NC] {
    for (xo, yo) in cols {
        let xv = &x[xo..xo + rows];
        for (c, a) in acc.iter_mut().enumerate() {
            let f = y[yo + c * ys];
            for (av, &xr) in a.iter_mut().zip(xv) {
                *av = madd::<FMA>(f, xr, *av);
            }
        }
    }
    acc
}

/// Column j of `out` (columns `n4` apart, n4 a multiple of 4) += `col`·f(j) for every
/// column, as whole 4-vectors (`col`'s padding entries are zeros, so the padding of
/// `out` stays zero).
#[inline(always)]
fn add_scaled_column<const FMA: bool>(
    col: &[f64],
    out: &mut [f64],
    n4: usize,
    f: impl Fn(usize) -> f64,
) {
    for (j, oc) in out.chunks_exact_mut(n4).enumerate() {
        let fj = f(j);
        for (o4, c4) in oc.chunks_exact_mut(4).zip(col.chunks_exact(4)) {
            for (o, &c) in o4.iter_mut().zip(c4) {
                *o = madd::<FMA>(c, fj, *o);
            }
        }
    }
}

/// Columns `c0 + cskip..c0 + NC` of G = [P_·q, P_·v, T]·Cᵀ (S×N) into `g`, with C = `af`
/// (N×3N) and T (S×N) in `t`: the first 2N terms of each sum from P's columns, the last
/// N from T's, in register tiles as [`product_cols`].
#[inline(always)]
fn two_source_cols<const FMA: bool, const NC: usize>(
    (p, t): (&[f64], &[f64]),
    af: &[f64],
    g: &mut [f64],
    (n, s): (usize, usize),
    (c0, cskip): (usize, usize),
) {
    let mut r0 = 0;
    while r0 < s {
        let len = (s - r0).min(TILE_ROWS);
        let (t0, skip) = full_tile(r0, len, s);
        let acc = tile::<FMA, NC>((p, s, t0), (af, n, c0), len + skip, 2 * n);
        let yt = (&af[2 * n * n..], n, c0);
        let acc = tile_from::<FMA, NC>(acc, (t, s, t0), yt, len + skip, n);
        store_tile(&acc, g, s, (r0, len, skip), (c0, cskip));
        r0 += len;
    }
}

/// Columns `c0 + cskip..c0 + NC` of T = P_·λ·Φᵀ (S×N) into `t`, summing over the
/// parameters with a non-zero in rows `c0 + cskip..c0 + NC` of Φ only (their column offsets in
/// P and Φ listed in `nz`, P-long scratch), in register tiles.
#[inline(always)]
fn p_lambda_phi_t_cols<const FMA: bool, const NC: usize>(
    p: &[f64],
    phi: &[f64],
    nz: &mut [(usize, usize)],
    t: &mut [f64],
    (n, s): (usize, usize),
    (c0, cskip): (usize, usize),
) {
    // The rows of Φ this tile writes: a tile overlapping its predecessor sums only the
    // parameters of its new columns (the overlapped columns' sums are left incomplete
    // and not written).
    let mut cnt = 0;
    for k in 0..s - 2 * n {
        if phi[k * n + c0 + cskip..k * n + c0 + NC]
            .iter()
            .any(|&v| v != 0.0)
        {
            nz[cnt] = ((2 * n + k) * s, k * n);
            cnt += 1;
        }
    }
    let nz = &nz[..cnt];
    let mut r0 = 0;
    while r0 < s {
        let len = (s - r0).min(TILE_ROWS);
        let (t0, skip) = full_tile(r0, len, s);
        let acc = tile_listed::<FMA, NC>((p, t0), (phi, c0), nz);
        store_tile(&acc, t, s, (r0, len, skip), (c0, cskip));
        r0 += len;
    }
}

/// Solves L·X = [A | b] in place (L column-major n×n, overwritten; A column-major n×m,
/// b n-long) by Gaussian elimination with partial pivoting, rows swapped in every
/// right-hand side as it goes (no pivot storage). Returns false if L is numerically
/// singular (A and b are then partly eliminated: the caller restores them).
fn solve_in_place(l: &mut [f64], n: usize, a: &mut [f64], b: &mut [f64]) -> bool {
    let m = a.len() / n.max(1);
    let scale = l.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for k in 0..n {
        let mut p = k;
        for i in k + 1..n {
            if l[k * n + i].abs() > l[k * n + p].abs() {
                p = i;
            }
        }
        let pivot = l[k * n + p].abs();
        if pivot.is_nan() || pivot <= 1e-12 * scale {
            return false;
        }
        if p != k {
            for j in 0..n {
                l.swap(j * n + k, j * n + p);
            }
            for j in 0..m {
                a.swap(j * n + k, j * n + p);
            }
            b.swap(k, p);
        }
        let piv = l[k * n + k];
        // The multipliers are kept in L's column k (below the diagonal, which the back
        // substitution never reads) so that A is eliminated column by column: its
        // columns are contiguous, rows are not (S columns of N, the stiff step's cost).
        // Each entry gets the same operations in the same order as row by row.
        for i in k + 1..n {
            let f = l[k * n + i] / piv;
            l[k * n + i] = f;
            if f == 0.0 {
                continue;
            }
            for j in k + 1..n {
                l[j * n + i] -= f * l[j * n + k];
            }
            b[i] -= f * b[k];
        }
        let fs = &l[k * n + k + 1..(k + 1) * n];
        for col in a.chunks_exact_mut(n) {
            let ak = col[k];
            for (x, &f) in col[k + 1..].iter_mut().zip(fs) {
                if f != 0.0 {
                    *x -= f * ak;
                }
            }
        }
        l[k * n + k + 1..(k + 1) * n].fill(0.0);
    }
    // Back substitution row by row over all right-hand sides, so that their divisions
    // overlap instead of each column's waiting on the last (each column gets the same
    // operations in the same order).
    for i in (0..n).rev() {
        let d = l[i * n + i];
        for x in a.chunks_exact_mut(n).chain(std::iter::once(&mut b[..n])) {
            let mut v = x[i];
            for j in i + 1..n {
                v -= l[j * n + i] * x[j];
            }
            x[i] = v / d;
        }
    }
    true
}

fn check_variances(what: &str, v: &[f64], zero_ok: bool) -> Result<()> {
    for (i, &x) in v.iter().enumerate() {
        let ok = x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0));
        if !ok {
            return Err(PrrrpError::InvalidParameter {
                field: format!("{what}[{i}]"),
                value: x,
                reason: if zero_ok {
                    "variances must be finite and >= 0"
                } else {
                    "variances must be finite and > 0"
                },
            });
        }
    }
    Ok(())
}

/// The gain K = P_·z·S_z⁻¹ (S×N) into `k` from L⁻¹ of S_z = L·Lᵀ: S_z⁻¹ = L⁻ᵀ·L⁻¹ (N×N,
/// cheap, into `sinv`), then N independent column sums over whole S-long columns (the
/// two triangular solves on K would chain every column to the previous one).
#[inline(always)]
fn gain_from_factor<const FMA: bool, N: Dim, S: Dim>(
    pz: &[f64],
    linv: &OMatrix<f64, N, N>,
    sinv: &mut OMatrix<f64, N, N>,
    k: &mut OMatrix<f64, S, N>,
    n: usize,
    s: usize,
) where
    DefaultAllocator: Allocator<N, N> + Allocator<S, N>,
{
    linv.tr_mul_to(linv, sinv);
    k.fill(0.0);
    gain_columns::<FMA>(pz, sinv.as_slice(), k.as_mut_slice(), n, s);
}

/// x += α·K·ν without K: x += α·P_·z·y with y = S_z⁻¹·ν = L⁻ᵀ·(L⁻¹·ν) from L⁻¹ (N×N,
/// lower) of S_z = L·Lᵀ; `nu` (N) is overwritten with y, `z` is N scratch. The same
/// vector as K·ν to round-off, in S·N multiply-adds.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn step_from_factor<const FMA: bool>(
    pz: &[f64],
    linv: &[f64],
    nu: &mut [f64],
    z: &mut [f64],
    alpha: f64,
    x: &mut [f64],
    n: usize,
    s: usize,
) {
    // z = L⁻¹·ν (lower: z_i sums j ≤ i), then y = L⁻ᵀ·z (y_j sums i ≥ j).
    for (i, zi) in z[..n].iter_mut().enumerate() {
        *zi = (0..=i).map(|j| linv[j * n + i] * nu[j]).sum();
    }
    for (j, y) in nu[..n].iter_mut().enumerate() {
        *y = (j..n).map(|i| linv[j * n + i] * z[i]).sum();
    }
    for m in 0..n {
        let f = alpha * nu[m];
        for (xv, &pv) in x[..s].iter_mut().zip(&pz[m * s..m * s + s]) {
            *xv = madd::<FMA>(f, pv, *xv);
        }
    }
}

/// K = P_·z·S_z⁻¹ as N independent column sums over whole S-long columns (slices as
/// parameters: the optimiser then knows that K does not alias P_·z).
#[inline(always)]
fn gain_columns<const FMA: bool>(pzs: &[f64], sinv: &[f64], ks: &mut [f64], n: usize, s: usize) {
    for m in 0..n {
        let pc = &pzs[m * s..m * s + s];
        for j in 0..n {
            let f = sinv[j * n + m];
            for (kv, &pv) in ks[j * s..j * s + s].iter_mut().zip(pc) {
                *kv = madd::<FMA>(f, pv, *kv);
            }
        }
    }
}

/// G += P·Aᵀ (S×N) with A = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ] given as its three column-major
/// blocks, skipping zero entries of A (most of −M⁻¹Φ for PRRRP).
#[inline(always)]
fn p_times_at<const FMA: bool>(ps: &[f64], a: &[f64], gs: &mut [f64], n: usize, s: usize) {
    for kk in 0..s {
        let acol = &a[kk * n..kk * n + n];
        let pc = &ps[kk * s..kk * s + s];
        for (i, &f) in acol.iter().enumerate() {
            if f != 0.0 {
                let gc = &mut gs[i * s..i * s + s];
                for (gv, &pv) in gc.iter_mut().zip(pc) {
                    *gv = madd::<FMA>(f, pv, *gv);
                }
            }
        }
    }
}

/// D −= K'·S_z (D = P_·z on entry), column by column.
#[inline(always)]
fn minus_k_sz<const FMA: bool>(ks: &[f64], sz: &[f64], dsm: &mut [f64], n: usize, s: usize) {
    for j in 0..n {
        let dc = &mut dsm[j * s..j * s + s];
        for m in 0..n {
            let f = sz[j * n + m];
            let kc = &ks[m * s..m * s + s];
            for (a, &bv) in dc.iter_mut().zip(kc) {
                *a = madd::<FMA>(-f, bv, *a);
            }
        }
    }
}

/// A·P·Aᵀ = A·G (N×N) into `apa`. Column kk of A outer, so that the N column sums advance
/// side by side instead of one dependent chain at a time; zero columns of A (joints the
/// dynamics do not depend on) are skipped.
#[inline(always)]
fn a_times_g<const FMA: bool>(a: &[f64], gs: &[f64], apa: &mut [f64], n: usize, s: usize) {
    for kk in 0..s {
        let ac = &a[kk * n..kk * n + n];
        if ac.iter().all(|&v| v == 0.0) {
            continue;
        }
        for j in 0..n {
            let gv = gs[j * s + kk];
            let col = &mut apa[j * n..j * n + n];
            for (x, &a) in col.iter_mut().zip(ac) {
                *x = madd::<FMA>(a, gv, *x);
            }
        }
    }
}

/// Rows per stack accumulator of [`joseph_columns`]: a whole column at the PRRRP's S = 18
/// (kept in registers), a few blocks at run-time sizes.
const ACC_ROWS: usize = 32;

/// The Joseph update P ← P − K'·P_z· − D·K'ᵀ column by column: column j of P loses
/// Σ_m (P_·z)_jm·K'_·m + K'_jm·D_·m, in blocks of [`ACC_ROWS`] rows summed in a stack
/// array (the accumulator stays in registers and cannot alias P). Up to [`ACC_ROWS`]
/// states whole columns, fully unrolled and vectorised, which is faster than the
/// triangle's ragged loops although it does twice the flops; beyond, the upper triangle
/// only, copied onto the lower one (exactly symmetric).
#[inline(always)]
fn joseph_columns<const FMA: bool>(
    ks: &[f64],
    ds: &[f64],
    pzs: &[f64],
    p: &mut [f64],
    n: usize,
    s: usize,
    (jx, jy): (&mut [f64], &mut [f64]),
) {
    if s <= ACC_ROWS {
        // One block per column (every compile-time size up to 32 states, PRRRP's 18):
        // the trip count is the constant S, so the column is fully unrolled.
        for j in 0..s {
            let mut acc = [0.0f64; ACC_ROWS];
            for m in 0..n {
                let a = pzs[m * s + j];
                let bv = ks[m * s + j];
                let kc = &ks[m * s..m * s + s];
                let dc = &ds[m * s..m * s + s];
                for r in 0..s {
                    acc[r] = madd::<FMA>(a, kc[r], madd::<FMA>(bv, dc[r], acc[r]));
                }
            }
            for (c, &v) in p[j * s..j * s + s].iter_mut().zip(acc.iter()) {
                *c -= v;
            }
        }
        return;
    }
    // Larger states: the upper triangle only, half the work, in register tiles as
    // `minus_w_wt` (the stack accumulators of ragged column blocks went through memory on
    // every multiply-add), each entry written to both triangles as it is finished (the
    // caller's separate mirroring pass read P row-wise once more). Every entry sums the
    // same products in the same order as column by column.
    // The interleaved columns make entry (i, j) the plain sum Σ_k X_ik·Y_jk over 2N
    // terms, in the same order as above.
    for m in 0..n {
        jx[2 * m * s..(2 * m + 1) * s].copy_from_slice(&ds[m * s..m * s + s]);
        jx[(2 * m + 1) * s..(2 * m + 2) * s].copy_from_slice(&ks[m * s..m * s + s]);
        jy[2 * m * s..(2 * m + 1) * s].copy_from_slice(&ks[m * s..m * s + s]);
        jy[(2 * m + 1) * s..(2 * m + 2) * s].copy_from_slice(&pzs[m * s..m * s + s]);
    }
    joseph_upper::<FMA>(jx, jy, p, 2 * n, s);
}

/// P ← P − X·Yᵀ on the upper triangle in register tiles, each entry mirrored as written,
/// with X and Y given by `k2` S-long columns each.
#[inline(always)]
fn joseph_upper<const FMA: bool>(jx: &[f64], jy: &[f64], p: &mut [f64], k2: usize, s: usize) {
    column_tiles!(s, |c0, cskip| joseph_upper_cols::<FMA>(
        (jx, jy),
        p,
        (k2, s),
        (c0, cskip)
    ));
}

/// Whether a covariance update takes the rank-N form P − W·Wᵀ (see
/// `EkfOf::update_covariance`): the optimal gain (α = 1) at a chain's size with a
/// prior-to-noise ratio up to [`RANK_N_MAX_PRIOR_TO_NOISE`]; the Joseph form otherwise.
#[inline(always)]
fn rank_n_form(alpha: f64, s: usize, prior_to_noise: f64) -> bool {
    alpha == 1.0 && s > ACC_ROWS && prior_to_noise <= RANK_N_MAX_PRIOR_TO_NOISE
}

/// Writes the factors of one measurement update with gain α·K into columns `c0..` of the
/// interleaved X = `jx`, Y = `jy` (S-long columns), so that the update is P ← P − X·Yᵀ,
/// and returns their count: W = P_·z·L⁻ᵀ twice (N columns) when `linv` (L⁻¹ of S_z =
/// L·Lᵀ) is given, the rank-N form; else the Joseph form's [D, K'] and [K', P_·z]
/// interleaved (2N), K' = α·K and D = P_·z − K'·S_z, the same products in the same order
/// as [`joseph_columns`]. `kd` and `d` are S×N scratch. While only rank-N factors are
/// pushed, Y = X and `jy` is not written (`jy_is_jx`, true for `c0` = 0).
#[inline(always)]
fn push_factors<const FMA: bool>(
    (k, pz, sz): (&[f64], &[f64], &[f64]),
    linv: Option<&[f64]>,
    alpha: f64,
    (kd, d): (&mut [f64], &mut [f64]),
    (jx, jy, jy_is_jx): (&mut [f64], &mut [f64], &mut bool),
    c0: usize,
    (n, s): (usize, usize),
) -> usize {
    let col = |c: usize| (c0 + c) * s..(c0 + c + 1) * s;
    if let Some(linv) = linv {
        let w = c0 * s..(c0 + n) * s;
        w_from_pz::<FMA>(pz, linv, &mut jx[w.clone()], n, s);
        if !*jy_is_jx {
            jy[w.clone()].copy_from_slice(&jx[w]);
        }
        return n;
    }
    if *jy_is_jx {
        // Y's columns so far are X's, which `jy` does not hold yet.
        jy[..c0 * s].copy_from_slice(&jx[..c0 * s]);
        *jy_is_jx = false;
    }
    let k: &[f64] = if alpha == 1.0 {
        k
    } else {
        for (a, &b) in kd.iter_mut().zip(k) {
            *a = b * alpha;
        }
        kd
    };
    d.copy_from_slice(pz);
    minus_k_sz::<FMA>(k, sz, d, n, s);
    for m in 0..n {
        let c = m * s..m * s + s;
        jx[col(2 * m)].copy_from_slice(&d[c.clone()]);
        jx[col(2 * m + 1)].copy_from_slice(&k[c.clone()]);
        jy[col(2 * m)].copy_from_slice(&k[c.clone()]);
        jy[col(2 * m + 1)].copy_from_slice(&pz[c]);
    }
    2 * n
}

/// Columns N..2N of P − X·Yᵀ (`cols` factor columns) from those of P in `pv` (S×N)
/// into `out`: column j is P's minus Σ_k X_·k·Y_(N+j)k, summed in register tiles (as
/// [`product_cols`]) and then subtracted (one column-long multiply-add per factor
/// column and joint, each a load, a store and one vector multiply-add, took as long as
/// the whole P·Aᵀ).
#[inline(always)]
fn minus_factor_rows<const FMA: bool>(
    (jx, jy): (&[f64], &[f64]),
    pv: &[f64],
    out: &mut [f64],
    cols: usize,
    (n, s): (usize, usize),
) {
    column_tiles!(n, |c0, cskip| minus_factor_rows_cols::<FMA>(
        (jx, jy),
        (pv, out),
        cols,
        (n, s),
        (c0, cskip)
    ));
}

#[inline(always)]
fn minus_factor_rows_cols<const FMA: bool, const NC: usize>(
    (jx, jy): (&[f64], &[f64]),
    (pv, out): (&[f64], &mut [f64]),
    cols: usize,
    (n, s): (usize, usize),
    (c0, cskip): (usize, usize),
) {
    let mut r0 = 0;
    while r0 < s {
        let len = (s - r0).min(TILE_ROWS);
        let (t0, skip) = full_tile(r0, len, s);
        let acc = tile::<FMA, NC>((jx, s, t0), (jy, s, n + c0), len + skip, cols);
        for (c, a) in acc.iter().enumerate() {
            if c < cskip {
                continue;
            }
            let o = (c0 + c) * s + r0;
            for ((x, &p), &v) in out[o..o + len]
                .iter_mut()
                .zip(&pv[o..o + len])
                .zip(&a[skip..])
            {
                *x = p - v;
            }
        }
        r0 += len;
    }
}

/// Columns `c0 + cskip..c0 + NC` of [`joseph_columns`]' upper triangle (rows up to the
/// last column's diagonal) from its interleaved factors (`k2` columns each), mirrored
/// into the lower triangle. Every row tile is a whole one (S ≥ TILE_ROWS; rows past the
/// diagonal are summed and not written).
#[inline(always)]
fn joseph_upper_cols<const FMA: bool, const NC: usize>(
    (jx, jy): (&[f64], &[f64]),
    p: &mut [f64],
    (k2, s): (usize, usize),
    (c0, cskip): (usize, usize),
) {
    let end = c0 + NC;
    let mut r0 = 0;
    while r0 < end {
        let t0 = r0.min(s.max(TILE_ROWS) - TILE_ROWS);
        let len = (s - t0).min(TILE_ROWS);
        let skip = r0 - t0;
        let acc = tile::<FMA, NC>((jx, s, t0), (jy, s, c0), len, k2);
        if len == TILE_ROWS && skip == 0 && cskip == 0 && r0 + TILE_ROWS <= c0 {
            // A whole tile above the diagonal: its columns are contiguous in the upper
            // triangle and its rows in the lower one, so both are written as vectors (one
            // strided scalar store per entry took as long as the tile's multiply-adds).
            #[cfg(target_arch = "x86_64")]
            if let (true, Ok(acc)) = (FMA, <&[[f64; TILE_ROWS]; 4]>::try_from(&acc[..])) {
                // SAFETY: FMA = true only runs on a CPU with AVX2 and FMA (see `madd`).
                unsafe { avx2::subtract_mirrored(acc, p, s, (r0, c0)) };
                r0 += TILE_ROWS;
                continue;
            }
            let mut u = [[0.0f64; TILE_ROWS]; NC];
            for (c, (uc, a)) in u.iter_mut().zip(&acc).enumerate() {
                let o = (c0 + c) * s + r0;
                if let Ok(col) = <&mut [f64; TILE_ROWS]>::try_from(&mut p[o..o + TILE_ROWS]) {
                    for ((x, y), &v) in uc.iter_mut().zip(col.iter_mut()).zip(a) {
                        *x = *y - v;
                        *y = *x;
                    }
                }
            }
            let rows: [[f64; NC]; TILE_ROWS] =
                std::array::from_fn(|r| std::array::from_fn(|c| u[c][r]));
            for (r, row) in rows.iter().enumerate() {
                let o = (r0 + r) * s + c0;
                if let Ok(dst) = <&mut [f64; NC]>::try_from(&mut p[o..o + NC]) {
                    *dst = *row;
                }
            }
        } else {
            // Every column and row of the tile visited, those not written skipped inside:
            // a dynamic range of tile columns or rows kept the accumulators in memory,
            // and the tile's multiply-adds became scalar.
            for (c, a) in acc.iter().enumerate() {
                let j = c0 + c;
                for (r, &v) in a.iter().enumerate() {
                    let i = t0 + r;
                    if c >= cskip && r >= skip && r < len && i <= j {
                        let x = p[j * s + i] - v;
                        p[j * s + i] = x;
                        p[i * s + j] = x;
                    }
                }
            }
        }
        r0 += TILE_ROWS;
    }
}

/// W = P_·z·L⁻ᵀ (S×N) from the inverse L⁻¹ of the innovation covariance's Cholesky factor
/// (lower: column j of W sums columns m ≤ j of P_·z; the entries above L⁻¹'s diagonal are
/// exact zeros and add nothing), in register tiles as [`product_cols`].
#[inline(always)]
fn w_from_pz<const FMA: bool>(pzs: &[f64], linv: &[f64], ws: &mut [f64], n: usize, s: usize) {
    // A tile's columns j < c0 + NC sum columns m ≤ j of P_·z only: the rest add exact
    // zeros after the sum, which leave it as it is.
    column_tiles!(n, |c0, cskip| product_cols::<FMA>(
        (pzs, (c0 + TILE_COLS).min(n)),
        (linv, n),
        ws,
        s,
        (c0, cskip)
    ));
}

/// Largest prior-to-noise ratio max_j (H·P·Hᵀ)_jj / R_j at which the covariance update
/// uses the rank-N form P − W·Wᵀ. Its rounding grows with the ratio, and the entries it
/// cancels are the correlated ones: on exact data (R at its floor, P₀ from a prior) 1e6
/// still lost definiteness in `tests/identify_methods.rs`, 1e2 did not; the
/// Joseph form keeps P positive definite past it, and the steady state of a filter is
/// well below it.
const RANK_N_MAX_PRIOR_TO_NOISE: f64 = 1e2;

/// Rows and columns of the register tile of [`minus_w_wt`] and [`p_times_at_blocked`]: an
/// 8×4 block of accumulators (eight AVX2 registers) reused over the whole inner sum, so
/// that each multiply-add costs under one load instead of two loads and a store.
const TILE_ROWS: usize = 8;
const TILE_COLS: usize = 4;

/// `C[r, c] = Σ_k X[r0 + r, k]·Y[c0 + c, k]` for one tile of [`TILE_ROWS`] rows (`len`
/// of them if fewer, from a state of fewer rows) and `NC` columns, X's columns `sx` apart
/// in `x`, Y's `sy` apart in `y`, k < `kdim`: returns the accumulators. Shared by P·Aᵀ,
/// W·Wᵀ and the Joseph factors.
#[inline(always)]
fn tile<const FMA: bool, const NC: usize>(
    x: (&[f64], usize, usize),
    y: (&[f64], usize, usize),
    len: usize,
    kdim: usize,
) -> [[f64; TILE_ROWS]; NC] {
    tile_from::<FMA, NC>([[0.0f64; TILE_ROWS]; NC], x, y, len, kdim)
}

/// [`tile`] adding to the accumulators `acc` (the sums of a first factor pair, which a
/// second then continues in the same order).
#[inline(always)]
fn tile_from<const FMA: bool, const NC: usize>(
    acc: [[f64; TILE_ROWS]; NC],
    x: (&[f64], usize, usize),
    y: (&[f64], usize, usize),
    len: usize,
    kdim: usize,
) -> [[f64; TILE_ROWS]; NC] {
    let ((xs, sx, r0), (ys, sy, c0)) = (x, y);
    if len == TILE_ROWS {
        #[cfg(target_arch = "x86_64")]
        if FMA {
            // SAFETY: FMA = true only runs on a CPU with AVX2 and FMA (see `madd`).
            return unsafe { avx2::strided_tile::<NC>(acc, (xs, sx, r0), (ys, sy, c0), kdim) };
        }
        let cols = (0..kdim).map(|k| (k * sx + r0, k * sy + c0));
        return whole_tile_portable::<FMA, NC>(acc, xs, (ys, 1), cols);
    }
    let mut acc = acc;
    for k in 0..kdim {
        let o = k * sx + r0;
        let xv = &xs[o..o + len];
        let yv = column::<NC>(ys, k * sy + c0);
        for (a, &f) in acc.iter_mut().zip(yv) {
            for (av, &xr) in a.iter_mut().zip(xv) {
                *av = madd::<FMA>(f, xr, *av);
            }
        }
    }
    acc
}

/// [`tile`] over a list of columns: X's column k at `x[xo..]`, Y's at `y[yo..]` for each
/// `(xo, yo)` of `offsets` (a chain's Φ: the parameters that enter the tile's rows), in
/// increasing order of both (the last pair bounds the others).
#[inline(always)]
fn tile_listed<const FMA: bool, const NC: usize>(
    (x, r0): (&[f64], usize),
    (y, c0): (&[f64], usize),
    offsets: &[(usize, usize)],
) -> [[f64; TILE_ROWS]; NC] {
    debug_assert!(
        offsets
            .windows(2)
            .all(|w| w[0].0 <= w[1].0 && w[0].1 <= w[1].1),
        "the last offsets must bound the others"
    );
    let cols = offsets.iter().map(|&(xo, yo)| (xo + r0, yo + c0));
    let (xm, ym) = offsets.last().copied().unwrap_or((0, 0));
    let bound = (xm.saturating_add(r0), ym.saturating_add(c0));
    whole_tile::<FMA, NC>([[0.0f64; TILE_ROWS]; NC], x, (y, 1), cols, bound)
}

/// The inner loop of a whole register tile: `acc[c][r] += y[yo + c·ys]·x[xo + r]` for
/// each `(xo, yo)` of `cols`, in order (Y's entries `ys` apart: 1 for a column, S for a
/// row of an S-row matrix). The fused copy holds the accumulators in AVX2 registers
/// explicitly: left to the compiler, the same loop was vectorised or not depending on
/// the code around it in the inlined step (scalar, it took 2.5× the time). `bound` is
/// the largest `(xo, yo)` of `cols`: the fused copy checks it against `x` and `y` once
/// instead of every column's range (those checks were a sixth of the step's
/// instructions, callgrind).
#[inline(always)]
fn whole_tile<const FMA: bool, const NC: usize>(
    acc: [[f64; TILE_ROWS]; NC],
    x: &[f64],
    (y, ys): (&[f64], usize),
    cols: impl Iterator<Item = (usize, usize)>,
    bound: (usize, usize),
) -> [[f64; TILE_ROWS]; NC] {
    #[cfg(target_arch = "x86_64")]
    if FMA {
        // SAFETY: FMA = true only runs on a CPU with AVX2 and FMA (see `madd`).
        return unsafe { avx2::whole_tile::<NC>(acc, x, (y, ys), cols, bound) };
    }
    let _ = bound;
    whole_tile_portable::<FMA, NC>(acc, x, (y, ys), cols)
}

/// [`whole_tile`] as plain loops (the portable copy, and the reference of the fused one).
#[inline(always)]
fn whole_tile_portable<const FMA: bool, const NC: usize>(
    mut acc: [[f64; TILE_ROWS]; NC],
    x: &[f64],
    (y, ys): (&[f64], usize),
    cols: impl Iterator<Item = (usize, usize)>,
) -> [[f64; TILE_ROWS]; NC] {
    for (xo, yo) in cols {
        let xv = column::<TILE_ROWS>(x, xo);
        for (c, a) in acc.iter_mut().enumerate() {
            let f = y[yo + c * ys];
            for r in 0..TILE_ROWS {
                a[r] = madd::<FMA>(f, xv[r], a[r]);
            }
        }
    }
    acc
}

/// The kernels of the fused (AVX2 and FMA) copy that are written with intrinsics: each
/// multiply-add is one fused `vfmadd` per lane, the rounding of `f64::mul_add`, in the
/// order of the portable code, so the bits are those of `madd::<true>`.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{column, TILE_ROWS};
    use std::arch::x86_64::{
        __m256d, _mm256_fmadd_pd, _mm256_loadu_pd, _mm256_maskload_pd, _mm256_permute2f128_pd,
        _mm256_set1_pd, _mm256_setr_epi64x, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd,
        _mm256_unpackhi_pd, _mm256_unpacklo_pd,
    };

    /// Two 4-lane halves of an 8-row column.
    #[inline(always)]
    fn halves(v: &[f64; TILE_ROWS]) -> (&[f64; 4], &[f64; 4]) {
        let (lo, hi) = v.split_at(4);
        (column::<4>(lo, 0), column::<4>(hi, 0))
    }

    /// An accumulator tile in registers: each column's two 4-lane halves.
    type Tile<const NC: usize> = ([__m256d; NC], [__m256d; NC]);

    /// # Safety
    /// The CPU must support AVX2 (see [`whole_tile`]).
    #[inline(always)]
    unsafe fn load_tile<const NC: usize>(acc: &[[f64; TILE_ROWS]; NC]) -> Tile<NC> {
        // SAFETY: AVX2 by the caller; each pointer is a reference to 4 f64.
        unsafe {
            let (mut lo, mut hi) = ([_mm256_setzero_pd(); NC], [_mm256_setzero_pd(); NC]);
            for (c, a) in acc.iter().enumerate() {
                let (a0, a1) = halves(a);
                lo[c] = _mm256_loadu_pd(a0.as_ptr());
                hi[c] = _mm256_loadu_pd(a1.as_ptr());
            }
            (lo, hi)
        }
    }

    /// # Safety
    /// The CPU must support AVX2 (see [`whole_tile`]).
    #[inline(always)]
    unsafe fn store_tile<const NC: usize>((lo, hi): &Tile<NC>) -> [[f64; TILE_ROWS]; NC] {
        let mut out = [[0.0f64; TILE_ROWS]; NC];
        for (c, o) in out.iter_mut().enumerate() {
            let (a, b) = o.split_at_mut(4);
            // SAFETY: AVX2 by the caller; each half of `o` holds the 4 lanes written.
            unsafe {
                _mm256_storeu_pd(a.as_mut_ptr(), lo[c]);
                _mm256_storeu_pd(b.as_mut_ptr(), hi[c]);
            }
        }
        out
    }

    /// Tile column c += f(c)·[x0; x1] for every c (one fused multiply-add per lane).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA (see [`whole_tile`]).
    #[inline(always)]
    unsafe fn madd_columns<const NC: usize>(
        (lo, hi): &mut Tile<NC>,
        (x0, x1): (__m256d, __m256d),
        f: impl Fn(usize) -> f64,
    ) {
        for c in 0..NC {
            // SAFETY: AVX2 and FMA by the caller; registers only.
            unsafe {
                let f = _mm256_set1_pd(f(c));
                lo[c] = _mm256_fmadd_pd(f, x0, lo[c]);
                hi[c] = _mm256_fmadd_pd(f, x1, hi[c]);
            }
        }
    }

    /// [`super::whole_tile`], fused. Not a `#[target_feature]` function (those cannot be
    /// forced inline, and out of line each tile paid a call with its accumulators
    /// through memory): it is inlined into `step_avx2`, whose features the intrinsics
    /// then use.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    pub(super) unsafe fn whole_tile<const NC: usize>(
        acc: [[f64; TILE_ROWS]; NC],
        x: &[f64],
        (y, ys): (&[f64], usize),
        cols: impl Iterator<Item = (usize, usize)>,
        (xmax, ymax): (usize, usize),
    ) -> [[f64; TILE_ROWS]; NC] {
        let y_span = (NC - 1).saturating_mul(ys).saturating_add(1);
        let in_bounds =
            xmax.saturating_add(TILE_ROWS) <= x.len() && ymax.saturating_add(y_span) <= y.len();
        // SAFETY (every intrinsic): the caller guarantees AVX2 and FMA; each pointer
        // comes from a reference to an array of 4 f64, valid for the 4 lanes read or
        // written, or (checked path) from offsets clamped to `xmax`, `ymax`, whose
        // whole column and row were checked to lie inside `x` and `y` above. A wrong
        // bound from the caller gives wrong sums (caught by the tests' comparisons with
        // the portable loop), never an access outside the slices.
        unsafe {
            let mut t = load_tile(&acc);
            if in_bounds {
                let (xp, yp) = (x.as_ptr(), y.as_ptr());
                for (xo, yo) in cols {
                    let (xo, yo) = (xo.min(xmax), yo.min(ymax));
                    let xv = (_mm256_loadu_pd(xp.add(xo)), _mm256_loadu_pd(xp.add(xo + 4)));
                    madd_columns(&mut t, xv, |c| *yp.add(yo + c * ys));
                }
                return store_tile(&t);
            }
            for (xo, yo) in cols {
                let (x0, x1) = halves(column::<TILE_ROWS>(x, xo));
                let xv = (_mm256_loadu_pd(x0.as_ptr()), _mm256_loadu_pd(x1.as_ptr()));
                if ys == 1 {
                    let yv = column::<NC>(y, yo);
                    madd_columns(&mut t, xv, |c| yv[c]);
                } else {
                    madd_columns(&mut t, xv, |c| y[yo + c * ys]);
                }
            }
            store_tile(&t)
        }
    }

    /// [`whole_tile`] on columns `sx` apart in `x` from `r0` and `sy` apart in `y` from
    /// `c0` (Y's entries contiguous), k < `kdim`: the bounds of the last column checked
    /// once, then pointers advanced by the strides (no index arithmetic or range check
    /// per column: the loop is its loads and fused multiply-adds). The same products in
    /// the same order, so the same bits.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[inline(always)]
    pub(super) unsafe fn strided_tile<const NC: usize>(
        acc: [[f64; TILE_ROWS]; NC],
        (x, sx, r0): (&[f64], usize, usize),
        (y, sy, c0): (&[f64], usize, usize),
        kdim: usize,
    ) -> [[f64; TILE_ROWS]; NC] {
        let last = kdim.saturating_sub(1);
        let end = |stride: usize, first: usize, width: usize| {
            last.checked_mul(stride)
                .and_then(|o| o.checked_add(first))
                .and_then(|o| o.checked_add(width))
        };
        let fits = end(sx, r0, TILE_ROWS).is_some_and(|e| e <= x.len())
            && end(sy, c0, NC).is_some_and(|e| e <= y.len());
        if kdim == 0 || !fits {
            let cols = (0..kdim).map(|k| (k * sx + r0, k * sy + c0));
            // SAFETY: AVX2 and FMA by the caller.
            return unsafe { whole_tile::<NC>(acc, x, (y, 1), cols, (usize::MAX, usize::MAX)) };
        }
        // SAFETY (every intrinsic and pointer): AVX2 and FMA by the caller; column k of
        // X is x[k·sx + r0..][..TILE_ROWS] and of Y y[k·sy + c0..][..NC], for k ≤ last
        // inside the slices by the check above.
        unsafe {
            let mut t = load_tile(&acc);
            let (mut xp, mut yp) = (x.as_ptr().add(r0), y.as_ptr().add(c0));
            for _ in 0..kdim {
                let xv = (_mm256_loadu_pd(xp), _mm256_loadu_pd(xp.add(4)));
                madd_columns(&mut t, xv, |c| *yp.add(c));
                // Wrapping: past the last column the pointers are never read.
                (xp, yp) = (xp.wrapping_add(sx), yp.wrapping_add(sy));
            }
            store_tile(&t)
        }
    }

    /// [`super::short_tile`], fused: X's columns loaded with lane masks past `rows`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA (see [`whole_tile`]).
    #[inline(always)]
    pub(super) unsafe fn short_tile<const NC: usize>(
        acc: [[f64; TILE_ROWS]; NC],
        (x, rows): (&[f64], usize),
        (y, ys): (&[f64], usize),
        cols: impl Iterator<Item = (usize, usize)>,
    ) -> [[f64; TILE_ROWS]; NC] {
        let rows = rows.min(TILE_ROWS);
        let lane = |r: usize, l: usize| if l < r { -1i64 } else { 0 };
        // SAFETY (every intrinsic): the caller guarantees AVX2 and FMA; every pointer
        // comes from a range-checked slice of the lanes that are read or written (a
        // masked load reads only its active lanes).
        unsafe {
            let mask =
                |r: usize| _mm256_setr_epi64x(lane(r, 0), lane(r, 1), lane(r, 2), lane(r, 3));
            let (m0, m1) = (mask(rows), mask(rows.saturating_sub(4)));
            let mut t = load_tile(&acc);
            for (xo, yo) in cols {
                let xs = &x[xo..xo + rows];
                let x0 = _mm256_maskload_pd(xs.as_ptr(), m0);
                let x1 = if rows > 4 {
                    _mm256_maskload_pd(xs[4..].as_ptr(), m1)
                } else {
                    _mm256_setzero_pd()
                };
                madd_columns(&mut t, (x0, x1), |c| y[yo + c * ys]);
            }
            store_tile(&t)
        }
    }

    /// Rows `r0..r0 + TILE_ROWS` of P's columns `c0..c0 + 4` (a tile above the diagonal)
    /// minus `acc`, written to the upper triangle by columns and, transposed in registers
    /// four rows at a time, to the lower one by rows: the values of the portable loop
    /// (one subtraction per entry). (Tiles on the diagonal, written with lane masks,
    /// took longer than the portable loop.)
    ///
    /// # Safety
    /// The CPU must support AVX2 (see [`whole_tile`]).
    #[inline(always)]
    pub(super) unsafe fn subtract_mirrored(
        acc: &[[f64; TILE_ROWS]; 4],
        p: &mut [f64],
        s: usize,
        (r0, c0): (usize, usize),
    ) {
        // One range check for the tile: the last column's rows and the last row's
        // columns end every piece read or written (one check per piece was ≈ 2 % of a
        // whole-arm EKF update, callgrind).
        let end = ((c0 + 3) * s + r0 + TILE_ROWS).max((r0 + TILE_ROWS - 1) * s + c0 + 4);
        let base = p[..end].as_mut_ptr();
        // SAFETY (every intrinsic and pointer): the caller guarantees AVX2; every piece
        // read or written, (c0 + c)·s + r0 + 0..8 for c < 4 and (r0 + r)·s + c0 + 0..4
        // for r < 8, ends at or before `end`, inside `p` (checked by the slice above).
        unsafe {
            let mut u = [[_mm256_setzero_pd(); 4]; 2];
            for (c, a) in acc.iter().enumerate() {
                let col = base.add((c0 + c) * s + r0);
                let (a0, a1) = halves(a);
                u[0][c] = _mm256_sub_pd(_mm256_loadu_pd(col), _mm256_loadu_pd(a0.as_ptr()));
                u[1][c] = _mm256_sub_pd(_mm256_loadu_pd(col.add(4)), _mm256_loadu_pd(a1.as_ptr()));
                _mm256_storeu_pd(col, u[0][c]);
                _mm256_storeu_pd(col.add(4), u[1][c]);
            }
            for (h, [c0v, c1v, c2v, c3v]) in u.into_iter().enumerate() {
                // 4×4 transpose: rows of the four columns' pieces.
                let t0 = _mm256_unpacklo_pd(c0v, c1v);
                let t1 = _mm256_unpackhi_pd(c0v, c1v);
                let t2 = _mm256_unpacklo_pd(c2v, c3v);
                let t3 = _mm256_unpackhi_pd(c2v, c3v);
                let rows = [
                    _mm256_permute2f128_pd::<0x20>(t0, t2),
                    _mm256_permute2f128_pd::<0x20>(t1, t3),
                    _mm256_permute2f128_pd::<0x31>(t0, t2),
                    _mm256_permute2f128_pd::<0x31>(t1, t3),
                ];
                for (r, row) in rows.into_iter().enumerate() {
                    _mm256_storeu_pd(base.add((r0 + 4 * h + r) * s + c0), row);
                }
            }
        }
    }
}

/// Entries `o..o + L` of `v` as an array reference: one bounds check for a column of a
/// tile's Y (one per entry, in the tile's inner loop, cost about as many instructions as
/// its multiply-adds). A reference, not a copy: a copied array of X's column made the
/// compiler split the tile into scalar multiply-adds through the stack.
#[inline(always)]
fn column<const L: usize>(v: &[f64], o: usize) -> &[f64; L] {
    v[o..o + L].try_into().unwrap_or(&[0.0; L])
}

/// The tile for rows `r0..r0 + len` of `d`: a whole tile ending at the last row when
/// `len` is short and there are enough rows above (the register tile instead of the
/// short one's loop through memory; each entry's sum is the same), as (first row, rows
/// of it to skip).
#[inline(always)]
fn full_tile(r0: usize, len: usize, d: usize) -> (usize, usize) {
    if len < TILE_ROWS && d >= TILE_ROWS {
        let t0 = r0 + len - TILE_ROWS;
        (t0, r0 - t0)
    } else {
        (r0, 0)
    }
}

/// Writes rows `skip..skip + len` of the tile `acc`, columns `cskip..NC`, into the
/// S-long columns `c0 + c` of `out` at rows `r0..r0 + len` (`r0` is the tile's first
/// row plus `skip`). A whole tile is copied as fixed-size arrays (a copy of run-time
/// length was a call of `memcpy` per column).
#[inline(always)]
fn store_tile<const NC: usize>(
    acc: &[[f64; TILE_ROWS]; NC],
    out: &mut [f64],
    s: usize,
    (r0, len, skip): (usize, usize, usize),
    (c0, cskip): (usize, usize),
) {
    for (c, av) in acc.iter().enumerate() {
        if c < cskip {
            continue;
        }
        let o = (c0 + c) * s + r0;
        if len == TILE_ROWS {
            if let Ok(col) = <&mut [f64; TILE_ROWS]>::try_from(&mut out[o..o + TILE_ROWS]) {
                *col = *av;
            }
        } else {
            out[o..o + len].copy_from_slice(&av[skip..skip + len]);
        }
    }
}

/// The reference for [`joseph_upper`] with X = Y = W in the tests: P ← P − W·Wᵀ (W is
/// S×N) on whole columns, tiled: the sum for entry (i, j) runs over
/// the same products in the same order as for (j, i), so a symmetric P stays exactly so.
#[cfg(test)]
#[inline(always)]
fn minus_w_wt<const FMA: bool>(ws: &[f64], p: &mut [f64], n: usize, s: usize) {
    column_tiles!(s, |c0, cskip| minus_w_wt_cols::<FMA>(
        ws,
        p,
        n,
        s,
        (c0, cskip)
    ));
}

#[cfg(test)]
#[inline(always)]
fn minus_w_wt_cols<const FMA: bool, const NC: usize>(
    ws: &[f64],
    p: &mut [f64],
    n: usize,
    s: usize,
    (c0, cskip): (usize, usize),
) {
    let mut r0 = 0;
    while r0 < s {
        let len = (s - r0).min(TILE_ROWS);
        let (t0, skip) = full_tile(r0, len, s);
        let acc = tile::<FMA, NC>((ws, s, t0), (ws, s, c0), len + skip, n);
        for (c, a) in acc.iter().enumerate() {
            if c < cskip {
                continue;
            }
            let col = &mut p[(c0 + c) * s + r0..(c0 + c) * s + r0 + len];
            for (pv, &av) in col.iter_mut().zip(&a[skip..]) {
                *pv -= av;
            }
        }
        r0 += len;
    }
}

/// G = X·Aᵀ (S×N) for X given by `kdim` S-long columns (P itself: `kdim` = S) and A (N×kdim)
/// on whole columns, tiled as [`minus_w_wt`]; for run-time sizes, where A (the chain's
/// −M⁻¹·Φ and its q, q̇ derivatives) is dense and skipping zeros would not pay.
#[inline(always)]
fn p_times_at_blocked<const FMA: bool>(
    ps: &[f64],
    a: &[f64],
    gs: &mut [f64],
    n: usize,
    s: usize,
    kdim: usize,
) {
    column_tiles!(n, |c0, cskip| product_cols::<FMA>(
        (ps, kdim),
        (a, n),
        gs,
        s,
        (c0, cskip)
    ));
}

/// Columns `c0 + cskip..c0 + NC` of C = X·Yᵀ (S-long columns, X's `kdim` columns S
/// apart, Y's `sy` apart) into `out`, whole columns in register tiles ([`tile`]).
#[inline(always)]
fn product_cols<const FMA: bool, const NC: usize>(
    (x, kdim): (&[f64], usize),
    (y, sy): (&[f64], usize),
    out: &mut [f64],
    s: usize,
    (c0, cskip): (usize, usize),
) {
    let mut r0 = 0;
    while r0 < s {
        let len = (s - r0).min(TILE_ROWS);
        let (t0, skip) = full_tile(r0, len, s);
        let acc = tile::<FMA, NC>((x, s, t0), (y, sy, c0), len + skip, kdim);
        store_tile(&acc, out, s, (r0, len, skip), (c0, cskip));
        r0 += len;
    }
}

/// Lower Cholesky factor of a small SPD n×n matrix (column-major slices) into `l`;
/// `false` if a pivot is not positive.
#[inline(always)]
fn cholesky(a: &[f64], n: usize, l: &mut [f64]) -> bool {
    l.fill(0.0);
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= l[k * n + j] * l[k * n + j];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let djj = d.sqrt();
        l[j * n + j] = djj;
        let inv = 1.0 / djj;
        for i in j + 1..n {
            let mut s = a[j * n + i];
            for k in 0..j {
                s -= l[k * n + i] * l[k * n + j];
            }
            l[j * n + i] = s * inv;
        }
    }
    true
}

/// Inverse of a lower-triangular n×n matrix with a positive diagonal (column-major
/// slices), by forward substitution.
#[inline(always)]
fn lower_triangular_inverse(l: &[f64], n: usize, inv: &mut [f64]) {
    inv.fill(0.0);
    for j in 0..n {
        inv[j * n + j] = 1.0 / l[j * n + j];
        for i in j + 1..n {
            let mut s = 0.0;
            for k in j..i {
                s += l[k * n + i] * inv[j * n + k];
            }
            inv[j * n + i] = -s / l[i * n + i];
        }
    }
}

/// Copies rows `0..rows` of the upper triangle of the column-major d×d `p`, columns up
/// to `cols`, onto the lower one: row i of the upper triangle (strided) becomes column i
/// below the diagonal (contiguous).
#[inline(always)]
fn mirror_upper_rows(p: &mut [f64], d: usize, rows: usize, cols: usize) {
    for i in 0..rows.min(d) {
        for j in i + 1..cols.min(d) {
            p[i * d + j] = p[j * d + i];
        }
    }
}

/// Copies rows `rows..d` of columns `0..rows` of the column-major d×d `p` (contiguous)
/// onto the upper triangle's rows `0..rows` (strided), in 4×4 blocks: a block's four
/// column pieces are read as vectors and written as four row pieces, which are columns
/// of the upper triangle again.
#[inline(always)]
fn mirror_lower_rows(p: &mut [f64], d: usize, rows: usize) {
    const B: usize = 4;
    let mut i = 0;
    while i < rows {
        let w = (rows - i).min(B);
        let mut j = rows;
        while j < d {
            if w == B && j + B <= d {
                let a: [[f64; B]; B] = std::array::from_fn(|c| {
                    let o = (i + c) * d + j;
                    *column::<B>(p, o)
                });
                let rows: [[f64; B]; B] = std::array::from_fn(|r| std::array::from_fn(|c| a[c][r]));
                for (r, row) in rows.iter().enumerate() {
                    let o = (j + r) * d + i;
                    if let Ok(dst) = <&mut [f64; B]>::try_from(&mut p[o..o + B]) {
                        *dst = *row;
                    }
                }
                j += B;
            } else {
                for c in i..i + w {
                    p[j * d + c] = p[c * d + j];
                }
                j += 1;
            }
        }
        i += w;
    }
}

/// Copies the upper triangle of the column-major d×d `p` onto the lower one, in 8×8 tiles:
/// a row of the upper triangle is strided in memory, and a tile reads each cache line of
/// it once instead of once per element (a 78×78 P does not fit in L1).
#[inline(always)]
fn mirror_upper(p: &mut [f64], d: usize) {
    const T: usize = 8;
    for jb in (0..d).step_by(T) {
        let je = (jb + T).min(d);
        for ib in (jb..d).step_by(T) {
            let ie = (ib + T).min(d);
            for j in jb..je {
                for i in ib.max(j + 1)..ie {
                    p[j * d + i] = p[i * d + j];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::Sample;
    use crate::Robot;

    /// Uniform numbers in [−0.5, 0.5) from a xorshift generator seeded with `seed`: the
    /// random data of the kernel tests, reproducible without a dependency.
    fn xorshift(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// The portable kernels, and the fused ones (AVX2 and FMA) where the CPU has them.
    fn fma_modes() -> Vec<bool> {
        if cpu_has_avx2_fma() {
            vec![false, true]
        } else {
            vec![false]
        }
    }

    /// The AVX2/FMA copy of the step and the portable one compute the same filter (up to
    /// the rounding of fused multiply-adds).
    #[test]
    fn portable_and_avx2_paths_agree() {
        let robot = Robot::paper();
        let (model, lambda) = (robot.model(), robot.base_parameters());
        let cfg = EkfConfig::default();
        let mut fast = PrrrpEkf::new(model, lambda * 1.2, cfg).unwrap();
        let mut portable = fast.clone();
        portable.avx2 = false;
        let zero = crate::Vec5::zeros();
        // The true arm under gravity compensation plus a small sinusoidal torque,
        // integrated with 20 Euler sub-steps per sample.
        let (mut q, mut v) = (zero, zero);
        for k in 0..200 {
            let t = k as f64 * cfg.dt;
            let tau = model.inverse_dynamics(&q, &zero, &zero, &lambda)
                + crate::Vec5::from_fn(|j, _| 0.05 * (t * (1.0 + j as f64)).sin());
            let s = Sample::new(&q, &v, &zero, &tau);
            let a = *fast.step(s).unwrap();
            let b = *portable.step(s).unwrap();
            assert!((a - b).amax() <= 1e-9 * lambda.amax(), "k {k}: {a} vs {b}");
            let h = cfg.dt / 20.0;
            for _ in 0..20 {
                let acc = model.forward_dynamics(&q, &v, &tau, &lambda).unwrap();
                q += h * v;
                v += h * acc;
            }
        }
        let dp = (fast.covariance() - portable.covariance()).amax();
        assert!(dp <= 1e-9 * fast.covariance().amax(), "{dp}");
    }

    /// The time update's partial mirroring (rows of q and q̇ only, when P is exactly
    /// symmetric) gives the bits of mirroring the whole triangle, at a chain's size, from
    /// a P₀ symmetric only to round-off (which the first update must mirror whole), and P
    /// stays exactly symmetric.
    #[test]
    fn partial_mirror_equals_full_mirror() {
        use crate::{BaseOptions, SerialChain};
        use nalgebra::DVector;
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let beta = model.chain_base_values().clone();
        let n = chain.dof();
        let cfg = EkfConfig {
            measurement: EkfMeasurement::PositionsVelocities,
            ..EkfConfig::default()
        };
        let mut a = DynEkf::new(model, &beta * 1.1, cfg).unwrap();
        let s = a.covariance().nrows();
        assert!(s > ACC_ROWS, "the test needs a chain-sized state, S = {s}");
        let mut p0 = a.covariance().clone();
        p0[(1, 0)] += 1e-13 * p0[(0, 0)];
        a.set_initial_covariance(&p0).unwrap();
        a.set_parameter_anchor(&beta).unwrap();
        assert!(!a.p_symmetric);
        let mut b = a.clone();
        for k in 0..300 {
            let t = k as f64 * cfg.dt;
            let f = |d: usize| -> DVector<f64> {
                DVector::from_fn(n, |j, _| {
                    let w = 1.0 + 0.3 * j as f64;
                    0.5 * w.powi(d as i32)
                        * (w * t + (d as f64 + j as f64) * std::f64::consts::FRAC_PI_2).sin()
                })
            };
            let (q, qd, qdd) = (f(0), f(1), f(2));
            let tau = chain
                .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
                .unwrap();
            let tau = DVector::from_vec(tau);
            let sample = SampleOf::new(&q, &qd, &qdd, &tau);
            b.p_symmetric = false;
            a.step(sample).unwrap();
            b.step(sample).unwrap();
            assert_eq!(a.covariance(), b.covariance(), "k {k}");
            assert_eq!(a.covariance(), &a.covariance().transpose(), "k {k}");
        }
        assert!(a.p_symmetric);
    }

    /// The position and velocity updates as formed by the filter (both gains before P
    /// is touched, the velocity gain from P's velocity columns after the first update, P
    /// updated once by both) against the textbook sequence on random data: K₁ = P·H₁ᵀ·
    /// (H₁·P·H₁ᵀ + R₁)⁻¹, the Joseph form (I − αK₁H₁)·P·(I − αK₁H₁)ᵀ + α²K₁R₁K₁ᵀ, then the
    /// same for the velocities from that P, computed densely by nalgebra, for a
    /// chain-sized state (the rank-N form at a low prior-to-noise ratio and α = 1, the
    /// Joseph form otherwise), damped and not.
    #[test]
    fn combined_updates_match_the_sequential_textbook_form() {
        use crate::{BaseOptions, SerialChain};
        use nalgebra::DMatrix;
        fn check<M, N: Dim, P: Dim, S: Dim>(f: &mut EkfOf<M, N, P, S>, seed: u64)
        where
            M: LinearModel<N, P>,
            DefaultAllocator: EkfAllocator<N, P, S>,
        {
            let mut rnd = xorshift(seed);
            let (n, s) = (f.n(), f.x.nrows());
            let (nd, _) = f.model.dims();
            // Noise levels giving prior-to-noise ratios around 1 (rank-N form) and 1e4
            // (Joseph form).
            for (noise, alpha) in [(1.0, 1.0), (1e-4, 1.0), (1.0, 0.5), (1e-4, 0.25)] {
                let b = DMatrix::from_fn(s, s, |_, _| rnd());
                let p = &b * b.transpose() + DMatrix::identity(s, s) * 0.1;
                let x = DMatrix::from_fn(s, 1, |_, _| rnd());
                let zq = DMatrix::from_fn(n, 1, |_, _| rnd());
                let zv = DMatrix::from_fn(n, 1, |_, _| rnd());
                let r1 = DMatrix::from_fn(n, 1, |i, _| noise * (1.0 + i as f64));
                let r2 = DMatrix::from_fn(n, 1, |i, _| noise * (2.0 + 0.5 * i as f64));
                f.p.as_mut_slice().copy_from_slice(p.as_slice());
                f.x.as_mut_slice().copy_from_slice(x.as_slice());
                f.r_pos.as_mut_slice().copy_from_slice(r1.as_slice());
                f.r_vel.as_mut_slice().copy_from_slice(r2.as_slice());
                f.p_symmetric = true;
                let zq_n = OVector::<f64, N>::from_iterator_generic(nd, U1, zq.iter().copied());
                let zv_n = OVector::<f64, N>::from_iterator_generic(nd, U1, zv.iter().copied());
                f.position_gain::<false>(&zq_n).unwrap();
                let cols = f
                    .candidate_and_factors::<false>(true, Some(&zv_n), alpha)
                    .unwrap();
                f.subtract_factors::<false>(cols);

                let (mut pw, mut xw) = (p.clone(), x.clone());
                for (o, z, r) in [(0, &zq, &r1), (n, &zv, &r2)] {
                    let h = DMatrix::from_fn(n, s, |i, j| if j == o + i { 1.0 } else { 0.0 });
                    let rm = DMatrix::from_diagonal(&r.column(0).into_owned());
                    let sz = &h * &pw * h.transpose() + &rm;
                    let k = &pw * h.transpose() * sz.try_inverse().unwrap() * alpha;
                    xw = &xw + &k * (z - &h * &xw);
                    let ikh = DMatrix::identity(s, s) - &k * &h;
                    pw = &ikh * &pw * ikh.transpose() + &k * &rm * k.transpose();
                }
                let got = DMatrix::from_column_slice(s, s, f.p.as_slice());
                let err = (&got - &pw).amax() / pw.amax();
                assert!(err <= 1e-12, "S {s}, noise {noise}, α {alpha}: P {err:e}");
                let gx = DMatrix::from_column_slice(s, 1, f.buf.candidate.as_slice());
                let err = (&gx - &xw).amax() / xw.amax();
                assert!(err <= 1e-12, "S {s}, noise {noise}, α {alpha}: x {err:e}");
                assert_eq!(got, got.transpose(), "S {s}: not exactly symmetric");
            }
        }
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let beta = model.chain_base_values().clone();
        let mut big = DynEkf::new(model, beta, EkfConfig::default()).unwrap();
        assert!(big.x.nrows() > ACC_ROWS);
        check(&mut big, 0x1234_5678_9ABC_DEF1);
    }

    /// The time update with ∂q̈/∂λ in factors (P_·λ·Φᵀ over Φ's non-zeros, then −M⁻¹)
    /// against the one with the model's assembled A = [A_q, A_v, −M⁻¹·Φ] (G = P·Aᵀ as
    /// written), and for the explicit Euler step against F·P·Fᵀ + Q formed densely by
    /// nalgebra: random SPD P and states on the PUMA 560 (S > 32), at the predicted and
    /// the data's acceleration, stiff and not, plain and fused multiply-adds.
    #[test]
    fn factored_time_update_matches_the_assembled_one() {
        use crate::{BaseOptions, SerialChain};
        use nalgebra::{DMatrix, DVector};
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let beta = model.chain_base_values().clone();
        let n = chain.dof();
        let mut rnd = xorshift(0xD1B5_4A32_D192_ED03u64);
        let cases = [
            (
                ParameterJacobian::Predicted,
                Discretisation::Euler,
                1e-3,
                false,
            ),
            (
                ParameterJacobian::DataAcceleration,
                Discretisation::Euler,
                1e-3,
                false,
            ),
            (
                ParameterJacobian::DataAcceleration,
                Discretisation::SecondOrder,
                1e-3,
                false,
            ),
            (
                ParameterJacobian::DataAcceleration,
                Discretisation::Euler,
                0.5,
                true,
            ),
            (
                ParameterJacobian::Predicted,
                Discretisation::SecondOrder,
                0.5,
                true,
            ),
        ];
        for (jac, disc, dt, stiff) in cases {
            for fma in fma_modes() {
                let cfg = EkfConfig {
                    measurement: EkfMeasurement::PositionsVelocities,
                    parameter_jacobian: jac,
                    discretisation: disc,
                    dt,
                    ..EkfConfig::default()
                };
                let mut f = DynEkf::new(model.clone(), beta.clone(), cfg).unwrap();
                f.set_stiff_handling(true);
                let s = f.x.nrows();
                assert!(s > ACC_ROWS);
                let b = DMatrix::from_fn(s, s, |_, _| rnd());
                let p = &b * b.transpose() * 1e-2 + DMatrix::identity(s, s) * 1e-3;
                f.p.copy_from(&p);
                f.p_symmetric = true;
                for i in 0..2 * n {
                    f.x[i] = 2.0 * rnd();
                }
                let v = |r: &mut dyn FnMut() -> f64| DVector::from_fn(n, |_, _| 4.0 * r());
                let (q, qd, qdd, tau) = (v(&mut rnd), v(&mut rnd), v(&mut rnd), v(&mut rnd));
                let sample = SampleOf::new(&q, &qd, &qdd, &tau);
                let mut r = f.clone();
                r.use_factors = false;
                f.derivatives(false, sample).unwrap();
                r.derivatives(false, sample).unwrap();
                assert!(f.buf.factored && !r.buf.factored);
                // The model's factors: the same q, q̇ derivatives, −M⁻¹·Φ = ∂q̈/∂λ.
                assert_eq!(f.buf.fd.dqdd_dq, r.buf.fd.dqdd_dq);
                assert_eq!(f.buf.fd.dqdd_dqd, r.buf.fd.dqdd_dqd);
                if jac == ParameterJacobian::DataAcceleration {
                    // Φ at q̈_data, bit for bit the regressor's (the derivatives reuse the
                    // Newton–Euler pass's kinematics).
                    let mut phi = DMatrix::zeros(n, s - 2 * n);
                    let mut ws = f.model.workspace();
                    let (bq, bv) = (&f.buf.q, &f.buf.v);
                    f.model
                        .regressor_into(&mut ws, bq, bv, &qdd, &mut phi)
                        .unwrap();
                    assert_eq!(phi, f.buf.fd.dqdd_dlambda);
                }
                let dl = -&f.buf.minv * &f.buf.fd.dqdd_dlambda;
                let err = (&dl - &r.buf.fd.dqdd_dlambda).amax();
                assert!(err <= 1e-12 * dl.amax(), "∂q̈/∂λ: {err:e}");
                let a = DMatrix::from_column_slice(n, s, {
                    assemble_a(&r.buf.fd, r.buf.a.as_mut_slice(), n);
                    r.buf.a.as_slice()
                });
                if fma {
                    f.predict::<true>();
                    r.predict::<true>();
                } else {
                    f.predict::<false>();
                    r.predict::<false>();
                }
                assert_eq!(
                    f.stiff_steps(),
                    usize::from(stiff),
                    "{jac:?} {disc:?} h {dt}"
                );
                assert_eq!(r.stiff_steps(), usize::from(stiff));
                let err = (f.covariance() - r.covariance()).amax() / r.covariance().amax();
                assert!(err <= 1e-12, "{jac:?} {disc:?} h {dt} fma {fma}: P {err:e}");
                assert_eq!(f.covariance(), &f.covariance().transpose());
                let err = (f.state() - r.state()).amax() / r.state().amax();
                assert!(err <= 1e-14, "{jac:?} h {dt}: x {err:e}");
                if disc == Discretisation::Euler && !stiff {
                    let mut fm = DMatrix::identity(s, s);
                    for i in 0..n {
                        fm[(i, n + i)] += dt;
                        for k in 0..s {
                            fm[(n + i, k)] += dt * a[(i, k)];
                        }
                    }
                    let want = &fm * &p * fm.transpose()
                        + DMatrix::from_diagonal(&DVector::from_column_slice(f.q_diag.as_slice()));
                    let err = (f.covariance() - &want).amax() / want.amax();
                    assert!(err <= 1e-12, "{jac:?} fma {fma}: F·P·Fᵀ + Q {err:e}");
                }
            }
        }
    }

    /// The stiff step's solve, eliminating A column by column, against the textbook
    /// elimination row by row (bit for bit: the same operations on every entry, in the
    /// same order) and against L·X = A (to round-off), on random systems that pivot and
    /// have zero multipliers.
    #[test]
    fn column_wise_solve_matches_row_wise_elimination() {
        use nalgebra::{DMatrix, DVector};
        fn rows(l: &mut [f64], n: usize, a: &mut [f64], b: &mut [f64]) {
            let m = a.len() / n;
            for k in 0..n {
                let mut p = k;
                for i in k + 1..n {
                    if l[k * n + i].abs() > l[k * n + p].abs() {
                        p = i;
                    }
                }
                if p != k {
                    for j in 0..n {
                        l.swap(j * n + k, j * n + p);
                    }
                    for j in 0..m {
                        a.swap(j * n + k, j * n + p);
                    }
                    b.swap(k, p);
                }
                let piv = l[k * n + k];
                for i in k + 1..n {
                    let f = l[k * n + i] / piv;
                    if f == 0.0 {
                        continue;
                    }
                    l[k * n + i] = 0.0;
                    for j in k + 1..n {
                        l[j * n + i] -= f * l[j * n + k];
                    }
                    for j in 0..m {
                        a[j * n + i] -= f * a[j * n + k];
                    }
                    b[i] -= f * b[k];
                }
            }
            for x in a.chunks_exact_mut(n).chain(std::iter::once(b)) {
                for i in (0..n).rev() {
                    let mut v = x[i];
                    for j in i + 1..n {
                        v -= l[j * n + i] * x[j];
                    }
                    x[i] = v / l[i * n + i];
                }
            }
        }
        let mut rnd = xorshift(0x6A09_E667_F3BC_C909u64);
        for (n, m, trial) in [(7usize, 78usize, 0), (7, 78, 1), (6, 45, 2), (1, 3, 3)] {
            let l0 = DMatrix::from_fn(n, n, |i, j| {
                // Some exact zeros below the diagonal (zero multipliers), and a weak
                // diagonal so that rows are swapped.
                if i > j && (i + j + trial) % 3 == 0 {
                    0.0
                } else if i == j {
                    0.1 * rnd()
                } else {
                    rnd()
                }
            });
            let a0 = DMatrix::from_fn(n, m, |_, _| rnd());
            let b0 = DVector::from_fn(n, |_, _| rnd());
            let (mut l, mut a, mut b) = (l0.clone(), a0.clone(), b0.clone());
            assert!(solve_in_place(
                l.as_mut_slice(),
                n,
                a.as_mut_slice(),
                b.as_mut_slice()
            ));
            let (mut lr, mut ar, mut br) = (l0.clone(), a0.clone(), b0.clone());
            rows(lr.as_mut_slice(), n, ar.as_mut_slice(), br.as_mut_slice());
            assert_eq!(a, ar, "n {n}");
            assert_eq!(b, br, "n {n}");
            let res = (&l0 * &a - &a0).amax().max((&l0 * &b - &b0).amax());
            let scale = a.amax().max(b.amax()) * l0.amax();
            assert!(res <= 1e-13 * scale, "n {n}: residual {res:e}");
        }
    }

    /// The fused register tiles (AVX2 intrinsics) against the portable loops with fused
    /// multiply-adds on random data, bit for bit: tile widths 1 to 4, Y's entries
    /// contiguous and S apart, a continued sum, listed columns in any order, and X's
    /// columns of 1 to 8 entries.
    #[test]
    fn fused_tile_matches_the_portable_loop() {
        if !cpu_has_avx2_fma() {
            return;
        }
        fn check<const NC: usize>(rnd: &mut impl FnMut() -> f64) {
            let (s, k) = (37usize, 23usize);
            let x: Vec<f64> = (0..s * k).map(|_| rnd()).collect();
            let y: Vec<f64> = (0..s * (k + NC)).map(|_| rnd()).collect();
            let acc: [[f64; TILE_ROWS]; NC] =
                std::array::from_fn(|_| std::array::from_fn(|_| rnd()));
            let cols: Vec<(usize, usize)> = (0..k)
                .map(|j| ((j * 7) % k, (j * 5) % k))
                .map(|(a, b)| (a * s + (a % (s - TILE_ROWS)), b * s + (b % 9)))
                .collect();
            let exact = cols
                .iter()
                .fold((0, 0), |(a, b), &(xo, yo)| (a.max(xo), b.max(yo)));
            for ys in [1, s] {
                let want = whole_tile_portable::<true, NC>(acc, &x, (&y, ys), cols.iter().copied());
                // The bound checked once (exact), and a bound past the slices, which
                // takes the loop that checks every column.
                for bound in [exact, (x.len(), y.len())] {
                    // SAFETY: the CPU has AVX2 and FMA (checked above).
                    let got = unsafe {
                        avx2::whole_tile::<NC>(acc, &x, (&y, ys), cols.iter().copied(), bound)
                    };
                    assert_eq!(
                        got, want,
                        "NC {NC}, Y's entries {ys} apart, bound {bound:?}"
                    );
                }
            }
            // Columns at fixed strides (P·Aᵀ, the Joseph factors), the last ending at the
            // end of X and of Y; none.
            for (sx, r0, sy, c0, kdim) in [(s, s - TILE_ROWS, s, s - NC, k), (1, 3, 2, 1, 0)] {
                let cols = (0..kdim).map(|j| (j * sx + r0, j * sy + c0));
                let want = whole_tile_portable::<true, NC>(acc, &x, (&y, 1), cols);
                let (xs, ys) = (&x[..s * k], &y[..s * k]);
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                let got =
                    unsafe { avx2::strided_tile::<NC>(acc, (xs, sx, r0), (ys, sy, c0), kdim) };
                assert_eq!(got, want, "NC {NC}, strides {sx}, {sy}, {kdim} columns");
            }
            // Columns of 1 to 8 entries, the last one ending at the end of X (a load of
            // the whole 8 rows would run past it).
            for rows in 1..=TILE_ROWS {
                let xs = &x[..rows * k];
                let cols = (0..k).map(|j| (j * rows, (j * 5) % k * s + j % 3));
                let want = short_tile_portable::<true, NC>(acc, (xs, rows), (&y, s), cols.clone());
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                let got = unsafe { avx2::short_tile::<NC>(acc, (xs, rows), (&y, s), cols) };
                assert_eq!(got, want, "NC {NC}, {rows} rows");
            }
        }
        let mut rnd = xorshift(0x6A09_E667_F3BC_C909u64);
        check::<1>(&mut rnd);
        check::<2>(&mut rnd);
        check::<3>(&mut rnd);
        check::<4>(&mut rnd);
    }

    /// The factored time products against nalgebra's dense ones on random data: G = P·Aᵀ
    /// and A·G for A = [A_q, A_v, C·Φ], with Φ half zeros (and a zero column) as a
    /// chain's, for 3, 7 and 9 joints (column tiles narrower than, overlapping at and
    /// past the register tile; past TILE_ROWS joints the column loops), plain and fused.
    #[test]
    fn factored_time_products_match_the_dense_products() {
        use nalgebra::DMatrix;
        let mut rnd = xorshift(0xBB67_AE85_84CA_A73Bu64);
        for (n, np) in [(3usize, 30usize), (7, 64), (9, 40)] {
            let s = 2 * n + np;
            let b = DMatrix::from_fn(s, s, |_, _| rnd());
            let p = &b * b.transpose();
            let af = DMatrix::from_fn(n, 3 * n, |_, _| rnd());
            let phi = DMatrix::from_fn(n, np, |i, k| {
                let v = rnd();
                if k == 5 || (i * 3 + k) % 5 < 2 {
                    0.0
                } else {
                    v
                }
            });
            let c = af.columns(2 * n, n).into_owned();
            let mut a = DMatrix::zeros(n, s);
            a.columns_mut(0, 2 * n).copy_from(&af.columns(0, 2 * n));
            a.columns_mut(2 * n, np).copy_from(&(&c * &phi));
            let g_want = &p * a.transpose();
            let apa_want = &a * &g_want;
            for fma in fma_modes() {
                let mut g = DMatrix::from_element(s, n, f64::NAN);
                let mut apa = DMatrix::from_element(n, n, f64::NAN);
                let mut xg = vec![0.0; s * n];
                let mut nz = vec![(0, 0); np];
                let n4 = n.div_ceil(4) * 4;
                let mut u = vec![0.0; (TILE_ROWS * n).max(n4 + 2 * n4 * n)];
                let args = (p.as_slice(), af.as_slice(), phi.as_slice());
                let scratch = (xg.as_mut_slice(), nz.as_mut_slice(), u.as_mut_slice());
                let out = (g.as_mut_slice(), apa.as_mut_slice());
                if fma {
                    factored_time_products::<true>(args.0, args.1, args.2, scratch, out, n, s);
                } else {
                    factored_time_products::<false>(args.0, args.1, args.2, scratch, out, n, s);
                }
                let err = (&g - &g_want).amax() / g_want.amax();
                assert!(err <= 1e-13, "N {n} fma {fma}: G {err:e}");
                let err = (&apa - &apa_want).amax() / apa_want.amax();
                assert!(err <= 1e-13, "N {n} fma {fma}: A·G {err:e}");
            }
        }
    }

    /// The tiled P·Aᵀ of run-time sizes against nalgebra's product on random data (state
    /// counts with a short last tile, and below one tile).
    #[test]
    fn p_times_at_tiles_match_the_product() {
        use nalgebra::DMatrix;
        let mut rnd = xorshift(0x9E37_79B9_7F4A_7C15u64);
        for (n, s) in [(7usize, 78usize), (6, 45), (2, 6)] {
            let p = DMatrix::from_fn(s, s, |_, _| rnd());
            let a = DMatrix::from_fn(n, s, |_, _| rnd());
            let want = &p * a.transpose();
            let mut got = DMatrix::from_element(s, n, f64::NAN);
            p_times_at_blocked::<false>(p.as_slice(), a.as_slice(), got.as_mut_slice(), n, s, s);
            let err = (&got - &want).amax();
            assert!(err <= 1e-14 * s as f64, "S {s}: {err:e}");
        }
    }

    /// The tiled Joseph kernel of larger states against the plain formula on random
    /// data: the upper triangle of P − K'·P_z·ᵀ − D·K'ᵀ (S×N factors; fused and plain
    /// multiply-adds, state counts past one tile and ragged), copied exactly onto the
    /// lower one.
    #[test]
    fn joseph_tiles_match_the_formula() {
        use nalgebra::DMatrix;
        let mut rnd = xorshift(0x2545_F491_4F6C_DD1Du64);
        for (n, s) in [(7usize, 78usize), (3, 33), (6, 81)] {
            let k = DMatrix::from_fn(s, n, |_, _| rnd());
            let d = DMatrix::from_fn(s, n, |_, _| rnd());
            let pz = DMatrix::from_fn(s, n, |_, _| rnd());
            let b = DMatrix::from_fn(s, s, |_, _| rnd());
            let p = &b * b.transpose();
            let want = &p - &k * pz.transpose() - &d * k.transpose();
            let (mut jx, mut jy) = (vec![0.0; 2 * s * n], vec![0.0; 2 * s * n]);
            for fma in fma_modes() {
                let mut got = p.clone();
                let args = (k.as_slice(), d.as_slice(), pz.as_slice());
                let scratch = (jx.as_mut_slice(), jy.as_mut_slice());
                if fma {
                    joseph_columns::<true>(
                        args.0,
                        args.1,
                        args.2,
                        got.as_mut_slice(),
                        n,
                        s,
                        scratch,
                    );
                } else {
                    joseph_columns::<false>(
                        args.0,
                        args.1,
                        args.2,
                        got.as_mut_slice(),
                        n,
                        s,
                        scratch,
                    );
                }
                assert_eq!(got, got.transpose(), "S {s}: not exactly symmetric");
                for j in 0..s {
                    for i in 0..=j {
                        let err = (got[(i, j)] - want[(i, j)]).abs();
                        assert!(
                            err <= 1e-14 * (n as f64 + p.amax()),
                            "S {s} ({i}, {j}): {err:e}"
                        );
                    }
                }
            }
        }
    }

    /// The kernels that replace the gain and the whole-column rank-N update at a chain's
    /// size, against the plain formulas on random data: the state step α·P_·z·S_z⁻¹·ν from
    /// L⁻¹ (nalgebra's inverse of S_z), and P − W·Wᵀ on the upper triangle mirrored as
    /// written (bit for bit the whole-column kernel's, and nalgebra's product to
    /// round-off), plain and fused multiply-adds.
    #[test]
    fn step_and_triangle_kernels_match_the_plain_formulas() {
        use nalgebra::{DMatrix, DVector};
        let mut rnd = xorshift(0x3C6E_F372_FE94_F82Bu64);
        for (n, s) in [(7usize, 78usize), (3, 33), (6, 81)] {
            for fma in fma_modes() {
                let pz = DMatrix::from_fn(s, n, |_, _| rnd());
                let b = DMatrix::from_fn(n, n, |_, _| rnd());
                let sz = &b * b.transpose() + DMatrix::identity(n, n) * 0.5;
                let nu = DVector::from_fn(n, |_, _| rnd());
                let x0 = DVector::from_fn(s, |_, _| rnd());
                let alpha = 0.5;
                let want = &x0 + &pz * (sz.clone().try_inverse().unwrap() * &nu) * alpha;
                let mut l = vec![0.0; n * n];
                assert!(cholesky(sz.as_slice(), n, &mut l));
                let mut linv = vec![0.0; n * n];
                lower_triangular_inverse(&l, n, &mut linv);
                let (mut y, mut z, mut x) = (nu.clone(), vec![0.0; n], x0.clone());
                let args = (pz.as_slice(), linv.as_slice(), y.as_mut_slice());
                if fma {
                    step_from_factor::<true>(
                        args.0,
                        args.1,
                        args.2,
                        &mut z,
                        alpha,
                        x.as_mut_slice(),
                        n,
                        s,
                    );
                } else {
                    step_from_factor::<false>(
                        args.0,
                        args.1,
                        args.2,
                        &mut z,
                        alpha,
                        x.as_mut_slice(),
                        n,
                        s,
                    );
                }
                let err = (&x - &want).amax() / want.amax();
                assert!(err <= 1e-13, "S {s} fma {fma}: step {err:e}");

                let w = DMatrix::from_fn(s, n, |_, _| rnd());
                let c = DMatrix::from_fn(s, s, |_, _| rnd());
                let p = &c * c.transpose();
                let (mut tri, mut cols) = (p.clone(), p.clone());
                if fma {
                    joseph_upper::<true>(w.as_slice(), w.as_slice(), tri.as_mut_slice(), n, s);
                    minus_w_wt::<true>(w.as_slice(), cols.as_mut_slice(), n, s);
                } else {
                    joseph_upper::<false>(w.as_slice(), w.as_slice(), tri.as_mut_slice(), n, s);
                    minus_w_wt::<false>(w.as_slice(), cols.as_mut_slice(), n, s);
                }
                assert_eq!(
                    tri, cols,
                    "S {s} fma {fma}: triangle differs from whole columns"
                );
                let want = &p - &w * w.transpose();
                let err = (&tri - &want).amax() / want.amax();
                assert!(err <= 1e-14, "S {s} fma {fma}: P − W·Wᵀ {err:e}");
            }
        }
    }

    /// The symmetric rank-N update P − W·Wᵀ of run-time sizes against the textbook Joseph
    /// form (I − K·H)·P·(I − K·H)ᵀ + K·R·Kᵀ with K = P·Hᵀ·S⁻¹, computed densely by
    /// nalgebra, for a 78-state P with prior-to-noise ratios from 1 to 1e6: the same
    /// matrix to round-off, exactly symmetric, positive definite.
    #[test]
    fn rank_n_update_equals_the_joseph_form() {
        use nalgebra::DMatrix;
        let (n, s) = (7usize, 78usize);
        // A deterministic SPD P with a spread of scales: B·Bᵀ + diag.
        let mut rnd = xorshift(0x9E37_79B9_7F4A_7C15u64);
        for ratio in [1.0, 1e3, 1e6] {
            let b = DMatrix::from_fn(s, s, |_, _| rnd());
            let scale = DMatrix::from_fn(s, s, |i, j| {
                let d = |k: usize| {
                    if k < 2 * n {
                        1e-3
                    } else {
                        1.0 + k as f64 / 10.0
                    }
                };
                d(i) * d(j)
            });
            let p = (&b * b.transpose()).component_mul(&scale) + DMatrix::identity(s, s) * 1e-9;
            let r = DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    1e-3 * 1e-3 * (s as f64) / ratio
                } else {
                    0.0
                }
            });
            // H selects the positions (the first n states).
            let h = DMatrix::from_fn(n, s, |i, j| if i == j { 1.0 } else { 0.0 });
            let pz = &p * h.transpose();
            let sz = &h * &pz + &r;
            let k = &pz * sz.clone().try_inverse().unwrap();
            let ikh = DMatrix::identity(s, s) - &k * &h;
            let joseph = &ikh * &p * ikh.transpose() + &k * &r * k.transpose();

            let mut l = vec![0.0; n * n];
            assert!(cholesky(sz.as_slice(), n, &mut l));
            let mut linv = vec![0.0; n * n];
            lower_triangular_inverse(&l, n, &mut linv);
            let mut w = vec![0.0; s * n];
            let mut got = p.clone();
            w_from_pz::<false>(pz.as_slice(), &linv, &mut w, n, s);
            minus_w_wt::<false>(&w, got.as_mut_slice(), n, s);

            let err = (&got - &joseph).amax() / p.amax();
            assert!(err <= 1e-12, "ratio {ratio}: {err:e}");
            assert_eq!(got, got.transpose(), "ratio {ratio}: not exactly symmetric");
            assert!(got.clone().cholesky().is_some(), "ratio {ratio}: not PD");
        }
    }
}
