//! `prrrp._prrrp.read_numeric_csv`: the fast path of `prrrp.csvio.read_table`.

use numpy::{PyArray1, PyArrayMethods};
use prrrp_core::data::csv::parse_numeric_csv;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// The plain case of a measurement CSV file's bytes `data` (see
/// `prrrp_core::data::csv::parse_numeric_csv`): `(header line, its 1-based line number,
/// values (rows, width) float64)`, or None when the text holds anything else (quoted
/// cells, a cell that is not a finite number, a row of another width, ...), for the
/// general reader to say what is wrong. Parsed with the GIL released.
#[pyfunction]
fn read_numeric_csv<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyBytes>,
) -> PyResult<Option<(String, usize, Bound<'py, PyAny>)>> {
    let bytes = data.as_bytes();
    let Some(table) = py.detach(|| parse_numeric_csv(bytes)) else {
        return Ok(None);
    };
    let values = PyArray1::from_vec(py, table.values).reshape([table.rows, table.width])?;
    Ok(Some((table.header, table.header_line, values.into_any())))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_numeric_csv, m)?)?;
    Ok(())
}
