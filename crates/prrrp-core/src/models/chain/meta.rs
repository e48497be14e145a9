//! What a robot file says about a chain besides its dynamics: names, joint limits and the
//! file's own damping/friction figures. Constant data, carried by [`super::DynChain`].

/// Limits of one joint, SI units (rad, rad/s, rad/s², N·m for rotational joints; m, m/s,
/// m/s², N for prismatic ones). `NaN` where the source gives none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimit {
    /// Lowest position.
    pub lower: f64,
    /// Highest position.
    pub upper: f64,
    /// Largest speed |q̇|.
    pub velocity: f64,
    /// Largest acceleration |q̈| (URDF has no such field; TOML files may give it).
    pub acceleration: f64,
    /// Largest effort |τ|.
    pub effort: f64,
}

impl Default for JointLimit {
    /// No limits known: every field `NaN`.
    fn default() -> Self {
        Self {
            lower: f64::NAN,
            upper: f64::NAN,
            velocity: f64::NAN,
            acceleration: f64::NAN,
            effort: f64::NAN,
        }
    }
}

/// One joint's name, limits and the `<dynamics damping friction>` figures of its file
/// (N·m·s/rad and N·m for rotational joints; `NaN` where not given). The file's figures are
/// kept for reference and as a prior; the chain's friction model is set separately.
#[derive(Debug, Clone, PartialEq)]
pub struct JointInfo {
    /// Joint name (the URDF `name`, or `joint1`, `joint2`, … for DH tables).
    pub name: String,
    /// Position, velocity, acceleration and effort limits.
    pub limit: JointLimit,
    /// Viscous damping from the file.
    pub damping: f64,
    /// Dry friction from the file.
    pub friction: f64,
}

impl JointInfo {
    /// A joint with a name and nothing else known.
    pub fn named(name: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            limit: JointLimit::default(),
            damping: f64::NAN,
            friction: f64::NAN,
        }
    }
}

/// Names and limits of a chain: the robot, its base link, the link each joint moves, the
/// joints, and the movable joints of the source file that are held at zero (locked) and
/// merged into the chain's links.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainMeta {
    /// Robot name.
    pub name: String,
    /// Name of the fixed base link (frame 0).
    pub base_link: String,
    /// Name of the link each joint moves (one per joint).
    pub links: Vec<String>,
    /// One entry per joint, base to tip.
    pub joints: Vec<JointInfo>,
    /// Movable joints of the source file held at zero and merged into the chain's links.
    pub locked_joints: Vec<String>,
}

impl ChainMeta {
    /// Default names for an n-joint chain: `robot`, `base_link`, `link1`…, `joint1`….
    pub fn numbered(n: usize) -> Self {
        Self {
            name: "robot".into(),
            base_link: "base_link".into(),
            links: (1..=n).map(|i| format!("link{i}")).collect(),
            joints: (1..=n)
                .map(|i| JointInfo::named(format!("joint{i}")))
                .collect(),
            locked_joints: Vec::new(),
        }
    }
}
