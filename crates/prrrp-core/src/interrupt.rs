//! Cooperative interruption and size bounds of long computations.
//!
//! Long loops (simulation, excitation optimisation, sensitivity grids, the study) poll for a
//! stop and return [`PrrrpError::Interrupted`] once one is requested, leaving no partial
//! result. Two flags are polled:
//! - a **per-call** [`StopFlag`]: [`StopFlag::run`] makes it the current thread's flag for
//!   the duration of a call, and the worker threads prrrp spawns inherit it, so raising it
//!   stops that call and nothing else (the Python bindings give every call its own, so
//!   Ctrl-C in one thread does not interrupt a computation running in another);
//! - the **process-wide** flag of [`request_stop`] / [`clear_stop`], which stops every
//!   computation of the process (for hosts that want exactly that).
//!
//! Every size a caller asks for (samples of a simulation, grid points, random states) is
//! checked against [`MAX_SAMPLES`] before anything is allocated.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use crate::error::{PrrrpError, Result};

static STOP: AtomicBool = AtomicBool::new(false);

thread_local! {
    static CURRENT: RefCell<Option<StopFlag>> = const { RefCell::new(None) };
}

/// Asks every running prrrp computation of this process to stop at its next check.
pub fn request_stop() {
    STOP.store(true, Ordering::Relaxed);
}

/// Lowers the flag of [`request_stop`], so that new computations run.
pub fn clear_stop() {
    STOP.store(false, Ordering::Relaxed);
}

/// Whether a stop has been requested for the computation running on this thread: the
/// process-wide flag of [`request_stop`] or this thread's [`StopFlag`].
pub fn stop_requested() -> bool {
    STOP.load(Ordering::Relaxed)
        || CURRENT.with(|c| c.borrow().as_ref().is_some_and(StopFlag::is_raised))
}

/// A stop flag for one call (see the module docs): cheap to clone (the clones share the
/// flag), raised from any thread.
///
/// ```
/// use prrrp_core::StopFlag;
///
/// let flag = StopFlag::new();
/// let seen = flag.run(|| prrrp_core::stop_requested());
/// assert!(!seen);
/// flag.raise();
/// assert!(flag.run(prrrp_core::stop_requested));
/// assert!(!prrrp_core::stop_requested()); // other calls are not affected
/// ```
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// A lowered flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks the call running under this flag (and its worker threads) to stop at its next
    /// check.
    pub fn raise(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`StopFlag::raise`] was called.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// Runs `f` with this flag as the current thread's stop flag (restored afterwards, also
    /// when `f` panics).
    pub fn run<R>(&self, f: impl FnOnce() -> R) -> R {
        within(Some(self.clone()), f)
    }
}

/// The current thread's [`StopFlag`], for handing to worker threads ([`within`]).
pub(crate) fn current() -> Option<StopFlag> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Runs `f` with `flag` as the current thread's stop flag; worker threads spawned by a
/// computation call this with the spawning thread's [`current`] flag.
pub(crate) fn within<R>(flag: Option<StopFlag>, f: impl FnOnce() -> R) -> R {
    struct Restore(Option<StopFlag>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let previous = self.0.take();
            CURRENT.with(|c| *c.borrow_mut() = previous);
        }
    }
    let previous = CURRENT.with(|c| std::mem::replace(&mut *c.borrow_mut(), flag));
    let _restore = Restore(previous);
    f()
}

/// `Err(Interrupted)` once a stop has been requested; loops call it every iteration (an
/// atomic load and a thread-local read, a few nanoseconds).
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
