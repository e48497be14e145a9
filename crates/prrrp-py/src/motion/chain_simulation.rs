//! Simulation of any chain: `prrrp.ChainTrajectory` (per-joint Fourier series, sinusoids,
//! or a sampled trajectory), `prrrp.simulate_chain` (computed-torque tracking) and
//! `prrrp.simulate_chain_open_loop` (a torque sequence), both returning a
//! `prrrp.ChainSimulation` record convertible to `prrrp.Dataset`.

use prrrp_core::{
    simulate_dyn_closed_loop, simulate_dyn_open_loop, DynSampledTrajectory, DynSensorNoise,
    DynSimulationConfig, DynSimulationRecord, DynTrajectory, FourierTrajectory, PrrrpError,
    Sinusoid,
};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::arrays::{
    any_array, first_non_finite, fmt_shape, times, to_array, vector, Out, Triple, UInt,
};
use crate::data::dataset::PyDataset;
use crate::errors::{shape_error, to_pyerr, ToPyResult};
use crate::interrupt::interruptible;
use crate::models::chain::PySerialChain;
use crate::motion::simulation::SimArgs;

/// The trajectories a Python caller can build, dispatched to the core's.
#[derive(Debug, Clone)]
enum Traj {
    Fourier(FourierTrajectory),
    Sinusoids(Vec<Sinusoid>),
    Sampled(DynSampledTrajectory),
}

impl DynTrajectory for Traj {
    fn dof(&self) -> usize {
        match self {
            Traj::Fourier(f) => f.dof(),
            Traj::Sinusoids(s) => s.dof(),
            Traj::Sampled(s) => s.dof(),
        }
    }

    #[inline]
    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        match self {
            Traj::Fourier(f) => f.eval_into(t, q, qd, qdd),
            Traj::Sinusoids(s) => s.eval_into(t, q, qd, qdd),
            Traj::Sampled(s) => s.eval_into(t, q, qd, qdd),
        }
    }

    fn end_time(&self) -> Option<f64> {
        match self {
            Traj::Fourier(f) => f.end_time(),
            Traj::Sinusoids(s) => s.end_time(),
            Traj::Sampled(s) => s.end_time(),
        }
    }
}

/// A reference trajectory of n joints; see `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "ChainTrajectory", frozen)]
pub(crate) struct PyChainTrajectory {
    inner: Traj,
}

/// A per-joint vector: a scalar broadcast to n joints, or shape (n,).
fn per_joint(obj: &Bound<'_, PyAny>, name: &'static str, n: usize) -> PyResult<Vec<f64>> {
    let (shape, data) = any_array(obj, name, &format!("() or ({n},)"))?;
    match *shape {
        [] => Ok(vec![data[0]; n]),
        [m] if m == n => Ok(data),
        _ => Err(shape_error(
            obj.py(),
            name,
            format!("() or ({n},)"),
            fmt_shape(&shape),
        )),
    }
}

/// A 2-D table (rows, cols) with `cols` fixed when given.
fn table(
    obj: &Bound<'_, PyAny>,
    name: &'static str,
    rows: Option<usize>,
    cols: Option<usize>,
) -> PyResult<(usize, usize, Vec<f64>)> {
    let want = format!(
        "({}, {})",
        rows.map_or("N".into(), |r| r.to_string()),
        cols.map_or("n".into(), |c| c.to_string())
    );
    let (shape, data) = any_array(obj, name, &want)?;
    match *shape {
        [r, c] if rows.map_or(true, |x| x == r) && cols.map_or(true, |x| x == c) => {
            Ok((r, c, data))
        }
        _ => Err(shape_error(obj.py(), name, want, fmt_shape(&shape))),
    }
}

