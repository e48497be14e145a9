//! [`DynChain`] → URDF 1.0 text.

use std::fmt::Write as _;

use nalgebra::{Isometry3, Matrix3, Vector3};

use crate::error::{PrrrpError, Result};
use crate::models::chain::{transform_inertial_parameters, DynChain, JointType, LINK_PARAMS};

/// Shortest text that reads back to the same `f64` (Rust's `Debug` is round-trip exact);
/// −0 is written as 0, which no reader treats differently.
pub(super) fn num(x: f64) -> String {
    let x = if x == 0.0 { 0.0 } else { x };
    format!("{x:?}")
}

fn vec3(v: &Vector3<f64>) -> String {
    format!("{} {} {}", num(v.x), num(v.y), num(v.z))
}

/// Escapes a name for a double-quoted XML attribute. Tab, newline and carriage return
/// are written as character references, which survive the attribute-value normalisation
/// of XML readers (a literal one would be read back as a space).
pub(super) fn attr(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\t' => out.push_str("&#9;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            c => out.push(c),
        }
    }
    out
}

fn bad_name(field: String, reason: &'static str) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field,
        value: f64::NAN,
        reason,
    }
}

/// The names a URDF identifies links and joints by: non-empty, representable in XML 1.0
/// (no control character but tab, newline and carriage return) and unique, or the
/// written file would not read back.
fn check_names(c: &DynChain) -> Result<()> {
    let meta = c.meta();
    let check = |field: String, name: &str| -> Result<()> {
        if name.trim().is_empty() {
            return Err(bad_name(
                field,
                "an empty name cannot identify a URDF link or joint",
            ));
        }
        if name
            .chars()
            .any(|ch| ch.is_control() && !matches!(ch, '\t' | '\n' | '\r'))
        {
            return Err(bad_name(
                field,
                "a control character cannot be written in XML 1.0; rename it",
            ));
        }
        Ok(())
    };
    let mut links = std::collections::HashSet::new();
    check("meta.base_link".into(), &meta.base_link)?;
    links.insert(meta.base_link.as_str());
    for (i, l) in meta.links.iter().enumerate() {
        check(format!("meta.links[{i}]"), l)?;
        if !links.insert(l.as_str()) {
            return Err(bad_name(
                format!("meta.links[{i}] ({l})"),
                "link names must be unique (the base link's too) to be written to URDF",
            ));
        }
    }
    let mut joints = std::collections::HashSet::new();
    for (i, j) in meta.joints.iter().enumerate() {
        check(format!("meta.joints[{i}].name"), &j.name)?;
        if !joints.insert(j.name.as_str()) {
            return Err(bad_name(
                format!("meta.joints[{i}].name ({})", j.name),
                "joint names must be unique to be written to URDF",
            ));
        }
    }
    if let Some(last) = meta.links.last() {
        let frame = format!("{last}_dh_frame");
        let joint = format!("{last}_dh_frame_joint");
        let needs_frame = c
            .joints()
            .last()
            .is_some_and(|j| j.link_frame != Isometry3::identity());
        if needs_frame && (links.contains(frame.as_str()) || joints.contains(joint.as_str())) {
            return Err(bad_name(
                format!("meta.links ({frame})"),
                "the name of the last link's DH frame (`<last link>_dh_frame`) is taken; \
                 rename that link or joint",
            ));
        }
    }
    Ok(())
}

/// Every number written must read back: a NaN or ∞ (a placement that overflowed, a centre
/// of mass of a vanishing mass) is an error naming where it would have gone.
fn finite(values: &[f64], field: impl FnOnce() -> String) -> Result<()> {
    match values.iter().find(|v| !v.is_finite()) {
        None => Ok(()),
        Some(&v) => Err(PrrrpError::InvalidParameter {
            field: field(),
            value: v,
            reason: "would be written to URDF as a NaN or infinite number, which no URDF \
                     reader accepts; check the chain's placements and parameters",
        }),
    }
}

fn iso_values(iso: &Isometry3<f64>) -> [f64; 6] {
    let (r, p, y) = rpy(&iso.rotation.to_rotation_matrix().into_inner());
    let t = iso.translation.vector;
    [t.x, t.y, t.z, r, p, y]
}

/// Fixed-axis roll, pitch, yaw of a rotation, R = Rz(y)·Ry(p)·Rx(r), accurate also near
/// pitch = ±π/2 (common in URDFs), where `asin`-based formulas lose half the digits: the
/// yaw is taken out first and roll and pitch come from entries of order 1 of the rest, so
/// that the three angles reproduce R to round-off whatever the yaw's own error.
fn rpy(rot: &Matrix3<f64>) -> (f64, f64, f64) {
    let yaw = rot[(1, 0)].atan2(rot[(0, 0)]);
    let (s, c) = yaw.sin_cos();
    let unyaw = Matrix3::new(c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0);
    // Ry(p)·Rx(r) = [[cp, sp·sr, sp·cr], [0, cr, −sr], [−sp, cp·sr, cp·cr]]
    let m = unyaw * rot;
    let pitch = (-m[(2, 0)]).atan2(m[(0, 0)]);
    let roll = (-m[(1, 2)]).atan2(m[(1, 1)]);
    (roll, pitch, yaw)
}

