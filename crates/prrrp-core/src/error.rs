//! The crate-wide error type.

use std::fmt;

/// Everything that can go wrong in prrrp, with a message that says what to fix.
///
/// Every fallible public function returns `Result<_, PrrrpError>`; no public function
/// panics on bad input.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum PrrrpError {
    /// A physical or configuration value is out of its valid range (non-positive mass,
    /// negative inertia, NaN, a non-positive step size, …).
    InvalidParameter {
        /// Name of the offending field, e.g. `"m[2]"` or `"dt"`.
        field: String,
        /// The rejected value.
        value: f64,
        /// What the value must satisfy.
        reason: &'static str,
    },
    /// A matrix that must be symmetric positive definite is not (e.g. the mass matrix for
    /// a non-physical λ, or an innovation covariance).
    NotPositiveDefinite {
        /// Which matrix failed.
        what: &'static str,
    },
    /// An input contains NaN or infinity.
    NonFinite {
        /// Which input, e.g. `"q"`, `"tau[3]"`.
        what: String,
        /// Sample index (row) of the first bad value, when the input is a series.
        row: Option<usize>,
    },
    /// Array or series lengths do not match.
    ShapeMismatch {
        /// Which input.
        what: String,
        /// Expected shape or length.
        expected: String,
        /// Actual shape or length.
        got: String,
    },
    /// Not enough samples to identify the requested number of parameters.
    TooFewSamples {
        /// Minimum number of samples.
        needed: usize,
        /// Number supplied.
        got: usize,
    },
    /// The observation matrix does not determine every parameter.
    RankDeficient {
        /// Numerical rank found.
        rank: usize,
        /// Number of parameters.
        params: usize,
        /// Condition number σmax/σmin of the observation matrix (may be infinite).
        cond: f64,
        /// Unit vectors in parameter space (length `params`) spanning the unidentifiable
        /// directions, from the right singular vectors of the smallest singular values.
        directions: Vec<Vec<f64>>,
    },
    /// An iterative estimator or integrator blew up.
    Diverged {
        /// Which algorithm.
        what: &'static str,
        /// Sample or iteration at which divergence was detected.
        at: usize,
        /// What to change.
        hint: &'static str,
    },
    /// A simulation's state became NaN or infinite (it diverged): which signal, joint and
    /// time, so the setting to change (gains, step, parameters, torques) can be found.
    SimulationDiverged {
        /// The output sample the integration was heading for when the state became
        /// non-finite.
        sample: usize,
        /// Time of the integration step at whose end the state was non-finite, s.
        time: f64,
        /// Index of the first non-finite joint (0-based).
        joint: usize,
        /// `"q"` or `"qd"`.
        signal: &'static str,
    },
    /// A constrained problem (e.g. excitation under joint limits) has no feasible answer.
    Infeasible {
        /// What could not be met.
        what: String,
    },
    /// A long computation stopped because [`crate::request_stop`] was called (Ctrl-C in
    /// Python); nothing partial is returned.
    Interrupted {
        /// Which computation.
        what: &'static str,
    },
    /// Time stamps are not strictly increasing.
    NonIncreasingTime {
        /// First row whose time is not larger than the previous one.
        row: usize,
    },
    /// A robot file (URDF or TOML) cannot be read or does not describe a valid chain.
    RobotFile {
        /// The file's path, or `<string>` when the text was given directly.
        file: String,
        /// The offending element or key, e.g. `joint[panda_joint3]/axis` (URDF) or
        /// `joint[3].inertial` (TOML); `file` for problems with the whole file.
        element: String,
        /// What is wrong and what to fix.
        message: String,
    },
}

impl fmt::Display for PrrrpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::InvalidParameter {
                field,
                value,
                reason,
            } => {
                // NaN is also the value of a field that is not a number (a method's name,
                // a file's key): "invalid value NaN for `online method \"EKF\"`" misled.
                // 1e300 in positional notation is 301 digits long.
                let a = value.abs();
                if value.is_nan() {
                    write!(f, "invalid `{field}`: {reason}")
                } else if a >= 1e9 || (a > 0.0 && a < 1e-6) {
                    write!(f, "invalid value {value:e} for `{field}`: {reason}")
                } else {
                    write!(f, "invalid value {value} for `{field}`: {reason}")
                }
            }
            Self::NotPositiveDefinite { what } => write!(
                f,
                "{what} is not positive definite; check that the parameters are physical \
                 (positive masses and inertias)"
            ),
            Self::NonFinite { what, row } => match row {
                Some(r) => write!(f, "`{what}` has a NaN or infinite value at row {r}"),
                None => write!(f, "`{what}` has a NaN or infinite value"),
            },
            Self::ShapeMismatch {
                what,
                expected,
                got,
            } => {
                write!(f, "`{what}` has shape {got}, expected {expected}")
            }
            Self::TooFewSamples { needed, got } => write!(
                f,
                "too few samples: got {got}, need at least {needed}; record a longer trajectory"
            ),
            Self::RankDeficient {
                rank,
                params,
                cond,
                directions,
            } => {
                write!(
                    f,
                    "the observation matrix has rank {rank} < {params} (cond = {cond:.3e}): \
                     the data do not excite every parameter; use a richer excitation trajectory. \
                     Unidentifiable directions:"
                )?;
                for d in directions {
                    write!(f, " [")?;
                    for (i, x) in d.iter().enumerate() {
                        if i > 0 {
                            write!(f, ", ")?;
                        }
                        write!(f, "{x:.3}")?;
                    }
                    write!(f, "]")?;
                }
                Ok(())
            }
            Self::Diverged { what, at, hint } => {
                write!(f, "{what} diverged at sample/iteration {at}: {hint}")
            }
            Self::SimulationDiverged {
                sample,
                time,
                joint,
                signal,
            } => write!(
                f,
                "simulation diverged: {signal}[{joint}] (joint {}) is NaN/∞ at t = {time:.6} s \
                 (sample {sample}); check the torques, gains and parameters (a non-physical \
                 model, or links without mass whose mass matrix turns singular along the \
                 path), or increase substeps",
                joint + 1
            ),
            Self::Infeasible { what } => write!(f, "infeasible: {what}"),
            Self::Interrupted { what } => write!(f, "{what} interrupted"),
            Self::NonIncreasingTime { row } => {
                write!(
                    f,
                    "time stamps must be strictly increasing; row {row} is not"
                )
            }
            Self::RobotFile {
                file,
                element,
                message,
            } => {
                // Problems of the whole file name no element.
                if element == "file" || element.is_empty() {
                    write!(f, "robot file {file}: {message}")
                } else {
                    write!(f, "robot file {file}, `{element}`: {message}")
                }
            }
        }
    }
}

