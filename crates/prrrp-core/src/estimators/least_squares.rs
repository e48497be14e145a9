//! Batch least squares (eqs. 2–4, 35–36) and weighted least squares with per-joint noise
//! variances.
//!
//! Well-conditioned problems (cond(W) ≤ 1e4, the rank clear by a factor of 2) go through
//! the normal equations, scaled to unit diagonal, with one step of iterative refinement:
//! their error ≈ cond(W)²·ε ≤ 2e-8 before the refinement falls to QR's cond(W)·ε after it,
//! at a lower cost. Anything else goes to a blocked Householder QR of W (faer), which loses
//! only cond·ε and decides the rank from the singular values of R.
//!
//! Design and measurements: docs/design/least-squares.md.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::matmul::matmul;
use faer::linalg::matmul::triangular::{self as tri, BlockStructure};
use faer::linalg::qr::no_pivoting::factor::{
    qr_in_place, qr_in_place_scratch, recommended_block_size,
};
use faer::linalg::triangular_solve;
use faer::{Accum, Conj, Mat, MatMut, MatRef, Par, Side};
use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OMatrix, OVector, U1};

use super::estimator::check_model_size;
use super::samples::SamplesOf;
use crate::error::{PrrrpError, Result};
use crate::models::LinearModel;

/// Per-joint noise of a compile-time-size model.
pub type JointNoise<const N: usize> = JointNoiseOf<Const<N>>;
/// Per-joint noise of a run-time-size model.
pub type DynJointNoise = JointNoiseOf<Dyn>;
/// Least-squares result of a compile-time-size model.
pub type LeastSquaresReport<const N: usize, const P: usize> =
    LeastSquaresReportOf<Const<N>, Const<P>>;
/// Least-squares result of a run-time-size model.
pub type DynLeastSquaresReport = LeastSquaresReportOf<Dyn, Dyn>;

/// Passes of variance re-estimation for [`JointNoiseOf::Estimated`] (the fixed point is
/// usually reached, to 0.1 %, in two to five).
const MAX_VARIANCE_PASSES: usize = 20;

/// Samples between two polls of the stop flag while W is stacked (one atomic load each).
const POLL_SAMPLES: usize = 1024;

/// Largest condition number for which the normal equations are trusted (dimensionless).
/// Their relative error is ≈ cond²·ε: at cond ≤ 1e4 that is ≤ 1e4²·2.2e-16 ≈ 2e-8 before
/// the refinement step (which takes it to ≈ cond·ε), far below the parameters' statistical
/// uncertainty; exciting trajectories give cond 5–100 (up to ~2e3 with friction and
/// inertial columns of different units). Beyond it the solve falls back to Householder
/// QR, which loses only cond·ε.
const NORMAL_EQUATIONS_MAX_COND: f64 = 1e4;

/// Largest condition number for which the normal equations' solution is kept without the
/// refinement step (dimensionless). Its error ≈ cond²·ε is then ≤ 1e2²·2.2e-16 ≈ 2e-12 in
/// the scaled norm, QR's accuracy at cond ≈ 1e4 and six decades below any parameter's
/// statistical uncertainty; exciting data of the paper's arm have cond 5–50. Skipping the
/// refinement saves a pass over W (its residual and Wᵀρ) and a triangular solve. (With
/// cond(W_s) ≤ √P·cond(W) for the unit-diagonal scaling, the bound is 2e-11 for P = 8.)
const UNREFINED_MAX_COND: f64 = 1e2;

/// Settings of [`least_squares`] and [`weighted_least_squares`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeastSquaresConfig {
    /// Relative rank tolerance (dimensionless, default `1e-10`): a singular value of the
    /// observation matrix below `rank_tolerance · σmax` counts as zero and the solve fails
    /// with [`PrrrpError::RankDeficient`]. At 1e-10 the parameter error amplification
    /// cond(W)·ε would already exceed 1e-6.
    pub rank_tolerance: f64,
}

impl Default for LeastSquaresConfig {
    fn default() -> Self {
        Self {
            rank_tolerance: 1e-10,
        }
    }
}

/// Noise variances of the N joint equations for [`weighted_least_squares`] (N is
/// `Const<N>`, [`JointNoise`], or [`Dyn`], [`DynJointNoise`]).
#[derive(Debug, Clone, PartialEq)]
pub enum JointNoiseOf<N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    /// Variances estimated from the data, as the field does it: an ordinary least-squares
    /// pass gives σ_j² of each joint from its residuals (see
    /// [`LeastSquaresReport::joint_variances`]); then each σ_j² is re-estimated from the
    /// residuals of the weighted fit until it changes by less than 0.1 % (at most 20
    /// passes), and the weighted solve uses those. The plain two-step estimate is biased
    /// when noise levels differ by decades (the noisy joints' errors leak into the quiet
    /// joints' ordinary residuals through shared parameters).
    Estimated,
    /// Known variances σ_j² of each joint's generalised force (N² or N²·m², per joint);
    /// every entry must be finite and > 0. Only their ratios change λ̂.
    Variances(OVector<f64, N>),
}

impl<N: Dim> Copy for JointNoiseOf<N>
where
    DefaultAllocator: Allocator<N>,
    OVector<f64, N>: Copy,
{
}

/// Result of a least-squares identification (N joints and P parameters as nalgebra
/// dimensions: [`LeastSquaresReport`] at compile-time sizes, [`DynLeastSquaresReport`] at
/// run-time sizes).
#[derive(Debug, Clone, PartialEq)]
pub struct LeastSquaresReportOf<N: Dim, P: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    /// Estimated parameters λ̂ (units of the model's parameters; kg, kg·m² for PRRRP).
    pub lambda: OVector<f64, P>,
    /// Condition number σmax/σmin of the matrix that was factorised (W for ordinary least
    /// squares, the row-weighted W for weighted least squares).
    pub cond: f64,
    /// Singular values of that matrix, largest first.
    pub singular_values: OVector<f64, P>,
    /// Residual variance σ² = ‖ρ‖²/(rows − P) of the solved problem (N², N²·m² for ordinary
    /// least squares; dimensionless — ≈ 1 when the variances are right — for weighted).
    pub sigma2: f64,
    /// Standard deviation σ_i of each parameter: the square root of the diagonal of
    /// σ²·(WᵀW)⁻¹, with (WᵀW)⁻¹ = R⁻¹·R⁻ᵀ from the triangular factor (of the scaled
    /// Cholesky factorisation of WᵀW when cond(W) ≤ 1e4, of the QR factorisation of W
    /// otherwise).
    pub std_dev: OVector<f64, P>,
    /// Relative standard deviation %σ_i = 100·σ_i/|λ̂_i| (percent). Always defined: +∞
    /// for an estimate λ̂_i = 0 exactly (even when σ_i = 0 too, e.g. τ ≡ 0), never NaN.
    pub rel_std_dev: OVector<f64, P>,
    /// Per-joint noise variances σ_j² (units of τ_j²). Ordinary least squares: estimated
    /// from the residuals of joint j as ‖ρ_j‖²/(n − P/N), the residual degrees of freedom
    /// shared equally among the joints. Weighted least squares: the variances used as
    /// weights.
    pub joint_variances: OVector<f64, N>,
    /// Number of samples n (the stacked problem has N·n rows).
    pub samples: usize,
}