fn origin(iso: &Isometry3<f64>) -> String {
    let (r, p, y) = rpy(&iso.rotation.to_rotation_matrix().into_inner());
    format!(
        "<origin xyz=\"{}\" rpy=\"{} {} {}\"/>",
        vec3(&iso.translation.vector),
        num(r),
        num(p),
        num(y)
    )
}

/// (mass, centre of mass, inertia about it) of standard parameters. Unlike
/// `com_and_inertia` it also converts negative masses (identified parameters may have
/// them) and zero masses with a zero first moment; `None` for a zero mass with a nonzero
/// first moment, which no URDF inertial can express.
fn com_form(p: &[f64; 10]) -> Option<(f64, Vector3<f64>, Matrix3<f64>)> {
    let m = p[0];
    let h = Vector3::new(p[1], p[2], p[3]);
    let i_o = Matrix3::new(p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9]);
    if m != 0.0 {
        let c = h / m;
        let i_c = i_o - (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m;
        Some((m, c, i_c))
    } else if h == Vector3::zeros() {
        Some((0.0, h, i_o))
    } else {
        None
    }
}

fn inertial_xml(out: &mut String, p: &[f64; 10], link: usize) -> Result<()> {
    let Some((m, c, i)) = com_form(p) else {
        return Err(PrrrpError::InvalidParameter {
            field: format!("parameters[{}] (mx{} …)", LINK_PARAMS * link + 1, link + 1),
            value: 0.0,
            reason: "a link with zero mass and a nonzero first moment has no centre of \
                     mass and cannot be written to URDF",
        });
    };
    finite(&[c.x, c.y, c.z, m], || {
        format!(
            "link {} inertial (centre of mass = first moment / mass)",
            link + 1
        )
    })?;
    finite(i.as_slice(), || {
        format!(
            "link {} inertial (inertia about the centre of mass)",
            link + 1
        )
    })?;
    let _ = write!(
        out,
        "    <inertial>\n      <origin xyz=\"{}\" rpy=\"0 0 0\"/>\n      <mass value=\"{}\"/>\n      \
         <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/>\n    \
         </inertial>\n",
        vec3(&c),
        num(m),
        num(i[(0, 0)]),
        num(i[(0, 1)]),
        num(i[(0, 2)]),
        num(i[(1, 1)]),
        num(i[(1, 2)]),
        num(i[(2, 2)]),
    );
    Ok(())
}

