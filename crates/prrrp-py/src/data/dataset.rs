//! `prrrp.Dataset`: a validated identification data set of any robot (time stamps and
//! per-sample q, q̇, q̈, τ of n joints), wrapping the core's `DynDataset`; and
//! `prrrp.preprocess_log`, which makes one from a real log.

use prrrp_core::nalgebra::Dim;
use prrrp_core::{preprocess_log, Dataset, DatasetOf, DynDataset, LogConfig, PrrrpError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PySlice};

use crate::arrays::{any_array, index_arg, to_array, vector, Out, UInt};
use crate::errors::{to_pyerr, ToPyResult};

/// Time stamps t (N,) s and q, qd, qdd, tau (N, n), checked on creation: equal lengths,
/// N ≥ 8, every value finite, t strictly increasing.
#[pyclass(module = "prrrp", name = "Dataset", frozen)]
pub(crate) struct PyDataset {
    pub(crate) inner: DynDataset,
}

/// (rows, n) and the row-major values of a 2-D array argument.
fn table(obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<(usize, usize, Vec<f64>)> {
    let (shape, data) = any_array(obj, name, "(N, n)")?;
    match *shape {
        [rows, n] => Ok((rows, n, data)),
        _ => Err(crate::errors::shape_error(
            obj.py(),
            name,
            "(N, n)",
            crate::arrays::fmt_shape(&shape),
        )),
    }
}

pymethods_with_getters!(PyDataset {
    column: [
        /// Joint positions (m, rad), (N, n).
        q(),
        /// Joint velocities (m/s, rad/s), (N, n).
        qd(),
        /// Joint accelerations (m/s², rad/s²), (N, n).
        qdd(),
        /// Generalised forces (N, N·m), (N, n).
        tau(),
    ]
} inner {
    /// Number of joints n.
    dof: usize = { dof() }
    /// Time span t[-1] − t[0], s.
    duration: f64 = { duration() }
} {
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
        let (_, n, q) = table(q, "q")?;
        let qd = columns_like(qd, "qd", n)?;
        let qdd = columns_like(qdd, "qdd", n)?;
        let tau = columns_like(tau, "tau", n)?;
        let inner =
            DynDataset::with_min_samples(n, Dataset::MIN_SAMPLES, t, q, qd, qdd, tau).to_py(py)?;
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

    /// Samples start..stop (step 1) as a new validated data set; raises
    /// TooFewSamplesError if fewer than 8 remain.
    fn slice(&self, py: Python<'_>, start: i64, stop: i64) -> PyResult<Self> {
        let reason = "must be >= 0 (a sample index; data[a:b] takes negative ones)";
        let index = |name: &str, v: i64| index_arg(py, v, None, || name.into(), reason);
        let range = index("start", start)?..index("stop", stop)?;
        let inner = self.inner.slice(range).to_py(py)?;
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
        let (start, stop) = (ind.start as i64, ind.stop.max(ind.start) as i64);
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
            "Dataset(samples={}, joints={}, t=[{}, {}] s)",
            self.inner.len(),
            self.inner.dof(),
            self.inner.t()[0],
            self.inner.t()[self.inner.len() - 1]
        )
    }
});

/// The values of a (N, n) argument whose joint count must match q's.
fn columns_like(obj: &Bound<'_, PyAny>, name: &'static str, n: usize) -> PyResult<Vec<f64>> {
    let (rows, m, data) = table(obj, name)?;
    if m != n {
        return Err(crate::errors::shape_error(
            obj.py(),
            name,
            format!("(N, {n}) (n = {n} joints, from q)"),
            format!("({rows}, {m})"),
        ));
    }
    Ok(data)
}

impl PyDataset {
    fn column<'py>(&self, py: Python<'py>, flat: &[f64]) -> Out<'py> {
        to_array(
            py,
            flat.to_vec(),
            Some(self.inner.len()),
            &[self.inner.dof()],
        )
    }
}

