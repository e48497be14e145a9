//! The interface every parametric rigid-body model offers to the estimators.
//!
//! A model is linear in its P parameters: τ = Φ(q, q̇, q̈)·λ. Estimators are generic over
//! this trait, so they work for the PRRRP arm ([`crate::PrrrpModel`]) and for any other
//! robot with N joints and P parameters that implements it.

use nalgebra::{SMatrix, SVector};

use crate::error::Result;

/// Derivatives of the forward dynamics q̈ = M⁻¹(τ − C·q̇ − G), all at fixed τ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForwardDerivatives<const N: usize, const P: usize> {
    /// The acceleration q̈ itself.
    pub qdd: SVector<f64, N>,
    /// ∂q̈/∂q.
    pub dqdd_dq: SMatrix<f64, N, N>,
    /// ∂q̈/∂q̇.
    pub dqdd_dqd: SMatrix<f64, N, N>,
    /// ∂q̈/∂λ = −M⁻¹·Φ(q, q̇, q̈).
    pub dqdd_dlambda: SMatrix<f64, N, P>,
}

/// A rigid-body model with N joints whose dynamics are linear in P parameters.
///
/// All methods are per-sample and must not allocate.
pub trait LinearDynamics<const N: usize, const P: usize> {
    /// Regressor Φ(q, q̇, q̈) ∈ R^{N×P}, so that τ = Φ·λ.
    fn regressor(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SMatrix<f64, N, P>;

    /// Inverse dynamics τ = M(q, λ)·q̈ + C(q, q̇, λ)·q̇ + G(q, λ).
    fn inverse_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> SVector<f64, N> {
        self.regressor(q, qd, qdd) * lambda
    }

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G).
    ///
    /// # Errors
    /// [`crate::PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite.
    fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<SVector<f64, N>>;

    /// Forward dynamics and its derivatives with respect to q, q̇ and λ.
    ///
    /// # Errors
    /// [`crate::PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite.
    fn forward_derivatives(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<ForwardDerivatives<N, P>>;
}
