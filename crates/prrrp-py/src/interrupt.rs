//! Ctrl-C and progress for long computations. A computation runs with the GIL released on
//! a scoped worker thread under its own [`StopFlag`] while the calling thread waits for it
//! in short slices. Between slices the calling thread — the only one that ever calls into
//! Python — runs Python's signal handlers (`check_signals`) and hands the progress the
//! worker reported to the Python callback. Workers only write progress into a Rust buffer
//! (never taking the GIL), and the buffer's lock is released before Python is called, so a
//! callback can never deadlock with a worker. On Ctrl-C, or when the callback raises, the
//! call's flag is raised, the worker returns `Interrupted` at its next check (no partial
//! result) and the caller gets the Python exception. Other calls, in other threads, are
//! not affected.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::mpsc::{channel, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use prrrp_core::StopFlag;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the waiting thread looks for signals and delivers progress.
const POLL: Duration = Duration::from_millis(40);

/// Reports kept between two deliveries. Every report is delivered, in order, unless more
/// than this many arrive within one slice: then a report of the same stage as the last
/// one replaces it (the callback still sees each stage's latest count), so the buffer
/// grows past this only by the number of stage changes.
const MAX_PENDING: usize = 4096;

/// Progress reports of a running computation, written by its (worker) threads and read by
/// the waiting thread. Holds no Python object.
#[derive(Default)]
pub(crate) struct Progress {
    pending: Mutex<Vec<Report>>,
}

/// One progress report: `done` of `total` steps of `stage`, and a value some callbacks
/// also receive (the excitation's best cond(W)).
struct Report {
    stage: String,
    done: usize,
    total: usize,
    value: f64,
}

impl Progress {
    /// Records that `stage` has `done` of `total` steps (see [`MAX_PENDING`]).
    pub(crate) fn report(&self, stage: &str, done: usize, total: usize) {
        self.report_value(stage, done, total, f64::NAN);
    }

    /// [`Progress::report`] with a value for [`Callback::CountsValue`].
    pub(crate) fn report_value(&self, stage: &str, done: usize, total: usize, value: f64) {
        let mut pending = self.pending.lock().unwrap_or_else(|p| p.into_inner());
        if pending.len() >= MAX_PENDING {
            if let Some(last) = pending.last_mut().filter(|l| l.stage == stage) {
                // Workers may report out of order; keep the furthest count.
                if done >= last.done {
                    (last.done, last.total, last.value) = (done, total, value);
                }
                return;
            }
        }
        pending.push(Report {
            stage: stage.into(),
            done,
            total,
            value,
        });
    }

    fn take(&self) -> Vec<Report> {
        std::mem::take(&mut *self.pending.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

/// How reports reach the Python callback.
#[derive(Clone, Copy)]
pub(crate) enum Callback<'a> {
    /// `callback(stage, done, total)`.
    Staged(&'a Py<PyAny>),
    /// `callback(done, total)` (single-stage computations).
    Counts(&'a Py<PyAny>),
    /// `callback(done, total, value)`.
    CountsValue(&'a Py<PyAny>),
}

impl Callback<'_> {
    fn deliver(self, py: Python<'_>, reports: Vec<Report>) -> PyResult<()> {
        for r in reports {
            match self {
                Callback::Staged(cb) => cb.call1(py, (r.stage, r.done, r.total))?,
                Callback::Counts(cb) => cb.call1(py, (r.done, r.total))?,
                Callback::CountsValue(cb) => cb.call1(py, (r.done, r.total, r.value))?,
            };
        }
        Ok(())
    }
}

/// Runs `f` as described in the module docs and returns its value.
pub(crate) fn interruptible<T, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    F: FnOnce() -> T + Send,
{
    with_progress(py, None, |_| f())
}

/// Runs `f` as described in the module docs, delivering what it reports to `callback`
/// from the calling thread; the callback's first exception stops the computation and is
/// raised.
pub(crate) fn with_progress<T, F>(
    py: Python<'_>,
    callback: Option<Callback<'_>>,
    f: F,
) -> PyResult<T>
where
    T: Send,
    F: FnOnce(&Progress) -> T + Send,
{
    let flag = StopFlag::new();
    let progress = Progress::default();
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
    let deliver = |py: Python<'_>| match callback {
        Some(cb) => cb.deliver(py, progress.take()),
        None => Ok(()),
    };
    std::thread::scope(|s| {
        let (worker_flag, progress) = (flag.clone(), &progress);
        s.spawn(move || {
            // A panic must not cross into Python; it becomes a RuntimeError below.
            let _ = tx.send(catch_unwind(AssertUnwindSafe(|| {
                worker_flag.run(|| f(progress))
            })));
        });
        // Stops the worker and waits for it; its result is dropped.
        let abandon = |py: Python<'_>, e: PyErr| {
            flag.raise();
            let _ = py.detach(|| recv(None));
            Err(e)
        };
        loop {
            match py.detach(|| recv(Some(POLL))) {
                Ok(Ok(v)) => {
                    deliver(py)?;
                    return Ok(v);
                }
                Ok(Err(_)) | Err(RecvTimeoutError::Disconnected) => {
                    return Err(PyRuntimeError::new_err(
                        "internal error: a prrrp worker thread panicked; please report it",
                    ))
                }
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals().and_then(|()| deliver(py)) {
                        return abandon(py, e);
                    }
                }
            }
        }
    })
}

/// Asks every running prrrp computation of the process to stop (see `_prrrp.pyi`).
#[pyfunction]
fn request_stop() {
    prrrp_core::interrupt::request_stop();
}

/// Lowers the flag of `request_stop` (see `_prrrp.pyi`).
#[pyfunction]
fn clear_stop() {
    prrrp_core::interrupt::clear_stop();
}

/// Whether the flag of `request_stop` is raised (see `_prrrp.pyi`).
#[pyfunction]
fn stop_requested() -> bool {
    prrrp_core::interrupt::stop_requested()
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(request_stop, m)?)?;
    m.add_function(wrap_pyfunction!(clear_stop, m)?)?;
    m.add_function(wrap_pyfunction!(stop_requested, m)?)?;
    Ok(())
}
