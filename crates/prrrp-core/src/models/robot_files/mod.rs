//! Robot files: chains read from URDF (any serial chain of a robot description) or from a
//! TOML Denavit–Hartenberg table, and chains written back as URDF.
//!
//! - [`DynChain::from_urdf_str`] / [`DynChain::from_urdf_file`]: the movable joints from a
//!   base link to a tip link; fixed joints and locked joints off the path are merged into
//!   the chain's links (see [`UrdfOptions`]).
//! - [`DynChain::from_toml_str`] / [`DynChain::from_toml_file`]: a DH table with optional
//!   inertials, friction and limits.
//! - [`DynChain::from_file`]: either, chosen by the file's extension.
//! - [`DynChain::to_urdf`]: a URDF of the chain with given standard parameters.
//!
//! Every problem with a file is a [`PrrrpError::RobotFile`] naming the file, the element or
//! key and what to fix; no input panics.

mod actuators;
mod toml_file;
mod transmission;
mod urdf;
mod urdf_export;
mod xml_scan;

pub use xml_scan::{MAX_URDF_DEPTH, MAX_URDF_ELEMENTS};

use std::path::Path;

use crate::error::{PrrrpError, Result};
use crate::models::chain::DynChain;

/// How to cut a serial chain out of a URDF robot description.
///
/// `Default` gives the root link as base, the automatically found tip and gravity
/// (0, 0, −9.81) m/s².
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOptions {
    /// Name of the fixed base link (frame 0 of the chain); `None` = the root link of the
    /// file.
    pub base: Option<String>,
    /// Name of the tip link; `None` = the child link of the last movable joint when the
    /// movable joints below the base form a single path (otherwise an error lists the
    /// candidate tips).
    pub tip: Option<String>,
    /// Gravity in the base link's frame, m/s²; `None` = (0, 0, −9.81).
    pub gravity: Option<[f64; 3]>,
}

/// The `file` of a [`PrrrpError::RobotFile`] for text given directly rather than read from
/// a path.
pub(crate) const STRING_SOURCE: &str = "<string>";

pub(crate) fn file_error(
    file: &str,
    element: impl Into<String>,
    message: impl Into<String>,
) -> PrrrpError {
    PrrrpError::RobotFile {
        file: file.to_string(),
        element: element.into(),
        message: message.into(),
    }
}

