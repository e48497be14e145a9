//! Physically consistent identification (the method is documented on [`PhysicalProblem`]).

use faer::Mat;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix4};

use crate::error::{PrrrpError, Result};
use crate::models::chain::{
    pseudo_inertia, pseudo_inertia_to_parameters, BaseOptions, BaseParameters, DynChain,
    FeasibilityReport, FrictionModel, LINK_PARAMS, MAX_MATRIX_ENTRIES,
};

/// Base values are called reachable by a consistent π ([`BaseFeasibility::feasible`]) when
/// the achieved relative mismatch is at most this (dimensionless).
pub const BASE_FEASIBILITY_TOLERANCE: f64 = 1e-6;

/// Base values smaller than this fraction of the largest |β| are measured against that
/// fraction, not against themselves (dimensionless). Why 10⁻³ and not smaller: real robots
/// have base values that are exactly zero (symmetric links, a COM on a joint axis) and
/// links on the boundary of consistency (a massless link, a rod); weights 1/s_r² spread
/// over more than ~10⁶ made the barrier's Newton system so stiff that the PUMA 560's own
/// base values stalled at a mismatch of 7 (with 10⁻⁶) instead of 10⁻¹⁰ (with 10⁻³).
/// A mismatch of 10⁻⁶ on such an entry is then 10⁻⁹ of the largest base value.
pub const BASE_MISMATCH_FLOOR: f64 = 1e-3;

/// Default [`PhysicalConfig::divergence_weight`] γ (dimensionless, in units of the data's
/// χ²). For small departures D(J‖J₀) ≈ ½‖J₀^{-1/2}(J − J₀)J₀^{-1/2}‖²_F, so the prior
/// term γ·D is a Gaussian prior of relative width √(2/γ) on each link's pseudo-inertia,
/// in the link's own measure: ≈ 45 % at γ = 10, the agreement to expect of a robot
/// file's CAD inertials with the built arm. The fit is then the maximum a posteriori
/// estimate: a direction the data determine to a relative σ is pulled towards the prior by
/// a fraction ≈ (γ/2)·σ² of its distance from it (a base parameter known to 5 % by ≈ 1 %).
/// With a prior 20 % off every link of a 7-joint arm, no base parameter moved more than
/// 0.31 of its σ from least squares (0.53 σ with a prior 50 % off), as the Gaussian MAP
/// predicts (tests/physical.rs). On
/// simulated logs of the Panda, UR5 and Kinova Gen2 of example-robot-data (inertials
/// perturbed by 25 % in mass, 2 cm in COM, 30 % in second moments; two joints barely
/// moving) γ = 1 let a link's mass run to 14 times the file's; γ = 10 kept every Panda and
/// UR5 mass within 0.46–1.9 times (one light Kinova wrist link fell to 0.28) with held-out
/// torque errors within 0.2 % of weighted least squares' or better; γ ≥ 30 began to cost
/// held-out accuracy (up to 2.3 %). See docs/physical-prior.md.
pub const DEFAULT_DIVERGENCE_WEIGHT: f64 = 10.0;

/// Floor of the residual variance σ̂² that scales the divergence weight, relative to the
/// mean square (weighted) torque: exact data (σ̂² ≈ 0) still hold the directions they do
/// not see at the prior. At 10⁻¹² the prior's pull still moved a base value of the PUMA
/// 560 that is exactly 0 (its link 6 on the boundary of consistency) by 4·10⁻⁵ of the
/// largest; at 10⁻¹⁶ (round-off of the squared torques) that is 4·10⁻⁹.
const RESIDUAL_VARIANCE_FLOOR: f64 = 1e-16;

/// Settings of [`identify_physical`] and [`PhysicalProblem`].
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalConfig {
    /// Prior standard parameters π₀ (the chain's layout, e.g. the URDF's
    /// [`DynChain::parameters`]); `None` (default) uses a default body per link and zero
    /// friction. The start point is π₀ moved into the interior (pseudo-inertia
    /// eigenvalues raised to 10⁻⁴ of the link's largest, fv and fc to ≥ 10⁻³).
    pub prior: Option<Vec<f64>>,
    /// Weight ρ ≥ 0 of the prior term ρ·s·‖π − π₀‖² (dimensionless, relative to the data
    /// scale s = ‖Λ^{1/2}W‖²_F / P; SI units for π). Default 0: the prior only fixes the
    /// directions the data do not see. A positive ρ biases the base parameters towards
    /// the prior (a ridge / maximum a posteriori estimate).
    pub prior_weight: f64,
    /// Weight γ ≥ 0 of the geometric prior γ·σ²·Σ_i D(J_i‖J₀_i) (dimensionless, default
    /// [`DEFAULT_DIVERGENCE_WEIGHT`]): D is the log-det (Bregman) divergence of link i's
    /// pseudo-inertia from the prior's, σ² the variance of one unit of the data's χ²
    /// (`noise_variance`), so that γ counts in units of χ². It holds what the data do not
    /// determine at the prior and leaves what they do determine alone; see
    /// [`PhysicalProblem`]. 0 is the bare constrained least squares, whose weakly seen
    /// directions may run to absurd masses (and take many Newton steps to get there).
    pub divergence_weight: f64,
    /// Variance σ² of one unit of the data's χ² (units of the weighted squared residual),
    /// which scales `divergence_weight`; `None` (default): the residual variance σ̂² of the
    /// unconstrained least squares, each sample counted as an independent observation. Low-
    /// pass filtered logs have residuals correlated over κ samples and hold ≈ rows/κ
    /// independent equations: pass κ·σ̂² then ([`crate::identify`] does, κ from the
    /// residuals as for the least-squares covariance).
    pub noise_variance: Option<f64>,
    /// Weight ε of the proximal term that holds the directions the data do not see when
    /// `divergence_weight` is 0 (dimensionless, same scale as `prior_weight`, default
    /// 1e-10; unused otherwise); see [`PhysicalProblem`]. It does not bias the base
    /// parameters; must be > 0 unless `prior_weight` or `divergence_weight` is.
    pub regularisation: f64,
    /// Per-joint weights Λ (length n, each finite and ≥ 0, not all 0) multiplying each
    /// joint's squared residuals, e.g. inverse noise variances; `None` (default) weighs
    /// all joints 1. Applied when the problem is built.
    pub joint_weights: Option<Vec<f64>>,
    /// Most Newton steps per solve (default 1000); exceeding it is
    /// [`PrrrpError::Diverged`].
    pub max_iterations: usize,
    /// Relative tolerance (default 1e-10, in (0, 1)): stop when the duality-gap bound is
    /// below `tolerance` times the objective (or `tolerance²` times ‖Λ^{1/2}τ‖² for exact
    /// data) and a re-anchoring of the unseen directions changes the objective by less
    /// than `tolerance` times its value.
    pub tolerance: f64,
}

impl Default for PhysicalConfig {
    fn default() -> Self {
        Self {
            prior: None,
            prior_weight: 0.0,
            divergence_weight: DEFAULT_DIVERGENCE_WEIGHT,
            noise_variance: None,
            regularisation: 1e-10,
            joint_weights: None,
            max_iterations: 1000,
            tolerance: 1e-10,
        }
    }
}

