//! `prrrp.IdentifiedModel`: an identification result for any robot that predicts joint
//! torques on its own and saves to / loads from JSON (`docs/model-schema.md`).

use std::path::{Path, PathBuf};

use prrrp_core::{IdentifiedModel, PrrrpError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{dyn_samples_of, index_arg, map_samples_with, to_array, Out};
use crate::errors::{to_pyerr, Exc, ToPyResult};
use crate::models::chain::PySerialChain;

/// Largest model file `IdentifiedModel.load` reads, bytes (256 MiB). A model of a 7-joint
/// arm is ~30 kB; one of 100 joints with its full covariance ~40 MB. The bound keeps
/// `/dev/zero` or a mistaken log from exhausting memory before the parser can complain.
pub(crate) const MAX_MODEL_FILE_BYTES: u64 = 256 << 20;

/// The text of a model file: a regular file (checked with `stat` before opening, since
/// opening a FIFO blocks) of at most [`MAX_MODEL_FILE_BYTES`]. Errors: (what, message).
fn read_model_file(path: &Path) -> Result<String, (&'static str, String)> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| {
        (
            "path",
            format!("cannot read the model file ({e}); check the path"),
        )
    })?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a folder"
        } else {
            "not a regular file (a pipe, socket or device)"
        };
        return Err((
            "path",
            format!("{kind}; give a model.json written by IdentifiedModel.save"),
        ));
    }
    if meta.len() > MAX_MODEL_FILE_BYTES {
        return Err((
            "size",
            format!(
                "{} bytes is more than the {MAX_MODEL_FILE_BYTES} bytes a model file may have; \
                 check the path",
                meta.len()
            ),
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| {
        (
            "path",
            format!("cannot read the model file ({e}); check the path"),
        )
    })?;
    let mut text = String::new();
    // One byte past the bound tells a file that grew since the stat from one that fits.
    let n = file
        .take(MAX_MODEL_FILE_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(|e| {
            (
                "content",
                format!("cannot read the model file as UTF-8 text ({e})"),
            )
        })?;
    if n as u64 > MAX_MODEL_FILE_BYTES {
        return Err((
            "size",
            format!("more than the {MAX_MODEL_FILE_BYTES} bytes a model file may have"),
        ));
    }
    Ok(text)
}

/// An `InvalidParameterError` (as every bad model file has been) about a model file, with
/// `.file`, `.what` (path, size, content) and `.message` attributes besides the class's
/// `.field` (`model file`), `.value` (NaN) and `.reason` (the message), and the message
/// `FILE: MESSAGE`.
fn file_error(py: Python<'_>, file: &str, what: &str, message: String) -> PyErr {
    let mut attrs: Vec<(&str, Bound<'_, PyAny>)> = [
        ("file", file.to_string()),
        ("what", what.to_string()),
        ("message", message.clone()),
        ("field", "model file".to_string()),
        ("reason", message.clone()),
    ]
    .into_iter()
    .filter_map(|(k, v)| v.into_pyobject(py).ok().map(|o| (k, o.into_any())))
    .collect();
    let Ok(nan) = f64::NAN.into_pyobject(py);
    attrs.push(("value", nan.into_any()));
    Exc::InvalidParameter.new_err(py, format!("{file}: {message}"), &attrs)
}

/// See the class documentation in `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "IdentifiedModel", frozen)]
pub(crate) struct PyIdentifiedModel {
    pub(crate) inner: IdentifiedModel,
}

/// The value the string `v` names among `options`, or None for any other string.
fn pick<T: Copy>(v: &Bound<'_, PyAny>, options: &[(&str, T)]) -> PyResult<Option<T>> {
    Ok(crate::estimators::choose(&v.extract::<String>()?, options))
}

/// An optional value's JSON (from `serde_json::to_value`) as its Python form (dicts, lists,
/// numbers), or None.
fn json_or_none<'py>(
    py: Python<'py>,
    value: Option<serde_json::Result<serde_json::Value>>,
) -> Out<'py> {
    match value {
        Some(v) => {
            let v = v.map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
            json_to_py(py, &v)
        }
        None => Ok(py.None().into_bound(py)),
    }
}

fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> Out<'py> {
    let json = py.import("json")?;
    json.call_method1("loads", (v.to_string(),))
}

fn opt_array<'py>(py: Python<'py>, v: &Option<Vec<f64>>, shape: &[usize]) -> Out<'py> {
    match v {
        Some(v) => to_array(py, v.clone(), None, shape),
        None => Ok(py.None().into_bound(py)),
    }
}

pymethods_with_getters!(PyIdentifiedModel {} arrays(this, py) {
    /// Joint torques τ = Y_b(q, q̇, q̈)·β̂ (N·m or N): (n,) or (N, n).
    fn predict(q, qd, qdd) {
        let predictor = this.inner.predictor().to_py(py)?;
        let n = predictor.chain().dof();
        let ([q, qd, qdd], count) = dyn_samples_of(py, [q, qd, qdd], ["q", "qd", "qdd"], n)?;
        let [tau] = map_samples_with(py, count, [&[n]], predictor, |p, k, [out]| {
            p.predict_into(q.at(k), qd.at(k), qdd.at(k), out)
        })?;
        Ok(tau)
    }
} {
    /// A model from the JSON text of `to_json`.
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        let inner = py.detach(|| IdentifiedModel::from_json(text)).to_py(py)?;
        Ok(Self { inner })
    }

    /// Largest model file `load` reads, bytes.
    #[classattr]
    const MAX_FILE_BYTES: u64 = MAX_MODEL_FILE_BYTES;

    /// A model from a JSON file written by `save`. The path must name a regular file of
    /// at most `MAX_FILE_BYTES`, checked before it is opened (a FIFO would block the
    /// open, /dev/zero would never end).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let shown = path.display().to_string();
        let text = py
            .detach(|| read_model_file(&path))
            .map_err(|(what, message)| file_error(py, &shown, what, message))?;
        let inner = py.detach(|| IdentifiedModel::from_json(&text));
        match inner {
            Ok(inner) => Ok(Self { inner }),
            // The core names the line and column; serde's message says what is wrong there
            // (e.g. `invalid type: string "ten", expected usize`).
            Err(PrrrpError::InvalidParameter { field, .. }) if field.starts_with("model JSON") => {
                let detail = serde_json::from_str::<IdentifiedModel>(&text)
                    .err()
                    .map_or_else(|| field.clone(), |e| e.to_string());
                Err(file_error(
                    py,
                    &shown,
                    "content",
                    format!(
                        "not a prrrp model file ({detail}); write it with IdentifiedModel.save"
                    ),
                ))
            }
            Err(e) => Err(to_pyerr(py, &e)),
        }
    }

    /// The model as JSON text (schema version 2).
    fn to_json(&self, py: Python<'_>) -> PyResult<String> {
        self.inner.to_json().to_py(py)
    }

    /// Writes `report.md` and figures about this model on `data` into the folder `dir`
    /// (built aside and swapped in whole); see `prrrp.model_report`.
    #[pyo3(signature = (dir, data, *, validation=None))]
    fn report<'py>(
        slf: &Bound<'py, Self>,
        dir: PathBuf,
        data: &Bound<'py, PyAny>,
        validation: Option<&Bound<'py, PyAny>>,
    ) -> Out<'py> {
        let py = slf.py();
        py.import("prrrp.model_report")?
            .call_method1("write_report_dir", (slf, dir, data, validation))
    }

    /// A URDF of the robot with the identified inertials (models of method "physical").
    fn to_urdf(&self, py: Python<'_>) -> PyResult<String> {
        self.inner.to_urdf().to_py(py)
    }

    /// Physically consistent standard parameters π (P,), where the method gives them.
    #[getter]
    fn standard_parameters<'py>(&self, py: Python<'py>) -> Out<'py> {
        let n = self.inner.standard.as_ref().map(|v| v.len()).unwrap_or(0);
        opt_array(py, &self.inner.standard, &[n])
    }

    /// Writes the model to `path` as JSON, atomically (a temporary file moved into place).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let text = self.to_json(py)?;
        let csvio = py.import("prrrp.csvio")?;
        csvio.call_method1("write_text_atomic", (path, text))?;
        Ok(())
    }

    /// The robot as a `SerialChain` (with the inertials it was loaded with).
    #[getter]
    fn robot(&self, py: Python<'_>) -> PyResult<PySerialChain> {
        Ok(PySerialChain::wrap(self.inner.chain().to_py(py)?))
    }

    /// The identification method, e.g. 'ls'.
    #[getter]
    fn method(&self) -> String {
        self.inner.method.clone()
    }

    /// β̂, (b,).
    #[getter]
    fn beta<'py>(&self, py: Python<'py>) -> Out<'py> {
        to_array(py, self.inner.beta.clone(), None, &[self.inner.beta.len()])
    }

    /// Standard deviation of β̂, (b,), or None.
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Out<'py> {
        opt_array(py, &self.inner.sigma, &[self.inner.beta.len()])
    }

    /// 100·σ/|β̂| (%), (b,) with NaN where β̂ = 0, or None.
    #[getter]
    fn rsd_percent<'py>(&self, py: Python<'py>) -> Out<'py> {
        let v = self
            .inner
            .rsd_percent
            .as_ref()
            .map(|v| v.iter().map(|x| x.unwrap_or(f64::NAN)).collect());
        opt_array(py, &v, &[self.inner.beta.len()])
    }

    /// Covariance of β̂, (b, b), or None.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Out<'py> {
        let b = self.inner.beta.len();
        opt_array(py, &self.inner.covariance, &[b, b])
    }

    /// cond(W_b) of the identification data, or None.
    #[getter]
    fn cond(&self) -> Option<f64> {
        self.inner.cond
    }

    /// RMS torque residual per joint on the identification data, (n,).
    #[getter]
    fn residual_rms<'py>(&self, py: Python<'py>) -> Out<'py> {
        let v = self.inner.residual_rms.clone();
        let n = v.len();
        to_array(py, v, None, &[n])
    }

    /// Names of the base parameters (the standard parameter each is named after).
    #[getter]
    fn base_names(&self) -> Vec<String> {
        let b = &self.inner.base;
        b.independent
            .iter()
            .map(|&j| b.standard_names[j].clone())
            .collect()
    }

    /// Each base parameter as a readable combination of standard parameters.
    #[getter]
    fn combinations(&self) -> Vec<String> {
        self.inner.base.combinations.clone()
    }

    /// Whether the method met its stopping rule (Adaline, Hopfield: the relative changes
    /// per epoch fell below their tolerances before `max_epochs`); True for the other
    /// methods when they finished normally.
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged
    }

    /// Epochs the gradient methods trained (Adaline, Hopfield), or None.
    #[getter]
    fn epochs(&self) -> Option<usize> {
        self.inner.epochs
    }

    /// The method's settings, a dict.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> Out<'py> {
        json_to_py(py, &self.inner.settings)
    }

    /// What the preprocessing did, a dict.
    #[getter]
    fn preprocessing<'py>(&self, py: Python<'py>) -> Out<'py> {
        json_to_py(py, &self.inner.preprocessing)
    }

    /// Each actuator's identified terms (friction, armature) with the base parameter they
    /// are identified in, β̂ and σ: a list of dicts (see `_prrrp.pyi`); empty without
    /// actuator terms.
    #[getter]
    fn actuators<'py>(&self, py: Python<'py>) -> Out<'py> {
        let v = serde_json::to_value(self.inner.actuator_estimates())
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        json_to_py(py, &v)
    }

    /// The payload the model carries (mass, com, inertia about the COM, their σ,
    /// `identifiable` flags, the 10 parameters and their covariance; a dict in the JSON
    /// layout of `payload.json`), or None for the bare arm.
    #[getter]
    fn payload<'py>(&self, py: Python<'py>) -> Out<'py> {
        json_or_none(py, self.inner.payload.as_ref().map(serde_json::to_value))
    }

    /// Drive gains identified with the model (`values`, `sigma` in N·m/A, `identifiable`,
    /// `identification`), or None.
    #[getter]
    fn drive_gains<'py>(&self, py: Python<'py>) -> Out<'py> {
        json_or_none(
            py,
            self.inner.drive_gains.as_ref().map(serde_json::to_value),
        )
    }

    /// The payload as the JSON text of `payload.json`, or None.
    fn payload_json(&self, py: Python<'_>) -> PyResult<Option<String>> {
        self.inner
            .payload
            .as_ref()
            .map(|p| p.to_json())
            .transpose()
            .to_py(py)
    }

    /// The arm + payload model identified from `data` (a `Dataset` of a run with the
    /// payload, torques as the model's): see `prrrp_core::identify_payload`. `mass` (kg)
    /// fixes a known mass; `tip` names (or indexes, 0-based) the carrying link (default:
    /// the last).
    #[pyo3(signature = (data, mass=None, *, tip=None, refit_friction=true,
        max_relative_sigma=0.1, com_tolerance=0.01))]
    #[allow(clippy::too_many_arguments)]
    fn identify_payload(
        &self,
        py: Python<'_>,
        data: &crate::data::dataset::PyDataset,
        mass: Option<f64>,
        tip: Option<&Bound<'_, PyAny>>,
        refit_friction: bool,
        max_relative_sigma: f64,
        com_tolerance: f64,
    ) -> PyResult<Self> {
        let link = link_index(py, &self.inner, tip)?;
        let settings = prrrp_core::PayloadSettings {
            link,
            mass,
            refit_friction,
            thresholds: thresholds(py, max_relative_sigma, com_tolerance)?,
        };
        let model = &self.inner;
        let inner = crate::interrupt::interruptible(py, || {
            prrrp_core::identify_payload(model, &data.inner, &settings)
        })?
        .to_py(py)?;
        Ok(Self { inner })
    }

    /// The model with its payload removed (the bare arm).
    fn without_payload(&self) -> Self {
        let mut inner = self.inner.clone();
        inner.payload = None;
        Self { inner }
    }

    /// Pickle support through the JSON text.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
        let rebuild = py.get_type::<PyIdentifiedModel>().getattr("from_json")?;
        let args = pyo3::types::PyTuple::new(py, [self.to_json(py)?])?;
        pyo3::types::PyTuple::new(py, [rebuild, args.into_any()])
    }

    fn __repr__(&self) -> String {
        format!(
            "IdentifiedModel(robot='{}', method='{}', base_parameters={}, cond={})",
            self.inner.robot.name,
            self.inner.method,
            self.inner.beta.len(),
            self.inner
                .cond
                .map_or("None".to_string(), |c| format!("{c:.4e}"))
        )
    }
});

