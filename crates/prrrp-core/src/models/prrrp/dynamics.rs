//! Closed-form Lagrange–Euler dynamics of the PRRRP arm as functions of λ
//! (paper Annex A, with typos 1 and 3 of the notes corrected).

use nalgebra::SMatrix;

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::terms::{
    accel_coeffs, coupling_angles, velocity_coeffs, Trig, COUPLING_PARAM,
};
use crate::models::prrrp::types::{Lambda, Mat5, Vec5};

/// The constant part of the PRRRP dynamic model: only gravity, since every inertial
/// quantity enters through λ, which each call takes as an argument (the estimators need
/// the model at any λ, not only at the physical one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrrrpModel {
    /// Gravitational acceleration, m/s², along world −z (default 9.81).
    pub gravity: f64,
}

impl Default for PrrrpModel {
    fn default() -> Self {
        Self {
            gravity: crate::models::prrrp::robot::STANDARD_GRAVITY,
        }
    }
}

/// Cholesky factorisation of the PRRRP mass matrix, exploiting its block structure:
/// the prismatic joints (1, 5) and the planar joints (2, 3, 4) do not couple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassCholesky {
    /// Lower factor of the 2×2 prismatic block (rows/cols d1, d5): [l00, l10, l11].
    p: [f64; 3],
    /// Lower factor of the 3×3 planar block: [l00, l10, l11, l20, l21, l22].
    r: [f64; 6],
    /// Reciprocals of the five pivots (prismatic l00, l11, planar l00, l11, l22): a solve
    /// then multiplies instead of dividing, which matters when the EKF solves 19
    /// right-hand sides per sample (a division costs several multiplications).
    inv: [f64; 5],
}

impl MassCholesky {
    /// Factorises M = L·Lᵀ.
    ///
    /// # Errors
    /// [`PrrrpError::NotPositiveDefinite`] if a pivot is not strictly positive and finite.
    #[inline]
    pub fn new(m: &Mat5) -> Result<Self> {
        #[inline(always)]
        fn root(x: f64) -> Result<f64> {
            if x > 0.0 && x.is_finite() {
                Ok(x.sqrt())
            } else {
                Err(PrrrpError::NotPositiveDefinite {
                    what: "mass matrix M(q, λ)",
                })
            }
        }
        let p00 = root(m[(0, 0)])?;
        let p10 = m[(4, 0)] / p00;
        let p11 = root(m[(4, 4)] - p10 * p10)?;
        let r00 = root(m[(1, 1)])?;
        let r10 = m[(2, 1)] / r00;
        let r20 = m[(3, 1)] / r00;
        let r11 = root(m[(2, 2)] - r10 * r10)?;
        let r21 = (m[(3, 2)] - r20 * r10) / r11;
        let r22 = root(m[(3, 3)] - r20 * r20 - r21 * r21)?;
        Ok(Self {
            p: [p00, p10, p11],
            r: [r00, r10, r11, r20, r21, r22],
            inv: [1.0 / p00, 1.0 / p11, 1.0 / r00, 1.0 / r11, 1.0 / r22],
        })
    }

    /// Solves M·x = b.
    #[inline]
    pub fn solve(&self, b: &Vec5) -> Vec5 {
        let mut x = *b;
        self.solve_in_place(x.as_mut_slice());
        x
    }

