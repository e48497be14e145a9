//! numpy ⇄ nalgebra at the boundary: one sample `(D,)` or a batch `(N, D)` in, arrays of the
//! matching shape out, with the per-sample loop run in Rust with the GIL released.
//!
//! Inputs are copied into fixed-size vectors while the GIL is held. The copy costs one pass
//! over memory, and it is what makes releasing the GIL sound: another Python thread may
//! write into the caller's array while the loop runs, but never into our copy. It also
//! handles any dtype convertible to float64 and any strides.

use nalgebra::{SMatrix, SVector};
use numpy::ndarray::Dimension;
use numpy::{
    AllowTypeChange, PyArray1, PyArrayLike, PyArrayLikeDyn, PyArrayMethods, PyUntypedArrayMethods,
};
use prrrp_core::PrrrpError;
use pyo3::prelude::*;
use pyo3::types::PyFloat;

use crate::errors::{shape_error, to_pyerr, Exc};

/// What most bindings return: any Python object (an array, a float, a dict ...).
pub(crate) type Out<'py> = PyResult<Bound<'py, PyAny>>;

/// `(q, qd, qdd)` of a trajectory evaluated at t.
pub(crate) type Triple<'py> = PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)>;

/// One sample or a batch of samples of a D-vector, from a numpy array-like argument.
pub(crate) struct Samples<const D: usize> {
    name: &'static str,
    data: Vec<SVector<f64, D>>,
    batch: bool,
}

impl<const D: usize> Samples<D> {
    /// A single sample that broadcasts against any batch.
    pub(crate) fn single(name: &'static str, v: SVector<f64, D>) -> Self {
        Self {
            name,
            data: vec![v],
            batch: false,
        }
    }

    /// Reads argument `name`: anything numpy converts to float64 with shape `(D,)` or
    /// `(N, D)`, every value finite.
    pub(crate) fn extract(obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Self> {
        let py = obj.py();
        let want = format!("({D},) or (N, {D})");
        let arr = float_array(obj, name, &want)?;
        let shape = arr.shape();
        let (batch, n) = match *shape {
            [d] if d == D => (false, 1),
            [n, d] if d == D => (true, n),
            _ => return Err(shape_error(py, name, want, fmt_shape(shape))),
        };
        let mut data: Vec<SVector<f64, D>> = Vec::with_capacity(n);
        // `as_slice` also accepts Fortran order, whose flat order is not the rows'.
        let finite = match arr.as_slice() {
            Ok(flat) if arr.is_c_contiguous() => {
                data.extend(flat.chunks_exact(D).map(SVector::from_column_slice));
                all_finite(flat)
            }
            // Strided or Fortran order: ndarray iterates in logical (row-major) order.
            _ => {
                let view = arr.as_array();
                let mut it = view.iter().copied();
                for _ in 0..n {
                    data.push(SVector::from_iterator(it.by_ref().take(D)));
                }
                data.iter().all(|v| all_finite(v.as_slice()))
            }
        };
        if !finite {
            let k = data
                .iter()
                .position(|v| !v.iter().all(|x| x.is_finite()))
                .unwrap_or(0);
            return Err(to_pyerr(
                py,
                &PrrrpError::NonFinite {
                    what: name.into(),
                    row: batch.then_some(k),
                },
            ));
        }
        Ok(Self { name, data, batch })
    }

    /// Like [`Samples::extract`], or `default` (a single sample) when `obj` is `None`.
    pub(crate) fn extract_or(
        obj: Option<&Bound<'_, PyAny>>,
        name: &'static str,
        default: SVector<f64, D>,
    ) -> PyResult<Self> {
        match obj {
            Some(o) => Self::extract(o, name),
            None => Ok(Self::single(name, default)),
        }
    }

    /// Sample `k` of the batch (the single sample broadcasts).
    #[inline(always)]
    pub(crate) fn at(&self, k: usize) -> &SVector<f64, D> {
        if self.batch {
            &self.data[k]
        } else {
            &self.data[0]
        }
    }

    fn arg(&self) -> Arg<'_> {
        Arg {
            name: self.name,
            dim: D,
            len: self.batch.then_some(self.data.len()),
        }
    }
}

/// What [`batch_len`] needs to know about an argument.
pub(crate) struct Arg<'a> {
    name: &'a str,
    dim: usize,
    len: Option<usize>,
}

