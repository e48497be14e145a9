//! Python bindings of prrrp: the private native module `prrrp._prrrp`, re-exported by the
//! pure-Python package `prrrp` (python/prrrp/__init__.py).
//!
//! The crate is thin: it converts numpy arrays to the core's fixed-size types and back,
//! loops over batches with the GIL released, and maps errors to Python exceptions. Every
//! computation is a call into `prrrp-core`. One file per concept:
//! - `errors`: the exception hierarchy and the one conversion trait `ToPyResult`;
//! - `arrays`: numpy ⇄ nalgebra, shape checks, the batched loop;
//! - `robot`: `Robot` and its dynamics;
//! - `chain`: `SerialChain` (any DH arm) and `BaseParameters`;
//! - `dataset`: `Dataset`, a validated identification data set;
//! - `validation`: `validate`, `torque_prediction`, `sensitivity`;
//! - `regressor`: `regressor`, `observation_matrix`, `singular_values`, `condition_number`;
//! - `derivatives`: the derivative result classes;
//! - `trajectories`: the excitation optimisation and reference trajectories;
//! - `simulation`: the closed- and open-loop simulators;
//! - `preprocessing`: filtering and differentiation of measurements;
//! - `estimators`: least squares and the online estimators;
//! - `metrics`: the error indices;
//! - `study`: the whole study as JSON;
//! - `online`: `OnlineIdentifier`, identification one sample at a time.

#[macro_use]
mod macros;

mod arrays;
mod data;
mod errors;
mod estimators;
mod identification;
mod interrupt;
mod models;
mod motion;
mod online;
mod paper;
mod validation;

use pyo3::prelude::*;

/// The native part of prrrp; import `prrrp` instead.
#[pymodule]
fn _prrrp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("NDOF", prrrp_core::NDOF)?;
    m.add("NPARAM", prrrp_core::NPARAM)?;
    m.add("STANDARD_GRAVITY", prrrp_core::STANDARD_GRAVITY)?;
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
    estimators::register(m)?;
    validation::metrics::register(m)?;
    paper::study::register(m)?;
    online::register(m)?;
    Ok(())
}
