//! Python exceptions for [`PrrrpError`] and the one conversion trait, [`ToPyResult`].
//!
//! Hierarchy (all in module `prrrp`):
//! ```text
//! PrrrpError(Exception)
//! ├── InvalidInputError(PrrrpError, ValueError)     the caller's input is at fault
//! │   ├── InvalidParameterError                      .field .value .reason
//! │   ├── NonFiniteError                             .what .row
//! │   ├── ShapeMismatchError                         .what .expected .got
//! │   ├── TooFewSamplesError                         .needed .got
//! │   ├── NonIncreasingTimeError                     .row
//! │   ├── RankDeficientError                         .rank .params .cond .directions
//! │   ├── NotPositiveDefiniteError                   .what
//! │   ├── InfeasibleError                            .what
//! │   └── RobotFileError                             .file .element .message
//! └── DivergedError(PrrrpError, ArithmeticError)    .what .at .hint
//! ```
//! A non-physical λ is what makes the mass matrix indefinite, so like numpy's
//! `LinAlgError` the definiteness error is a `ValueError`. Divergence of an iterative
//! algorithm is an arithmetic failure whose fix is a setting, not the data.
//!
//! The types need two bases, which `create_exception!` cannot express, so they are made
//! with Python's `type(name, bases, dict)` once and cached.

use prrrp_core::PrrrpError;
use pyo3::exceptions::{
    PyArithmeticError, PyException, PyKeyboardInterrupt, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

/// The Python exception classes, in creation order (a base before its subclasses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Exc {
    Base,
    InvalidInput,
    InvalidParameter,
    NonFinite,
    ShapeMismatch,
    TooFewSamples,
    NonIncreasingTime,
    RankDeficient,
    NotPositiveDefinite,
    Infeasible,
    RobotFile,
    Diverged,
}

const ALL: [Exc; 12] = [
    Exc::Base,
    Exc::InvalidInput,
    Exc::InvalidParameter,
    Exc::NonFinite,
    Exc::ShapeMismatch,
    Exc::TooFewSamples,
    Exc::NonIncreasingTime,
    Exc::RankDeficient,
    Exc::NotPositiveDefinite,
    Exc::Infeasible,
    Exc::RobotFile,
    Exc::Diverged,
];

static TYPES: [PyOnceLock<Py<PyType>>; 12] = [const { PyOnceLock::new() }; 12];

impl Exc {
    fn name(self) -> &'static str {
        match self {
            Exc::Base => "PrrrpError",
            Exc::InvalidInput => "InvalidInputError",
            Exc::InvalidParameter => "InvalidParameterError",
            Exc::NonFinite => "NonFiniteError",
            Exc::ShapeMismatch => "ShapeMismatchError",
            Exc::TooFewSamples => "TooFewSamplesError",
            Exc::NonIncreasingTime => "NonIncreasingTimeError",
            Exc::RankDeficient => "RankDeficientError",
            Exc::NotPositiveDefinite => "NotPositiveDefiniteError",
            Exc::Infeasible => "InfeasibleError",
            Exc::RobotFile => "RobotFileError",
            Exc::Diverged => "DivergedError",
        }
    }

    fn doc(self) -> &'static str {
        match self {
            Exc::Base => "Base class of every error raised by prrrp.",
            Exc::InvalidInput => {
                "The input is at fault (shape, value, too few samples, ...). Also a ValueError."
            }
            Exc::InvalidParameter => {
                "A physical or configuration value is out of range. Attributes: field, value, reason."
            }
            Exc::NonFinite => {
                "An input holds NaN or infinity. Attributes: what, row (sample index or None)."
            }
            Exc::ShapeMismatch => {
                "An array has the wrong shape or length. Attributes: what, expected, got."
            }
            Exc::TooFewSamples => "Too few samples to identify the parameters. Attributes: needed, got.",
            Exc::NonIncreasingTime => {
                "Time stamps are not strictly increasing. Attribute: row (first bad row)."
            }
            Exc::RankDeficient => {
                "The observation matrix does not determine every parameter. Attributes: rank, \
                 params, cond, directions (unidentifiable directions in parameter space)."
            }
            Exc::NotPositiveDefinite => {
                "A matrix that must be positive definite is not (e.g. M(q, λ) for a non-physical \
                 λ). Attribute: what."
            }
            Exc::Infeasible => "A constrained problem has no feasible answer. Attribute: what.",
            Exc::RobotFile => {
                "A robot file (URDF, TOML) cannot be read or describes no usable chain. \
                 Attributes: file, element (the element or key at fault), message."
            }
            Exc::Diverged => {
                "An iterative estimator or integrator blew up. Also an ArithmeticError. \
                 Attributes: what, at, hint."
            }
        }
    }

    /// The class object, created on first use.
    pub(crate) fn type_object(self, py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
        let cell = &TYPES[self as usize];
        let ty = cell.get_or_try_init(py, || self.create(py))?;
        Ok(ty.bind(py))
    }

    fn create(self, py: Python<'_>) -> PyResult<Py<PyType>> {
        let bases = match self {
            Exc::Base => PyTuple::new(py, [py.get_type::<PyException>()])?,
            Exc::InvalidInput => PyTuple::new(
                py,
                [
                    Exc::Base.type_object(py)?.clone(),
                    py.get_type::<PyValueError>(),
                ],
            )?,
            Exc::Diverged => PyTuple::new(
                py,
                [
                    Exc::Base.type_object(py)?.clone(),
                    py.get_type::<PyArithmeticError>(),
                ],
            )?,
            _ => PyTuple::new(py, [Exc::InvalidInput.type_object(py)?.clone()])?,
        };
        let dict = PyDict::new(py);
        dict.set_item("__module__", "prrrp")?;
        dict.set_item("__doc__", self.doc())?;
        let ty = py
            .get_type::<PyType>()
            .call1((self.name(), bases, dict))?
            .cast_into::<PyType>()?;
        Ok(ty.unbind())
    }

    /// A new exception of this class with message `msg` and the given attributes.
    pub(crate) fn new_err<'py>(
        self,
        py: Python<'py>,
        msg: String,
        attrs: &[(&str, Bound<'py, PyAny>)],
    ) -> PyErr {
        let build = || -> PyResult<PyErr> {
            let value = self.type_object(py)?.call1((msg.clone(),))?;
            for (k, v) in attrs {
                value.setattr(*k, v)?;
            }
            Ok(PyErr::from_value(value))
        };
        // Creating the class or setting an attribute can only fail if Python itself is in
        // trouble (out of memory); still raise something that carries the message.
        build().unwrap_or_else(|e| {
            let err = PyRuntimeError::new_err(msg);
            err.set_cause(py, Some(e));
            err
        })
    }
}