/// Builds a model from its parts (used by `prrrp.identify` and tests).
#[pyfunction]
#[pyo3(signature = (robot, beta, *, sigma=None, covariance=None, cond=None, residual_rms=None,
    method="manual", settings=None, preprocessing=None, base=None))]
#[allow(clippy::too_many_arguments)]
fn identified_model_from_parts(
    py: Python<'_>,
    robot: &PySerialChain,
    beta: &Bound<'_, PyAny>,
    sigma: Option<&Bound<'_, PyAny>>,
    covariance: Option<&Bound<'_, PyAny>>,
    cond: Option<f64>,
    residual_rms: Option<&Bound<'_, PyAny>>,
    method: &str,
    settings: Option<&Bound<'_, PyDict>>,
    preprocessing: Option<&Bound<'_, PyDict>>,
    base: Option<&crate::models::chain::PyBaseParameters>,
) -> PyResult<PyIdentifiedModel> {
    let chain = robot.chain();
    let base = match base {
        Some(b) => b.inner.clone(),
        None => robot.default_base(py)?.clone(),
    };
    let vec = |o: Option<&Bound<'_, PyAny>>, name: &'static str| {
        o.map(|o| crate::arrays::vector(o, name)).transpose()
    };
    let covariance = match covariance {
        Some(c) => Some(crate::arrays::any_array(c, "covariance", "(b, b)")?.1),
        None => None,
    };
    let json = |d: Option<&Bound<'_, PyDict>>| -> PyResult<serde_json::Value> {
        let Some(d) = d else {
            return Ok(serde_json::Value::Object(Default::default()));
        };
        let text: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
        serde_json::from_str(&text).map_err(|e| {
            to_pyerr(
                py,
                &prrrp_core::PrrrpError::InvalidParameter {
                    field: format!("settings ({e})"),
                    value: f64::NAN,
                    reason: "must be a JSON-serialisable dict of finite values",
                },
            )
        })
    };
    let rms = vec(residual_rms, "residual_rms")?.unwrap_or_else(|| vec![0.0; chain.dof()]);
    let inner = IdentifiedModel::new(
        chain,
        &base,
        crate::arrays::vector(beta, "beta")?,
        vec(sigma, "sigma")?,
        covariance,
        cond,
        rms,
        method,
        json(settings)?,
        json(preprocessing)?,
    )
    .to_py(py)?;
    Ok(PyIdentifiedModel { inner })
}

