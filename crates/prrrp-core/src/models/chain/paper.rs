//! The PRRRP arm of the paper as a generic chain (Table 1 geometry, Table 2 inertia).

use super::dh::DhConvention;
use super::inertia::inertial_parameters;
use super::meta::{ChainMeta, JointLimit};
use super::serial_chain::{DynChain, SerialChain};
use crate::error::Result;
use crate::models::prrrp::robot::Robot;
use crate::motion::limits::JointLimits;

impl SerialChain<5> {
    /// The paper's robot (Tables 1–2, g = 9.81 m/s²) as a generic chain; see
    /// [`SerialChain::from_robot`].
    pub fn paper() -> Self {
        Self::from_robot_unchecked(&Robot::paper())
    }

    /// A PRRRP robot as a generic chain: standard DH from [`Robot::dh_table`], gravity
    /// (0, 0, −g), and the link parameters converted to the 10-parameter form about each
    /// link-frame origin (standard DH: frame i at the distal end of link i):
    /// - link 1 (translates only): a point mass m1 at its frame origin;
    /// - links 2–4: centre of mass on the link's x axis at lcᵢ from joint i, i.e. at
    ///   x = lcᵢ − lᵢ in frame i; inertia about the centre of mass Izz = Iyy = `inertia_zz`,
    ///   Ixx = 0 (a thin rod along x: the paper gives only Izz, and Ixx, Iyy do not act
    ///   on this planar arm);
    /// - link 5: a point mass m5 at the origin of frame 5, i.e. at the end of link 4,
    ///   moving with d5 along −z (DH α4 = 180°).
    ///
    /// # Errors
    /// [`crate::PrrrpError::InvalidParameter`] if the robot fails [`Robot::validate`].
    pub fn from_robot(robot: &Robot) -> Result<Self> {
        robot.validate()?;
        Ok(Self::from_robot_unchecked(robot))
    }

    fn from_robot_unchecked(robot: &Robot) -> Self {
        let m = robot.mass;
        let l = robot.length;
        let rod = |k: usize| {
            let i = k + 1;
            let izz = robot.inertia_zz[k];
            inertial_parameters(
                m[i],
                [robot.com[k] - l[i], 0.0, 0.0],
                [0.0, 0.0, izz, 0.0, 0.0, izz],
            )
        };
        let point = |mass: f64| inertial_parameters(mass, [0.0; 3], [0.0; 6]);
        SerialChain::from_parts_unchecked(
            robot.dh_table(),
            DhConvention::Standard,
            [point(m[0]), rod(0), rod(1), rod(2), point(m[4])],
            [0.0, 0.0, -robot.gravity],
        )
    }
}

impl DynChain {
    /// The paper's robot as a run-time chain ([`SerialChain::paper`]) whose joints carry the
    /// limits its excitation is designed within ([`JointLimits::default`]: m and rad,
    /// /s, /s²; no effort limit), so that it runs through everything that takes a robot
    /// (the command line's `--robot paper`).
    pub fn paper() -> Self {
        let l = JointLimits::default();
        let mut meta = ChainMeta::numbered(5);
        meta.name = "paper-prrrp".into();
        for (i, j) in meta.joints.iter_mut().enumerate() {
            j.limit = JointLimit {
                lower: l.q_min[i],
                upper: l.q_max[i],
                velocity: l.qd_max[i],
                acceleration: l.qdd_max[i],
                effort: f64::NAN,
            };
        }
        SerialChain::paper()
            .to_dyn()
            .with_meta(meta)
            .expect("five joints and links")
    }
}
