//! Error indices between an observed and a predicted series (paper eqs. 45–47), and the
//! relative errors the field reports next to them.
//!
//! With o the observed series, p the predicted one, n samples and o_m the mean of o:
//! ```text
//! RMS = √( Σ (oᵢ − pᵢ)² / n )                                  (eq. 45, units of o)
//! RSD = √( Σ (oᵢ − pᵢ)² / Σ oᵢ² )                              (eq. 46, dimensionless)
//! AI  = 1 − Σ (oᵢ − pᵢ)² / Σ (|pᵢ − o_m| + |oᵢ − o_m|)²        (eq. 47, Willmott's index)
//! ```
//! The paper's extracted text lost the radical signs; we take the root forms, so that RMS
//! is in the units of the series (m, rad, N, N·m) and RSD is a relative error (0 = exact).
//! Identical series give RMS = RSD = 0 and AI = 1.
//!
//! **Zero denominators** (documented values, never NaN):
//! - AI: the denominator vanishes only when o is constant and p equals that constant,
//!   i.e. when the two series agree exactly: AI = 1.
//! - RSD: the denominator vanishes when o ≡ 0. If p ≡ 0 too, RSD = 0; otherwise the
//!   relative error is undefined and [`PrrrpError::InvalidParameter`] is returned
//!   (compare RMS instead).

use crate::error::{PrrrpError, Result};

/// The three indices of eqs. 45–47 for one series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorIndices {
    /// Residual mean square (root form), in the units of the series.
    pub rms: f64,
    /// Residual standard deviation relative to the observed series, dimensionless.
    pub rsd: f64,
    /// Willmott's agreement index in [0, 1]; 1 is a perfect match.
    pub ai: f64,
}

fn check(observed: &[f64], predicted: &[f64]) -> Result<()> {
    if observed.len() != predicted.len() {
        return Err(PrrrpError::ShapeMismatch {
            what: "predicted".into(),
            expected: format!("{} samples (as observed)", observed.len()),
            got: format!("{} samples", predicted.len()),
        });
    }
    if observed.is_empty() {
        return Err(PrrrpError::TooFewSamples { needed: 1, got: 0 });
    }
    for (name, s) in [("observed", observed), ("predicted", predicted)] {
        if let Some(row) = s.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: name.into(),
                row: Some(row),
            });
        }
    }
    Ok(())
}

/// The largest magnitude in both series (1 for all zeros). Sums are formed of the values
/// divided by it, so that squares of finite values near 1e308 (or below 1e-154) neither
/// overflow nor underflow; only a result that itself exceeds f64 is an error.
fn scale(observed: &[f64], predicted: &[f64]) -> f64 {
    let s = observed
        .iter()
        .chain(predicted)
        .fold(0.0f64, |m, x| m.max(x.abs()));
    if s > 0.0 {
        s
    } else {
        1.0
    }
}

/// Σ((oᵢ − pᵢ)/s)².
fn sse(observed: &[f64], predicted: &[f64], s: f64) -> f64 {
    observed
        .iter()
        .zip(predicted)
        .map(|(o, p)| {
            let d = o / s - p / s;
            d * d
        })
        .sum()
}

/// `r`, or [`PrrrpError::NonFinite`] saying why (`what`) if it overflowed.
fn finite(r: f64, what: &str) -> Result<f64> {
    if r.is_finite() {
        Ok(r)
    } else {
        Err(PrrrpError::NonFinite {
            what: what.into(),
            row: None,
        })
    }
}

/// Residual mean square (eq. 45, root form): √(Σ(oᵢ − pᵢ)²/n), in the units of the series.
///
/// # Errors
/// Lengths differ, empty series, or NaN/∞ values.
pub fn rms(observed: &[f64], predicted: &[f64]) -> Result<f64> {
    check(observed, predicted)?;
    let s = scale(observed, predicted);
    finite(
        s * (sse(observed, predicted, s) / observed.len() as f64).sqrt(),
        "rms (the residuals exceed the f64 range)",
    )
}

