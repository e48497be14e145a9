//! The whole study of the paper (§5): `prrrp._prrrp.run_study_json`, wrapped by
//! `prrrp.run_study` (python/prrrp/__init__.py), which parses the JSON into a dict.

use std::sync::Mutex;

use prrrp_core::{run_study, Robot, StudyConfig};
use pyo3::prelude::*;

use crate::arrays::UInt;
use crate::errors::ToPyResult;
use crate::interrupt::interruptible;

/// Runs the study with `seed` on the paper robot and returns its JSON (schema_version 1).
/// `progress(stage, done, total)` is called from Rust (possibly from worker threads, with
/// the GIL re-acquired); its first exception is re-raised when the study returns.
#[pyfunction]
#[pyo3(signature = (seed=UInt(0), progress=None))]
fn run_study_json(
    py: Python<'_>,
    seed: UInt<u64>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let seed = seed.0;
    let config = StudyConfig {
        seed,
        ..StudyConfig::default()
    };
    let robot = Robot::paper();
    let callback_error: Mutex<Option<PyErr>> = Mutex::new(None);
    let slot = || match callback_error.lock() {
        Ok(g) => g,
        Err(p) => p.into_inner(),
    };
    let report = |stage: &str, done: usize, total: usize| {
        let Some(cb) = progress.as_ref() else { return };
        if slot().is_some() {
            return;
        }
        // The callback runs without the lock held: a worker that held it while calling
        // Python waited for the GIL that another worker, attached and waiting for the
        // lock, kept: `prrrp reproduce` and the study tests hung (futex deadlock).
        Python::attach(|py| {
            if let Err(e) = cb.call1(py, (stage, done, total)) {
                slot().get_or_insert(e);
            }
        });
    };
    let result = interruptible(py, || {
        run_study(&robot, &config, &report).and_then(|r| r.to_json())
    })?;
    let err = match callback_error.into_inner() {
        Ok(e) => e,
        Err(p) => p.into_inner(),
    };
    if let Some(e) = err {
        return Err(e);
    }
    result.to_py(py)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_study_json, m)?)?;
    Ok(())
}
