//! Serial chains of revolute and prismatic joints described by a DH table: a fixed-size
//! [`SerialChain<N>`] (allocation-free per sample) and a run-time-size [`DynChain`].

use faer::Mat;
use nalgebra::{DMatrix, SMatrix, SVector, Vector3};

use super::actuators::{ActuatorLayout, Actuators, ACTUATOR_PARAMETER_NAMES};
use super::crba::{cholesky_in_place, cholesky_solve};
use super::dh::DhConvention;
use super::friction::{FrictionModel, FRICTION_PARAMETER_NAMES};
use super::inertia::INERTIAL_PARAMETER_NAMES;
use super::joint::{Joint, JointGeom};
use super::meta::{ChainMeta, JointInfo};
use super::paper::ClosedBackend;
use super::regressor::StandardSink;
use super::rnea::{ChainView, LinkState};
use crate::error::{check_joints, invalid, PrrrpError, Result};
use crate::models::prrrp::robot::{DhRow, STANDARD_GRAVITY};

/// A serial manipulator with `N` joints, sized at compile time: every per-sample method
/// works on the stack and never allocates.
///
/// # Model
/// - Geometry: one [`Joint`] per joint — a placement, an axis and the link frame — built
///   from a DH table ([`SerialChain::new`], either [`DhConvention`]) or given directly
///   ([`SerialChain::from_joints`], e.g. from a URDF). Frame 0 is the world (base) frame;
///   link i carries frame i.
/// - Inertial parameters: for each link the 10-vector
///   πᵢ = [m, m·x, m·y, m·z, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (kg, kg·m, kg·m²) — Pinocchio's
///   order — with the centre of mass (x, y, z) in frame i and the inertia tensor **about
///   the origin of frame i**, in the axes of frame i. In standard DH frame i sits at the
///   distal end of link i: a centre of mass at distance lc from joint i along a link of
///   length aᵢ lies at x = lc − aᵢ. See [`super::inertial_parameters`] to convert from a
///   centre-of-mass description.
/// - Gravity: a vector in world coordinates (m/s²), default (0, 0, −9.81).
/// - Friction: optional per-actuator terms, see [`FrictionModel`] (default none).
/// - Actuators: a coupling C of the actuator velocities C·q̇ on which friction acts and an
///   optional rotor inertia (armature) per actuator, see [`Actuators`] (default: one motor
///   per joint, C = I, no armature: friction on each joint's own velocity).
///
/// The full parameter vector is π = [π₁, …, π_N, actuator terms] with
/// [`SerialChain::num_params`] = 10·N + (terms per actuator)·N entries, named by
/// [`SerialChain::parameter_names`].
///
/// ```
/// use prrrp_core::{SerialChain, DhConvention, DhRow, JointKind};
/// use prrrp_core::nalgebra::{SMatrix, SVector};
///
/// // A planar 2R arm in the vertical x–z plane (standard DH, α = 0, base x axis
/// // horizontal): gravity along −y of the base frame.
/// let row = |a| DhRow { kind: JointKind::Revolute, theta: 0.0, d: 0.0, a, alpha: 0.0 };
/// let rod = |m: f64, l: f64| prrrp_core::inertial_parameters(
///     m, [-l / 2.0, 0.0, 0.0], [0.0, 0.0, m * l * l / 12.0, 0.0, 0.0, m * l * l / 12.0]);
/// let chain = SerialChain::new([row(0.5), row(0.4)], DhConvention::Standard)?
///     .with_inertial([rod(2.0, 0.5), rod(1.0, 0.4)])?
///     .with_gravity([0.0, -9.81, 0.0])?;
/// let q = SVector::<f64, 2>::new(0.3, -0.8);
/// let qd = SVector::<f64, 2>::new(1.0, 0.5);
/// let qdd = SVector::<f64, 2>::new(-2.0, 3.0);
/// let tau = chain.inverse_dynamics(&q, &qd, &qdd);
/// // The regressor reproduces it (20 = 10·N columns).
/// let y: SMatrix<f64, 2, 20> = chain.regressor(&q, &qd, &qdd);
/// assert!((y * chain.inertial_vector::<20>() - tau).norm() < 1e-12);
/// // Forward dynamics inverts it.
/// assert!((chain.forward_dynamics(&q, &qd, &tau)? - qdd).norm() < 1e-10);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SerialChain<const N: usize> {
    joints: [Joint; N],
    dh: Option<([DhRow; N], DhConvention)>,
    geom: [JointGeom; N],
    inertial: [[f64; 10]; N],
    friction: FrictionModel,
    friction_params: [[f64; 3]; N],
    gravity: Vector3<f64>,
    /// The first link whose inertial parameters no rigid body has, cached so that the
    /// per-sample forward dynamics can refuse it with one branch.
    non_physical: Option<usize>,
    /// Actuator coupling C by rows (`None` = identity), see [`Actuators`].
    coupling: Option<[[f64; N]; N]>,
    /// Whether the armature term is on, and its values (kg·m² or kg, joint side).
    armature: bool,
    armature_values: [f64; N],
    gear_ratios: Option<[f64; N]>,
    /// The closed form while the chain is exactly the paper's arm (see `super::paper`).
    pub(super) closed: ClosedBackend,
}

/// A serial manipulator whose number of joints is known only at run time (e.g. read from
/// a file or a Python call). Same model and conventions as [`SerialChain`]; joint-space
/// inputs are slices of length n, and each call allocates O(n) scratch (the `*_into`
/// methods with a [`super::DynWorkspace`] do not). It also carries the names and limits of
/// its robot file ([`DynChain::meta`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DynChain {
    joints: Vec<Joint>,
    dh: Option<(Vec<DhRow>, DhConvention)>,
    geom: Vec<JointGeom>,
    inertial: Vec<[f64; 10]>,
    friction: FrictionModel,
    friction_params: Vec<[f64; 3]>,
    gravity: Vector3<f64>,
    meta: ChainMeta,
    /// See [`SerialChain`]'s field of the same name.
    non_physical: Option<usize>,
    /// The actuators as given (validated), and the forms the kernels read: C row-major
    /// (`None` when it is the identity) and one armature value per actuator.
    actuators: Actuators,
    coupling: Option<Vec<f64>>,
    armature_values: Vec<f64>,
    /// See [`SerialChain`]'s field of the same name.
    pub(super) closed: ClosedBackend,
}

