//! `prrrp.design_excitation`: the excitation design of any robot (see
//! `prrrp_core::optimise_chain_excitation`).

use prrrp_core::{optimise_chain_excitation, ChainExcitationConfig, JointLimit};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{check_len, to_array, vector, UInt};
use crate::errors::ToPyResult;
use crate::interrupt::{with_progress, Callback};
use crate::models::chain::PySerialChain;

/// Per-joint limits: the chain's own, with the keys of `overrides` (lower, upper,
/// velocity, acceleration; (n,) arrays, NaN = not given) replacing them.
fn limits(
    chain: &prrrp_core::DynChain,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<Vec<JointLimit>> {
    let mut out: Vec<JointLimit> = chain.joint_info().iter().map(|j| j.limit).collect();
    let Some(d) = overrides else { return Ok(out) };
    let n = out.len();
    for (key, value) in d.iter() {
        let key: String = key.extract()?;
        let v = vector(&value, "limits")?;
        check_len(d.py(), &format!("limits['{key}']"), v.len(), n, "")?;
        for (l, x) in out.iter_mut().zip(v) {
            match key.as_str() {
                "lower" => l.lower = x,
                "upper" => l.upper = x,
                "velocity" => l.velocity = x,
                "acceleration" => l.acceleration = x,
                _ => {
                    return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                        "unknown limit '{key}': use lower, upper, velocity, acceleration"
                    )))
                }
            }
        }
    }
    Ok(out)
}

/// See `_prrrp.pyi`.
#[pyfunction]
#[pyo3(signature = (robot, *, harmonics=UInt(5), base_frequency=0.1, sample_rate=10.0,
    margin=0.05, seed=UInt(0), restarts=UInt(16), max_evaluations=UInt(2000), limits=None,
    progress=None))]
#[allow(clippy::too_many_arguments)]
fn design_excitation<'py>(
    py: Python<'py>,
    robot: &PySerialChain,
    harmonics: UInt<usize>,
    base_frequency: f64,
    sample_rate: f64,
    margin: f64,
    seed: UInt<u64>,
    restarts: UInt<usize>,
    max_evaluations: UInt<usize>,
    limits: Option<&Bound<'py, PyDict>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let chain = robot.chain();
    let lim = self::limits(chain, limits)?;
    let base = robot.default_base(py)?.clone();
    let config = ChainExcitationConfig {
        harmonics: harmonics.0,
        base_frequency_hz: base_frequency,
        sample_rate_hz: sample_rate,
        margin,
        seed: seed.0,
        restarts: restarts.0,
        max_evaluations: max_evaluations.0,
    };
    let callback = progress.as_ref().map(Callback::Counts);
    let result = with_progress(py, callback, |report| {
        optimise_chain_excitation(chain, &base, Some(&lim), &config, |done, total| {
            report.report("excitation", done, total)
        })
    })?;
    let e = result.to_py(py)?;
    let t = &e.trajectory;
    let (n, h) = (t.offsets().len(), t.harmonics());
    let out = PyDict::new(py);
    let offsets = to_array(py, t.offsets().to_vec(), None, &[n])?;
    let a = to_array(py, t.a().to_vec(), None, &[n, h])?;
    let b = to_array(py, t.b().to_vec(), None, &[n, h])?;
    let traj = py
        .import("prrrp")?
        .getattr("ChainTrajectory")?
        .call_method1(
            "fourier",
            (t.omega(), offsets.clone(), a.clone(), b.clone()),
        )?;
    out.set_item("trajectory", traj)?;
    out.set_item("omega", t.omega())?;
    out.set_item("offsets", offsets)?;
    out.set_item("a", a)?;
    out.set_item("b", b)?;
    out.set_item("period", e.period)?;
    out.set_item("cond_initial", e.cond_initial)?;
    out.set_item("cond_final", e.cond_final)?;
    out.set_item("evaluations", e.evaluations)?;
    let usage: Vec<f64> = e.limit_usage.iter().flatten().copied().collect();
    out.set_item("limit_usage", to_array(py, usage, None, &[n, 3])?)?;
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(design_excitation, m)?)
}
