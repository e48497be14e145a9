//! The simulators: `prrrp.simulate_closed_loop` (computed-torque tracking of a reference)
//! and `prrrp.simulate_open_loop` (a torque sequence). Results are dicts of arrays.

use prrrp_core::{
    simulate_closed_loop as core_closed, simulate_open_loop as core_open, Lambda, Robot,
    SensorNoise, SimulationConfig, SimulationRecord, Vec5, NDOF, NPARAM,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{fixed_or, rows_to_array, to_array, Samples, UInt};
use crate::errors::ToPyResult;
use crate::interrupt::interruptible;
use crate::motion::trajectories::{Excitation, SinusoidReference};

pub(crate) fn record_dict<'py>(
    py: Python<'py>,
    r: &SimulationRecord,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("t", to_array(py, r.t.clone(), Some(r.t.len()), &[])?)?;
    for (k, v) in [
        ("q_ref", &r.q_ref),
        ("qd_ref", &r.qd_ref),
        ("qdd_ref", &r.qdd_ref),
        ("q", &r.q),
        ("qd", &r.qd),
        ("qdd", &r.qdd),
        ("tau", &r.tau),
        ("q_measured", &r.q_measured),
        ("tau_measured", &r.tau_measured),
    ] {
        // The open-loop simulator has no reference.
        if v.len() == r.t.len() {
            d.set_item(k, rows_to_array(py, v)?)?;
        }
    }
    Ok(d)
}

/// λ (8,) or the paper's Table 3 values.
fn lambda_or(obj: Option<&Bound<'_, PyAny>>, name: &'static str) -> PyResult<Lambda> {
    fixed_or::<NPARAM>(obj, name, Robot::paper().base_parameters())
}

type Opt<'a, 'py> = Option<&'a Bound<'py, PyAny>>;

/// The controller-gain and sensor-noise arguments of a simulation call, None where not
/// given: read here for the paper's arm and in `chain_simulation` for any chain.
#[derive(Clone, Copy, Default)]
pub(crate) struct SimArgs<'a, 'py> {
    pub(crate) kp: Opt<'a, 'py>,
    pub(crate) kd: Opt<'a, 'py>,
    pub(crate) q_noise: Opt<'a, 'py>,
    /// Chains only: the paper's simulator measures no velocities.
    pub(crate) qd_noise: Opt<'a, 'py>,
    pub(crate) tau_noise: Opt<'a, 'py>,
}

impl<'a, 'py> SimArgs<'a, 'py> {
    /// The controller gains `kp`, `kd`, no sensor noise given.
    pub(crate) fn gains(kp: Opt<'a, 'py>, kd: Opt<'a, 'py>) -> Self {
        Self {
            kp,
            kd,
            ..Self::default()
        }
    }

    /// With the sensor-noise arguments `q_noise`, `qd_noise`, `tau_noise`.
    pub(crate) fn noise(self, q: Opt<'a, 'py>, qd: Opt<'a, 'py>, tau: Opt<'a, 'py>) -> Self {
        Self {
            q_noise: q,
            qd_noise: qd,
            tau_noise: tau,
            ..self
        }
    }
}

/// The paper arm's simulation settings: gains and noise (5,) each, the core's default
/// gains and the sensor noise `noise` where not given.
pub(crate) fn config(
    dt: f64,
    substeps: usize,
    a: SimArgs<'_, '_>,
    noise: SensorNoise,
    seed: u64,
) -> PyResult<SimulationConfig> {
    let d = SimulationConfig::default();
    Ok(SimulationConfig {
        dt,
        substeps,
        kp: fixed_or(a.kp, "kp", d.kp)?,
        kd: fixed_or(a.kd, "kd", d.kd)?,
        noise: SensorNoise {
            q_std: fixed_or(a.q_noise, "q_noise", noise.q_std)?,
            tau_std: fixed_or(a.tau_noise, "tau_noise", noise.tau_std)?,
        },
        seed,
    })
}