/// Something that is one argument of a batched call.
pub(crate) trait AsArg {
    fn as_arg(&self) -> Arg<'_>;
}

impl<const D: usize> AsArg for Samples<D> {
    fn as_arg(&self) -> Arg<'_> {
        self.arg()
    }
}

/// The common batch length N of the arguments, `None` if every one is a single sample.
/// Single samples broadcast; two batches must have the same N.
pub(crate) fn batch_len(py: Python<'_>, args: &[&dyn AsArg]) -> PyResult<Option<usize>> {
    let mut first: Option<(usize, &str)> = None;
    for a in args {
        let a = a.as_arg();
        if let Some(n) = a.len {
            match first {
                None => first = Some((n, a.name)),
                Some((n0, name0)) if n0 != n => {
                    return Err(shape_error(
                        py,
                        a.name,
                        format!(
                            "({}, {}) or ({},) ({n0} samples, as `{name0}`)",
                            n0, a.dim, a.dim
                        ),
                        format!("({n}, {})", a.dim),
                    ))
                }
                Some(_) => {}
            }
        }
    }
    Ok(first.map(|(n, _)| n))
}

/// K arguments of (D,) or (N, D), read in order (the first bad one raises, by its
/// name), and the batch length they share with the arguments `with` ([`batch_len`]).
pub(crate) fn samples_of<const D: usize, const K: usize>(
    py: Python<'_>,
    args: [&Bound<'_, PyAny>; K],
    names: [&'static str; K],
    with: &[&dyn AsArg],
) -> PyResult<([Samples<D>; K], Option<usize>)> {
    read_args(py, args, names, with, Samples::<D>::extract)
}

/// [`samples_of`] for vectors whose length `dim` is known only at run time (a chain's
/// joints): K arguments of (dim,) or (N, dim) and their common batch length.
pub(crate) fn dyn_samples_of<const K: usize>(
    py: Python<'_>,
    args: [&Bound<'_, PyAny>; K],
    names: [&'static str; K],
    dim: usize,
) -> PyResult<([DynSamples; K], Option<usize>)> {
    read_args(py, args, names, &[], |obj, name| {
        DynSamples::extract(obj, name, dim)
    })
}

/// K arguments read in order by `read` and their batch length (with `with`'s).
fn read_args<S: AsArg, const K: usize>(
    py: Python<'_>,
    args: [&Bound<'_, PyAny>; K],
    names: [&'static str; K],
    with: &[&dyn AsArg],
    read: impl Fn(&Bound<'_, PyAny>, &'static str) -> PyResult<S>,
) -> PyResult<([S; K], Option<usize>)> {
    let mut out = Vec::with_capacity(K);
    for (obj, name) in args.into_iter().zip(names) {
        out.push(read(obj, name)?);
    }
    let Ok(samples) = <[S; K]>::try_from(out) else {
        unreachable!("K arguments read as K sample sets")
    };
    let mut all: Vec<&dyn AsArg> = samples.iter().map(|s| s as &dyn AsArg).collect();
    all.extend_from_slice(with);
    let n = batch_len(py, &all)?;
    Ok((samples, n))
}

pub(crate) fn fmt_shape(shape: &[usize]) -> String {
    match shape {
        [d] => format!("({d},)"),
        _ => {
            let parts: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
            format!("({})", parts.join(", "))
        }
    }
}

/// Copies `m` into `out` in row-major (numpy) order; nalgebra stores column-major.
#[inline(always)]
pub(crate) fn write_row_major<const R: usize, const C: usize>(
    m: &SMatrix<f64, R, C>,
    out: &mut [f64],
) {
    for (i, row) in out.chunks_exact_mut(C).take(R).enumerate() {
        for (j, o) in row.iter_mut().enumerate() {
            *o = m[(i, j)];
        }
    }
}

/// Runs `f(k, outputs)` for every sample k and returns K arrays: output i has shape
/// `shapes[i]` for a single sample and `(N, *shapes[i])` for a batch of N. A 0-d single
/// output is returned as a Python float.
///
/// For a batch the loop runs with the GIL released. The first failing sample stops it;
/// its error is raised with a note and attribute `sample` giving k.
pub(crate) fn map_samples<'py, const K: usize, F>(
    py: Python<'py>,
    n: Option<usize>,
    shapes: [&[usize]; K],
    f: F,
) -> PyResult<[Bound<'py, PyAny>; K]>
where
    F: Fn(usize, [&mut [f64]; K]) -> Result<(), PrrrpError> + Sync,
{
    map_samples_with(py, n, shapes, (), |_, k, outs| f(k, outs))
}

/// [`map_samples`] with a mutable per-call `state` (e.g. a workspace of scratch buffers
/// made once per batch) passed to every call of `f`.
pub(crate) fn map_samples_with<'py, const K: usize, S, F>(
    py: Python<'py>,
    n: Option<usize>,
    shapes: [&[usize]; K],
    mut state: S,
    f: F,
) -> PyResult<[Bound<'py, PyAny>; K]>
where
    S: Send,
    F: Fn(&mut S, usize, [&mut [f64]; K]) -> Result<(), PrrrpError> + Sync,
{
    let inner: [usize; K] = shapes.map(|s| s.iter().product());
    let count = n.unwrap_or(1);
    let mut bufs: [Vec<f64>; K] = inner.map(|i| vec![0.0; i * count]);
    let mut run = |bufs: &mut [Vec<f64>; K]| -> Result<(), (usize, PrrrpError)> {
        for k in 0..count {
            let mut i = 0;
            let outs = bufs.each_mut().map(|b| {
                let s = inner[i];
                i += 1;
                &mut b[k * s..(k + 1) * s]
            });
            f(&mut state, k, outs).map_err(|e| (k, e))?;
            // Inputs are finite (checked on extraction), so a NaN or ∞ here is an overflow
            // (e.g. torques of 1e308): an error, never a silent value.
            for (b, &s) in bufs.iter().zip(&inner) {
                if !b[k * s..(k + 1) * s].iter().all(|x| x.is_finite()) {
                    return Err((
                        k,
                        PrrrpError::NonFinite {
                            what: "result (it overflowed: are the inputs in SI units?)".into(),
                            row: n.map(|_| k),
                        },
                    ));
                }
            }
        }
        Ok(())
    };
    let result = match n {
        None => run(&mut bufs),
        Some(_) => py.detach(|| run(&mut bufs)),
    };
    if let Err((k, e)) = result {
        let err = to_pyerr(py, &e);
        if n.is_some() {
            err.value(py).setattr("sample", k)?;
            err.add_note(py, format!("at sample {k} (index along the leading axis)"))?;
        }
        return Err(err);
    }
    let mut i = 0;
    let outs = bufs.map(|b| {
        let shape = shapes[i];
        i += 1;
        (b, shape)
    });
    let mut result = Vec::with_capacity(K);
    for (b, shape) in outs {
        result.push(to_array(py, b, n, shape)?);
    }
    result
        .try_into()
        .map_err(|_| Exc::Base.new_err(py, "internal: output count".into(), &[]))
}

/// A flat row-major buffer as a numpy array of shape `(N, *shape)` or `shape`, without a
/// copy; a 0-d single value as a Python float.
pub(crate) fn to_array<'py>(
    py: Python<'py>,
    buf: Vec<f64>,
    n: Option<usize>,
    shape: &[usize],
) -> Out<'py> {
    if n.is_none() && shape.is_empty() {
        return Ok(PyFloat::new(py, buf.first().copied().unwrap_or(f64::NAN)).into_any());
    }
    let full: Vec<usize> = n.into_iter().chain(shape.iter().copied()).collect();
    let arr = PyArray1::from_vec(py, buf);
    if full.len() == 1 {
        return Ok(arr.into_any());
    }
    Ok(arr.reshape(full)?.into_any())
}

/// Any float64-convertible array of exactly the shape `shape`, or an error naming `name`.
fn exact_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &'static str,
    shape: &[usize],
) -> PyResult<PyArrayLikeDyn<'py, f64, AllowTypeChange>> {
    let want = fmt_shape(shape);
    let arr = float_array(obj, name, &want)?;
    if arr.shape() != shape {
        return Err(shape_error(obj.py(), name, want, fmt_shape(arr.shape())));
    }
    Ok(arr)
}

/// Reads a fixed-length parameter vector (e.g. the five link masses): anything numpy
/// converts to float64 with shape `(D,)`. Values are not checked here; the core's
/// validation names the offending entry.
pub(crate) fn fixed_vector<const D: usize>(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
) -> PyResult<[f64; D]> {
    let arr = exact_array(obj, name, &[D])?;
    let mut out = [0.0; D];
    for (o, x) in out.iter_mut().zip(arr.as_array().iter()) {
        *o = *x;
    }
    Ok(out)
}

/// Reads a fixed-size matrix (e.g. an 18×18 covariance): anything numpy converts to
/// float64 with shape `(R, C)`.
pub(crate) fn fixed_matrix<const R: usize, const C: usize>(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
) -> PyResult<SMatrix<f64, R, C>> {
    let arr = exact_array(obj, name, &[R, C])?;
    let a = arr.as_array();
    Ok(SMatrix::from_fn(|i, j| a[[i, j]]))
}

impl<const D: usize> Samples<D> {
    /// The rows as a vector: a batch's N rows, or the one row of a single sample.
    pub(crate) fn into_rows(self) -> Vec<SVector<f64, D>> {
        self.data
    }

    /// Whether the argument had a leading batch axis.
    pub(crate) fn is_batch(&self) -> bool {
        self.batch
    }
}

/// Rows of D-vectors as a numpy array of shape (N, D).
pub(crate) fn rows_to_array<'py, const D: usize>(
    py: Python<'py>,
    rows: &[SVector<f64, D>],
) -> Out<'py> {
    let mut buf = Vec::with_capacity(rows.len() * D);
    for r in rows {
        buf.extend_from_slice(r.as_slice());
    }
    to_array(py, buf, Some(rows.len()), &[D])
}

