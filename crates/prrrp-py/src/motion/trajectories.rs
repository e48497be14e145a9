//! Reference trajectories: the optimised excitation (`prrrp.optimise_excitation` →
//! `prrrp.Excitation`), one sinusoid per joint (`prrrp.SinusoidReference`) and the joint
//! limits (`prrrp.joint_limits`).

use nalgebra::SVector;
use prrrp_core::{
    optimise_excitation as core_optimise, ExcitationConfig, ExcitationResult, ExcitationTrajectory,
    JointLimits, JointTrajectory, PrrrpError, Reflected, Robot, Sinusoid, Vec5,
    DEFAULT_EXCITATION_KNOTS, NDOF,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{
    first_non_finite, fixed_or, fixed_vector, rows_to_array, times, to_array, Triple, UInt,
};
use crate::errors::{to_pyerr, ToPyResult};
use crate::interrupt::{with_progress, Callback};

type Result = ExcitationResult<DEFAULT_EXCITATION_KNOTS>;

/// The joint limits as a dict of (5,) arrays `q_min`, `q_max` (m, rad), `qd_max` (m/s,
/// rad/s), `qdd_max` (m/s², rad/s²).
fn limits_dict<'py>(py: Python<'py>, l: &JointLimits) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in [
        ("q_min", l.q_min),
        ("q_max", l.q_max),
        ("qd_max", l.qd_max),
        ("qdd_max", l.qdd_max),
    ] {
        d.set_item(k, to_array(py, v.as_slice().to_vec(), None, &[NDOF])?)?;
    }
    Ok(d)
}

/// Reads a limits dict (missing keys → the defaults).
fn limits_from(obj: Option<&Bound<'_, PyAny>>) -> PyResult<JointLimits> {
    let mut l = JointLimits::default();
    let Some(obj) = obj else { return Ok(l) };
    let get = |key: &str| obj.get_item(key).ok();
    l.q_min = fixed_or(get("q_min").as_ref(), "limits['q_min']", l.q_min)?;
    l.q_max = fixed_or(get("q_max").as_ref(), "limits['q_max']", l.q_max)?;
    l.qd_max = fixed_or(get("qd_max").as_ref(), "limits['qd_max']", l.qd_max)?;
    l.qdd_max = fixed_or(get("qdd_max").as_ref(), "limits['qdd_max']", l.qdd_max)?;
    l.validate().to_py(obj.py())?;
    Ok(l)
}

/// The default joint limits of the excitation search (dict of (5,) arrays).
#[pyfunction]
fn joint_limits(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    limits_dict(py, &JointLimits::default())
}

/// Evaluates a trajectory at a scalar t → three (5,) arrays, or at t of shape (N,) → three
/// (N, 5) arrays.
pub(crate) fn eval_at<'py, T: JointTrajectory + Sync>(
    py: Python<'py>,
    traj: &T,
    t: &Bound<'py, PyAny>,
) -> Triple<'py> {
    let (ts, batch) = times(t)?;
    let batch = batch.is_some();
    let (mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new());
    py.detach(|| {
        for &tk in &ts {
            let p = traj.eval(tk);
            q.push(p.q);
            qd.push(p.qd);
            qdd.push(p.qdd);
        }
    });
    if batch {
        Ok((
            rows_to_array(py, &q)?,
            rows_to_array(py, &qd)?,
            rows_to_array(py, &qdd)?,
        ))
    } else {
        let one = |v: &[Vec5]| to_array(py, v[0].as_slice().to_vec(), None, &[NDOF]);
        Ok((one(&q)?, one(&qd)?, one(&qdd)?))
    }
}

/// An optimised excitation trajectory (paper §4.1) and the figures of its search. Call
/// `eval(t)` (alias `sample(t)`) for (q, qd, qdd) at a scalar t (s) or t of shape (N,).
#[pyclass(module = "prrrp", name = "Excitation", frozen)]
pub(crate) struct Excitation {
    pub(crate) inner: Result,
    duration: f64,
    dt: f64,
    /// Played forward and backward in turn beyond `duration` (see `reflected`).
    pub(crate) reflected: bool,
}

