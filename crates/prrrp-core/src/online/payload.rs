//! The payload as the online tracker needs it — a small private adapter.
//!
//! prrrp has one payload definition, [`Payload`] (`models::payload`, shared with the
//! payload identification). The tracker reaches it through the functions below:
//! - [`tip_columns`]: the tip link's 10 standard parameters (their regressor columns),
//! - [`project`]: the nearest rigid body, every sample (allocation-free; the shared
//!   [`crate::project_physical`] is metric-weighted but allocates, so it is not used
//!   per sample),
//! - [`summary_json`]: the [`Payload`] as JSON (the `payload.json` of
//!   `prrrp track --payload`).
//!
//! The 10 parameters π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] are those of
//! a rigid body fixed to the chain's last link, in that link's frame, inertia about its
//! origin (kg, kg·m, kg·m²), in the same order as the chain's own per-link parameters:
//! carrying a payload is adding π to the tip link's standard parameters.

use nalgebra::Matrix4;
use serde_json::json;

use crate::error::{PrrrpError, Result};
use crate::models::chain::{
    pseudo_inertia, pseudo_inertia_to_parameters, INERTIAL_PARAMETER_NAMES, LINK_PARAMS,
};
use crate::models::payload::{Payload, PayloadThresholds};

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
    // A non-finite π has no eigenvalues to clip: left as it is.
    let Some(eig) = crate::linalg::symmetric_eigen(pseudo_inertia(pi)) else {
        return false;
    };
    if eig.eigenvalues.iter().all(|&e| e >= 0.0) {
        return false;
    }
    let d = eig.eigenvalues.map(|e| e.max(0.0));
    let j = eig.eigenvectors * Matrix4::from_diagonal(&d) * eig.eigenvectors.transpose();
    *pi = pseudo_inertia_to_parameters(&j);
    true
}

/// The payload as load data (`payload.json`): the shared [`Payload`] (carried by the
/// tip link `link`, index `n − 1`) as JSON — `mass` (kg), `com` (m, tip frame),
/// `inertia` ([Ixx, Ixy, Iyy, Ixz, Iyz, Izz] about the centre of mass, kg·m²), each with
/// its σ propagated from the covariance `cov` of π (row-major 10×10) — plus `physical`.
/// A π that is no payload (mass ≤ 0, e.g. an empty gripper, which [`Payload`] refuses)
/// is reported by its parameters and mass alone, with `physical: false`.
pub(crate) fn summary_json(
    link: &str,
    n: usize,
    pi: &[f64; PAYLOAD_PARAMS],
    cov: Option<Vec<f64>>,
) -> serde_json::Value {
    // The thresholds of the payload identification (σ at most 10 % of the mass and of the
    // inertia's scale, 1 cm on each centre-of-mass coordinate) decide `identifiable`, as
    // for `prrrp payload`; without them every quantity read as determined, a centre of
    // mass of ±0.8 m included.
    let payload =
        Payload::from_parameters(link, n.saturating_sub(1), *pi, cov.clone()).and_then(|mut p| {
            p.classify(&PayloadThresholds::default());
            p.to_json()
        });
    match payload {
        Ok(text) => {
            let mut v: serde_json::Value = serde_json::from_str(&text).unwrap_or(json!({}));
            v["physical"] = json!(true);
            v
        }
        Err(e) => json!({
            "link": link,
            "link_index": n.saturating_sub(1),
            "mass": pi[0],
            "mass_sigma": cov.as_ref().map(|c| c[0].max(0.0).sqrt()),
            "com": null,
            "com_sigma": null,
            "inertia": null,
            "inertia_sigma": null,
            "parameters": pi,
            "covariance": cov,
            "physical": false,
            "note": e.to_string(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chain::{inertial_parameters, is_physically_consistent};

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
