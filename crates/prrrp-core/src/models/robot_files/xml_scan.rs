//! A linear pre-scan of a URDF's XML before urdf-rs reads it.
//!
//! urdf-rs builds and walks its XML tree recursively: a file of 30 000 nested elements
//! overflows the stack (SIGSEGV, which no `Result` can report) and the parse time grows
//! with the square of the depth. A streaming pass of quick-xml (which urdf-rs already
//! depends on; it keeps no tree and does not recurse) bounds the nesting depth and the
//! element count first, and checks what urdf-rs would silently turn into the identity: a
//! `quat_xyzw` that is NaN, infinite or zero (urdfdom's conversion maps every such
//! quaternion to "no rotation").
//!
//! The same pass leaves out what the dynamics never read — `visual` and `collision`
//! elements and the robot's `material` list — so that a geometry detail urdf-rs is
//! stricter about than urdfdom (iCub's and Romeo's `<texture />` without a file name)
//! does not refuse a robot whose kinematics and inertias are fine.

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, Writer};

use super::file_error;
use crate::error::Result;

/// Deepest element nesting accepted in a URDF: 64. A URDF nests at most six levels
/// (`robot/link/visual/geometry/mesh`); xacro output is no deeper.
pub const MAX_URDF_DEPTH: usize = 64;

/// Most elements accepted in a URDF: 50 000. A detailed robot has a few hundred to a
/// few thousand (the Panda's URDF 250, a humanoid's about 2 000). urdf-rs reads about
/// 20 000 elements a second (measured: 1.9 s for a file of 10 000 joints, 40 000
/// elements), without a way to interrupt it, so the bound keeps a read under a few
/// seconds.
pub const MAX_URDF_ELEMENTS: usize = 50_000;

/// What the scan tracks of the element that owns an `<origin>`, for error messages.
fn owner_name(e: &BytesStart<'_>) -> Option<(String, String)> {
    let tag = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
    if tag != "link" && tag != "joint" {
        return None;
    }
    let name = attribute(e, b"name").unwrap_or_default();
    Some((tag, name))
}

fn attribute(e: &BytesStart<'_>, key: &[u8]) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.local_name().as_ref() == key)
        .map(|a| String::from_utf8_lossy(&a.value).into_owned())
}

/// URDF ≥ 1.1 reads `quat_xyzw`; 1.0 ignores it (as urdfdom does).
fn reads_quaternions(robot: &BytesStart<'_>) -> bool {
    attribute(robot, b"version")
        .and_then(|v| {
            let (major, minor) = v.trim().split_once('.')?;
            Some((major.parse::<u32>().ok()?, minor.parse::<u32>().ok()?))
        })
        .is_some_and(|v| v >= (1, 1))
}

/// The quaternion check: four finite numbers with a norm that can be normalised.
fn check_quaternion(text: &str, file: &str, element: impl FnOnce() -> String) -> Result<()> {
    let values: Vec<f64> = text
        .split_whitespace()
        .map(|s| s.parse::<f64>().unwrap_or(f64::NAN))
        .collect();
    // Four values are urdf-rs's own check; the others are what it lets through.
    if values.len() != 4 {
        return Ok(());
    }
    let norm = values.iter().map(|v| v * v).sum::<f64>().sqrt();
    if values.iter().all(|v| v.is_finite()) && norm.is_finite() && norm > 1e-6 {
        return Ok(());
    }
    Err(file_error(
        file,
        element(),
        format!(
            "quat_xyzw = \"{}\" is not a rotation (NaN, infinite or zero); give a unit \
             quaternion x y z w, e.g. \"0 0 0 1\"",
            text.trim()
        ),
    ))
}

/// Checks the nesting depth, the element count and the `quat_xyzw` attributes of `xml`
/// in one pass (linear in its length).
///
/// # Errors
/// [`crate::PrrrpError::RobotFile`] naming the limit that was exceeded, the malformed
/// quaternion's element, or the XML error.
/// Whether an element at `depth` (1 = the root `robot`, 2 = its children) is geometry or
/// appearance only, left out of what urdf-rs reads.
fn is_geometry(tag: &[u8], depth: usize) -> bool {
    matches!(tag, b"visual" | b"collision") || (depth == 2 && tag == b"material")
}