impl<N: Dim, P: Dim> Copy for LeastSquaresReportOf<N, P>
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
    OVector<f64, N>: Copy,
    OVector<f64, P>: Copy,
{
}

/// Batch least-squares solver owning its buffers (W, τ, Householder factors, scratch):
/// they are sized on first use and reused, so repeated solves of same-sized problems do
/// not allocate or fault in fresh pages for W. [`least_squares`] and
/// [`weighted_least_squares`] are one-shot wrappers.
pub struct LeastSquares {
    config: LeastSquaresConfig,
    w: Mat<f64>,
    y: Mat<f64>,
    block: Mat<f64>,
    block_y: Mat<f64>,
    householder: Mat<f64>,
    gram: Mat<f64>,
    resid: Mat<f64>,
    /// W_iᵀW_i (lower triangle, over the joint's column runs) of each joint i of the
    /// unscaled W, and W_iᵀy_i: a row scaling s_i of joint i's equations multiplies them by
    /// s_i², so every weighting of one data set is solved from one stack of W.
    joint_grams: Vec<Mat<f64>>,
    joint_wty: Vec<Mat<f64>>,
    /// Which joints' equations involve which parameters (bit masks) in W.
    masks: Vec<u64>,
    /// Whether `w`, `y`, `joint_grams` and `joint_wty` hold the unscaled stack of the data
    /// of the current solve (the QR path factorises a row-scaled W in place).
    unscaled: bool,
    normal_equations_used: bool,
    scratch: Option<((usize, usize), MemBuffer)>,
}

impl std::fmt::Debug for LeastSquares {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LeastSquares")
            .field("config", &self.config)
            .field("rows", &self.w.nrows())
            .finish_non_exhaustive()
    }
}

impl LeastSquares {
    /// A solver with empty buffers.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a rank tolerance outside [0, 1).
    pub fn new(config: LeastSquaresConfig) -> Result<Self> {
        check_config(&config)?;
        Ok(Self {
            config,
            w: Mat::new(),
            y: Mat::new(),
            block: Mat::new(),
            block_y: Mat::new(),
            householder: Mat::new(),
            gram: Mat::new(),
            resid: Mat::new(),
            joint_grams: Vec::new(),
            joint_wty: Vec::new(),
            masks: Vec::new(),
            unscaled: false,
            normal_equations_used: false,
            scratch: None,
        })
    }

    /// Whether the last factorisation (the last weighted pass for
    /// [`solve_weighted`](Self::solve_weighted)) went through the normal equations (true)
    /// or Householder QR (false, a cond(W) above 1e4 or a rank near the tolerance). Both
    /// give the same report to within ~cond(W)·ε; this is a diagnostic.
    pub fn used_normal_equations(&self) -> bool {
        self.normal_equations_used
    }

    /// Ordinary least squares; see [`least_squares`].
    ///
    /// # Errors
    /// As [`least_squares`].
    pub fn solve<N: Dim, P: Dim, M: LinearModel<N, P>>(
        &mut self,
        model: &M,
        data: &SamplesOf<'_, N>,
    ) -> Result<LeastSquaresReportOf<N, P>>
    where
        DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
    {
        let (nd, pd) = model.dims();
        check_samples(nd.value(), pd.value(), data)?;
        self.unscaled = false;
        let ones = OVector::<f64, N>::repeat_generic(nd, U1, 1.0);
        let (sol, joint_ss) = self.solve_scaled(model, data, &ones)?;
        // σ_j² = ‖ρ_j‖²/(n − P/N): the residual degrees of freedom shared equally.
        let joint_variances =
            joint_ss / (data.len() as f64 - pd.value() as f64 / nd.value() as f64);
        sol.report(joint_variances, data.len())
    }

