//! The drives of a chain: actuators geared to the joints, possibly coupled (a wrist motor
//! that turns with two joints), each with a reflected rotor inertia (armature) and friction
//! on its own velocity.
//!
//! With actuator velocities q̇ₘ = C·q̇ (C invertible, the identity by default) the joint
//! forces are, by virtual work,
//!
//! τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q) + Cᵀ·(diag(Ia)·C·q̈ + f(C·q̇)),
//!
//! one definition that the regressor, base parameters, dynamics, simulation, estimators and
//! the identified model all use through the chain. The armature, when enabled
//! ([`Actuators::armature`]), adds one linear parameter per actuator after its friction
//! terms (fv, fc, fo, Ia). Gear ratios do not enter the dynamics; they only map motor-side
//! measurements to the joint side ([`Actuators::joint_torques_from_motor`]).
//!
//! Design: docs/design/actuators.md.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::error::{invalid, PrrrpError, Result};

/// Names of the per-actuator parameters in their order (viscous, Coulomb, offset,
/// armature); the chain appends the 1-based actuator number (e.g. `Ia6`).
pub const ACTUATOR_PARAMETER_NAMES: [&str; 4] = ["fv", "fc", "fo", "Ia"];

/// Smallest accepted ratio of the smallest to the largest singular value of a coupling
/// matrix: below it C is treated as singular (q̇ₘ = C·q̇ would not determine q̇).
pub const COUPLING_CONDITION_LIMIT: f64 = 1e-10;

/// The actuators of a chain (see the module docs for the model). `Default`: one motor per
/// joint (C = I), no armature, no gear ratios — the rigid chain with joint friction.
///
/// Set on a chain with [`super::DynChain::with_actuators`] (or
/// [`super::SerialChain::with_actuators`]), which checks it against the joint count: C
/// square n×n, finite and invertible; armature values finite, ≥ 0 and one per actuator;
/// gear ratios finite, non-zero and one per actuator.
///
/// ```
/// use prrrp_core::{Actuators, SerialChain};
/// // A PUMA 560 whose sixth motor turns with q̇5 + q̇6, with rotor inertias.
/// let mut c = vec![vec![0.0; 6]; 6];
/// for i in 0..6 { c[i][i] = 1.0; }
/// c[5][4] = 1.0;
/// let act = Actuators {
///     coupling: Some(c),
///     armature: true,
///     armature_values: Some(vec![1.1, 1.8, 0.6, 0.05, 0.04, 0.03]),
///     gear_ratios: None,
/// };
/// let chain = SerialChain::puma560().to_dyn().with_actuators(act)?;
/// assert_eq!(chain.num_params(), 60 + 6);           // one Ia per actuator
/// let m = chain.mass_matrix(&[0.1; 6])?;
/// let m0 = SerialChain::puma560().to_dyn().mass_matrix(&[0.1; 6])?;
/// // Cᵀ·diag(Ia)·C: the sixth armature couples joints 5 and 6.
/// assert!((m[(4, 5)] - m0[(4, 5)] - 0.03).abs() < 1e-12);
/// assert!((m[(4, 4)] - m0[(4, 4)] - 0.07).abs() < 1e-12);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Actuators {
    /// The coupling matrix C as n rows of n entries: actuator m's joint-side velocity is
    /// Σⱼ `C[m][j]`·q̇ⱼ (dimensionless for rotary joints). `None` = the identity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling: Option<Vec<Vec<f64>>>,
    /// Whether each actuator has a rotor-inertia (armature) term Iaₘ·q̈ₘ, identified as one
    /// linear parameter per actuator. Default `false`.
    #[serde(default)]
    pub armature: bool,
    /// The armature values Iaₘ (kg·m², or kg for a prismatic joint; joint side), one per
    /// actuator: the dynamics' values when [`Actuators::armature`] is on (a prior for
    /// identification, the truth for simulation). `None` = zeros. Ignored (and refused by
    /// the robot files) without `armature`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub armature_values: Option<Vec<f64>>,
    /// Gear ratios rₘ = motor angle / joint-side actuator angle (dimensionless, non-zero),
    /// used only to map motor-side measurements to the joint side. `None` = not known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gear_ratios: Option<Vec<f64>>,
}

fn check_count(what: &str, len: usize, n: usize) -> Result<()> {
    if len == n {
        return Ok(());
    }
    let note = format!(" (one per actuator: the chain has {n} joints)");
    crate::error::check_len(what, len, n, "entries", &note)
}

