//! Cooperative interruption and size bounds of long computations.
//!
//! Long loops (simulation, excitation optimisation, sensitivity grids, the study) poll a
//! process-wide stop flag and return [`PrrrpError::Interrupted`] once it is raised, leaving
//! no partial result. A host raises it with [`request_stop`] — the Python bindings do so
//! when Ctrl-C arrives while a computation runs — and lowers it with [`clear_stop`]. Every
//! size a caller asks for (samples of a simulation, grid points, random states) is checked
//! against [`MAX_SAMPLES`] before anything is allocated.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{PrrrpError, Result};

static STOP: AtomicBool = AtomicBool::new(false);

/// Asks every running prrrp computation of this process to stop at its next check.
pub fn request_stop() {
    STOP.store(true, Ordering::Relaxed);
}

/// Lowers the flag of [`request_stop`], so that new computations run.
pub fn clear_stop() {
    STOP.store(false, Ordering::Relaxed);
}

/// Whether a stop has been requested.
pub fn stop_requested() -> bool {
    STOP.load(Ordering::Relaxed)
}

/// `Err(Interrupted)` once a stop has been requested; loops call it every iteration (one
/// relaxed atomic load, about a nanosecond).
#[inline]
pub(crate) fn check(what: &'static str) -> Result<()> {
    if stop_requested() {
        Err(PrrrpError::Interrupted { what })
    } else {
        Ok(())
    }
}

/// Largest number of samples (time steps, states, grid points, data rows) that one call
/// produces or accepts: 10 million, i.e. 2.8 h of a 1 kHz log. A 5-joint simulation
/// record of that length takes about 3 GB; larger requests are refused before allocating.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Checks a requested count against [`MAX_SAMPLES`] and converts it to `usize`. `count`
/// may be fractional (a duration over a step); non-finite or negative counts are refused.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] naming `field`, with the count asked for.
pub fn check_count(field: &str, count: f64, hint: &'static str) -> Result<usize> {
    if !(count.is_finite() && count >= 0.0 && count <= MAX_SAMPLES as f64) {
        return Err(PrrrpError::InvalidParameter {
            field: field.into(),
            value: count,
            reason: hint,
        });
    }
    Ok(count as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_bounded() {
        assert_eq!(check_count("n", 12.0, "").unwrap(), 12);
        for bad in [-1.0, f64::NAN, f64::INFINITY, 1e9, 2f64.powi(63)] {
            assert!(check_count("n", bad, "too large").is_err(), "{bad}");
        }
    }
}