/// A recorded trajectory from its arguments [t (N,), q, qd, qdd (N, n)].
fn sampled(args: [&Bound<'_, PyAny>; 4]) -> PyResult<DynSampledTrajectory> {
    let [t, q, qd, qdd] = args;
    let t = vector(t, "t")?;
    let (rows, n, q) = table(q, "q", Some(t.len()), None)?;
    let (_, _, qd) = table(qd, "qd", Some(rows), Some(n))?;
    let (_, _, qdd) = table(qdd, "qdd", Some(rows), Some(n))?;
    DynSampledTrajectory::new(n, t, q, qd, qdd).to_py(args[0].py())
}

pymethods_with_getters!(PyChainTrajectory {} inner {
    /// Number of joints.
    dof: usize = { dof() }
    /// Last time at which the trajectory is defined (s), or None.
    end_time: Option<f64> = { end_time() }
} {
    /// Per-joint Fourier series with base angular frequency `omega` (rad/s), offsets (n,)
    /// and sine/cosine coefficients `a`, `b` (n, H) in velocity units.
    #[staticmethod]
    fn fourier(
        py: Python<'_>,
        omega: f64,
        offsets: &Bound<'_, PyAny>,
        a: &Bound<'_, PyAny>,
        b: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let offsets = vector(offsets, "offsets")?;
        let n = offsets.len();
        let (_, h, a) = table(a, "a", Some(n), None)?;
        let (_, _, b) = table(b, "b", Some(n), Some(h))?;
        let f = FourierTrajectory::new(omega, offsets, a, b).to_py(py)?;
        Ok(Self {
            inner: Traj::Fourier(f),
        })
    }

    /// One sinusoid per joint, q_j = offset_j + amplitude_j·sin(omega_j·t + phase_j);
    /// each argument a scalar or (n,), n taken from `offset`.
    #[staticmethod]
    #[pyo3(signature = (offset, amplitude, omega, phase=None))]
    fn sinusoids(
        py: Python<'_>,
        offset: &Bound<'_, PyAny>,
        amplitude: &Bound<'_, PyAny>,
        omega: &Bound<'_, PyAny>,
        phase: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let offset = vector(offset, "offset")?;
        let n = offset.len();
        let amplitude = per_joint(amplitude, "amplitude", n)?;
        let omega = per_joint(omega, "omega", n)?;
        let phase = match phase {
            Some(p) => per_joint(p, "phase", n)?,
            None => vec![0.0; n],
        };
        let named = [
            ("offset", &offset[..]),
            ("amplitude", &amplitude[..]),
            ("omega", &omega[..]),
            ("phase", &phase[..]),
        ];
        if let Some((name, j, _)) = first_non_finite(named) {
            let what = format!("{name}[{j}]");
            return Err(to_pyerr(py, &PrrrpError::NonFinite { what, row: None }));
        }
        if n == 0 {
            return Err(shape_error(py, "offset", "(n,) with n >= 1", "(0,)"));
        }
        let s = (0..n)
            .map(|j| Sinusoid {
                offset: offset[j],
                amplitude: amplitude[j],
                omega: omega[j],
                phase: phase[j],
            })
            .collect();
        Ok(Self {
            inner: Traj::Sinusoids(s),
        })
    }

    /// A recorded trajectory: t (N,) s and q, qd, qdd (N, n), interpolated by quintics.
    #[staticmethod]
    fn sampled(
        t: &Bound<'_, PyAny>,
        q: &Bound<'_, PyAny>,
        qd: &Bound<'_, PyAny>,
        qdd: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        Ok(Self {
            inner: Traj::Sampled(sampled([t, q, qd, qdd])?),
        })
    }

    /// (q, qd, qdd) at a scalar t (each (n,)) or at t of shape (N,) (each (N, n)).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
    ) -> Triple<'py> {
        let (ts, batch) = times(t)?;
        let n = self.inner.dof();
        let (mut q, mut qd, mut qdd) = (
            vec![0.0; n * ts.len()],
            vec![0.0; n * ts.len()],
            vec![0.0; n * ts.len()],
        );
        py.detach(|| {
            for (k, &t) in ts.iter().enumerate() {
                let r = n * k..n * k + n;
                self.inner
                    .eval_into(t, &mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r]);
            }
        });
        Ok((
            to_array(py, q, batch, &[n])?,
            to_array(py, qd, batch, &[n])?,
            to_array(py, qdd, batch, &[n])?,
        ))
    }

    fn __repr__(&self) -> String {
        let kind = match &self.inner {
            Traj::Fourier(f) => format!("fourier, {} harmonics", f.harmonics()),
            Traj::Sinusoids(_) => "sinusoids".into(),
            Traj::Sampled(s) => format!("sampled, {} samples", s.len()),
        };
        format!("ChainTrajectory({kind}, dof={})", self.inner.dof())
    }
});