impl Actuators {
    /// True when this is the default: C = I, no armature, no gear ratios.
    pub fn is_default(&self) -> bool {
        self.is_default_coupling() && !self.armature && self.gear_ratios.is_none()
    }

    /// True when the coupling is the identity (given as such or not at all).
    pub fn is_default_coupling(&self) -> bool {
        match &self.coupling {
            None => true,
            Some(c) => is_identity(c),
        }
    }

    /// Checks the actuators against a chain of `n` joints (see the type docs).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a coupling that is not n×n or a list without one
    /// entry per actuator; [`PrrrpError::InvalidParameter`] for a non-finite entry, a
    /// singular coupling (the error gives cond(C)), an armature outside
    /// [0, [`crate::bounds::MAX_INERTIAL`]] or a gear ratio outside ±[[`crate::bounds::MIN_FACTOR`],
    /// [`crate::bounds::MAX_FACTOR`]].
    pub fn validate(&self, n: usize) -> Result<()> {
        if let Some(c) = &self.coupling {
            coupling_matrix(c, n)?;
        }
        if let Some(v) = &self.armature_values {
            check_count("actuators.armature_values", v.len(), n)?;
            for (m, &x) in v.iter().enumerate() {
                // 1e200 was taken, and `prrrp simulate` wrote torques of 1e201 N·m.
                if !(x.is_finite() && (0.0..=crate::bounds::MAX_INERTIAL).contains(&x)) {
                    return Err(invalid(
                        format!("actuators.armature_values[{m}]"),
                        x,
                        "a reflected rotor inertia must be between 0 and MAX_INERTIAL (1e12) \
                         (kg·m², joint side)",
                    ));
                }
            }
        }
        if let Some(r) = &self.gear_ratios {
            check_count("actuators.gear_ratios", r.len(), n)?;
            for (m, &x) in r.iter().enumerate() {
                if !crate::bounds::is_factor(x.abs()) {
                    return Err(invalid(
                        format!("actuators.gear_ratios[{m}]"),
                        x,
                        "a gear ratio (motor angle per joint-side angle) must be between \
                         MIN_FACTOR (1e-6) and MAX_FACTOR (1e6) in magnitude (negative for a \
                         reversed motor)",
                    ));
                }
            }
        }
        Ok(())
    }

    /// C as a row-major n·n vector (the identity when no coupling is given).
    pub fn coupling_row_major(&self, n: usize) -> Vec<f64> {
        match &self.coupling {
            Some(rows) => rows.iter().flatten().copied().collect(),
            None => identity(n),
        }
    }

    /// Joint positions (rad or m) from motor angles θ (rad, motor side): q = C⁻¹·(θ/r),
    /// per sample of a flat row-major (samples × n) array. Needs the gear ratios.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] without gear ratios; as [`Actuators::validate`];
    /// [`PrrrpError::ShapeMismatch`] if the length is not a multiple of n.
    pub fn joint_positions_from_motor(&self, n: usize, theta: &[f64]) -> Result<Vec<f64>> {
        self.validate(n)?;
        let r = self.ratios("motor-side positions")?;
        let c = DMatrix::from_row_slice(n, n, &self.coupling_row_major(n));
        let lu = c.lu();
        samples_of(n, theta.len(), "motor-side positions")?;
        let mut out = Vec::with_capacity(theta.len());
        for row in theta.chunks_exact(n) {
            let b = nalgebra::DVector::from_iterator(n, row.iter().zip(r).map(|(t, r)| t / r));
            let q = lu
                .solve(&b)
                .ok_or_else(|| invalid("actuators.coupling", 0.0, "is singular"))?;
            out.extend(q.iter());
        }
        Ok(out)
    }

    /// Joint torques (N·m or N) from motor-side torques τ_motor (N·m at the motor shaft):
    /// τ = Cᵀ·(r∘τ_motor), per sample of a flat row-major (samples × n) array. Needs the
    /// gear ratios.
    ///
    /// # Errors
    /// As [`Actuators::joint_positions_from_motor`].
    pub fn joint_torques_from_motor(&self, n: usize, tau_motor: &[f64]) -> Result<Vec<f64>> {
        self.validate(n)?;
        let r = self.ratios("motor-side torques")?.to_vec();
        self.reflect(n, tau_motor, &r, "motor-side torques")
    }

