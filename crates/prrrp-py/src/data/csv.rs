//! `prrrp._prrrp.read_numeric_csv`: the fast path of `prrrp.csvio.read_table`.

use prrrp_core::data::csv::parse_numeric_csv;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// What [`read_numeric_csv`] returns for a plain file: header line, its line number, rows,
/// cells per row, values.
type Plain<'py> = (String, usize, usize, usize, Bound<'py, PyBytes>);

/// The plain case of a measurement CSV file's bytes `data` (see
/// `prrrp_core::data::csv::parse_numeric_csv`): `(header line, its 1-based line number,
/// rows, cells per row, the values as native-endian float64 bytes, row after row)`, or
/// None when the text holds anything else (quoted cells, a cell that is not a finite
/// number, a row of another width, ...), for the general reader to say what is wrong.
/// Parsed with the GIL released. Bytes, not an array: the first array a process makes
/// loads numpy's C API, which a Ctrl-C arriving then would turn into a panic.
#[pyfunction]
fn read_numeric_csv<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyBytes>,
) -> PyResult<Option<Plain<'py>>> {
    let bytes = data.as_bytes();
    let Some(table) = py.detach(|| parse_numeric_csv(bytes)) else {
        return Ok(None);
    };
    let values = PyBytes::new_with(py, 8 * table.values.len(), |buf| {
        for (cell, x) in buf.chunks_exact_mut(8).zip(&table.values) {
            cell.copy_from_slice(&x.to_ne_bytes());
        }
        Ok(())
    })?;
    Ok(Some((
        table.header,
        table.header_line,
        table.rows,
        table.width,
        values,
    )))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_numeric_csv, m)?)?;
    Ok(())
}