/// Most movable joints a chain may have: 64. The longest serial chains built (snake and
/// continuum robots) have a few dozen. The base-parameter analysis grows as n⁴ (its
/// stacked regressor is 52n × 13n): measured 0.9 s at 32 joints, 8 s at 64 and 65 s at
/// 128 on one core, so longer chains from a file or a saved model are refused before any
/// work.
pub const MAX_DOF: usize = 64;

/// The error of a chain with more than [`MAX_DOF`] joints; `what` names the input.
pub(crate) fn check_dof(what: &str, n: usize) -> Result<()> {
    if n > MAX_DOF {
        return Err(PrrrpError::ShapeMismatch {
            what: what.into(),
            expected: format!("at most MAX_DOF = {MAX_DOF} joints"),
            got: format!("{n} joints"),
        });
    }
    Ok(())
}

/// The error of an empty input `what` that needs at least one `unit` (a chain has a joint).
fn check_nonempty(what: &str, len: usize, unit: &str) -> Result<()> {
    if len == 0 {
        return Err(PrrrpError::shape(
            what,
            format!("at least one {unit}"),
            format!("0 {unit}s"),
        ));
    }
    Ok(())
}

/// The error of the first non-finite entry of per-link (or per-joint) rows, named
/// `field[i][k] (name_k i+1)` after the rows' parameter `names`.
fn check_rows_finite<const K: usize>(
    field: &str,
    rows: &[[f64; K]],
    names: &[&str; K],
    reason: &'static str,
) -> Result<()> {
    for (i, row) in rows.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            if !v.is_finite() {
                let name = format!("{field}[{i}][{k}] ({}{})", names[k], i + 1);
                return Err(invalid(name, v, reason));
            }
        }
    }
    Ok(())
}

fn validate_joints(joints: &[Joint]) -> Result<()> {
    check_nonempty("joints", joints.len(), "joint")?;
    check_dof("joints", joints.len())?;
    for (i, j) in joints.iter().enumerate() {
        j.validate(&format!("joint {}", i + 1))?;
    }
    Ok(())
}

fn validate_dh(dh: &[DhRow]) -> Result<()> {
    check_nonempty("DH table", dh.len(), "row")?;
    for (i, r) in dh.iter().enumerate() {
        for (name, v) in [
            ("theta", r.theta),
            ("d", r.d),
            ("a", r.a),
            ("alpha", r.alpha),
        ] {
            if !v.is_finite() {
                return Err(invalid(
                    format!("dh[{i}].{name}"),
                    v,
                    "DH constants must be finite (m, rad)",
                ));
            }
            if matches!(name, "d" | "a") && v.abs() > crate::bounds::MAX_ROBOT_SIZE {
                return Err(invalid(
                    format!("dh[{i}].{name}"),
                    v,
                    "DH lengths must be at most MAX_ROBOT_SIZE (1e6 m) in magnitude: check \
                     the file's units (m)",
                ));
            }
        }
    }
    Ok(())
}

fn validate_inertial(p: &[[f64; 10]]) -> Result<()> {
    let reason = "inertial parameters must be finite";
    check_rows_finite("inertial", p, &INERTIAL_PARAMETER_NAMES, reason)?;
    for (i, row) in p.iter().enumerate() {
        for (k, &v) in row.iter().enumerate() {
            if v.abs() > crate::bounds::MAX_INERTIAL {
                let name = format!(
                    "inertial[{i}][{k}] ({}{})",
                    INERTIAL_PARAMETER_NAMES[k],
                    i + 1
                );
                return Err(invalid(
                    name,
                    v,
                    "inertial parameters must be at most MAX_INERTIAL (1e12 kg, kg·m, \
                     kg·m²) in magnitude: check the file's units (kg, m)",
                ));
            }
        }
    }
    Ok(())
}

fn validate_gravity(g: [f64; 3]) -> Result<Vector3<f64>> {
    for (k, &v) in g.iter().enumerate() {
        // 1e299 m/s² predicted torques near 1e300 N·m, printed as errors of inf.
        if !(v.is_finite() && v.abs() < crate::MAX_MAGNITUDE) {
            return Err(invalid(
                format!("gravity[{k}]"),
                v,
                "gravity must be finite and below MAX_MAGNITUDE (1e100) (m/s², world frame)",
            ));
        }
    }
    Ok(Vector3::from(g))
}

fn validate_friction(model: &FrictionModel, p: &[[f64; 3]]) -> Result<()> {
    // Past the factor range the term is gone (tanh(q̇/1e300) = 0) or its slope at rest,
    // fc/v_s, overflows the EKF's Jacobian: 0 asks for the exact sign instead.
    let s = model.coulomb_smoothing;
    if !(s == 0.0 || crate::bounds::is_factor(s)) {
        return Err(invalid(
            "friction.coulomb_smoothing",
            s,
            "must be 0 (exact sign) or between MIN_FACTOR (1e-6) and MAX_FACTOR (1e6) rad/s \
             or m/s",
        ));
    }
    let reason = "friction parameters must be finite";
    check_rows_finite("friction", p, &FRICTION_PARAMETER_NAMES, reason)
}

