//! The closed-form building blocks shared by the dynamics, the regressor and the
//! derivatives of the PRRRP arm.
//!
//! Written in λ, the Lagrangian of the arm is (ω2 = θ̇2, ω3 = ω2 + θ̇3, ω4 = ω3 + θ̇4)
//! ```text
//! T = ½λ1·ḋ1² + ½λ8·(ḋ1 − ḋ5)² + ½λ2·ω2² + ½λ3·ω3² + ½λ5·ω4²
//!     + λ4·ω2·ω3·cosθ3 + λ6·ω2·ω4·cos(θ3+θ4) + λ7·ω3·ω4·cosθ4
//! U = g·(λ1·d1 + λ8·(d1 − d5))
//! ```
//! (`derivation/regressor.py` derives Φ from this symbolically). The three couplings λ4,
//! λ6, λ7 each contribute to τ2..τ4 a term λk·(A·cos φk + B·sin φk) with φ = θ3, θ3+θ4,
//! θ4; A depends only on q̈ and B only on q̇. Keeping A and B explicit gives the regressor,
//! inverse dynamics and both derivatives from one set of formulas.

use crate::models::prrrp::types::Vec5;

/// Sines and cosines of the three coupling angles θ3, θ3+θ4, θ4.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Trig {
    pub c3: f64,
    pub s3: f64,
    pub c34: f64,
    pub s34: f64,
    pub c4: f64,
    pub s4: f64,
}

impl Trig {
    #[inline(always)]
    pub fn new(q: &Vec5) -> Self {
        // std's sin_cos is two separate libm calls; libm::sincos shares one argument
        // reduction (fdlibm, < 1 ulp) and takes a third off the regressor's time.
        let (s3, c3) = libm::sincos(q[2]);
        let (s4, c4) = libm::sincos(q[3]);
        // sin/cos of θ3+θ4 from the addition formulas: saves two transcendental calls.
        Self {
            c3,
            s3,
            c4,
            s4,
            c34: c3 * c4 - s3 * s4,
            s34: s3 * c4 + c3 * s4,
        }
    }
}

/// The acceleration-only coefficients A of the three couplings (λ4, λ6, λ7).
#[inline(always)]
pub(crate) fn accel_coeffs(qdd: &Vec5) -> [[f64; 3]; 3] {
    let (a2, a3, a4) = (qdd[1], qdd[1] + qdd[2], qdd[1] + qdd[2] + qdd[3]);
    [
        [a2 + a3, a2, 0.0],
        [a2 + a4, a2, a2],
        [a3 + a4, a3 + a4, a3],
    ]
}

/// The velocity-only coefficients B of the three couplings (λ4, λ6, λ7).
#[inline(always)]
pub(crate) fn velocity_coeffs(qd: &Vec5) -> [[f64; 3]; 3] {
    let (w2, t3, t4) = (qd[1], qd[2], qd[3]);
    let w3 = w2 + t3;
    let u = t3 + t4;
    let w2sq = w2 * w2;
    [
        [-(2.0 * w2 + t3) * t3, w2sq, 0.0],
        [-(2.0 * w2 + u) * u, w2sq, w2sq],
        [-(2.0 * w3 + t4) * t4, -(2.0 * w3 + t4) * t4, w3 * w3],
    ]
}

/// ∂B/∂q̇ for the three couplings: `[coupling][row τ2..τ4][θ̇2..θ̇4]`.
#[inline(always)]
pub(crate) fn velocity_coeffs_jacobian(qd: &Vec5) -> [[[f64; 3]; 3]; 3] {
    let (w2, t3, t4) = (qd[1], qd[2], qd[3]);
    let w3 = w2 + t3;
    let u = t3 + t4;
    let g4_row = [-2.0 * t4, -2.0 * t4, -2.0 * (w3 + t4)];
    [
        [
            [-2.0 * t3, -2.0 * (w2 + t3), 0.0],
            [2.0 * w2, 0.0, 0.0],
            [0.0; 3],
        ],
        [
            [-2.0 * u, -2.0 * (w2 + u), -2.0 * (w2 + u)],
            [2.0 * w2, 0.0, 0.0],
            [2.0 * w2, 0.0, 0.0],
        ],
        [g4_row, g4_row, [2.0 * w3, 2.0 * w3, 0.0]],
    ]
}

/// (cos φk, sin φk) of the three couplings, in the order λ4, λ6, λ7.
#[inline(always)]
pub(crate) fn coupling_angles(t: &Trig) -> [(f64, f64); 3] {
    [(t.c3, t.s3), (t.c34, t.s34), (t.c4, t.s4)]
}

/// Index in λ (0-based) of the three couplings.
pub(crate) const COUPLING_PARAM: [usize; 3] = [3, 5, 6];
