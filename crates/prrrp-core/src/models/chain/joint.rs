//! The general joint model of a serial chain: a constant placement in the parent link's
//! frame, a motion along or about a unit axis, and the frame of the moved link. URDF
//! joints, modified DH rows and standard DH rows are three ways to fill it in.

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};

use super::dh::DhConvention;
use crate::error::{PrrrpError, Result};
use crate::models::prrrp::robot::{DhRow, JointKind};

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointType {
    /// Rotation about the axis; its coordinate is an angle in rad, within position limits.
    Revolute,
    /// Rotation about the axis without position limits (URDF `continuous`), rad.
    Continuous,
    /// Translation along the axis; its coordinate is a length in m.
    Prismatic,
}

impl JointType {
    /// True for [`JointType::Revolute`] and [`JointType::Continuous`].
    pub fn is_rotational(self) -> bool {
        !matches!(self, JointType::Prismatic)
    }
    /// The URDF name of the type: `"revolute"`, `"continuous"` or `"prismatic"`.
    pub fn urdf_name(self) -> &'static str {
        match self {
            JointType::Revolute => "revolute",
            JointType::Continuous => "continuous",
            JointType::Prismatic => "prismatic",
        }
    }
}

impl From<JointKind> for JointType {
    fn from(k: JointKind) -> Self {
        match k {
            JointKind::Revolute => JointType::Revolute,
            JointKind::Prismatic => JointType::Prismatic,
        }
    }
}

/// One joint of a serial chain and the frame of the link it moves.
///
/// The pose of link i's frame in link i−1's frame is
///
/// ```text
/// ⁱ⁻¹Tᵢ(q) = placement · Motion(axis, q) · link_frame
/// ```
///
/// where `Motion` rotates by q (rad) about `axis` through the joint frame's origin, or
/// translates by q (m) along it. `axis` is a unit vector in the joint frame.
///
/// - **URDF**: `placement` is the joint's `<origin xyz rpy>`, `axis` its `<axis xyz>`,
///   `link_frame` the identity (the child link's frame is the joint frame).
/// - **Modified DH** (Craig): `placement` = Rx(αᵢ₋₁)·Tx(aᵢ₋₁)·Rz(θᵢ)·Tz(dᵢ), axis z,
///   `link_frame` the identity.
/// - **Standard DH**: `placement` the identity, axis z, `link_frame` =
///   Rz(θᵢ)·Tz(dᵢ)·Tx(aᵢ)·Rx(αᵢ): link i's frame sits at its distal end, off the joint axis.
///
/// Inertial parameters of link i are expressed in link i's frame (about its origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Joint {
    /// Revolute, continuous or prismatic.
    pub kind: JointType,
    /// Joint frame at q = 0 in the parent link's frame (translation in m).
    pub placement: Isometry3<f64>,
    /// Unit axis of the motion, in the joint frame.
    pub axis: Vector3<f64>,
    /// Link frame in the joint frame (constant; the identity for URDF and modified DH).
    pub link_frame: Isometry3<f64>,
}

/// Tolerance on |axis| − 1 for a joint axis to count as a unit vector.
pub const AXIS_UNIT_TOLERANCE: f64 = 1e-6;

impl Joint {
    /// A joint whose link frame is its joint frame (the URDF convention).
    pub fn new(kind: JointType, placement: Isometry3<f64>, axis: Vector3<f64>) -> Self {
        Self {
            kind,
            placement,
            axis,
            link_frame: Isometry3::identity(),
        }
    }