impl PhysicalConfig {
    fn validate(&self) -> Result<()> {
        for (field, v) in [
            ("PhysicalConfig::prior_weight", self.prior_weight),
            ("PhysicalConfig::divergence_weight", self.divergence_weight),
            ("PhysicalConfig::regularisation", self.regularisation),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: field.into(),
                    value: v,
                    reason: "must be finite and >= 0 (a weight relative to the data scale)",
                });
            }
        }
        if let Some(v) = self.noise_variance {
            if !(v.is_finite() && v > 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: "PhysicalConfig::noise_variance".into(),
                    value: v,
                    reason: "must be finite and > 0 (units of the weighted squared residual)",
                });
            }
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "PhysicalConfig::tolerance".into(),
                value: self.tolerance,
                reason: "must be in (0, 1); the default is 1e-10",
            });
        }
        if self.regularisation == 0.0 && self.prior_weight == 0.0 && self.divergence_weight == 0.0 {
            return Err(PrrrpError::InvalidParameter {
                field: "PhysicalConfig::regularisation".into(),
                value: 0.0,
                reason: "must be > 0 when prior_weight and divergence_weight are 0: something \
                         has to fix the directions the data do not see (default 1e-10)",
            });
        }
        if self.max_iterations == 0 {
            return Err(PrrrpError::InvalidParameter {
                field: "PhysicalConfig::max_iterations".into(),
                value: 0.0,
                reason: "must be >= 1; the default is 1000",
            });
        }
        Ok(())
    }
}

/// Result of a physically consistent identification.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalEstimate {
    /// Standard parameters π̂ (chain layout: 10 inertial per link, then the enabled
    /// friction terms; SI units), physically consistent.
    pub parameters: Vec<f64>,
    /// Their base values β̂ = K·π̂ (the layout of [`Self::base_parameters`]).
    pub base: Vec<f64>,
    /// The base-parameter analysis of the chain (names, K, combinations).
    pub base_parameters: BaseParameters,
    /// ‖Λ^{1/2}(W·π̂ − τ)‖ (N·m or N with unit weights).
    pub residual: f64,
    /// Unconstrained least-squares base parameters β_LS (minimum norm if the data leave
    /// some base directions unexcited).
    pub ls_base: Vec<f64>,
    /// ‖Λ^{1/2}(W_b·β_LS − τ)‖, the smallest residual any parameters reach.
    pub ls_residual: f64,
    /// 100·(residual / ls_residual − 1): the price of physical consistency on these data
    /// (%; 0 when both residuals vanish).
    pub residual_increase_percent: f64,
    /// The scale of [`PhysicalConfig::divergence_weight`]: [`PhysicalConfig::noise_variance`]
    /// or σ̂² = ls_residual² / (rows − base parameters), floored at 10⁻¹⁶ of the mean
    /// square weighted torque ((N·m)² with unit weights, ≈ 1 with weights 1/σ_j²).
    pub residual_variance: f64,
    /// Newton steps of the solve.
    pub iterations: usize,
    /// Feasibility of π̂ (every link consistent, friction ≥ 0, up to round-off).
    pub feasibility: FeasibilityReport,
}

/// Whether some physically consistent π reproduces given base values; see
/// [`base_feasibility`].
#[derive(Debug, Clone, PartialEq)]
pub struct BaseFeasibility {
    /// `max_relative_mismatch ≤` [`BASE_FEASIBILITY_TOLERANCE`].
    pub feasible: bool,
    /// The consistent standard parameters closest to reproducing β.
    pub parameters: Vec<f64>,
    /// K·π − β per base parameter (SI).
    pub mismatch: Vec<f64>,
    /// max_r |K·π − β|_r / s_r with s_r = max(|β_r|, [`BASE_MISMATCH_FLOOR`]·max|β|)
    /// (dimensionless).
    pub max_relative_mismatch: f64,
    /// Feasibility of `parameters`.
    pub report: FeasibilityReport,
    /// Newton steps of the solve.
    pub iterations: usize,
    /// Whether the solve converged within `max_iterations`. If not, `parameters` are
    /// still consistent and the mismatch they reach is an upper bound of the smallest
    /// one: `feasible = true` stays a proof, `false` is then not certain.
    pub converged: bool,
}

/// A physically consistent identification problem in compact form: the data reduced to
/// R (P×P) and z (P) once, so that solves (e.g. with other priors) cost the same whatever
/// the number of samples.
///
/// # Method
/// Physically consistent identification: least squares over the standard parameters of a
/// chain, constrained to rigid bodies and dissipative friction.
///
/// Least squares on the base parameters β fits the torques best but may return values no
/// rigid body has (a negative mass, an inertia breaking the triangle inequality, negative
/// friction) — a model that forward simulation refuses and controllers should not trust.
/// This estimator solves
///
/// min_π ‖Λ^{1/2}·(W·π − τ)‖² + γ·σ̂²·Σ_i D(J_i‖J₀_i) + ρ·s·‖π − π₀‖²
/// subject to J_i(π) ⪰ 0 for every link i, fv_j ≥ 0, fc_j ≥ 0 for every joint j,
///
/// with W the stacked full regressor (friction columns included), Λ per-joint weights,
/// J_i the 4×4 pseudo-inertia of link i (Wensing, Kim & Slotine 2017) and π₀ a prior
/// (e.g. the URDF inertials). The problem is convex in π (a least-squares objective under
/// linear matrix inequalities).
///
/// **Solver.** A barrier (interior-point) method, written here without a semidefinite
/// solver: Newton steps with a backtracking line search on
/// objective + t·(−Σ log det J_i − Σ log fv_j − Σ log fc_j), t shrunk tenfold after each
/// centring, until the duality-gap bound (4·links + friction terms)·t falls below
/// `tolerance` times the objective. The log-det barrier is self-concordant, its gradient
/// and Hessian are closed-form (tr(J⁻¹A_k), tr(J⁻¹A_k·J⁻¹A_l) with J = Σ π_k·A_k), and
/// boundary optima (a point mass, a rod, zero friction) are approached as t → 0. The
/// data enter once, through a QR factorisation of [Λ^{1/2}W | Λ^{1/2}τ]:
/// ‖Λ^{1/2}(Wπ − τ)‖² = ‖R·π − z‖² + r₀², so a Newton step costs O(P³) in the P standard
/// parameters (P = 91 for a 7-joint arm with three friction terms), independent of the
/// number of samples, and residuals are evaluated without the cancellation of the
/// normal equations.
///
/// A log-Cholesky parametrisation (Rucker & Wensing, IEEE RA-L 2022) with
/// Levenberg–Marquardt was tried first: from a default start on exact PUMA 560 data it
/// needed more than 1000 iterations (a curved, ill-conditioned valley towards the
/// boundary), where the barrier method takes about a hundred Newton steps.
///
/// **What the data do not determine.** The data see only the base combinations
/// β = K·π, and some of those only weakly (a joint that barely moves, a link whose mass
/// trades against its first moment). Least squares over π leaves such directions free,
/// and the barrier alone pushes them wherever it is most interior: on a 20 s Panda
/// trajectory links 1–3 came out at 41 765, 41 314 and 15 300 kg (the URDF: 4.97, 0.65,
/// 3.23 kg) with a residual only 0.16 % above least squares. The geometric prior
/// γ·σ̂²·Σ_i D(J_i‖J₀_i) holds them: D(J‖J₀) = −log det(J₀⁻¹J) + tr(J₀⁻¹J) − 4 is the
/// log-det (Bregman) divergence of link i's pseudo-inertia from the prior's (the
/// "entropic" regulariser of Lee, Wensing & Park, IEEE T-RO 36, 2020), zero at the prior,
/// convex, independent of the link's units and frame; σ̂² is the variance of one unit of
/// the data's χ² ([`PhysicalConfig::noise_variance`]: by default the residual variance of
/// the unconstrained least squares on the same weighted data), so that
/// [`PhysicalConfig::divergence_weight`] γ counts in units of χ². A direction the data
/// determine with relative uncertainty σ is pulled towards the prior by a fraction
/// ≈ (γ/2)·σ² of its distance from it (a fraction of its σ for well-determined base
/// parameters), a direction they do not see stays at the prior, and one in between is the
/// maximum a posteriori compromise (see [`DEFAULT_DIVERGENCE_WEIGHT`]). Prior links flatter than
/// any casting are thickened first (second moments about the centre of mass raised to
/// 10⁻³ of the largest: at least ≈ 3 % as thick as long). With the prior itself feasible
/// (and not that flat) and the data exact, the whole π₀ is returned. Without a prior, π₀
/// is a default body per link (1 kg at the link origin, second moments 0.01 kg·m² on
/// each axis) and zero friction; a prior link that is not strictly consistent (a point
/// mass, a massless link) is moved into the interior first (pseudo-inertia eigenvalues
/// raised to 10⁻⁴ of its largest; the default body if none is positive).
///
/// The solver works in coordinates x = Qᵀ·π with Q = [Q_r Q_n] an orthonormal basis of
/// row(K) and null(K), so that the data curvature and the prior's and barrier's curvature
/// sit in separate blocks and the Newton systems stay accurate as t → 0. With
/// `divergence_weight` 0 the unseen part x_n is held instead by a proximal term
/// ε·s·‖x_n − a‖² ([`PhysicalConfig::regularisation`] ε, s = ‖Λ^{1/2}W‖²_F / P): a starts
/// at the prior's Qₙᵀ·π₀ and is moved to the current iterate after every centring, so
/// that at the solution it vanishes and biases nothing — which also means it holds
/// nothing against the barrier's push towards the interior (the masses above).
/// A positive [`PhysicalConfig::prior_weight`] adds a ridge term ρ·s·‖π − π₀‖² on every
/// parameter (friction included), which biases β towards the prior in proportion to ρ.
#[derive(Debug, Clone)]
pub struct PhysicalProblem {
    base: BaseParameters,
    /// Data in compact form: ‖Λ^{1/2}(Wπ − τ)‖² = ‖a·π − z‖² + r0sq.
    a: DMatrix<f64>,
    z: DVector<f64>,
    r0sq: f64,
    /// Joints of the chain: rows of the data = dof × samples.
    dof: usize,
    samples: usize,
}