/// The reference of `simulate_chain`: a `ChainTrajectory`, a `Dataset`, a mapping with
/// keys t, q, qd, qdd, or a tuple (t, q, qd, qdd).
fn reference_from(obj: &Bound<'_, PyAny>) -> PyResult<Traj> {
    let py = obj.py();
    if let Ok(t) = obj.extract::<PyRef<'_, PyChainTrajectory>>() {
        return Ok(t.inner.clone());
    }
    if let Ok(d) = obj.extract::<PyRef<'_, PyDataset>>() {
        let d = &d.inner;
        let s = DynSampledTrajectory::new(
            d.dof(),
            d.t().to_vec(),
            d.q().to_vec(),
            d.qd().to_vec(),
            d.qdd().to_vec(),
        )
        .to_py(py)?;
        return Ok(Traj::Sampled(s));
    }
    if let Ok(tup) = obj.cast::<PyTuple>() {
        if tup.len() == 4 {
            let [t, q, qd, qdd] = [0, 1, 2, 3].map(|i| tup.get_item(i));
            return Ok(Traj::Sampled(sampled([&t?, &q?, &qd?, &qdd?])?));
        }
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let get = |k: &str| -> PyResult<Bound<'_, PyAny>> {
            d.get_item(k)?.ok_or_else(|| {
                to_pyerr(
                    py,
                    &PrrrpError::ShapeMismatch {
                        what: "reference".into(),
                        expected: "a mapping with keys t, q, qd, qdd".into(),
                        got: format!("no key {k:?}"),
                    },
                )
            })
        };
        let [t, q, qd, qdd] = ["t", "q", "qd", "qdd"].map(get);
        return Ok(Traj::Sampled(sampled([&t?, &q?, &qd?, &qdd?])?));
    }
    Err(PyTypeError::new_err(format!(
        "`reference` must be a prrrp.ChainTrajectory, a prrrp.Dataset, a dict with t, q, qd, \
         qdd or a tuple (t, q, qd, qdd), got {}",
        obj.get_type().name()?
    )))
}

/// Simulation settings from the Python arguments (gains and noise: scalar or (n,)).
fn config(
    n: usize,
    rate: f64,
    substeps: usize,
    a: SimArgs<'_, '_>,
    seed: u64,
) -> PyResult<DynSimulationConfig> {
    let d = DynSimulationConfig::new(n);
    let or = |o: Option<&Bound<'_, PyAny>>, name: &'static str, dflt: Vec<f64>| match o {
        Some(o) => per_joint(o, name, n),
        None => Ok(dflt),
    };
    Ok(DynSimulationConfig {
        // 1/rate: a bad rate (0, negative, NaN) becomes a bad dt that the core names.
        dt: 1.0 / rate,
        substeps,
        kp: or(a.kp, "kp", d.kp)?,
        kd: or(a.kd, "kd", d.kd)?,
        noise: DynSensorNoise {
            q_std: or(a.q_noise, "q_noise", vec![0.0; n])?,
            qd_std: a
                .qd_noise
                .map(|o| per_joint(o, "qd_noise", n))
                .transpose()?,
            tau_std: or(a.tau_noise, "tau_noise", vec![0.0; n])?,
        },
        seed,
    })
}

fn check_rate(py: Python<'_>, rate: f64) -> PyResult<()> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(to_pyerr(
            py,
            &PrrrpError::InvalidParameter {
                field: "rate".into(),
                value: rate,
                reason: "the sampling rate must be finite and > 0 Hz",
            },
        ));
    }
    Ok(())
}

/// What a chain simulation recorded; see `_prrrp.pyi`.
#[pyclass(module = "prrrp", name = "ChainSimulation", frozen)]
pub(crate) struct PyChainSimulation {
    inner: DynSimulationRecord,
}

impl PyChainSimulation {
    fn table<'py>(&self, py: Python<'py>, v: &[f64]) -> Out<'py> {
        let n = self.inner.dof();
        to_array(py, v.to_vec(), Some(v.len() / n), &[n])
    }

    fn reference<'py>(&self, py: Python<'py>, v: &[f64]) -> Out<'py> {
        if v.is_empty() {
            Ok(py.None().into_bound(py))
        } else {
            self.table(py, v)
        }
    }
}

pymethods_with_getters!(PyChainSimulation {
    table: [
        /// True positions (N, n).
        q,
        /// True velocities (N, n).
        qd,
        /// True accelerations (N, n).
        qdd,
        /// Applied torques (N, n).
        tau,
        /// Measured positions (N, n).
        q_measured,
        /// Measured torques (N, n).
        tau_measured,
    ]
    reference: [
        /// Reference positions (N, n), None for open-loop runs.
        q_ref,
        /// Reference velocities (N, n), None for open-loop runs.
        qd_ref,
        /// Reference accelerations (N, n), None for open-loop runs.
        qdd_ref,
    ]
} inner {
    /// Number of joints.
    dof: usize = { dof() }
} {
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// Time stamps (N,), s.
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Out<'py> {
        to_array(py, self.inner.t.clone(), Some(self.inner.len()), &[])
    }

    /// Measured velocities (N, n), None unless `qd_noise` was given.
    #[getter]
    fn qd_measured<'py>(&self, py: Python<'py>) -> Out<'py> {
        match &self.inner.qd_measured {
            Some(v) => self.table(py, v),
            None => Ok(py.None().into_bound(py)),
        }
    }

    /// The noise-free signals as a `Dataset`.
    fn true_dataset(&self, py: Python<'_>) -> PyResult<PyDataset> {
        let inner = self.inner.true_dataset().to_py(py)?;
        Ok(PyDataset { inner })
    }

    /// The measured signals through `prrrp.preprocess_log(t, q_measured, tau_measured,
    /// qd=qd_measured, **kwargs)`: returns (Dataset, report).
    #[pyo3(signature = (**kwargs))]
    fn measured_dataset<'py>(
        &self,
        py: Python<'py>,
        kwargs: Option<&Bound<'py, PyDict>>,
    ) -> Out<'py> {
        let kw = match kwargs {
            Some(k) => k.copy()?,
            None => PyDict::new(py),
        };
        if !kw.contains("qd")? {
            kw.set_item("qd", self.qd_measured(py)?)?;
        }
        py.import("prrrp")?.getattr("preprocess_log")?.call(
            (self.t(py)?, self.q_measured(py)?, self.tau_measured(py)?),
            Some(&kw),
        )
    }

    fn __repr__(&self) -> String {
        format!(
            "ChainSimulation(dof={}, samples={})",
            self.inner.dof(),
            self.inner.len()
        )
    }
});

