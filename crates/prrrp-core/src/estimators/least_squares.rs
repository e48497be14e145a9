//! Batch least squares (eqs. 2–4, 35–36) and weighted least squares with per-joint noise
//! variances, solved by a rank-revealing QR factorisation (faer, column pivoting) — never
//! through the normal equations WᵀW·λ = Wᵀτ, which square the condition number.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::householder;
use faer::linalg::qr::col_pivoting::factor::{
    qr_in_place, qr_in_place_scratch, recommended_block_size,
};
use faer::{Conj, Mat, Par};
use nalgebra::{SMatrix, SVector};

use super::samples::Samples;
use crate::error::{PrrrpError, Result};
use crate::model::LinearDynamics;

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

/// Noise variances of the N joint equations for [`weighted_least_squares`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointNoise<const N: usize> {
    /// Two-step weighted least squares, as the field does it: an ordinary least-squares
    /// pass, then σ_j² of each joint from its residuals (see
    /// [`LeastSquaresReport::joint_variances`]), then the weighted solve.
    Estimated,
    /// Known variances σ_j² of each joint's generalised force (N² or N²·m², per joint);
    /// every entry must be finite and > 0. Only their ratios change λ̂.
    Variances(SVector<f64, N>),
}

/// Result of a least-squares identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeastSquaresReport<const N: usize, const P: usize> {
    /// Estimated parameters λ̂ (units of the model's parameters; kg, kg·m² for PRRRP).
    pub lambda: SVector<f64, P>,
    /// Condition number σmax/σmin of the matrix that was factorised (W for ordinary least
    /// squares, the row-weighted W for weighted least squares).
    pub cond: f64,
    /// Singular values of that matrix, largest first.
    pub singular_values: SVector<f64, P>,
    /// Residual variance σ² = ‖ρ‖²/(rows − P) of the solved problem (N², N²·m² for ordinary
    /// least squares; dimensionless — ≈ 1 when the variances are right — for weighted).
    pub sigma2: f64,
    /// Standard deviation σ_i of each parameter: the square root of the diagonal of
    /// σ²·(WᵀW)⁻¹, with (WᵀW)⁻¹ = P·R⁻¹·R⁻ᵀ·Pᵀ from the QR factor (never formed from WᵀW).
    pub std_dev: SVector<f64, P>,
    /// Relative standard deviation %σ_i = 100·σ_i/|λ̂_i| (percent; infinite for λ̂_i = 0).
    pub rel_std_dev: SVector<f64, P>,
    /// Per-joint noise variances σ_j² (units of τ_j²). Ordinary least squares: estimated
    /// from the residuals of joint j as ‖ρ_j‖²/(n − P/N), the residual degrees of freedom
    /// shared equally among the joints. Weighted least squares: the variances used as
    /// weights.
    pub joint_variances: SVector<f64, N>,
    /// Number of samples n (the stacked problem has N·n rows).
    pub samples: usize,
}

