//! `prrrp.Robot`: the physical robot (paper Table 2) and its dynamics at its own λ or at a
//! user-supplied λ (keyword `lam`), for one sample or a batch.

use numpy::PyArray1;
use prrrp_core::nalgebra::SMatrix;
use prrrp_core::{JointKind, Robot, NPARAM, STANDARD_GRAVITY};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

use crate::arrays::{batch_len, fixed_vector, map_samples, write_row_major, Out, Samples};
use crate::errors::ToPyResult;
use crate::models::derivatives::{
    forward_derivatives, inverse_derivatives, PyForwardDerivatives, PyInverseDerivatives,
};

/// The PRRRP arm: link parameters in SI units and its dynamic model.
///
/// Every dynamics method takes q, q̇, q̈, τ as arrays of shape (5,) for one sample or
/// (N, 5) for N samples (single samples broadcast against a batch), and the base
/// parameters λ as the keyword `lam` of shape (8,) or (N, 8), by default this robot's own
/// `base_parameters()`. Batches are computed in Rust with the GIL released.
#[pyclass(module = "prrrp", name = "Robot", frozen, eq)]
#[derive(Clone, PartialEq)]
pub(crate) struct PyRobot {
    pub(crate) inner: Robot,
}

impl PyRobot {
    /// A parameter array (`array` getters).
    fn array<'py>(&self, py: Python<'py>, values: &[f64]) -> Out<'py> {
        Ok(PyArray1::from_slice(py, values).into_any())
    }

    fn lam(&self, lam: Option<&Bound<'_, PyAny>>) -> PyResult<Samples<NPARAM>> {
        Samples::extract_or(lam, "lam", self.inner.base_parameters())
    }
}

/// A per-sample result written into its output row: a matrix or vector (row-major) or a
/// scalar.
trait Put {
    fn put(&self, out: &mut [f64]);
}

impl<const R: usize, const C: usize> Put for SMatrix<f64, R, C> {
    fn put(&self, out: &mut [f64]) {
        write_row_major(self, out);
    }
}

impl Put for f64 {
    fn put(&self, out: &mut [f64]) {
        out[0] = *self;
    }
}