/// The settings of the gradient networks' step control and stopping rule
/// (`GradientSettings`), which Adaline and Hopfield share.
const GRADIENT_KEYS: &[&str] = &[
    "max_epochs",
    "halvings",
    "parameter_tolerance",
    "error_tolerance",
    "scale_columns",
    "whiten",
];

/// The settings keys each method accepts (besides `base` and `preprocessing`).
fn valid_keys(method: &str) -> Vec<&'static str> {
    let own: &[&str] = match method {
        "ls" | "wls" => &["rank_tolerance"],
        "physical" => &[
            "rank_tolerance",
            "prior",
            "prior_weight",
            "divergence_weight",
            "weighted",
        ],
        "rls" => &[
            "rank_tolerance",
            "forgetting",
            "initial_covariance",
            "scale_columns",
        ],
        "adaline" => &["rank_tolerance", "rule", "step_size", "learning_rate"],
        "hopfield" => &["rank_tolerance", "step_size", "bound"],
        _ => &[
            "rank_tolerance",
            "initial",
            "dt",
            "measurement",
            "discretisation",
            "position_noise",
            "velocity_noise",
            "process_position_noise",
            "process_velocity_noise",
            "process_parameter_noise",
            "initial_position_std",
            "initial_velocity_std",
            "initial_parameter_rel_std",
            "initial_parameter_min_std",
            "init_from_first_measurement",
            "noise_from_data",
            "process_noise_at_estimate",
            "parameter_jacobian",
            "least_squares_prior_width",
            "correlation_correction",
            "stiff_handling",
        ],
    };
    let shared = match method {
        "adaline" | "hopfield" => GRADIENT_KEYS,
        _ => &[],
    };
    [own, shared].concat()
}