impl PhysicalProblem {
    /// Builds the problem from samples of a chain: flat row-major (samples × n) joint
    /// positions (rad or m), velocities, accelerations and measured generalised forces
    /// τ (N·m or N); applies `config.joint_weights`.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for lengths that are not samples × n or weights not of
    /// length n, [`PrrrpError::NonFinite`] naming the first bad sample,
    /// [`PrrrpError::TooFewSamples`] for no samples, [`PrrrpError::InvalidParameter`] for
    /// negative or non-finite weights, all-zero weights, or more data than
    /// [`MAX_MATRIX_ENTRIES`].
    pub fn new(
        chain: &DynChain,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &[f64],
        config: &PhysicalConfig,
    ) -> Result<Self> {
        let n = chain.dof();
        let samples = crate::models::chain::flat_samples(n, q, qd, qdd)?;
        if samples == 0 {
            return Err(PrrrpError::TooFewSamples { needed: 1, got: 0 });
        }
        let entries = (n * samples) as f64 * (chain.num_params() + 1) as f64;
        if entries > MAX_MATRIX_ENTRIES || samples > crate::interrupt::MAX_SAMPLES {
            return Err(PrrrpError::InvalidParameter {
                field: "samples".into(),
                value: samples as f64,
                reason: "the stacked regressor would exceed MAX_MATRIX_ENTRIES (2.5e8 \
                         doubles) or MAX_SAMPLES: identify on fewer samples (decimate)",
            });
        }
        let w = chain.observation_matrix(q, qd, qdd)?;
        let base = chain.base_parameters(&BaseOptions::default())?;
        Self::from_observations(&w, tau, base, config.joint_weights.as_deref())
    }

