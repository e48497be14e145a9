//! Joint friction terms appended to the rigid-body regressor.

/// Names of the three friction parameters of a joint, in order; the chain appends the
/// 1-based joint number (e.g. `fv2`).
pub const FRICTION_PARAMETER_NAMES: [&str; 3] = ["fv", "fc", "fo"];

/// |x| from which tanh(x) is ±1 in f64 (dimensionless): 1 − tanh(20) ≈ 8.5e-18 < ε/2.
const TANH_SATURATION: f64 = 20.0;

/// Which friction terms each joint carries, identical for all joints.
///
/// Joint j adds τ_f,j = fv_j·q̇_j + fc_j·sgn(q̇_j) + fo_j to its generalised force, each term
/// only if enabled. Every enabled term is one more parameter per joint, appended after the
/// 10·n inertial parameters in the order: joint 1 (fv, fc, fo), joint 2 (…), … — keeping
/// only the enabled ones. Units: fv in N·s/m or N·m·s/rad, fc and fo in N or N·m.
///
/// With coupled actuators ([`super::Actuators`]) the terms act on each actuator's velocity
/// (C·q̇)ₘ instead and reach the joints through Cᵀ; with an armature each actuator's block
/// gains `Ia` after its friction terms.
///
/// Default: no friction (all `false`, `coulomb_smoothing` = 0).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrictionModel {
    /// Viscous term fv·q̇ (default `false`).
    pub viscous: bool,
    /// Coulomb term fc·sgn(q̇) (default `false`).
    pub coulomb: bool,
    /// Constant offset fo, e.g. an unmodelled torque-sensor bias (default `false`).
    pub offset: bool,
    /// Velocity scale v_s (rad/s or m/s) of a smoothed sign sgn(q̇) ≈ tanh(q̇/v_s), which
    /// keeps forward simulation smooth; 0 (default) uses the exact sign with sgn(0) = 0.
    /// Otherwise between [`crate::MIN_FACTOR`] and [`crate::MAX_FACTOR`] (checked where a
    /// chain takes it).
    pub coulomb_smoothing: f64,
}

impl FrictionModel {
    /// Viscous and Coulomb friction with the exact sign, the field's usual choice.
    pub const fn viscous_coulomb() -> Self {
        Self {
            viscous: true,
            coulomb: true,
            offset: false,
            coulomb_smoothing: 0.0,
        }
    }

    /// Viscous, Coulomb and offset terms with the exact sign.
    pub const fn all() -> Self {
        Self {
            viscous: true,
            coulomb: true,
            offset: true,
            coulomb_smoothing: 0.0,
        }
    }

    /// Number of friction parameters per joint (0 to 3).
    pub const fn columns_per_joint(&self) -> usize {
        self.viscous as usize + self.coulomb as usize + self.offset as usize
    }

    /// Enabled flags in parameter order (viscous, Coulomb, offset).
    #[inline(always)]
    pub(crate) const fn enabled(&self) -> [bool; 3] {
        [self.viscous, self.coulomb, self.offset]
    }

    /// Regressor entries [q̇, sgn(q̇), 1] of one joint (disabled terms still returned).
    #[inline(always)]
    pub(crate) fn features(&self, qd: f64) -> [f64; 3] {
        let sign = if self.coulomb_smoothing > 0.0 {
            let x = qd / self.coulomb_smoothing;
            // tanh rounds to ±1 from |x| ≈ 19.1 (1 − tanh x ≈ 2e^{−2x} < ε/2): skip the
            // call where most samples of a narrow scale sit (the speed-scale search).
            if x.abs() >= TANH_SATURATION {
                x.signum()
            } else {
                x.tanh()
            }
        } else if qd > 0.0 {
            1.0
        } else if qd < 0.0 {
            -1.0
        } else {
            0.0
        };
        [qd, sign, 1.0]
    }

    /// Friction force of one joint with parameters [fv, fc, fo] (disabled terms ignored).
    #[inline(always)]
    pub(crate) fn torque(&self, qd: f64, params: &[f64; 3]) -> f64 {
        let f = self.features(qd);
        let e = self.enabled();
        let mut t = 0.0;
        for k in 0..3 {
            if e[k] {
                t += f[k] * params[k];
            }
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_saturated_sign_is_what_tanh_gives() {
        let f = FrictionModel {
            coulomb: true,
            coulomb_smoothing: 0.01,
            ..FrictionModel::default()
        };
        for x in [19.2, 19.9, 20.0, 20.5, 25.0, 100.0, 1e300, f64::INFINITY] {
            assert_eq!(f.features(0.01 * x)[1], x.tanh(), "{x}");
            assert_eq!(f.features(-0.01 * x)[1], (-x).tanh(), "{x}");
        }
    }

    #[test]
    fn slots_and_torque() {
        let f = FrictionModel {
            viscous: true,
            coulomb: false,
            offset: true,
            coulomb_smoothing: 0.0,
        };
        assert_eq!(f.columns_per_joint(), 2);
        assert_eq!(f.torque(-2.0, &[0.5, 10.0, 0.1]), -1.0 + 0.1);
        let c = FrictionModel::all();
        assert_eq!(c.torque(-2.0, &[0.5, 0.3, 0.1]), -1.0 - 0.3 + 0.1);
        assert_eq!(c.torque(0.0, &[0.5, 0.3, 0.1]), 0.1);
        let s = FrictionModel {
            coulomb_smoothing: 0.01,
            ..FrictionModel::viscous_coulomb()
        };
        assert!((s.features(1.0)[1] - 1.0).abs() < 1e-15);
        assert!((s.features(0.005)[1] - 0.5f64.tanh()).abs() < 1e-15);
    }
}