/// The chain simulators: each `fn name(args; keywords) = |py, plant, settings| run`
/// becomes the `#[pyfunction]` `name(chain, args, *, rate=100.0, substeps=10, keywords,
/// q_noise=None, qd_noise=None, tau_noise=None, seed=0)` (`keywords` `name: Type`, each
/// defaulting to None) returning the `ChainSimulation` that the closure `run` records,
/// with the GIL released, of `chain` (`plant`); `settings(kp, kd)` are the simulation
/// settings at the controller gains `kp`, `kd` (None: the core's defaults).
macro_rules! chain_simulators {
    ($($(#[$doc:meta])*
       fn $name:ident($($arg:ident: $aty:ty),+; $($kw:ident: $kty:ty),*)
       = |$py:ident, $plant:ident, $settings:ident| $run:block)*) => {$(
        $(#[$doc])*
        #[pyfunction]
        #[pyo3(signature = (chain, $($arg),+, *, rate=100.0, substeps=UInt(10), $($kw=None,)*
            q_noise=None, qd_noise=None, tau_noise=None, seed=UInt(0)))]
        #[allow(clippy::too_many_arguments)]
        fn $name(
            $py: Python<'_>,
            chain: PyRef<'_, PySerialChain>,
            $($arg: $aty,)+
            rate: f64,
            substeps: UInt<usize>,
            $($kw: $kty,)*
            q_noise: Option<&Bound<'_, PyAny>>,
            qd_noise: Option<&Bound<'_, PyAny>>,
            tau_noise: Option<&Bound<'_, PyAny>>,
            seed: UInt<u64>,
        ) -> PyResult<PyChainSimulation> {
            check_rate($py, rate)?;
            let $plant = chain.chain();
            let $settings = |kp, kd| {
                let args = SimArgs::gains(kp, kd).noise(q_noise, qd_noise, tau_noise);
                config($plant.dof(), rate, substeps.0, args, seed.0)
            };
            let inner = interruptible($py, $run)?.to_py($py)?;
            Ok(PyChainSimulation { inner })
        }
    )*};
}

chain_simulators! {
    /// Simulates `chain` tracking `reference` under computed-torque control; see `_prrrp.pyi`.
    fn simulate_chain(
        reference: &Bound<'_, PyAny>,
        duration: f64;
        controller: Option<PyRef<'_, PySerialChain>>,
        kp: Option<&Bound<'_, PyAny>>,
        kd: Option<&Bound<'_, PyAny>>
    ) = |py, plant, settings| {
        let reference = reference_from(reference)?;
        let cfg = settings(kp, kd)?;
        let ctrl = controller.as_ref().map_or(plant, |c| c.chain());
        move || simulate_dyn_closed_loop(plant, ctrl, &reference, duration, &cfg)
    }

    /// Simulates `chain` from (q0, qd0) under the torques `tau` (N, n), each held for one
    /// sample; see `_prrrp.pyi`.
    fn simulate_chain_open_loop(
        q0: &Bound<'_, PyAny>,
        qd0: &Bound<'_, PyAny>,
        tau: &Bound<'_, PyAny>;
    ) = |py, plant, settings| {
        let q0 = vector(q0, "q0")?;
        let qd0 = vector(qd0, "qd0")?;
        let (_, _, tau) = table(tau, "tau", None, Some(plant.dof()))?;
        let cfg = settings(None, None)?;
        move || simulate_dyn_open_loop(plant, &q0, &qd0, &tau, &cfg)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyChainTrajectory>()?;
    m.add_class::<PyChainSimulation>()?;
    m.add_function(wrap_pyfunction!(simulate_chain, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_chain_open_loop, m)?)?;
    Ok(())
}
