//! Physical feasibility of a standard parameter vector: which links no rigid body can
//! have, by how much, and which joints have negative dissipative friction.
//!
//! A link's 10 parameters π = [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (about the
//! link origin, see [`super::inertial_parameters`]) belong to a rigid body exactly when its
//! pseudo-inertia J = [[½·tr(I)·1 − I, h], [hᵀ, m]] is positive semidefinite (Wensing, Kim
//! & Slotine, "Linear matrix inequalities for physically consistent inertial parameter
//! identification", IEEE RA-L 2017). For m > 0 that is the same as the inertia about the
//! centre of mass I_C having principal moments J₁ ≤ J₂ ≤ J₃ that satisfy the triangle
//! inequalities J_a + J_b ≥ J_c — the report gives both views: the smallest eigenvalue of
//! J, and the moments and margins. Joint (actuator) friction is dissipative when the
//! viscous and Coulomb coefficients are ≥ 0 (the offset fo has no sign), and a rotor
//! inertia (armature) is physical when Ia ≥ 0.

use nalgebra::Matrix3;

use super::actuators::ActuatorLayout;
use super::friction::FrictionModel;
use super::inertia::{com_and_inertia, pseudo_inertia, LINK_PARAMS};
use super::serial_chain::{DynChain, SerialChain, PHYSICAL_TOLERANCE};
use crate::error::{PrrrpError, Result};

/// Feasibility numbers of one link's inertial parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkFeasibility {
    /// Mass m (kg).
    pub mass: f64,
    /// Eigenvalues of the 4×4 pseudo-inertia J, ascending (mixed units: kg·m² for the
    /// second-moment part, kg for the mass; the smallest is the one that matters).
    pub pseudo_inertia_eigenvalues: [f64; 4],
    /// Centre of mass in the link frame (m); `None` if m ≤ 0.
    pub com: Option<[f64; 3]>,
    /// Principal moments J₁ ≤ J₂ ≤ J₃ of the inertia about the centre of mass (kg·m²);
    /// `None` if m ≤ 0.
    pub principal_moments: Option<[f64; 3]>,
    /// Triangle-inequality margins [J₂ + J₃ − J₁, J₁ + J₃ − J₂, J₁ + J₂ − J₃] (kg·m²),
    /// twice the eigenvalues of the second moment about the centre of mass; a rigid body
    /// has all three ≥ 0 (the last is the binding one). `None` if m ≤ 0.
    pub triangle_margins: Option<[f64; 3]>,
    /// Whether the link is physically consistent: smallest pseudo-inertia eigenvalue ≥
    /// −[`PHYSICAL_TOLERANCE`] × the link's largest parameter magnitude (the same test as
    /// [`DynChain::non_physical_links`]).
    pub consistent: bool,
}

impl LinkFeasibility {
    /// Smallest eigenvalue of the pseudo-inertia (negative: no rigid body has π).
    pub fn min_eigenvalue(&self) -> f64 {
        self.pseudo_inertia_eigenvalues[0]
    }

    /// Feasibility numbers of one link's inertial parameters (see the fields). Non-finite
    /// parameters give NaN numbers and `consistent = false`.
    pub fn of(params: &[f64; LINK_PARAMS]) -> Self {
        if !params.iter().all(|x| x.is_finite()) {
            return Self {
                mass: params[0],
                pseudo_inertia_eigenvalues: [f64::NAN; 4],
                com: None,
                principal_moments: None,
                triangle_margins: None,
                consistent: false,
            };
        }
        let mut eig: Vec<f64> = pseudo_inertia(params)
            .symmetric_eigenvalues()
            .iter()
            .copied()
            .collect();
        eig.sort_by(f64::total_cmp);
        let scale = params.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let (com, principal_moments, triangle_margins) = match com_and_inertia(params) {
            Some((_, c, i)) => {
                let ic = Matrix3::new(i[0], i[1], i[3], i[1], i[2], i[4], i[3], i[4], i[5]);
                let mut m: Vec<f64> = ic.symmetric_eigenvalues().iter().copied().collect();
                m.sort_by(f64::total_cmp);
                let margins = [m[1] + m[2] - m[0], m[0] + m[2] - m[1], m[0] + m[1] - m[2]];
                (Some(c), Some([m[0], m[1], m[2]]), Some(margins))
            }
            None => (None, None, None),
        };
        Self {
            mass: params[0],
            pseudo_inertia_eigenvalues: [eig[0], eig[1], eig[2], eig[3]],
            com,
            principal_moments,
            triangle_margins,
            consistent: eig[0] >= -PHYSICAL_TOLERANCE * scale,
        }
    }
}