pub(super) fn chain_to_urdf(c: &DynChain, parameters: Option<&[f64]>) -> Result<String> {
    let n = c.dof();
    let model = c.friction();
    let own = c.parameters();
    let params = parameters.unwrap_or(&own);
    if params.len() != LINK_PARAMS * n && params.len() != c.num_params() {
        return Err(PrrrpError::ShapeMismatch {
            what: "parameters".into(),
            expected: format!(
                "{} (inertial) or {} (with friction) values",
                LINK_PARAMS * n,
                c.num_params()
            ),
            got: format!("{} values", params.len()),
        });
    }
    if let Some(k) = params.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::InvalidParameter {
            field: format!("parameters[{k}]"),
            value: params[k],
            reason: "parameters written to URDF must be finite",
        });
    }
    // Each joint's [fv, fc] when the chain models them: from `params` when they follow
    // the inertials, else the chain's own. Friction of coupled actuators acts on C·q̇, not
    // on a joint: URDF cannot say so and the TOML robot file keeps it.
    let per_joint = c.layout().per;
    let coupled = c.actuators().coupling.is_some() && !c.actuators().is_default_coupling();
    let friction: Option<Vec<[f64; 2]>> =
        (!coupled && (model.viscous || model.coulomb)).then(|| {
            (0..n)
                .map(|j| {
                    let own = c.friction_params()[j];
                    if params.len() == c.num_params() {
                        let block = &params[LINK_PARAMS * n + per_joint * j..];
                        let fv = if model.viscous { block[0] } else { 0.0 };
                        let fc = if model.coulomb {
                            block[usize::from(model.viscous)]
                        } else {
                            0.0
                        };
                        [fv, fc]
                    } else {
                        [
                            if model.viscous { own[0] } else { 0.0 },
                            if model.coulomb { own[1] } else { 0.0 },
                        ]
                    }
                })
                .collect()
        });

    check_names(c)?;
    let meta = c.meta();
    let joints = c.joints();
    let g = c.gravity();
    finite(&g, || "gravity".into())?;
    let mut out = String::new();
    let _ = write!(
        out,
        "<?xml version=\"1.0\"?>\n<!-- Written by prrrp. Gravity in the base link's frame: \
         {} {} {} m/s^2 (not part of URDF). -->\n<robot name=\"{}\">\n  <link name=\"{}\"/>\n",
        num(g[0]),
        num(g[1]),
        num(g[2]),
        attr(&meta.name),
        attr(&meta.base_link)
    );
    for (i, j) in joints.iter().enumerate() {
        // The URDF link frame is the joint frame: the previous link's frame offset moves
        // into this joint's origin.
        let parent_frame = if i == 0 {
            Isometry3::identity()
        } else {
            joints[i - 1].link_frame
        };
        let parent = if i == 0 {
            &meta.base_link
        } else {
            &meta.links[i - 1]
        };
        let info = &meta.joints[i];
        finite(&iso_values(&(parent_frame * j.placement)), || {
            format!("joint {} ({}) origin", i + 1, info.name)
        })?;
        finite(j.axis.as_slice(), || {
            format!("joint {} ({}) axis", i + 1, info.name)
        })?;
        let _ = write!(
            out,
            "  <joint name=\"{}\" type=\"{}\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    \
             {}\n    <axis xyz=\"{}\"/>\n",
            attr(&info.name),
            j.kind.urdf_name(),
            attr(parent),
            attr(&meta.links[i]),
            origin(&(parent_frame * j.placement)),
            vec3(&j.axis),
        );
        let l = &info.limit;
        // URDF 1.0 requires effort and velocity in <limit>; 0 stands for "not given" and
        // is read back as such.
        let or0 = |v: f64| if v.is_finite() { v } else { 0.0 };
        if j.kind == JointType::Continuous {
            if l.effort.is_finite() || l.velocity.is_finite() {
                let _ = writeln!(
                    out,
                    "    <limit effort=\"{}\" velocity=\"{}\"/>",
                    num(or0(l.effort)),
                    num(or0(l.velocity))
                );
            }
        } else {
            out.push_str("    <limit");
            if l.lower.is_finite() {
                let _ = write!(out, " lower=\"{}\"", num(l.lower));
            }
            if l.upper.is_finite() {
                let _ = write!(out, " upper=\"{}\"", num(l.upper));
            }
            let _ = writeln!(
                out,
                " effort=\"{}\" velocity=\"{}\"/>",
                num(or0(l.effort)),
                num(or0(l.velocity))
            );
        }
        let dynamics = match &friction {
            Some(f) => Some(f[i]),
            None if info.damping.is_finite() || info.friction.is_finite() => {
                Some([or0(info.damping), or0(info.friction)])
            }
            None => None,
        };
        if let Some([d, f]) = dynamics {
            finite(&[d, f], || {
                format!("joint {} ({}) dynamics", i + 1, info.name)
            })?;
            let _ = writeln!(
                out,
                "    <dynamics damping=\"{}\" friction=\"{}\"/>",
                num(d),
                num(f)
            );
        }
        out.push_str("  </joint>\n");

        let mut p = [0.0; 10];
        p.copy_from_slice(&params[LINK_PARAMS * i..LINK_PARAMS * (i + 1)]);
        // From the link frame into the joint frame (identity for URDF and modified DH).
        let lf = &j.link_frame;
        let p = transform_inertial_parameters(
            &p,
            &lf.rotation.to_rotation_matrix().into_inner(),
            &lf.translation.vector,
        );
        let _ = writeln!(out, "  <link name=\"{}\">", attr(&meta.links[i]));
        inertial_xml(&mut out, &p, i)?;
        out.push_str("  </link>\n");
    }
    if let (Some(last), Some(name)) = (joints.last(), meta.links.last()) {
        // Keep the standard-DH frame of the last link (e.g. for a tool) as a massless link.
        if last.link_frame != Isometry3::identity() {
            finite(&iso_values(&last.link_frame), || {
                "last link's DH frame (origin)".into()
            })?;
            let _ = write!(
                out,
                "  <joint name=\"{0}_dh_frame_joint\" type=\"fixed\">\n    <parent link=\"{0}\"/>\n    \
                 <child link=\"{0}_dh_frame\"/>\n    {1}\n  </joint>\n  <link name=\"{0}_dh_frame\"/>\n",
                attr(name),
                origin(&last.link_frame)
            );
        }
    }
    super::transmission::write_transmissions(c, params, &mut out);
    out.push_str("</robot>\n");
    Ok(out)
}
