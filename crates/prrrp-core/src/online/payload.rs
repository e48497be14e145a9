//! The payload as the online tracker needs it — a small private adapter.
//!
//! prrrp has one payload definition (`models::payload`, owned by the payload
//! identification work). Until it lands on this branch, everything the tracker needs of a
//! payload goes through the four functions below, so that switching to the shared
//! definition touches this file only:
//! - [`tip_columns`]: the tip link's 10 standard parameters (their regressor columns),
//! - [`project`]: the nearest rigid body (allocation-free: it runs every sample),
//! - [`summary_json`]: mass, centre of mass and inertia about it, each with σ (the
//!   `payload.json` of `prrrp track --payload`).
//!
//! The 10 parameters π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] are those of
//! a rigid body fixed to the chain's last link, in that link's frame, inertia about its
//! origin (kg, kg·m, kg·m²), in the same order as the chain's own per-link parameters:
//! carrying a payload is adding π to the tip link's standard parameters.

use nalgebra::{Matrix4, SMatrix, Vector3};
use serde_json::json;

use crate::error::{PrrrpError, Result};
use crate::models::chain::{
    com_and_inertia, is_physically_consistent, pseudo_inertia, pseudo_inertia_to_parameters,
    INERTIAL_PARAMETER_NAMES, LINK_PARAMS,
};

/// Number of payload parameters.
pub(crate) const PAYLOAD_PARAMS: usize = LINK_PARAMS;

/// Indices of the tip link's 10 inertial parameters among the standard parameter
/// `names` of an `n`-joint chain (found by name, `m{n}`, `mx{n}`, …, `Izz{n}`, so that
/// friction or actuator columns do not matter).
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] when a name is missing.
pub(crate) fn tip_columns(names: &[String], n: usize) -> Result<[usize; PAYLOAD_PARAMS]> {
    let mut out = [0; PAYLOAD_PARAMS];
    for (k, base) in INERTIAL_PARAMETER_NAMES.iter().enumerate() {
        let want = format!("{base}{n}");
        out[k] =
            names
                .iter()
                .position(|s| *s == want)
                .ok_or_else(|| PrrrpError::ShapeMismatch {
                    what: "payload columns".into(),
                    expected: format!("a standard parameter named {want} (the tip link's)"),
                    got: format!("{} parameters without it", names.len()),
                })?;
    }
    Ok(out)
}

/// π projected onto the rigid bodies in place: the negative eigenvalues of the
/// pseudo-inertia J(π) set to zero (the Frobenius-nearest J ⪰ 0; Wensing, Kim & Slotine
/// 2017). Returns whether π changed. Allocation-free (4×4 stack matrices).
pub(crate) fn project(pi: &mut [f64; PAYLOAD_PARAMS]) -> bool {
    let eig = pseudo_inertia(pi).symmetric_eigen();
    if eig.eigenvalues.iter().all(|&e| e >= 0.0) {
        return false;
    }
    let d = eig.eigenvalues.map(|e| e.max(0.0));
    let j = eig.eigenvectors * Matrix4::from_diagonal(&d) * eig.eigenvectors.transpose();
    *pi = pseudo_inertia_to_parameters(&j);
    true
}

/// The payload as load data (`payload.json`): `mass` (kg), `com` (m, tip frame),
/// `inertia` ([Ixx, Ixy, Iyy, Ixz, Iyz, Izz] about the centre of mass, kg·m²), each with
/// its σ propagated to first order from the covariance `cov` of π (row-major 10×10), the
/// parameters π with their σ, and whether π is a rigid body. A mass ≤ 0 has no centre of
/// mass (`null`).
pub(crate) fn summary_json(pi: &[f64; PAYLOAD_PARAMS], cov: Option<&[f64]>) -> serde_json::Value {
    let sd = |c: &SMatrix<f64, 10, 10>, k: usize| c[(k, k)].max(0.0).sqrt();
    let cov = cov.map(SMatrix::<f64, 10, 10>::from_row_slice);
    let mut out = json!({
        "mass": pi[0],
        "mass_sigma": cov.as_ref().map(|c| sd(c, 0)),
        "com": null,
        "com_sigma": null,
        "inertia": null,
        "inertia_sigma": null,
        "parameter_names": INERTIAL_PARAMETER_NAMES,
        "parameters": pi,
        "parameters_sigma": cov.as_ref().map(|c| (0..10).map(|k| sd(c, k)).collect::<Vec<_>>()),
        "physical": is_physically_consistent(pi, 1e-9),
        "units": {"mass": "kg", "com": "m (tip link frame)", "inertia": "kg m^2 about the centre of mass, tip link axes"},
    });
    if let Some((_, com, inertia)) = com_and_inertia(pi) {
        out["com"] = json!(com);
        out["inertia"] = json!(inertia);
        if let Some(c) = &cov {
            let jac = summary_jacobian(pi);
            let s = jac * c * jac.transpose();
            out["com_sigma"] = json!([sd(&s, 1), sd(&s, 2), sd(&s, 3)]);
            out["inertia_sigma"] = json!((4..10).map(|k| sd(&s, k)).collect::<Vec<_>>());
        }
    }
    out
}