    /// Builds the problem from a stacked full observation matrix W ((n·samples) × p, rows
    /// sample-major as [`DynChain::observation_matrix`] stacks them), the stacked τ
    /// (n·samples) and the chain's base-parameter analysis.
    ///
    /// # Errors
    /// As [`PhysicalProblem::new`].
    pub fn from_observations(
        w: &Mat<f64>,
        tau: &[f64],
        base: BaseParameters,
        joint_weights: Option<&[f64]>,
    ) -> Result<Self> {
        let (n, p) = (base.dof, base.num_standard());
        if w.ncols() != p || w.nrows() % n.max(1) != 0 || n == 0 {
            return Err(PrrrpError::ShapeMismatch {
                what: "W".into(),
                expected: format!("(n·samples) × {p} with n = {n}"),
                got: format!("{} × {}", w.nrows(), w.ncols()),
            });
        }
        if tau.len() != w.nrows() {
            return Err(PrrrpError::ShapeMismatch {
                what: "tau (flat samples × n)".into(),
                expected: format!("{} values", w.nrows()),
                got: format!("{} values", tau.len()),
            });
        }
        let samples = w.nrows() / n;
        if samples == 0 {
            return Err(PrrrpError::TooFewSamples { needed: 1, got: 0 });
        }
        if let Some(k) = tau.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "tau".into(),
                row: Some(k / n),
            });
        }
        let sqrt_w: Vec<f64> = match joint_weights {
            None => vec![1.0; n],
            Some(wts) => {
                if wts.len() != n {
                    return Err(PrrrpError::ShapeMismatch {
                        what: "joint_weights".into(),
                        expected: format!("{n} entries (one per joint)"),
                        got: format!("{} entries", wts.len()),
                    });
                }
                for (j, &v) in wts.iter().enumerate() {
                    if !(v.is_finite() && v >= 0.0) {
                        return Err(PrrrpError::InvalidParameter {
                            field: format!("joint_weights[{j}]"),
                            value: v,
                            reason: "joint weights must be finite and >= 0",
                        });
                    }
                }
                if wts.iter().all(|&v| v == 0.0) {
                    return Err(PrrrpError::InvalidParameter {
                        field: "joint_weights".into(),
                        value: 0.0,
                        reason: "at least one joint weight must be > 0",
                    });
                }
                wts.iter().map(|v| v.sqrt()).collect()
            }
        };
        let rows = w.nrows();
        let aug = Mat::from_fn(rows, p + 1, |i, j| {
            let s = sqrt_w[i % n];
            if j < p {
                s * w[(i, j)]
            } else {
                s * tau[i]
            }
        });
        if let Some(i) = (0..rows).find(|&i| !(0..p).all(|j| aug[(i, j)].is_finite())) {
            return Err(PrrrpError::NonFinite {
                what: "W".into(),
                row: Some(i / n),
            });
        }
        crate::interrupt::check("physically consistent identification")?;
        // One QR of [W | τ]: its R holds R (P×P), z = Qᵀτ and the part r₀ of τ outside
        // the span of W, so that ‖Wπ − τ‖² = ‖Rπ − z‖² + r₀².
        let qr = aug.qr();
        let r = qr.R();
        let m = r.nrows();
        let k = m.min(p);
        let a = DMatrix::from_fn(k, p, |i, j| r[(i, j)]);
        let z = DVector::from_fn(k, |i, _| r[(i, p)]);
        let r0sq = if m > p { r[(p, p)] * r[(p, p)] } else { 0.0 };
        Ok(Self {
            base,
            a,
            z,
            r0sq,
            dof: n,
            samples,
        })
    }

    /// The chain's base-parameter analysis.
    pub fn base_parameters(&self) -> &BaseParameters {
        &self.base
    }

    /// Number of samples in the data.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// ‖Λ^{1/2}(W·π − τ)‖ of a standard parameter vector (N·m or N).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if π does not have p entries.
    pub fn residual(&self, pi: &[f64]) -> Result<f64> {
        check_len("standard parameters π", pi.len(), self.base.num_standard())?;
        let r = &self.a * DVector::from_column_slice(pi) - &self.z;
        Ok((r.norm_squared() + self.r0sq).sqrt())
    }

    /// Unconstrained least squares on the base parameters: (β_LS, residual). Minimum-norm
    /// (column-scaled, singular values below 10⁻¹² of the largest dropped) when the data
    /// do not excite every base direction.
    pub fn least_squares(&self) -> (Vec<f64>, f64) {
        let ind = &self.base.independent;
        let ab = DMatrix::from_fn(self.a.nrows(), ind.len(), |i, c| self.a[(i, ind[c])]);
        let norms: Vec<f64> = (0..ind.len())
            .map(|c| {
                let v = ab.column(c).norm();
                if v > 0.0 {
                    v
                } else {
                    1.0
                }
            })
            .collect();
        let mut scaled = ab.clone();
        for (c, &s) in norms.iter().enumerate() {
            scaled.column_mut(c).scale_mut(1.0 / s);
        }
        let y = crate::linalg::svd(scaled)
            .and_then(|svd| {
                let eps = 1e-12 * svd.singular_values.max();
                svd.solve(&self.z, eps).ok()
            })
            .unwrap_or_else(|| DVector::zeros(ind.len()));
        let beta: Vec<f64> = y.iter().zip(&norms).map(|(v, s)| v / s).collect();
        let r = &ab * DVector::from_column_slice(&beta) - &self.z;
        (beta, (r.norm_squared() + self.r0sq).sqrt())
    }

    /// Solves the physically consistent problem with `config`'s prior and weights (its
    /// `joint_weights` were applied when the problem was built).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a bad setting, [`PrrrpError::ShapeMismatch`]
    /// for a prior of the wrong length, [`PrrrpError::NonFinite`] for a non-finite prior,
    /// [`PrrrpError::Diverged`] if a solve does not converge within `max_iterations`,
    /// [`PrrrpError::Interrupted`] on [`crate::request_stop`].
    pub fn solve(&self, config: &PhysicalConfig) -> Result<PhysicalEstimate> {
        config.validate()?;
        let layout = Layout::of(&self.base);
        let anchor = layout.anchor(config.prior.as_deref())?;
        let (ls_base, ls_residual) = self.least_squares();
        let rows = (self.dof * self.samples) as f64;
        let dof = (rows - self.base.count() as f64).max(1.0);
        let signal = self.z.norm_squared() + self.r0sq;
        let residual_variance = config
            .noise_variance
            .unwrap_or(ls_residual * ls_residual / dof)
            .max(RESIDUAL_VARIANCE_FLOOR * signal / rows);
        let (pi, iterations, _) = interior_point(
            &layout,
            &self.a,
            &self.z,
            self.r0sq,
            &self.base,
            &anchor,
            config,
            config.divergence_weight * residual_variance,
            "physically consistent identification",
            false,
        )?;
        let base = self.base.base_values(&pi)?;
        let residual = self.residual(&pi)?;
        let residual_increase_percent = if ls_residual > 0.0 {
            100.0 * (residual / ls_residual - 1.0)
        } else if residual == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        let feasibility = feasibility_of(&pi, &self.base)?;
        Ok(PhysicalEstimate {
            parameters: pi,
            base,
            base_parameters: self.base.clone(),
            residual,
            ls_base,
            ls_residual,
            residual_increase_percent,
            residual_variance,
            iterations,
            feasibility,
        })
    }
}

/// Physically consistent identification of a chain's standard parameters from samples:
/// least squares on the torques over rigid-body inertias and dissipative friction (see
/// [`PhysicalProblem`] for the method). Inputs are flat row-major (samples × n)
/// slices as numpy arrays are: positions (rad or m), velocities, accelerations and
/// measured generalised forces τ (N·m or N).
///
/// Cost: one QR of the (n·samples) × (p + 1) data, then O(p³) per Newton step (tens to a
/// few hundred steps); see `benches/physical.rs` for the 7-joint arm on 2000 samples.
///
/// # Example
/// ```
/// use prrrp_core::{identify_physical, PhysicalConfig, SerialChain};
///
/// let chain = SerialChain::puma560().to_dyn();
/// let n = chain.dof();
/// // Exact torques of the true robot along a multi-sine trajectory.
/// let (mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![]);
/// for k in 0..300 {
///     let t = 0.02 * k as f64;
///     for j in 0..n {
///         let (w1, w2) = (0.7 + 0.3 * j as f64, 1.9 + 0.2 * j as f64);
///         q.push((w1 * t).sin() + 0.5 * (w2 * t + j as f64).sin());
///         qd.push(w1 * (w1 * t).cos() + 0.5 * w2 * (w2 * t + j as f64).cos());
///         qdd.push(-w1 * w1 * (w1 * t).sin() - 0.5 * w2 * w2 * (w2 * t + j as f64).sin());
///     }
///     let r = n * k..n * (k + 1);
///     tau.extend(chain.inverse_dynamics(&q[r.clone()], &qd[r.clone()], &qdd[r])?);
/// }
/// let est = identify_physical(&chain, &q, &qd, &qdd, &tau, &PhysicalConfig::default())?;
/// assert!(est.feasibility.is_feasible());
/// // The base parameters of the true robot are recovered.
/// let truth = est.base_parameters.base_values(&chain.parameters())?;
/// for (b, t) in est.base.iter().zip(&truth) {
///     assert!((b - t).abs() < 1e-6 * (1.0 + t.abs()));
/// }
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
///
/// # Errors
/// As [`PhysicalProblem::new`] and [`PhysicalProblem::solve`].
pub fn identify_physical(
    chain: &DynChain,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    tau: &[f64],
    config: &PhysicalConfig,
) -> Result<PhysicalEstimate> {
    config.validate()?;
    PhysicalProblem::new(chain, q, qd, qdd, tau, config)?.solve(config)
}

