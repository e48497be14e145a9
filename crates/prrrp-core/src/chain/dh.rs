//! Denavit–Hartenberg conventions and the per-joint geometry derived from a DH row.

use nalgebra::{Matrix3, Vector3};

use crate::robot::{DhRow, JointKind};

/// Which Denavit–Hartenberg convention a table follows.
///
/// Both conventions number links 1..n and attach frame i to link i; frame 0 is the fixed
/// base (world) frame. They differ in where frame i sits on link i and which row holds
/// which constant:
///
/// - [`DhConvention::Standard`] (Denavit–Hartenberg 1955, Paul 1981, the paper's Table 1,
///   Corke's `SerialLink` default): ⁱ⁻¹Tᵢ = Rz(θᵢ)·Tz(dᵢ)·Tx(aᵢ)·Rx(αᵢ). Joint i moves
///   about/along z_{i−1}; frame i sits at the **distal** end of link i (on the axis of
///   joint i+1). Row i holds (θᵢ, dᵢ, aᵢ, αᵢ).
/// - [`DhConvention::Modified`] (Craig 1986, Khalil–Kleinfinger): ⁱ⁻¹Tᵢ =
///   Rx(αᵢ₋₁)·Tx(aᵢ₋₁)·Rz(θᵢ)·Tz(dᵢ). Joint i moves about/along zᵢ; frame i sits at the
///   **proximal** end of link i (on the axis of joint i). Row i holds (αᵢ₋₁, aᵢ₋₁, θᵢ, dᵢ)
///   as Craig's tables list them: the `alpha` and `a` fields of row i are the twist and
///   length of the *previous* link.
///
/// In both, the joint coordinate qᵢ adds to θᵢ (revolute) or to dᵢ (prismatic).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DhConvention {
    /// Standard (distal) DH — the default, as in the paper's Table 1.
    #[default]
    Standard,
    /// Modified (proximal, Craig) DH.
    Modified,
}

/// Constant geometry of one joint, precomputed from its DH row.
///
/// The joint axis and the motion it produces are constant when expressed in the frame of
/// the link the joint moves (frame i): this is what makes both conventions share one
/// recursion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct JointGeom {
    pub(crate) revolute: bool,
    modified: bool,
    theta0: f64,
    d0: f64,
    a: f64,
    ca: f64,
    sa: f64,
    /// Joint axis u in frame i (unit).
    pub(crate) axis: Vector3<f64>,
    /// Position of the origin of frame i relative to a point of the joint axis, in frame i
    /// (zero for modified DH, (aᵢ, 0, 0) for standard DH).
    pub(crate) rho: Vector3<f64>,
    /// Angular part of the motion subspace S in frame i: u (revolute) or 0 (prismatic).
    pub(crate) s_ang: Vector3<f64>,
    /// Linear part of S: velocity of the origin of frame i per unit joint rate,
    /// u × ρ (revolute) or u (prismatic).
    pub(crate) s_lin: Vector3<f64>,
}

impl JointGeom {
    pub(crate) fn new(row: &DhRow, convention: DhConvention) -> Self {
        let (sa, ca) = row.alpha.sin_cos();
        let modified = convention == DhConvention::Modified;
        let (axis, rho) = if modified {
            (Vector3::z(), Vector3::zeros())
        } else {
            (Vector3::new(0.0, sa, ca), Vector3::new(row.a, 0.0, 0.0))
        };
        let revolute = row.kind == JointKind::Revolute;
        let (s_ang, s_lin) = if revolute {
            (axis, axis.cross(&rho))
        } else {
            (Vector3::zeros(), axis)
        };
        Self {
            revolute,
            modified,
            theta0: row.theta,
            d0: row.d,
            a: row.a,
            ca,
            sa,
            axis,
            rho,
            s_ang,
            s_lin,
        }
    }

    /// ⁱ⁻¹Tᵢ(q) as (rotation ⁱ⁻¹Rᵢ, origin of frame i in frame i−1).
    #[inline(always)]
    pub(crate) fn transform(&self, q: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let (theta, d) = if self.revolute {
            (self.theta0 + q, self.d0)
        } else {
            (self.theta0, self.d0 + q)
        };
        // One shared argument reduction (see `terms::Trig`).
        let (st, ct) = libm::sincos(theta);
        let (ca, sa, a) = (self.ca, self.sa, self.a);
        if self.modified {
            // Rx(α)·Rz(θ), origin Rx(α)·(a, 0, d)… with Tx before Rz: (a, −sα·d, cα·d).
            let r = Matrix3::new(ct, -st, 0.0, ca * st, ca * ct, -sa, sa * st, sa * ct, ca);
            (r, Vector3::new(a, -sa * d, ca * d))
        } else {
            // Rz(θ)·Rx(α), origin (a·cθ, a·sθ, d).
            let r = Matrix3::new(ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca);
            (r, Vector3::new(a * ct, a * st, d))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3};

    fn row(kind: JointKind) -> DhRow {
        DhRow {
            kind,
            theta: 0.3,
            d: 0.2,
            a: 0.5,
            alpha: -0.7,
        }
    }

    /// Compares the closed-form transform with the product of elementary transforms.
    #[test]
    fn transform_matches_elementary_products() {
        for kind in [JointKind::Revolute, JointKind::Prismatic] {
            let r = row(kind);
            let q = 0.4;
            let (theta, d) = match kind {
                JointKind::Revolute => (r.theta + q, r.d),
                JointKind::Prismatic => (r.theta, r.d + q),
            };
            let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), theta);
            let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), r.alpha);
            let tz = Translation3::new(0.0, 0.0, d);
            let tx = Translation3::new(r.a, 0.0, 0.0);
            let std =
                nalgebra::Isometry3::from_parts(nalgebra::Translation3::identity(), rz.into())
                    * nalgebra::Isometry3::from_parts(tz, nalgebra::UnitQuaternion::identity())
                    * nalgebra::Isometry3::from_parts(tx, nalgebra::UnitQuaternion::identity())
                    * nalgebra::Isometry3::from_parts(
                        nalgebra::Translation3::identity(),
                        rx.into(),
                    );
            let modi =
                nalgebra::Isometry3::from_parts(nalgebra::Translation3::identity(), rx.into())
                    * nalgebra::Isometry3::from_parts(tx, nalgebra::UnitQuaternion::identity())
                    * nalgebra::Isometry3::from_parts(
                        nalgebra::Translation3::identity(),
                        rz.into(),
                    )
                    * nalgebra::Isometry3::from_parts(tz, nalgebra::UnitQuaternion::identity());
            for (conv, want) in [
                (DhConvention::Standard, std),
                (DhConvention::Modified, modi),
            ] {
                let (rot, p) = JointGeom::new(&r, conv).transform(q);
                let want_r = want.rotation.to_rotation_matrix().into_inner();
                assert!((rot - want_r).norm() < 1e-14, "{conv:?} {kind:?}");
                assert!(
                    (p - want.translation.vector).norm() < 1e-14,
                    "{conv:?} {kind:?}"
                );
            }
        }
    }
}