impl Excitation {
    /// The trajectory as simulations and `eval` see it: reflected or not.
    pub(crate) fn reflected_trajectory(
        &self,
    ) -> Option<prrrp_core::Result<Reflected<ExcitationTrajectory<DEFAULT_EXCITATION_KNOTS>>>> {
        self.reflected
            .then(|| Reflected::new(self.inner.trajectory))
    }
}

pymethods_with_getters!(Excitation {} inner {
    /// cond(W) of the initial guess.
    cond_initial: f64 = { cond_initial }
    /// cond(W) of the optimised trajectory.
    cond_final: f64 = { cond_final }
    /// Cost evaluations spent.
    evaluations: usize = { evaluations }
    /// Whether every limit holds on the verification grid.
    limits_satisfied: bool = { limits_satisfied }
    /// Number of samples in W (duration/dt + 1).
    samples: usize = { samples }
} {
    /// Horizon, s.
    #[getter]
    fn duration(&self) -> f64 {
        self.duration
    }
    /// Sampling period of W, s.
    #[getter]
    fn dt(&self) -> f64 {
        self.dt
    }
    /// Fraction of each limit used: dict of (5,) arrays `q`, `qd`, `qdd`.
    #[getter]
    fn limit_usage<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let u = &self.inner.limit_usage;
        let d = PyDict::new(py);
        for (k, v) in [("q", u.q), ("qd", u.qd), ("qdd", u.qdd)] {
            d.set_item(k, to_array(py, v.as_slice().to_vec(), None, &[NDOF])?)?;
        }
        Ok(d)
    }
    /// (q, qd, qdd) at time t (s): (5,) arrays for a scalar t, (N, 5) for t of shape (N,).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
    ) -> Triple<'py> {
        match self.reflected_trajectory() {
            Some(r) => eval_at(py, &r.to_py(py)?, t),
            None => eval_at(py, &self.inner.trajectory, t),
        }
    }
    /// Same as `eval`.
    fn sample<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
    ) -> Triple<'py> {
        self.eval(py, t)
    }
    /// The same excitation played forward and backward in turn, defined for every t ≥ 0
    /// (period 2·duration): a recording longer than one excitation sees it again, C² at
    /// every turn since it starts and ends at rest, within the same limits. `duration`
    /// stays that of one pass.
    fn reflected(&self, py: Python<'_>) -> PyResult<Self> {
        Reflected::new(self.inner.trajectory).to_py(py)?;
        Ok(Self {
            inner: self.inner,
            duration: self.duration,
            dt: self.dt,
            reflected: true,
        })
    }
    /// Whether this is the forward-and-backward form of `reflected()`.
    #[getter]
    fn is_reflected(&self) -> bool {
        self.reflected
    }
    fn __repr__(&self) -> String {
        format!(
            "<prrrp.Excitation duration={} s{}, dt={} s, cond {:.4} -> {:.4}, {} evaluations>",
            self.duration,
            if self.reflected { " (reflected)" } else { "" },
            self.dt,
            self.inner.cond_initial,
            self.inner.cond_final,
            self.inner.evaluations
        )
    }
});

/// Optimises the excitation trajectory (paper §4.1): minimises cond(W) of the sampled
/// observation matrix within the joint limits. `duration` and `dt` in s; `limits` a dict
/// like `joint_limits()` (missing keys → defaults); `progress(evaluations,
/// max_evaluations, best_cond)` is called every `progress_every` evaluations and at the
/// end. An exception raised by `progress` stops further calls and is re-raised when the
/// search returns.
#[pyfunction]
#[pyo3(signature = (*, seed=UInt(0), duration=10.0, dt=0.02, max_evaluations=UInt(6000), restarts=UInt(6),
    margin=0.01, limits=None, progress=None, progress_every=UInt(100)))]
