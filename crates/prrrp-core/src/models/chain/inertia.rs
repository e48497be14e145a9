//! The 10 standard inertial parameters of a rigid link and their frame changes.
//!
//! A link's inertial parameters are the vector
//! π = [m, m·x, m·y, m·z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (Pinocchio's order), where
//! - m is the mass (kg),
//! - (x, y, z) is the centre of mass in the link frame (m), so m·x, m·y, m·z are the first
//!   moments (kg·m),
//! - Ixx..Izz are the entries of the inertia tensor **about the origin of the link frame**,
//!   in the axes of the link frame (kg·m²): I_O = I_C + m·(‖c‖²·1 − c·cᵀ), with I_C the
//!   tensor about the centre of mass.
//!
//! The dynamics are linear in π, which is why these (and not the centre-of-mass form) are
//! the "standard parameters" of identification.

use nalgebra::{Matrix3, Matrix4, Vector3};

/// Number of standard inertial parameters per link.
pub const LINK_PARAMS: usize = 10;

/// Short names of the 10 inertial parameters, in order; the chain appends the 1-based
/// link number (e.g. `mx3`, `Izz2`).
pub const INERTIAL_PARAMETER_NAMES: [&str; LINK_PARAMS] = [
    "m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz",
];

/// Standard inertial parameters of a link from its mass (kg), centre of mass `com` in the
/// link frame (m) and inertia tensor about the centre of mass in link-frame axes,
/// `inertia_com = [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]` (kg·m²), by the parallel-axis theorem.
///
/// No validation: see [`is_physically_consistent`].
pub fn inertial_parameters(mass: f64, com: [f64; 3], inertia_com: [f64; 6]) -> [f64; 10] {
    let c = Vector3::from(com);
    let i_c = unpack_inertia(&inertia_com);
    let i_o = i_c + (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * mass;
    let mut p = [0.0; 10];
    p[0] = mass;
    p[1] = mass * com[0];
    p[2] = mass * com[1];
    p[3] = mass * com[2];
    p[4..].copy_from_slice(&pack_inertia(&i_o));
    p
}

/// Inverse of [`inertial_parameters`]: (mass, centre of mass, inertia about the centre of
/// mass as [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]); `None` if the mass is not strictly positive
/// (the centre of mass is then undefined).
pub fn com_and_inertia(params: &[f64; 10]) -> Option<(f64, [f64; 3], [f64; 6])> {
    let m = params[0];
    if m.is_nan() || m <= 0.0 {
        return None;
    }
    let c = first_moment(params) / m;
    let i_c =
        inertia_matrix(params) - (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m;
    Some((m, [c.x, c.y, c.z], pack_inertia(&i_c)))
}

/// Whether π describes a physically realisable rigid body: its 4×4 pseudo-inertia
/// matrix J = [[½·tr(I)·1 − I, h], [hᵀ, m]] is positive semidefinite (Wensing, Kim &
/// Slotine 2017) — equivalent to m ≥ 0 and a density-realisable inertia (triangle
/// inequalities about the centre of mass). `tol` (≥ 0) is the accepted negative eigenvalue
/// of J in kg·m², to absorb round-off (e.g. 1e-12). Point masses and rods are consistent.
pub fn is_physically_consistent(params: &[f64; 10], tol: f64) -> bool {
    if !params.iter().all(|x| x.is_finite()) {
        return false;
    }
    pseudo_inertia(params)
        .symmetric_eigenvalues()
        .iter()
        .all(|&e| e >= -tol)
}

/// The 4×4 pseudo-inertia J = [[Σ, h], [hᵀ, m]] of π (kg·m² in the 3×3 block, kg·m in
/// h, kg in m), with Σ = ½·tr(I)·1 − I = ∫ r·rᵀ dm the second moment of the mass
/// distribution about the link origin (Wensing, Kim & Slotine 2017). π is physically
/// consistent exactly when J ⪰ 0; see [`pseudo_inertia_to_parameters`] for the inverse.
pub fn pseudo_inertia(params: &[f64; 10]) -> Matrix4<f64> {
    let i = inertia_matrix(params);
    let h = first_moment(params);
    let sigma = Matrix3::identity() * (0.5 * i.trace()) - i;
    let mut j = Matrix4::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
    j.fixed_view_mut::<3, 1>(0, 3).copy_from(&h);
    j.fixed_view_mut::<1, 3>(3, 0).copy_from(&h.transpose());
    j[(3, 3)] = params[0];
    j
}

/// Inverse of [`pseudo_inertia`]: π from a symmetric J (I = tr(Σ)·1 − Σ; only the upper
/// triangle of J is read).
pub fn pseudo_inertia_to_parameters(j: &Matrix4<f64>) -> [f64; 10] {
    let tr = j[(0, 0)] + j[(1, 1)] + j[(2, 2)];
    [
        j[(3, 3)],
        j[(0, 3)],
        j[(1, 3)],
        j[(2, 3)],
        tr - j[(0, 0)],
        -j[(0, 1)],
        tr - j[(1, 1)],
        -j[(0, 2)],
        -j[(1, 2)],
        tr - j[(2, 2)],
    ]
}

/// Expresses the inertial parameters of a body, given in frame B, in frame A, where frame B
/// has orientation `rotation` (ᴬR_B) and origin `translation` (the origin of B in A
/// coordinates, m) relative to frame A.
pub fn transform_inertial_parameters(
    params: &[f64; 10],
    rotation: &Matrix3<f64>,
    translation: &Vector3<f64>,
) -> [f64; 10] {
    let mut out = [0.0; 10];
    transform_to_parent(params, rotation, translation, &mut out);
    out
}

/// `out = params expressed in the parent frame`; see [`transform_inertial_parameters`].
/// With h_B the first moment about B in A axes and p the origin of B:
/// I_A = R·I_B·Rᵀ − [h_B]×[p]× − [p]×[h_B]× − m·[p]×².
#[inline(always)]
pub(crate) fn transform_to_parent(
    params: &[f64; 10],
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
    out: &mut [f64; 10],
) {
    let m = params[0];
    let hr = r * first_moment(params);
    let i_rot = r * inertia_matrix(params) * r.transpose();
    let px = p.cross_matrix();
    let hx = hr.cross_matrix();
    let i_a = i_rot - hx * px - px * hx - px * px * m;
    let h_a = hr + p * m;
    out[0] = m;
    out[1] = h_a.x;
    out[2] = h_a.y;
    out[3] = h_a.z;
    out[4..].copy_from_slice(&pack_inertia(&i_a));
}

#[inline(always)]
pub(crate) fn first_moment(p: &[f64; 10]) -> Vector3<f64> {
    Vector3::new(p[1], p[2], p[3])
}

#[inline(always)]
pub(crate) fn inertia_matrix(p: &[f64; 10]) -> Matrix3<f64> {
    Matrix3::new(p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9])
}

/// I·w for the inertia part of π, without building the matrix.
#[inline(always)]
pub(crate) fn inertia_times(p: &[f64; 10], w: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        p[4] * w.x + p[5] * w.y + p[7] * w.z,
        p[5] * w.x + p[6] * w.y + p[8] * w.z,
        p[7] * w.x + p[8] * w.y + p[9] * w.z,
    )
}