/// `method` with its settings from the keyword arguments; unknown keys are a TypeError
/// naming the valid ones.
fn parse_method(
    py: Python<'_>,
    method: &str,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<prrrp_core::Method> {
    use crate::estimators::{
        ADALINE_RULES, ADALINE_RULE_REASON, EKF_MEASUREMENTS, EKF_MEASUREMENT_REASON,
    };
    use prrrp_core::{Discretisation, EkfStart, Method, ParameterJacobian};
    let mut m = Method::parse(method).to_py(py)?;
    let Some(settings) = settings else {
        return Ok(m);
    };
    let valid = valid_keys(method);
    let bad = |field: String, reason: &'static str| {
        to_pyerr(
            py,
            &prrrp_core::PrrrpError::InvalidParameter {
                field,
                value: f64::NAN,
                reason,
            },
        )
    };
    for (k, v) in settings.iter() {
        let key: String = k.extract()?;
        if !valid.contains(&key.as_str()) {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "identify(method={method:?}) got an unknown setting {key:?}; valid settings: \
                 {}",
                valid.join(", ")
            )));
        }
        let f = || -> PyResult<f64> { v.extract::<f64>() };
        let u = || -> PyResult<usize> { Ok(v.extract::<crate::arrays::UInt<usize>>()?.0) };
        match (&mut m, key.as_str()) {
            (Method::Ls(s) | Method::Wls(s), "rank_tolerance") => s.rank_tolerance = f()?,
            (Method::Rls(s), "rank_tolerance") => s.rank_tolerance = f()?,
            (Method::Adaline(s) | Method::Hopfield(s), "rank_tolerance") => s.rank_tolerance = f()?,
            (Method::Ekf(s), "rank_tolerance") => s.rank_tolerance = f()?,
            (Method::Physical(s), "rank_tolerance") => s.rank_tolerance = f()?,
            (Method::Physical(s), "prior_weight") => s.prior_weight = f()?,
            (Method::Physical(s), "divergence_weight") => s.divergence_weight = f()?,
            (Method::Physical(s), "weighted") => s.weighted = v.extract()?,
            (Method::Physical(s), "prior") => {
                s.prior = if v.is_none() {
                    None
                } else {
                    Some(crate::arrays::vector(&v, "prior")?)
                }
            }
            (Method::Rls(s), "forgetting") => s.forgetting = f()?,
            (Method::Rls(s), "initial_covariance") => s.initial_covariance = f()?,
            (Method::Rls(s), "scale_columns") => s.scale_columns = v.extract()?,
            (Method::Adaline(s) | Method::Hopfield(s), k) => match k {
                "rule" => {
                    s.rule = pick(&v, &ADALINE_RULES)?
                        .ok_or_else(|| bad("rule".into(), ADALINE_RULE_REASON))?;
                }
                "step_size" => s.step_size = f()?,
                "learning_rate" => s.learning_rate = Some(f()?),
                "bound" => s.bound = Some(f()?),
                "max_epochs" => s.max_epochs = u()?,
                "halvings" => s.halvings = u()?,
                "parameter_tolerance" => s.parameter_tolerance = f()?,
                "error_tolerance" => s.error_tolerance = f()?,
                "whiten" => s.whiten = v.extract()?,
                _ => s.scale_columns = v.extract()?,
            },
            (Method::Ekf(s), k) => {
                let c = &mut s.config;
                match k {
                    "initial" => {
                        s.initial = if let Ok(name) = v.extract::<String>() {
                            match name.as_str() {
                                "ls" => EkfStart::LeastSquares,
                                "prior" => EkfStart::Prior,
                                _ => {
                                    return Err(bad(
                                        "initial".into(),
                                        "must be \"ls\", \"prior\" or an array of β0",
                                    ))
                                }
                            }
                        } else {
                            EkfStart::Given(crate::arrays::vector(&v, "initial")?)
                        }
                    }
                    "dt" => s.dt = Some(f()?),
                    "measurement" => {
                        c.measurement = pick(&v, &EKF_MEASUREMENTS)?
                            .ok_or_else(|| bad("measurement".into(), EKF_MEASUREMENT_REASON))?;
                    }
                    "discretisation" => {
                        let options = [
                            ("euler", Discretisation::Euler),
                            ("second_order", Discretisation::SecondOrder),
                            ("midpoint", Discretisation::Midpoint),
                        ];
                        let reason = "must be \"euler\", \"second_order\" or \"midpoint\"";
                        c.discretisation = pick(&v, &options)?
                            .ok_or_else(|| bad("discretisation".into(), reason))?;
                    }
                    // A noise given by the user replaces the one taken from the data.
                    "position_noise" => {
                        c.position_noise = f()?;
                        s.noise_from_data = false;
                    }
                    "velocity_noise" => {
                        c.velocity_noise = f()?;
                        s.noise_from_data = false;
                    }
                    "parameter_jacobian" => {
                        let options = [
                            ("predicted", ParameterJacobian::Predicted),
                            ("data_acceleration", ParameterJacobian::DataAcceleration),
                        ];
                        let reason = "must be \"predicted\" or \"data_acceleration\"";
                        c.parameter_jacobian = pick(&v, &options)?
                            .ok_or_else(|| bad("parameter_jacobian".into(), reason))?;
                    }
                    "noise_from_data" => s.noise_from_data = v.extract()?,
                    "least_squares_prior_width" => s.least_squares_prior_width = f()?,
                    "correlation_correction" => s.correlation_correction = v.extract()?,
                    "stiff_handling" => s.stiff_handling = v.extract()?,
                    "process_noise_at_estimate" => s.process_noise_at_estimate = v.extract()?,
                    "process_position_noise" => c.process_position_noise = f()?,
                    "process_velocity_noise" => c.process_velocity_noise = f()?,
                    "process_parameter_noise" => c.process_parameter_noise = f()?,
                    "initial_position_std" => c.initial_position_std = f()?,
                    "initial_velocity_std" => c.initial_velocity_std = f()?,
                    "initial_parameter_rel_std" => c.initial_parameter_rel_std = f()?,
                    "initial_parameter_min_std" => c.initial_parameter_min_std = f()?,
                    _ => c.init_from_first_measurement = v.extract()?,
                }
            }
            _ => unreachable!("keys are checked against valid_keys"),
        }
    }
    Ok(m)
}

