//! Physically consistent identification: least squares over the standard parameters of a
//! chain, constrained to rigid bodies and dissipative friction.
//!
//! Least squares on the base parameters β fits the torques best but may return values no
//! rigid body has (a negative mass, an inertia breaking the triangle inequality, negative
//! friction) — a model that forward simulation refuses and controllers should not trust.
//! This estimator solves
//!
//! min_π ‖Λ^{1/2}·(W·π − τ)‖² + ρ·s·‖π − π₀‖²
//! subject to J_i(π) ⪰ 0 for every link i, fv_j ≥ 0, fc_j ≥ 0 for every joint j,
//!
//! with W the stacked full regressor (friction columns included), Λ per-joint weights,
//! J_i the 4×4 pseudo-inertia of link i (Wensing, Kim & Slotine 2017) and π₀ a prior
//! (e.g. the URDF inertials). The problem is convex in π; it is solved without a
//! semidefinite solver by writing every link as J = U·Uᵀ with the **log-Cholesky**
//! parametrisation of Rucker & Wensing ("Smooth parameterization of rigid-body inertia",
//! IEEE RA-L 2022):
//!
//! U = e^α·[[e^{d₁}, s₁₂, s₁₃, t₁], [0, e^{d₂}, s₂₃, t₂], [0, 0, e^{d₃}, t₃], [0, 0, 0, 1]],
//!
//! ten unconstrained numbers θ = (α, d₁, d₂, d₃, s₁₂, s₂₃, s₁₃, t₁, t₂, t₃) per link that
//! reach every positive definite J, and fv = θ², fc = θ² (the offset fo is free). The map
//! θ ↦ π is a diffeomorphism onto the interior of the feasible set, so every stationary
//! point of the objective in θ is the global constrained minimum (the problem in π being
//! convex); optima on the boundary (a point mass, a rod, zero friction) are approached as
//! θ runs off to −∞, which the iteration reaches in a few steps.
//!
//! **Solver.** Levenberg–Marquardt (Nielsen's damping update, Marquardt's diagonal
//! scaling) with the analytic Jacobian dπ/dθ (block diagonal: 10×10 per link, scalars for
//! friction). The data enter once, through a QR factorisation of [Λ^{1/2}W | Λ^{1/2}τ]:
//! ‖Λ^{1/2}(Wπ − τ)‖² = ‖R·π − z‖² + r₀², so an iteration costs O(P²) (P standard
//! parameters), independent of the number of samples, and residuals are evaluated without
//! the cancellation of the normal equations.
//!
//! **Unidentifiable directions.** The data see only the base combinations β = K·π; the
//! other directions of π are fixed by the prior: a first solve adds the small regulariser
//! ε·s·‖π − π₀‖² ([`PhysicalConfig::regularisation`], s = ‖Λ^{1/2}W‖²_F / P, so ε is
//! dimensionless) to make the minimum unique; a second solve from there drops ε (keeping
//! the user's ρ), so the base parameters are the constrained least-squares ones,
//! unbiased by ε, while the unseen directions stay where the first solve put them
//! (Levenberg–Marquardt steps have no component along directions the objective does not
//! see). Without a prior, π₀ is a default body per link (1 kg at the link origin, second
//! moments 0.01 kg·m² on each axis) and zero friction.

use faer::Mat;
use nalgebra::{DMatrix, DVector, Matrix4};

use crate::error::{PrrrpError, Result};
use crate::models::chain::{
    pseudo_inertia, pseudo_inertia_to_parameters, BaseOptions, BaseParameters, DynChain,
    FeasibilityReport, FrictionModel, LINK_PARAMS, MAX_MATRIX_ENTRIES,
};

/// Base values are called reachable by a consistent π ([`BaseFeasibility::feasible`]) when
/// the achieved relative mismatch is at most this (dimensionless).
pub const BASE_FEASIBILITY_TOLERANCE: f64 = 1e-6;

