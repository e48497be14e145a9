//! `prrrp.Dataset`: a validated identification data set of the PRRRP arm (time stamps
//! and per-sample q, q̇, q̈, τ), wrapping the core's `Dataset`.

use prrrp_core::{Dataset, PrrrpError, NDOF};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PySlice};

use crate::arrays::{rows_to_array, to_array, vector, Samples};
use crate::errors::{to_pyerr, ToPyResult};
use crate::preprocessing::dataset_dict;

type Out<'py> = PyResult<Bound<'py, PyAny>>;

/// Time stamps t (N,) s and q, qd, qdd, tau (N, 5), checked on creation: equal lengths,
/// N ≥ 8, every value finite, t strictly increasing.
#[pyclass(module = "prrrp", name = "Dataset", frozen)]
pub(crate) struct PyDataset {
    pub(crate) inner: Dataset,
}

#[pymethods]
impl PyDataset {
    /// Smallest accepted number of samples (8, one per base parameter).
    #[classattr]
    const MIN_SAMPLES: usize = Dataset::MIN_SAMPLES;

    #[new]
    fn new(
        py: Python<'_>,
        t: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        qd: &Bound<'_, PyAny>,
        qdd: &Bound<'_, PyAny>,
        tau: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let t = vector(t, "t")?;
        let inner = Dataset::new(
            t,
            Samples::<NDOF>::extract_rows(q, "q")?,
            Samples::<NDOF>::extract_rows(qd, "qd")?,
            Samples::<NDOF>::extract_rows(qdd, "qdd")?,
            Samples::<NDOF>::extract_rows(tau, "tau")?,
        )
        .to_py(py)?;
        Ok(Self { inner })
    }

    /// A data set from a mapping with keys t, q, qd, qdd, tau (e.g. the dict returned by
    /// `preprocess` or `simulate_closed_loop`; extra keys are ignored).
    #[staticmethod]
    fn from_dict(py: Python<'_>, d: &Bound<'_, PyAny>) -> PyResult<Self> {
        let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
            d.get_item(k).map_err(|_| {
                to_pyerr(
                    py,
                    &PrrrpError::ShapeMismatch {
                        what: "data".into(),
                        expected: "a mapping with keys t, q, qd, qdd, tau".into(),
                        got: format!("no key {k:?}"),
                    },
                )
            })
        };
        Self::new(
            py,
            &get("t")?,
            &get("q")?,
            &get("qd")?,
            &get("qdd")?,
            &get("tau")?,
        )
    }

    /// Time stamps, s, (N,).
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Out<'py> {
        to_array(py, self.inner.t().to_vec(), Some(self.inner.len()), &[])
    }
    /// Joint positions [d1, θ2, θ3, θ4, d5] (m, rad), (N, 5).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Out<'py> {
        rows_to_array(py, self.inner.q())
    }
    /// Joint velocities (m/s, rad/s), (N, 5).
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> Out<'py> {
        rows_to_array(py, self.inner.qd())
    }
    /// Joint accelerations (m/s², rad/s²), (N, 5).
    #[getter]
    fn qdd<'py>(&self, py: Python<'py>) -> Out<'py> {
        rows_to_array(py, self.inner.qdd())
    }
    /// Generalised forces [F1, τ2, τ3, τ4, F5] (N, N·m), (N, 5).
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Out<'py> {
        rows_to_array(py, self.inner.tau())
    }
    /// Time span t[-1] − t[0], s.
    #[getter]
    fn duration(&self) -> f64 {
        self.inner.duration()
    }

    /// Samples start..stop (step 1) as a new validated data set; raises
    /// TooFewSamplesError if fewer than 8 remain.
    fn slice(&self, py: Python<'_>, start: usize, stop: usize) -> PyResult<Self> {
        let inner = self.inner.slice(start..stop).to_py(py)?;
        Ok(Self { inner })
    }

    /// `data[a:b]`: a contiguous slice (step 1; negative indices as in Python).
    fn __getitem__(&self, py: Python<'_>, key: &Bound<'_, PyAny>) -> PyResult<Self> {
        let slice = key.cast::<PySlice>().map_err(|_| {
            to_pyerr(
                py,
                &PrrrpError::ShapeMismatch {
                    what: "Dataset index".into(),
                    expected: "a slice start:stop (use the array properties for single samples)"
                        .into(),
                    got: "a non-slice index".into(),
                },
            )
        })?;
        let len = self.inner.len() as isize;
        // Python raises ValueError (step 0) or TypeError (non-integer bounds) here: make
        // both the package's typed error.
        let ind = slice.indices(len).map_err(|e| {
            let err = to_pyerr(
                py,
                &PrrrpError::InvalidParameter {
                    field: "Dataset slice".into(),
                    value: f64::NAN,
                    reason: "needs integer bounds and step 1, e.g. data[10:200]",
                },
            );
            err.set_cause(py, Some(e));
            err
        })?;
        if ind.step != 1 {
            return Err(to_pyerr(
                py,
                &PrrrpError::InvalidParameter {
                    field: "Dataset slice step".into(),
                    value: ind.step as f64,
                    reason: "only contiguous slices (step 1) keep the time stamps uniform",
                },
            ));
        }
        let (start, stop) = (ind.start as usize, (ind.stop.max(ind.start)) as usize);
        self.slice(py, start, stop)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// The columns as a dict of arrays t, q, qd, qdd, tau.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        dataset_dict(py, &self.inner)
    }

    fn __repr__(&self) -> String {
        format!(
            "Dataset(samples={}, t=[{}, {}] s)",
            self.inner.len(),
            self.inner.t()[0],
            self.inner.t()[self.inner.len() - 1]
        )
    }
}

/// A core data set from a `prrrp.Dataset` or a mapping with keys t, q, qd, qdd, tau.
pub(crate) fn dataset_from(obj: &Bound<'_, PyAny>) -> PyResult<Dataset> {
    if let Ok(d) = obj.cast::<PyDataset>() {
        return Ok(d.get().inner.clone());
    }
    Ok(PyDataset::from_dict(obj.py(), obj)?.inner)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDataset>()
}
