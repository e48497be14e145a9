//! Published robots as chains, for examples, tests and benchmarks.

use super::dh::DhConvention;
use super::inertia::inertial_parameters;
use super::serial_chain::SerialChain;
use crate::models::prrrp::robot::{DhRow, JointKind};

impl SerialChain<6> {
    /// The Unimation PUMA 560 (6R), standard DH, link masses, centres of mass and
    /// inertias as compiled by P. Corke and B. Armstrong-Hélouvry, "A search for consensus
    /// among model parameters reported for the PUMA 560 robot", Proc. IEEE ICRA 1994,
    /// pp. 1608–1613 — the values of Corke's Robotics Toolbox `mdl_puma560` (parameters of
    /// 8/95), SI units, gravity (0, 0, −9.81) m/s².
    ///
    /// Only the links are modelled: the toolbox's motor inertias, gear ratios and friction
    /// are left out. As in the source, link 1 has zero mass and the inertia Iyy = 0.35 kg·m²
    /// about its joint axis (y in frame 1).
    ///
    /// Two of the source's inertias are not a rigid body's (they break the triangle
    /// inequality Ixx + Izz ≥ Iyy), and forward dynamics and simulation refuse such links,
    /// so they are raised to the smallest values a body can have: link 1's Ixx = Izz = 0
    /// become Iyy/2 (they do not act on the dynamics — link 1 only turns about y₁, so ω₁
    /// and ω̇₁ have no x or z part), and link 3's Izz = 0.0125 becomes Iyy − Ixx =
    /// 0.020 kg·m² (this one changes M(q) by up to 0.0075 kg·m² on joints 3–6's block).
    pub fn puma560() -> Self {
        use std::f64::consts::FRAC_PI_2;
        let row = |d: f64, a: f64, alpha: f64| DhRow {
            kind: JointKind::Revolute,
            theta: 0.0,
            d,
            a,
            alpha,
        };
        // Corke lists the inertia about the centre of mass as [Ixx, Iyy, Izz, Ixy, Iyz, Ixz]
        // (all products zero here); ours is [Ixx, Ixy, Iyy, Ixz, Iyz, Izz].
        let link = |m: f64, r: [f64; 3], i: [f64; 3]| {
            inertial_parameters(m, r, [i[0], 0.0, i[1], 0.0, 0.0, i[2]])
        };
        SerialChain::from_parts_unchecked(
            [
                row(0.0, 0.0, FRAC_PI_2),
                row(0.0, 0.4318, 0.0),
                row(0.15005, 0.0203, -FRAC_PI_2),
                row(0.4318, 0.0, FRAC_PI_2),
                row(0.0, 0.0, -FRAC_PI_2),
                row(0.0, 0.0, 0.0),
            ],
            DhConvention::Standard,
            [
                link(0.0, [0.0, 0.0, 0.0], [0.175, 0.35, 0.175]),
                link(17.4, [-0.3638, 0.006, 0.2275], [0.13, 0.524, 0.539]),
                link(4.8, [-0.0203, -0.0141, 0.070], [0.066, 0.086, 0.020]),
                link(0.82, [0.0, 0.019, 0.0], [1.8e-3, 1.3e-3, 1.8e-3]),
                link(0.34, [0.0, 0.0, 0.0], [0.3e-3, 0.4e-3, 0.3e-3]),
                link(0.09, [0.0, 0.0, 0.032], [0.15e-3, 0.15e-3, 0.04e-3]),
            ],
            [0.0, 0.0, -crate::models::prrrp::robot::STANDARD_GRAVITY],
        )
    }
}