/// The first non-finite entry of named vectors, as (name, index, value).
pub(crate) fn first_non_finite<'a, const K: usize>(
    named: [(&'a str, &[f64]); K],
) -> Option<(&'a str, usize, f64)> {
    named.into_iter().find_map(|(name, v)| {
        let j = v.iter().position(|x| !x.is_finite())?;
        Some((name, j, v[j]))
    })
}

/// Reads a 1-D float64 argument of any length (e.g. time stamps, shape (N,)).
pub(crate) fn vector(obj: &Bound<'_, PyAny>, name: &'static str) -> PyResult<Vec<f64>> {
    let (shape, data) = any_array(obj, name, "(N,)")?;
    if shape.len() != 1 {
        return Err(shape_error(obj.py(), name, "(N,)", fmt_shape(&shape)));
    }
    Ok(data)
}

/// A `ShapeMismatchError` naming `name` unless its `got` entries are the `want` it needs;
/// `note` (e.g. " (one type per DH row)") follows the expected shape in the message.
pub(crate) fn check_len(
    py: Python<'_>,
    name: &str,
    got: usize,
    want: usize,
    note: &str,
) -> PyResult<()> {
    if got == want {
        return Ok(());
    }
    Err(shape_error(
        py,
        name,
        format!("({want},){note}"),
        format!("({got},)"),
    ))
}

/// [`vector`] of exactly `len` values ([`check_len`]).
pub(crate) fn vector_of_len(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
    len: usize,
    note: &str,
) -> PyResult<Vec<f64>> {
    let v = vector(obj, name)?;
    check_len(obj.py(), name, v.len(), len, note)?;
    Ok(v)
}

/// Anything numpy converts to float64 (complex refused), or an `InvalidInputError` naming
/// `name` and the `expected` shape.
fn float_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &'static str,
    expected: &str,
) -> PyResult<PyArrayLikeDyn<'py, f64, AllowTypeChange>> {
    float_array_of(obj, name, &format!("a float64 array of shape {expected}"))
}