/// The least-squares work `identify` calls on one data set share; see `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "FitCache", frozen)]
#[derive(Default)]
pub(crate) struct PyFitCache {
    inner: prrrp_core::FitCache,
}

#[pymethods]
impl PyFitCache {
    #[new]
    fn new() -> Self {
        Self::default()
    }

    /// Least-squares stacks held; see `_prrrp.pyi`.
    #[getter]
    fn stacks(&self) -> usize {
        self.inner.stacks()
    }

    fn __repr__(&self) -> String {
        format!("FitCache(stacks={})", self.inner.stacks())
    }
}

/// Identifies `robot` from `data`; see `_prrrp.pyi`.
#[pyfunction]
#[pyo3(signature = (
    robot, data, method="ls", *, base=None, preprocessing=None, cache=None, **settings
))]
#[allow(clippy::too_many_arguments)] // Python's keywords
fn identify(
    py: Python<'_>,
    robot: &Bound<'_, PyAny>,
    data: &crate::data::dataset::PyDataset,
    method: &str,
    base: Option<&crate::models::chain::PyBaseParameters>,
    preprocessing: Option<&Bound<'_, PyDict>>,
    cache: Option<&PyFitCache>,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyIdentifiedModel> {
    let fresh;
    let cache = match cache {
        Some(c) => &c.inner,
        None => {
            fresh = prrrp_core::FitCache::new();
            &fresh
        }
    };
    let invalid = |field: &str, reason: &'static str| {
        to_pyerr(
            py,
            &prrrp_core::PrrrpError::InvalidParameter {
                field: field.into(),
                value: f64::NAN,
                reason,
            },
        )
    };
    let method = parse_method(py, method, settings)?;
    let preprocessing = match preprocessing {
        Some(d) => {
            let text: String = py.import("json")?.call_method1("dumps", (d,))?.extract()?;
            serde_json::from_str(&text).map_err(|_| {
                invalid(
                    "preprocessing",
                    "must be a JSON-serialisable dict of finite values",
                )
            })?
        }
        None => serde_json::Value::Object(Default::default()),
    };
    if let Ok(r) = robot.cast::<crate::models::robot::PyRobot>() {
        if base.is_some() {
            return Err(invalid(
                "base",
                "is chosen by identify for the paper's Robot (its chain form's analysis); \
                 pass prrrp.SerialChain.paper() to give one",
            ));
        }
        let robot = r.get().inner;
        let inner = crate::interrupt::interruptible(py, || {
            prrrp_core::identify_robot_cached(&robot, &data.inner, &method, preprocessing, cache)
        })?
        .to_py(py)?;
        return Ok(PyIdentifiedModel { inner });
    }
    let Ok(chain) = robot.cast::<PySerialChain>() else {
        return Err(invalid(
            "robot",
            "must be a prrrp.SerialChain or a prrrp.Robot (the paper's arm)",
        ));
    };
    let chain = chain.get();
    let base = match base {
        Some(b) => b.inner.clone(),
        None => chain.default_base(py)?.clone(),
    };
    let inner = crate::interrupt::interruptible(py, || {
        prrrp_core::identify_cached(
            chain.chain(),
            &base,
            &data.inner,
            &method,
            preprocessing,
            cache,
        )
    })?
    .to_py(py)?;
    Ok(PyIdentifiedModel { inner })
}

