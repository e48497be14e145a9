//! Recursive least squares: the online form of eqs. 2–4, with an optional forgetting
//! factor.

use nalgebra::{SMatrix, SVector};

use super::estimator::Estimator;
use super::samples::Sample;
use crate::error::{PrrrpError, Result};
use crate::model::LinearDynamics;

/// Settings of [`Rls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor ν ∈ (0, 1] (dimensionless, default `1.0`: no forgetting, the
    /// estimate converges to the batch least-squares solution). With ν < 1 old samples
    /// weigh ν^age, which tracks slowly varying parameters; the effective memory is
    /// 1/(1 − ν) samples.
    pub forgetting: f64,
    /// Initial covariance P₀ = δ·I (units of λ² per unit of τ², default `1e6`): large means
    /// "λ₀ is barely known"; the estimate then equals batch least squares regularised by
    /// ‖λ − λ₀‖²/δ.
    pub initial_covariance: f64,
}

impl Default for RlsConfig {
    fn default() -> Self {
        Self {
            forgetting: 1.0,
            initial_covariance: 1e6,
        }
    }
}

/// Recursive least squares over the rows of τ = Φ·λ.
///
/// Each of the N joint equations of a sample is one scalar update (exactly equivalent to
/// the vector update with unit noise covariance, and free of any matrix inversion); the
/// forgetting factor is applied once per sample. Cost per sample ≈ N·(2P² + 4P) flops.
#[derive(Debug, Clone)]
pub struct Rls<M, const N: usize, const P: usize> {
    model: M,
    config: RlsConfig,
    lambda0: SVector<f64, P>,
    lambda: SVector<f64, P>,
    cov: SMatrix<f64, P, P>,
    samples: usize,
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize> Rls<M, N, P> {
    /// A filter starting from λ₀ with covariance `config.initial_covariance`·I.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a forgetting factor outside (0, 1], a
    /// non-positive initial covariance, or a non-finite λ₀.
    pub fn new(model: M, lambda0: SVector<f64, P>, config: RlsConfig) -> Result<Self> {
        let nu = config.forgetting;
        if !(nu > 0.0 && nu <= 1.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "forgetting".into(),
                value: nu,
                reason: "must be in (0, 1]",
            });
        }
        let d = config.initial_covariance;
        if !(d.is_finite() && d > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "initial_covariance".into(),
                value: d,
                reason: "must be finite and > 0",
            });
        }
        check_lambda0(&lambda0)?;
        Ok(Self {
            model,
            config,
            lambda0,
            lambda: lambda0,
            cov: SMatrix::identity() * d,
            samples: 0,
        })
    }

    /// The covariance P (units of λ² per unit of τ²); σ²·P approximates the covariance of
    /// λ̂ when the equation noise has variance σ².
    pub fn covariance(&self) -> &SMatrix<f64, P, P> {
        &self.cov
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
    }

    #[inline(always)]
    fn update_row(&mut self, phi: &SVector<f64, P>, tau: f64) -> bool {
        let p_phi = self.cov * phi;
        let den = 1.0 + phi.dot(&p_phi);
        if !(den > 0.0 && den.is_finite()) {
            return false;
        }
        let e = tau - phi.dot(&self.lambda);
        let inv = 1.0 / den;
        self.lambda.axpy(e * inv, &p_phi, 1.0);
        // P ← P − p·pᵀ/den on one triangle, mirrored, so that P stays exactly symmetric.
        for j in 0..P {
            let pj = p_phi[j] * inv;
            for i in 0..=j {
                let v = self.cov[(i, j)] - p_phi[i] * pj;
                self.cov[(i, j)] = v;
                self.cov[(j, i)] = v;
            }
        }
        true
    }
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize> Estimator<N, P> for Rls<M, N, P> {
    /// One sample: N scalar updates, then P ← P/ν.
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] for NaN/∞ in the sample; [`PrrrpError::Diverged`] if the
    /// covariance lost positive definiteness or the estimate became non-finite (with
    /// ν < 1 and poor excitation P grows without bound: raise ν or excite more).
    fn step(&mut self, sample: Sample<'_, N>) -> Result<&SVector<f64, P>> {
        sample.check_finite()?;
        let phi = self.model.regressor(sample.q, sample.qd, sample.qdd);
        for i in 0..N {
            let row = phi.row(i).transpose();
            if !self.update_row(&row, sample.tau[i]) {
                return Err(diverged(self.samples));
            }
        }
        if self.config.forgetting != 1.0 {
            self.cov /= self.config.forgetting;
        }
        if !(self.lambda.iter().all(|x| x.is_finite()) && self.cov[(0, 0)].is_finite()) {
            return Err(diverged(self.samples));
        }
        self.samples += 1;
        Ok(&self.lambda)
    }

    fn estimate(&self) -> &SVector<f64, P> {
        &self.lambda
    }

    fn reset(&mut self) {
        self.lambda = self.lambda0;
        self.cov = SMatrix::identity() * self.config.initial_covariance;
        self.samples = 0;
    }
}

fn diverged(at: usize) -> PrrrpError {
    PrrrpError::Diverged {
        what: "recursive least squares",
        at,
        hint: "the covariance is no longer positive definite or finite: use a forgetting \
               factor closer to 1 or a trajectory that excites every parameter",
    }
}

pub(crate) fn check_lambda0<const P: usize>(lambda0: &SVector<f64, P>) -> Result<()> {
    if let Some((i, &v)) = lambda0.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(PrrrpError::InvalidParameter {
            field: format!("lambda0[{i}]"),
            value: v,
            reason: "the initial estimate must be finite",
        });
    }
    Ok(())
}