/// Relative tolerance of the chains' physical-consistency check: the accepted negative
/// eigenvalue of a link's pseudo-inertia, as a fraction of the link's largest parameter
/// magnitude (absorbs the round-off of files that list a thin rod's zero moment).
pub const PHYSICAL_TOLERANCE: f64 = 1e-9;

fn non_physical_links(inertial: &[[f64; 10]]) -> Vec<usize> {
    inertial
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            let scale = p.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
            !super::is_physically_consistent(p, PHYSICAL_TOLERANCE * scale)
        })
        .map(|(i, _)| i)
        .collect()
}

/// The typed error of a dynamics function that needs a physical robot (forward dynamics,
/// simulation): M(q) of a non-physical link is not a rigid body's, and an integrator
/// driven by it produces motion no robot makes.
pub(crate) fn non_physical_error(link: &str) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field: format!("inertial parameters of link {link}"),
        value: f64::NAN,
        reason: "are not physically consistent (negative mass, or an inertia breaking the \
                 triangle inequality); forward dynamics and simulation need a physical robot: \
                 fix the link's mass, centre of mass and inertia",
    }
}

pub(crate) fn parameter_names(n: usize, layout: &ActuatorLayout) -> Vec<String> {
    let mut names = Vec::with_capacity(n * (10 + layout.per));
    for i in 0..n {
        for s in INERTIAL_PARAMETER_NAMES {
            names.push(format!("{s}{}", i + 1));
        }
    }
    let en = layout.enabled();
    for j in 0..n {
        for k in 0..4 {
            if en[k] {
                names.push(format!("{}{}", ACTUATOR_PARAMETER_NAMES[k], j + 1));
            }
        }
    }
    names
}

fn parameter_vector(
    inertial: &[[f64; 10]],
    layout: &ActuatorLayout,
    fp: &[[f64; 3]],
    armature: &[f64],
) -> Vec<f64> {
    let mut v: Vec<f64> = inertial.iter().flatten().copied().collect();
    let en = layout.enabled();
    for (row, &ia) in fp.iter().zip(armature) {
        let terms = [row[0], row[1], row[2], ia];
        for k in 0..4 {
            if en[k] {
                v.push(terms[k]);
            }
        }
    }
    v
}

/// Stacks the full regressor (with friction) of `samples` samples into a faer matrix,
/// checking finiteness. `get(k)` returns (q, q̇, q̈) of sample k.
pub(crate) fn stack_regressor<'s>(
    view: &ChainView<'_>,
    samples: usize,
    mut get: impl FnMut(usize) -> (&'s [f64], &'s [f64], &'s [f64]),
    st: &mut [LinkState],
) -> Result<Mat<f64>> {
    let n = view.dof();
    let layout = view.layout();
    let p = n * (10 + layout.per);
    let mut w = Mat::<f64>::zeros(n * samples, p);
    for k in 0..samples {
        crate::interrupt::check("regressor stacking")?;
        let (q, qd, qdd) = get(k);
        for (name, v) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            if !v.iter().all(|x| x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: name.into(),
                    row: Some(k),
                });
            }
        }
        let mut sink = StandardSink {
            out: &mut w,
            row0: n * k,
            n,
            layout,
        };
        view.regressor_into(q, qd, qdd, true, st, &mut sink);
    }
    Ok(w)
}

/// The accessors [`SerialChain`] and [`DynChain`] share: their fields have the same names
/// and meanings and differ only in storage (arrays of N, or vectors of n), so one body
/// serves both. The arguments are the borrowed types of the per-joint fields, and the two
/// fields stored differently: whether the armature term is on, and the coupling C
/// row-major (`None` for the identity), as expressions of `self` (passed in, for macro
/// hygiene).
macro_rules! chain_accessors {
    (
        $s:ident,
        types: $joints:ty, $dh:ty, $inertial:ty, $friction_params:ty,
        armature: $armature:expr,
        coupling: $coupling:expr $(,)?
    ) => {
        /// The joints (placements, axes, link frames).
        pub fn joints(&self) -> &$joints {
            &self.joints
        }
        /// The DH table, when the chain was built from one.
        pub fn dh(&self) -> Option<&$dh> {
            self.dh
                .as_ref()
                .map(|(t, _)| std::borrow::Borrow::borrow(t))
        }
        /// The DH convention, when the chain was built from a DH table.
        pub fn convention(&self) -> Option<DhConvention> {
            self.dh.as_ref().map(|(_, c)| *c)
        }
        /// Inertial parameters of each link.
        pub fn inertial(&self) -> &$inertial {
            &self.inertial
        }
        /// Gravity vector in world coordinates, m/s².
        pub fn gravity(&self) -> [f64; 3] {
            self.gravity.into()
        }
        /// The friction model.
        pub fn friction(&self) -> FrictionModel {
            self.friction
        }
        /// Friction parameters [fv, fc, fo] of each joint.
        pub fn friction_params(&self) -> &$friction_params {
            &self.friction_params
        }
        /// Number of standard parameters: 10 inertial per link plus the enabled actuator
        /// terms (friction and armature) of each actuator.
        pub fn num_params(&self) -> usize {
            self.dof() * (10 + self.layout().per)
        }
        /// Names of the standard parameters in order, e.g. `m1, mx1, …, Izz6, fv1, fc1, …`.
        pub fn parameter_names(&self) -> Vec<String> {
            parameter_names(self.dof(), &self.layout())
        }
        /// The standard parameter vector π (inertial, then enabled actuator terms).
        pub fn parameters(&self) -> Vec<f64> {
            parameter_vector(
                &self.inertial,
                &self.layout(),
                &self.friction_params,
                &self.armature_values,
            )
        }

        /// Indices (0-based) of the links whose inertial parameters no rigid body has: a
        /// pseudo-inertia that is not positive semidefinite (see
        /// [`super::is_physically_consistent`]; tolerance [`PHYSICAL_TOLERANCE`] relative
        /// to the link's largest parameter).
        pub fn non_physical_links(&self) -> Vec<usize> {
            non_physical_links(&self.inertial)
        }

        /// True when every link's inertial parameters describe a rigid body
        /// ([`Self::non_physical_links`] is empty).
        pub fn is_physically_consistent(&self) -> bool {
            self.non_physical.is_none()
        }

        /// Sets the gravity vector in world (base-frame) coordinates, m/s².
        ///
        /// # Errors
        /// [`PrrrpError::InvalidParameter`] for a non-finite entry.
        pub fn with_gravity(mut self, gravity: [f64; 3]) -> Result<Self> {
            self.gravity = validate_gravity(gravity)?;
            self.closed = ClosedBackend::default();
            Ok(self)
        }

        pub(crate) fn layout(&$s) -> ActuatorLayout {
            ActuatorLayout::new(&$s.friction, $armature)
        }

        /// The kernels' view of the chain (borrowed, whatever its storage).
        pub(crate) fn view(&$s) -> ChainView<'_> {
            ChainView {
                geom: &$s.geom,
                inertial: &$s.inertial,
                friction_params: &$s.friction_params,
                friction: $s.friction,
                gravity: $s.gravity,
                coupling: $coupling,
                armature: $armature.then_some(&$s.armature_values[..]),
                closed: $s.closed.0,
            }
        }
    };
}