    /// Solves M·X = B for C right-hand sides at once.
    ///
    /// Forms the two diagonal blocks of M⁻¹ = L⁻ᵀ·L⁻¹ from the factor (13 numbers) and
    /// multiplies: every entry of X is then a short independent sum, where substitution
    /// would run one chain of dependent operations per column. For one right-hand side
    /// [`Self::solve`] is the better choice.
    #[inline]
    pub fn solve_matrix<const C: usize>(&self, b: &SMatrix<f64, 5, C>) -> SMatrix<f64, 5, C> {
        let [_, p10, _] = self.p;
        let [ip00, ip11, ir00, ir11, ir22] = self.inv;
        // Prismatic block: L⁻¹ = [[a, 0], [c, d]].
        let (a, d) = (ip00, ip11);
        let c = -p10 * a * d;
        let (m00, m04, m44) = (a * a + c * c, c * d, d * d);
        // Planar block: L⁻¹ lower triangular with entries e.., then M⁻¹ = L⁻ᵀ·L⁻¹.
        let [_, r10, _, r20, r21, _] = self.r;
        let (e00, e11, e22) = (ir00, ir11, ir22);
        let e10 = -r10 * e00 * e11;
        let e21 = -r21 * e11 * e22;
        let e20 = -(r20 * e00 + r21 * e10) * e22;
        let n11 = e00 * e00 + e10 * e10 + e20 * e20;
        let n12 = e10 * e11 + e20 * e21;
        let n13 = e20 * e22;
        let n22 = e11 * e11 + e21 * e21;
        let n23 = e21 * e22;
        let n33 = e22 * e22;
        let mut x = SMatrix::<f64, 5, C>::zeros();
        for j in 0..C {
            let (b0, b1, b2, b3, b4) = (b[(0, j)], b[(1, j)], b[(2, j)], b[(3, j)], b[(4, j)]);
            x[(0, j)] = m00 * b0 + m04 * b4;
            x[(4, j)] = m04 * b0 + m44 * b4;
            x[(1, j)] = n11 * b1 + n12 * b2 + n13 * b3;
            x[(2, j)] = n12 * b1 + n22 * b2 + n23 * b3;
            x[(3, j)] = n13 * b1 + n23 * b2 + n33 * b3;
        }
        x
    }

    #[inline(always)]
    fn solve_in_place(&self, x: &mut [f64]) {
        let [_, p10, _] = self.p;
        let [ip00, ip11, ir00, ir11, ir22] = self.inv;
        let y0 = x[0] * ip00;
        let y1 = (x[4] - p10 * y0) * ip11;
        let z1 = y1 * ip11;
        x[0] = (y0 - p10 * z1) * ip00;
        x[4] = z1;

        let [_, r10, _, r20, r21, _] = self.r;
        let y0 = x[1] * ir00;
        let y1 = (x[2] - r10 * y0) * ir11;
        let y2 = (x[3] - r20 * y0 - r21 * y1) * ir22;
        let z2 = y2 * ir22;
        let z1 = (y1 - r21 * z2) * ir11;
        let z0 = (y0 - r10 * z1 - r20 * z2) * ir00;
        x[1] = z0;
        x[2] = z1;
        x[3] = z2;
    }
}

impl PrrrpModel {
    /// A model with the given gravity (m/s², along −z).
    pub fn new(gravity: f64) -> Self {
        Self { gravity }
    }

    /// Mass matrix M(q, λ) (kg for the prismatic entries, kg·m² for the revolute ones).
    #[inline]
    pub fn mass_matrix(&self, q: &Vec5, lambda: &Lambda) -> Mat5 {
        mass_matrix_trig(&Trig::new(q), lambda)
    }

    /// Coriolis and centrifugal vector C(q, q̇, λ)·q̇ (N, N·m).
    #[inline]
    pub fn coriolis(&self, q: &Vec5, qd: &Vec5, lambda: &Lambda) -> Vec5 {
        let t = Trig::new(q);
        let b = velocity_coeffs(qd);
        let mut h = Vec5::zeros();
        for (k, &(_, s)) in coupling_angles(&t).iter().enumerate() {
            let l = lambda[COUPLING_PARAM[k]] * s;
            for r in 0..3 {
                h[r + 1] += l * b[k][r];
            }
        }
        h
    }

    /// Gravity vector G(λ) (N, N·m); independent of q for this arm.
    #[inline]
    pub fn gravity_vector(&self, lambda: &Lambda) -> Vec5 {
        let g = self.gravity;
        Vec5::new((lambda[0] + lambda[7]) * g, 0.0, 0.0, 0.0, -lambda[7] * g)
    }