/// Whether a physically consistent standard vector π with K·π = β exists, for base values
/// β of the analysis `base` (e.g. a least-squares estimate): minimises the relative
/// mismatch Σ_r ((K·π − β)_r / s_r)² over consistent π (s_r as in
/// [`BaseFeasibility::max_relative_mismatch`]) and reports the mismatch reached. A
/// mismatch above [`BASE_FEASIBILITY_TOLERANCE`] means no rigid bodies reproduce β. The
/// unidentifiable directions come from `config.prior` as in [`identify_physical`].
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] / [`PrrrpError::NonFinite`] for a bad β or prior, and
/// as [`PhysicalProblem::solve`].
pub fn base_feasibility(
    base: &BaseParameters,
    beta: &[f64],
    config: &PhysicalConfig,
) -> Result<BaseFeasibility> {
    config.validate()?;
    let (b, p) = (base.count(), base.num_standard());
    check_len("base parameters β", beta.len(), b)?;
    if let Some(k) = beta.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: format!("base parameters β[{k}]"),
            row: None,
        });
    }
    let bmax = beta.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    let s: Vec<f64> = beta
        .iter()
        .map(|x| {
            x.abs()
                .max(BASE_MISMATCH_FLOOR * bmax)
                .max(f64::MIN_POSITIVE)
        })
        .collect();
    let a = DMatrix::from_fn(b, p, |r, j| base.map[(r, j)] / s[r]);
    let z = DVector::from_fn(b, |r, _| beta[r] / s[r]);
    let layout = Layout::of(base);
    let anchor = layout.anchor(config.prior.as_deref())?;
    // A yes/no question with a mismatch to report: 1e-7 of the objective is accuracy
    // enough, and saves the slow last digits of boundary optima.
    let loose = PhysicalConfig {
        tolerance: config.tolerance.max(1e-7),
        ..config.clone()
    };
    let (pi, iterations, converged) = interior_point(
        &layout,
        &a,
        &z,
        0.0,
        base,
        &anchor,
        &loose,
        0.0,
        "base feasibility",
        true,
    )?;
    let kb = base.base_values(&pi)?;
    let mismatch: Vec<f64> = kb.iter().zip(beta).map(|(x, y)| x - y).collect();
    let max_relative_mismatch = mismatch
        .iter()
        .zip(&s)
        .fold(0.0f64, |m, (d, s)| m.max(d.abs() / s));
    let report = feasibility_of(&pi, base)?;
    Ok(BaseFeasibility {
        feasible: max_relative_mismatch <= BASE_FEASIBILITY_TOLERANCE,
        parameters: pi,
        mismatch,
        max_relative_mismatch,
        report,
        iterations,
        converged,
    })
}

fn check_len(what: &str, got: usize, want: usize) -> Result<()> {
    crate::error::check_len(what, got, want, "entries", "")
}

/// s = ‖A‖²_F / P: the mean squared column norm, the scale the regularisers are relative to.
fn data_scale(a: &DMatrix<f64>, p: usize) -> f64 {
    let s = a.norm_squared() / p as f64;
    if s > 0.0 && s.is_finite() {
        s
    } else {
        1.0
    }
}

/// Whether a friction term is constrained (viscous, Coulomb: ≥ 0) or free (offset).
#[derive(Debug, Clone, Copy, PartialEq)]
enum FrictionParam {
    NonNegative,
    Free,
}

/// Layout of a chain's standard parameters for the solver.
struct Layout {
    dof: usize,
    p: usize,
    /// Kind of each friction parameter, in the chain's order.
    friction: Vec<FrictionParam>,
}

/// Second moment of the default body along each axis (kg·m²) per kg.
const DEFAULT_SECOND_MOMENT: f64 = 0.01;
/// Start value of dissipative friction terms whose prior is below this (SI).
const FRICTION_FLOOR: f64 = 1e-3;
/// Pseudo-inertia eigenvalues of the start point are raised to this fraction of the
/// link's largest.
const EIGEN_FLOOR: f64 = 1e-4;
/// Factor by which the barrier weight t shrinks between centering steps.
const BARRIER_SHRINK: f64 = 10.0;

/// Feasibility of π in the layout of the analysis `base` (actuator terms included).
fn feasibility_of(pi: &[f64], base: &BaseParameters) -> Result<FeasibilityReport> {
    FeasibilityReport::with_armature(pi, base.dof, &base.friction, base.armature)
}

impl Layout {
    /// The layout of the analysis `base`: its friction terms and, per actuator, a rotor
    /// inertia Ia ≥ 0 when the chain has an armature term.
    fn of(base: &BaseParameters) -> Self {
        let mut l = Self::new(base.dof, base.friction);
        if base.armature {
            let per = base.friction.columns_per_joint();
            let mut kinds = Vec::with_capacity(l.friction.len() + base.dof);
            for m in 0..base.dof {
                kinds.extend_from_slice(&l.friction[per * m..per * (m + 1)]);
                kinds.push(FrictionParam::NonNegative);
            }
            l.friction = kinds;
            l.p = base.dof * LINK_PARAMS + l.friction.len();
        }
        l
    }

    fn new(dof: usize, model: FrictionModel) -> Self {
        let mut friction = Vec::new();
        for _ in 0..dof {
            if model.viscous {
                friction.push(FrictionParam::NonNegative);
            }
            if model.coulomb {
                friction.push(FrictionParam::NonNegative);
            }
            if model.offset {
                friction.push(FrictionParam::Free);
            }
        }
        Self {
            dof,
            p: dof * LINK_PARAMS + friction.len(),
            friction,
        }
    }

    /// Degree of the barrier: 4 per pseudo-inertia, 1 per constrained friction term; the
    /// central point of weight t is within degree·t of the optimum.
    fn degree(&self) -> f64 {
        (4 * self.dof
            + self
                .friction
                .iter()
                .filter(|k| **k == FrictionParam::NonNegative)
                .count()) as f64
    }

    /// The prior π₀, or the default one.
    fn anchor(&self, prior: Option<&[f64]>) -> Result<Vec<f64>> {
        match prior {
            Some(v) => {
                check_len("PhysicalConfig::prior", v.len(), self.p)?;
                if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                    return Err(PrrrpError::NonFinite {
                        what: format!("PhysicalConfig::prior[{k}]"),
                        row: None,
                    });
                }
                Ok(v.to_vec())
            }
            None => {
                let mut v = vec![0.0; self.p];
                for i in 0..self.dof {
                    v[LINK_PARAMS * i..LINK_PARAMS * (i + 1)].copy_from_slice(&default_body());
                }
                Ok(v)
            }
        }
    }

    /// A strictly feasible start near π₀, which is also the prior the divergence measures
    /// from: each link thickened ([`thickened_link`]), its pseudo-inertia's eigenvalues
    /// raised to [`EIGEN_FLOOR`] of its largest (the default body if none is positive),
    /// constrained friction raised to [`FRICTION_FLOOR`].
    fn start(&self, anchor: &[f64]) -> Vec<f64> {
        let mut pi = anchor.to_vec();
        for i in 0..self.dof {
            let r = LINK_PARAMS * i..LINK_PARAMS * (i + 1);
            let mut l = [0.0; LINK_PARAMS];
            l.copy_from_slice(&anchor[r.clone()]);
            pi[r].copy_from_slice(&interior_link(&thickened_link(&l)));
        }
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            if *kind == FrictionParam::NonNegative {
                pi[off + k] = pi[off + k].max(FRICTION_FLOOR);
            }
        }
        pi
    }

    /// −Σ log det J_i − Σ log f_j, or `None` outside the interior.
    #[cfg(test)]
    fn barrier(&self, pi: &[f64]) -> Option<f64> {
        self.barrier_parts(pi).map(|(l, b)| l + b)
    }

    /// (−Σ log det J_i over the links, −Σ log f_j over the bounded extra columns), or
    /// `None` outside the interior.
    fn barrier_parts(&self, pi: &[f64]) -> Option<(f64, f64)> {
        let mut l = 0.0;
        for i in 0..self.dof {
            let chol = pseudo_inertia(&link(pi, i)).cholesky()?;
            l -= 2.0 * chol.l_dirty().diagonal().map(f64::ln).sum();
        }
        let mut b = 0.0;
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            if *kind == FrictionParam::NonNegative {
                let f = pi[off + k];
                if f.is_nan() || f <= 0.0 {
                    return None;
                }
                b -= f.ln();
            }
        }
        (l.is_finite() && b.is_finite()).then_some((l, b))
    }

    /// Adds the gradient and Hessian of t_links·(−Σ log det J_i) + t_bounds·(−Σ log f_j)
    /// to `grad` and `hess` at an interior π: ∂/∂π_k (−log det J) = −tr(J⁻¹A_k),
    /// ∂²/∂π_k∂π_l = tr(J⁻¹A_k·J⁻¹A_l), with J = Σ π_k·A_k linear in π.
    fn add_barrier_derivatives(
        &self,
        pi: &[f64],
        t_links: f64,
        t_bounds: f64,
        basis: &[Matrix4<f64>; LINK_PARAMS],
        grad: &mut DVector<f64>,
        hess: &mut DMatrix<f64>,
    ) -> Option<()> {
        let t = t_links;
        for i in 0..self.dof {
            let jinv = pseudo_inertia(&link(pi, i)).cholesky()?.inverse();
            let b: [Matrix4<f64>; LINK_PARAMS] = std::array::from_fn(|k| jinv * basis[k]);
            let o = LINK_PARAMS * i;
            for k in 0..LINK_PARAMS {
                grad[o + k] -= t * b[k].trace();
                for l in k..LINK_PARAMS {
                    // tr(B_k·B_l) without forming the product.
                    let v = b[k].component_mul(&b[l].transpose()).sum();
                    hess[(o + k, o + l)] += t * v;
                    if l != k {
                        hess[(o + l, o + k)] += t * v;
                    }
                }
            }
        }
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            if *kind == FrictionParam::NonNegative {
                let f = pi[off + k];
                grad[off + k] -= t_bounds / f;
                hess[(off + k, off + k)] += t_bounds / (f * f);
            }
        }
        Some(())
    }
}

