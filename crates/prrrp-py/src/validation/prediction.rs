//! Validation of estimates (paper section 5.1) and the sensitivity sweep (Table 6, Fig. 8):
//! `prrrp.validate`, `prrrp.torque_prediction`, `prrrp.sensitivity`. Results are dicts of
//! numpy arrays.

use prrrp_core::{
    sensitivity as core_sensitivity, torque_prediction as core_torque, validate as core_validate,
    validate_identified_model, validate_torque_prediction, ErrorIndices, Lambda,
    ParameterisedModel, PrrrpError, Robot, SensitivityConfig, SensorNoise, TorquePrediction,
    TorqueValidation, ValidationConfig, NDOF, NPARAM, STANDARD_GRAVITY,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use numpy::PyArrayMethods;

use crate::arrays::{fixed_or, fixed_vector, rows_to_array, to_array, vector, UInt};
use crate::data::dataset::{dataset_from, PyDataset};
use crate::errors::{to_pyerr, ToPyResult};
use crate::identification::PyIdentifiedModel;
use crate::interrupt::{interruptible, with_progress, Callback};
use crate::models::chain::{PyBaseParameters, PySerialChain};
use crate::motion::simulation::{config as sim_config, record_dict, SimArgs};
use crate::motion::trajectories::SinusoidReference;

fn paper_lambda() -> Lambda {
    Robot::paper().base_parameters()
}

fn torque_dict<'py>(py: Python<'py>, t: &TorquePrediction) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("rms", to_array(py, t.rms.to_vec(), None, &[NDOF])?)?;
    d.set_item(
        "relative_percent",
        to_array(py, t.relative_percent.to_vec(), None, &[NDOF])?,
    )?;
    d.set_item("predicted", rows_to_array(py, &t.predicted)?)?;
    Ok(d)
}

fn indices_dict<'py>(py: Python<'py>, e: &[ErrorIndices; NDOF]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let pick = |f: fn(&ErrorIndices) -> f64| e.iter().map(f).collect::<Vec<f64>>();
    d.set_item("rms", to_array(py, pick(|x| x.rms), None, &[NDOF])?)?;
    d.set_item("rsd", to_array(py, pick(|x| x.rsd), None, &[NDOF])?)?;
    d.set_item("ai", to_array(py, pick(|x| x.ai), None, &[NDOF])?)?;
    Ok(d)
}

/// The estimates as (name, λ) pairs from a dict {name: λ} or a sequence of (name, λ).
fn estimates_from(obj: &Bound<'_, PyAny>) -> PyResult<Vec<(String, Lambda)>> {
    let py = obj.py();
    let pairs: Vec<(String, Bound<'_, PyAny>)> = if let Ok(d) = obj.cast::<PyDict>() {
        d.iter()
            .map(|(k, v)| Ok((k.extract::<String>()?, v)))
            .collect::<PyResult<_>>()?
    } else {
        obj.try_iter()
            .and_then(|it| {
                it.map(|x| x.and_then(|x| x.extract::<(String, Bound<'_, PyAny>)>()))
                    .collect::<PyResult<_>>()
            })
            .map_err(|_| {
                to_pyerr(
                    py,
                    &PrrrpError::InvalidParameter {
                        field: "estimates".into(),
                        value: f64::NAN,
                        reason: "must be a dict {name: lam (8,)} or a list of (name, lam) pairs",
                    },
                )
            })?
    };
    pairs
        .into_iter()
        .map(|(name, v)| {
            Ok((
                name,
                Lambda::from(fixed_vector::<NPARAM>(&v, "estimates[..]")?),
            ))
        })
        .collect()
}

/// The reference (a `SinusoidReference`, default the core's validation reference).
fn validation_config(
    reference: Option<PyRef<'_, SinusoidReference>>,
    duration: f64,
    seed: u64,
    sim: prrrp_core::SimulationConfig,
) -> ValidationConfig {
    let d = ValidationConfig::default();
    ValidationConfig {
        reference: reference.map_or(d.reference, |r| r.inner),
        duration,
        simulation: sim,
        seed,
    }
}

/// Validates estimates λ̂ of the paper robot on a reference not used for estimation (see
/// `_prrrp.pyi` for arguments and the result's keys).
#[pyfunction]
#[pyo3(signature = (estimates, *, true_lam=None, controller_lam=None, relative_errors=true,
    reference=None, duration=10.0, seed=UInt(1), dt=0.02, substeps=UInt(20), kp=None, kd=None,
    q_noise=None, tau_noise=None))]