/// Anything numpy converts to a float64 array of dimension `D` (complex refused), or an
/// `InvalidInputError` saying that `name` must be convertible to `what`.
pub(crate) fn float_array_of<'py, D: Dimension + 'static>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    what: &str,
) -> PyResult<PyArrayLike<'py, f64, D, AllowTypeChange>> {
    let py = obj.py();
    reject_complex(obj, name)?;
    obj.extract::<PyArrayLike<'_, f64, D, AllowTypeChange>>()
        .map_err(|e| {
            let err = Exc::InvalidInput.new_err(
                py,
                format!("`{name}` must be convertible to {what}: {e}"),
                &[],
            );
            err.set_cause(py, Some(e));
            err
        })
}

/// Time stamps `t`: a scalar (None) or shape (N,) (Some(N)), every one finite.
pub(crate) fn times(t: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Option<usize>)> {
    let py = t.py();
    let (shape, ts) = any_array(t, "t", "() or (N,)")?;
    let batch = match *shape {
        [] => None,
        [k] => Some(k),
        _ => return Err(shape_error(py, "t", "() or (N,)", fmt_shape(&shape))),
    };
    if let Some(k) = ts.iter().position(|x| !x.is_finite()) {
        let what = "t".into();
        let row = batch.map(|_| k);
        return Err(to_pyerr(py, &PrrrpError::NonFinite { what, row }));
    }
    Ok((ts, batch))
}

