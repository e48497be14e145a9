//! Analytic derivatives of the PRRRP dynamics, for the extended Kalman filter.

use crate::error::Result;
use crate::models::prrrp::dynamics::{mass_matrix_trig, MassCholesky, PrrrpModel};
use crate::models::prrrp::terms::{
    accel_coeffs, coupling_angles, velocity_coeffs, velocity_coeffs_jacobian, Trig, COUPLING_PARAM,
};
use crate::models::prrrp::types::{Lambda, Mat5, Vec5, NDOF, NPARAM};
use crate::models::{ForwardDerivatives, LinearDynamics};

/// Derivatives of the inverse dynamics τ(q, q̇, q̈) at fixed q̈ and λ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseDerivatives {
    /// ∂τ/∂q (N/m, N, N·m/m, N·m per rad as the joint kinds dictate).
    pub dtau_dq: Mat5,
    /// ∂τ/∂q̇.
    pub dtau_dqd: Mat5,
}

impl PrrrpModel {
    /// ∂τ/∂q and ∂τ/∂q̇ of the inverse dynamics at fixed q̈ and λ (analytic).
    ///
    /// Only θ3 and θ4 enter τ through q (the arm is invariant to d1, θ2 and d5), and only
    /// the Coriolis/centrifugal terms depend on q̇.
    #[inline]
    pub fn inverse_derivatives(
        &self,
        q: &Vec5,
        qd: &Vec5,
        qdd: &Vec5,
        lambda: &Lambda,
    ) -> InverseDerivatives {
        self.inverse_derivatives_trig(&Trig::new(q), qd, qdd, lambda)
    }

    /// [`Self::inverse_derivatives`] with the trigonometry of q already evaluated.
    #[inline(always)]
    fn inverse_derivatives_trig(
        &self,
        t: &Trig,
        qd: &Vec5,
        qdd: &Vec5,
        lambda: &Lambda,
    ) -> InverseDerivatives {
        let a = accel_coeffs(qdd);
        let b = velocity_coeffs(qd);
        let db = velocity_coeffs_jacobian(qd);
        let angles = coupling_angles(t);
        let mut dq = Mat5::zeros();
        let mut dqd = Mat5::zeros();
        for (k, &(c, s)) in angles.iter().enumerate() {
            let l = lambda[COUPLING_PARAM[k]];
            for r in 0..3 {
                // d/dφ of (A cos φ + B sin φ)
                let d = l * (b[k][r] * c - a[k][r] * s);
                // φ = θ3 (k = 0), θ3+θ4 (k = 1), θ4 (k = 2)
                if k <= 1 {
                    dq[(r + 1, 2)] += d;
                }
                if k >= 1 {
                    dq[(r + 1, 3)] += d;
                }
                for j in 0..3 {
                    dqd[(r + 1, j + 1)] += l * s * db[k][r][j];
                }
            }
        }
        InverseDerivatives {
            dtau_dq: dq,
            dtau_dqd: dqd,
        }
    }

    /// Forward dynamics and its derivatives ∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ at fixed τ (analytic):
    /// ∂q̈/∂x = −M⁻¹·∂τ/∂x evaluated at the forward-dynamics q̈, and ∂q̈/∂λ = −M⁻¹·Φ.
    ///
    /// # Errors
    /// [`crate::PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite.
    #[inline]
    pub fn forward_derivatives(
        &self,
        q: &Vec5,
        qd: &Vec5,
        tau: &Vec5,
        lambda: &Lambda,
    ) -> Result<ForwardDerivatives<NDOF, NPARAM>> {
        // One evaluation of the sines and cosines serves M, C·q̇, ∂τ and Φ.
        let t = Trig::new(q);
        let chol = MassCholesky::new(&mass_matrix_trig(&t, lambda))?;
        let h = self.inverse_dynamics_trig(&t, qd, &Vec5::zeros(), lambda);
        let qdd = chol.solve(&(tau - h));
        let id = self.inverse_derivatives_trig(&t, qd, &qdd, lambda);
        let phi = self.regressor_trig(&t, qd, &qdd);
        Ok(ForwardDerivatives {
            qdd,
            dqdd_dq: -chol.solve_matrix(&id.dtau_dq),
            dqdd_dqd: -chol.solve_matrix(&id.dtau_dqd),
            dqdd_dlambda: -chol.solve_matrix(&phi),
        })
    }
}

impl LinearDynamics<NDOF, NPARAM> for PrrrpModel {
    #[inline]
    fn regressor(&self, q: &Vec5, qd: &Vec5, qdd: &Vec5) -> crate::models::prrrp::types::Regressor {
        PrrrpModel::regressor(self, q, qd, qdd)
    }

    #[inline]
    fn inverse_dynamics(&self, q: &Vec5, qd: &Vec5, qdd: &Vec5, lambda: &Lambda) -> Vec5 {
        PrrrpModel::inverse_dynamics(self, q, qd, qdd, lambda)
    }

    #[inline]
    fn forward_dynamics(&self, q: &Vec5, qd: &Vec5, tau: &Vec5, lambda: &Lambda) -> Result<Vec5> {
        PrrrpModel::forward_dynamics_unchecked(self, q, qd, tau, lambda)
    }

    #[inline]
    fn forward_derivatives(
        &self,
        q: &Vec5,
        qd: &Vec5,
        tau: &Vec5,
        lambda: &Lambda,
    ) -> Result<ForwardDerivatives<NDOF, NPARAM>> {
        PrrrpModel::forward_derivatives(self, q, qd, tau, lambda)
    }
}