/// Friction signs and armature of one joint's actuator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointFrictionFeasibility {
    /// Viscous coefficient fv (N·m·s/rad or N·s/m), `None` if the model has no viscous term.
    pub viscous: Option<f64>,
    /// Coulomb coefficient fc (N·m or N), `None` if the model has no Coulomb term.
    pub coulomb: Option<f64>,
    /// Reflected rotor inertia Ia (kg·m² or kg), `None` without an armature term.
    pub armature: Option<f64>,
    /// Whether the enabled terms are physical: fv ≥ 0, fc ≥ 0 and Ia ≥ 0.
    pub consistent: bool,
}

/// Physical feasibility of a whole standard parameter vector (inertial parameters of every
/// link, then the enabled friction terms, the layout of [`DynChain::parameters`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FeasibilityReport {
    /// One entry per link, from the base outwards.
    pub links: Vec<LinkFeasibility>,
    /// One entry per joint (per actuator: friction acts on the actuator velocities).
    pub friction: Vec<JointFrictionFeasibility>,
}

impl FeasibilityReport {
    /// Feasibility of the standard parameter vector π of an n-joint chain with friction
    /// model `friction` (length n·(10 + terms per joint)).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if π has the wrong length, [`PrrrpError::NonFinite`]
    /// if an entry is NaN or infinite.
    pub fn new(pi: &[f64], dof: usize, friction: &FrictionModel) -> Result<Self> {
        Self::with_armature(pi, dof, friction, false)
    }

    /// Feasibility of the standard parameter vector π of an n-joint chain with friction
    /// model `friction` and, if `armature`, one rotor inertia per actuator (length
    /// n·(10 + terms per actuator), the layout of [`DynChain::parameters`]).
    ///
    /// # Errors
    /// As [`FeasibilityReport::new`].
    pub fn with_armature(
        pi: &[f64],
        dof: usize,
        friction: &FrictionModel,
        armature: bool,
    ) -> Result<Self> {
        let layout = ActuatorLayout::new(friction, armature);
        let per = layout.per;
        let p = dof * (LINK_PARAMS + per);
        if pi.len() != p {
            return Err(PrrrpError::ShapeMismatch {
                what: "standard parameters π".into(),
                expected: format!("{p} entries ({dof} joints × (10 + {per} actuator terms))"),
                got: format!("{} entries", pi.len()),
            });
        }
        if let Some(k) = pi.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("standard parameters π[{k}]"),
                row: None,
            });
        }
        let links = (0..dof)
            .map(|i| {
                let mut l = [0.0; LINK_PARAMS];
                l.copy_from_slice(&pi[LINK_PARAMS * i..LINK_PARAMS * (i + 1)]);
                LinkFeasibility::of(&l)
            })
            .collect();
        let slots = layout.slots;
        let friction = (0..dof)
            .map(|j| {
                let base = LINK_PARAMS * dof + per * j;
                let viscous = friction.viscous.then(|| pi[base + slots[0]]);
                let coulomb = friction.coulomb.then(|| pi[base + slots[1]]);
                let armature = armature.then(|| pi[base + slots[3]]);
                JointFrictionFeasibility {
                    viscous,
                    coulomb,
                    armature,
                    consistent: viscous.unwrap_or(0.0) >= 0.0
                        && coulomb.unwrap_or(0.0) >= 0.0
                        && armature.unwrap_or(0.0) >= 0.0,
                }
            })
            .collect();
        Ok(Self { links, friction })
    }

    /// True when every link is a rigid body and every joint's friction is dissipative.
    pub fn is_feasible(&self) -> bool {
        self.links.iter().all(|l| l.consistent) && self.friction.iter().all(|f| f.consistent)
    }

    /// Indices (0-based) of the links no rigid body has.
    pub fn infeasible_links(&self) -> Vec<usize> {
        (0..self.links.len())
            .filter(|&i| !self.links[i].consistent)
            .collect()
    }

    /// Indices (0-based) of the joints (actuators) with negative viscous or Coulomb friction
    /// or a negative armature.
    pub fn infeasible_joints(&self) -> Vec<usize> {
        (0..self.friction.len())
            .filter(|&j| !self.friction[j].consistent)
            .collect()
    }

    /// Smallest pseudo-inertia eigenvalue over all links (kg·m² or kg).
    pub fn min_eigenvalue(&self) -> f64 {
        self.links
            .iter()
            .map(LinkFeasibility::min_eigenvalue)
            .fold(f64::INFINITY, f64::min)
    }
}