    /// Nonlinear effects C(q, q̇, λ)·q̇ + G(λ) (N, N·m): the torque at q̈ = 0.
    #[inline]
    pub fn nonlinear_effects(&self, q: &Vec5, qd: &Vec5, lambda: &Lambda) -> Vec5 {
        self.inverse_dynamics(q, qd, &Vec5::zeros(), lambda)
    }

    /// Inverse dynamics τ = M·q̈ + C·q̇ + G (N, N·m), without building Φ.
    #[inline]
    pub fn inverse_dynamics(&self, q: &Vec5, qd: &Vec5, qdd: &Vec5, lambda: &Lambda) -> Vec5 {
        self.inverse_dynamics_trig(&Trig::new(q), qd, qdd, lambda)
    }

    /// [`Self::inverse_dynamics`] with the trigonometry of q already evaluated, so that
    /// forward dynamics and its derivatives compute the sines and cosines once.
    #[inline(always)]
    pub(crate) fn inverse_dynamics_trig(
        &self,
        t: &Trig,
        qd: &Vec5,
        qdd: &Vec5,
        lambda: &Lambda,
    ) -> Vec5 {
        let g = self.gravity;
        let (a2, a3, a4) = (qdd[1], qdd[1] + qdd[2], qdd[1] + qdd[2] + qdd[3]);
        let e = qdd[0] - qdd[4] + g;
        let lin3 = lambda[2] * a3 + lambda[4] * a4;
        let mut tau = Vec5::new(
            lambda[0] * (qdd[0] + g) + lambda[7] * e,
            lambda[1] * a2 + lin3,
            lin3,
            lambda[4] * a4,
            -lambda[7] * e,
        );
        let a = accel_coeffs(qdd);
        let b = velocity_coeffs(qd);
        for (k, &(c, s)) in coupling_angles(t).iter().enumerate() {
            let l = lambda[COUPLING_PARAM[k]];
            for r in 0..3 {
                tau[r + 1] += l * (a[k][r] * c + b[k][r] * s);
            }
        }
        tau
    }

    /// Cholesky factor of M(q, λ).
    ///
    /// # Errors
    /// [`PrrrpError::NotPositiveDefinite`] for a non-physical λ.
    #[inline]
    pub fn mass_cholesky(&self, q: &Vec5, lambda: &Lambda) -> Result<MassCholesky> {
        MassCholesky::new(&self.mass_matrix(q, lambda))
    }

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G) (m/s², rad/s²) through a Cholesky
    /// factorisation of M.
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] naming the first NaN or infinite entry of q, q̇ or τ;
    /// [`PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite (a
    /// non-physical λ).
    #[inline]
    pub fn forward_dynamics(
        &self,
        q: &Vec5,
        qd: &Vec5,
        tau: &Vec5,
        lambda: &Lambda,
    ) -> Result<Vec5> {
        // A NaN q reached the Cholesky factorisation and was reported as a non-physical λ.
        check_finite_state(q, qd, tau)?;
        self.forward_dynamics_unchecked(q, qd, tau, lambda)
    }

    /// [`Self::forward_dynamics`] without the input check, for the estimators and
    /// integrators, which check their own states (a diverging one reports that).
    #[inline]
    pub(crate) fn forward_dynamics_unchecked(
        &self,
        q: &Vec5,
        qd: &Vec5,
        tau: &Vec5,
        lambda: &Lambda,
    ) -> Result<Vec5> {
        let t = Trig::new(q);
        let chol = MassCholesky::new(&mass_matrix_trig(&t, lambda))?;
        let h = self.inverse_dynamics_trig(&t, qd, &Vec5::zeros(), lambda);
        Ok(chol.solve(&(tau - h)))
    }

    /// Kinetic energy T = ½·q̇ᵀ·M(q, λ)·q̇ (J).
    #[inline]
    pub fn kinetic_energy(&self, q: &Vec5, qd: &Vec5, lambda: &Lambda) -> f64 {
        0.5 * qd.dot(&(self.mass_matrix(q, lambda) * qd))
    }

    /// Potential energy U = g·(λ1·d1 + λ8·(d1 − d5)) (J), zero at d1 = d5 = 0.
    #[inline]
    pub fn potential_energy(&self, q: &Vec5, lambda: &Lambda) -> f64 {
        self.gravity * (lambda[0] * q[0] + lambda[7] * (q[0] - q[4]))
    }
}