/// The columns of a data set of any joint count as a dict of arrays t (N,) and q, qd,
/// qdd, tau (N, n).
pub(crate) fn dataset_dict<'py, N: Dim>(
    py: Python<'py>,
    d: &DatasetOf<N>,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("t", to_array(py, d.t().to_vec(), Some(d.len()), &[])?)?;
    for (name, col) in [
        ("q", d.q()),
        ("qd", d.qd()),
        ("qdd", d.qdd()),
        ("tau", d.tau()),
    ] {
        out.set_item(name, to_array(py, col.to_vec(), Some(d.len()), &[d.dof()])?)?;
    }
    Ok(out)
}

/// A 5-joint core data set (the paper's arm) from a `prrrp.Dataset` or a mapping with keys
/// t, q, qd, qdd, tau.
pub(crate) fn dataset_from(obj: &Bound<'_, PyAny>) -> PyResult<Dataset> {
    let py = obj.py();
    let dyn_data = if let Ok(d) = obj.cast::<PyDataset>() {
        d.get().inner.clone()
    } else {
        PyDataset::from_dict(py, obj)?.inner
    };
    Dataset::try_from(dyn_data).to_py(py)
}

array_pyfunctions! {
/// Makes a `Dataset` of n joints from a real log; see `_prrrp.pyi`.
#[pyfunction(name = "preprocess_log")]
#[pyo3(signature = (t, q, tau, *, qd=None, rate_hz=None, cutoff_hz=None, order=UInt(4),
    filter_torque=true, trim_s=None, decimate_to_hz=None, max_gap_s=None))]
fn preprocess_log_py(py, t, q, tau;
    qd: Option<&Bound<'py, PyAny>>,
    rate_hz: Option<f64>,
    cutoff_hz: Option<f64>,
    order: UInt<usize>,
    filter_torque: bool,
    trim_s: Option<f64>,
    decimate_to_hz: Option<f64>,
    max_gap_s: Option<f64>,
) -> PyResult<(PyDataset, Bound<'py, PyDict>)> {
    let t = vector(t, "t")?;
    let (_, n, q) = table(q, "q")?;
    let tau = columns_like(tau, "tau", n)?;
    let qd = qd.map(|v| columns_like(v, "qd", n)).transpose()?;
    let config = LogConfig {
        rate_hz,
        cutoff_hz,
        order: order.0,
        filter_torque,
        trim_s,
        decimate_to_hz,
        max_gap_s,
        min_samples: Dataset::MIN_SAMPLES,
    };
    let (inner, r) = crate::interrupt::interruptible(py, || {
        preprocess_log(&t, &q, &tau, qd.as_deref(), n, &config)
    })?
    .to_py(py)?;
    let report = PyDict::new(py);
    report.set_item("rows_in", r.rows_in)?;
    report.set_item("repeated_rows", r.repeated_rows)?;
    report.set_item("conflicting_repeats", r.conflicting_repeats)?;
    report.set_item("median_rate_hz", r.median_rate_hz)?;
    report.set_item("rate_hz", r.rate_hz)?;
    report.set_item("resampled", r.resampled)?;
    report.set_item("largest_gap_s", r.largest_gap_s)?;
    report.set_item("largest_gap_row", r.largest_gap_row)?;
    report.set_item("cutoff_hz", r.cutoff_hz)?;
    report.set_item("order", r.order)?;
    report.set_item("trim_samples", r.trim_samples)?;
    report.set_item("trim_s", r.trim_s)?;
    report.set_item("decimation", r.decimation)?;
    report.set_item("output_rate_hz", r.output_rate_hz)?;
    report.set_item("measured_velocity", r.measured_velocity)?;
    report.set_item("rows_out", r.rows_out)?;
    Ok((PyDataset { inner }, report))
}
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDataset>()?;
    m.add_function(wrap_pyfunction!(preprocess_log_py, m)?)
}