    /// Weighted least squares; see [`weighted_least_squares`].
    ///
    /// # Errors
    /// As [`weighted_least_squares`].
    pub fn solve_weighted<N: Dim, P: Dim, M: LinearModel<N, P>>(
        &mut self,
        model: &M,
        data: &SamplesOf<'_, N>,
        noise: JointNoiseOf<N>,
    ) -> Result<LeastSquaresReportOf<N, P>>
    where
        DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
    {
        let (nd, pd) = model.dims();
        // Another data set may have been stacked by the last call (the estimated variances
        // start with an ordinary solve, which restacks).
        if matches!(noise, JointNoiseOf::Variances(_)) {
            self.unscaled = false;
        }
        let variances = match noise {
            JointNoiseOf::Variances(v) => {
                if v.nrows() != nd.value() {
                    return Err(PrrrpError::ShapeMismatch {
                        what: "joint noise variances".into(),
                        expected: format!("{} entries (one per joint)", nd.value()),
                        got: format!("{} entries", v.nrows()),
                    });
                }
                for (j, &s) in v.iter().enumerate() {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(PrrrpError::InvalidParameter {
                            field: format!("joint noise variance[{j}]"),
                            value: s,
                            reason: "must be finite and > 0 (units of τ_j²)",
                        });
                    }
                }
                v
            }
            JointNoiseOf::Estimated => {
                let ols = self.solve(model, data)?;
                let floor = |v: OVector<f64, N>| {
                    let max = v.max();
                    v.map(|s| s.max(1e-12 * max))
                };
                if ols.joint_variances.max() > 0.0 {
                    let mut var = floor(ols.joint_variances);
                    // The ordinary pass lets the noisiest joints pull shared parameters, and
                    // the quiet joints' residuals then carry that error: with noise levels
                    // decades apart their variances come out orders of magnitude too large.
                    // Re-estimating each σ_j² from the residuals of the weighted fit removes
                    // it; the fixed point is reached in a few passes.
                    let dof = data.len() as f64 - pd.value() as f64 / nd.value() as f64;
                    for _ in 0..MAX_VARIANCE_PASSES {
                        crate::interrupt::check("least squares")?;
                        let scale = var.map(|s| 1.0 / s.sqrt());
                        let (_, weighted_ss) = self.solve_scaled(model, data, &scale)?;
                        // The weighted residuals are ρ_j/σ_j.
                        let next = floor(var.component_mul(&weighted_ss) / dof);
                        let change =
                            next.zip_fold(&var, 0.0f64, |m, a, b| m.max((a / b - 1.0).abs()));
                        var = next;
                        if change < 1e-3 {
                            break;
                        }
                    }
                    var
                } else {
                    // A perfect fit: every weighting gives the same answer.
                    OVector::repeat_generic(nd, U1, 1.0)
                }
            }
        };
        check_samples(nd.value(), pd.value(), data)?;
        let scale = variances.map(|s| 1.0 / s.sqrt());
        let (sol, _) = self.solve_scaled(model, data, &scale)?;
        sol.report(variances, data.len())
    }

    /// The solve with joint i's equations scaled by `row_scale[i]`: through the normal
    /// equations assembled from the per-joint Gram matrices of the unscaled W (stacked
    /// once per data set: the regressor of every sample is the expensive part), or, when
    /// they cannot be trusted, by QR of the row-scaled W (stacked again, as the
    /// factorisation overwrites it).
    fn solve_scaled<N: Dim, P: Dim, M: LinearModel<N, P>>(
        &mut self,
        model: &M,
        data: &SamplesOf<'_, N>,
        row_scale: &OVector<f64, N>,
    ) -> Result<(Solution<P>, OVector<f64, N>)>
    where
        DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
    {
        let (nd, pd) = model.dims();
        let n = data.len();
        if !self.unscaled {
            let ones = OVector::<f64, N>::repeat_generic(nd, U1, 1.0);
            self.masks = self.build(model, data, &ones)?;
            self.joint_moments_of_w(n)?;
            self.unscaled = true;
        }
        if let Some(done) = self.normal_equations(nd, pd, n, row_scale.as_slice()) {
            self.normal_equations_used = true;
            return Ok(done);
        }
        self.unscaled = false;
        let masks = self.build(model, data, row_scale)?;
        self.factor_and_solve(nd, pd, n, &masks)
    }

    /// W_iᵀW_i and W_iᵀy_i of every joint i of the stacked (unscaled) W.
    fn joint_moments_of_w(&mut self, n: usize) -> Result<()> {
        let (nj, p) = (self.masks.len(), self.w.ncols());
        self.joint_grams.resize_with(nj, Mat::new);
        self.joint_wty.resize_with(nj, Mat::new);
        let mut runs: Vec<(usize, usize)> = Vec::with_capacity(8);
        for i in 0..nj {
            // Each joint's product is a fraction of a second on a 200k-row log.
            crate::interrupt::check("least squares")?;
            let g = &mut self.joint_grams[i];
            g.resize_with(p, p, |_, _| 0.0);
            g.fill(0.0);
            let wty = &mut self.joint_wty[i];
            wty.resize_with(p, 1, |_, _| 0.0);
            wty.fill(0.0);
            gram_and_wty_of_joint(&self.w, &self.y, i, self.masks[i], n, &mut runs, g, wty);
        }
        Ok(())
    }

    /// Each joint's W_iᵀW_i (full, symmetric) of the last solve's unscaled W, or `None`
    /// when W is no longer held unscaled (the last solve went through QR).
    pub(crate) fn joint_grams(&self) -> Option<Vec<Mat<f64>>> {
        if !self.unscaled {
            return None;
        }
        let full = |g: &Mat<f64>| {
            Mat::from_fn(g.nrows(), g.ncols(), |i, j| {
                if i >= j {
                    g[(i, j)]
                } else {
                    g[(j, i)]
                }
            })
        };
        Some(self.joint_grams.iter().map(full).collect())
    }

    /// The unscaled residuals τ − W·β of the last solve's data at parameters `beta`
    /// (joint-major: entry i·n + k is joint i of sample k), or `None` when W is no longer
    /// held unscaled (the last solve went through QR) or `beta` has another length.
    pub(crate) fn residuals_at(&self, beta: &[f64]) -> Option<Vec<f64>> {
        if !self.unscaled || beta.len() != self.w.ncols() {
            return None;
        }
        let n = self.w.nrows() / self.masks.len().max(1);
        let lam = Mat::<f64>::from_fn(beta.len(), 1, |k, _| beta[k]);
        let mut rho = Mat::<f64>::zeros(self.w.nrows(), 1);
        let mut runs = Vec::with_capacity(8);
        let ones = vec![1.0; self.masks.len()];
        residual(
            &self.w,
            &self.y,
            &self.masks,
            &ones,
            n,
            &mut runs,
            &lam,
            &mut rho,
            None,
        );
        Some(rho.col_as_slice(0).to_vec())
    }

    /// Stacks the row-scaled regressors into W (column-major, N·n × P) and τ into y, joint
    /// by joint (row i·n + k is joint i of sample k), and returns for each joint the set
    /// of parameters (bit mask) its equations ever involve.
    fn build<N: Dim, P: Dim, M: LinearModel<N, P>>(
        &mut self,
        model: &M,
        data: &SamplesOf<'_, N>,
        row_scale: &OVector<f64, N>,
    ) -> Result<Vec<u64>>
    where
        DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
    {
        let (nd, pd) = model.dims();
        let (nj, np) = (nd.value(), pd.value());
        let n = data.len();
        // Samples::new made every vector as long as q[0]: one length check covers them.
        if let Some(first) = data.iter().next() {
            first.check_len(nj)?;
        }
        let rows = nj * n;
        self.y.resize_with(rows, 1, |_, _| 0.0);
        let y = self.y.col_as_slice_mut(0);
        for (k, s) in data.iter().enumerate() {
            s.check_finite()
                .map_err(|e| super::estimator::with_row(e, k))?;
            for i in 0..nj {
                y[i * n + k] = s.tau[i] * row_scale[i];
            }
        }
        self.w.resize_with(rows, np, |_, _| 0.0);
        let mut ws = model.workspace();
        let mut phi = OMatrix::<f64, N, P>::zeros_generic(nd, pd);
        // An N-vector, so that the joint loop has the model's (compile-time) length.
        let mut masks = OVector::<u64, N>::zeros_generic(nd, U1);
        let w = &mut self.w;
        for (k, s) in data.iter().enumerate() {
            // A regressor per sample is the expensive part of a solve (seconds on a 200k-row
            // log, several times over for the QR path of weighted least squares): Ctrl-C
            // took up to 9 s to stop `identify --method wls` there.
            if k % POLL_SAMPLES == 0 {
                crate::interrupt::check("least squares")?;
            }
            model.with_regressor(&mut ws, s.q, s.qd, s.qdd, &mut phi, |phi| {
                for j in 0..np {
                    // More than 64 parameters: one block (every bit set).
                    let bit = if np <= 64 { 1u64 << j } else { u64::MAX };
                    let col = &mut w.col_as_slice_mut(j)[k..];
                    for i in 0..nj {
                        let v = phi[(i, j)] * row_scale[i];
                        col[i * n] = v;
                        if v != 0.0 {
                            masks[i] |= bit;
                        }
                    }
                }
            })?;
        }
        let masks = masks.as_slice().to_vec();
        Ok(masks)
    }

    /// The fast path: least squares through the normal equations WᵀW·λ = Wᵀy, or `None`
    /// when they cannot be trusted and the QR path must decide (rank deficiency, cond(W)
    /// above [`NORMAL_EQUATIONS_MAX_COND`], non-finite numbers).
    ///
    /// G = WᵀW costs N·n·P²/2 multiply-adds at matrix-product speed — half of the
    /// Householder QR's and without its level-2 panels — and only the joints' non-zero
    /// column runs enter it (a chain's joint i involves only links i.., about half of W).
    /// G is scaled to unit diagonal, G_s = D·G·D with D = diag(1/‖w_k‖) (the near-optimal
    /// diagonal scaling of van der Sluis), and Cholesky-factored, G_s = L·Lᵀ.
    ///
    /// Accuracy: the Cholesky solve has relative error ≈ cond(W_s)²·ε in the scaled
    /// norm (cond(W_s) ≤ √P·cond(W), in practice below cond(W)); above cond(W) =
    /// [`UNREFINED_MAX_COND`] one step of refinement with the exactly recomputed residual
    /// brings it to about cond(W)·ε, as QR (below, cond²·ε ≤ 2e-11 already is). The
    /// residuals are never taken from τᵀτ − 2λ̂ᵀWᵀτ + λ̂ᵀGλ̂, which cancels catastrophically
    /// for a near-perfect fit. R = Lᵀ·D⁻¹ satisfies RᵀR = G + E with ‖E‖ ≲ P²·ε·‖G‖
    /// (Cholesky backward error), so by Weyl's inequality each computed σ_i² is W's to
    /// within P²·ε·σmax²: a W whose cond(W) exceeds 1e4 cannot pass as better conditioned
    /// (σmin²/σmax² < 1e-8 stays below 1e-8 + 4e-13 for P = 64). The path is taken only when
    /// the computed cond(W) ≤ [`NORMAL_EQUATIONS_MAX_COND`] and σmin > 2·tolerance·σmax, so
    /// the rank decision, when it is close, is always the QR path's.
    fn normal_equations<N: Dim, P: Dim>(
        &mut self,
        nd: N,
        pd: P,
        n: usize,
        row_scale: &[f64],
    ) -> Option<(Solution<P>, OVector<f64, N>)>
    where
        DefaultAllocator: Allocator<N> + Allocator<P>,
    {
        let (nj, p) = (nd.value(), pd.value());
        if self.masks.contains(&0) {
            // A joint with no parameter: leave the bookkeeping to the QR path.
            return None;
        }
        // G = Σ_i s_i²·W_iᵀW_i and Wᵀy = Σ_i s_i²·W_iᵀy_i of the row-scaled problem.
        self.gram.resize_with(p, p, |_, _| 0.0);
        self.gram.fill(0.0);
        let mut wty = Mat::<f64>::zeros(p, 1);
        for ((g, gy), s) in self.joint_grams.iter().zip(&self.joint_wty).zip(row_scale) {
            let s2 = s * s;
            for j in 0..p {
                for i in j..p {
                    self.gram[(i, j)] += s2 * g[(i, j)];
                }
                wty[(j, 0)] += s2 * gy[(j, 0)];
            }
        }
        let masks = &self.masks;
        let mut runs_buf: Vec<(usize, usize)> = Vec::with_capacity(8);
        // Unit-diagonal scaling; a zero column is rank deficiency, for the QR path.
        let mut d = vec![0.0; p];
        for (k, dk) in d.iter_mut().enumerate() {
            let gkk = self.gram[(k, k)];
            if !(gkk.is_finite() && gkk > 0.0) {
                return None;
            }
            *dk = 1.0 / gkk.sqrt();
        }
        for j in 0..p {
            for i in j..p {
                self.gram[(i, j)] *= d[i] * d[j];
            }
        }
        let llt = self.gram.as_ref().llt(Side::Lower).ok()?;
        let l = llt.L();
        // R = Lᵀ·D⁻¹ has W's singular values.
        let r = Mat::<f64>::from_fn(p, p, |i, j| if i <= j { l[(j, i)] / d[j] } else { 0.0 });
        let mut sv = r.as_ref().singular_values().ok()?;
        sv.sort_by(|a, b| b.total_cmp(a));
        let (smax, smin) = (sv[0], sv[p - 1]);
        if !(sv.iter().all(|s| s.is_finite())
            && smin > 0.0
            && smax <= NORMAL_EQUATIONS_MAX_COND * smin
            && smin > 2.0 * self.config.rank_tolerance * smax)
        {
            return None;
        }
        // λ = D·μ with G_s·μ = D·Wᵀy, then, above cond(W) = UNREFINED_MAX_COND, one step
        // of iterative refinement with the exact residual (δ from G·δ = Wᵀρ): it takes the
        // error from cond²·ε·(scaled) to about QR's cond·ε, which the chain's small
        // parameters need (1e-8 relative), for one more pass over W at matrix-vector cost.
        let solve = |v: &mut Mat<f64>| {
            for (k, &dk) in d.iter().enumerate() {
                v[(k, 0)] *= dk;
            }
            triangular_solve::solve_lower_triangular_in_place(l, v.as_mut(), Par::Seq);
            triangular_solve::solve_upper_triangular_in_place(l.transpose(), v.as_mut(), Par::Seq);
            for (k, &dk) in d.iter().enumerate() {
                v[(k, 0)] *= dk;
            }
        };
        let mut lam = wty;
        solve(&mut lam);
        self.resid.resize_with(nj * n, 1, |_, _| 0.0);
        let (w, y, resid) = (&self.w, &self.y, &mut self.resid);
        let mut residual_at = |lam: &Mat<f64>, wtr: Option<&mut Mat<f64>>| {
            residual(w, y, masks, row_scale, n, &mut runs_buf, lam, resid, wtr);
        };
        if smax > UNREFINED_MAX_COND * smin {
            let mut delta = Mat::<f64>::zeros(p, 1);
            residual_at(&lam, Some(&mut delta));
            solve(&mut delta);
            lam += &delta;
        }
        residual_at(&lam, None);
        let lambda = OVector::<f64, P>::from_fn_generic(pd, U1, |k, _| lam[(k, 0)]);
        // (G⁻¹)_kk = d_k²·‖column k of L⁻¹‖², as ‖row k of R⁻¹‖² in the QR path.
        let mut linv = Mat::<f64>::identity(p, p);
        triangular_solve::solve_lower_triangular_in_place(l, linv.as_mut(), Par::Seq);
        let rinv_norm2 = OVector::<f64, P>::from_fn_generic(pd, U1, |k, _| {
            let c = linv.col(k);
            d[k] * d[k] * (k..p).map(|j| c[j] * c[j]).sum::<f64>()
        });
        // The residual is the unscaled y − W·λ̂; joint i's scaled residual is s_i times it.
        let rho = self.resid.col_as_slice(0);
        let joint_ss = OVector::<f64, N>::from_fn_generic(nd, U1, |i, _| {
            row_scale[i] * row_scale[i] * rho[i * n..i * n + n].iter().map(|v| v * v).sum::<f64>()
        });
        let sigma2 = joint_ss.sum() / (nj * n - p) as f64;
        let singular_values = OVector::<f64, P>::from_fn_generic(pd, U1, |i, _| sv[i]);
        let solution = Solution::new(lambda, singular_values, sigma2, &rinv_norm2);
        Some((solution, joint_ss))
    }

    /// Least squares block by block. After permuting rows and columns, W is block diagonal:
    /// each block couples the joints and parameters connected through non-zero entries
    /// (for PRRRP {F1, F5}×{λ1, λ8} and {τ2, τ3, τ4}×{λ2..λ7}, the networks of eq. 40).
    /// Each block is factorised by Householder QR in place (B = Q·R), with
    /// z = Qᵀy, λ̂ = R⁻¹·z and the residual Q·[0; z_p..]; the singular values of W are
    /// those of the blocks' R factors together, (WᵀW)⁻¹ is block diagonal, and a parameter
    /// in no block is an unidentifiable direction of its own. Returns the solution and the
    /// residual sum of squares of each joint. (The normal equations are tried first by
    /// [`Self::solve_scaled`].)
    fn factor_and_solve<N: Dim, P: Dim>(
        &mut self,
        nd: N,
        pd: P,
        n: usize,
        masks: &[u64],
    ) -> Result<(Solution<P>, OVector<f64, N>)>
    where
        DefaultAllocator: Allocator<N> + Allocator<P>,
    {
        self.normal_equations_used = false;
        #[allow(non_snake_case)]
        let (N, P) = (nd.value(), pd.value());
        let blocks = blocks(masks, P);
        let whole = blocks.len() == 1 && blocks[0].0.len() == N && blocks[0].1.len() == P;
        let total_rows = N * n;
        let bs = recommended_block_size::<f64>(total_rows, P);
        let needs_scratch =
            !matches!(&self.scratch, Some((shape, _)) if *shape == (total_rows, bs));
        if needs_scratch {
            let req = StackReq::any_of(&[
                qr_in_place_scratch::<f64>(total_rows, P, bs, Par::Seq, Default::default()),
                householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(total_rows, bs, 1),
                householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(total_rows, bs, 1),
            ]);
            self.scratch = Some(((total_rows, bs), MemBuffer::new(req)));
        }

        let mut spectrum: Vec<(f64, Vec<f64>)> = Vec::with_capacity(P);
        let mut lambda = OVector::<f64, P>::zeros_generic(pd, U1);
        let mut rinv_norm2 = OVector::<f64, P>::zeros_generic(pd, U1);
        let mut joint_ss = OVector::<f64, N>::zeros_generic(nd, U1);
        let mut covered = vec![false; P];
        for (i, &m) in masks.iter().enumerate() {
            if m == 0 {
                // A joint whose equations involve no parameter: all of τ_i is residual.
                let ys = &self.y.col_as_slice(0)[i * n..i * n + n];
                joint_ss[i] = ys.iter().map(|v| v * v).sum();
            }
        }
        for (joints, params) in &blocks {
            crate::interrupt::check("least squares")?;
            let (rows, pc) = (joints.len() * n, params.len());
            if !whole {
                self.block.resize_with(rows, pc, |_, _| 0.0);
                self.block_y.resize_with(rows, 1, |_, _| 0.0);
                for (c, &j) in params.iter().enumerate() {
                    let src = self.w.col_as_slice(j);
                    let dst = self.block.col_as_slice_mut(c);
                    for (a, &i) in joints.iter().enumerate() {
                        dst[a * n..a * n + n].copy_from_slice(&src[i * n..i * n + n]);
                    }
                }
                let src = self.y.col_as_slice(0);
                let dst = self.block_y.col_as_slice_mut(0);
                for (a, &i) in joints.iter().enumerate() {
                    dst[a * n..a * n + n].copy_from_slice(&src[i * n..i * n + n]);
                }
            }
            let (wm, ym) = if whole {
                (&mut self.w, &mut self.y)
            } else {
                (&mut self.block, &mut self.block_y)
            };
            self.householder.resize_with(bs, pc, |_, _| 0.0);
            let Some((_, buf)) = self.scratch.as_mut() else {
                unreachable!("scratch was just allocated");
            };
            qr_in_place(
                wm.as_mut(),
                self.householder.as_mut(),
                Par::Seq,
                MemStack::new(buf),
                Default::default(),
            );
            let r = Mat::<f64>::from_fn(pc, pc, |i, j| if i <= j { wm[(i, j)] } else { 0.0 });
            if !(0..pc).all(|j| (0..pc).all(|i| r[(i, j)].is_finite())) {
                return Err(PrrrpError::NonFinite {
                    what: "QR factor of W".into(),
                    row: None,
                });
            }
            // The Householder basis is the unit lower trapezoid of the factored block.
            for j in 0..pc {
                for i in 0..j {
                    wm[(i, j)] = 0.0;
                }
                wm[(j, j)] = 1.0;
            }
            // Parameter index of the k-th column of the block.
            let pidx = |k: usize| params[k];

            // The block and R share their singular values; its right singular vectors are
            // V_R, embedded in parameter space.
            let svd = r.svd().map_err(|_| PrrrpError::NonFinite {
                what: "SVD of the QR factor R (did not converge)".into(),
                row: None,
            })?;
            let (sv, v) = (svd.S().column_vector(), svd.V());
            for o in 0..pc {
                let mut d = vec![0.0; P];
                for k in 0..pc {
                    d[pidx(k)] = v[(k, o)];
                }
                spectrum.push((sv[o], d));
            }

            // z = Qᵀ·y, then (its first pc entries cleared) the residual Q·z.
            let hh = &self.householder;
            apply_q(wm.as_ref(), hh.as_ref(), true, ym.as_mut(), buf);
            let y = ym.col_as_slice_mut(0);
            // λ̂ = R⁻¹·z; var(λ̂_pidx(k)) = σ²·‖row k of R⁻¹‖² ((WᵀW)⁻¹ = R⁻¹·R⁻ᵀ).
            let r_inv = upper_triangular_inverse_dyn(&r);
            for k in 0..pc {
                let mut l = 0.0;
                let mut norm2 = 0.0;
                for j in k..pc {
                    l += r_inv[(k, j)] * y[j];
                    norm2 += r_inv[(k, j)] * r_inv[(k, j)];
                }
                lambda[pidx(k)] = l;
                rinv_norm2[pidx(k)] = norm2;
                covered[pidx(k)] = true;
            }
            y[..pc].fill(0.0);
            apply_q(wm.as_ref(), hh.as_ref(), false, ym.as_mut(), buf);
            let rho = ym.col_as_slice(0);
            for (a, &i) in joints.iter().enumerate() {
                joint_ss[i] = rho[a * n..a * n + n].iter().map(|v| v * v).sum();
            }
        }
        for (j, &c) in covered.iter().enumerate() {
            if !c {
                // A parameter no equation involves.
                let mut d = vec![0.0; P];
                d[j] = 1.0;
                spectrum.push((0.0, d));
            }
        }
        spectrum.sort_by(|a, b| b.0.total_cmp(&a.0));
        let singular_values = OVector::<f64, P>::from_fn_generic(pd, U1, |i, _| spectrum[i].0);
        let smax = singular_values[0];
        let rank = singular_values
            .iter()
            .filter(|&&s| s > self.config.rank_tolerance * smax && s > 0.0)
            .count();
        if rank < P {
            let cond = if singular_values[P - 1] > 0.0 {
                smax / singular_values[P - 1]
            } else {
                f64::INFINITY
            };
            return Err(PrrrpError::RankDeficient {
                rank,
                params: P,
                cond,
                directions: spectrum.drain(rank..).map(|(_, d)| d).collect(),
            });
        }
        let rss = joint_ss.sum();
        let sigma2 = rss / (total_rows - P) as f64;
        let solution = Solution::new(lambda, singular_values, sigma2, &rinv_norm2);
        Ok((solution, joint_ss))
    }
}