    /// The joint of one DH row in the given convention (see the type docs).
    pub fn from_dh(row: &DhRow, convention: DhConvention) -> Self {
        let rz = |t: f64| Isometry3::from_parts(Translation3::identity(), rot_z(t));
        let rx = |t: f64| {
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), t),
            )
        };
        let tz = |d: f64| Isometry3::translation(0.0, 0.0, d);
        let tx = |a: f64| Isometry3::translation(a, 0.0, 0.0);
        let kind = row.kind.into();
        match convention {
            DhConvention::Standard => Self {
                kind,
                placement: Isometry3::identity(),
                axis: Vector3::z(),
                link_frame: rz(row.theta) * tz(row.d) * tx(row.a) * rx(row.alpha),
            },
            DhConvention::Modified => Self::new(
                kind,
                rx(row.alpha) * tx(row.a) * rz(row.theta) * tz(row.d),
                Vector3::z(),
            ),
        }
    }

    /// ⁱ⁻¹Tᵢ(q): link i's frame in link i−1's frame, composed from the definition (a
    /// reference; the algorithms use a precomputed form of it).
    pub fn transform(&self, q: f64) -> Isometry3<f64> {
        let u = Unit::new_normalize(self.axis);
        let motion = if self.kind.is_rotational() {
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&u, q),
            )
        } else {
            Isometry3::from_parts(
                Translation3::from(u.into_inner() * q),
                UnitQuaternion::identity(),
            )
        };
        self.placement * motion * self.link_frame
    }

    /// Checks that the placement and link frame are finite and the axis is a unit vector.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming `what` (e.g. `"joint 3 (panda_joint3)"`).
    pub fn validate(&self, what: &str) -> Result<()> {
        let finite = |iso: &Isometry3<f64>| {
            iso.translation.vector.iter().all(|x| x.is_finite())
                && iso.rotation.coords.iter().all(|x| x.is_finite())
        };
        if !finite(&self.placement) || !finite(&self.link_frame) {
            return Err(PrrrpError::InvalidParameter {
                field: format!("{what}: placement"),
                value: f64::NAN,
                reason: "joint placements must be finite (m, rad)",
            });
        }
        let size = |iso: &Isometry3<f64>| iso.translation.vector.amax();
        let far = size(&self.placement).max(size(&self.link_frame));
        if far > crate::bounds::MAX_ROBOT_SIZE {
            return Err(PrrrpError::InvalidParameter {
                field: format!("{what}: placement"),
                value: far,
                reason: "joint offsets must be at most MAX_ROBOT_SIZE (1e6 m): check the \
                         file's units (m)",
            });
        }
        let norm = self.axis.norm();
        if !norm.is_finite() || (norm - 1.0).abs() > AXIS_UNIT_TOLERANCE {
            return Err(PrrrpError::InvalidParameter {
                field: format!("{what}: axis"),
                value: norm,
                reason: "a joint axis must be a unit vector (this is its length); \
                         give e.g. [0, 0, 1]",
            });
        }
        Ok(())
    }
}

fn rot_z(t: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), t)
}

/// Constant geometry of one joint, precomputed from a [`Joint`] so that the per-sample
/// transform costs a few multiply-adds.
///
/// Everything is expressed in the frame of the link the joint moves (frame i), where the
/// joint's axis and motion subspace are constant: the joint is a rotation about (or a
/// translation along) the unit axis `axis` through a point of frame i at −`rho`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct JointGeom {
    pub(crate) revolute: bool,
    /// Rotation ⁱ⁻¹Rᵢ(q) = `k` + cos q·`d` + sin q·`b` (revolute) or `k` (prismatic).
    k: Matrix3<f64>,
    d: Matrix3<f64>,
    b: Matrix3<f64>,
    /// Origin of frame i in frame i−1: `p1` + cos q·`dr` + sin q·`br` (revolute) or
    /// `p1` + q·`dr` (prismatic).
    p1: Vector3<f64>,
    dr: Vector3<f64>,
    br: Vector3<f64>,
    /// Joint axis u in frame i (unit).
    pub(crate) axis: Vector3<f64>,
    /// Position of the origin of frame i relative to the nearest point of the joint axis,
    /// in frame i (zero when the link frame sits on the axis, as in URDF).
    pub(crate) rho: Vector3<f64>,
    /// Angular part of the motion subspace S in frame i: u (revolute) or 0 (prismatic).
    pub(crate) s_ang: Vector3<f64>,
    /// Linear part of S: velocity of the origin of frame i per unit joint rate,
    /// u × ρ (revolute) or u (prismatic).
    pub(crate) s_lin: Vector3<f64>,
}

impl JointGeom {
    /// Precomputes the geometry of a validated joint.
    pub(crate) fn new(j: &Joint) -> Self {
        let r_pre = j.placement.rotation.to_rotation_matrix().into_inner();
        let r_post = j.link_frame.rotation.to_rotation_matrix().into_inner();
        let r0 = r_pre * r_post;
        let p0 = j.placement.translation.vector + r_pre * j.link_frame.translation.vector;
        let u_joint = j.axis / j.axis.norm();
        // In frame i the axis passes through the joint frame's origin, which sits at
        // −R_postᵀ·p_post.
        let u = r_post.transpose() * u_joint;
        let rho_full = r_post.transpose() * j.link_frame.translation.vector;
        let rho = rho_full - u * u.dot(&rho_full);
        let revolute = j.kind.is_rotational();
        if revolute {
            // Rodrigues: R0·Rot(u, q) = R0·u·uᵀ + cos q·R0·(1 − u·uᵀ) + sin q·R0·[u]×, and
            // the origin moves as R(q)·ρ with ρ ⟂ u.
            let k = r0 * u * u.transpose();
            let d = r0 - k;
            let b = r0 * u.cross_matrix();
            Self {
                revolute,
                k,
                d,
                b,
                p1: p0 - r0 * rho,
                dr: d * rho,
                br: b * rho,
                axis: u,
                rho,
                s_ang: u,
                s_lin: u.cross(&rho),
            }
        } else {
            Self {
                revolute,
                k: r0,
                d: Matrix3::zeros(),
                b: Matrix3::zeros(),
                p1: p0,
                dr: r0 * u,
                br: Vector3::zeros(),
                axis: u,
                rho,
                s_ang: Vector3::zeros(),
                s_lin: u,
            }
        }
    }