impl<const N: usize> SerialChain<N> {
    chain_accessors!(
        self,
        types: [Joint; N], [DhRow; N], [[f64; 10]; N], [[f64; 3]; N],
        armature: self.armature,
        coupling: self.coupling.as_ref().map(|c| c.as_flattened()),
    );

    /// A chain with the given DH table and convention, massless links, no friction and
    /// gravity (0, 0, −9.81) m/s².
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if N = 0, [`PrrrpError::InvalidParameter`] for a
    /// non-finite DH constant.
    pub fn new(dh: [DhRow; N], convention: DhConvention) -> Result<Self> {
        validate_dh(&dh)?;
        let mut c = Self::from_joints(dh.map(|r| Joint::from_dh(&r, convention)))?;
        c.dh = Some((dh, convention));
        Ok(c)
    }

    /// A chain of general joints (see [`Joint`]), massless links, no friction and gravity
    /// (0, 0, −9.81) m/s².
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if N = 0, [`PrrrpError::InvalidParameter`] for a
    /// non-finite placement or an axis that is not a unit vector.
    pub fn from_joints(joints: [Joint; N]) -> Result<Self> {
        validate_joints(&joints)?;
        Ok(Self {
            joints,
            dh: None,
            geom: joints.map(|j| JointGeom::new(&j)),
            inertial: [[0.0; 10]; N],
            friction: FrictionModel::default(),
            friction_params: [[0.0; 3]; N],
            gravity: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
            non_physical: None,
            coupling: None,
            armature: false,
            armature_values: [0.0; N],
            gear_ratios: None,
            closed: ClosedBackend::default(),
        })
    }

    pub(crate) fn from_parts_unchecked(
        dh: [DhRow; N],
        convention: DhConvention,
        inertial: [[f64; 10]; N],
        gravity: [f64; 3],
    ) -> Self {
        let joints = dh.map(|r| Joint::from_dh(&r, convention));
        Self {
            joints,
            dh: Some((dh, convention)),
            geom: joints.map(|j| JointGeom::new(&j)),
            inertial,
            friction: FrictionModel::default(),
            friction_params: [[0.0; 3]; N],
            gravity: Vector3::from(gravity),
            non_physical: non_physical_links(&inertial).first().copied(),
            coupling: None,
            armature: false,
            armature_values: [0.0; N],
            gear_ratios: None,
            closed: ClosedBackend::default(),
        }
    }

    /// Sets the inertial parameters of every link (see the type docs for the frame).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-finite entry or one above
    /// [`crate::bounds::MAX_INERTIAL`] in magnitude. Parameters no rigid body
    /// has (a negative mass, an inertia breaking the triangle inequality) are accepted, as
    /// a robot file's inertials are only a prior: see
    /// [`SerialChain::non_physical_links`].
    pub fn with_inertial(mut self, inertial: [[f64; 10]; N]) -> Result<Self> {
        validate_inertial(&inertial)?;
        self.closed = ClosedBackend::default();
        self.non_physical = non_physical_links(&inertial).first().copied();
        self.inertial = inertial;
        Ok(self)
    }

    /// Sets the friction model and each joint's [fv, fc, fo] (disabled terms are kept but
    /// ignored).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-finite value or a negative smoothing.
    pub fn with_friction(mut self, model: FrictionModel, params: [[f64; 3]; N]) -> Result<Self> {
        validate_friction(&model, &params)?;
        self.friction = model;
        self.friction_params = params;
        Ok(self)
    }

    /// Sets the actuators: coupling, armature, gear ratios (see [`Actuators`]). Friction
    /// then acts on the actuator velocities C·q̇, one [fv, fc, fo] row per actuator.
    ///
    /// # Errors
    /// As [`Actuators::validate`] with n = N.
    pub fn with_actuators(mut self, actuators: &Actuators) -> Result<Self> {
        actuators.validate(N)?;
        self.coupling = match &actuators.coupling {
            Some(rows) if !is_identity_rows(rows) => {
                Some(std::array::from_fn(|m| std::array::from_fn(|j| rows[m][j])))
            }
            _ => None,
        };
        self.armature = actuators.armature;
        self.armature_values = match &actuators.armature_values {
            Some(v) => std::array::from_fn(|m| v[m]),
            None => [0.0; N],
        };
        self.gear_ratios = actuators
            .gear_ratios
            .as_ref()
            .map(|r| std::array::from_fn(|m| r[m]));
        // Gear ratios alone leave the dynamics the arm's; a coupling or an armature not.
        if self.coupling.is_some() || self.armature {
            self.closed = ClosedBackend::default();
        }
        Ok(self)
    }