/// Ordinary least squares λ̂ = argmin ‖τ − W·λ‖² over a dataset (eqs. 35–36), with the
/// statistics the field reports.
///
/// Builds W ∈ R^{(N·n)×P} from the regressor of every sample and solves through the
/// scaled normal equations with one refinement step when cond(W) ≤ 1e4, otherwise by
/// Householder QR of W (faer; see the module documentation for the accuracy argument);
/// the singular values come from an SVD of the P×P triangular factor R, which has the same
/// singular values as W. Allocates W for this call: use
/// [`LeastSquares`] to reuse the buffers across solves.
///
/// # Errors
/// - [`PrrrpError::TooFewSamples`] if N·n ≤ P (no residual degree of freedom left);
/// - [`PrrrpError::NonFinite`] naming the first sample with NaN or ∞ in q, q̇, q̈ or τ;
/// - [`PrrrpError::RankDeficient`] with the unidentifiable parameter directions when W does
///   not determine every parameter (a trajectory that does not excite them);
/// - [`PrrrpError::InvalidParameter`] for a rank tolerance outside [0, 1).
pub fn least_squares<N: Dim, P: Dim, M: LinearModel<N, P>>(
    model: &M,
    data: &SamplesOf<'_, N>,
    config: &LeastSquaresConfig,
) -> Result<LeastSquaresReportOf<N, P>>
where
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    LeastSquares::new(*config)?.solve(model, data)
}