/// ∂(m, c, I_c)/∂π (rows: m, cx, cy, cz, then I_c as Ixx, Ixy, Iyy, Ixz, Iyz, Izz), for
/// m > 0: c = h/m, I_c = I_O − (‖h‖²·1 − h·hᵀ)/m.
fn summary_jacobian(pi: &[f64; PAYLOAD_PARAMS]) -> SMatrix<f64, 10, 10> {
    let m = pi[0];
    let h = Vector3::new(pi[1], pi[2], pi[3]);
    let mut jac = SMatrix::<f64, 10, 10>::zeros();
    jac[(0, 0)] = 1.0;
    for i in 0..3 {
        jac[(1 + i, 1 + i)] = 1.0 / m;
        jac[(1 + i, 0)] = -h[i] / (m * m);
    }
    let s = nalgebra::Matrix3::identity() * h.norm_squared() - h * h.transpose();
    let entries = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)];
    for (r, &(a, b)) in entries.iter().enumerate() {
        let row = 4 + r;
        jac[(row, 4 + r)] = 1.0;
        jac[(row, 0)] = s[(a, b)] / (m * m);
        for k in 0..3 {
            // ∂S/∂h_k = 2·h_k·1 − e_k·hᵀ − h·e_kᵀ.
            let mut ds = if a == b { 2.0 * h[k] } else { 0.0 };
            if a == k {
                ds -= h[b];
            }
            if b == k {
                ds -= h[a];
            }
            jac[(row, 1 + k)] = -ds / m;
        }
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chain::inertial_parameters;

    /// The σ propagation's Jacobian against central differences of com_and_inertia.
    #[test]
    fn summary_jacobian_matches_finite_differences() {
        let pi = inertial_parameters(
            2.5,
            [0.03, -0.02, 0.07],
            [4e-3, 2e-4, 5e-3, -1e-4, 3e-4, 6e-3],
        );
        let jac = summary_jacobian(&pi);
        let f = |p: &[f64; 10]| {
            let (m, c, i) = com_and_inertia(p).unwrap();
            let mut v = [0.0; 10];
            v[0] = m;
            v[1..4].copy_from_slice(&c);
            v[4..].copy_from_slice(&i);
            v
        };
        for k in 0..10 {
            let step = 1e-6 * pi[k].abs().max(1e-3);
            let (mut a, mut b) = (pi, pi);
            a[k] += step;
            b[k] -= step;
            let (fa, fb) = (f(&a), f(&b));
            for r in 0..10 {
                let fd = (fa[r] - fb[r]) / (2.0 * step);
                assert!(
                    (fd - jac[(r, k)]).abs() < 1e-6 * (1.0 + fd.abs()),
                    "({r}, {k})"
                );
            }
        }
    }

    /// A rigid body is kept; a body breaking the triangle inequality, or of negative
    /// mass, lands on a rigid body; projecting twice changes nothing more.
    #[test]
    fn projection_onto_rigid_bodies() {
        let rigid = inertial_parameters(1.0, [0.1, 0.0, 0.0], [1e-3, 0.0, 1e-3, 0.0, 0.0, 1e-3]);
        let mut p = rigid;
        assert!(!project(&mut p));
        assert_eq!(p, rigid);
        let mut bad = inertial_parameters(1.0, [0.0; 3], [1e-3, 0.0, 1e-3, 0.0, 0.0, 5e-3]);
        assert!(!is_physically_consistent(&bad, 1e-12));
        assert!(project(&mut bad));
        assert!(is_physically_consistent(&bad, 1e-12));
        let once = bad;
        project(&mut bad);
        for k in 0..10 {
            assert!((once[k] - bad[k]).abs() < 1e-14);
        }
        let mut negative = [-0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        project(&mut negative);
        assert!(negative[0].abs() < 1e-15);
    }
}
