//! Batch least squares (eqs. 2–4, 35–36) and weighted least squares with per-joint noise
//! variances, solved by a rank-revealing QR factorisation (faer, column pivoting) — never
//! through the normal equations WᵀW·λ = Wᵀτ, which square the condition number.

use faer::linalg::solvers::SolveLstsqCore;
use faer::{Conj, Mat};
use nalgebra::{SMatrix, SVector};

use super::samples::{all_finite, Samples};
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

/// Ordinary least squares λ̂ = argmin ‖τ − W·λ‖² over a dataset (eqs. 35–36), with the
/// statistics the field reports.
///
/// Builds W ∈ R^{(N·n)×P} from the regressor of every sample and factorises it by QR with
/// column pivoting (faer); the singular values come from an SVD of the P×P factor R,
/// which has the same singular values as W.
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
    check_config(config)?;
    check_samples::<N, P>(data)?;
    let (w, y) = build_system(model, data, &SVector::<f64, N>::repeat(1.0))?;
    let sol = solve::<P>(w, y, config.rank_tolerance)?;
    let joint_variances = joint_residual_variances::<N, P>(&sol.residual, data.len());
    Ok(sol.report(joint_variances, data.len()))
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
    check_config(config)?;
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
            let ols = least_squares(model, data, config)?;
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
    let (w, y) = build_system(model, data, &scale)?;
    let sol = solve::<P>(w, y, config.rank_tolerance)?;
    Ok(sol.report(variances, data.len()))
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

/// Stacks the row-scaled regressors into W (column-major, N·n × P) and τ into y.
fn build_system<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
    model: &M,
    data: &Samples<'_, N>,
    row_scale: &SVector<f64, N>,
) -> Result<(Mat<f64>, Vec<f64>)> {
    let n = data.len();
    let rows = N * n;
    let mut w = Mat::<f64>::zeros(rows, P);
    let mut y = vec![0.0; rows];
    for (k, s) in data.iter().enumerate() {
        s.check_finite()
            .map_err(|e| super::estimator::with_row(e, k))?;
        let phi: SMatrix<f64, N, P> = model.regressor(s.q, s.qd, s.qdd);
        for i in 0..N {
            y[N * k + i] = s.tau[i] * row_scale[i];
        }
        for j in 0..P {
            let col = &mut w.col_as_slice_mut(j)[N * k..N * k + N];
            for i in 0..N {
                col[i] = phi[(i, j)] * row_scale[i];
            }
        }
    }
    debug_assert!(all_finite(row_scale));
    Ok((w, y))
}

/// The solved problem, before the per-joint statistics.
struct Solution<const P: usize> {
    lambda: SVector<f64, P>,
    singular_values: SVector<f64, P>,
    sigma2: f64,
    std_dev: SVector<f64, P>,
    residual: Vec<f64>,
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

/// Solves min ‖y − W·λ‖ by QR with column pivoting: W·Πᵀ = Q·R.
fn solve<const P: usize>(w: Mat<f64>, y: Vec<f64>, rank_tolerance: f64) -> Result<Solution<P>> {
    let rows = w.nrows();
    debug_assert_eq!(w.ncols(), P);
    let qr = w.as_ref().col_piv_qr();
    // fwd[k] = index in λ of the k-th pivoted column.
    let (fwd, _) = qr.P().arrays();
    let r_faer = qr.thin_R();
    let r = SMatrix::<f64, P, P>::from_fn(|i, j| if i <= j { r_faer[(i, j)] } else { 0.0 });
    if !r.iter().all(|x| x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "QR factor of W".into(),
            row: None,
        });
    }

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
        .filter(|&&s| s > rank_tolerance * smax && s > 0.0)
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

    let mut rhs = Mat::<f64>::from_fn(rows, 1, |i, _| y[i]);
    qr.solve_lstsq_in_place_with_conj(Conj::No, rhs.as_mut());
    let lambda = SVector::<f64, P>::from_fn(|i, _| rhs[(i, 0)]);

    // ρ = y − W·λ̂ from the factors: W·λ̂ = Q·R·Π·λ̂, computed directly from W instead, which
    // is exact to rounding and cheap (one pass).
    let mut residual = y;
    for j in 0..P {
        let col = w.col_as_slice(j);
        let l = lambda[j];
        for (r, &wij) in residual.iter_mut().zip(col) {
            *r -= wij * l;
        }
    }
    let sigma2 = residual.iter().map(|r| r * r).sum::<f64>() / (rows - P) as f64;

    // (WᵀW)⁻¹ = Πᵀ·R⁻¹·R⁻ᵀ·Π: the variance of λ_fwd[k] is σ²·‖row k of R⁻¹‖².
    let r_inv = upper_triangular_inverse(&r);
    let mut std_dev = SVector::<f64, P>::zeros();
    for k in 0..P {
        let row_norm2: f64 = (k..P).map(|j| r_inv[(k, j)] * r_inv[(k, j)]).sum();
        std_dev[fwd[k]] = (sigma2 * row_norm2).sqrt();
    }
    Ok(Solution {
        lambda,
        singular_values,
        sigma2,
        std_dev,
        residual,
    })
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