/// Weighted least squares: every equation of joint j is divided by σ_j, so that noisier
/// joints count less (the field's standard for joints with different sensors or units).
///
/// With [`JointNoiseOf::Estimated`] the variances come from an ordinary least-squares pass,
/// refined from the weighted residuals (see [`JointNoiseOf::Estimated`]; floored at 1e-12 of
/// the largest, so that a noise-free joint cannot get an infinite weight). The reported σ_i use σ²·(W_wᵀW_w)⁻¹, with σ² the weighted residual
/// variance, so they stay right when the variances are known only up to a common factor.
///
/// # Errors
/// As [`least_squares`], and [`PrrrpError::InvalidParameter`] for a given variance that is
/// not finite and > 0.
pub fn weighted_least_squares<N: Dim, P: Dim, M: LinearModel<N, P>>(
    model: &M,
    data: &SamplesOf<'_, N>,
    noise: JointNoiseOf<N>,
    config: &LeastSquaresConfig,
) -> Result<LeastSquaresReportOf<N, P>>
where
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    LeastSquares::new(*config)?.solve_weighted(model, data, noise)
}

fn check_config(config: &LeastSquaresConfig) -> Result<()> {
    let t = config.rank_tolerance;
    if !(t.is_finite() && (0.0..1.0).contains(&t)) {
        return Err(PrrrpError::InvalidParameter {
            field: "rank_tolerance".into(),
            value: t,
            reason: "must be in [0, 1) (relative to the largest singular value)",
        });
    }
    Ok(())
}