#[allow(clippy::too_many_arguments)]
fn validate<'py>(
    py: Python<'py>,
    estimates: &Bound<'py, PyAny>,
    true_lam: Option<&Bound<'py, PyAny>>,
    controller_lam: Option<&Bound<'py, PyAny>>,
    relative_errors: bool,
    reference: Option<PyRef<'py, SinusoidReference>>,
    duration: f64,
    seed: UInt<u64>,
    dt: f64,
    substeps: UInt<usize>,
    kp: Option<&Bound<'py, PyAny>>,
    kd: Option<&Bound<'py, PyAny>>,
    q_noise: Option<&Bound<'py, PyAny>>,
    tau_noise: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let seed = seed.0;
    let substeps = substeps.0;
    let estimates = estimates_from(estimates)?;
    let truth = fixed_or::<NPARAM>(true_lam, "true_lam", paper_lambda())?;
    let ctrl = fixed_or::<NPARAM>(controller_lam, "controller_lam", truth)?;
    let args = SimArgs::gains(kp, kd).noise(q_noise, None, tau_noise);
    let sim = sim_config(dt, substeps, args, SensorNoise::default(), seed)?;
    let cfg = validation_config(reference, duration, seed, sim);
    let model = Robot::paper().model();
    let known = relative_errors.then_some(truth);
    let report = interruptible(py, || {
        core_validate(&model, &truth, &ctrl, &estimates, known.as_ref(), &cfg)
    })?
    .to_py(py)?;
    let methods = PyList::empty(py);
    for m in &report.methods {
        let d = PyDict::new(py);
        d.set_item("method", &m.method)?;
        d.set_item(
            "lam",
            to_array(py, m.lambda.as_slice().to_vec(), None, &[NPARAM])?,
        )?;
        d.set_item("q", rows_to_array(py, &m.q)?)?;
        d.set_item("indices", indices_dict(py, &m.indices)?)?;
        d.set_item("torque", torque_dict(py, &m.torque)?)?;
        match &m.relative_error_percent {
            Some(v) => d.set_item(
                "relative_error_percent",
                to_array(py, v.clone(), None, &[v.len()])?,
            )?,
            None => d.set_item("relative_error_percent", py.None())?,
        }
        methods.append(d)?;
    }
    let out = PyDict::new(py);
    out.set_item("truth", record_dict(py, &report.truth)?)?;
    out.set_item("methods", methods)?;
    Ok(out)
}

/// Predicts the torques of `data` (a `Dataset` or a dict with t, q, qd, qdd, tau) with
/// Φ(q, q̇, q̈)·λ̂ and compares them with data's tau.
#[pyfunction]
#[pyo3(signature = (data, lam, *, gravity=STANDARD_GRAVITY))]
fn torque_prediction<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    lam: &Bound<'py, PyAny>,
    gravity: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let data = dataset_from(data)?;
    let lam = Lambda::from(fixed_vector::<NPARAM>(lam, "lam")?);
    let model = crate::models::regressor::model(py, gravity)?;
    let t = py.detach(|| core_torque(&model, &data, &lam)).to_py(py)?;
    torque_dict(py, &t)
}