    /// The actuators (see [`Actuators`]).
    pub fn actuators(&self) -> Actuators {
        Actuators {
            coupling: self
                .coupling
                .map(|c| c.iter().map(|r| r.to_vec()).collect()),
            armature: self.armature,
            armature_values: (self.armature || self.armature_values.iter().any(|&x| x != 0.0))
                .then(|| self.armature_values.to_vec()),
            gear_ratios: self.gear_ratios.map(|r| r.to_vec()),
        }
    }
    /// Number of joints.
    pub const fn dof(&self) -> usize {
        N
    }

    /// `Ok` if every link is physical, else the typed error functions that need a physical
    /// robot (forward dynamics, simulation) return, naming the first bad link.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the link.
    pub fn require_physical(&self) -> Result<()> {
        match self.non_physical {
            None => Ok(()),
            Some(i) => Err(non_physical_error(&(i + 1).to_string())),
        }
    }

    /// The 10·N inertial parameters as one vector, matching [`SerialChain::regressor`].
    /// P must equal 10·N (checked at compile time).
    pub fn inertial_vector<const P: usize>(&self) -> SVector<f64, P> {
        const { assert!(P == 10 * N, "P must equal 10·N") };
        SVector::from_iterator(self.inertial.iter().flatten().copied())
    }

    /// Inverse dynamics τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q) + Cᵀ·(diag(Ia)·C·q̈ + f(C·q̇)) by
    /// recursive Newton–Euler plus the actuator terms of [`Actuators`] (N or N·m per
    /// joint; with the default actuators the last term is the joint friction).
    #[inline]
    pub fn inverse_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SVector<f64, N> {
        let mut st = [LinkState::default(); N];
        let mut tau = SVector::<f64, N>::zeros();
        self.view().rnea(
            q.as_slice(),
            qd.as_slice(),
            qdd.as_slice(),
            &mut st,
            tau.as_mut_slice(),
        );
        tau
    }

    /// Nonlinear effects C(q, q̇)·q̇ + G(q) + τ_friction(q̇): the torque at q̈ = 0.
    #[inline]
    pub fn nonlinear_effects(&self, q: &SVector<f64, N>, qd: &SVector<f64, N>) -> SVector<f64, N> {
        self.inverse_dynamics(q, qd, &SVector::zeros())
    }

    /// Gravity torques G(q) (N, N·m).
    #[inline]
    pub fn gravity_torques(&self, q: &SVector<f64, N>) -> SVector<f64, N> {
        let z = SVector::<f64, N>::zeros();
        let mut st = [LinkState::default(); N];
        let mut tau = SVector::<f64, N>::zeros();
        let view = self.view().rigid();
        view.rnea(
            q.as_slice(),
            z.as_slice(),
            z.as_slice(),
            &mut st,
            tau.as_mut_slice(),
        );
        tau
    }

    /// Joint-space mass matrix M(q) by the composite-rigid-body algorithm (kg, kg·m,
    /// kg·m² by joint kinds), plus the armature's Cᵀ·diag(Ia)·C when it is on.
    #[inline]
    pub fn mass_matrix(&self, q: &SVector<f64, N>) -> SMatrix<f64, N, N> {
        let mut st = [LinkState::default(); N];
        let mut comp = [[0.0; 10]; N];
        let mut m = SMatrix::<f64, N, N>::zeros();
        self.view().mass_matrix_with(
            &self.inertial,
            q.as_slice(),
            &mut st,
            &mut comp,
            m.as_mut_slice(),
        );
        m
    }