    /// ⁱ⁻¹Tᵢ(q) as (rotation ⁱ⁻¹Rᵢ, origin of frame i in frame i−1).
    #[inline(always)]
    pub(crate) fn transform(&self, q: f64) -> (Matrix3<f64>, Vector3<f64>) {
        if self.revolute {
            // One shared argument reduction (see `terms::Trig`).
            let (s, c) = libm::sincos(q);
            (
                self.k + self.d * c + self.b * s,
                self.p1 + self.dr * c + self.br * s,
            )
        } else {
            (self.k, self.p1 + self.dr * q)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn row(kind: JointKind) -> DhRow {
        DhRow {
            kind,
            theta: 0.3,
            d: 0.2,
            a: 0.5,
            alpha: -0.7,
        }
    }

    /// DH rows: the joint model reproduces the products of elementary transforms written
    /// from the conventions' definitions.
    #[test]
    fn dh_joints_match_elementary_products() {
        for kind in [JointKind::Revolute, JointKind::Prismatic] {
            let r = row(kind);
            let q = 0.4;
            let (theta, d) = match kind {
                JointKind::Revolute => (r.theta + q, r.d),
                JointKind::Prismatic => (r.theta, r.d + q),
            };
            let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), theta);
            let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), r.alpha);
            let std = Isometry3::from_parts(Translation3::identity(), rz.into())
                * Isometry3::translation(0.0, 0.0, d)
                * Isometry3::translation(r.a, 0.0, 0.0)
                * Isometry3::from_parts(Translation3::identity(), rx.into());
            let modi = Isometry3::from_parts(Translation3::identity(), rx.into())
                * Isometry3::translation(r.a, 0.0, 0.0)
                * Isometry3::from_parts(Translation3::identity(), rz.into())
                * Isometry3::translation(0.0, 0.0, d);
            for (conv, want) in [
                (DhConvention::Standard, std),
                (DhConvention::Modified, modi),
            ] {
                let joint = Joint::from_dh(&r, conv);
                let (rot, p) = JointGeom::new(&joint).transform(q);
                let want_r = want.rotation.to_rotation_matrix().into_inner();
                assert!((rot - want_r).norm() < 1e-14, "{conv:?} {kind:?}");
                assert!(
                    (p - want.translation.vector).norm() < 1e-14,
                    "{conv:?} {kind:?}"
                );
                let iso = joint.transform(q);
                assert!((iso.translation.vector - p).norm() < 1e-14);
            }
        }
    }

    /// An arbitrary axis, placement and link frame: the precomputed transform equals the
    /// composed definition, and S is the derivative of the transform.
    #[test]
    fn general_joint_matches_definition() {
        let placement = Isometry3::new(Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.4, -0.5, 0.6));
        let link = Isometry3::new(Vector3::new(-0.3, 0.25, 0.7), Vector3::new(-0.2, 0.9, 0.1));
        let axis = Vector3::new(0.3, -0.4, 0.5).normalize();
        for kind in [JointType::Revolute, JointType::Prismatic] {
            let j = Joint {
                kind,
                placement,
                axis,
                link_frame: link,
            };
            j.validate("test").unwrap();
            let g = JointGeom::new(&j);
            for q in [-2.0, 0.0, 0.7, 3.0] {
                let (r, p) = g.transform(q);
                let want = j.transform(q);
                let wr = want.rotation.to_rotation_matrix().into_inner();
                assert!((r - wr).norm() < 1e-14, "{kind:?} {q}");
                assert!((p - want.translation.vector).norm() < 1e-14, "{kind:?} {q}");
                // Twist of frame i relative to frame i−1, in frame i, per unit q̇:
                // ω = Rᵀ·dR/dq (skew), v = Rᵀ·dp/dq, by central differences.
                let h = 1e-6;
                let (r1, p1) = g.transform(q + h);
                let (r0, p0) = g.transform(q - h);
                let dr = (r1 - r0) / (2.0 * h);
                let w = r.transpose() * dr;
                let v = r.transpose() * (p1 - p0) / (2.0 * h);
                let w_vec = Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]);
                assert!((w_vec - g.s_ang).norm() < 1e-8, "{kind:?} ω");
                assert!((v - g.s_lin).norm() < 1e-8, "{kind:?} v");
            }
        }
    }

    #[test]
    fn bad_axes_are_refused() {
        for axis in [
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, 2.0),
            Vector3::new(f64::NAN, 0.0, 1.0),
        ] {
            let j = Joint::new(JointType::Revolute, Isometry3::identity(), axis);
            let e = j.validate("joint 1").unwrap_err().to_string();
            assert!(e.contains("joint 1: axis"), "{e}");
        }
    }
}