fn link(pi: &[f64], i: usize) -> [f64; LINK_PARAMS] {
    let mut l = [0.0; LINK_PARAMS];
    l.copy_from_slice(&pi[LINK_PARAMS * i..LINK_PARAMS * (i + 1)]);
    l
}

fn default_body() -> [f64; LINK_PARAMS] {
    // Σ = 0.01·1 kg·m² ⇒ I = tr(Σ)·1 − Σ = 0.02·1 kg·m², 1 kg at the origin.
    let i = 2.0 * DEFAULT_SECOND_MOMENT;
    [1.0, 0.0, 0.0, 0.0, i, 0.0, i, 0.0, 0.0, i]
}

/// Smallest second moment about the centre of mass a prior link keeps along any axis,
/// relative to its largest (dimensionless): a body at least ≈ 3 % as thick as it is long
/// (extents go as the square root). Robot files carry links flatter than any casting —
/// the Panda's link 2 of example-robot-data is a sheet 0.5 % thick (second moments
/// 8.6·10⁻⁷ against 0.028 kg·m²) — and the divergence, which measures departures
/// relative to the prior, would read that flatness as certain: a real link 2 only 10 %
/// thick then costs hundreds of χ² units, more than pushing its mass up tens of times
/// where the data allow it. Long slender links (the Panda's link 1, 8 % as thick as
/// long in its file) are left as they are.
const PRIOR_THICKNESS: f64 = 1e-3;

/// A link's parameters with the second moments about its centre of mass raised to
/// [`PRIOR_THICKNESS`] of the largest (mass and centre of mass kept); unchanged when the
/// mass or every second moment is not positive.
fn thickened_link(params: &[f64; LINK_PARAMS]) -> [f64; LINK_PARAMS] {
    let j = pseudo_inertia(params);
    let m = j[(3, 3)];
    if !(m > 0.0 && m.is_finite()) {
        return *params;
    }
    let h = j.fixed_view::<3, 1>(0, 3).into_owned();
    let sigma_c = j.fixed_view::<3, 3>(0, 0) - h * h.transpose() / m;
    let Some(eig) = crate::linalg::symmetric_eigen(sigma_c) else {
        return *params;
    };
    let top = eig.eigenvalues.max();
    if !(top > 0.0 && top.is_finite()) {
        return *params;
    }
    let floor = PRIOR_THICKNESS * top;
    if eig.eigenvalues.min() >= floor {
        return *params;
    }
    let d = eig.eigenvalues.map(|l| l.max(floor));
    let sigma = eig.eigenvectors * Matrix3::from_diagonal(&d) * eig.eigenvectors.transpose()
        + h * h.transpose() / m;
    let mut out = j;
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
    pseudo_inertia_to_parameters(&out)
}

/// A link's parameters with the pseudo-inertia's eigenvalues raised to [`EIGEN_FLOOR`] of
/// the largest (the default body if none is positive).
fn interior_link(params: &[f64; LINK_PARAMS]) -> [f64; LINK_PARAMS] {
    let Some(eig) = crate::linalg::symmetric_eigen(pseudo_inertia(params)) else {
        return default_body();
    };
    let top = eig.eigenvalues.max();
    if !(top > 0.0 && top.is_finite()) {
        return default_body();
    }
    let d = eig.eigenvalues.map(|l| l.max(EIGEN_FLOOR * top));
    let j = eig.eigenvectors * Matrix4::from_diagonal(&d) * eig.eigenvectors.transpose();
    pseudo_inertia_to_parameters(&j)
}

/// An orthonormal basis Q = [Q_r Q_n] of parameter space whose first `rows` columns span
/// the row space of K (what the data see) and the others its null space.
fn split_basis(base: &BaseParameters) -> (DMatrix<f64>, usize) {
    let (b, p) = (base.count(), base.num_standard());
    let k = DMatrix::from_fn(b, p, |r, j| base.map[(r, j)]);
    let kkt = &k * k.transpose();
    let x = match kkt.cholesky() {
        Some(c) => c.solve(&k),
        None => DMatrix::zeros(b, p),
    };
    // Projector onto row(K): eigenvalues 1 on row(K), 0 on null(K).
    let proj = k.transpose() * x;
    let eig = proj.symmetric_eigen();
    let mut order: Vec<usize> = (0..p).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let rows = order.iter().filter(|&&i| eig.eigenvalues[i] > 0.5).count();
    let q = DMatrix::from_fn(p, p, |r, c| eig.eigenvectors[(r, order[c])]);
    (q, rows)
}

/// The quadratic part of a solve in the coordinates x = Qᵀ·π of [`split_basis`].
struct Quadratic<'a> {
    /// Data restricted to the seen directions: ‖ar·x_r − z‖² (+ r0sq).
    ar: DMatrix<f64>,
    z: &'a DVector<f64>,
    /// Qᵀ·π₀.
    x0: DVector<f64>,
    /// Anchor of the proximal term in the unseen directions (starts at Qᵀ·π₀).
    xn: DVector<f64>,
    rows: usize,
    /// ρ·s of the full prior term.
    rho: f64,
    /// ε·s of the proximal term ε·s·‖x_n − anchor‖² in the unseen directions.
    omega: f64,
}