    /// Forward dynamics q̈ = M⁻¹·(τ − C·q̇ − G − τ_friction) via a Cholesky factorisation of M.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the link if a link is not physical
    /// ([`SerialChain::non_physical_links`]); [`PrrrpError::NotPositiveDefinite`] if M(q)
    /// is singular (e.g. a massless end of the chain).
    #[inline]
    pub fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
    ) -> Result<SVector<f64, N>> {
        self.require_physical()?;
        let mut m = self.mass_matrix(q);
        cholesky_in_place(m.as_mut_slice(), N)?;
        let mut x = tau - self.nonlinear_effects(q, qd);
        cholesky_solve(m.as_slice(), N, x.as_mut_slice());
        Ok(x)
    }

    /// Friction forces of the enabled terms reflected to the joints, Cᵀ·f(C·q̇) (N, N·m;
    /// with the default actuators each joint's own friction).
    #[inline]
    pub fn friction_torque(&self, qd: &SVector<f64, N>) -> SVector<f64, N> {
        let mut tau = SVector::<f64, N>::zeros();
        let zero = SVector::<f64, N>::zeros();
        let mut view = self.view();
        view.armature = None;
        view.add_actuator_torques(
            &self.friction_params,
            qd.as_slice(),
            zero.as_slice(),
            tau.as_mut_slice(),
        );
        tau
    }

    /// Standard rigid-body regressor Y(q, q̇, q̈) ∈ R^{N×P}, P = 10·N (checked at compile
    /// time): τ − τ_friction = Y·π with π = [`SerialChain::inertial_vector`]. Column
    /// 10·i + k belongs to parameter k of link i+1 in the order
    /// [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz].
    #[inline]
    pub fn regressor<const P: usize>(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SMatrix<f64, N, P> {
        const { assert!(P == 10 * N, "P must equal 10·N") };
        let mut y = SMatrix::<f64, N, P>::zeros();
        let (q, qd, qdd) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
        self.view()
            .column_major_regressor_into::<N>(q, qd, qdd, false, y.as_mut_slice());
        y
    }

    /// The full regressor, actuator columns included, written column-major (N rows,
    /// [`SerialChain::num_params`] columns) into `out`: τ = Y_full·π with
    /// π = [`SerialChain::parameters`]. Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `out.len()` ≠ N·num_params.
    pub fn regressor_full_into(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        out: &mut [f64],
    ) -> Result<()> {
        check_joints(
            "regressor output (column-major N × num_params)",
            out.len(),
            N * self.num_params(),
        )?;
        out.fill(0.0);
        let (q, qd, qdd) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
        self.view()
            .column_major_regressor_into::<N>(q, qd, qdd, true, out);
        Ok(())
    }

    /// The full regressor (friction included) of many samples stacked into
    /// W ∈ R^{(N·samples)×num_params}: rows N·k .. N·k+N hold sample k.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if the slices differ in length,
    /// [`PrrrpError::NonFinite`] naming the first bad sample.
    pub fn observation_matrix(
        &self,
        q: &[SVector<f64, N>],
        qd: &[SVector<f64, N>],
        qdd: &[SVector<f64, N>],
    ) -> Result<Mat<f64>> {
        crate::models::prrrp::regressor::check_lengths(
            q.len(),
            &[("qd", qd.len()), ("qdd", qdd.len())],
        )?;
        let mut st = [LinkState::default(); N];
        stack_regressor(
            &self.view(),
            q.len(),
            |k| (q[k].as_slice(), qd[k].as_slice(), qdd[k].as_slice()),
            &mut st,
        )
    }

    /// The same chain with a run-time size.
    pub fn to_dyn(&self) -> DynChain {
        DynChain {
            joints: self.joints.to_vec(),
            dh: self.dh.map(|(t, c)| (t.to_vec(), c)),
            geom: self.geom.to_vec(),
            inertial: self.inertial.to_vec(),
            friction: self.friction,
            friction_params: self.friction_params.to_vec(),
            gravity: self.gravity,
            meta: ChainMeta::numbered(N),
            non_physical: self.non_physical,
            actuators: self.actuators(),
            coupling: self.coupling.map(|c| c.as_flattened().to_vec()),
            armature_values: self.armature_values.to_vec(),
            closed: self.closed,
        }
    }
}

impl DynChain {
    chain_accessors!(
        self,
        types: [Joint], [DhRow], [[f64; 10]], [[f64; 3]],
        armature: self.actuators.armature,
        coupling: self.coupling.as_deref(),
    );

    /// A chain with the given DH table and convention, massless links, no friction and
    /// gravity (0, 0, −9.81) m/s².
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for an empty table, [`PrrrpError::InvalidParameter`]
    /// for a non-finite DH constant.
    pub fn new(dh: Vec<DhRow>, convention: DhConvention) -> Result<Self> {
        validate_dh(&dh)?;
        let mut c = Self::from_joints(dh.iter().map(|r| Joint::from_dh(r, convention)).collect())?;
        c.dh = Some((dh, convention));
        Ok(c)
    }

    /// A chain of general joints (see [`Joint`]), massless links, no friction, gravity
    /// (0, 0, −9.81) m/s² and numbered names ([`ChainMeta::numbered`]).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for no joints, [`PrrrpError::InvalidParameter`] for a
    /// non-finite placement or an axis that is not a unit vector.
    pub fn from_joints(joints: Vec<Joint>) -> Result<Self> {
        validate_joints(&joints)?;
        let n = joints.len();
        Ok(Self {
            geom: joints.iter().map(JointGeom::new).collect(),
            joints,
            dh: None,
            inertial: vec![[0.0; 10]; n],
            friction: FrictionModel::default(),
            friction_params: vec![[0.0; 3]; n],
            gravity: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
            meta: ChainMeta::numbered(n),
            non_physical: None,
            actuators: Actuators::default(),
            coupling: None,
            armature_values: vec![0.0; n],
            closed: ClosedBackend::default(),
        })
    }

    /// Sets the names and limits (one [`JointInfo`] and one link name per joint).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `meta` does not name every joint and link.
    pub fn with_meta(mut self, meta: ChainMeta) -> Result<Self> {
        check_joints("meta.joints", meta.joints.len(), self.dof())?;
        check_joints("meta.links", meta.links.len(), self.dof())?;
        self.meta = meta;
        Ok(self)
    }

    /// Names and limits of the chain and its joints.
    pub fn meta(&self) -> &ChainMeta {
        &self.meta
    }

    /// Joint names, base to tip.
    pub fn joint_names(&self) -> Vec<&str> {
        self.meta.joints.iter().map(|j| j.name.as_str()).collect()
    }

    /// Each joint's name, limits and file figures.
    pub fn joint_info(&self) -> &[JointInfo] {
        &self.meta.joints
    }

    /// Sets the inertial parameters of every link (one 10-vector per joint).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a wrong count, [`PrrrpError::InvalidParameter`]
    /// for a non-finite entry or one above [`crate::bounds::MAX_INERTIAL`] in magnitude.
    /// Non-physical parameters are accepted: see
    /// [`DynChain::non_physical_links`].
    pub fn with_inertial(mut self, inertial: Vec<[f64; 10]>) -> Result<Self> {
        check_joints("inertial", inertial.len(), self.dof())?;
        validate_inertial(&inertial)?;
        self.closed = ClosedBackend::default();
        self.non_physical = non_physical_links(&inertial).first().copied();
        self.inertial = inertial;
        Ok(self)
    }

    /// Sets the friction model and each joint's [fv, fc, fo].
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a wrong count, [`PrrrpError::InvalidParameter`]
    /// for a non-finite value or a negative smoothing.
    pub fn with_friction(mut self, model: FrictionModel, params: Vec<[f64; 3]>) -> Result<Self> {
        check_joints("friction params", params.len(), self.dof())?;
        validate_friction(&model, &params)?;
        self.friction = model;
        self.friction_params = params;
        Ok(self)
    }