fn check_samples<N: Dim>(nj: usize, np: usize, data: &SamplesOf<'_, N>) -> Result<()>
where
    DefaultAllocator: Allocator<N>,
{
    check_model_size(nj, np)?;
    // At least one residual degree of freedom, so that σ² is defined.
    let needed = (np + 1).div_ceil(nj);
    if data.len() < needed {
        return Err(PrrrpError::TooFewSamples {
            needed,
            got: data.len(),
        });
    }
    Ok(())
}

/// The solved problem, before the per-joint statistics.
struct Solution<P: Dim>
where
    DefaultAllocator: Allocator<P>,
{
    lambda: OVector<f64, P>,
    singular_values: OVector<f64, P>,
    sigma2: f64,
    std_dev: OVector<f64, P>,
}

impl<P: Dim> Solution<P>
where
    DefaultAllocator: Allocator<P>,
{
    /// The solution with std(λ̂_k) = σ·‖row k of R⁻¹‖ from `rinv_norm2`, the squared norms
    /// ((WᵀW)⁻¹_kk).
    fn new(
        lambda: OVector<f64, P>,
        singular_values: OVector<f64, P>,
        sigma2: f64,
        rinv_norm2: &OVector<f64, P>,
    ) -> Self {
        let std_dev = rinv_norm2.map(|v| (sigma2 * v).sqrt());
        Self {
            lambda,
            singular_values,
            sigma2,
            std_dev,
        }
    }

    /// The report, or [`PrrrpError::NonFinite`] when λ̂, σ_i or σ² overflowed (finite data
    /// whose magnitudes, e.g. τ = 1e308, are beyond what f64 arithmetic can square and sum).
    fn report<N: Dim>(
        self,
        joint_variances: OVector<f64, N>,
        samples: usize,
    ) -> Result<LeastSquaresReportOf<N, P>>
    where
        DefaultAllocator: Allocator<N>,
    {
        let finite = |v: &OVector<f64, P>| v.iter().all(|x| x.is_finite());
        if !(finite(&self.lambda) && finite(&self.std_dev) && self.sigma2.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "least-squares estimate (the data's magnitudes overflow f64 arithmetic: \
                       remove or rescale rows with huge values such as 1e308)"
                    .into(),
                row: None,
            });
        }
        let s = &self.singular_values;
        let last = s.nrows() - 1;
        let cond = if s[last] > 0.0 {
            s[0] / s[last]
        } else {
            f64::INFINITY
        };
        // λ̂_i = 0 exactly: +∞ (not 0/0 = NaN when σ_i = 0 as well).
        let rel_std_dev = self.std_dev.zip_map(&self.lambda, |sd, l| {
            if l == 0.0 {
                f64::INFINITY
            } else {
                100.0 * sd / l.abs()
            }
        });
        Ok(LeastSquaresReportOf {
            lambda: self.lambda,
            cond,
            singular_values: self.singular_values,
            sigma2: self.sigma2,
            std_dev: self.std_dev,
            rel_std_dev,
            joint_variances,
            samples,
        })
    }
}

