//! `prrrp.preprocess`: measured (t, q, τ) → filtered q, q̇, q̈, τ.

use prrrp_core::{preprocess as core_preprocess, PreprocessConfig, NDOF};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{vector, Samples, UInt};
use crate::data::dataset::dataset_dict;
use crate::errors::ToPyResult;

array_pyfunctions! {
/// Turns uniformly sampled measurements `t` (N,) s, `q` (N, 5), `tau` (N, 5) into a dict of
/// arrays `t`, `q`, `qd`, `qdd`, `tau`: zero-phase Butterworth low-pass (`cutoff_hz` Hz,
/// `order` 2/4/6/8) of q (and τ if `filter_torque`), central differences, `trim` samples
/// dropped at each end (default ⌈3·fs/fc⌉), then every `decimate`-th sample kept.
///
/// Errors name the column and row (NaN → `NonFiniteError`, non-increasing t →
/// `NonIncreasingTimeError`); too little data left → `TooFewSamplesError`.
#[pyfunction]
#[pyo3(signature = (t, q, tau, *, cutoff_hz=5.0, order=4, filter_torque=true, trim=None,
    decimate=UInt(1)))]
fn preprocess(py, t, q, tau;
    cutoff_hz: f64,
    order: usize,
    filter_torque: bool,
    trim: Option<UInt<usize>>,
    decimate: UInt<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let trim = trim.map(|v| v.0);
    let decimate = decimate.0;
    let t = vector(t, "t")?;
    let q = Samples::<NDOF>::extract_rows(q, "q")?;
    let tau = Samples::<NDOF>::extract_rows(tau, "tau")?;
    let config = PreprocessConfig {
        cutoff_hz,
        order,
        filter_torque,
        trim,
        decimate,
    };
    let data = py.detach(|| core_preprocess(&t, &q, &tau, &config));
    dataset_dict(py, &data.to_py(py)?)
}
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(preprocess, m)?)?;
    Ok(())
}