impl Quadratic<'_> {
    fn data(&self, x: &DVector<f64>) -> f64 {
        (&self.ar * x.rows(0, self.rows) - self.z).norm_squared()
    }

    fn prox(&self, x: &DVector<f64>) -> f64 {
        let n = x.len() - self.rows;
        self.omega * (x.rows(self.rows, n) - &self.xn).norm_squared()
    }

    fn value(&self, x: &DVector<f64>) -> f64 {
        self.data(x) + self.rho * (x - &self.x0).norm_squared() + self.prox(x)
    }
}

/// Σ_i D(J_i‖J₀_i) with D(J‖J₀) = −log det(J₀⁻¹J) + tr(J₀⁻¹J) − 4, the Bregman
/// divergence of −log det (Lee, Wensing & Park, "Geometric robot dynamic identification:
/// a convex programming approach", IEEE T-RO 36 (2020)): zero at the prior, convex,
/// invariant to the units and frame of the link, and a self-concordant barrier of the
/// cone J ≻ 0 whose centre is the prior instead of infinity. Only the links carry it; the
/// extra columns (friction) do not.
struct Divergence {
    /// Σ_i (log det J₀_i − 4).
    constant: f64,
    /// ∂/∂π Σ_i tr(J₀_i⁻¹·J_i), zero on the extra columns: the linear part.
    linear: DVector<f64>,
}

impl Divergence {
    /// The divergence from the links of `prior` (each strictly consistent, as
    /// [`Layout::start`] makes them).
    fn new(layout: &Layout, prior: &[f64], basis: &[Matrix4<f64>; LINK_PARAMS]) -> Self {
        let mut linear = DVector::zeros(layout.p);
        let mut constant = 0.0;
        for i in 0..layout.dof {
            let Some(chol) = pseudo_inertia(&link(prior, i)).cholesky() else {
                continue;
            };
            constant += 2.0 * chol.l_dirty().diagonal().map(f64::ln).sum() - 4.0;
            let j0inv = chol.inverse();
            for (k, a) in basis.iter().enumerate() {
                linear[LINK_PARAMS * i + k] = j0inv.component_mul(a).sum();
            }
        }
        Self { constant, linear }
    }

    /// Σ_i D(J_i‖J₀_i) at π, given the links' barrier −Σ log det J_i there.
    fn value(&self, pi: &DVector<f64>, link_barrier: f64) -> f64 {
        link_barrier + self.constant + self.linear.dot(pi)
    }
}

/// Barrier (interior-point) method for
/// min ‖a·π − z‖² + ρ·s·‖π − π₀‖² + γ'·Σ_i D(J_i‖J₀_i) subject to every J_i(π) ⪰ 0 and
/// the constrained friction terms ≥ 0 ([`Divergence`], J₀ the prior's links moved into
/// the interior; γ' = `divergence_weight`, possibly 0). Damped Newton steps with a
/// backtracking line search on φ_t = ‖a·π − z‖² + ρ-term + (γ' + t)·Σ_i D(J_i‖J₀_i) −
/// t·Σ log f_j: the links' barrier is the divergence itself, so that the central path
/// starts at the prior and the directions the data do not see stay there (−log det alone
/// would push them towards infinity, held only by γ'). t shrinks tenfold once φ_t is
/// centred, until the duality-gap bound t·(degree + Σ tr(J₀⁻¹J)) is below `tolerance`
/// times the objective (plus `r0sq`, the part of the data outside the model) or
/// `tolerance²` times the data energy; with γ' = 0 a proximal term ε·s·‖x_n − anchor‖²,
/// re-anchored after every centring, also holds the unseen directions, and the solve ends
/// when re-anchoring no longer changes the objective, so that it biases nothing.
/// Working in the coordinates x = Qᵀπ of [`split_basis`] keeps the Newton systems
/// accurate as t → 0: the seen block carries the data curvature, the unseen one only the
/// prior's and terms of order t, and Cholesky eliminates the first before the second.
/// Returns π, the number of Newton steps and whether it converged.
#[allow(clippy::too_many_arguments)]
fn interior_point(
    layout: &Layout,
    a: &DMatrix<f64>,
    z: &DVector<f64>,
    r0sq: f64,
    base: &BaseParameters,
    anchor: &[f64],
    config: &PhysicalConfig,
    divergence_weight: f64,
    what: &'static str,
    partial_ok: bool,
) -> Result<(Vec<f64>, usize, bool)> {
    let p = layout.p;
    let tol = config.tolerance;
    let scale = data_scale(a, p);
    let (q, rows) = split_basis(base);
    let anchor_v = DVector::from_column_slice(anchor);
    let x0 = q.tr_mul(&anchor_v);
    let mut quad = Quadratic {
        ar: a * q.columns(0, rows),
        z,
        xn: x0.rows(rows, p - rows).into_owned(),
        x0,
        rows,
        rho: config.prior_weight * scale,
        // The divergence holds every link direction the data do not see; a proximal term
        // next to it would only slow the re-anchoring down to its own pace.
        omega: if divergence_weight > 0.0 {
            0.0
        } else {
            config.regularisation * scale
        },
    };
    let data_hess = quad.ar.tr_mul(&quad.ar) * 2.0;
    let basis: [Matrix4<f64>; LINK_PARAMS] = std::array::from_fn(|k| {
        let mut e = [0.0; LINK_PARAMS];
        e[k] = 1.0;
        pseudo_inertia(&e)
    });
    let pi_start = DVector::from_vec(layout.start(anchor));
    let div = Divergence::new(layout, pi_start.as_slice(), &basis);
    let gamma = divergence_weight;
    let mut x = q.tr_mul(&pi_start);
    let mut pi = &q * &x;
    let Some((bar_links, mut bar_bounds)) = layout.barrier_parts(pi.as_slice()) else {
        return Err(PrrrpError::Infeasible {
            what: "no interior start point (prior too close to the boundary)".into(),
        });
    };
    let f0 = quad.data(&x);
    if !f0.is_finite() {
        return Err(PrrrpError::NonFinite {
            what: "objective at the start point (data or prior too large)".into(),
            row: None,
        });
    }
    let degree = layout.degree();
    let signal = z.norm_squared() + r0sq;
    let mut t = (f0 + r0sq).max(f64::MIN_POSITIVE) / degree;
    // φ_t = f + (γ' + t)·Σ D + t·Σ −log f_j, tracked as f = quad + γ'·ΣD and the parts.
    let mut dsum = div.value(&pi, bar_links);
    let mut f = quad.value(&x) + gamma * dsum;
    let mut steps = 0;
    let mut last_fd = f64::INFINITY;
    let mut gpi = DVector::zeros(p);
    let mut hpi = DMatrix::zeros(p, p);
    let mut grad = DVector::zeros(p);
    let mut hess = DMatrix::zeros(p, p);
    loop {
        // Centre φ_t by damped Newton.
        loop {
            steps += 1;
            if steps > config.max_iterations {
                if partial_ok {
                    return Ok((pi.as_slice().to_vec(), steps - 1, false));
                }
                return Err(PrrrpError::Diverged {
                    what,
                    at: config.max_iterations,
                    hint: "no convergence within PhysicalConfig::max_iterations (Newton \
                           steps): raise it or the tolerance, and check the data (outliers, \
                           scaling); a divergence_weight near 0 lets directions the data \
                           barely see run far from the prior (keep the default 10)",
                });
            }
            crate::interrupt::check(what)?;
            gpi.copy_from(&(&div.linear * (t + gamma)));
            hpi.fill(0.0);
            if layout
                .add_barrier_derivatives(pi.as_slice(), t + gamma, t, &basis, &mut gpi, &mut hpi)
                .is_none()
            {
                return Err(PrrrpError::Infeasible {
                    what: "the iterate left the interior (round-off)".into(),
                });
            }
            // Barrier and prior terms to x, then the quadratic ones.
            grad.copy_from(&q.tr_mul(&gpi));
            hess.copy_from(&(q.tr_mul(&(&hpi * &q))));
            let d = &x - &quad.x0;
            let r = &quad.ar * x.rows(0, rows) - z;
            let gd = quad.ar.tr_mul(&r) * 2.0;
            {
                let mut top = grad.rows_mut(0, rows);
                top += gd;
            }
            let mut hb = hess.view_mut((0, 0), (rows, rows));
            hb += &data_hess;
            grad += &d * (2.0 * quad.rho);
            for k in 0..p {
                hess[(k, k)] += 2.0 * quad.rho;
            }
            for k in rows..p {
                grad[k] += 2.0 * quad.omega * (x[k] - quad.xn[k - rows]);
                hess[(k, k)] += 2.0 * quad.omega;
            }
            let Some(step) = newton_step(&hess, &grad) else {
                return Err(PrrrpError::NotPositiveDefinite {
                    what: "the Newton system of the physically consistent fit",
                });
            };
            // Newton decrement λ² = −∇φᵀ·Δ; φ_t is within λ²/2 of its minimum.
            let dec = -grad.dot(&step);
            // (NaN-safe: a NaN decrement also stops the centring.)
            if dec.is_nan() || dec <= 0.05 * degree * t {
                break;
            }
            let phi = f + t * (dsum + bar_bounds);
            let mut s = 1.0;
            let mut moved = false;
            while s > 1e-10 {
                let cand = &x + &step * s;
                let cand_pi = &q * &cand;
                if let Some((cl, cb)) = layout.barrier_parts(cand_pi.as_slice()) {
                    let dc = div.value(&cand_pi, cl);
                    let fc = quad.value(&cand) + gamma * dc;
                    let phi_c = fc + t * (dc + cb);
                    // Strictly lower: at the round-off floor equal values would loop.
                    if phi_c < phi - 0.25 * s * dec && phi_c < phi {
                        x = cand;
                        pi = cand_pi;
                        f = fc;
                        dsum = dc;
                        bar_bounds = cb;
                        moved = true;
                        break;
                    }
                }
                s *= 0.5;
            }
            if !moved {
                // Round-off floor of φ_t: as centred as it gets.
                break;
            }
        }
        let fd = quad.data(&x) + quad.rho * (&x - &quad.x0).norm_squared() + gamma * dsum;
        // f(π_t) − f* ≤ t·(ν + Σ tr(J₀⁻¹J*)), ν the barrier degree; Σ tr(J₀⁻¹J) at π_t
        // stands in for the unknown optimum's.
        let gap = t * (degree + div.linear.dot(&pi).max(0.0));
        let gap_ok = gap <= tol * (fd + r0sq) || gap <= tol * tol * signal;
        // Re-anchored solves that no longer lower the objective: the proximal term
        // biases nothing any more.
        let settled = (last_fd - fd).abs() <= tol * (fd + r0sq) + tol * tol * signal;
        last_fd = fd;
        if gap_ok && settled {
            return Ok((pi.as_slice().to_vec(), steps, true));
        }
        // Proximal re-anchoring: the unseen directions stay where the path brought them,
        // so at the fixed point the proximal term vanishes and does not bias β.
        quad.xn.copy_from(&x.rows(rows, p - rows));
        if !gap_ok {
            t /= BARRIER_SHRINK;
        }
        f = quad.value(&x) + gamma * dsum;
    }
}

