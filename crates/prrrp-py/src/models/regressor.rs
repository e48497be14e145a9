//! The regressor Φ(q, q̇, q̈) (τ = Φ·λ), the stacked observation matrix W and its
//! singular values / condition number: `prrrp.regressor`, `prrrp.observation_matrix`,
//! `prrrp.singular_values`, `prrrp.condition_number`.

use faer::Mat;
use numpy::ndarray::Ix2;
use numpy::{PyArray1, PyUntypedArrayMethods};
use prrrp_core::{PrrrpError, PrrrpModel, NDOF, NPARAM, STANDARD_GRAVITY};
use pyo3::prelude::*;

use crate::arrays::{map_samples, samples_of, write_row_major, Out};
use crate::errors::{to_pyerr, ToPyResult};

/// A model with gravity `g` (m/s², along −z), checked like `Robot`'s.
pub(crate) fn model(py: Python<'_>, g: f64) -> PyResult<PrrrpModel> {
    if !(g.is_finite() && g >= 0.0) {
        return Err(to_pyerr(
            py,
            &PrrrpError::InvalidParameter {
                field: "gravity".into(),
                value: g,
                reason: "must be finite and >= 0 m/s²",
            },
        ));
    }
    Ok(PrrrpModel::new(g))
}

/// Φ at the arguments `[q, qd, qdd]`: (5, 8), or (N, 5, 8) for a batch.
pub(crate) fn regressor_at<'py>(
    py: Python<'py>,
    model: PrrrpModel,
    args: [&Bound<'py, PyAny>; 3],
) -> Out<'py> {
    let ([q, qd, qdd], n) = samples_of::<NDOF, 3>(py, args, ["q", "qd", "qdd"], &[])?;
    let [phi] = map_samples(py, n, [&[NDOF, NPARAM]], |k, [out]| {
        write_row_major(&model.regressor(q.at(k), qd.at(k), qdd.at(k)), out);
        Ok(())
    })?;
    Ok(phi)
}

/// The module functions of Φ of the paper's arm: each `fn name = |phi| value;` becomes
/// `name(q, qd, qdd, *, gravity)` returning `value` of the regressors `phi` of its
/// arguments at that gravity.
macro_rules! regressor_functions {
    ($($(#[$doc:meta])* fn $name:ident = |$phi:ident| $value:expr;)*) => {$(
        $(#[$doc])*
        #[pyfunction]
        #[pyo3(signature = (q, qd, qdd, *, gravity=STANDARD_GRAVITY))]
        fn $name<'py>(
            py: Python<'py>,
            q: &Bound<'py, PyAny>,
            qd: &Bound<'py, PyAny>,
            qdd: &Bound<'py, PyAny>,
            gravity: f64,
        ) -> Out<'py> {
            let $phi = regressor_at(py, model(py, gravity)?, [q, qd, qdd])?;
            $value
        }
    )*};
}

regressor_functions! {
    /// Regressor Φ(q, q̇, q̈) with τ = Φ·λ: shape (5, 8) for one sample, (N, 5, 8) for a batch.
    /// `gravity` in m/s² (default 9.81).
    fn regressor = |phi| Ok(phi);

    /// Observation matrix W (eq. 35): the regressors of N samples stacked, shape (5·N, 8);
    /// rows 5k..5k+5 hold Φ(q_k, q̇_k, q̈_k). `gravity` in m/s² (default 9.81).
    // The batch of Φ, row-major (N, 5, 8), is W read as (5·N, 8).
    fn observation_matrix = |phi| phi.call_method1("reshape", ((-1i64, NPARAM),));
}

/// Reads a 2-D matrix argument into faer.
fn matrix(w: &Bound<'_, PyAny>, name: &str) -> PyResult<Mat<f64>> {
    let what = "a 2-D float64 array (rows, cols)";
    let arr = crate::arrays::float_array_of::<Ix2>(w, name, what)?;
    let v = arr.as_array();
    Ok(Mat::from_fn(arr.shape()[0], arr.shape()[1], |i, j| {
        v[[i, j]]
    }))
}

/// Singular values of W in decreasing order, shape (cols,). W needs at least as many rows
/// as columns.
#[pyfunction]
fn singular_values<'py>(
    py: Python<'py>,
    w: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let w = matrix(w, "w")?;
    let s = py.detach(|| prrrp_core::singular_values(&w)).to_py(py)?;
    Ok(PyArray1::from_vec(py, s))
}

/// Condition number σmax/σmin of W (eq. 38); `inf` if W is rank deficient.
#[pyfunction]
fn condition_number(py: Python<'_>, w: &Bound<'_, PyAny>) -> PyResult<f64> {
    let w = matrix(w, "w")?;
    py.detach(|| prrrp_core::condition_number(&w)).to_py(py)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(regressor, m)?)?;
    m.add_function(wrap_pyfunction!(observation_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(singular_values, m)?)?;
    m.add_function(wrap_pyfunction!(condition_number, m)?)
}