/// Checks `xml` as the module docs say and returns it without its geometry elements
/// ([`is_geometry`]), for urdf-rs.
pub(super) fn prescan(xml: &str, file: &str) -> Result<String> {
    let mut reader = Reader::from_str(xml);
    let mut writer = Writer::new(Vec::with_capacity(xml.len()));
    // Depth at which the geometry element being skipped started, if any.
    let mut skipping: Option<usize> = None;
    let mut depth = 0usize;
    let mut elements = 0usize;
    let mut quaternions = false;
    // The link or joint being read and the depth at which it started.
    let mut owner: Option<(String, String, usize)> = None;
    loop {
        let event = reader.read_event().map_err(|e| {
            file_error(
                file,
                "robot",
                format!(
                    "not a readable URDF document (XML error at byte {}: {e}); fix the XML",
                    reader.error_position()
                ),
            )
        })?;
        let (start, empty) = match &event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(_) => {
                if skipping.is_none() {
                    write(&mut writer, event.borrow(), file)?;
                } else if skipping == Some(depth) {
                    skipping = None;
                }
                depth = depth.saturating_sub(1);
                if owner.as_ref().is_some_and(|o| o.2 > depth) {
                    owner = None;
                }
                continue;
            }
            Event::Eof => {
                return String::from_utf8(writer.into_inner()).map_err(|e| {
                    file_error(file, "robot", format!("not UTF-8 after filtering ({e})"))
                });
            }
            _ => {
                if skipping.is_none() {
                    write(&mut writer, event.borrow(), file)?;
                }
                continue;
            }
        };
        elements += 1;
        if elements > MAX_URDF_ELEMENTS {
            return Err(file_error(
                file,
                "robot",
                format!(
                    "more than {MAX_URDF_ELEMENTS} XML elements (MAX_URDF_ELEMENTS); a robot \
                     description has a few thousand at most: check the file"
                ),
            ));
        }
        if !empty {
            depth += 1;
            if depth > MAX_URDF_DEPTH {
                return Err(file_error(
                    file,
                    "robot",
                    format!(
                        "XML elements nested more than {MAX_URDF_DEPTH} deep (MAX_URDF_DEPTH); \
                         a URDF nests about six levels: check the file"
                    ),
                ));
            }
        }
        let tag = start.local_name();
        let level = if empty { depth + 1 } else { depth };
        if skipping.is_none() {
            if is_geometry(tag.as_ref(), level) {
                skipping = (!empty).then_some(depth);
            } else {
                write(&mut writer, event.borrow(), file)?;
            }
        }
        if elements == 1 {
            // urdf-rs reads any root as the robot: a `<sdf>` or `<launch>` file would be a
            // robot of no links, refused later with a message about links.
            if tag.as_ref() != b"robot" {
                return Err(file_error(
                    file,
                    "robot",
                    format!(
                        "the root element is <{}>, not <robot>: not a URDF (run xacro \
                         first for a .xacro file; an SDF file is not read)",
                        String::from_utf8_lossy(tag.as_ref())
                    ),
                ));
            }
            quaternions = reads_quaternions(start);
        } else if let Some((t, n)) = owner_name(start) {
            if owner.is_none() && !empty {
                owner = Some((t, n, depth));
            }
        } else if quaternions && tag.as_ref() == b"origin" {
            if let Some(q) = attribute(start, b"quat_xyzw") {
                check_quaternion(&q, file, || match &owner {
                    Some((t, n, _)) => format!("{t}[{n}]/origin/quat_xyzw"),
                    None => "origin/quat_xyzw".into(),
                })?;
            }
        }
    }
}

fn write(writer: &mut Writer<Vec<u8>>, event: Event<'_>, file: &str) -> Result<()> {
    writer
        .write_event(event)
        .map_err(|e| file_error(file, "robot", format!("cannot copy the XML ({e})")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternions_must_be_rotations() {
        let el = || "joint[j]/origin/quat_xyzw".to_string();
        assert!(check_quaternion("0 0 0 1", "f", el).is_ok());
        assert!(check_quaternion("0 0 0 2", "f", el).is_ok());
        for bad in ["nan nan nan nan", "0 0 0 0", "inf 0 0 1", "0 0 0 1e200"] {
            assert!(check_quaternion(bad, "f", el).is_err(), "{bad}");
        }
    }
}