/// Δ = −H⁻¹·g by Cholesky, with a growing diagonal shift if H is numerically singular.
fn newton_step(h: &DMatrix<f64>, g: &DVector<f64>) -> Option<DVector<f64>> {
    let p = h.nrows();
    let hmax = (0..p).fold(0.0f64, |m, k| m.max(h[(k, k)].abs()));
    let mut shift = 0.0;
    for _ in 0..12 {
        let mut m = h.clone();
        for k in 0..p {
            m[(k, k)] += shift;
        }
        if let Some(c) = m.cholesky() {
            let step = -c.solve(g);
            if step.iter().all(|x| x.is_finite()) {
                return Some(step);
            }
        }
        shift = if shift == 0.0 {
            1e-14 * hmax
        } else {
            shift * 100.0
        };
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The barrier's analytic gradient and Hessian against central differences of its
    /// value, at an interior point of a link with friction.
    #[test]
    fn barrier_derivatives_match_finite_differences() {
        let layout = Layout::new(1, FrictionModel::all());
        let mut pi = crate::models::chain::inertial_parameters(
            2.0,
            [0.1, -0.2, 0.3],
            [0.05, 0.001, 0.04, -0.002, 0.003, 0.03],
        )
        .to_vec();
        pi.extend([0.4, 0.7, -0.2]);
        let basis: [Matrix4<f64>; LINK_PARAMS] = std::array::from_fn(|k| {
            let mut e = [0.0; LINK_PARAMS];
            e[k] = 1.0;
            pseudo_inertia(&e)
        });
        let mut g = DVector::zeros(13);
        let mut h = DMatrix::zeros(13, 13);
        layout
            .add_barrier_derivatives(&pi, 1.0, 1.0, &basis, &mut g, &mut h)
            .unwrap();
        let eps = 1e-6;
        let grad_at = |x: &[f64]| {
            let mut g = DVector::zeros(13);
            let mut h = DMatrix::zeros(13, 13);
            layout
                .add_barrier_derivatives(x, 1.0, 1.0, &basis, &mut g, &mut h)
                .unwrap();
            g
        };
        for k in 0..13 {
            let (mut a, mut b) = (pi.clone(), pi.clone());
            a[k] += eps;
            b[k] -= eps;
            let fd = (layout.barrier(&a).unwrap() - layout.barrier(&b).unwrap()) / (2.0 * eps);
            assert!(
                (fd - g[k]).abs() < 1e-5 * (1.0 + g[k].abs()),
                "grad {k}: {fd} vs {}",
                g[k]
            );
            let dg = (grad_at(&a) - grad_at(&b)) / (2.0 * eps);
            for l in 0..13 {
                assert!(
                    (dg[l] - h[(l, k)]).abs() < 1e-4 * (1.0 + h[(l, k)].abs()),
                    "hess ({l},{k}): {} vs {}",
                    dg[l],
                    h[(l, k)]
                );
            }
        }
        assert_eq!(g[12], 0.0, "the offset is free");
    }

    /// The start point of a consistent link is the link itself; of a non-physical one, a
    /// strictly consistent body.
    #[test]
    fn interior_start() {
        let p = crate::models::chain::inertial_parameters(
            2.0,
            [0.1, -0.2, 0.3],
            [0.05, 0.001, 0.04, -0.002, 0.003, 0.03],
        );
        let q = interior_link(&p);
        for k in 0..10 {
            assert!((q[k] - p[k]).abs() < 1e-12, "{k}");
        }
        let bad = crate::models::chain::inertial_parameters(
            1.0,
            [0.0; 3],
            [0.01, 0.0, 0.01, 0.0, 0.0, 0.05],
        );
        assert!(pseudo_inertia(&interior_link(&bad)).cholesky().is_some());
        assert_eq!(interior_link(&[0.0; 10]), default_body());
    }
}
