//! Python bindings of prrrp: the private native module `prrrp._prrrp`, re-exported by the
//! pure-Python package `prrrp` (python/prrrp/__init__.py, typed by python/prrrp/_prrrp.pyi).
//!
//! The crate is thin: it converts numpy arrays to the core's types and back, loops over
//! batches with the GIL released, reports progress and honours Ctrl-C, and maps errors to
//! Python exceptions; every computation is a call into `prrrp-core`. Its modules mirror the
//! core's layers (`models`, `data`, `motion`, `estimators`, `identification`, `online`,
//! `validation`, `paper`), beside the shared plumbing: `errors` (the exception hierarchy
//! and `ToPyResult`), `arrays` (numpy ⇄ nalgebra, shape checks, the batched loop) and
//! `interrupt` (stop flags and progress). Layers: docs/architecture.md.

#[macro_use]
mod macros;

mod arrays;
mod data;
mod errors;
mod estimators;
mod figures;
mod identification;
mod interrupt;
mod models;
mod motion;
mod online;
mod paper;
mod validation;

use pyo3::prelude::*;

/// Whether `v` lies in [MIN_FACTOR, MAX_FACTOR] (false for NaN and infinities): the
/// core's own check, so that Python's options are bounded as the library's fields are.
#[pyfunction]
fn is_factor(v: f64) -> bool {
    prrrp_core::is_factor(v)
}

/// The native part of prrrp; import `prrrp` instead.
#[pymodule]
fn _prrrp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("NDOF", prrrp_core::NDOF)?;
    m.add("NPARAM", prrrp_core::NPARAM)?;
    m.add("STANDARD_GRAVITY", prrrp_core::STANDARD_GRAVITY)?;
    m.add("MAX_MAGNITUDE", prrrp_core::MAX_MAGNITUDE)?;
    m.add("MIN_FACTOR", prrrp_core::MIN_FACTOR)?;
    m.add("MAX_FACTOR", prrrp_core::MAX_FACTOR)?;
    m.add("MAX_HARMONICS", prrrp_core::MAX_HARMONICS)?;
    m.add("SETTLING_PERIODS", prrrp_core::SETTLING_PERIODS)?;
    m.add_function(wrap_pyfunction!(is_factor, m)?)?;
    errors::register(m)?;
    models::robot::register(m)?;
    models::chain::register(m)?;
    identification::register(m)?;
    data::dataset::register(m)?;
    validation::prediction::register(m)?;
    models::derivatives::register(m)?;
    models::regressor::register(m)?;
    motion::trajectories::register(m)?;
    motion::chain_excitation::register(m)?;
    motion::simulation::register(m)?;
    data::preprocessing::register(m)?;
    data::csv::register(m)?;
    estimators::register(m)?;
    validation::metrics::register(m)?;
    paper::study::register(m)?;
    online::register(m)?;
    interrupt::register(m)?;
    figures::register(m)?;
    Ok(())
}