/// The first problem of a joint's limits, as (key, message): `lower` above `upper`, or a
/// bound on |q̇|, |q̈|, |τ| (`velocity`, `acceleration`, `effort`) below 0, or at 0 too
/// unless `zero_is_none` (URDF 1.0 writes an absent limit as 0). NaN is "not given".
pub(crate) fn limit_problem(
    lower: f64,
    upper: f64,
    bounds: [(&'static str, f64); 3],
    zero_is_none: bool,
) -> Option<(&'static str, String)> {
    if lower > upper {
        return Some((
            "lower",
            format!("lower = {lower} is above upper = {upper}; swap them"),
        ));
    }
    bounds.into_iter().find_map(|(key, v)| {
        let bad = if zero_is_none { v < 0.0 } else { v <= 0.0 };
        bad.then(|| {
            let allowed = if zero_is_none { " (or 0 for none)" } else { "" };
            (
                key,
                format!("{v} is not positive; a limit on |·| must be > 0{allowed}"),
            )
        })
    })
}

/// Reads a whole text file, with the path in every error.
/// Largest robot file read, bytes (64 MiB). Real descriptions are kilobytes (the Panda's
/// URDF is 15 kB); the bound keeps `/dev/zero` or a mistaken log file from exhausting
/// memory before the parser can complain.
pub const MAX_ROBOT_FILE_BYTES: u64 = 64 << 20;

fn read_text(path: &Path) -> Result<(String, String)> {
    use std::io::Read;
    let file = path.display().to_string();
    // Opening a FIFO blocks until a writer comes, in a system call that Ctrl-C and
    // SIGTERM do not end; its kind is known without opening it.
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if let Ok(m) = std::fs::metadata(path) {
            let t = m.file_type();
            if t.is_fifo() || t.is_socket() {
                return Err(file_error(
                    &file,
                    "file",
                    "a pipe or socket, not a robot file: give the path of a URDF or TOML \
                     file",
                ));
            }
        }
    }
    let read = std::fs::File::open(path).and_then(|f| {
        let mut text = String::new();
        // One byte past the bound tells a file that is too large from one that fits.
        let n = f.take(MAX_ROBOT_FILE_BYTES + 1).read_to_string(&mut text)?;
        Ok((n, text))
    });
    match read {
        Ok((n, _)) if n as u64 > MAX_ROBOT_FILE_BYTES => Err(file_error(
            &file,
            "file",
            format!(
                "the file is larger than {MAX_ROBOT_FILE_BYTES} bytes; a robot description \
                 is a few kilobytes: check the path"
            ),
        )),
        Ok((_, text)) => Ok((file, text)),
        Err(e) => Err(file_error(
            &file,
            "file",
            format!("cannot read the file ({e}); check the path and permissions"),
        )),
    }
}

impl DynChain {
    /// Reads a chain from a robot file, choosing the format by the extension: `.urdf`
    /// ([`DynChain::from_urdf_file`] with `opts`) or `.toml` ([`DynChain::from_toml_file`];
    /// `opts.base` and `opts.tip` override those of a TOML file that takes its links from a
    /// URDF), case-insensitively.
    ///
    /// # Errors
    /// [`PrrrpError::RobotFile`] for another or no extension, and every error of the two
    /// readers.
    pub fn from_file(path: impl AsRef<Path>, opts: &UrdfOptions) -> Result<DynChain> {
        let path = path.as_ref();
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("urdf") => Self::from_urdf_file(path, opts),
            Some("toml") => {
                let (file, text) = read_text(path)?;
                toml_file::chain_from_toml(&text, &file, opts)
            }
            Some(other) => Err(file_error(
                &path.display().to_string(),
                "file",
                format!(
                    "unknown robot file extension `.{other}`; use `.urdf` (URDF) or `.toml` \
                     (DH table)"
                ),
            )),
            None => Err(file_error(
                &path.display().to_string(),
                "file",
                "the file name has no extension; use `.urdf` (URDF) or `.toml` (DH table)",
            )),
        }
    }

    /// Reads a chain from a URDF file; see [`DynChain::from_urdf_str`].
    ///
    /// # Errors
    /// [`PrrrpError::RobotFile`] naming the path if the file cannot be read, and every error
    /// of [`DynChain::from_urdf_str`] with the path as `file`.
    pub fn from_urdf_file(path: impl AsRef<Path>, opts: &UrdfOptions) -> Result<DynChain> {
        let (file, text) = read_text(path.as_ref())?;
        urdf::chain_from_urdf(&text, &file, opts)
    }

    /// Reads the chain of movable joints (revolute, continuous, prismatic) from `opts.base`
    /// to `opts.tip` out of a URDF robot description.
    ///
    /// - Each chain joint's placement is its `<origin xyz rpy>` (m, rad; R = Rz(y)·Ry(p)·Rx(r))
    ///   composed with every fixed joint between the previous chain link and its parent
    ///   link; its axis is `<axis xyz>` (default (1, 0, 0)), which must be a unit vector.
    /// - Links attached through fixed joints, and subtrees behind movable joints off the
    ///   base→tip path or below the tip (held at q = 0 and listed in
    ///   [`crate::ChainMeta::locked_joints`]), are merged into the chain link they hang
    ///   from. What hangs from the base link is ignored: it exerts no joint torque. The
    ///   result equals Pinocchio's `buildReducedModel` with those joints locked at zero.
    /// - `<inertial>` (kg, m, kg·m² about the centre of mass) becomes the 10 standard
    ///   parameters in the link frame; a link without one is massless. Non-physical
    ///   inertias load; check them with [`crate::is_physically_consistent`].
    /// - Names, `<limit>` and `<dynamics>` go to [`DynChain::meta`]. URDF 1.0 writes a
    ///   missing bound as 0, so `lower = upper = 0` is read as "no position limits" and a
    ///   zero `velocity` or `effort` as "not given" (`NaN`).
    ///
    /// # Errors
    /// [`PrrrpError::RobotFile`] naming `<string>` and the element: malformed XML, a link
    /// or joint name that does not exist or repeats, a tip not below the base, several
    /// candidate tips, a floating, planar or mimic joint on the path, a floating or planar
    /// joint below a moving link off it, an axis that is not a unit vector, a non-finite
    /// number. Non-physical inertials (a negative mass, a broken triangle inequality)
    /// load: see [`DynChain::non_physical_links`];
    /// [`PrrrpError::InvalidParameter`] for a non-finite `opts.gravity`.
    pub fn from_urdf_str(xml: &str, opts: &UrdfOptions) -> Result<DynChain> {
        urdf::chain_from_urdf(xml, STRING_SOURCE, opts)
    }

    /// Reads a chain from a TOML DH table file; see [`DynChain::from_toml_str`].
    ///
    /// # Errors
    /// [`PrrrpError::RobotFile`] naming the path if the file cannot be read, and every error
    /// of [`DynChain::from_toml_str`] with the path as `file`.
    pub fn from_toml_file(path: impl AsRef<Path>) -> Result<DynChain> {
        let (file, text) = read_text(path.as_ref())?;
        toml_file::chain_from_toml(&text, &file, &UrdfOptions::default())
    }

    /// Reads a chain from a TOML DH table:
    ///
    /// ```toml
    /// name = "panda"                     # optional, default "robot"
    /// convention = "modified"            # or "standard"
    /// gravity = [0.0, 0.0, -9.80665]     # optional (m/s², base frame), default [0, 0, -9.81]
    /// base_link = "panda_link0"          # optional, default "base_link"
    /// [[joint]]                          # one per joint, base to tip
    /// type = "revolute"                  # "revolute", "continuous" or "prismatic"
    /// a = 0.0                            # m
    /// alpha = 0.0                        # rad
    /// d = 0.333                          # m
    /// theta = 0.0                        # rad
    /// # optional: name, link (the moved link's name), lower, upper, velocity,
    /// # acceleration, effort (SI limits), inertial = [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz,
    /// # Iyz, Izz] (kg, kg·m, kg·m², about the link frame's origin), friction = [fv, fc, fo]
    /// ```
    ///
    /// Integers are accepted for numbers. If any joint gives `friction`, the chain uses
    /// [`crate::FrictionModel::all`] with zeros for the joints that give none.
    ///
    /// Instead of `[[joint]]` tables (and `convention`, `base_link`) a file may take its
    /// links, joints, limits and inertials from a URDF: `urdf = "arm.urdf"` (relative to the
    /// TOML file's folder; to the working directory for text given here), optional `base`
    /// and `tip` links and `gravity`. Either kind of file may declare its drives in an
    /// `[actuators]` table (see [`crate::Actuators`]): `armature = true` (one rotor inertia
    /// per actuator, identified), `coupling = [[…], …]` (n×n, q̇ₘ = C·q̇; square, finite and
    /// invertible), `armature_values = […]` (kg·m², joint side; needs `armature = true`),
    /// `gear_ratios = […]` and `friction = [[fv, fc, fo], …]` (per actuator, instead of the
    /// joints' `friction`). The URDF's `<transmission>` elements are read first; the table
    /// overrides them key by key.
    ///
    /// ```
    /// use prrrp_core::{DynChain, DhConvention};
    ///
    /// let chain = DynChain::from_toml_str(
    ///     r#"
    ///     convention = "modified"
    ///     [[joint]]
    ///     type = "revolute"
    ///     a = 0
    ///     alpha = 0
    ///     d = 0.333
    ///     theta = 0
    ///     inertial = [1, 0, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1]
    ///     "#,
    /// )?;
    /// assert_eq!(chain.dof(), 1);
    /// assert_eq!(chain.convention(), Some(DhConvention::Modified));
    /// # Ok::<(), prrrp_core::PrrrpError>(())
    /// ```
    ///
    /// # Errors
    /// [`PrrrpError::RobotFile`] naming `<string>` and the key path (e.g.
    /// `joint[3].inertial`, 0-based): a TOML syntax error, an unknown key, a missing key, a
    /// value of the wrong type, length or sign, a non-finite number, or a repeated link or
    /// joint name.
    pub fn from_toml_str(text: &str) -> Result<DynChain> {
        toml_file::chain_from_toml(text, STRING_SOURCE, &UrdfOptions::default())
    }

    /// A URDF 1.0 document of the chain, with `parameters` as its standard parameters
    /// (`None` = the chain's own, [`DynChain::parameters`]).
    ///
    /// - `parameters` holds the 10·n inertial parameters, optionally followed by the
    ///   friction parameters of the chain's [`crate::FrictionModel`]; viscous and Coulomb
    ///   terms are written as `<dynamics damping friction>` (without friction parameters,
    ///   the file figures of [`DynChain::meta`] are written when given).
    /// - Inertials are written about the centre of mass with `rpy="0 0 0"`; a massless link
    ///   gets mass 0 and its inertia about the link origin.
    /// - The URDF link frame is the joint frame; for chains whose link frame differs
    ///   (standard DH), placements and inertials are re-expressed so that the dynamics are
    ///   unchanged, and the last link frame is kept as a massless link on a fixed joint.
    /// - Names and limits come from [`DynChain::meta`] (URDF 1.0 has no acceleration
    ///   limit). Numbers are written so that they read back to the same `f64`.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `parameters` has neither 10·n nor
    /// [`DynChain::num_params`] entries; [`PrrrpError::InvalidParameter`] for a non-finite
    /// parameter or a link with zero mass and a nonzero first moment (no centre of mass).
    pub fn to_urdf(&self, parameters: Option<&[f64]>) -> Result<String> {
        urdf_export::chain_to_urdf(self, parameters)
    }
}