fn unpack_inertia(i: &[f64; 6]) -> Matrix3<f64> {
    Matrix3::new(i[0], i[1], i[3], i[1], i[2], i[4], i[3], i[4], i[5])
}

/// The upper triangle of a symmetric I in the order of [`unpack_inertia`]: Ixx, Ixy, Iyy,
/// Ixz, Iyz, Izz.
fn pack_inertia(i: &Matrix3<f64>) -> [f64; 6] {
    [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)].map(|rc| i[rc])
}

#[cfg(test)]
mod tests {
    use super::*;

    // A 2 kg body with its centre of mass at (0.1, −0.2, 0.3) m and a full inertia tensor
    // about it (Ixx, Ixy, Iyy, Ixz, Iyz, Izz, kg·m²).
    const MASS: f64 = 2.0;
    const COM: [f64; 3] = [0.1, -0.2, 0.3];
    const INERTIA: [f64; 6] = [0.05, 0.001, 0.04, -0.002, 0.003, 0.03];

    #[test]
    fn parallel_axis_and_back() {
        let p = inertial_parameters(MASS, COM, INERTIA);
        // Izz about the origin = Izz_C + m (x² + y²).
        assert!((p[9] - (0.03 + 2.0 * (0.01 + 0.04))).abs() < 1e-15);
        // Ixy about the origin = Ixy_C − m x y.
        assert!((p[5] - (0.001 - 2.0 * 0.1 * -0.2)).abs() < 1e-15);
        let (m, c, i) = com_and_inertia(&p).unwrap();
        assert_eq!(m, 2.0);
        assert!((c[2] - 0.3).abs() < 1e-15);
        assert!((i[4] - 0.003).abs() < 1e-15);
        assert!(is_physically_consistent(&p, 1e-12));
        // A body whose Izz_C exceeds Ixx_C + Iyy_C cannot exist.
        let bad = inertial_parameters(1.0, [0.0; 3], [0.01, 0.0, 0.01, 0.0, 0.0, 0.05]);
        assert!(!is_physically_consistent(&bad, 1e-12));
    }

    /// Σ of a point mass is m·c·cᵀ, and J ↦ π inverts π ↦ J.
    #[test]
    fn pseudo_inertia_round_trip() {
        let p = inertial_parameters(MASS, COM, INERTIA);
        let back = pseudo_inertia_to_parameters(&pseudo_inertia(&p));
        for k in 0..10 {
            assert!((back[k] - p[k]).abs() < 1e-15, "{k}");
        }
        let point = inertial_parameters(3.0, [0.1, 0.2, 0.3], [0.0; 6]);
        let j = pseudo_inertia(&point);
        assert!((j[(0, 1)] - 3.0 * 0.1 * 0.2).abs() < 1e-15);
        assert!((j[(2, 2)] - 3.0 * 0.09).abs() < 1e-15);
    }

    /// Transforming a point mass moves it to the transformed point.
    #[test]
    fn transform_point_mass() {
        let p = inertial_parameters(3.0, [0.1, 0.2, 0.3], [0.0; 6]);
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 1.1).into_inner();
        let t = Vector3::new(-0.4, 0.7, 0.05);
        let q = transform_inertial_parameters(&p, &r, &t);
        let c = r * Vector3::new(0.1, 0.2, 0.3) + t;
        let want = inertial_parameters(3.0, [c.x, c.y, c.z], [0.0; 6]);
        for k in 0..10 {
            assert!(
                (q[k] - want[k]).abs() < 1e-14,
                "{k}: {} vs {}",
                q[k],
                want[k]
            );
        }
    }
}