/// Reads a float64 array of any shape: its shape and its values in row-major order.
pub(crate) fn any_array(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
    expected: &str,
) -> PyResult<(Vec<usize>, Vec<f64>)> {
    let arr = float_array(obj, name, expected)?;
    let shape = arr.shape().to_vec();
    let data = arr.as_array().iter().copied().collect();
    Ok((shape, data))
}

/// Reads an optional fixed-length vector (`None` → `default`).
pub(crate) fn fixed_or<const D: usize>(
    obj: Option<&Bound<'_, PyAny>>,
    name: &'static str,
    default: SVector<f64, D>,
) -> PyResult<SVector<f64, D>> {
    match obj {
        Some(o) => Ok(SVector::from(fixed_vector::<D>(o, name)?)),
        None => Ok(default),
    }
}

impl<const D: usize> Samples<D> {
    /// Reads a batch argument of shape (N, D) (a single sample is refused: the caller needs
    /// a time series), NaN/inf → NonFiniteError with the row.
    pub(crate) fn extract_rows(
        obj: &Bound<'_, PyAny>,
        name: &'static str,
    ) -> PyResult<Vec<SVector<f64, D>>> {
        let s = Self::extract(obj, name)?;
        if !s.is_batch() {
            return Err(shape_error(
                obj.py(),
                name,
                format!("(N, {D})"),
                format!("({D},)"),
            ));
        }
        Ok(s.into_rows())
    }
}

/// One sample `(D,)` or a batch `(N, D)` of a vector whose length D is known only at run
/// time (e.g. the joints of a `SerialChain`); the run-time twin of [`Samples`].
pub(crate) struct DynSamples {
    name: &'static str,
    dim: usize,
    /// Row-major values, `dim` per sample.
    data: Vec<f64>,
    batch: bool,
}

impl DynSamples {
    /// Reads argument `name`: anything numpy converts to float64 with shape `(dim,)` or
    /// `(N, dim)`, every value finite.
    pub(crate) fn extract(
        obj: &Bound<'_, PyAny>,
        name: &'static str,
        dim: usize,
    ) -> PyResult<Self> {
        let py = obj.py();
        let expected = format!("({dim},) or (N, {dim})");
        let (shape, data) = any_array(obj, name, &expected)?;
        let batch = match *shape {
            [d] if d == dim => false,
            [_, d] if d == dim => true,
            _ => return Err(shape_error(py, name, expected, fmt_shape(&shape))),
        };
        if dim > 0 && !all_finite(&data) {
            if let Some(k) = data
                .chunks_exact(dim)
                .position(|v| !v.iter().all(|x| x.is_finite()))
            {
                return Err(to_pyerr(
                    py,
                    &PrrrpError::NonFinite {
                        what: name.into(),
                        row: batch.then_some(k),
                    },
                ));
            }
        }
        Ok(Self {
            name,
            dim,
            data,
            batch,
        })
    }

    /// Sample `k` of the batch (the single sample broadcasts).
    #[inline(always)]
    pub(crate) fn at(&self, k: usize) -> &[f64] {
        let k = if self.batch { k } else { 0 };
        &self.data[k * self.dim..(k + 1) * self.dim]
    }
}

impl AsArg for DynSamples {
    fn as_arg(&self) -> Arg<'_> {
        Arg {
            name: self.name,
            dim: self.dim,
            len: self
                .batch
                .then(|| self.data.len().checked_div(self.dim).unwrap_or(0)),
        }
    }
}

/// Reads a 2-D float64 argument of shape `(rows, cols)`, returning its rows, row-major.
/// `rows` None accepts any number of rows.
pub(crate) fn matrix_rows(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
    rows: Option<usize>,
    cols: usize,
) -> PyResult<(usize, Vec<f64>)> {
    let expected = match rows {
        Some(r) => format!("({r}, {cols})"),
        None => format!("(n, {cols})"),
    };
    let (shape, data) = any_array(obj, name, &expected)?;
    match *shape {
        [r, c] if c == cols && (rows.is_none() || rows == Some(r)) => Ok((r, data)),
        _ => Err(shape_error(obj.py(), name, expected, fmt_shape(&shape))),
    }
}