/// Inverse of a nonsingular upper-triangular matrix by back substitution.
fn upper_triangular_inverse_dyn(r: &Mat<f64>) -> Mat<f64> {
    let p = r.nrows();
    let mut inv = Mat::<f64>::zeros(p, p);
    for j in 0..p {
        // Column j of R⁻¹ solves R·x = e_j; x_i = 0 for i > j.
        inv[(j, j)] = 1.0 / r[(j, j)];
        for i in (0..j).rev() {
            let s: f64 = (i + 1..=j).map(|k| r[(i, k)] * inv[(k, j)]).sum();
            inv[(i, j)] = -s / r[(i, i)];
        }
    }
    inv
}

/// Rows per chunk of the passes over W: a chunk of up to 64 columns (≤ 256 KiB) stays in
/// the L2 cache between the products that read it.
const CHUNK_ROWS: usize = 512;

/// Lower triangle of G += W_iᵀW_i and wty += W_iᵀy_i of joint i (rows i·n..(i+1)·n, the
/// parameters of `mask`) over its column runs, chunk by chunk of rows so that W is read
/// from memory once.
#[allow(clippy::too_many_arguments)]
fn gram_and_wty_of_joint(
    w: &Mat<f64>,
    y: &Mat<f64>,
    i: usize,
    mask: u64,
    n: usize,
    runs: &mut Vec<(usize, usize)>,
    gram: &mut Mat<f64>,
    wty: &mut Mat<f64>,
) {
    column_runs(mask, w.ncols(), runs);
    for c0 in (0..n).step_by(CHUNK_ROWS) {
        let rows = CHUNK_ROWS.min(n - c0);
        let wi = w.as_ref().subrows(i * n + c0, rows);
        let yi = y.as_ref().subrows(i * n + c0, rows);
        for (ia, &(a0, a1)) in runs.iter().enumerate() {
            let wa = wi.subcols(a0, a1 - a0);
            tri::matmul(
                gram.as_mut().submatrix_mut(a0, a0, a1 - a0, a1 - a0),
                BlockStructure::TriangularLower,
                Accum::Add,
                wa.transpose(),
                BlockStructure::Rectangular,
                wa,
                BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
            for &(b0, b1) in &runs[ia + 1..] {
                matmul(
                    gram.as_mut().submatrix_mut(b0, a0, b1 - b0, a1 - a0),
                    Accum::Add,
                    wi.subcols(b0, b1 - b0).transpose(),
                    wa,
                    1.0,
                    Par::Seq,
                );
            }
            matmul(
                wty.as_mut().subrows_mut(a0, a1 - a0),
                Accum::Add,
                wa.transpose(),
                yi,
                1.0,
                Par::Seq,
            );
        }
    }
}

/// rho = y − W·λ over the joints' column runs and, when `wtr` is given, wtr += Σ_i
/// s_i²·W_iᵀ·rho_i (the row-scaled problem's Wᵀρ, `row_scale` s_i) in the same pass (chunk
/// by chunk, while the chunk of W is in cache).
#[allow(clippy::too_many_arguments)]
fn residual(
    w: &Mat<f64>,
    y: &Mat<f64>,
    masks: &[u64],
    row_scale: &[f64],
    n: usize,
    runs: &mut Vec<(usize, usize)>,
    lambda: &Mat<f64>,
    rho: &mut Mat<f64>,
    mut wtr: Option<&mut Mat<f64>>,
) {
    rho.col_as_slice_mut(0).copy_from_slice(y.col_as_slice(0));
    for (i, &m) in masks.iter().enumerate() {
        column_runs(m, w.ncols(), runs);
        for c0 in (0..n).step_by(CHUNK_ROWS) {
            let rows = CHUNK_ROWS.min(n - c0);
            let wi = w.as_ref().subrows(i * n + c0, rows);
            let mut ri = rho.as_mut().subrows_mut(i * n + c0, rows);
            for &(a0, a1) in runs.iter() {
                matmul(
                    ri.as_mut(),
                    Accum::Add,
                    wi.subcols(a0, a1 - a0),
                    lambda.as_ref().subrows(a0, a1 - a0),
                    -1.0,
                    Par::Seq,
                );
            }
            if let Some(out) = wtr.as_deref_mut() {
                for &(a0, a1) in runs.iter() {
                    matmul(
                        out.as_mut().subrows_mut(a0, a1 - a0),
                        Accum::Add,
                        wi.subcols(a0, a1 - a0).transpose(),
                        ri.as_ref(),
                        row_scale[i] * row_scale[i],
                        Par::Seq,
                    );
                }
            }
        }
    }
}

/// The runs [start, end) of set bits of `mask` among the first `p` columns (every column
/// for p > 64, whose masks have every bit set), gaps of up to two columns bridged: a few
/// long runs make fewer, more efficient matrix products than exact short ones.
fn column_runs(mask: u64, p: usize, out: &mut Vec<(usize, usize)>) {
    out.clear();
    if p > 64 {
        out.push((0, p));
        return;
    }
    for j in 0..p {
        if mask & (1u64 << j) == 0 {
            continue;
        }
        match out.last_mut() {
            Some((_, end)) if j <= *end + 2 => *end = j + 1,
            _ => out.push((j, j + 1)),
        }
    }
}

/// Groups joints and parameters into independent blocks: two parameters are in the same
/// block when some joint's equations involve both. Returns (joints, parameters) of every
/// block that has at least one parameter, in order of their first joint.
fn blocks(masks: &[u64], p: usize) -> Vec<(Vec<usize>, Vec<usize>)> {
    #[allow(non_snake_case)]
    let (N, P) = (masks.len(), p);
    let mut merged: Vec<u64> = Vec::new();
    for &m in masks.iter().filter(|&&m| m != 0) {
        let mut acc = m;
        merged.retain(|&b| {
            if b & acc != 0 {
                acc |= b;
                false
            } else {
                true
            }
        });
        merged.push(acc);
    }
    // A later merge can connect earlier groups: repeat until stable.
    loop {
        let mut changed = false;
        let mut out: Vec<u64> = Vec::new();
        for &m in &merged {
            if let Some(o) = out.iter_mut().find(|o| **o & m != 0) {
                *o |= m;
                changed = true;
            } else {
                out.push(m);
            }
        }
        merged = out;
        if !changed {
            break;
        }
    }
    let mut out: Vec<(Vec<usize>, Vec<usize>)> = merged
        .iter()
        .map(|&b| {
            let joints = (0..N)
                .filter(|&i| masks[i] != 0 && masks[i] & b != 0)
                .collect();
            let params = (0..P.min(64))
                .filter(|&j| b & (1 << j) != 0)
                .collect::<Vec<_>>();
            let params = if P > 64 { (0..P).collect() } else { params };
            (joints, params)
        })
        .collect();
    out.sort_by_key(|(j, _): &(Vec<usize>, Vec<usize>)| j[0]);
    out
}

/// y ← Qᵀ·y (`transpose`) or Q·y, Q the orthogonal factor of a block QR in place
/// (`basis`: the Householder vectors below the diagonal, `factor`: their block factors),
/// on one thread in the scratch `buf` (sized for both directions).
fn apply_q(
    basis: MatRef<'_, f64>,
    factor: MatRef<'_, f64>,
    transpose: bool,
    y: MatMut<'_, f64>,
    buf: &mut MemBuffer,
) {
    let apply = if transpose {
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj
    } else {
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj
    };
    apply(basis, factor, Conj::No, y, Par::Seq, MemStack::new(buf));
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::SMatrix;

    #[test]
    fn triangular_inverse() {
        let r = SMatrix::<f64, 3, 3>::new(2.0, 1.0, -1.0, 0.0, 3.0, 0.5, 0.0, 0.0, 4.0);
        let rf = Mat::<f64>::from_fn(3, 3, |i, j| r[(i, j)]);
        let inv = upper_triangular_inverse_dyn(&rf);
        let inv = SMatrix::<f64, 3, 3>::from_fn(|i, j| inv[(i, j)]);
        assert!((r * inv - SMatrix::<f64, 3, 3>::identity()).norm() < 1e-14);
    }

    #[test]
    fn blocks_of_the_prrrp_pattern() {
        // F1: λ1, λ8; τ2..τ4: λ2..λ7; F5: λ8.
        let masks = [
            0b1000_0001,
            0b0111_1110,
            0b0111_1100,
            0b0111_0000,
            0b1000_0000,
        ];
        let b = blocks(&masks, 8);
        assert_eq!(
            b,
            vec![
                (vec![0, 4], vec![0, 7]),
                (vec![1, 2, 3], vec![1, 2, 3, 4, 5, 6])
            ]
        );
        // A joint linking two groups merges them, whatever the order.
        let masks = [0b0001, 0b0100, 0b0110, 0b1000];
        let b = blocks(&masks, 4);
        assert_eq!(
            b,
            vec![
                (vec![0], vec![0]),
                (vec![1, 2], vec![1, 2]),
                (vec![3], vec![3])
            ]
        );
        let masks = [0b0011, 0b1100, 0b0110];
        assert_eq!(blocks(&masks, 4), vec![(vec![0, 1, 2], vec![0, 1, 2, 3])]);
    }
}