    /// Sets the actuators: coupling, armature, gear ratios (see [`Actuators`]). Friction
    /// then acts on the actuator velocities C·q̇, one [fv, fc, fo] row per actuator.
    ///
    /// # Errors
    /// As [`Actuators::validate`] with n = [`DynChain::dof`].
    pub fn with_actuators(mut self, actuators: Actuators) -> Result<Self> {
        let n = self.dof();
        actuators.validate(n)?;
        self.coupling = match &actuators.coupling {
            Some(rows) if !is_identity_rows(rows) => Some(actuators.coupling_row_major(n)),
            _ => None,
        };
        self.armature_values = actuators
            .armature_values
            .clone()
            .unwrap_or_else(|| vec![0.0; n]);
        self.actuators = actuators;
        // Gear ratios alone leave the dynamics the arm's; a coupling or an armature not.
        if self.coupling.is_some() || self.actuators.armature {
            self.closed = ClosedBackend::default();
        }
        Ok(self)
    }

    /// The actuators (see [`Actuators`]).
    pub fn actuators(&self) -> &Actuators {
        &self.actuators
    }

    /// The armature values Iaₘ in use (one per actuator; kg·m² or kg, joint side), zeros
    /// when none are given.
    pub fn armature_values(&self) -> &[f64] {
        &self.armature_values
    }

