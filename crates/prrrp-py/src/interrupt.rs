//! Ctrl-C for long computations. A computation runs with the GIL released on a scoped
//! worker thread while the calling thread waits for it in 50 ms slices and, between
//! slices, lets Python run its signal handlers (`check_signals`). On Ctrl-C the core's
//! stop flag is raised, the worker returns `Interrupted` at its next check (no partial
//! result), and the caller gets the `KeyboardInterrupt`.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the waiting thread looks for signals.
const POLL: Duration = Duration::from_millis(50);

/// Runs `f` as described in the module docs and returns its value.
pub(crate) fn interruptible<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> T + Send,
{
    let (tx, rx) = channel();
    // `detach` needs a `Sync` borrow; only this thread ever locks it.
    let rx = Mutex::new(rx);
    let recv = |timeout: Option<Duration>| {
        let rx = rx.lock().unwrap_or_else(|p| p.into_inner());
        match timeout {
            Some(t) => rx.recv_timeout(t),
            None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
        }
    };
    std::thread::scope(|s| {
        s.spawn(move || {
            // A panic must not cross into Python; it becomes a RuntimeError below.
            let _ = tx.send(catch_unwind(AssertUnwindSafe(f)));
        });
        loop {
            match py.detach(|| recv(Some(POLL))) {
                Ok(Ok(v)) => return Ok(v),
                Ok(Err(_)) | Err(RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err(
                        "internal error: a prrrp worker thread panicked; please report it",
                    ))
                }
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(signal) = py.check_signals() {
                        prrrp_core::request_stop();
                        // The worker stops at its next check; its result is dropped.
                        let _ = py.detach(|| recv(None));
                        prrrp_core::clear_stop();
                        return Err(signal);
                    }
                }
            }
        }
    })
}