/// Settings of [`identify_physical`] and [`PhysicalProblem`].
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalConfig {
    /// Prior standard parameters π₀ (the chain's layout, e.g. the URDF's
    /// [`DynChain::parameters`]); `None` (default) uses a default body per link and zero
    /// friction. The start point is π₀ projected onto the feasible set (pseudo-inertia
    /// eigenvalues raised to 10⁻⁶ of the link's largest, friction to ≥ 10⁻³).
    pub prior: Option<Vec<f64>>,
    /// Weight ρ ≥ 0 of the prior term ρ·s·‖π − π₀‖² (dimensionless, relative to the data
    /// scale s = ‖Λ^{1/2}W‖²_F / P; SI units for π). Default 0: the prior only fixes the
    /// directions the data do not see. A positive ρ biases the base parameters towards
    /// the prior (a ridge / maximum a posteriori estimate).
    pub prior_weight: f64,
    /// The small regulariser ε ≥ 0 of the first solve (dimensionless, same scale as
    /// `prior_weight`, default 1e-6); see the module docs. 0 skips the first solve.
    pub regularisation: f64,
    /// Per-joint weights Λ (length n, each finite and ≥ 0, not all 0) multiplying each
    /// joint's squared residuals, e.g. inverse noise variances; `None` (default) weighs
    /// all joints 1. Applied when the problem is built.
    pub joint_weights: Option<Vec<f64>>,
    /// Most Levenberg–Marquardt iterations per solve (default 1000); exceeding it is
    /// [`PrrrpError::Diverged`].
    pub max_iterations: usize,
    /// Relative tolerance (default 1e-10): stop when an accepted step lowers the
    /// objective by less than `tolerance` times its value, or the step is shorter than
    /// `tolerance` times ‖θ‖.
    pub tolerance: f64,
}