/// The sensitivity sweep of the paper robot around `nominal` (default Table 3 λ); see
/// `_prrrp.pyi`. Non-physical variations are NaN in `rms` and False in `physical`.
#[pyfunction]
#[pyo3(signature = (*, nominal=None, range=0.5, points=UInt(11), threads=UInt(0), reference=None,
    duration=10.0, dt=0.02, substeps=UInt(20), kp=None, kd=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn sensitivity<'py>(
    py: Python<'py>,
    nominal: Option<&Bound<'py, PyAny>>,
    range: f64,
    points: UInt<usize>,
    threads: UInt<usize>,
    reference: Option<PyRef<'py, SinusoidReference>>,
    duration: f64,
    dt: f64,
    substeps: UInt<usize>,
    kp: Option<&Bound<'py, PyAny>>,
    kd: Option<&Bound<'py, PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let points = points.0;
    let threads = threads.0;
    let substeps = substeps.0;
    let nominal = fixed_or::<NPARAM>(nominal, "nominal", paper_lambda())?;
    // Sensor noise is not used by the sweep.
    let args = SimArgs::gains(kp, kd);
    let sim = sim_config(dt, substeps, args, SensorNoise::default(), 0)?;
    let d = SensitivityConfig::default();
    let cfg = SensitivityConfig {
        range,
        points,
        validation: validation_config(reference, duration, d.validation.seed, sim),
        threads,
    };
    let model = Robot::paper().model();
    let callback = progress.as_ref().map(Callback::Counts);
    let r = with_progress(py, callback, |p| {
        core_sensitivity(&model, &nominal, &cfg, &|done, total| {
            p.report("sensitivity", done, total)
        })
    })?
    .to_py(py)?;
    let k = r.factors.len();
    let mut rms = Vec::with_capacity(NPARAM * k * NDOF);
    let mut physical = Vec::with_capacity(NPARAM * k);
    for row in &r.rms {
        for cell in row {
            match cell {
                Some(v) => rms.extend_from_slice(v),
                None => rms.extend([f64::NAN; NDOF]),
            }
            physical.push(cell.is_some());
        }
    }
    let ranges: Vec<f64> = r.ranges.iter().flat_map(|&(a, b)| [a, b]).collect();
    let out = PyDict::new(py);
    out.set_item("factors", to_array(py, r.factors.clone(), None, &[k])?)?;
    out.set_item("ranges", to_array(py, ranges, Some(NPARAM), &[2])?)?;
    out.set_item("rms", to_array(py, rms, Some(NPARAM), &[k, NDOF])?)?;
    let phys = numpy::PyArray1::from_vec(py, physical).reshape([NPARAM, k])?;
    out.set_item("physical", phys)?;
    Ok(out)
}

fn torque_validation_dict<'py>(
    py: Python<'py>,
    v: &TorqueValidation,
) -> PyResult<Bound<'py, PyDict>> {
    let n = v.dof();
    let d = PyDict::new(py);
    d.set_item("rms", to_array(py, v.rms(), None, &[n])?)?;
    d.set_item("rsd", to_array(py, v.rsd(), None, &[n])?)?;
    d.set_item("ai", to_array(py, v.agreement_index(), None, &[n])?)?;
    d.set_item(
        "predicted",
        to_array(py, v.predicted.clone(), Some(v.len()), &[n])?,
    )?;
    Ok(d)
}

/// Torque-prediction validation of a model of any robot on a `Dataset` it was not fitted
/// on; see `_prrrp.pyi`.
#[pyfunction]
#[pyo3(signature = (model, data, *, beta=None, base=None))]
fn validate_model<'py>(
    py: Python<'py>,
    model: &Bound<'py, PyAny>,
    data: PyRef<'py, PyDataset>,
    beta: Option<&Bound<'py, PyAny>>,
    base: Option<PyRef<'py, PyBaseParameters>>,
) -> PyResult<Bound<'py, PyDict>> {
    let data = &data.inner;
    let report = if let Ok(m) = model.extract::<PyRef<'_, PyIdentifiedModel>>() {
        if beta.is_some() || base.is_some() {
            return Err(to_pyerr(
                py,
                &PrrrpError::InvalidParameter {
                    field: "beta/base".into(),
                    value: f64::NAN,
                    reason: "an IdentifiedModel carries its own β and base analysis:                              leave beta and base out",
                },
            ));
        }
        let m = &m.inner;
        interruptible(py, || validate_identified_model(m, data))?
    } else if let Ok(chain) = model.extract::<PyRef<'_, PySerialChain>>() {
        match beta {
            None => {
                let c = chain.chain();
                interruptible(py, || validate_torque_prediction(c, data))?
            }
            Some(beta) => {
                let beta = vector(beta, "beta")?;
                let base = match &base {
                    Some(b) => &b.inner,
                    None => chain.default_base(py)?,
                };
                let bm = chain.chain().base_model(base).to_py(py)?;
                let pm = ParameterisedModel::new(bm, nalgebra::DVector::from_vec(beta))
                    .to_py(py)?;
                interruptible(py, || validate_torque_prediction(&pm, data))?
            }
        }
    } else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "`model` must be a prrrp.IdentifiedModel or a prrrp.SerialChain, got {}",
            model.get_type().name()?
        )));
    }
    .to_py(py)?;
    torque_validation_dict(py, &report)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(validate_model, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(torque_prediction, m)?)?;
    m.add_function(wrap_pyfunction!(sensitivity, m)?)?;
    Ok(())
}