fn thresholds(
    py: Python<'_>,
    max_relative_sigma: f64,
    com_tolerance: f64,
) -> PyResult<prrrp_core::PayloadThresholds> {
    for (field, v) in [
        ("max_relative_sigma", max_relative_sigma),
        ("com_tolerance", com_tolerance),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(to_pyerr(
                py,
                &prrrp_core::PrrrpError::InvalidParameter {
                    field: field.into(),
                    value: v,
                    reason: "must be finite and > 0",
                },
            ));
        }
    }
    Ok(prrrp_core::PayloadThresholds {
        max_relative_sigma,
        com_tolerance,
    })
}

/// The carrying link from a name or a 0-based index (None: the tip).
fn link_index(
    py: Python<'_>,
    model: &IdentifiedModel,
    tip: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<usize>> {
    let Some(tip) = tip else {
        return Ok(None);
    };
    let links: Vec<String> = model.robot.joints.iter().map(|j| j.link.clone()).collect();
    if let Ok(name) = tip.extract::<String>() {
        return match links.iter().position(|l| *l == name) {
            Some(i) => Ok(Some(i)),
            None => Err(to_pyerr(
                py,
                &prrrp_core::PrrrpError::InvalidParameter {
                    field: format!("tip '{name}' (links: {})", links.join(", ")),
                    value: f64::NAN,
                    reason: "is not a link of the model's chain; name one of its links",
                },
            )),
        };
    }
    let i: i64 = tip.extract()?;
    let field = || {
        let listed: Vec<String> = links
            .iter()
            .enumerate()
            .map(|(k, l)| format!("{k} = {l}"))
            .collect();
        format!("tip {i} (links: {})", listed.join(", "))
    };
    let reason = "is not a link index of the model's chain; give one of its indices \
                  (0-based) or the link's name";
    index_arg(py, i, Some(links.len()), field, reason).map(Some)
}

/// Drive gains, the arm and the payload from current logs of an unloaded and a loaded
/// run (see `_prrrp.pyi`).
#[pyfunction]
#[pyo3(signature = (model, unloaded, loaded, mass, *, tip=None, iterations=3,
    refit_friction=true, max_relative_sigma=0.05))]