/// Complex input would be cast to float64 with its imaginary part silently dropped
/// (numpy only warns): refuse it instead. Arrays and numpy scalars are told by their
/// dtype; anything else (lists, Python complex numbers) by `numpy.iscomplexobj`.
pub(crate) fn reject_complex(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    let py = obj.py();
    let complex = match obj.getattr(pyo3::intern!(py, "dtype")) {
        Ok(dt) => dt
            .getattr(pyo3::intern!(py, "kind"))
            .and_then(|k| k.extract::<String>())
            .is_ok_and(|k| k == "c"),
        Err(_) => py
            .import(pyo3::intern!(py, "numpy"))
            .and_then(|np| np.call_method1(pyo3::intern!(py, "iscomplexobj"), (obj,)))
            .and_then(|r| r.extract::<bool>())
            .unwrap_or(false),
    };
    if complex {
        return Err(Exc::InvalidInput.new_err(
            py,
            format!("`{name}` is complex; give real numbers (float64)"),
            &[],
        ));
    }
    Ok(())
}

/// A 0-based index argument, taken as an i64 so that a negative one (Python's "from the
/// end") is an `InvalidParameterError` naming it (`field`, built only on failure) instead of
/// the conversion's `OverflowError`. `len`, where known, bounds it (exclusive).
pub(crate) fn index_arg(
    py: Python<'_>,
    v: i64,
    len: Option<usize>,
    field: impl FnOnce() -> String,
    reason: &'static str,
) -> PyResult<usize> {
    // Not `Option::is_none_or`: it needs Rust 1.82, the MSRV is 1.80.
    match usize::try_from(v)
        .ok()
        .filter(|&i| !matches!(len, Some(n) if i >= n))
    {
        Some(i) => Ok(i),
        None => Err(to_pyerr(
            py,
            &PrrrpError::InvalidParameter {
                field: field(),
                value: v as f64,
                reason,
            },
        )),
    }
}

/// A non-negative integer argument (a seed, a count). Out of range (negative, too large)
/// is an `InvalidParameterError` — a `ValueError`, like every bad value — instead of
/// Python's `OverflowError`; pyo3 adds a note naming the argument.
#[derive(Debug, Clone, Copy)]
pub(crate) struct UInt<T>(pub T);

macro_rules! uint_extract {
    ($t:ty, $bound:literal) => {
        impl<'a, 'py> FromPyObject<'a, 'py> for UInt<$t> {
            type Error = PyErr;
            fn extract(obj: pyo3::Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
                let py = obj.py();
                match obj.extract::<$t>() {
                    Ok(v) => Ok(UInt(v)),
                    Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => {
                        let text = obj.repr().map(|r| r.to_string()).unwrap_or_default();
                        let reason = concat!("must be an integer in [0, ", $bound, ")");
                        let attrs = [
                            ("field", "integer argument".into_pyobject(py)?.into_any()),
                            ("value", text.as_str().into_pyobject(py)?.into_any()),
                            ("reason", reason.into_pyobject(py)?.into_any()),
                        ];
                        Err(Exc::InvalidParameter.new_err(
                            py,
                            format!("integer argument {text} is out of range: {reason}"),
                            &attrs,
                        ))
                    }
                    Err(e) => Err(e),
                }
            }
        }
    };
}
uint_extract!(u64, "2**64");
uint_extract!(usize, "2**64");

/// Whether every value is finite, with one branch for the whole array (x − x is 0 for a
/// finite x and NaN otherwise, and a NaN survives the sum); the row of a non-finite value
/// is looked up only when there is one. Eight partial sums, so that the loop vectorises.
#[allow(clippy::eq_op)]
fn all_finite(values: &[f64]) -> bool {
    let mut acc = [0.0f64; 8];
    let chunks = values.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for (a, &x) in acc.iter_mut().zip(c) {
            *a += x - x;
        }
    }
    for (a, &x) in acc.iter_mut().zip(rest) {
        *a += x - x;
    }
    acc.iter().sum::<f64>() == 0.0
}