    /// Joint torques (N·m or N) from motor currents i (A) with joint-side drive gains K
    /// (N·m/A: torque constant times gear ratio, per actuator): τ = Cᵀ·(K∘i), per sample
    /// of a flat row-major (samples × n) array.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for gains not one per actuator or a length that is not
    /// a multiple of n; [`PrrrpError::InvalidParameter`] for a non-finite or zero gain; as
    /// [`Actuators::validate`].
    pub fn joint_torques_from_currents(
        &self,
        n: usize,
        current: &[f64],
        gains: &[f64],
    ) -> Result<Vec<f64>> {
        self.validate(n)?;
        check_count("drive gains", gains.len(), n)?;
        for (m, &k) in gains.iter().enumerate() {
            if !(k.is_finite() && k != 0.0) {
                return Err(invalid(
                    format!("drive gains[{m}]"),
                    k,
                    "a drive gain (N·m/A, joint side) must be finite and non-zero",
                ));
            }
        }
        self.reflect(n, current, gains, "motor currents")
    }

    fn ratios(&self, what: &str) -> Result<&[f64]> {
        self.gear_ratios
            .as_deref()
            .ok_or_else(|| PrrrpError::InvalidParameter {
                field: format!("actuators.gear_ratios (needed for {what})"),
                value: f64::NAN,
                reason: "are not given: set gear_ratios = [...] under [actuators] in the robot \
                     file (motor angle per joint angle, one per actuator)",
            })
    }

    /// Cᵀ·(s∘x) per sample.
    fn reflect(&self, n: usize, x: &[f64], s: &[f64], what: &str) -> Result<Vec<f64>> {
        samples_of(n, x.len(), what)?;
        let c = self.coupling_row_major(n);
        let mut out = vec![0.0; x.len()];
        for (row, o) in x.chunks_exact(n).zip(out.chunks_exact_mut(n)) {
            for m in 0..n {
                let t = s[m] * row[m];
                for (j, oj) in o.iter_mut().enumerate() {
                    *oj += c[m * n + j] * t;
                }
            }
        }
        Ok(out)
    }
}

fn samples_of(n: usize, len: usize, what: &str) -> Result<usize> {
    if n == 0 || len % n != 0 {
        return Err(PrrrpError::ShapeMismatch {
            what: format!("{what} (flat samples × n)"),
            expected: format!("a multiple of n = {n}"),
            got: format!("{len} values"),
        });
    }
    Ok(len / n)
}

fn identity(n: usize) -> Vec<f64> {
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    v
}

fn is_identity(rows: &[Vec<f64>]) -> bool {
    rows.iter().enumerate().all(|(i, r)| {
        r.iter()
            .enumerate()
            .all(|(j, &x)| x == if i == j { 1.0 } else { 0.0 })
    })
}

/// The coupling rows checked for a chain of `n` joints: square, finite and invertible.
fn coupling_matrix(rows: &[Vec<f64>], n: usize) -> Result<DMatrix<f64>> {
    if rows.len() != n || rows.iter().any(|r| r.len() != n) {
        let got = rows.iter().map(Vec::len).collect::<Vec<_>>();
        return Err(PrrrpError::ShapeMismatch {
            what: "actuators.coupling".into(),
            expected: format!("{n} rows of {n} numbers (square: one row per actuator)"),
            got: format!("{} rows of lengths {got:?}", rows.len()),
        });
    }
    for (m, r) in rows.iter().enumerate() {
        for (j, &x) in r.iter().enumerate() {
            if !x.is_finite() {
                return Err(invalid(
                    format!("actuators.coupling[{m}][{j}]"),
                    x,
                    "coupling entries must be finite",
                ));
            }
        }
    }
    let c = DMatrix::from_fn(n, n, |i, j| rows[i][j]);
    let sv = c.singular_values();
    let (lo, hi) = sv
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    if !(hi > 0.0 && lo > COUPLING_CONDITION_LIMIT * hi) {
        return Err(invalid(
            "actuators.coupling (cond)",
            if lo > 0.0 { hi / lo } else { f64::INFINITY },
            "is singular: the actuator velocities C·q̇ must determine the joint velocities \
             (C invertible); check for a zero or repeated row",
        ));
    }
    Ok(c)
}

/// Where the per-actuator parameters sit: how many each actuator has and the slot of each
/// kind (fv, fc, fo, Ia) among them (`usize::MAX` when disabled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ActuatorLayout {
    pub(crate) per: usize,
    pub(crate) slots: [usize; 4],
}

