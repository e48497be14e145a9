//! A complete, serialisable description of a [`DynChain`]: joints, inertials, friction,
//! actuators, gravity and names. It is what a saved model carries so that it predicts without its
//! original robot file, and what Python pickles. Versioned by [`CHAIN_SCHEMA_VERSION`].

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::actuators::Actuators;
use super::dh::DhConvention;
use super::friction::FrictionModel;
use super::joint::{Joint, JointType};
use super::meta::{ChainMeta, JointInfo, JointLimit};
use super::serial_chain::DynChain;
use crate::error::{invalid, PrrrpError, Result};
use crate::models::prrrp::robot::{DhRow, JointKind};

/// Version of the [`ChainDescription`] layout; bumped on any incompatible change.
/// Version 2 added [`ChainDescription::actuators`]; version 1 descriptions (no actuators:
/// one motor per joint, no armature) still load.
pub const CHAIN_SCHEMA_VERSION: u32 = 2;

/// A rigid transform: translation (m) and unit quaternion `[w, x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseDescription {
    /// Translation, m.
    pub xyz: [f64; 3],
    /// Rotation as a unit quaternion [w, x, y, z].
    pub quaternion: [f64; 4],
}

/// One joint: type, placement, axis, link frame, name and limits (`None` = not given).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointDescription {
    /// Joint name.
    pub name: String,
    /// Name of the link it moves.
    pub link: String,
    /// `"revolute"`, `"continuous"` or `"prismatic"`.
    #[serde(rename = "type")]
    pub kind: String,
    /// Joint frame at q = 0 in the parent link's frame.
    pub placement: PoseDescription,
    /// Unit axis in the joint frame.
    pub axis: [f64; 3],
    /// Link frame in the joint frame.
    pub link_frame: PoseDescription,
    /// Position limits (rad or m).
    pub lower: Option<f64>,
    /// Position limits (rad or m).
    pub upper: Option<f64>,
    /// Speed limit (rad/s or m/s).
    pub velocity: Option<f64>,
    /// Acceleration limit (rad/s² or m/s²).
    pub acceleration: Option<f64>,
    /// Effort limit (N·m or N).
    pub effort: Option<f64>,
    /// The source file's damping figure.
    pub damping: Option<f64>,
    /// The source file's friction figure.
    pub friction: Option<f64>,
}

/// The DH table a chain was built from, kept so that it reloads as a DH chain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DhDescription {
    /// `"standard"` or `"modified"`.
    pub convention: String,
    /// Rows [a, alpha, d, theta] (m, rad, m, rad).
    pub rows: Vec<[f64; 4]>,
}

/// Everything that defines a [`DynChain`] (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainDescription {
    /// [`CHAIN_SCHEMA_VERSION`] of the writer.
    pub schema_version: u32,
    /// Robot name.
    pub name: String,
    /// Fixed base link.
    pub base_link: String,
    /// Joints, base to tip.
    pub joints: Vec<JointDescription>,
    /// Joints of the source file held at zero.
    pub locked_joints: Vec<String>,
    /// The DH table, for chains built from one.
    pub dh: Option<DhDescription>,
    /// Per link [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] about the link-frame origin.
    pub inertial: Vec<[f64; 10]>,
    /// Gravity in the base frame, m/s².
    pub gravity: [f64; 3],
    /// Enabled friction terms among `"viscous"`, `"coulomb"`, `"offset"`.
    pub friction: Vec<String>,
    /// Speed scale of the smooth Coulomb sign (0 = exact sign), rad/s or m/s.
    pub coulomb_smoothing: f64,
    /// Per actuator (= per joint without coupling) [fv, fc, fo].
    pub friction_params: Vec<[f64; 3]>,
    /// The actuators: coupling, armature, gear ratios (schema 2; absent = the default,
    /// one motor per joint without armature).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuators: Option<Actuators>,
}

fn pose(iso: &Isometry3<f64>) -> PoseDescription {
    let q = iso.rotation.quaternion();
    PoseDescription {
        xyz: iso.translation.vector.into(),
        quaternion: [q.w, q.i, q.j, q.k],
    }
}

fn iso(p: &PoseDescription, what: &str) -> Result<Isometry3<f64>> {
    let [w, x, y, z] = p.quaternion;
    let q = Quaternion::new(w, x, y, z);
    let n = q.norm();
    if !(n.is_finite() && (n - 1.0).abs() < 1e-9) {
        return Err(PrrrpError::InvalidParameter {
            field: format!("{what}.quaternion"),
            value: n,
            reason: "must be a unit quaternion [w, x, y, z] (this is its norm)",
        });
    }
    Ok(Isometry3::from_parts(
        Translation3::from(Vector3::from(p.xyz)),
        UnitQuaternion::new_unchecked(q),
    ))
}

fn some(x: f64) -> Option<f64> {
    (!x.is_nan()).then_some(x)
}

