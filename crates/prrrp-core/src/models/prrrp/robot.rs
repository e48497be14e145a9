//! The physical description of the PRRRP arm: DH table (paper Table 1), link parameters
//! (Table 2) and the map to the 8 grouped base parameters λ (Table 3, corrected).

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::types::Lambda;

/// Standard gravity used by the paper's robot, m/s² (the paper writes g_z without a value).
pub const STANDARD_GRAVITY: f64 = 9.81;

/// Kind of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Translation along the joint's z axis; its coordinate is a length in m.
    Prismatic,
    /// Rotation about the joint's z axis; its coordinate is an angle in rad.
    Revolute,
}

/// One row of a standard Denavit–Hartenberg table, at zero joint coordinate.
///
/// The joint coordinate adds to `theta` (revolute) or to `d` (prismatic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// Joint kind.
    pub kind: JointKind,
    /// Constant rotation about z_{i-1}, rad.
    pub theta: f64,
    /// Constant offset along z_{i-1}, m.
    pub d: f64,
    /// Link length along x_i, m.
    pub a: f64,
    /// Link twist about x_i, rad.
    pub alpha: f64,
}

/// Physical parameters of the PRRRP arm in SI units (paper Table 2).
///
/// Conventions (see the crate docs): q = [d1, θ2, θ3, θ4, d5]; joint 1 lifts the whole arm
/// along world +z; joints 2–4 form a planar 3R arm in the horizontal plane; joint 5 moves
/// the tool along world −z. The centre of mass of links 2–4 lies on the link's x axis at
/// `com[i]` from its joint, and `inertia_zz[i]` is the moment of inertia about the vertical
/// axis **through the centre of mass** (paper Annex A says "about the joint", but its
/// formulas add m·lc² explicitly). Link 5 is a point mass at the end of link 4.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Robot {
    /// Link masses m1..m5, kg.
    pub mass: [f64; 5],
    /// Link lengths l1..l5, m (l2, l3, l4 are the planar link lengths; l1, l5 only enter
    /// the DH table as constant offsets).
    pub length: [f64; 5],
    /// Distances lc2, lc3, lc4 from joints 2–4 to the centres of mass of links 2–4, m.
    pub com: [f64; 3],
    /// Moments of inertia I2zz, I3zz, I4zz about the centre of mass, kg·m².
    pub inertia_zz: [f64; 3],
    /// Gravitational acceleration, m/s², acting along world −z.
    pub gravity: f64,
}

impl Default for Robot {
    fn default() -> Self {
        Self::paper()
    }
}

impl Robot {
    /// The robot of Urrea & Pascal 2017, Table 2, with g = 9.81 m/s².
    pub const fn paper() -> Self {
        Self {
            mass: [1.228, 1.023, 1.023, 1.023, 0.5114],
            length: [0.524, 0.2, 0.2, 0.2, 0.14],
            com: [0.0229; 3],
            inertia_zz: [0.0058; 3],
            gravity: STANDARD_GRAVITY,
        }
    }

    /// A robot with user-supplied parameters (SI units, see the field docs), validated.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the first non-physical field: a mass or
    /// length that is not strictly positive, a negative centre-of-mass distance or
    /// inertia, a negative gravity, or any NaN/infinite value.
    pub fn new(
        mass: [f64; 5],
        length: [f64; 5],
        com: [f64; 3],
        inertia_zz: [f64; 3],
        gravity: f64,
    ) -> Result<Self> {
        let r = Self {
            mass,
            length,
            com,
            inertia_zz,
            gravity,
        };
        r.validate()?;
        Ok(r)
    }

