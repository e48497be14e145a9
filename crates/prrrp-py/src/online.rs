//! `prrrp.OnlineIdentifier`: identification while the arm runs, one raw sample at a time
//! (see `prrrp_core::OnlineIdentifier`; the class documentation is in `_prrrp.pyi`).

use prrrp_core::{
    ChangeDetection, CoulombSearch, OnlineConfig, OnlineIdentifier, OnlineMethod, PrrrpError,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{to_array, vector, Out, UInt};
use crate::errors::ToPyResult;
use crate::identification::PyIdentifiedModel;
use crate::models::chain::PySerialChain;

/// See the class documentation in `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "OnlineIdentifier")]
pub(crate) struct PyOnlineIdentifier {
    inner: OnlineIdentifier,
}

fn json_to_py<'py>(py: Python<'py>, v: &serde_json::Value) -> Out<'py> {
    py.import("json")?.call_method1("loads", (v.to_string(),))
}

#[pymethods]
impl PyOnlineIdentifier {
    #[new]
    #[pyo3(signature = (robot=None, *, prior=None, method="rls", payload=false, forgetting=None,
        directional=true, change_detection=true, change_threshold=9.0, cutoff_hz=None,
        prior_width=3.0, initial_covariance=1e6, payload_mass_std=10.0, payload_size=0.2,
        ekf_noise=1.0, ekf_warmup=2.0, step_size=0.5, seed=UInt(0), coulomb_scale=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        robot: Option<&PySerialChain>,
        prior: Option<&PyIdentifiedModel>,
        method: &str,
        payload: bool,
        forgetting: Option<f64>,
        directional: bool,
        change_detection: bool,
        change_threshold: f64,
        cutoff_hz: Option<f64>,
        prior_width: f64,
        initial_covariance: f64,
        payload_mass_std: f64,
        payload_size: f64,
        ekf_noise: f64,
        ekf_warmup: f64,
        step_size: f64,
        seed: UInt<u64>,
        coulomb_scale: Option<&str>,
    ) -> PyResult<Self> {
        let defaults = OnlineConfig::default();
        let coulomb_search = match coulomb_scale {
            None => None,
            Some("auto") => Some(CoulombSearch::default()),
            Some(_) => {
                return Err(PrrrpError::InvalidParameter {
                    field: "coulomb_scale".into(),
                    value: f64::NAN,
                    reason: "must be \"auto\" or None (the robot's own scale; set another \
                             with prrrp.workflow.with_coulomb_scale)",
                })
                .to_py(py)
            }
        };
        let config = OnlineConfig {
            method: OnlineMethod::parse(method).to_py(py)?,
            payload,
            forgetting,
            directional,
            cutoff_hz: cutoff_hz.unwrap_or(defaults.cutoff_hz),
            auto_cutoff: cutoff_hz.is_none(),
            change_detection: change_detection.then(|| ChangeDetection {
                threshold: change_threshold,
                ..ChangeDetection::default()
            }),
            prior_width,
            initial_covariance,
            payload_mass_std,
            payload_size,
            ekf_noise,
            ekf_warmup,
            step_size,
            seed: seed.0,
            coulomb_search,
            ..defaults
        };
        let inner = match (prior, robot) {
            // The prior carries its robot: a second one was dropped without a word (a
            // Panda given with a UR5 prior tracked the UR5).
            (Some(_), Some(_)) => Err(PrrrpError::InvalidParameter {
                field: "robot".into(),
                value: f64::NAN,
                reason: "is not needed with a prior: the prior model carries its robot; \
                         give one of robot and prior",
            }),
            (Some(p), None) => OnlineIdentifier::with_prior(&p.inner, config),
            (None, Some(r)) => {
                let base = r.default_base(py)?.clone();
                OnlineIdentifier::new(r.chain(), &base, config)
            }
            (None, None) => Err(PrrrpError::InvalidParameter {
                field: "robot".into(),
                value: f64::NAN,
                reason: "give the robot (a SerialChain) or a prior model",
            }),
        }
        .to_py(py)?;
        Ok(Self { inner })
    }

    /// Consumes one raw sample; returns a dict (see `_prrrp.pyi`).
    #[pyo3(signature = (t, q, tau, qd=None))]
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        q: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        qd: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let q = vector(q, "q")?;
        let tau = vector(tau, "tau")?;
        let qd = qd.map(|v| vector(v, "qd")).transpose()?;
        let u = self.inner.update(t, &q, &tau, qd.as_deref()).to_py(py)?;
        let d = PyDict::new(py);
        d.set_item(
            "prediction",
            to_array(py, u.prediction.to_vec(), None, &[u.prediction.len()])?,
        )?;
        d.set_item(
            "estimate",
            to_array(py, u.estimate.to_vec(), None, &[u.estimate.len()])?,
        )?;
        match u.sigma {
            Some(s) => d.set_item("sigma", to_array(py, s.to_vec(), None, &[s.len()])?)?,
            None => d.set_item("sigma", py.None())?,
        }
        d.set_item("change", u.change)?;
        d.set_item("updated", u.updated)?;
        Ok(d)
    }

    /// The current estimate as an `IdentifiedModel`.
    fn estimate(&self, py: Python<'_>) -> PyResult<PyIdentifiedModel> {
        let inner = self.inner.estimate().to_py(py)?;
        Ok(PyIdentifiedModel { inner })
    }

    /// Payload mode: the payload as load data (dict), else None.
    fn payload<'py>(&self, py: Python<'py>) -> Out<'py> {
        match self.inner.payload_summary() {
            Some(v) => json_to_py(py, &v),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// Names of the estimated parameters.
    #[getter]
    fn parameter_names(&self) -> Vec<String> {
        self.inner.parameter_names()
    }

    /// The current estimate, (p,).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> Out<'py> {
        let v = self.inner.parameters();
        to_array(py, v.to_vec(), None, &[v.len()])
    }

    /// σ of the current estimate, (p,), or None.
    #[getter]
    fn sigma<'py>(&self, py: Python<'py>) -> Out<'py> {
        match self.inner.sigma() {
            Some(v) => to_array(py, v.to_vec(), None, &[v.len()]),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// Rows consumed, rows that updated the estimate, repeated rows, detected changes.
    #[getter]
    fn counts(&self) -> (usize, usize, usize, usize) {
        self.inner.counts()
    }

    /// Alarms of the change test whose look dropped the opening: the estimate before them
    /// predicted the following rows as well (a spike, not a change).
    #[getter]
    fn dropped_alarms(&self) -> usize {
        self.inner.dropped_alarms()
    }

    /// Running noise level per joint (N·m or N).
    #[getter]
    fn noise_rms(&self) -> Vec<f64> {
        self.inner.noise_rms()
    }

    /// Whether the EKF is running (False during its RLS warm-up and for other methods).
    #[getter]
    fn ekf_running(&self) -> bool {
        self.inner.ekf_running()
    }

    /// The settings as used, a dict.
    #[getter]
    fn settings<'py>(&self, py: Python<'py>) -> Out<'py> {
        json_to_py(py, &self.inner.settings_json())
    }

    fn __repr__(&self) -> String {
        let (rows, _, _, changes) = self.inner.counts();
        format!(
            "OnlineIdentifier(method='{}', payload={}, parameters={}, rows={rows}, changes={changes})",
            self.inner.config().method.name(),
            if self.inner.config().payload { "True" } else { "False" },
            self.inner.parameters().len(),
        )
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOnlineIdentifier>()?;
    Ok(())
}