impl std::error::Error for PrrrpError {}

/// Shorthand for `Result<T, PrrrpError>`.
pub type Result<T> = std::result::Result<T, PrrrpError>;

impl PrrrpError {
    /// A [`PrrrpError::ShapeMismatch`]: `what` has shape `got`, `expected` wanted.
    pub(crate) fn shape(
        what: impl Into<String>,
        expected: impl Into<String>,
        got: impl Into<String>,
    ) -> Self {
        Self::ShapeMismatch {
            what: what.into(),
            expected: expected.into(),
            got: got.into(),
        }
    }
}

/// A [`PrrrpError::InvalidParameter`]: setting `field` has the value `value`, which `reason`
/// says is out of range.
pub(crate) fn invalid(field: impl Into<String>, value: f64, reason: &'static str) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field: field.into(),
        value,
        reason,
    }
}

/// A [`PrrrpError::ShapeMismatch`] naming `what` unless its length `len` is `want`:
/// expected "`want` `unit``note`", got "`len` `unit`" (`note` says what `want` counts,
/// e.g. " (one per joint)"). Allocates only on the error.
pub(crate) fn check_len(what: &str, len: usize, want: usize, unit: &str, note: &str) -> Result<()> {
    if len != want {
        return Err(PrrrpError::shape(
            what,
            format!("{want} {unit}{note}"),
            format!("{len} {unit}"),
        ));
    }
    Ok(())
}

/// [`check_len`] for each (what, len) of `pairs`, the first mismatch returned.
pub(crate) fn check_lens(
    pairs: &[(&str, usize)],
    want: usize,
    unit: &str,
    note: &str,
) -> Result<()> {
    for &(what, len) in pairs {
        check_len(what, len, want, unit, note)?;
    }
    Ok(())
}

/// A [`PrrrpError::ShapeMismatch`] naming `what` unless its shape `got` (rows, columns) is
/// `want`. Allocates only on the error.
pub(crate) fn check_shape(what: &str, got: (usize, usize), want: (usize, usize)) -> Result<()> {
    if got != want {
        return Err(PrrrpError::shape(
            what,
            format!("{}×{}", want.0, want.1),
            format!("{}×{}", got.0, got.1),
        ));
    }
    Ok(())
}

/// An [`PrrrpError::InvalidParameter`] naming `what[i]` for the first entry of `v` that is
/// not finite and >= 0 (`reason` says what the entries are and their units).
pub(crate) fn check_non_negative(what: &str, v: &[f64], reason: &'static str) -> Result<()> {
    match v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
        Some(i) => Err(invalid(format!("{what}[{i}]"), v[i], reason)),
        None => Ok(()),
    }
}

/// A [`PrrrpError::ShapeMismatch`] naming `what` unless its length `len` is the joint
/// count `n`.
pub(crate) fn check_joints(what: &str, len: usize, n: usize) -> Result<()> {
    check_len(what, len, n, "entries", " (one per joint)")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn invalid(value: f64) -> String {
        PrrrpError::InvalidParameter {
            field: "x".into(),
            value,
            reason: "why",
        }
        .to_string()
    }

    #[test]
    fn invalid_values_are_written_to_be_read() {
        assert_eq!(invalid(0.5), "invalid value 0.5 for `x`: why");
        assert_eq!(invalid(-1e300), "invalid value -1e300 for `x`: why");
        assert_eq!(invalid(2e-9), "invalid value 2e-9 for `x`: why");
        assert_eq!(invalid(f64::INFINITY), "invalid value inf for `x`: why");
        // NaN also stands for a field that is not a number (a name, a key).
        assert_eq!(invalid(f64::NAN), "invalid `x`: why");
    }

    #[test]
    fn a_diverged_simulation_is_one_readable_line() {
        // It carried two runs of 18 spaces (a broken line continuation) and t's every digit.
        let shown = PrrrpError::SimulationDiverged {
            sample: 119,
            time: 1.1829999999999998,
            joint: 0,
            signal: "qd",
        }
        .to_string();
        assert!(
            shown.starts_with(
                "simulation diverged: qd[0] (joint 1) is NaN/∞ at t = 1.183000 s (sample 119); "
            ),
            "{shown}"
        );
        assert!(!shown.contains("  ") && !shown.contains('\n'), "{shown}");
        assert!(shown.contains("mass matrix turns singular"), "{shown}");
    }
}