#[allow(clippy::too_many_arguments)]
fn optimise_excitation(
    py: Python<'_>,
    seed: UInt<u64>,
    duration: f64,
    dt: f64,
    max_evaluations: UInt<usize>,
    restarts: UInt<usize>,
    margin: f64,
    limits: Option<&Bound<'_, PyAny>>,
    progress: Option<Py<PyAny>>,
    progress_every: UInt<usize>,
) -> PyResult<Excitation> {
    let seed = seed.0;
    let max_evaluations = max_evaluations.0;
    let restarts = restarts.0;
    let progress_every = progress_every.0;
    let config = ExcitationConfig {
        duration,
        dt,
        limits: limits_from(limits)?,
        max_evaluations,
        restarts,
        margin,
        seed,
        progress_every: progress_every.max(1),
        ..ExcitationConfig::default()
    };
    let model = Robot::paper().model();
    let callback = progress.as_ref().map(Callback::CountsValue);
    let result = with_progress(py, callback, |report| {
        core_optimise::<DEFAULT_EXCITATION_KNOTS>(&model, &config, |p| {
            report.report_value("excitation", p.evaluations, p.max_evaluations, p.best_cond)
        })
    })?;
    Ok(Excitation {
        inner: result.to_py(py)?,
        duration,
        dt,
        reflected: false,
    })
}

/// One sinusoid per joint: q_i(t) = offset_i + amplitude_i·sin(omega_i·t + phase_i), each a
/// (5,) array (m or rad, rad/s, rad). A reference for `simulate_closed_loop`.
#[pyclass(module = "prrrp", name = "SinusoidReference", frozen)]
pub(crate) struct SinusoidReference {
    pub(crate) inner: [Sinusoid; NDOF],
}

#[pymethods]
impl SinusoidReference {
    #[new]
    #[pyo3(signature = (*, offset, amplitude, omega, phase=None))]
    fn new(
        offset: &Bound<'_, PyAny>,
        amplitude: &Bound<'_, PyAny>,
        omega: &Bound<'_, PyAny>,
        phase: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let o = fixed_vector::<NDOF>(offset, "offset")?;
        let a = fixed_vector::<NDOF>(amplitude, "amplitude")?;
        let w = fixed_vector::<NDOF>(omega, "omega")?;
        let p: [f64; NDOF] = fixed_or(phase, "phase", SVector::<f64, NDOF>::zeros())?.into();
        let py = offset.py();
        let named = [
            ("offset", &o),
            ("amplitude", &a),
            ("omega", &w),
            ("phase", &p),
        ];
        if let Some((name, j, value)) = first_non_finite(named.map(|(n, v)| (n, &v[..]))) {
            let field = format!("{name}[{j}]");
            let reason = "must be finite";
            let e = PrrrpError::InvalidParameter {
                field,
                value,
                reason,
            };
            return Err(to_pyerr(py, &e));
        }
        Ok(Self {
            inner: std::array::from_fn(|j| Sinusoid {
                offset: o[j],
                amplitude: a[j],
                omega: w[j],
                phase: p[j],
            }),
        })
    }
    /// (q, qd, qdd) at time t (s): (5,) arrays for a scalar t, (N, 5) for t of shape (N,).
    fn eval<'py>(&self, py: Python<'py>, t: &Bound<'py, PyAny>) -> Triple<'py> {
        eval_at(py, &self.inner, t)
    }
    /// Same as `eval`.
    fn sample<'py>(&self, py: Python<'py>, t: &Bound<'py, PyAny>) -> Triple<'py> {
        self.eval(py, t)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Excitation>()?;
    m.add_class::<SinusoidReference>()?;
    m.add_function(wrap_pyfunction!(optimise_excitation, m)?)?;
    m.add_function(wrap_pyfunction!(joint_limits, m)?)?;
    Ok(())
}