#[allow(clippy::too_many_arguments)]
fn identify_drive_gains<'py>(
    py: Python<'py>,
    model: &PyIdentifiedModel,
    unloaded: &crate::data::dataset::PyDataset,
    loaded: &crate::data::dataset::PyDataset,
    mass: f64,
    tip: Option<&Bound<'py, PyAny>>,
    iterations: usize,
    refit_friction: bool,
    max_relative_sigma: f64,
) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
    let link = link_index(py, &model.inner, tip)?;
    let mut settings = prrrp_core::DriveGainSettings::new(mass);
    settings.link = link;
    settings.iterations = iterations;
    settings.refit_friction = refit_friction;
    settings.max_relative_sigma = thresholds(py, max_relative_sigma, 0.01)?.max_relative_sigma;
    let inner = &model.inner;
    let fit = crate::interrupt::interruptible(py, || {
        prrrp_core::identify_drive_gains(inner, &unloaded.inner, &loaded.inner, &settings)
    })?
    .to_py(py)?;
    let v = serde_json::to_value(&fit.payload)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(e.to_string()))?;
    let payload = json_to_py(py, &v)?;
    let arm = Bound::new(py, PyIdentifiedModel { inner: fit.model })?;
    let naive = pyo3::types::PyList::new(py, fit.naive_gains)?;
    pyo3::types::PyTuple::new(py, [arm.into_any(), payload, naive.into_any()])
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyIdentifiedModel>()?;
    m.add_function(wrap_pyfunction!(identify_drive_gains, m)?)?;
    m.add_class::<PyFitCache>()?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(identified_model_from_parts, m)?)?;
    Ok(())
}