/// The paper arm's simulators: each `fn name(args; keywords; gains) = |py, model, lam,
/// settings| record` becomes the `#[pyfunction]` `name(args, *, lam=None, keywords,
/// dt=0.02, substeps=20, gains, q_noise=None, tau_noise=None, seed=0)` (`keywords`
/// `name: Type` and the gains, optional (5,) arrays, default to None) returning the dict
/// of the simulation `record` (`record_dict`) of the arm `model` with parameters `lam`
/// (default Table 3); `settings(kp, kd, noise)` are the simulation settings at the
/// controller gains `kp`, `kd` (None: the core's defaults), with the sensor noise `noise`
/// where not given.
macro_rules! paper_simulators {
    ($($(#[$doc:meta])*
       fn $name:ident($($arg:ident: $aty:ty),+; $($kw:ident: $kty:ty),*;
                      $($gain:ident),*)
       = |$py:ident, $model:ident, $lam:ident, $settings:ident| $record:block)*) => {$(
        $(#[$doc])*
        #[pyfunction]
        #[pyo3(signature = ($($arg),+, *, lam=None, $($kw=None,)* dt=0.02, substeps=UInt(20),
            $($gain=None,)* q_noise=None, tau_noise=None, seed=UInt(0)))]
        #[allow(clippy::too_many_arguments)]
        fn $name<'py>(
            $py: Python<'py>,
            $($arg: $aty,)+
            lam: Option<&Bound<'py, PyAny>>,
            $($kw: $kty,)*
            dt: f64,
            substeps: UInt<usize>,
            $($gain: Option<&Bound<'py, PyAny>>,)*
            q_noise: Option<&Bound<'py, PyAny>>,
            tau_noise: Option<&Bound<'py, PyAny>>,
            seed: UInt<u64>,
        ) -> PyResult<Bound<'py, PyDict>> {
            let $lam = lambda_or(lam, "lam")?;
            let $settings = |kp, kd, noise| {
                let args = SimArgs::gains(kp, kd).noise(q_noise, None, tau_noise);
                config(dt, substeps.0, args, noise, seed.0)
            };
            let $model = Robot::paper().model();
            record_dict($py, &$record.to_py($py)?)
        }
    )*};
}

paper_simulators! {
    /// Simulates the paper robot with parameters `lam` (default Table 3) tracking `reference`
    /// (an `Excitation` or a `SinusoidReference`) under computed-torque control with the
    /// controller's parameters `controller_lam` (default `lam`), gains `kp`, `kd` (5,) (default
    /// 400, 40), from t = 0 to `duration` s, sampled every `dt` s (RK4 with `substeps` steps
    /// per sample). Sensor noise standard deviations `q_noise`, `tau_noise` (5,) (m, rad; N,
    /// N·m; default the core's `SensorNoise`, zeros for none), seeded by `seed`.
    ///
    /// Returns a dict of arrays: `t` (N,), `q_ref`, `qd_ref`, `qdd_ref`, `q`, `qd`, `qdd`,
    /// `tau`, `q_measured`, `tau_measured` (N, 5).
    fn simulate_closed_loop(
        reference: &Bound<'py, PyAny>,
        duration: f64;
        controller_lam: Option<&Bound<'py, PyAny>>;
        kp, kd
    ) = |py, model, lam, settings| {
        let ctrl = fixed_or::<NPARAM>(controller_lam, "controller_lam", lam)?;
        let cfg = settings(kp, kd, SensorNoise::default())?;
        if let Ok(e) = reference.extract::<PyRef<'_, Excitation>>() {
            if let Some(r) = e.reflected_trajectory() {
                let traj = r.to_py(py)?;
                interruptible(py, || {
                    core_closed(&model, &lam, &ctrl, &traj, duration, &cfg)
                })?
            } else {
                let traj = e.inner.trajectory;
                interruptible(py, || {
                    core_closed(&model, &lam, &ctrl, &traj, duration, &cfg)
                })?
            }
        } else if let Ok(s) = reference.extract::<PyRef<'_, SinusoidReference>>() {
            let traj = s.inner;
            interruptible(py, || {
                core_closed(&model, &lam, &ctrl, &traj, duration, &cfg)
            })?
        } else {
            return Err(PyTypeError::new_err(format!(
                "`reference` must be a prrrp.Excitation or prrrp.SinusoidReference, got {}",
                reference.get_type().name()?
            )));
        }
    }

    /// Simulates the paper robot with parameters `lam` (default Table 3) from (q0, qd0) (5,)
    /// under the torques `tau` (N, 5), each held over one period `dt` s (zero-order hold).
    /// Returns a dict of arrays `t`, `q`, `qd`, `qdd`, `tau`, `q_measured`, `tau_measured`
    /// (noise-free unless `q_noise`/`tau_noise` are given).
    fn simulate_open_loop(
        q0: &Bound<'py, PyAny>,
        qd0: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>;
        ;
    ) = |py, model, lam, settings| {
        let q0: Vec5 = fixed_or(Some(q0), "q0", Vec5::zeros())?;
        let qd0: Vec5 = fixed_or(Some(qd0), "qd0", Vec5::zeros())?;
        let tau = Samples::<NDOF>::extract_rows(tau, "tau")?;
        let cfg = settings(None, None, SensorNoise::none())?;
        interruptible(py, || core_open(&model, &lam, &q0, &qd0, &tau, &cfg))?
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate_closed_loop, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_open_loop, m)?)?;
    crate::motion::chain_simulation::register(m)?;
    Ok(())
}
