//! `prrrp.IdentifiedModel`: an identification result for any robot that predicts joint
//! torques on its own and saves to / loads from JSON (`docs/model-schema.md`).

use std::path::PathBuf;

use prrrp_core::IdentifiedModel;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{batch_len, map_samples_with, to_array, DynSamples};
use crate::errors::{to_pyerr, ToPyResult};
use crate::models::chain::PySerialChain;

type Out<'py> = PyResult<Bound<'py, PyAny>>;

/// See the class documentation in `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "IdentifiedModel", frozen)]
pub(crate) struct PyIdentifiedModel {
    pub(crate) inner: IdentifiedModel,
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

#[pymethods]
impl PyIdentifiedModel {
    /// A model from the JSON text of `to_json`.
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        let inner = py.detach(|| IdentifiedModel::from_json(text)).to_py(py)?;
        Ok(Self { inner })
    }

    /// A model from a JSON file written by `save`.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path).map_err(|e| {
            to_pyerr(
                py,
                &prrrp_core::PrrrpError::InvalidParameter {
                    field: format!("model file {} ({e})", path.display()),
                    value: f64::NAN,
                    reason: "cannot be read; check the path",
                },
            )
        })?;
        Self::from_json(py, &text)
    }

    /// The model as JSON text (schema version 1).
    fn to_json(&self, py: Python<'_>) -> PyResult<String> {
        self.inner.to_json().to_py(py)
    }

    /// Writes the model to `path` as JSON, atomically (a temporary file moved into place).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let text = self.to_json(py)?;
        let csvio = py.import("prrrp.csvio")?;
        csvio.call_method1("write_text_atomic", (path, text))?;
        Ok(())
    }

    /// Joint torques τ = Y_b(q, q̇, q̈)·β̂ (N·m or N): (n,) or (N, n).
    fn predict<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
    ) -> Out<'py> {
        let predictor = self.inner.predictor().to_py(py)?;
        let n = predictor.chain().dof();
        let (q, qd, qdd) = (
            DynSamples::extract(q, "q", n)?,
            DynSamples::extract(qd, "qd", n)?,
            DynSamples::extract(qdd, "qdd", n)?,
        );
        let count = batch_len(py, &[&q, &qd, &qdd])?;
        let [tau] = map_samples_with(py, count, [&[n]], predictor, |p, k, [out]| {
            p.predict_into(q.at(k), qd.at(k), qdd.at(k), out)
        })?;
        Ok(tau)
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
}

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

/// Identifies `robot` from `data`; see `_prrrp.pyi`.
#[pyfunction]
#[pyo3(signature = (robot, data, method="ls", *, base=None, rank_tolerance=1e-10,
    preprocessing=None))]
fn identify(
    py: Python<'_>,
    robot: &Bound<'_, PyAny>,
    data: &crate::data::dataset::PyDataset,
    method: &str,
    base: Option<&crate::models::chain::PyBaseParameters>,
    rank_tolerance: f64,
    preprocessing: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyIdentifiedModel> {
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
    let Ok(chain) = robot.cast::<PySerialChain>() else {
        return Err(invalid(
            "robot",
            "must be a prrrp.SerialChain (for the paper's arm: prrrp.SerialChain.paper(), or \
             the closed-form estimators prrrp.least_squares, Adaline, Hopfield, Ekf)",
        ));
    };
    let chain = chain.get();
    let weighted = match method {
        "ls" => false,
        "wls" => true,
        "rls" | "adaline" | "hopfield" | "ekf" => {
            return Err(invalid(
                &format!("method {method:?}"),
                "is not yet available through identify for SerialChain robots; use \"ls\" \
                 or \"wls\"",
            ))
        }
        _ => {
            return Err(invalid(
                &format!("method {method:?}"),
                "unknown: use \"ls\" or \"wls\"",
            ))
        }
    };
    let base = match base {
        Some(b) => b.inner.clone(),
        None => chain.default_base(py)?.clone(),
    };
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
    let config = prrrp_core::LeastSquaresConfig { rank_tolerance };
    let inner = crate::interrupt::interruptible(py, || {
        prrrp_core::identify_least_squares(
            chain.chain(),
            &base,
            &data.inner,
            weighted,
            &config,
            preprocessing,
        )
    })?
    .to_py(py)?;
    Ok(PyIdentifiedModel { inner })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyIdentifiedModel>()?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    m.add_function(wrap_pyfunction!(identified_model_from_parts, m)?)?;
    Ok(())
}