    /// Checks every field; see [`Robot::new`].
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the first non-physical field.
    pub fn validate(&self) -> Result<()> {
        fn bad(field: String, value: f64, reason: &'static str) -> PrrrpError {
            PrrrpError::InvalidParameter {
                field,
                value,
                reason,
            }
        }
        for (i, &m) in self.mass.iter().enumerate() {
            if !(m.is_finite() && m > 0.0) {
                return Err(bad(
                    format!("mass[{i}] (m{})", i + 1),
                    m,
                    "must be finite and > 0 kg",
                ));
            }
        }
        for (i, &l) in self.length.iter().enumerate() {
            if !(l.is_finite() && l > 0.0) {
                return Err(bad(
                    format!("length[{i}] (l{})", i + 1),
                    l,
                    "must be finite and > 0 m",
                ));
            }
        }
        for (i, &c) in self.com.iter().enumerate() {
            if !(c.is_finite() && c >= 0.0) {
                return Err(bad(
                    format!("com[{i}] (lc{})", i + 2),
                    c,
                    "must be finite and >= 0 m",
                ));
            }
        }
        for (i, &inertia) in self.inertia_zz.iter().enumerate() {
            if !(inertia.is_finite() && inertia >= 0.0) {
                return Err(bad(
                    format!("inertia_zz[{i}] (I{}zz)", i + 2),
                    inertia,
                    "must be finite and >= 0 kg·m²",
                ));
            }
        }
        if !(self.gravity.is_finite() && self.gravity >= 0.0) {
            return Err(bad(
                "gravity".into(),
                self.gravity,
                "must be finite and >= 0 m/s²",
            ));
        }
        Ok(())
    }

    /// The standard DH table of the arm at q = 0 (paper Table 1): lengths from `self`.
    ///
    /// α4 = 180° turns the tool axis downwards, which is why d5 moves the tool along −z.
    pub fn dh_table(&self) -> [DhRow; 5] {
        let l = self.length;
        let pi = std::f64::consts::PI;
        [
            DhRow {
                kind: JointKind::Prismatic,
                theta: 0.0,
                d: l[0],
                a: 0.0,
                alpha: 0.0,
            },
            DhRow {
                kind: JointKind::Revolute,
                theta: 0.0,
                d: 0.0,
                a: l[1],
                alpha: 0.0,
            },
            DhRow {
                kind: JointKind::Revolute,
                theta: 0.0,
                d: 0.0,
                a: l[2],
                alpha: 0.0,
            },
            DhRow {
                kind: JointKind::Revolute,
                theta: 0.0,
                d: 0.0,
                a: l[3],
                alpha: pi,
            },
            DhRow {
                kind: JointKind::Prismatic,
                theta: 0.0,
                d: l[4],
                a: 0.0,
                alpha: 0.0,
            },
        ]
    }

    /// The 8 grouped base parameters λ (paper Table 3 with typo 4 corrected: I4zz in λ5).
    ///
    /// Units: λ1, λ8 in kg; λ2, λ3, λ5 in kg·m²; λ4, λ6, λ7 in kg·m².
    /// ```text
    /// λ1 = m1 + m2 + m3 + m4
    /// λ2 = m2·lc2² + (m3 + m4 + m5)·l2² + I2zz
    /// λ3 = m3·lc3² + (m4 + m5)·l3² + I3zz
    /// λ4 = l2·(m3·lc3 + (m4 + m5)·l3)
    /// λ5 = m4·lc4² + m5·l4² + I4zz
    /// λ6 = l2·(m4·lc4 + m5·l4)
    /// λ7 = l3·(m4·lc4 + m5·l4)
    /// λ8 = m5
    /// ```
    pub fn base_parameters(&self) -> Lambda {
        let [m1, m2, m3, m4, m5] = self.mass;
        let [_, l2, l3, l4, _] = self.length;
        let [lc2, lc3, lc4] = self.com;
        let [i2, i3, i4] = self.inertia_zz;
        let mx4 = m4 * lc4 + m5 * l4;
        Lambda::from([
            m1 + m2 + m3 + m4,
            m2 * lc2 * lc2 + (m3 + m4 + m5) * l2 * l2 + i2,
            m3 * lc3 * lc3 + (m4 + m5) * l3 * l3 + i3,
            l2 * (m3 * lc3 + (m4 + m5) * l3),
            m4 * lc4 * lc4 + m5 * l4 * l4 + i4,
            l2 * mx4,
            l3 * mx4,
            m5,
        ])
    }

    /// The dynamic model of this robot (its gravity), to be evaluated at any λ.
    pub fn model(&self) -> crate::models::prrrp::dynamics::PrrrpModel {
        crate::models::prrrp::dynamics::PrrrpModel {
            gravity: self.gravity,
        }
    }
}
