//! The closed form with the first moments across the links: the model the arm's chain
//! evaluates through (see `models/chain/paper.rs`).
//!
//! The paper's λ puts every centre of mass on its link's x axis. A chain of the same
//! geometry with any inertial parameters also has the first moments across links 3 and 4
//! (its base parameters `my3`, `my4`): each coupling λk·cos φk of the Lagrangian (see
//! [`super::terms`]) gains a partner μk·sin φk. The Lagrangian depends on φk only through
//! that cosine, so the μk term of τ is the λk term at φk − π/2: A·sin φ − B·cos φ where
//! the λk term is A·cos φ + B·sin φ. The extended parameters are λ1..λ8 then μ4, μ6, μ7.

use nalgebra::SMatrix;

use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::terms::{
    accel_coeffs, coupling_angles, velocity_coeffs, Trig, COUPLING_PARAM,
};
use crate::models::prrrp::types::{Lambda, Mat5, Vec5, NPARAM};

/// Number of extended parameters: the paper's 8 and the three μk.
pub(crate) const NEXT: usize = NPARAM + 3;

/// The extended parameters [λ1..λ8, μ4, μ6, μ7] (units of λ4, λ6, λ7 for μ: kg·m²).
pub(crate) type ExtLambda = [f64; NEXT];

/// The extended regressor, 5 × 11: τ = Y·[λ, μ].
pub(crate) type ExtRegressor = SMatrix<f64, 5, NEXT>;

/// (λk·cos φk + μk·sin φk, λk·sin φk − μk·cos φk) of the three couplings: what multiplies
/// A and B in τ, and (the first) what replaces λk·cos φk in M.
#[inline(always)]
fn couplings(t: &Trig, l: &ExtLambda) -> [(f64, f64); 3] {
    let ang = coupling_angles(t);
    std::array::from_fn(|k| {
        let (c, s) = ang[k];
        let (lam, mu) = (l[COUPLING_PARAM[k]], l[NPARAM + k]);
        (lam * c + mu * s, lam * s - mu * c)
    })
}

/// The paper's λ part of the extended parameters.
#[inline(always)]
fn paper_part(l: &ExtLambda) -> Lambda {
    Lambda::from_fn(|i, _| l[i])
}

/// Y(q, q̇, q̈) with gravity `g` (m/s² along −z), q given by its trigonometry.
#[inline(always)]
pub(crate) fn regressor(g: f64, t: &Trig, qd: &Vec5, qdd: &Vec5) -> ExtRegressor {
    let mut y = ExtRegressor::zeros();
    y.fixed_columns_mut::<NPARAM>(0)
        .copy_from(&PrrrpModel::new(g).regressor_trig(t, qd, qdd));
    let a = accel_coeffs(qdd);
    let b = velocity_coeffs(qd);
    for (k, &(c, s)) in coupling_angles(t).iter().enumerate() {
        for r in 0..3 {
            y[(r + 1, NPARAM + k)] = a[k][r] * s - b[k][r] * c;
        }
    }
    y
}

/// τ = M·q̈ + C·q̇ + G at the extended parameters (N, N·m), without building Y.
#[inline(always)]
pub(crate) fn inverse_dynamics(g: f64, t: &Trig, qd: &Vec5, qdd: &Vec5, l: &ExtLambda) -> Vec5 {
    // The paper's form with the couplings zeroed, then the couplings with their partners.
    let mut lam = paper_part(l);
    for k in COUPLING_PARAM {
        lam[k] = 0.0;
    }
    let mut tau = PrrrpModel::new(g).inverse_dynamics_trig(t, qd, qdd, &lam);
    let a = accel_coeffs(qdd);
    let b = velocity_coeffs(qd);
    for (k, &(ec, es)) in couplings(t, l).iter().enumerate() {
        for r in 0..3 {
            tau[r + 1] += a[k][r] * ec + b[k][r] * es;
        }
    }
    tau
}

