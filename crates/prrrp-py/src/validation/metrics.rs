//! The error indices of eqs. 45–47: `prrrp.rms`, `prrrp.rsd`, `prrrp.agreement_index`,
//! `prrrp.error_indices`, and `prrrp.relative_errors_percent`.

use prrrp_core::{
    agreement_index as core_ai, error_indices as core_indices, relative_errors_percent,
    rms as core_rms, rsd as core_rsd, PrrrpError,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{any_array, fmt_shape, to_array, Out};
use crate::errors::{shape_error, ToPyResult};

/// The columns of `observed` and `predicted`: shape (N,) → one series, (N, C) → C series.
/// Returns the series and C (None for 1-D input).
#[allow(clippy::type_complexity)]
fn columns(
    observed: &Bound<'_, PyAny>,
    predicted: &Bound<'_, PyAny>,
) -> PyResult<(Vec<(Vec<f64>, Vec<f64>)>, Option<usize>)> {
    let py = observed.py();
    let (so, o) = any_array(observed, "observed", "(N,) or (N, C)")?;
    let (sp, p) = any_array(predicted, "predicted", "(N,) or (N, C)")?;
    if so.is_empty() || so.len() > 2 {
        return Err(shape_error(
            py,
            "observed",
            "(N,) or (N, C)",
            fmt_shape(&so),
        ));
    }
    if sp != so {
        return Err(shape_error(py, "predicted", fmt_shape(&so), fmt_shape(&sp)));
    }
    let c = if so.len() == 2 { so[1] } else { 1 };
    let n = so[0];
    let cols = (0..c)
        .map(|j| {
            let pick = |v: &[f64]| (0..n).map(|i| v[i * c + j]).collect::<Vec<f64>>();
            (pick(&o), pick(&p))
        })
        .collect();
    Ok((cols, (so.len() == 2).then_some(c)))
}

fn per_column<'py>(
    py: Python<'py>,
    observed: &Bound<'py, PyAny>,
    predicted: &Bound<'py, PyAny>,
    f: fn(&[f64], &[f64]) -> Result<f64, PrrrpError>,
) -> Out<'py> {
    let (cols, c) = columns(observed, predicted)?;
    let mut out = Vec::with_capacity(cols.len());
    for (o, p) in &cols {
        out.push(f(o, p).to_py(py)?);
    }
    match c {
        None => to_array(py, out, None, &[]),
        Some(c) => to_array(py, out, None, &[c]),
    }
}

/// One `#[pyfunction]` per index: `observed` and `predicted` (N,) or (N, C), the index of
/// each column by `per_column`.
macro_rules! per_column_functions {
    ($($(#[$doc:meta])* $name:ident = $f:path;)*) => {$(
        $(#[$doc])*
        #[pyfunction]
        fn $name<'py>(
            py: Python<'py>,
            observed: &Bound<'py, PyAny>,
            predicted: &Bound<'py, PyAny>,
        ) -> Out<'py> {
            per_column(py, observed, predicted, $f)
        }
    )*};
}

per_column_functions! {
    /// RMS of observed − predicted (eq. 45), in their units: a float for (N,) inputs, (C,) per
    /// column for (N, C).
    rms = core_rms;
    /// Residual standard deviation relative to the observed series (eq. 46), dimensionless;
    /// float or (C,).
    rsd = core_rsd;
    /// Willmott's agreement index (eq. 47) in [0, 1]; float or (C,).
    agreement_index = core_ai;
}

/// The three indices as a dict `rms`, `rsd`, `ai`: floats for (N,) inputs, (C,) arrays
/// for (N, C).
#[pyfunction]
fn error_indices<'py>(
    py: Python<'py>,
    observed: &Bound<'py, PyAny>,
    predicted: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let (cols, c) = columns(observed, predicted)?;
    let (mut r, mut s, mut a) = (Vec::new(), Vec::new(), Vec::new());
    for (o, p) in &cols {
        let e = core_indices(o, p).to_py(py)?;
        r.push(e.rms);
        s.push(e.rsd);
        a.push(e.ai);
    }
    let d = PyDict::new(py);
    for (k, v) in [("rms", r), ("rsd", s), ("ai", a)] {
        let shape: Vec<usize> = c.into_iter().collect();
        d.set_item(k, to_array(py, v, None, &shape)?)?;
    }
    Ok(d)
}

/// Relative errors 100·|estimate − truth|/|truth| (%) per entry (the absolute error where the
/// truth is 0); (K,) arrays in and out.
#[pyfunction(name = "relative_errors_percent")]
fn relative_errors<'py>(
    py: Python<'py>,
    estimate: &Bound<'py, PyAny>,
    truth: &Bound<'py, PyAny>,
) -> Out<'py> {
    let e = crate::arrays::vector(estimate, "estimate")?;
    let t = crate::arrays::vector(truth, "truth")?;
    crate::arrays::check_len(py, "truth", t.len(), e.len(), "")?;
    for (name, v) in [("estimate", &e), ("truth", &t)] {
        if let Some(row) = v.iter().position(|x| !x.is_finite()) {
            return Err(crate::errors::to_pyerr(
                py,
                &prrrp_core::PrrrpError::NonFinite {
                    what: name.into(),
                    row: Some(row),
                },
            ));
        }
    }
    let n = e.len();
    let r = relative_errors_percent(&e, &t);
    // Finite inputs can still overflow (|e − t| of ±1e308).
    if let Some(row) = r.iter().position(|x| !x.is_finite()) {
        return Err(crate::errors::to_pyerr(
            py,
            &prrrp_core::PrrrpError::NonFinite {
                what: "relative error (it overflowed)".into(),
                row: Some(row),
            },
        ));
    }
    to_array(py, r, None, &[n])
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(rms, m)?)?;
    m.add_function(wrap_pyfunction!(rsd, m)?)?;
    m.add_function(wrap_pyfunction!(agreement_index, m)?)?;
    m.add_function(wrap_pyfunction!(error_indices, m)?)?;
    m.add_function(wrap_pyfunction!(relative_errors, m)?)?;
    Ok(())
}