/// Residual standard deviation (eq. 46, root form): √(Σ(oᵢ − pᵢ)²/Σoᵢ²).
///
/// # Errors
/// As [`rms`], and [`PrrrpError::InvalidParameter`] when o ≡ 0 but p is not (see the
/// module docs).
pub fn rsd(observed: &[f64], predicted: &[f64]) -> Result<f64> {
    check(observed, predicted)?;
    let s = scale(observed, predicted);
    let num = sse(observed, predicted, s);
    let den: f64 = observed.iter().map(|o| (o / s) * (o / s)).sum();
    // Σ(o/s)² also underflows to 0 when the prediction dwarfs a non-zero observation by
    // more than ~1e160 (the scale s is the larger of both): that is no zero series.
    if den == 0.0 && observed.iter().any(|&o| o != 0.0) {
        return finite(
            f64::INFINITY,
            "rsd (the residual dwarfs the observed series beyond the f64 range)",
        );
    }
    if den == 0.0 {
        return if num == 0.0 {
            Ok(0.0)
        } else {
            Err(PrrrpError::InvalidParameter {
                field: "observed".into(),
                value: 0.0,
                reason: "the observed series is identically zero, so its relative residual \
                         (RSD) is undefined; compare RMS instead",
            })
        };
    }
    // √num/√den: num/den itself can overflow when o is tiny next to p.
    finite(
        num.sqrt() / den.sqrt(),
        "rsd (the residual dwarfs the observed series beyond the f64 range)",
    )
}

/// Willmott's agreement index (eq. 47): 1 − Σ(oᵢ − pᵢ)² / Σ(|pᵢ − o_m| + |oᵢ − o_m|)².
///
/// # Errors
/// As [`rms`]. A zero denominator means the series agree exactly and gives 1.
pub fn agreement_index(observed: &[f64], predicted: &[f64]) -> Result<f64> {
    check(observed, predicted)?;
    let s = scale(observed, predicted);
    let mean = observed.iter().map(|o| o / s).sum::<f64>() / observed.len() as f64;
    let num = sse(observed, predicted, s);
    let den: f64 = observed
        .iter()
        .zip(predicted)
        .map(|(o, p)| {
            let d = (p / s - mean).abs() + (o / s - mean).abs();
            d * d
        })
        .sum();
    // den ≥ num always (|o − p| ≤ |o − o_m| + |p − o_m|), so den = 0 implies num = 0.
    Ok(if den == 0.0 { 1.0 } else { 1.0 - num / den })
}

/// All three indices of one series.
///
/// # Errors
/// As [`rms`], [`rsd`] and [`agreement_index`].
pub fn error_indices(observed: &[f64], predicted: &[f64]) -> Result<ErrorIndices> {
    Ok(ErrorIndices {
        rms: rms(observed, predicted)?,
        rsd: rsd(observed, predicted)?,
        ai: agreement_index(observed, predicted)?,
    })
}