/// M(q) at the extended parameters (kg, kg·m²): the paper's M with λk·cos φk replaced by
/// λk·cos φk + μk·sin φk.
#[inline(always)]
pub(crate) fn mass_matrix(t: &Trig, l: &ExtLambda) -> Mat5 {
    let [(e4, _), (e6, _), (e7, _)] = couplings(t, l);
    let (l2, l3, l5) = (l[1], l[2], l[4]);
    let m22 = l2 + l3 + l5 + 2.0 * (e4 + e6 + e7);
    let m23 = l3 + l5 + e4 + e6 + 2.0 * e7;
    let m24 = l5 + e6 + e7;
    let m33 = l3 + l5 + 2.0 * e7;
    let m34 = l5 + e7;
    let (m11, m15) = (l[0] + l[7], -l[7]);
    Mat5::new(
        m11, 0.0, 0.0, 0.0, m15, //
        0.0, m22, m23, m24, 0.0, //
        0.0, m23, m33, m34, 0.0, //
        0.0, m24, m34, l5, 0.0, //
        m15, 0.0, 0.0, 0.0, l[7],
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::prrrp::dynamics::mass_matrix_trig;
    use crate::Robot;

    fn state(k: usize) -> (Vec5, Vec5, Vec5) {
        let f = |a: usize| Vec5::from_fn(|i, _| ((7 * a + 3 * i + k) as f64 * 0.77).sin());
        (f(1) * 2.0, f(2), f(3) * 3.0)
    }

    /// With μ = 0 the extension is the paper's model (its regressor, τ and M).
    #[test]
    fn reduces_to_the_paper_at_zero_mu() {
        let lam = Robot::paper().base_parameters();
        let mut l = [0.0; NEXT];
        l[..NPARAM].copy_from_slice(lam.as_slice());
        let model = PrrrpModel::default();
        for k in 0..5 {
            let (q, qd, qdd) = state(k);
            let t = Trig::new(&q);
            let y = regressor(model.gravity, &t, &qd, &qdd);
            assert_eq!(y.fixed_columns::<NPARAM>(0), model.regressor(&q, &qd, &qdd));
            let tau = model.inverse_dynamics(&q, &qd, &qdd, &lam);
            let ext = inverse_dynamics(model.gravity, &t, &qd, &qdd, &l);
            assert!((ext - tau).amax() < 1e-12 * tau.amax());
            assert!((mass_matrix(&t, &l) - mass_matrix_trig(&t, &lam)).amax() < 1e-14);
        }
    }

    /// τ = Y·l and M·q̈ = τ(q̈) − τ(0) at a λ with every μk nonzero, and the μk terms are
    /// the λk terms with φk shifted by −π/2 (θ3 and θ4 shifted, λ6's angle by −π).
    #[test]
    fn mu_terms_are_phase_shifted_couplings() {
        let l: ExtLambda = std::array::from_fn(|i| 0.3 + 0.1 * i as f64);
        for k in 0..5 {
            let (q, qd, qdd) = state(k);
            let t = Trig::new(&q);
            let y = regressor(9.81, &t, &qd, &qdd);
            let tau = inverse_dynamics(9.81, &t, &qd, &qdd, &l);
            let yl = y * nalgebra::SVector::<f64, NEXT>::from(l);
            assert!((yl - tau).amax() < 1e-12 * tau.amax(), "{yl} {tau}");
            let h = inverse_dynamics(9.81, &t, &qd, &Vec5::zeros(), &l);
            let mq = mass_matrix(&t, &l) * qdd;
            assert!((mq - (tau - h)).amax() < 1e-12 * tau.amax());
            // μ4 alone: the λ4 column at θ3 − π/2 (λ6's angle θ3+θ4 moves too, but its
            // column is not read).
            let mut qs = q;
            qs[2] -= std::f64::consts::FRAC_PI_2;
            let shifted = PrrrpModel::new(9.81).regressor(&qs, &qd, &qdd);
            let d = y.column(NPARAM) - shifted.column(COUPLING_PARAM[0]);
            assert!(d.amax() < 1e-12, "{d}");
        }
    }
}