/// Batch least-squares solver owning its buffers (W, τ, Householder factors, scratch):
/// they are sized on first use and reused, so repeated solves of same-sized problems do
/// not allocate or fault in fresh pages for W. [`least_squares`] and
/// [`weighted_least_squares`] are one-shot wrappers.
pub struct LeastSquares {
    config: LeastSquaresConfig,
    w: Mat<f64>,
    y: Mat<f64>,
    householder: Mat<f64>,
    perm_fwd: Vec<usize>,
    perm_bwd: Vec<usize>,
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
            householder: Mat::new(),
            perm_fwd: Vec::new(),
            perm_bwd: Vec::new(),
            scratch: None,
        })
    }

    /// Ordinary least squares; see [`least_squares`].
    ///
    /// # Errors
    /// As [`least_squares`].
    pub fn solve<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
        &mut self,
        model: &M,
        data: &Samples<'_, N>,
    ) -> Result<LeastSquaresReport<N, P>> {
        check_samples::<N, P>(data)?;
        self.build(model, data, &SVector::<f64, N>::repeat(1.0))?;
        let sol = self.factor_and_solve::<P>()?;
        let joint_variances = joint_residual_variances::<N, P>(self.residual(), data.len());
        Ok(sol.report(joint_variances, data.len()))
    }

    /// Weighted least squares; see [`weighted_least_squares`].
    ///
    /// # Errors
    /// As [`weighted_least_squares`].
    pub fn solve_weighted<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
        &mut self,
        model: &M,
        data: &Samples<'_, N>,
        noise: JointNoise<N>,
    ) -> Result<LeastSquaresReport<N, P>> {
        let variances = match noise {
            JointNoise::Variances(v) => {
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
            JointNoise::Estimated => {
                let ols = self.solve(model, data)?;
                let max = ols.joint_variances.max();
                if max > 0.0 {
                    ols.joint_variances.map(|s| s.max(1e-12 * max))
                } else {
                    // A perfect fit: every weighting gives the same answer.
                    SVector::repeat(1.0)
                }
            }
        };
        check_samples::<N, P>(data)?;
        let scale = variances.map(|s| 1.0 / s.sqrt());
        self.build(model, data, &scale)?;
        let sol = self.factor_and_solve::<P>()?;
        Ok(sol.report(variances, data.len()))
    }

    /// Stacks the row-scaled regressors into W (column-major, N·n × P) and τ into y.
    fn build<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
        &mut self,
        model: &M,
        data: &Samples<'_, N>,
        row_scale: &SVector<f64, N>,
    ) -> Result<()> {
        let rows = N * data.len();
        self.w.resize_with(rows, P, |_, _| 0.0);
        self.y.resize_with(rows, 1, |_, _| 0.0);
        let y = self.y.col_as_slice_mut(0);
        for (k, s) in data.iter().enumerate() {
            s.check_finite()
                .map_err(|e| super::estimator::with_row(e, k))?;
            for i in 0..N {
                y[N * k + i] = s.tau[i] * row_scale[i];
            }
        }
        for (k, s) in data.iter().enumerate() {
            let phi: SMatrix<f64, N, P> = model.regressor(s.q, s.qd, s.qdd);
            for j in 0..P {
                let col = &mut self.w.col_as_slice_mut(j)[N * k..N * k + N];
                for i in 0..N {
                    col[i] = phi[(i, j)] * row_scale[i];
                }
            }
        }
        Ok(())
    }

    /// QR with column pivoting of W in place (W·Πᵀ = Q·R), z = Qᵀy, λ̂ = Πᵀ·R⁻¹·z, then
    /// y ← ρ = Q·[0; z_P..] (the residual, without keeping W).
    fn factor_and_solve<const P: usize>(&mut self) -> Result<Solution<P>> {
        let rows = self.w.nrows();
        let bs = recommended_block_size::<f64>(rows, P);
        self.householder.resize_with(bs, P, |_, _| 0.0);
        self.perm_fwd.resize(P, 0);
        self.perm_bwd.resize(P, 0);
        let needs_scratch = !matches!(&self.scratch, Some((shape, _)) if *shape == (rows, bs));
        if needs_scratch {
            let req = StackReq::any_of(&[
                qr_in_place_scratch::<usize, f64>(rows, P, bs, Par::Seq, Default::default()),
                householder::apply_block_householder_sequence_transpose_on_the_left_in_place_scratch::<f64>(rows, bs, 1),
                householder::apply_block_householder_sequence_on_the_left_in_place_scratch::<f64>(rows, bs, 1),
            ]);
            self.scratch = Some(((rows, bs), MemBuffer::new(req)));
        }
        let Some((_, buf)) = self.scratch.as_mut() else {
            unreachable!("scratch was just allocated");
        };
        let stack = MemStack::new(buf);
        qr_in_place(
            self.w.as_mut(),
            self.householder.as_mut(),
            &mut self.perm_fwd,
            &mut self.perm_bwd,
            Par::Seq,
            stack,
            Default::default(),
        );
        let r = SMatrix::<f64, P, P>::from_fn(|i, j| if i <= j { self.w[(i, j)] } else { 0.0 });
        if !r.iter().all(|x| x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "QR factor of W".into(),
                row: None,
            });
        }
        // The Householder basis is the unit lower trapezoid of the factored W.
        for j in 0..P {
            for i in 0..j {
                self.w[(i, j)] = 0.0;
            }
            self.w[(j, j)] = 1.0;
        }
        let fwd: [usize; P] = std::array::from_fn(|k| self.perm_fwd[k]);

        // W and R share their singular values; W's right singular vectors are Πᵀ·V_R.
        let r_mat = Mat::<f64>::from_fn(P, P, |i, j| r[(i, j)]);
        let svd = r_mat.svd().map_err(|_| PrrrpError::NonFinite {
            what: "SVD of the QR factor R (did not converge)".into(),
            row: None,
        })?;
        let (sv, v) = (svd.S().column_vector(), svd.V());
        let mut order: [usize; P] = std::array::from_fn(|i| i);
        order.sort_by(|&a, &b| sv[b].total_cmp(&sv[a]));
        let singular_values = SVector::<f64, P>::from_fn(|i, _| sv[order[i]]);
        let smax = singular_values[0];
        let rank = singular_values
            .iter()
            .filter(|&&s| s > self.config.rank_tolerance * smax && s > 0.0)
            .count();
        if rank < P {
            let directions = order[rank..]
                .iter()
                .map(|&o| {
                    let mut d = vec![0.0; P];
                    for k in 0..P {
                        d[fwd[k]] = v[(k, o)];
                    }
                    d
                })
                .collect();
            let cond = if singular_values[P - 1] > 0.0 {
                smax / singular_values[P - 1]
            } else {
                f64::INFINITY
            };
            return Err(PrrrpError::RankDeficient {
                rank,
                params: P,
                cond,
                directions,
            });
        }

        let stack = MemStack::new(buf);
        householder::apply_block_householder_sequence_transpose_on_the_left_in_place_with_conj(
            self.w.as_ref(),
            self.householder.as_ref(),
            Conj::No,
            self.y.as_mut(),
            Par::Seq,
            stack,
        );
        let y = self.y.col_as_slice_mut(0);
        let z = SVector::<f64, P>::from_column_slice(&y[..P]);
        let rss: f64 = y[P..].iter().map(|v| v * v).sum();
        let sigma2 = rss / (rows - P) as f64;
        // λ̂_fwd = R⁻¹·z; (WᵀW)⁻¹ = Πᵀ·R⁻¹·R⁻ᵀ·Π, so var(λ_fwd[k]) = σ²·‖row k of R⁻¹‖².
        let r_inv = upper_triangular_inverse(&r);
        let lp = r_inv * z;
        let mut lambda = SVector::<f64, P>::zeros();
        let mut std_dev = SVector::<f64, P>::zeros();
        for k in 0..P {
            lambda[fwd[k]] = lp[k];
            let row_norm2: f64 = (k..P).map(|j| r_inv[(k, j)] * r_inv[(k, j)]).sum();
            std_dev[fwd[k]] = (sigma2 * row_norm2).sqrt();
        }

        y[..P].fill(0.0);
        let stack = MemStack::new(buf);
        householder::apply_block_householder_sequence_on_the_left_in_place_with_conj(
            self.w.as_ref(),
            self.householder.as_ref(),
            Conj::No,
            self.y.as_mut(),
            Par::Seq,
            stack,
        );
        Ok(Solution {
            lambda,
            singular_values,
            sigma2,
            std_dev,
        })
    }

    /// The residual ρ = y − W·λ̂ of the last solve (rows N·k + j belong to joint j).
    fn residual(&self) -> &[f64] {
        self.y.col_as_slice(0)
    }
}