/// The standard vector closest to an anchor π₀ (Euclidean, SI) among those with base
/// values β: π = π₀ + Kᵀ·(K·Kᵀ)⁻¹·(β − K·π₀). With π₀ = 0 it is the minimum-norm standard
/// vector of β. Used to inspect least-squares base estimates link by link (the
/// unidentifiable combinations come from π₀).
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] for wrong lengths, [`PrrrpError::NonFinite`] for a NaN or
/// infinite entry of β or π₀.
pub fn standard_from_base(
    base: &super::BaseParameters,
    beta: &[f64],
    anchor: &[f64],
) -> Result<Vec<f64>> {
    let (b, p) = (base.count(), base.num_standard());
    if beta.len() != b {
        return Err(PrrrpError::ShapeMismatch {
            what: "base parameters β".into(),
            expected: format!("{b} entries"),
            got: format!("{} entries", beta.len()),
        });
    }
    let k0 = base.base_values(anchor)?;
    // A NaN in either spreads through the solve into every returned standard value.
    for (what, v) in [("base parameters β", beta), ("anchor π₀", anchor)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("{what}[{i}]"),
                row: None,
            });
        }
    }
    let k = nalgebra::DMatrix::from_fn(b, p, |r, j| base.map[(r, j)]);
    let kkt = &k * k.transpose();
    let rhs = nalgebra::DVector::from_iterator(b, beta.iter().zip(&k0).map(|(x, y)| x - y));
    // K = [1 K_d] up to a permutation, so K·Kᵀ = 1 + K_d·K_dᵀ is positive definite.
    let y = kkt
        .cholesky()
        .ok_or(PrrrpError::NotPositiveDefinite { what: "K·Kᵀ" })?
        .solve(&rhs);
    let dpi = k.transpose() * y;
    Ok(anchor.iter().zip(dpi.iter()).map(|(a, d)| a + d).collect())
}

impl DynChain {
    /// Feasibility of the chain's own parameters ([`DynChain::parameters`]).
    pub fn feasibility_report(&self) -> FeasibilityReport {
        FeasibilityReport::with_armature(
            &self.parameters(),
            self.dof(),
            &self.friction(),
            self.actuators().armature,
        )
        .unwrap_or_else(|_| unreachable_report(self.dof()))
    }
}

impl<const N: usize> SerialChain<N> {
    /// Feasibility of the chain's own parameters ([`SerialChain::parameters`]).
    pub fn feasibility_report(&self) -> FeasibilityReport {
        FeasibilityReport::with_armature(
            &self.parameters(),
            N,
            &self.friction(),
            self.actuators().armature,
        )
        .unwrap_or_else(|_| unreachable_report(N))
    }
}

/// A chain's parameters are validated finite and of the right length at construction, so
/// this never runs; it keeps the accessor infallible without a panic path.
fn unreachable_report(n: usize) -> FeasibilityReport {
    let nan = LinkFeasibility::of(&[f64::NAN; LINK_PARAMS]);
    FeasibilityReport {
        links: vec![nan; n],
        friction: vec![
            JointFrictionFeasibility {
                viscous: None,
                coulomb: None,
                armature: None,
                consistent: false,
            };
            n
        ],
    }
}