/// Adds every exception class to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    for exc in ALL {
        m.add(exc.name(), exc.type_object(py)?)?;
    }
    Ok(())
}

/// Turns a core error into the matching Python exception, with its fields as attributes.
pub(crate) fn to_pyerr(py: Python<'_>, err: &PrrrpError) -> PyErr {
    let msg = err.to_string();
    macro_rules! attrs {
        ($($k:literal => $v:expr),* $(,)?) => {
            {
                let mut v: Vec<(&str, Bound<'_, PyAny>)> = Vec::new();
                $( match $v.into_pyobject(py) {
                    Ok(o) => v.push(($k, o.into_any())),
                    Err(e) => return PyErr::from(e),
                } )*
                v
            }
        };
    }
    match err {
        PrrrpError::InvalidParameter {
            field,
            value,
            reason,
        } => Exc::InvalidParameter.new_err(
            py,
            msg,
            &attrs!("field" => field.as_str(), "value" => *value, "reason" => *reason),
        ),
        PrrrpError::NotPositiveDefinite { what } => {
            Exc::NotPositiveDefinite.new_err(py, msg, &attrs!("what" => *what))
        }
        PrrrpError::NonFinite { what, row } => Exc::NonFinite.new_err(
            py,
            msg,
            &attrs!("what" => what.as_str(), "row" => *row),
        ),
        PrrrpError::ShapeMismatch {
            what,
            expected,
            got,
        } => Exc::ShapeMismatch.new_err(
            py,
            msg,
            &attrs!("what" => what.as_str(), "expected" => expected.as_str(), "got" => got.as_str()),
        ),
        PrrrpError::TooFewSamples { needed, got } => Exc::TooFewSamples.new_err(
            py,
            msg,
            &attrs!("needed" => *needed, "got" => *got),
        ),
        PrrrpError::RankDeficient {
            rank,
            params,
            cond,
            directions,
        } => Exc::RankDeficient.new_err(
            py,
            msg,
            &attrs!(
                "rank" => *rank,
                "params" => *params,
                "cond" => *cond,
                "directions" => directions.clone(),
            ),
        ),
        PrrrpError::Diverged { what, at, hint } => Exc::Diverged.new_err(
            py,
            msg,
            &attrs!("what" => *what, "at" => *at, "hint" => *hint),
        ),
        PrrrpError::SimulationDiverged {
            sample,
            time,
            joint,
            signal,
        } => Exc::Diverged.new_err(
            py,
            msg,
            &attrs!(
                "what" => "simulation",
                "at" => *sample,
                "hint" => "check the torques, gains and parameters, or increase substeps",
                "time" => *time,
                "joint" => *joint,
                "signal" => *signal,
            ),
        ),
        PrrrpError::Infeasible { what } => {
            Exc::Infeasible.new_err(py, msg, &attrs!("what" => what.as_str()))
        }
        PrrrpError::NonIncreasingTime { row } => {
            Exc::NonIncreasingTime.new_err(py, msg, &attrs!("row" => *row))
        }
        PrrrpError::RobotFile {
            file,
            element,
            message,
        } => Exc::RobotFile.new_err(
            py,
            msg,
            &attrs!(
                "file" => file.as_str(),
                "element" => element.as_str(),
                "message" => message.as_str(),
            ),
        ),
        // Raised when a Ctrl-C reached another thread's computation first: the same stop.
        PrrrpError::Interrupted { .. } => PyKeyboardInterrupt::new_err(msg),
        // A variant added to the core later still maps to the base class.
        _ => Exc::Base.new_err(py, msg, &[]),
    }
}

/// The one conversion from core results to Python results.
pub(crate) trait ToPyResult<T> {
    /// Converts the error, if any, with [`to_pyerr`].
    fn to_py(self, py: Python<'_>) -> PyResult<T>;
}

impl<T> ToPyResult<T> for Result<T, PrrrpError> {
    #[inline]
    fn to_py(self, py: Python<'_>) -> PyResult<T> {
        self.map_err(|e| to_pyerr(py, &e))
    }
}

/// A [`PrrrpError::ShapeMismatch`] raised by the bindings themselves.
pub(crate) fn shape_error(
    py: Python<'_>,
    what: &str,
    expected: impl Into<String>,
    got: impl Into<String>,
) -> PyErr {
    to_pyerr(
        py,
        &PrrrpError::ShapeMismatch {
            what: what.into(),
            expected: expected.into(),
            got: got.into(),
        },
    )
}