fn friction_terms(f: &FrictionModel) -> Vec<String> {
    [
        (f.viscous, "viscous"),
        (f.coulomb, "coulomb"),
        (f.offset, "offset"),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .map(|(_, n)| n.to_string())
    .collect()
}

impl DynChain {
    /// The chain's complete description (exact: `from_description` rebuilds an equal chain).
    pub fn description(&self) -> ChainDescription {
        let meta = self.meta();
        let f = self.friction();
        ChainDescription {
            schema_version: CHAIN_SCHEMA_VERSION,
            name: meta.name.clone(),
            base_link: meta.base_link.clone(),
            joints: self
                .joints()
                .iter()
                .zip(&meta.joints)
                .zip(&meta.links)
                .map(|((j, info), link)| JointDescription {
                    name: info.name.clone(),
                    link: link.clone(),
                    kind: j.kind.urdf_name().into(),
                    placement: pose(&j.placement),
                    axis: j.axis.into(),
                    link_frame: pose(&j.link_frame),
                    lower: some(info.limit.lower),
                    upper: some(info.limit.upper),
                    velocity: some(info.limit.velocity),
                    acceleration: some(info.limit.acceleration),
                    effort: some(info.limit.effort),
                    damping: some(info.damping),
                    friction: some(info.friction),
                })
                .collect(),
            locked_joints: meta.locked_joints.clone(),
            dh: self
                .dh()
                .zip(self.convention())
                .map(|(rows, c)| DhDescription {
                    convention: match c {
                        DhConvention::Standard => "standard".into(),
                        DhConvention::Modified => "modified".into(),
                    },
                    rows: rows.iter().map(|r| [r.a, r.alpha, r.d, r.theta]).collect(),
                }),
            inertial: self.inertial().to_vec(),
            gravity: self.gravity(),
            friction: friction_terms(&f),
            coulomb_smoothing: f.coulomb_smoothing,
            friction_params: self.friction_params().to_vec(),
            actuators: (*self.actuators() != Actuators::default())
                .then(|| self.actuators().clone()),
        }
    }

    /// Rebuilds a chain from its description.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for an unknown schema version, joint type,
    /// convention or friction term, a non-unit quaternion or axis, non-finite values;
    /// [`PrrrpError::ShapeMismatch`] when the per-joint lists differ in length or there are
    /// more than [`crate::MAX_DOF`] joints.
    pub fn from_description(d: &ChainDescription) -> Result<DynChain> {
        if !(1..=CHAIN_SCHEMA_VERSION).contains(&d.schema_version) {
            return Err(PrrrpError::InvalidParameter {
                field: "schema_version".into(),
                value: d.schema_version as f64,
                reason: "unknown chain description version (this prrrp reads versions 1 and 2)",
            });
        }
        // Before anything is built: every later size (regressor, covariance) grows with it.
        super::check_dof("joints", d.joints.len())?;
        let mut joints = Vec::with_capacity(d.joints.len());
        let mut infos = Vec::with_capacity(d.joints.len());
        for (i, j) in d.joints.iter().enumerate() {
            let what = format!("joints[{i}] ({})", j.name);
            let kind = match j.kind.as_str() {
                "revolute" => JointType::Revolute,
                "continuous" => JointType::Continuous,
                "prismatic" => JointType::Prismatic,
                _ => {
                    let reason = "must be \"revolute\", \"continuous\" or \"prismatic\"";
                    return Err(invalid(format!("{what}.type"), f64::NAN, reason));
                }
            };
            joints.push(Joint {
                kind,
                placement: iso(&j.placement, &format!("{what}.placement"))?,
                axis: Vector3::from(j.axis),
                link_frame: iso(&j.link_frame, &format!("{what}.link_frame"))?,
            });
            let nan = |x: Option<f64>| x.unwrap_or(f64::NAN);
            infos.push(JointInfo {
                name: j.name.clone(),
                limit: JointLimit {
                    lower: nan(j.lower),
                    upper: nan(j.upper),
                    velocity: nan(j.velocity),
                    acceleration: nan(j.acceleration),
                    effort: nan(j.effort),
                },
                damping: nan(j.damping),
                friction: nan(j.friction),
            });
        }
        let mut chain = match &d.dh {
            Some(dh) => {
                let convention = match dh.convention.as_str() {
                    "standard" => DhConvention::Standard,
                    "modified" => DhConvention::Modified,
                    _ => {
                        return Err(PrrrpError::InvalidParameter {
                            field: "dh.convention".into(),
                            value: f64::NAN,
                            reason: "must be \"standard\" or \"modified\"",
                        })
                    }
                };
                let rows = dh
                    .rows
                    .iter()
                    .zip(&joints)
                    .map(|(r, j)| DhRow {
                        kind: if j.kind.is_rotational() {
                            JointKind::Revolute
                        } else {
                            JointKind::Prismatic
                        },
                        a: r[0],
                        alpha: r[1],
                        d: r[2],
                        theta: r[3],
                    })
                    .collect::<Vec<_>>();
                if rows.len() != joints.len() {
                    return Err(PrrrpError::ShapeMismatch {
                        what: "dh.rows".into(),
                        expected: format!("{} rows (one per joint)", joints.len()),
                        got: format!("{} rows", dh.rows.len()),
                    });
                }
                DynChain::new(rows, convention)?
            }
            None => DynChain::from_joints(joints)?,
        };
        let mut model = FrictionModel {
            coulomb_smoothing: d.coulomb_smoothing,
            ..FrictionModel::default()
        };
        for t in &d.friction {
            match t.as_str() {
                "viscous" => model.viscous = true,
                "coulomb" => model.coulomb = true,
                "offset" => model.offset = true,
                _ => {
                    return Err(PrrrpError::InvalidParameter {
                        field: "friction".into(),
                        value: f64::NAN,
                        reason: "terms must be among \"viscous\", \"coulomb\", \"offset\"",
                    })
                }
            }
        }
        let links = d.joints.iter().map(|j| j.link.clone()).collect();
        chain = chain
            .with_inertial(d.inertial.clone())?
            .with_gravity(d.gravity)?
            .with_friction(model, d.friction_params.clone())?
            .with_meta(ChainMeta {
                name: d.name.clone(),
                base_link: d.base_link.clone(),
                links,
                joints: infos,
                locked_joints: d.locked_joints.clone(),
            })?;
        if let Some(a) = &d.actuators {
            chain = chain.with_actuators(a.clone())?;
        }
        Ok(chain)
    }

    /// The description as JSON (see [`ChainDescription`]).
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] if a parameter is not finite (JSON has no NaN).
    pub fn to_json(&self) -> Result<String> {
        serde_json::to_string(&self.description()).map_err(|_| PrrrpError::NonFinite {
            what: "chain description".into(),
            row: None,
        })
    }

    /// A chain from the JSON of [`DynChain::to_json`].
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the JSON problem, or as
    /// [`DynChain::from_description`].
    pub fn from_json(text: &str) -> Result<DynChain> {
        let d: ChainDescription = crate::json::parse(
            text,
            "chain",
            "not a prrrp chain description; write it with DynChain::to_json",
        )?;
        DynChain::from_description(&d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chain::SerialChain;

    #[test]
    fn json_round_trip_is_exact() {
        let puma = SerialChain::puma560()
            .to_dyn()
            .with_friction(FrictionModel::all(), vec![[0.1, 0.2, 0.3]; 6])
            .unwrap();
        // NaN limits make `==` on the chains false; compare what defines the dynamics and
        // the re-serialised text.
        let same = |a: &DynChain, b: &DynChain| {
            assert!(a.joints() == b.joints() && a.inertial() == b.inertial());
            assert!(a.friction() == b.friction() && a.friction_params() == b.friction_params());
            assert!(a.gravity() == b.gravity() && a.dh() == b.dh());
            assert!(a.to_json().unwrap() == b.to_json().unwrap());
        };
        let back = DynChain::from_json(&puma.to_json().unwrap()).unwrap();
        same(&back, &puma);
        let general = DynChain::from_joints(puma.joints().to_vec())
            .unwrap()
            .with_inertial(puma.inertial().to_vec())
            .unwrap();
        let back = DynChain::from_json(&general.to_json().unwrap()).unwrap();
        same(&back, &general);
    }

    #[test]
    fn actuators_round_trip_and_version_1_loads() {
        let mut c = vec![vec![0.0; 6]; 6];
        for (i, r) in c.iter_mut().enumerate() {
            r[i] = 1.0;
        }
        c[5][4] = 1.0;
        let act = Actuators {
            coupling: Some(c),
            armature: true,
            armature_values: Some(vec![1.0, 2.0, 0.5, 0.1, 0.05, 0.02]),
            gear_ratios: Some(vec![100.0; 6]),
        };
        let puma = SerialChain::puma560()
            .to_dyn()
            .with_friction(FrictionModel::all(), vec![[0.1, 0.2, 0.3]; 6])
            .unwrap()
            .with_actuators(act.clone())
            .unwrap();
        let back = DynChain::from_json(&puma.to_json().unwrap()).unwrap();
        assert_eq!(back.actuators(), &act);
        assert_eq!(back.parameters(), puma.parameters());
        // A version-1 description (written before actuators existed) still loads.
        let mut d = SerialChain::puma560().to_dyn().description();
        d.schema_version = 1;
        let v1 = serde_json::to_string(&d).unwrap();
        assert!(!v1.contains("actuators"));
        let old = DynChain::from_json(&v1).unwrap();
        assert_eq!(old.actuators(), &Actuators::default());
    }

    #[test]
    fn bad_json_is_a_typed_error() {
        assert!(DynChain::from_json("{").is_err());
        let mut d = SerialChain::puma560().to_dyn().description();
        d.joints[2].placement.quaternion = [2.0, 0.0, 0.0, 0.0];
        assert!(DynChain::from_description(&d).is_err());
        d.schema_version = 99;
        assert!(DynChain::from_description(&d).is_err());
    }
}