/// The `#[pymethods]` of `Robot`: its paper Table 2 `fields` (each the (k,) array
/// `Robot.field`: its getter, the keyword of the constructor that defaults to the paper's
/// value, and its entry in the pickle arguments and the repr, beside `gravity`), its other
/// getters (as `pymethods_with_getters!` takes them after its read list), its own items,
/// the methods `at_lam { fn name(args) -> Type; }` returning what the function `name`
/// computes from `[args]` at the keyword `lam`, then one method per dynamics quantity
/// `fn name(args) -> [shape] = value;`, taking (5,) or (N, 5) arguments and the keyword
/// `lam`, with `value` computed at sample `k` by `model` with the GIL released.
macro_rules! robot_pymethods {
    (fields [$($(#[$gdoc:meta])* $field:ident,)+]
     getters ($($getters:tt)*)
     |$model:ident, $k:ident, $lam:ident| { $($extra:tt)* }
     at_lam { $($(#[$fdoc:meta])* fn $fname:ident($($farg:ident),+) -> $fty:ty;)* }
     $($(#[$doc:meta])* fn $name:ident($($arg:ident),+) -> [$($dim:expr),*] = $value:expr;)*) => {
        pymethods_with_getters!(PyRobot { array: [$($(#[$gdoc])* $field,)+] } $($getters)* {
            /// A robot from the paper's Table 2 quantities (keyword-only, SI units). Omitted
            /// arguments take the paper's values.
            #[new]
            #[pyo3(signature = (*, $($field=None,)+ gravity=STANDARD_GRAVITY))]
            fn new(
                py: Python<'_>,
                $($field: Option<&Bound<'_, PyAny>>,)+
                gravity: f64,
            ) -> PyResult<Self> {
                let paper = Robot::paper();
                $(let $field =
                    $field.map_or(Ok(paper.$field), |o| fixed_vector(o, stringify!($field)))?;)+
                let inner = Robot::new($($field,)+ gravity).to_py(py)?;
                Ok(Self { inner })
            }

            fn __repr__(&self) -> String {
                let r = &self.inner;
                let fields = [$(format!(concat!(stringify!($field), "={:?}"), r.$field)),+];
                format!("Robot({}, gravity={:?})", fields.join(", "), r.gravity)
            }

            /// Pickle and copy support: the keyword arguments that rebuild this robot.
            fn __getnewargs_ex__<'py>(
                &self,
                py: Python<'py>,
            ) -> PyResult<(Bound<'py, PyTuple>, Bound<'py, PyDict>)> {
                let kw = PyDict::new(py);
                $(kw.set_item(stringify!($field), self.inner.$field.to_vec())?;)+
                kw.set_item("gravity", self.inner.gravity)?;
                Ok((PyTuple::empty(py), kw))
            }

            $($extra)*
            $(
            $(#[$fdoc])*
            #[pyo3(signature = ($($farg),+, *, lam=None))]
            fn $fname(
                &self,
                py: Python<'_>,
                $($farg: &Bound<'_, PyAny>,)+
                lam: Option<&Bound<'_, PyAny>>,
            ) -> PyResult<$fty> {
                $fname(py, self.inner.model(), [$($farg),+], self.lam(lam)?)
            }
            )*
            $(
            $(#[$doc])*
            #[pyo3(signature = ($($arg),+, *, lam=None))]
            fn $name<'py>(
                &self,
                py: Python<'py>,
                $($arg: &Bound<'py, PyAny>,)+
                lam: Option<&Bound<'py, PyAny>>,
            ) -> Out<'py> {
                $(let $arg = Samples::<5>::extract($arg, stringify!($arg))?;)+
                let $lam = self.lam(lam)?;
                let n = batch_len(py, &[$(&$arg,)+ &$lam])?;
                let $model = self.inner.model();
                let [out] = map_samples(py, n, [&[$($dim),*]], |$k, [row]| {
                    $value.put(row);
                    Ok(())
                })?;
                Ok(out)
            }
            )*
        });
    };
}

robot_pymethods! {
fields [
    /// Link masses m1..m5, kg, shape (5,).
    mass,
    /// Link lengths l1..l5, m, shape (5,).
    length,
    /// Centre-of-mass distances lc2..lc4 from joints 2–4, m, shape (3,).
    com,
    /// Moments of inertia I2zz..I4zz about the centres of mass, kg·m², shape (3,).
    inertia_zz,
]
getters (inner {
    /// Gravitational acceleration g, m/s², acting along world −z.
    g: f64 = { gravity }
} arrays(this, py) {
    /// Regressor Φ(q, q̇, q̈) at this robot's gravity, shape (5, 8) or (N, 5, 8); τ = Φ·λ.
    fn regressor(q, qd, qdd) {
        crate::models::regressor::regressor_at(py, this.inner.model(), [q, qd, qdd])
    }
})
|model, k, lam| {
    /// The robot of Urrea & Pascal 2017, Table 2, with g = 9.81 m/s².
    #[staticmethod]
    fn paper() -> Self {
        Self {
            inner: Robot::paper(),
        }
    }

    /// The 8 grouped base parameters λ (paper Table 3, corrected), shape (8,).
    fn base_parameters<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.inner.base_parameters().as_slice())
    }

    /// Standard DH table at q = 0 (paper Table 1): a list of five dicts with keys
    /// kind ("prismatic"/"revolute"), theta (rad), d (m), a (m), alpha (rad).
    fn dh_table<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let rows = self.inner.dh_table();
        let list = PyList::empty(py);
        for r in rows {
            let d = PyDict::new(py);
            let kind = match r.kind {
                JointKind::Prismatic => "prismatic",
                JointKind::Revolute => "revolute",
            };
            d.set_item("kind", kind)?;
            d.set_item("theta", r.theta)?;
            d.set_item("d", r.d)?;
            d.set_item("a", r.a)?;
            d.set_item("alpha", r.alpha)?;
            list.append(d)?;
        }
        Ok(list)
    }
}
at_lam {
    /// ∂τ/∂q and ∂τ/∂q̇ of the inverse dynamics at fixed q̈ and λ (analytic), each of shape
    /// (5, 5) or (N, 5, 5).
    fn inverse_derivatives(q, qd, qdd) -> PyInverseDerivatives;

    /// Forward dynamics and its derivatives at fixed τ: qdd (5,), dqdd_dq (5, 5),
    /// dqdd_dqd (5, 5), dqdd_dlambda (5, 8), each with a leading N for a batch.
    fn forward_derivatives(q, qd, tau) -> PyForwardDerivatives;
}

    /// Mass matrix M(q, λ), shape (5, 5) or (N, 5, 5).
    fn mass_matrix(q) -> [5, 5] = model.mass_matrix(q.at(k), lam.at(k));

    /// Coriolis and centrifugal vector C(q, q̇, λ)·q̇ (N, N·m), shape (5,) or (N, 5).
    fn coriolis(q, qd) -> [5] = model.coriolis(q.at(k), qd.at(k), lam.at(k));

    /// Gravity vector G(λ) (N, N·m), shape (5,) or (N, 5). It does not depend on q for
    /// this arm; q sets the output shape.
    fn gravity(q) -> [5] = model.gravity_vector(lam.at(k));

    /// Nonlinear effects C(q, q̇, λ)·q̇ + G(λ) (N, N·m), shape (5,) or (N, 5).
    fn nonlinear_effects(q, qd) -> [5] = model.nonlinear_effects(q.at(k), qd.at(k), lam.at(k));

    /// Inverse dynamics τ = M·q̈ + C·q̇ + G (N, N·m), shape (5,) or (N, 5).
    fn inverse_dynamics(q, qd, qdd) -> [5] =
        model.inverse_dynamics(q.at(k), qd.at(k), qdd.at(k), lam.at(k));

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G) (m/s², rad/s²), shape (5,) or (N, 5).
    /// Raises NotPositiveDefiniteError if M(q, λ) is not positive definite (non-physical λ).
    fn forward_dynamics(q, qd, tau) -> [5] =
        model.forward_dynamics(q.at(k), qd.at(k), tau.at(k), lam.at(k))?;

    /// Kinetic energy ½·q̇ᵀ·M(q, λ)·q̇ (J): a float, or shape (N,).
    fn kinetic_energy(q, qd) -> [] = model.kinetic_energy(q.at(k), qd.at(k), lam.at(k));

    /// Potential energy g·(λ1·d1 + λ8·(d1 − d5)) (J), zero at d1 = d5 = 0: a float, or
    /// shape (N,).
    fn potential_energy(q) -> [] = model.potential_energy(q.at(k), lam.at(k));
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRobot>()
}
