//! Analytic derivatives of the dynamics (for the extended Kalman filter and for
//! sensitivity studies): the result classes `prrrp.InverseDerivatives` and
//! `prrrp.ForwardDerivatives`, computed by `Robot.inverse_derivatives` /
//! `Robot.forward_derivatives`.

use prrrp_core::{PrrrpModel, NPARAM};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{batch_len, map_samples, write_row_major, Samples};

/// ∂τ/∂q and ∂τ/∂q̇ of the inverse dynamics at fixed q̈ and λ. Unpacks as
/// `dtau_dq, dtau_dqd = ...`.
#[pyclass(module = "prrrp", name = "InverseDerivatives", frozen)]
pub(crate) struct PyInverseDerivatives {
    /// ∂τ/∂q, shape (5, 5) or (N, 5, 5).
    #[pyo3(get)]
    dtau_dq: Py<PyAny>,
    /// ∂τ/∂q̇, shape (5, 5) or (N, 5, 5).
    #[pyo3(get)]
    dtau_dqd: Py<PyAny>,
}

#[pymethods]
impl PyInverseDerivatives {
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = PyTuple::new(py, [&self.dtau_dq, &self.dtau_dqd])?;
        Ok(t.try_iter()?.into_any())
    }

    fn __len__(&self) -> usize {
        2
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "InverseDerivatives(dtau_dq={}, dtau_dqd={})",
            self.dtau_dq.bind(py).repr()?,
            self.dtau_dqd.bind(py).repr()?
        ))
    }
}

/// Forward dynamics q̈ and its derivatives at fixed τ. Unpacks as
/// `qdd, dqdd_dq, dqdd_dqd, dqdd_dlambda = ...`.
#[pyclass(module = "prrrp", name = "ForwardDerivatives", frozen)]
pub(crate) struct PyForwardDerivatives {
    /// q̈, shape (5,) or (N, 5).
    #[pyo3(get)]
    qdd: Py<PyAny>,
    /// ∂q̈/∂q, shape (5, 5) or (N, 5, 5).
    #[pyo3(get)]
    dqdd_dq: Py<PyAny>,
    /// ∂q̈/∂q̇, shape (5, 5) or (N, 5, 5).
    #[pyo3(get)]
    dqdd_dqd: Py<PyAny>,
    /// ∂q̈/∂λ = −M⁻¹·Φ, shape (5, 8) or (N, 5, 8).
    #[pyo3(get)]
    dqdd_dlambda: Py<PyAny>,
}

#[pymethods]
impl PyForwardDerivatives {
    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = PyTuple::new(
            py,
            [&self.qdd, &self.dqdd_dq, &self.dqdd_dqd, &self.dqdd_dlambda],
        )?;
        Ok(t.try_iter()?.into_any())
    }

    fn __len__(&self) -> usize {
        4
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "ForwardDerivatives(qdd={}, dqdd_dq={}, dqdd_dqd={}, dqdd_dlambda={})",
            self.qdd.bind(py).repr()?,
            self.dqdd_dq.bind(py).repr()?,
            self.dqdd_dqd.bind(py).repr()?,
            self.dqdd_dlambda.bind(py).repr()?
        ))
    }
}

pub(crate) fn inverse_derivatives(
    py: Python<'_>,
    model: PrrrpModel,
    q: &Bound<'_, PyAny>,
    qd: &Bound<'_, PyAny>,
    qdd: &Bound<'_, PyAny>,
    lam: Samples<NPARAM>,
) -> PyResult<PyInverseDerivatives> {
    let (q, qd, qdd) = (
        Samples::<5>::extract(q, "q")?,
        Samples::<5>::extract(qd, "qd")?,
        Samples::<5>::extract(qdd, "qdd")?,
    );
    let n = batch_len(py, &[&q, &qd, &qdd, &lam])?;
    let [dq, dqd] = map_samples(py, n, [&[5, 5], &[5, 5]], |k, [dq, dqd]| {
        let d = model.inverse_derivatives(q.at(k), qd.at(k), qdd.at(k), lam.at(k));
        write_row_major(&d.dtau_dq, dq);
        write_row_major(&d.dtau_dqd, dqd);
        Ok(())
    })?;
    Ok(PyInverseDerivatives {
        dtau_dq: dq.unbind(),
        dtau_dqd: dqd.unbind(),
    })
}

pub(crate) fn forward_derivatives(
    py: Python<'_>,
    model: PrrrpModel,
    q: &Bound<'_, PyAny>,
    qd: &Bound<'_, PyAny>,
    tau: &Bound<'_, PyAny>,
    lam: Samples<NPARAM>,
) -> PyResult<PyForwardDerivatives> {
    let (q, qd, tau) = (
        Samples::<5>::extract(q, "q")?,
        Samples::<5>::extract(qd, "qd")?,
        Samples::<5>::extract(tau, "tau")?,
    );
    let n = batch_len(py, &[&q, &qd, &tau, &lam])?;
    let [qdd, dq, dqd, dl] = map_samples(
        py,
        n,
        [&[5], &[5, 5], &[5, 5], &[5, NPARAM]],
        |k, [qdd, dq, dqd, dl]| {
            let d = model.forward_derivatives(q.at(k), qd.at(k), tau.at(k), lam.at(k))?;
            qdd.copy_from_slice(d.qdd.as_slice());
            write_row_major(&d.dqdd_dq, dq);
            write_row_major(&d.dqdd_dqd, dqd);
            write_row_major(&d.dqdd_dlambda, dl);
            Ok(())
        },
    )?;
    Ok(PyForwardDerivatives {
        qdd: qdd.unbind(),
        dqdd_dq: dq.unbind(),
        dqdd_dqd: dqd.unbind(),
        dqdd_dlambda: dl.unbind(),
    })
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyInverseDerivatives>()?;
    m.add_class::<PyForwardDerivatives>()
}