/// M(q, λ): the extended form's ([`super::extended::mass_matrix`]) with μ = 0, which
/// adds exact zeros.
#[inline(always)]
pub(crate) fn mass_matrix_trig(t: &Trig, l: &Lambda) -> Mat5 {
    let mut ext = [0.0; super::extended::NEXT];
    ext[..l.len()].copy_from_slice(l.as_slice());
    super::extended::mass_matrix(t, &ext)
}

/// The [`PrrrpError::NonFinite`] of the first NaN or infinite entry of q, q̇ or τ (named
/// e.g. `q[2]`), checked before anything is computed from them. Allocates only on the
/// error.
pub(crate) fn check_finite_state(q: &Vec5, qd: &Vec5, tau: &Vec5) -> Result<()> {
    for (what, v) in [("q", q), ("qd", qd), ("tau", tau)] {
        if let Some(j) = v.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("{what}[{j}]"),
                row: None,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Robot;

    /// M·X = B for both solvers, on states far from the origin and a λ scaled away from
    /// the paper's (a different conditioning of M).
    #[test]
    fn solvers_invert_the_mass_matrix() {
        let model = PrrrpModel::default();
        for (k, scale) in [(0, 1.0), (1, 0.7), (2, 3.0)] {
            let lambda = Robot::paper().base_parameters() * scale;
            let t = k as f64;
            let q = Vec5::new(0.3, 1.1 + t, -2.0 + t, 0.4 * t - 0.9, 0.1);
            let m = model.mass_matrix(&q, &lambda);
            let chol = model.mass_cholesky(&q, &lambda).unwrap();
            let b = SMatrix::<f64, 5, 7>::from_fn(|i, j| ((3 * i + 5 * j) as f64).sin() + 0.1);
            let x = chol.solve_matrix(&b);
            assert!(
                (m * x - b).amax() < 1e-12 * b.amax() * m.amax(),
                "{}",
                m * x - b
            );
            for j in 0..7 {
                let col: Vec5 = b.column(j).into_owned();
                let xs = chol.solve(&col);
                assert!((m * xs - col).amax() < 1e-12 * m.amax());
            }
        }
    }

    /// A NaN state is refused as such: it reached the Cholesky factorisation and read
    /// "mass matrix … not positive definite; check that the parameters are physical".
    #[test]
    fn non_finite_states_are_refused_before_the_mass_matrix() {
        let model = PrrrpModel::default();
        let lambda = Robot::paper().base_parameters();
        let ok = Vec5::repeat(0.1);
        let mut bad = ok;
        bad[2] = f64::NAN;
        for (q, qd, tau, what) in [
            (bad, ok, ok, "q[2]"),
            (ok, bad, ok, "qd[2]"),
            (ok, ok, bad, "tau[2]"),
        ] {
            for err in [
                model.forward_dynamics(&q, &qd, &tau, &lambda).unwrap_err(),
                crate::rk4_step(&model, &lambda, &q, &qd, &tau, 1e-3).unwrap_err(),
            ] {
                assert!(
                    matches!(&err, PrrrpError::NonFinite { what: w, .. } if w == what),
                    "{what}: {err}"
                );
            }
        }
        let step = crate::rk4_step(&model, &lambda, &ok, &ok, &ok, f64::NAN).unwrap_err();
        assert!(
            matches!(step, PrrrpError::InvalidParameter { .. }),
            "{step}"
        );
        assert!(model.forward_dynamics(&ok, &ok, &ok, &lambda).is_ok());
    }
}