    /// The same chain with a compile-time size.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if the chain does not have N joints.
    pub fn to_fixed<const N: usize>(&self) -> Result<SerialChain<N>> {
        check_joints("chain joints", self.dof(), N)?;
        let mut c = SerialChain::<N>::from_joints(std::array::from_fn(|i| self.joints[i]))?;
        c.dh = self
            .dh
            .as_ref()
            .map(|(t, conv)| (std::array::from_fn(|i| t[i]), *conv));
        c.inertial = std::array::from_fn(|i| self.inertial[i]);
        c.non_physical = self.non_physical;
        c.friction = self.friction;
        c.friction_params = std::array::from_fn(|i| self.friction_params[i]);
        c.gravity = self.gravity;
        c.closed = self.closed;
        c.with_actuators(&self.actuators)
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// `Ok` if every link is physical, else the typed error functions that need a physical
    /// robot (forward dynamics, simulation) return, naming the first bad link.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the link.
    pub fn require_physical(&self) -> Result<()> {
        match self.non_physical {
            None => Ok(()),
            Some(i) => Err(non_physical_error(&format!(
                "'{}' (link {})",
                self.meta.links[i],
                i + 1
            ))),
        }
    }

    /// Lengths, then values: NaN, ∞ or values past [`crate::MAX_MAGNITUDE`] gave `Ok`
    /// with NaN torques. `names` are the three inputs' names (the third is q̈ or τ).
    fn check3_named(&self, names: [&str; 3], q: &[f64], qd: &[f64], third: &[f64]) -> Result<()> {
        let n = self.dof();
        for (what, v) in names.into_iter().zip([q, qd, third]) {
            check_joints(what, v.len(), n)?;
        }
        for (what, v) in names.into_iter().zip([q, qd, third]) {
            crate::bounds::check_sample(what, v)?;
        }
        Ok(())
    }

    fn check3(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<()> {
        self.check3_named(["q", "qd", "qdd"], q, qd, qdd)
    }

    /// Inverse dynamics τ (actuator terms included, see [`SerialChain::inverse_dynamics`])
    /// by recursive Newton–Euler.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if an input does not have n entries,
    /// [`PrrrpError::NonFinite`] for a NaN or infinite entry,
    /// [`PrrrpError::InvalidParameter`] for one at or above [`crate::MAX_MAGNITUDE`].
    pub fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Vec<f64>> {
        self.check3(q, qd, qdd)?;
        let mut st = vec![LinkState::default(); self.dof()];
        let mut tau = vec![0.0; self.dof()];
        self.view().rnea(q, qd, qdd, &mut st, &mut tau);
        Ok(tau)
    }

    /// Mass matrix M(q) (n×n) by the composite-rigid-body algorithm.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `q` does not have n entries,
    /// [`PrrrpError::NonFinite`] / [`PrrrpError::InvalidParameter`] for an entry that is
    /// NaN, infinite or at or above [`crate::MAX_MAGNITUDE`].
    pub fn mass_matrix(&self, q: &[f64]) -> Result<DMatrix<f64>> {
        let n = self.dof();
        check_joints("q", q.len(), n)?;
        crate::bounds::check_sample("q", q)?;
        let mut st = vec![LinkState::default(); n];
        let mut comp = vec![[0.0; 10]; n];
        let mut m = DMatrix::zeros(n, n);
        self.view()
            .mass_matrix_with(&self.inertial, q, &mut st, &mut comp, m.as_mut_slice());
        Ok(m)
    }

    /// Forward dynamics q̈ = M⁻¹·(τ − C·q̇ − G − τ_friction).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for wrong lengths, [`PrrrpError::NonFinite`] /
    /// [`PrrrpError::InvalidParameter`] for an input entry that is NaN, infinite or at or
    /// above [`crate::MAX_MAGNITUDE`], [`PrrrpError::InvalidParameter`] naming the link if
    /// a link is not physical ([`DynChain::non_physical_links`]),
    /// [`PrrrpError::NotPositiveDefinite`] if M(q) is singular.
    pub fn forward_dynamics(&self, q: &[f64], qd: &[f64], tau: &[f64]) -> Result<Vec<f64>> {
        self.check3_named(["q", "qd", "tau"], q, qd, tau)?;
        self.require_physical()?;
        let n = self.dof();
        let mut m = self.mass_matrix(q)?;
        cholesky_in_place(m.as_mut_slice(), n)?;
        let zero = vec![0.0; n];
        let bias = self.inverse_dynamics(q, qd, &zero)?;
        let mut x: Vec<f64> = tau.iter().zip(&bias).map(|(t, b)| t - b).collect();
        cholesky_solve(m.as_slice(), n, &mut x);
        Ok(x)
    }

    /// The full regressor (n × num_params, friction columns included): τ = Y·π with
    /// π = [`DynChain::parameters`].
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics`].
    pub fn regressor(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<DMatrix<f64>> {
        self.check3(q, qd, qdd)?;
        let n = self.dof();
        let mut y = DMatrix::zeros(n, self.num_params());
        let mut st = vec![LinkState::default(); n];
        let mut sink = StandardSink {
            out: &mut y,
            row0: 0,
            n,
            layout: self.layout(),
        };
        self.view()
            .regressor_into(q, qd, qdd, true, &mut st, &mut sink);
        Ok(y)
    }

    /// The full regressor of many samples stacked into W ∈ R^{(n·samples)×num_params}.
    /// Inputs are flat, row-major (samples × n) slices, as numpy arrays are.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if a slice length is not a multiple of n or the three
    /// differ, [`PrrrpError::NonFinite`] naming the first bad sample.
    pub fn observation_matrix(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Mat<f64>> {
        let n = self.dof();
        let samples = flat_samples(n, q, qd, qdd)?;
        let mut st = vec![LinkState::default(); n];
        stack_regressor(
            &self.view(),
            samples,
            |k| {
                let r = n * k..n * k + n;
                (&q[r.clone()], &qd[r.clone()], &qdd[r])
            },
            &mut st,
        )
    }
}

/// Number of samples in three flat row-major (samples × n) arrays.
pub(crate) fn flat_samples(n: usize, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<usize> {
    if q.len() % n != 0 {
        return Err(PrrrpError::ShapeMismatch {
            what: "q (flat samples × n)".into(),
            expected: format!("a multiple of n = {n}"),
            got: format!("{} values", q.len()),
        });
    }
    crate::models::prrrp::regressor::check_lengths(
        q.len(),
        &[("qd", qd.len()), ("qdd", qdd.len())],
    )?;
    Ok(q.len() / n)
}

impl<const N: usize> From<&SerialChain<N>> for DynChain {
    fn from(c: &SerialChain<N>) -> Self {
        c.to_dyn()
    }
}

fn is_identity_rows(rows: &[Vec<f64>]) -> bool {
    rows.iter().enumerate().all(|(i, r)| {
        r.iter()
            .enumerate()
            .all(|(j, &x)| x == if i == j { 1.0 } else { 0.0 })
    })
}

#[cfg(test)]
mod input_tests {
    use crate::{BaseOptions, PrrrpError};

    /// NaN, ∞ and values past MAX_MAGNITUDE are refused by the per-sample calls (they
    /// returned `Ok` with NaN: a NaN q, or q̇ = 1e200 whose square overflows), naming the
    /// input and joint.
    #[test]
    fn per_sample_dynamics_refuse_non_finite_and_huge_inputs() {
        let chain = crate::test_support::puma(false);
        let ok = [0.1; 6];
        let mut nan = ok;
        nan[3] = f64::NAN;
        let mut huge = ok;
        huge[3] = 1e200;
        let non_finite = |r: Result<(), PrrrpError>, what: &str| {
            assert!(
                matches!(&r, Err(PrrrpError::NonFinite { what: w, .. }) if w == what),
                "{what}: {r:?}"
            );
        };
        let too_large = |r: Result<(), PrrrpError>, what: &str| {
            assert!(
                matches!(&r, Err(PrrrpError::InvalidParameter { field, .. }) if field == what),
                "{what}: {r:?}"
            );
        };
        non_finite(chain.inverse_dynamics(&nan, &ok, &ok).map(drop), "q[3]");
        too_large(chain.inverse_dynamics(&ok, &huge, &ok).map(drop), "qd[3]");
        non_finite(chain.inverse_dynamics(&ok, &ok, &nan).map(drop), "qdd[3]");
        non_finite(chain.forward_dynamics(&ok, &ok, &nan).map(drop), "tau[3]");
        too_large(chain.forward_dynamics(&huge, &ok, &ok).map(drop), "q[3]");
        non_finite(chain.mass_matrix(&nan).map(drop), "q[3]");
        too_large(chain.mass_matrix(&huge).map(drop), "q[3]");
        non_finite(chain.regressor(&nan, &ok, &ok).map(drop), "q[3]");
        too_large(chain.regressor(&ok, &ok, &huge).map(drop), "qdd[3]");
        // Valid inputs still give finite results.
        let tau = chain.inverse_dynamics(&ok, &ok, &ok).unwrap();
        assert!(tau.iter().all(|t| t.is_finite()));
        let qdd = chain.forward_dynamics(&ok, &ok, &tau).unwrap();
        assert!(qdd.iter().all(|x| (x - 0.1).abs() < 1e-8), "{qdd:?}");
    }

    /// A NaN β (or anchor) is refused: it spread through the solve into every standard
    /// value, returned as `Ok`.
    #[test]
    fn standard_from_base_refuses_nan() {
        let chain = crate::test_support::puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let pi = chain.parameters();
        let mut beta = base.base_values(&pi).unwrap();
        assert!(crate::standard_from_base(&base, &beta, &pi).is_ok());
        beta[1] = f64::NAN;
        let err = crate::standard_from_base(&base, &beta, &pi);
        assert!(matches!(err, Err(PrrrpError::NonFinite { .. })), "{err:?}");
        beta[1] = 0.0;
        let mut anchor = pi.clone();
        anchor[0] = f64::INFINITY;
        let err = crate::standard_from_base(&base, &beta, &anchor);
        assert!(matches!(err, Err(PrrrpError::NonFinite { .. })), "{err:?}");
    }
}
