//! Joint position, velocity and acceleration limits, and how much of them a trajectory
//! uses.

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::types::{Vec5, NDOF};
use crate::motion::trajectory::JointTrajectory;

/// Joint limits in SI units, joint order [d1, θ2, θ3, θ4, d5].
///
/// The defaults are chosen for the paper's arm (link lengths 0.2 m, link masses ≈ 1 kg),
/// which the paper does not specify:
///
/// | joint | position | \|velocity\| | \|acceleration\| |
/// |---|---|---|---|
/// | d1 (lift) | 0 … 0.3 m | 0.5 m/s | 5 m/s² |
/// | θ2, θ3, θ4 | −2.5 … 2.5 rad (±143°) | 3 rad/s | 10 rad/s² |
/// | d5 (tool) | 0 … 0.1 m | 0.5 m/s | 5 m/s² |
///
/// Why: the lift travel is about half the 0.524 m column; ±143° is the usual range of a
/// SCARA-type elbow (cables and the stacked links stop a full turn); 3 rad/s and
/// 10 rad/s² are modest for a small arm (M22 ≤ 0.43 kg·m² for the paper's masses) and
/// lead to peak torques of 2–3 N·m at joint 2 on optimised excitations; the 0.1 m tool
/// stroke fits inside the 0.14 m last link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower position limits (m, rad).
    pub q_min: Vec5,
    /// Upper position limits (m, rad).
    pub q_max: Vec5,
    /// Symmetric velocity limits |q̇| ≤ qd_max (m/s, rad/s).
    pub qd_max: Vec5,
    /// Symmetric acceleration limits |q̈| ≤ qdd_max (m/s², rad/s²).
    pub qdd_max: Vec5,
}

impl Default for JointLimits {
    fn default() -> Self {
        Self {
            q_min: Vec5::new(0.0, -2.5, -2.5, -2.5, 0.0),
            q_max: Vec5::new(0.3, 2.5, 2.5, 2.5, 0.1),
            qd_max: Vec5::new(0.5, 3.0, 3.0, 3.0, 0.5),
            qdd_max: Vec5::new(5.0, 10.0, 10.0, 10.0, 5.0),
        }
    }
}

impl JointLimits {
    /// Checks that every limit is finite, velocity and acceleration limits are > 0 and
    /// q_min < q_max, so that every joint can move.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the first bad entry (NaN, ∞, negative);
    /// [`PrrrpError::Infeasible`] if a joint cannot move at all (q_min ≥ q_max, or a zero
    /// velocity or acceleration limit): its parameters could not be excited.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("q_min", &self.q_min),
            ("q_max", &self.q_max),
            ("qd_max", &self.qd_max),
            ("qdd_max", &self.qdd_max),
        ] {
            for j in 0..NDOF {
                let x = v[j];
                let is_rate = name != "q_min" && name != "q_max";
                let bad = !x.is_finite() || (is_rate && x < 0.0);
                if bad {
                    return Err(PrrrpError::InvalidParameter {
                        field: format!("limits.{name}[{j}] (joint {})", j + 1),
                        value: x,
                        reason: "limits must be finite; velocity and acceleration limits >= 0",
                    });
                }
            }
        }
        for j in 0..NDOF {
            let why = if self.q_min[j] >= self.q_max[j] {
                Some("q_min >= q_max")
            } else if self.qd_max[j] == 0.0 {
                Some("qd_max = 0")
            } else if self.qdd_max[j] == 0.0 {
                Some("qdd_max = 0")
            } else {
                None
            };
            if let Some(why) = why {
                return Err(PrrrpError::Infeasible {
                    what: format!(
                        "joint {} cannot move ({why}), so the parameters it drives cannot be \
                         excited; widen its limits",
                        j + 1
                    ),
                });
            }
        }
        Ok(())
    }

    /// Centre of the position range (m, rad).
    pub fn q_center(&self) -> Vec5 {
        0.5 * (self.q_min + self.q_max)
    }

    /// Half width of the position range (m, rad).
    pub fn q_half_range(&self) -> Vec5 {
        0.5 * (self.q_max - self.q_min)
    }
}

/// The fraction of each limit a trajectory uses (1 = at the limit, > 1 = violated),
/// measured on a time grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitUsage {
    /// max over time of |q − centre| / half range, per joint.
    pub q: Vec5,
    /// max over time of |q̇| / qd_max, per joint.
    pub qd: Vec5,
    /// max over time of |q̈| / qdd_max, per joint.
    pub qdd: Vec5,
}

impl LimitUsage {
    /// The largest fraction of any limit.
    pub fn max(&self) -> f64 {
        self.q.max().max(self.qd.max()).max(self.qdd.max())
    }

    /// True when no limit is exceeded by more than the relative tolerance `tol`.
    pub fn within(&self, tol: f64) -> bool {
        self.max() <= 1.0 + tol
    }
}

/// How much of `limits` the trajectory uses on t ∈ [t0, t1], evaluated at `points`
/// (2 to [`crate::MAX_SAMPLES`]) equally spaced instants including both ends.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] if the interval is empty or not finite, `points < 2` or
/// `points` exceeds [`crate::MAX_SAMPLES`] (10⁷); errors of [`JointLimits::validate`].
pub fn limit_usage<T: JointTrajectory + ?Sized>(
    traj: &T,
    limits: &JointLimits,
    t0: f64,
    t1: f64,
    points: usize,
) -> Result<LimitUsage> {
    limits.validate()?;
    if !(t0.is_finite() && t1.is_finite() && t1 > t0) {
        return Err(PrrrpError::InvalidParameter {
            field: "t1".into(),
            value: t1,
            reason: "the interval [t0, t1] must be finite with t1 > t0",
        });
    }
    if points < 2 {
        return Err(PrrrpError::InvalidParameter {
            field: "points".into(),
            value: points as f64,
            reason: "at least 2 evaluation points are needed",
        });
    }
    // 1e7 points take about a second; usize::MAX never returned.
    crate::interrupt::check_count(
        "points",
        points as f64,
        "more than MAX_SAMPLES (1e7) evaluation points: use fewer",
    )?;
    let (c, h) = (limits.q_center(), limits.q_half_range());
    let mut u = LimitUsage {
        q: Vec5::zeros(),
        qd: Vec5::zeros(),
        qdd: Vec5::zeros(),
    };
    let step = (t1 - t0) / (points - 1) as f64;
    for k in 0..points {
        let p = traj.eval(t0 + step * k as f64);
        for j in 0..NDOF {
            // NaN compares false with max(): treat it as an infinite violation.
            let nan_inf = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
            u.q[j] = u.q[j].max(nan_inf((p.q[j] - c[j]).abs() / h[j]));
            u.qd[j] = u.qd[j].max(nan_inf(p.qd[j].abs() / limits.qd_max[j]));
            u.qdd[j] = u.qdd[j].max(nan_inf(p.qdd[j].abs() / limits.qdd_max[j]));
        }
    }
    Ok(u)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validation::default_validation_reference;

    #[test]
    fn more_points_than_max_samples_are_refused() {
        let traj = default_validation_reference();
        let limits = JointLimits::default();
        let points = crate::MAX_SAMPLES + 1;
        let got = limit_usage(&traj, &limits, 0.0, 1.0, points);
        assert!(
            matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "points"),
            "{got:?}"
        );
        assert!(limit_usage(&traj, &limits, 0.0, 1.0, usize::MAX).is_err());
    }
}