/// Ordinary least squares λ̂ = argmin ‖τ − W·λ‖² over a dataset (eqs. 35–36), with the
/// statistics the field reports.
///
/// Builds W ∈ R^{(N·n)×P} from the regressor of every sample and factorises it in place
/// by QR with column pivoting (faer); the singular values come from an SVD of the P×P
/// factor R, which has the same singular values as W. Allocates W for this call: use
/// [`LeastSquares`] to reuse the buffers across solves.
///
/// # Errors
/// - [`PrrrpError::TooFewSamples`] if N·n ≤ P (no residual degree of freedom left);
/// - [`PrrrpError::NonFinite`] naming the first sample with NaN or ∞ in q, q̇, q̈ or τ;
/// - [`PrrrpError::RankDeficient`] with the unidentifiable parameter directions when W does
///   not determine every parameter (a trajectory that does not excite them);
/// - [`PrrrpError::InvalidParameter`] for a rank tolerance outside [0, 1).
pub fn least_squares<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
    model: &M,
    data: &Samples<'_, N>,
    config: &LeastSquaresConfig,
) -> Result<LeastSquaresReport<N, P>> {
    LeastSquares::new(*config)?.solve(model, data)
}

/// Weighted least squares: every equation of joint j is divided by σ_j, so that noisier
/// joints count less (the field's standard for joints with different sensors or units).
///
/// With [`JointNoise::Estimated`] the variances come from an ordinary least-squares pass
/// first (floored at 1e-12 of the largest, so that a noise-free joint cannot get an
/// infinite weight). The reported σ_i use σ²·(W_wᵀW_w)⁻¹, with σ² the weighted residual
/// variance, so they stay right when the variances are known only up to a common factor.
///
/// # Errors
/// As [`least_squares`], and [`PrrrpError::InvalidParameter`] for a given variance that is
/// not finite and > 0.
pub fn weighted_least_squares<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
    model: &M,
    data: &Samples<'_, N>,
    noise: JointNoise<N>,
    config: &LeastSquaresConfig,
) -> Result<LeastSquaresReport<N, P>> {
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

fn check_samples<const N: usize, const P: usize>(data: &Samples<'_, N>) -> Result<()> {
    // At least one residual degree of freedom, so that σ² is defined.
    let needed = (P + 1).div_ceil(N.max(1));
    if data.len() < needed || N == 0 {
        return Err(PrrrpError::TooFewSamples {
            needed,
            got: data.len(),
        });
    }
    Ok(())
}

/// The solved problem, before the per-joint statistics.
struct Solution<const P: usize> {
    lambda: SVector<f64, P>,
    singular_values: SVector<f64, P>,
    sigma2: f64,
    std_dev: SVector<f64, P>,
}

impl<const P: usize> Solution<P> {
    fn report<const N: usize>(
        &self,
        joint_variances: SVector<f64, N>,
        samples: usize,
    ) -> LeastSquaresReport<N, P> {
        let s = &self.singular_values;
        let cond = if s[P - 1] > 0.0 {
            s[0] / s[P - 1]
        } else {
            f64::INFINITY
        };
        LeastSquaresReport {
            lambda: self.lambda,
            cond,
            singular_values: self.singular_values,
            sigma2: self.sigma2,
            std_dev: self.std_dev,
            rel_std_dev: self
                .std_dev
                .zip_map(&self.lambda, |sd, l| 100.0 * sd / l.abs()),
            joint_variances,
            samples,
        }
    }
}

/// Inverse of a nonsingular upper-triangular matrix by back substitution.
fn upper_triangular_inverse<const P: usize>(r: &SMatrix<f64, P, P>) -> SMatrix<f64, P, P> {
    let mut inv = SMatrix::<f64, P, P>::zeros();
    for j in 0..P {
        // Column j of R⁻¹ solves R·x = e_j; x_i = 0 for i > j.
        inv[(j, j)] = 1.0 / r[(j, j)];
        for i in (0..j).rev() {
            let s: f64 = (i + 1..=j).map(|k| r[(i, k)] * inv[(k, j)]).sum();
            inv[(i, j)] = -s / r[(i, i)];
        }
    }
    inv
}

/// σ_j² = ‖ρ_j‖²/(n − P/N) from the stacked residual (rows N·k + j belong to joint j).
fn joint_residual_variances<const N: usize, const P: usize>(
    residual: &[f64],
    n: usize,
) -> SVector<f64, N> {
    let mut ss = SVector::<f64, N>::zeros();
    for chunk in residual.chunks_exact(N) {
        for j in 0..N {
            ss[j] += chunk[j] * chunk[j];
        }
    }
    let dof = n as f64 - P as f64 / N as f64;
    ss / dof
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangular_inverse() {
        let r = SMatrix::<f64, 3, 3>::new(2.0, 1.0, -1.0, 0.0, 3.0, 0.5, 0.0, 0.0, 4.0);
        let inv = upper_triangular_inverse(&r);
        assert!((r * inv - SMatrix::<f64, 3, 3>::identity()).norm() < 1e-14);
    }
}