impl Default for PhysicalConfig {
    fn default() -> Self {
        Self {
            prior: None,
            prior_weight: 0.0,
            regularisation: 1e-6,
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
        if !(self.tolerance.is_finite() && self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "PhysicalConfig::tolerance".into(),
                value: self.tolerance,
                reason: "must be in (0, 1); the default is 1e-10",
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
    /// Levenberg–Marquardt iterations (accepted and rejected steps) over both solves.
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
    /// max_r |K·π − β|_r / s_r with s_r = max(|β_r|, 10⁻⁶·max|β|) (dimensionless).
    pub max_relative_mismatch: f64,
    /// Feasibility of `parameters`.
    pub report: FeasibilityReport,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
}

/// A physically consistent identification problem in compact form: the data reduced to
/// R (P×P) and z (P) once, so that solves with other priors or weights of the prior cost
/// O(P²) per iteration whatever the number of samples.
#[derive(Debug, Clone)]
pub struct PhysicalProblem {
    dof: usize,
    friction: FrictionModel,
    base: BaseParameters,
    /// Data in compact form: ‖Λ^{1/2}(Wπ − τ)‖² = ‖a·π − z‖² + r0sq.
    a: DMatrix<f64>,
    z: DVector<f64>,
    r0sq: f64,
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
            dof: n,
            friction: base.friction,
            base,
            a,
            z,
            r0sq,
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
        let svd = scaled.svd(true, true);
        let smax = svd.singular_values.max();
        let eps = 1e-12 * smax;
        let y = svd
            .solve(&self.z, eps)
            .unwrap_or_else(|_| DVector::zeros(ind.len()));
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
        let layout = Layout::new(self.dof, self.friction);
        let anchor = layout.anchor(config.prior.as_deref())?;
        let p = layout.p;
        let scale = data_scale(&self.a, p);
        let mut theta = layout.start(&anchor);
        let mut iterations = 0;
        let what = "physically consistent identification";
        if config.regularisation > 0.0 {
            let reg = (config.prior_weight + config.regularisation) * scale;
            iterations += lm(
                &layout, &self.a, &self.z, self.r0sq, reg, &anchor, &mut theta, config, what,
            )?;
        }
        iterations += lm(
            &layout,
            &self.a,
            &self.z,
            self.r0sq,
            config.prior_weight * scale,
            &anchor,
            &mut theta,
            config,
            what,
        )?;
        let pi = layout.pi(&theta);
        let base = self.base.base_values(&pi)?;
        let residual = self.residual(&pi)?;
        let (ls_base, ls_residual) = self.least_squares();
        let residual_increase_percent = if ls_residual > 0.0 {
            100.0 * (residual / ls_residual - 1.0)
        } else if residual == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        let feasibility = FeasibilityReport::new(&pi, self.dof, &self.friction)?;
        Ok(PhysicalEstimate {
            parameters: pi,
            base,
            base_parameters: self.base.clone(),
            residual,
            ls_base,
            ls_residual,
            residual_increase_percent,
            iterations,
            feasibility,
        })
    }
}

/// Physically consistent identification of a chain's standard parameters from samples:
/// least squares on the torques over rigid-body inertias and dissipative friction (see
/// the [module docs](self) for the method). Inputs are flat row-major (samples × n)
/// slices as numpy arrays are: positions (rad or m), velocities, accelerations and
/// measured generalised forces τ (N·m or N).
///
/// Cost: one QR of the (n·samples) × (p + 1) data, then O(p²) per iteration; a 7-joint
/// arm with friction (91 parameters) on 2000 samples takes a fraction of a second.
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
        .map(|x| x.abs().max(1e-6 * bmax).max(f64::MIN_POSITIVE))
        .collect();
    let a = DMatrix::from_fn(b, p, |r, j| base.map[(r, j)] / s[r]);
    let z = DVector::from_fn(b, |r, _| beta[r] / s[r]);
    let layout = Layout::new(base.dof, base.friction);
    let anchor = layout.anchor(config.prior.as_deref())?;
    let scale = data_scale(&a, p);
    let mut theta = layout.start(&anchor);
    let what = "base feasibility";
    let mut iterations = 0;
    if config.regularisation > 0.0 {
        let reg = (config.prior_weight + config.regularisation) * scale;
        iterations += lm(
            &layout, &a, &z, 0.0, reg, &anchor, &mut theta, config, what,
        )?;
    }
    iterations += lm(
        &layout,
        &a,
        &z,
        0.0,
        config.prior_weight * scale,
        &anchor,
        &mut theta,
        config,
        what,
    )?;
    let pi = layout.pi(&theta);
    let kb = base.base_values(&pi)?;
    let mismatch: Vec<f64> = kb.iter().zip(beta).map(|(x, y)| x - y).collect();
    let max_relative_mismatch = mismatch
        .iter()
        .zip(&s)
        .fold(0.0f64, |m, (d, s)| m.max(d.abs() / s));
    let report = FeasibilityReport::new(&pi, base.dof, &base.friction)?;
    Ok(BaseFeasibility {
        feasible: max_relative_mismatch <= BASE_FEASIBILITY_TOLERANCE,
        parameters: pi,
        mismatch,
        max_relative_mismatch,
        report,
        iterations,
    })
}

fn check_len(what: &str, got: usize, want: usize) -> Result<()> {
    if got != want {
        return Err(PrrrpError::ShapeMismatch {
            what: what.into(),
            expected: format!("{want} entries"),
            got: format!("{got} entries"),
        });
    }
    Ok(())
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

/// How a friction term is parametrised: dissipative terms as θ² (≥ 0), the offset freely.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FrictionParam {
    Square,
    Free,
}

/// The parametrisation θ ↦ π of a chain's standard parameters.
struct Layout {
    dof: usize,
    p: usize,
    /// Kind of each friction parameter, in the chain's order.
    friction: Vec<FrictionParam>,
}

/// Second moment of the default body along each axis (kg·m²) per kg.
const DEFAULT_SECOND_MOMENT: f64 = 0.01;
/// Start value of dissipative friction terms whose prior is ≤ this (SI).
const FRICTION_FLOOR: f64 = 1e-3;
/// Pseudo-inertia eigenvalues of the start point are raised to this fraction of the
/// link's largest.
const EIGEN_FLOOR: f64 = 1e-6;

impl Layout {
    fn new(dof: usize, model: FrictionModel) -> Self {
        let mut friction = Vec::new();
        for _ in 0..dof {
            if model.viscous {
                friction.push(FrictionParam::Square);
            }
            if model.coulomb {
                friction.push(FrictionParam::Square);
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

    /// θ of the feasible point nearest to π₀ in the sense of the module docs.
    fn start(&self, anchor: &[f64]) -> Vec<f64> {
        let mut theta = vec![0.0; self.p];
        for i in 0..self.dof {
            let mut l = [0.0; LINK_PARAMS];
            l.copy_from_slice(&anchor[LINK_PARAMS * i..LINK_PARAMS * (i + 1)]);
            theta[LINK_PARAMS * i..LINK_PARAMS * (i + 1)].copy_from_slice(&link_theta(&l));
        }
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            let f = anchor[off + k];
            theta[off + k] = match kind {
                FrictionParam::Square => f.max(FRICTION_FLOOR).sqrt(),
                FrictionParam::Free => f,
            };
        }
        theta
    }

    fn pi(&self, theta: &[f64]) -> Vec<f64> {
        let mut pi = vec![0.0; self.p];
        self.pi_into(theta, &mut pi);
        pi
    }

    fn pi_into(&self, theta: &[f64], pi: &mut [f64]) {
        for i in 0..self.dof {
            let r = LINK_PARAMS * i..LINK_PARAMS * (i + 1);
            let u = link_u(&theta[r.clone()]);
            pi[r].copy_from_slice(&pseudo_inertia_to_parameters(&(u * u.transpose())));
        }
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            let t = theta[off + k];
            pi[off + k] = match kind {
                FrictionParam::Square => t * t,
                FrictionParam::Free => t,
            };
        }
    }

    /// dπ/dθ: `links[i]` is link i's 10×10 block, `fric[k]` friction parameter k's slope.
    fn jacobian(&self, theta: &[f64], links: &mut [DMatrix<f64>], fric: &mut [f64]) {
        for (i, blk) in links.iter_mut().enumerate() {
            link_jacobian(&theta[LINK_PARAMS * i..LINK_PARAMS * (i + 1)], blk);
        }
        let off = self.dof * LINK_PARAMS;
        for (k, kind) in self.friction.iter().enumerate() {
            fric[k] = match kind {
                FrictionParam::Square => 2.0 * theta[off + k],
                FrictionParam::Free => 1.0,
            };
        }
    }
}

fn default_body() -> [f64; LINK_PARAMS] {
    // Σ = 0.01·1 kg·m² ⇒ I = tr(Σ)·1 − Σ = 0.02·1 kg·m², 1 kg at the origin.
    let i = 2.0 * DEFAULT_SECOND_MOMENT;
    [1.0, 0.0, 0.0, 0.0, i, 0.0, i, 0.0, 0.0, i]
}

/// U(θ) of the log-Cholesky parametrisation (module docs), θ = (α, d₁, d₂, d₃, s₁₂, s₂₃,
/// s₁₃, t₁, t₂, t₃).
fn link_u(t: &[f64]) -> Matrix4<f64> {
    let e = t[0].exp();
    Matrix4::new(
        e * t[1].exp(),
        e * t[4],
        e * t[6],
        e * t[7],
        0.0,
        e * t[2].exp(),
        e * t[5],
        e * t[8],
        0.0,
        0.0,
        e * t[3].exp(),
        e * t[9],
        0.0,
        0.0,
        0.0,
        e,
    )
}

/// Position in U of the entry each θ_k (k ≥ 4) drives linearly.
const OFF_DIAGONAL: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];

/// dπ/dθ of one link into a 10×10 block: column k = π(dU/dθ_k·Uᵀ + U·dU/dθ_kᵀ), π(·)
/// being linear in J.
fn link_jacobian(t: &[f64], out: &mut DMatrix<f64>) {
    let u = link_u(t);
    let e = t[0].exp();
    for k in 0..LINK_PARAMS {
        let mut du = Matrix4::zeros();
        match k {
            0 => du = u,
            1..=3 => du[(k - 1, k - 1)] = u[(k - 1, k - 1)],
            _ => {
                let (r, c) = OFF_DIAGONAL[k - 4];
                du[(r, c)] = e;
            }
        }
        let m = du * u.transpose();
        let dj = m + m.transpose();
        let col = pseudo_inertia_to_parameters(&dj);
        for (row, v) in col.iter().enumerate() {
            out[(row, k)] = *v;
        }
    }
}

/// θ of a link's parameters after raising the pseudo-inertia's eigenvalues to
/// [`EIGEN_FLOOR`] of the largest (the default body if none is positive).
fn link_theta(params: &[f64; LINK_PARAMS]) -> [f64; LINK_PARAMS] {
    let j = pseudo_inertia(params);
    let eig = j.symmetric_eigen();
    let top = eig.eigenvalues.max();
    let j = if top > 0.0 && top.is_finite() {
        let floor = EIGEN_FLOOR * top;
        let d = eig.eigenvalues.map(|l| l.max(floor));
        eig.eigenvectors * Matrix4::from_diagonal(&d) * eig.eigenvectors.transpose()
    } else {
        pseudo_inertia(&default_body())
    };
    // J = U·Uᵀ with U upper triangular: the Cholesky factor of J with rows and columns
    // reversed, reversed back.
    let rev = Matrix4::from_fn(|r, c| j[(3 - r, 3 - c)]);
    let l = match rev.cholesky() {
        Some(c) => c.l(),
        None => return link_theta(&default_body()),
    };
    let u = Matrix4::from_fn(|r, c| l[(3 - r, 3 - c)]);
    let e = u[(3, 3)];
    [
        e.ln(),
        (u[(0, 0)] / e).ln(),
        (u[(1, 1)] / e).ln(),
        (u[(2, 2)] / e).ln(),
        u[(0, 1)] / e,
        u[(1, 2)] / e,
        u[(0, 2)] / e,
        u[(0, 3)] / e,
        u[(1, 3)] / e,
        u[(2, 3)] / e,
    ]
}

/// Levenberg–Marquardt on F(θ) = ‖a·π(θ) − z‖² + reg·‖π(θ) − π₀‖² from `theta` (updated in
/// place); returns the iterations. `r0sq` only enters the relative stopping test.
#[allow(clippy::too_many_arguments)]
fn lm(
    layout: &Layout,
    a: &DMatrix<f64>,
    z: &DVector<f64>,
    r0sq: f64,
    reg: f64,
    anchor: &[f64],
    theta: &mut [f64],
    config: &PhysicalConfig,
    what: &'static str,
) -> Result<usize> {
    let p = layout.p;
    let nl = layout.dof;
    let tol = config.tolerance;
    let mut gram = a.transpose() * a;
    for k in 0..p {
        gram[(k, k)] += reg;
    }
    let anchor = DVector::from_column_slice(anchor);
    let objective = |pi: &DVector<f64>| -> (f64, DVector<f64>) {
        let r = a * pi - z;
        let d = pi - &anchor;
        let f = r.norm_squared() + reg * d.norm_squared();
        // Half-gradient in π: aᵀ·r + reg·(π − π₀), without forming aᵀa·π − aᵀz.
        let g = a.tr_mul(&r) + d * reg;
        (f, g)
    };
    let mut pi = DVector::from_column_slice(&layout.pi(theta));
    let (mut f, mut g) = objective(&pi);
    if !f.is_finite() {
        return Err(PrrrpError::NonFinite {
            what: "objective at the start point (data or prior too large)".into(),
            row: None,
        });
    }
    let signal = z.norm_squared() + r0sq;
    let mut links = vec![DMatrix::zeros(LINK_PARAMS, LINK_PARAMS); nl];
    let mut fric = vec![0.0; layout.friction.len()];
    let mut gd = DMatrix::zeros(p, p);
    let mut h = DMatrix::zeros(p, p);
    let mut j = DVector::zeros(p);
    let mut scale = vec![0.0f64; p];
    let mut mu = 1e-3;
    let mut nu = 2.0;
    let mut fresh = true;
    let mut new_theta = vec![0.0; p];
    let mut new_pi = DVector::zeros(p);
    let off = nl * LINK_PARAMS;
    for it in 1..=config.max_iterations {
        crate::interrupt::check(what)?;
        if fresh {
            // H = Dᵀ·G·D and j = Dᵀ·g with D = dπ/dθ block diagonal.
            layout.jacobian(theta, &mut links, &mut fric);
            for (i, blk) in links.iter().enumerate() {
                let c = LINK_PARAMS * i;
                let gcols = gram.columns(c, LINK_PARAMS) * blk;
                gd.columns_mut(c, LINK_PARAMS).copy_from(&gcols);
            }
            for (k, &s) in fric.iter().enumerate() {
                let col = gram.column(off + k) * s;
                gd.column_mut(off + k).copy_from(&col);
            }
            for (i, blk) in links.iter().enumerate() {
                let c = LINK_PARAMS * i;
                let rows = blk.tr_mul(&gd.rows(c, LINK_PARAMS));
                h.rows_mut(c, LINK_PARAMS).copy_from(&rows);
                let gj = blk.tr_mul(&g.rows(c, LINK_PARAMS));
                j.rows_mut(c, LINK_PARAMS).copy_from(&gj);
            }
            for (k, &s) in fric.iter().enumerate() {
                let row = gd.row(off + k) * s;
                h.row_mut(off + k).copy_from(&row);
                j[off + k] = g[off + k] * s;
            }
            let hmax = (0..p).fold(0.0f64, |m, k| m.max(h[(k, k)]));
            for (k, s) in scale.iter_mut().enumerate() {
                *s = s.max(h[(k, k)]).max(1e-12 * hmax);
            }
            // Every direction already optimal: the gradient's cosine with each Jacobian
            // column, |jₖ| / (‖(AD)ₖ‖·‖r‖), is scale-free.
            let ftot = f + r0sq;
            let cos = (0..p).fold(0.0f64, |m, k| {
                let d = (h[(k, k)] * ftot).sqrt();
                if d > 0.0 {
                    m.max(j[k].abs() / d)
                } else {
                    m
                }
            });
            if cos <= tol || ftot <= tol * tol * signal {
                return Ok(it - 1);
            }
        }
        let mut sys = h.clone();
        for k in 0..p {
            sys[(k, k)] += mu * scale[k];
        }
        let Some(chol) = sys.cholesky() else {
            mu *= nu;
            nu *= 2.0;
            fresh = false;
            continue;
        };
        let delta = -chol.solve(&j);
        let tnorm = theta.iter().map(|x| x * x).sum::<f64>().sqrt();
        if delta.norm() <= tol * (tnorm + tol) {
            return Ok(it);
        }
        for k in 0..p {
            new_theta[k] = theta[k] + delta[k];
        }
        layout.pi_into(&new_theta, new_pi.as_mut_slice());
        let (nf, ng) = objective(&new_pi);
        // Predicted decrease of the local quadratic model: δᵀHδ + 2μ·δᵀSδ > 0.
        let hd = &h * &delta;
        let pred = delta.dot(&hd)
            + 2.0 * mu * (0..p).map(|k| scale[k] * delta[k] * delta[k]).sum::<f64>();
        let actual = f - nf;
        if nf.is_finite() && actual > 0.0 && pred > 0.0 {
            let rho = actual / pred;
            theta.copy_from_slice(&new_theta);
            pi.copy_from(&new_pi);
            f = nf;
            g = ng;
            mu *= (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
            nu = 2.0;
            fresh = true;
            let ftot = f + r0sq;
            if actual <= tol * ftot && pred <= tol * ftot {
                return Ok(it);
            }
        } else {
            mu *= nu;
            nu *= 2.0;
            fresh = false;
            if !mu.is_finite() {
                return Ok(it);
            }
        }
    }
    Err(PrrrpError::Diverged {
        what,
        at: config.max_iterations,
        hint: "no convergence within PhysicalConfig::max_iterations: raise it, or the \
               regularisation / prior_weight, and check the data (outliers, scaling)",
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic dπ/dθ against central differences, at a generic θ.
    #[test]
    fn jacobian_matches_finite_differences() {
        let t = [0.3, -0.4, 0.2, -1.1, 0.15, -0.3, 0.25, 0.1, -0.2, 0.05];
        let mut jac = DMatrix::zeros(10, 10);
        link_jacobian(&t, &mut jac);
        let pi_of = |t: &[f64]| {
            let u = link_u(t);
            pseudo_inertia_to_parameters(&(u * u.transpose()))
        };
        let h = 1e-6;
        for k in 0..10 {
            let (mut tp, mut tm) = (t, t);
            tp[k] += h;
            tm[k] -= h;
            let (a, b) = (pi_of(&tp), pi_of(&tm));
            for r in 0..10 {
                let fd = (a[r] - b[r]) / (2.0 * h);
                assert!((fd - jac[(r, k)]).abs() < 1e-7, "({r},{k}): {fd} vs {}", jac[(r, k)]);
            }
        }
    }

    /// θ of a consistent link maps back to the same parameters, and the image is always
    /// consistent.
    #[test]
    fn theta_round_trip() {
        let p = crate::models::chain::inertial_parameters(
            2.0,
            [0.1, -0.2, 0.3],
            [0.05, 0.001, 0.04, -0.002, 0.003, 0.03],
        );
        let t = link_theta(&p);
        let u = link_u(&t);
        let back = pseudo_inertia_to_parameters(&(u * u.transpose()));
        for k in 0..10 {
            assert!((back[k] - p[k]).abs() < 1e-12, "{k}: {} vs {}", back[k], p[k]);
        }
    }
}