/// Relative error |estimate − truth| / |truth| of each parameter, in percent.
///
/// A true value of exactly zero gives the absolute error instead (documented so the
/// result is never NaN or infinite).
pub fn relative_errors_percent(estimate: &[f64], truth: &[f64]) -> Vec<f64> {
    estimate
        .iter()
        .zip(truth)
        .map(|(e, t)| {
            if *t == 0.0 {
                (e - t).abs() * 100.0
            } else {
                100.0 * (e - t).abs() / t.abs()
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_values() {
        // o = [1, 2, 3, 4], p = [1.5, 2, 2, 4]: residuals [-0.5, 0, 1, 0], SSE = 1.25.
        let o = [1.0, 2.0, 3.0, 4.0];
        let p = [1.5, 2.0, 2.0, 4.0];
        assert!((rms(&o, &p).unwrap() - (1.25f64 / 4.0).sqrt()).abs() < 1e-15);
        // Σo² = 30
        assert!((rsd(&o, &p).unwrap() - (1.25f64 / 30.0).sqrt()).abs() < 1e-15);
        // o_m = 2.5; |p − o_m| = [1, .5, .5, 1.5]; |o − o_m| = [1.5, .5, .5, 1.5];
        // sums [2.5, 1, 1, 3] squared: 6.25 + 1 + 1 + 9 = 17.25
        assert!((agreement_index(&o, &p).unwrap() - (1.0 - 1.25 / 17.25)).abs() < 1e-15);
    }

    #[test]
    fn identical_series_limits() {
        let o = [0.3, -1.0, 2.0, 5.0];
        let e = error_indices(&o, &o).unwrap();
        assert_eq!((e.rms, e.rsd, e.ai), (0.0, 0.0, 1.0));
    }

    #[test]
    fn constant_and_zero_series() {
        let c = [2.0; 5];
        assert_eq!(agreement_index(&c, &c).unwrap(), 1.0);
        // A constant observation predicted wrongly: AI well defined (= 0 here, since
        // every |p − o_m| = |o − p| and o − o_m = 0).
        assert_eq!(agreement_index(&c, &[3.0; 5]).unwrap(), 0.0);
        let z = [0.0; 5];
        assert_eq!(rsd(&z, &z).unwrap(), 0.0);
        // Σ(o/s)² underflows with a prediction 1e195 times the observation: that was
        // reported as an observed series of zeros.
        assert!(matches!(
            rsd(&[6.67, -3.0], &[1e195, 2e195]),
            Err(PrrrpError::NonFinite { .. })
        ));
        assert!(matches!(
            rsd(&z, &[1.0; 5]),
            Err(PrrrpError::InvalidParameter { .. })
        ));
    }

    #[test]
    fn bad_input() {
        assert!(matches!(
            rms(&[1.0], &[1.0, 2.0]),
            Err(PrrrpError::ShapeMismatch { .. })
        ));
        assert!(matches!(
            rms(&[], &[]),
            Err(PrrrpError::TooFewSamples { .. })
        ));
        assert!(matches!(
            agreement_index(&[1.0, f64::NAN], &[1.0, 2.0]),
            Err(PrrrpError::NonFinite { row: Some(1), .. })
        ));
    }

    #[test]
    fn relative_errors() {
        let r = relative_errors_percent(&[1.1, 0.5, 0.01], &[1.0, -0.5, 0.0]);
        assert!(
            (r[0] - 10.0).abs() < 1e-12
                && (r[1] - 200.0).abs() < 1e-12
                && (r[2] - 1.0).abs() < 1e-12
        );
    }
}

#[cfg(test)]
mod extreme {
    use super::*;

    /// Values near the ends of the f64 range give the exact indices (the indices are
    /// homogeneous of degree 1 and 0 in the data), not ∞ or NaN.
    #[test]
    fn scale_does_not_matter() {
        let o = [1.0, -2.0, 3.0, 0.5];
        let p = [1.5, -2.0, 2.0, 0.25];
        for k in [1e-300, 1e-160, 1.0, 1e150, 1e300] {
            let (os, ps): (Vec<f64>, Vec<f64>) =
                o.iter().zip(&p).map(|(a, b)| (a * k, b * k)).unzip();
            let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-300);
            assert!(rel(rms(&os, &ps).unwrap(), k * rms(&o, &p).unwrap()) < 1e-14);
            assert!(rel(rsd(&os, &ps).unwrap(), rsd(&o, &p).unwrap()) < 1e-14);
            assert!(
                rel(
                    agreement_index(&os, &ps).unwrap(),
                    agreement_index(&o, &p).unwrap()
                ) < 1e-14
            );
        }
        assert!(rms(&[f64::MAX, -f64::MAX], &[-f64::MAX, f64::MAX]).is_err());
        // A tiny observed series next to a huge prediction: RSD is huge but representable.
        let r = rsd(&[8e133, 0.0], &[5e287, 5e287]).unwrap();
        assert!(
            (r / (5e287 * 2f64.sqrt() / 8e133) - 1.0).abs() < 1e-12,
            "{r}"
        );
    }
}
