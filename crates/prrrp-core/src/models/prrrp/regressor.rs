//! The 5×8 regressor Φ(q, q̇, q̈) of the PRRRP arm (paper Annex B, completed) and the
//! stacked observation matrix W with its condition number (eqs. 35–38).
//!
//! Every entry of Φ is derived symbolically from the Lagrangian written in λ by
//! `derivation/regressor.py`; the tests check Φ·λ against the inverse dynamics and against
//! Pinocchio.

use faer::Mat;
use nalgebra::{SMatrix, SVector};

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::terms::{
    accel_coeffs, coupling_angles, velocity_coeffs, Trig, COUPLING_PARAM,
};
use crate::models::prrrp::types::{Regressor, Vec5};
use crate::models::LinearDynamics;

impl PrrrpModel {
    /// Regressor Φ(q, q̇, q̈) ∈ R^{5×8} with τ = Φ·λ.
    ///
    /// Columns (λ1..λ8):
    /// ```text
    /// Φ[:,1] = [d̈1 + g, 0, 0, 0, 0]
    /// Φ[:,2] = [0, θ̈2, 0, 0, 0]
    /// Φ[:,3] = [0, θ̈2+θ̈3, θ̈2+θ̈3, 0, 0]
    /// Φ[:,4] = [0, (2θ̈2+θ̈3)c3 − (2θ̇2+θ̇3)θ̇3 s3, θ̈2 c3 + θ̇2² s3, 0, 0]
    /// Φ[:,5] = [0, a4, a4, a4, 0]                        with a4 = θ̈2+θ̈3+θ̈4
    /// Φ[:,6] = [0, (θ̈2+a4)c34 − (2θ̇2+u)u s34, θ̈2 c34 + θ̇2² s34, θ̈2 c34 + θ̇2² s34, 0]
    ///                                                    with u = θ̇3+θ̇4
    /// Φ[:,7] = [0, (a3+a4)c4 − (2ω3+θ̇4)θ̇4 s4, (same), a3 c4 + ω3² s4, 0]
    ///                                                    with a3 = θ̈2+θ̈3, ω3 = θ̇2+θ̇3
    /// Φ[:,8] = [e, 0, 0, 0, −e]                          with e = d̈1 − d̈5 + g
    /// ```
    #[inline]
    pub fn regressor(&self, q: &Vec5, qd: &Vec5, qdd: &Vec5) -> Regressor {
        self.regressor_trig(&Trig::new(q), qd, qdd)
    }

    /// [`Self::regressor`] with the trigonometry of q already evaluated.
    #[inline(always)]
    pub(crate) fn regressor_trig(&self, t: &Trig, qd: &Vec5, qdd: &Vec5) -> Regressor {
        let g = self.gravity;
        let (a2, a3, a4) = (qdd[1], qdd[1] + qdd[2], qdd[1] + qdd[2] + qdd[3]);
        let e = qdd[0] - qdd[4] + g;
        let mut phi = Regressor::zeros();
        phi[(0, 0)] = qdd[0] + g;
        phi[(1, 1)] = a2;
        phi[(1, 2)] = a3;
        phi[(2, 2)] = a3;
        phi[(1, 4)] = a4;
        phi[(2, 4)] = a4;
        phi[(3, 4)] = a4;
        phi[(0, 7)] = e;
        phi[(4, 7)] = -e;
        let a = accel_coeffs(qdd);
        let b = velocity_coeffs(qd);
        for (k, &(c, s)) in coupling_angles(t).iter().enumerate() {
            let col = COUPLING_PARAM[k];
            for r in 0..3 {
                phi[(r + 1, col)] = a[k][r] * c + b[k][r] * s;
            }
        }
        phi
    }
}

/// Stacks the regressors of N samples into the observation matrix W ∈ R^{(n·N)×p}
/// (eq. 35): rows n·k .. n·k+n hold Φ(q_k, q̇_k, q̈_k).
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if the three slices differ in length,
/// [`PrrrpError::NonFinite`] naming the first sample with a NaN or infinite value.
pub fn observation_matrix<const N: usize, const P: usize, M: LinearDynamics<N, P>>(
    model: &M,
    q: &[SVector<f64, N>],
    qd: &[SVector<f64, N>],
    qdd: &[SVector<f64, N>],
) -> Result<Mat<f64>> {
    check_lengths(q.len(), &[("qd", qd.len()), ("qdd", qdd.len())])?;
    let mut w = Mat::<f64>::zeros(N * q.len(), P);
    for k in 0..q.len() {
        for (name, v) in [("q", &q[k]), ("qd", &qd[k]), ("qdd", &qdd[k])] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: name.into(),
                    row: Some(k),
                });
            }
        }
        let phi: SMatrix<f64, N, P> = model.regressor(&q[k], &qd[k], &qdd[k]);
        for j in 0..P {
            for i in 0..N {
                w[(N * k + i, j)] = phi[(i, j)];
            }
        }
    }
    Ok(w)
}

/// Condition number σmax/σmin of a matrix with at least as many rows as columns
/// (eq. 38), from its singular values (faer SVD). Returns `f64::INFINITY` for a
/// numerically rank-deficient matrix: σmin ≤ σmax·max(rows, cols)·ε, the rank tolerance
/// of LAPACK and numpy's `matrix_rank`, below which σmin is round-off.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if W has fewer rows than columns or no columns;
/// [`PrrrpError::NonFinite`] if W holds NaN/∞ or the SVD does not converge.
pub fn condition_number(w: &Mat<f64>) -> Result<f64> {
    let s = singular_values(w)?;
    let (max, min) = (s[0], s[s.len() - 1]);
    let tol = max * w.nrows().max(w.ncols()) as f64 * f64::EPSILON;
    Ok(if min > tol { max / min } else { f64::INFINITY })
}

/// Singular values of W in decreasing order.
///
/// # Errors
/// As [`condition_number`].
pub fn singular_values(w: &Mat<f64>) -> Result<Vec<f64>> {
    if w.ncols() == 0 || w.nrows() < w.ncols() {
        return Err(PrrrpError::ShapeMismatch {
            what: "W".into(),
            expected: "at least as many rows as columns, and at least one column".into(),
            got: format!("{}×{}", w.nrows(), w.ncols()),
        });
    }
    let finite = (0..w.ncols()).all(|j| (0..w.nrows()).all(|i| w[(i, j)].is_finite()));
    if !finite {
        return Err(PrrrpError::NonFinite {
            what: "W".into(),
            row: None,
        });
    }
    let mut s = w.singular_values().map_err(|_| PrrrpError::NonFinite {
        what: "SVD of W (did not converge)".into(),
        row: None,
    })?;
    s.sort_by(|a, b| b.total_cmp(a));
    Ok(s)
}

pub(crate) fn check_lengths(n: usize, others: &[(&str, usize)]) -> Result<()> {
    crate::error::check_lens(others, n, "samples", " (as q)")
}
