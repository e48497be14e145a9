//! Fixtures shared by the robot-file tests: the data folder and the three-joint URDF.

use prrrp_core::UrdfOptions;

/// The path of `name` in this crate's `tests/data`.
pub fn data(name: &str) -> String {
    format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// The text of `tests/data/three_joint.urdf`.
pub fn three_joint_text() -> String {
    std::fs::read_to_string(data("three_joint.urdf")).unwrap()
}

/// URDF options that end the chain at link `name`.
pub fn tip(name: &str) -> UrdfOptions {
    UrdfOptions {
        tip: Some(name.into()),
        ..UrdfOptions::default()
    }
}
