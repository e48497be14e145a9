//! Analytic derivatives of the dynamics (for the extended Kalman filter and for
//! sensitivity studies): the result classes `prrrp.InverseDerivatives` and
//! `prrrp.ForwardDerivatives`, computed by `Robot.inverse_derivatives` /
//! `Robot.forward_derivatives`.

use prrrp_core::{PrrrpModel, NPARAM};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

use crate::arrays::{map_samples, samples_of, write_row_major, Out, Samples};

/// A frozen result class of named arrays that unpacks like a tuple of them, in order:
/// `__iter__`, `__len__` and a `Name(field=..., ...)` repr.
macro_rules! unpackable {
    ($(#[$doc:meta])* $ty:ident = $name:literal { $($(#[$fdoc:meta])* $field:ident,)+ }) => {
        $(#[$doc])*
        #[pyclass(module = "prrrp", name = $name, frozen)]
        pub(crate) struct $ty {
            $(
            $(#[$fdoc])*
            #[pyo3(get)]
            $field: Py<PyAny>,
            )+
        }

        #[pymethods]
        impl $ty {
            fn __iter__<'py>(&self, py: Python<'py>) -> Out<'py> {
                let t = PyTuple::new(py, [$(&self.$field),+])?;
                Ok(t.try_iter()?.into_any())
            }

            fn __len__(&self) -> usize {
                [$(stringify!($field)),+].len()
            }

            fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
                let fields = [$(format!(
                    concat!(stringify!($field), "={}"),
                    self.$field.bind(py).repr()?
                )),+];
                Ok(format!(concat!($name, "({})"), fields.join(", ")))
            }
        }
    };
}

unpackable! {
    /// ∂τ/∂q and ∂τ/∂q̇ of the inverse dynamics at fixed q̈ and λ. Unpacks as
    /// `dtau_dq, dtau_dqd = ...`.
    PyInverseDerivatives = "InverseDerivatives" {
        /// ∂τ/∂q, shape (5, 5) or (N, 5, 5).
        dtau_dq,
        /// ∂τ/∂q̇, shape (5, 5) or (N, 5, 5).
        dtau_dqd,
    }
}

unpackable! {
    /// Forward dynamics q̈ and its derivatives at fixed τ. Unpacks as
    /// `qdd, dqdd_dq, dqdd_dqd, dqdd_dlambda = ...`.
    PyForwardDerivatives = "ForwardDerivatives" {
        /// q̈, shape (5,) or (N, 5).
        qdd,
        /// ∂q̈/∂q, shape (5, 5) or (N, 5, 5).
        dqdd_dq,
        /// ∂q̈/∂q̇, shape (5, 5) or (N, 5, 5).
        dqdd_dqd,
        /// ∂q̈/∂λ = −M⁻¹·Φ, shape (5, 8) or (N, 5, 8).
        dqdd_dlambda,
    }
}

/// `Robot.inverse_derivatives` at the arguments `[q, qd, qdd]`.
pub(crate) fn inverse_derivatives(
    py: Python<'_>,
    model: PrrrpModel,
    args: [&Bound<'_, PyAny>; 3],
    lam: Samples<NPARAM>,
) -> PyResult<PyInverseDerivatives> {
    let ([q, qd, qdd], n) = samples_of::<5, 3>(py, args, ["q", "qd", "qdd"], &[&lam])?;
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

/// `Robot.forward_derivatives` at the arguments `[q, qd, tau]`.
pub(crate) fn forward_derivatives(
    py: Python<'_>,
    model: PrrrpModel,
    args: [&Bound<'_, PyAny>; 3],
    lam: Samples<NPARAM>,
) -> PyResult<PyForwardDerivatives> {
    let ([q, qd, tau], n) = samples_of::<5, 3>(py, args, ["q", "qd", "tau"], &[&lam])?;
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