impl ActuatorLayout {
    pub(crate) fn new(friction: &super::FrictionModel, armature: bool) -> Self {
        let e = [
            friction.viscous,
            friction.coulomb,
            friction.offset,
            armature,
        ];
        let mut slots = [usize::MAX; 4];
        let mut next = 0;
        for k in 0..4 {
            if e[k] {
                slots[k] = next;
                next += 1;
            }
        }
        Self { per: next, slots }
    }

    /// Enabled flags in parameter order (fv, fc, fo, Ia).
    pub(crate) fn enabled(&self) -> [bool; 4] {
        self.slots.map(|s| s != usize::MAX)
    }

    /// The kind of the actuator parameter at slot `s`.
    pub(crate) fn kind_of(&self, s: usize) -> usize {
        self.slots.iter().position(|&x| x == s).unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eye(n: usize) -> Vec<Vec<f64>> {
        (0..n)
            .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
            .collect()
    }

    #[test]
    fn bad_couplings_are_clear_errors() {
        let a = |c: Vec<Vec<f64>>| Actuators {
            coupling: Some(c),
            ..Actuators::default()
        };
        assert!(a(eye(3)).validate(3).is_ok());
        // Not square / wrong size.
        let e = a(vec![vec![1.0, 0.0], vec![0.0, 1.0, 0.0]]).validate(2);
        assert!(matches!(e, Err(PrrrpError::ShapeMismatch { .. })), "{e:?}");
        assert!(a(eye(2)).validate(3).is_err());
        // Non-finite.
        let mut c = eye(3);
        c[1][2] = f64::NAN;
        let msg = a(c).validate(3).unwrap_err().to_string();
        assert!(msg.contains("coupling[1][2]"), "{msg}");
        // Singular: a repeated row.
        let mut c = eye(3);
        c[2] = c[1].clone();
        let msg = a(c).validate(3).unwrap_err().to_string();
        assert!(msg.contains("singular"), "{msg}");
        // Armature and gear ratios.
        let bad = Actuators {
            armature: true,
            armature_values: Some(vec![0.1, -0.2]),
            ..Actuators::default()
        };
        assert!(bad
            .validate(2)
            .unwrap_err()
            .to_string()
            .contains("armature_values[1]"));
        let bad = Actuators {
            gear_ratios: Some(vec![100.0, 0.0]),
            ..Actuators::default()
        };
        assert!(bad.validate(2).is_err());
    }

    #[test]
    fn motor_side_maps_invert_the_coupling() {
        // Motor 2 turns with q1 + q2; ratios 100 and 50.
        let act = Actuators {
            coupling: Some(vec![vec![1.0, 0.0], vec![1.0, 1.0]]),
            gear_ratios: Some(vec![100.0, 50.0]),
            ..Actuators::default()
        };
        let q = [0.3, -0.2];
        let theta = [100.0 * 0.3, 50.0 * (0.3 - 0.2)];
        let back = act.joint_positions_from_motor(2, &theta).unwrap();
        assert!((back[0] - q[0]).abs() < 1e-14 && (back[1] - q[1]).abs() < 1e-14);
        // Power is conserved: θ̇ᵀτ_motor = q̇ᵀτ.
        let (qd, tm) = ([0.7, 1.3], [0.02, -0.05]);
        let tau = act.joint_torques_from_motor(2, &tm).unwrap();
        let thd = [100.0 * qd[0], 50.0 * (qd[0] + qd[1])];
        let p_motor = thd[0] * tm[0] + thd[1] * tm[1];
        let p_joint = qd[0] * tau[0] + qd[1] * tau[1];
        assert!((p_motor - p_joint).abs() < 1e-12);
        let t = act
            .joint_torques_from_currents(2, &[1.0, 2.0], &[10.0, 5.0])
            .unwrap();
        assert_eq!(t, vec![10.0 + 10.0, 10.0]);
        let none = Actuators::default();
        let msg = none
            .joint_torques_from_motor(2, &tm)
            .unwrap_err()
            .to_string();
        assert!(msg.contains("gear_ratios"), "{msg}");
    }

    #[test]
    fn layout_slots() {
        let f = super::super::FrictionModel {
            viscous: true,
            offset: true,
            ..Default::default()
        };
        let l = ActuatorLayout::new(&f, true);
        assert_eq!(l.per, 3);
        assert_eq!(l.slots, [0, usize::MAX, 1, 2]);
        assert_eq!(l.kind_of(2), 3);
    }
}
