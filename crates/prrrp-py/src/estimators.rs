//! The estimators: `prrrp.least_squares` (→ `LeastSquaresResult`) and the online estimators
//! `prrrp.Adaline`, `prrrp.Hopfield`, `prrrp.Ekf`, `prrrp.Rls`, each with `step(q, qd,
//! qdd, tau)`, `estimate`, `reset()` and the batch `run(...)` (plus `train(..., epochs)`
//! for Adaline and Hopfield), looping in Rust with the GIL released.

use prrrp_core::nalgebra::SVector;
use prrrp_core::{
    least_squares as core_ls, weighted_least_squares as core_wls, Adaline as CoreAdaline,
    AdalineConfig, AdalineRule, Discretisation, Ekf as CoreEkf, EkfConfig, EkfMeasurement,
    Estimator, Hopfield as CoreHopfield, HopfieldConfig, JointNoise, Lambda, LeastSquaresConfig,
    PrrrpError, PrrrpModel, Rls as CoreRls, RlsConfig, Robot, Sample, Samples as CoreSamples, Vec5,
    NDOF, NPARAM, PRRRP_EKF_STATES,
};
use std::sync::{Mutex, MutexGuard, TryLockError};

use pyo3::prelude::*;

use crate::arrays::{
    fixed_matrix, fixed_or, fixed_vector, rows_to_array, to_array, write_row_major, Samples, UInt,
};
use crate::errors::{to_pyerr, Exc, ToPyResult};
use crate::interrupt::interruptible;

type Model = PrrrpModel;

fn model() -> Model {
    Robot::paper().model()
}

fn lambda0(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Lambda> {
    fixed_or::<NPARAM>(obj, "lam0", Robot::paper().base_parameters())
}

fn vec8<'py>(py: Python<'py>, v: &Lambda) -> PyResult<Bound<'py, PyAny>> {
    to_array(py, v.as_slice().to_vec(), None, &[NPARAM])
}

fn invalid(py: Python<'_>, field: &str, reason: &'static str) -> PyErr {
    to_pyerr(
        py,
        &PrrrpError::InvalidParameter {
            field: field.into(),
            value: f64::NAN,
            reason,
        },
    )
}

/// Locks an estimator's state. A second thread using the same estimator while a call
/// runs (e.g. `step` during another thread's `run`, which releases the GIL) gets a
/// `prrrp.PrrrpError` instead of waiting or corrupting the state.
fn lock<'a, E>(py: Python<'_>, m: &'a Mutex<E>) -> PyResult<MutexGuard<'a, E>> {
    match m.try_lock() {
        Ok(g) => Ok(g),
        // A panic in an earlier call was already reported; the state is plain numbers.
        Err(TryLockError::Poisoned(p)) => Ok(p.into_inner()),
        Err(TryLockError::WouldBlock) => Err(Exc::Base.new_err(
            py,
            "estimator in use by another thread: use one estimator per thread, or wait \
             for the other call to finish"
                .into(),
            &[],
        )),
    }
}

/// Samples between two polls of the stop flag in `run`.
const CHECK_EVERY: usize = 1024;

/// The four (N, 5) columns of a batch call.
struct Columns {
    q: Vec<Vec5>,
    qd: Vec<Vec5>,
    qdd: Vec<Vec5>,
    tau: Vec<Vec5>,
}

impl Columns {
    fn extract(
        q: &Bound<'_, PyAny>,
        qd: &Bound<'_, PyAny>,
        qdd: &Bound<'_, PyAny>,
        tau: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        Ok(Self {
            q: Samples::<NDOF>::extract_rows(q, "q")?,
            qd: Samples::<NDOF>::extract_rows(qd, "qd")?,
            qdd: Samples::<NDOF>::extract_rows(qdd, "qdd")?,
            tau: Samples::<NDOF>::extract_rows(tau, "tau")?,
        })
    }

    fn samples(&self) -> Result<CoreSamples<'_, NDOF>, PrrrpError> {
        CoreSamples::new(&self.q, &self.qd, &self.qdd, &self.tau)
    }
}

/// Batch or per-sample least squares result (paper eq. 36).
#[pyclass(module = "prrrp", name = "LeastSquaresResult", frozen, get_all)]
struct LeastSquaresResult {
    /// Estimated λ, (8,).
    lam: Py<PyAny>,
    /// Standard deviations σ_λi, (8,).
    std: Py<PyAny>,
    /// Relative standard deviations 100·σ_λi/|λ_i|, (8,) %.
    rsd_percent: Py<PyAny>,
    /// cond(W).
    cond: f64,
    /// Residual variance σ² = ‖τ − Wλ‖²/(rows − 8).
    sigma2: f64,
    /// Singular values of W, (8,), descending.
    singular_values: Py<PyAny>,
    /// Residual variance of each joint's equations, (5,).
    joint_variances: Py<PyAny>,
    /// Number of samples used.
    samples: usize,
}

#[pymethods]
impl LeastSquaresResult {
    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "LeastSquaresResult(lam={}, cond={}, sigma2={}, samples={})",
            self.lam.bind(py).repr()?,
            self.cond,
            self.sigma2,
            self.samples
        ))
    }
}

/// Least-squares estimate of λ from N samples (q, qd, qdd, tau each (N, 5)), eq. 36.
/// `weighted=True` divides each joint's equations by its noise standard deviation:
/// `noise_variances` (5,) if given, else estimated from an ordinary pass.
/// Raises `RankDeficientError` (with `.directions`, `.cond`) when the data do not excite
/// every parameter and `TooFewSamplesError` for fewer than 8 samples.
#[pyfunction]
#[pyo3(signature = (q, qd, qdd, tau, *, weighted=false, noise_variances=None,
    rank_tolerance=1e-10))]
#[allow(clippy::too_many_arguments)]
fn least_squares(
    py: Python<'_>,
    q: &Bound<'_, PyAny>,
    qd: &Bound<'_, PyAny>,
    qdd: &Bound<'_, PyAny>,
    tau: &Bound<'_, PyAny>,
    weighted: bool,
    noise_variances: Option<&Bound<'_, PyAny>>,
    rank_tolerance: f64,
) -> PyResult<LeastSquaresResult> {
    let cols = Columns::extract(q, qd, qdd, tau)?;
    let noise = match noise_variances {
        Some(v) => {
            JointNoise::Variances(fixed_or::<NDOF>(Some(v), "noise_variances", Vec5::zeros())?)
        }
        None => JointNoise::Estimated,
    };
    let weighted = weighted || noise_variances.is_some();
    let config = LeastSquaresConfig { rank_tolerance };
    let model = model();
    let report = py
        .detach(|| {
            let s = cols.samples()?;
            // One sample per parameter (as `Dataset`): fewer leave the statistics
            // (σ², per-joint variances) without meaningful degrees of freedom.
            if s.len() < NPARAM {
                return Err(PrrrpError::TooFewSamples {
                    needed: NPARAM,
                    got: s.len(),
                });
            }
            if weighted {
                core_wls(&model, &s, noise, &config)
            } else {
                core_ls(&model, &s, &config)
            }
        })
        .to_py(py)?;
    Ok(LeastSquaresResult {
        lam: vec8(py, &report.lambda)?.unbind(),
        std: vec8(py, &report.std_dev)?.unbind(),
        rsd_percent: vec8(py, &report.rel_std_dev)?.unbind(),
        cond: report.cond,
        sigma2: report.sigma2,
        singular_values: vec8(py, &report.singular_values)?.unbind(),
        joint_variances: to_array(
            py,
            report.joint_variances.as_slice().to_vec(),
            None,
            &[NDOF],
        )?
        .unbind(),
        samples: report.samples,
    })
}

/// One `step` of any estimator on a single sample ((5,) arrays).
fn step_one<'py, E: Estimator<nalgebra::Const<NDOF>, nalgebra::Const<NPARAM>>>(
    py: Python<'py>,
    est: &mut E,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    qdd: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let one = |obj: &Bound<'py, PyAny>, name: &'static str| -> PyResult<Vec5> {
        fixed_or::<NDOF>(Some(obj), name, Vec5::zeros())
    };
    let (q, qd, qdd, tau) = (
        one(q, "q")?,
        one(qd, "qd")?,
        one(qdd, "qdd")?,
        one(tau, "tau")?,
    );
    let lam = *est.step(Sample::new(&q, &qd, &qdd, &tau)).to_py(py)?;
    if !lam.iter().all(|x| x.is_finite()) {
        let what = "estimate λ̂ (the sample's magnitudes overflow f64 arithmetic)".into();
        return Err(to_pyerr(py, &PrrrpError::NonFinite { what, row: None }));
    }
    vec8(py, &lam)
}

/// `run` of any estimator: steps over every sample with the GIL released. Returns λ̂ (8,),
/// or `(λ̂, history)` with history (M, 8) = λ̂ after every `history_every` samples.
#[allow(clippy::too_many_arguments)]
fn run_batch<'py, E: Estimator<nalgebra::Const<NDOF>, nalgebra::Const<NPARAM>> + Send>(
    py: Python<'py>,
    est: &mut E,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    qdd: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
    history_every: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let cols = Columns::extract(q, qd, qdd, tau)?;
    if history_every == Some(0) {
        return Err(invalid(py, "history_every", "must be >= 1 (or None)"));
    }
    let mut history: Vec<nalgebra::SVector<f64, NPARAM>> = Vec::new();
    let result = interruptible(py, || -> Result<Lambda, (usize, PrrrpError)> {
        let s = cols.samples().map_err(|e| (0, e))?;
        for (k, sample) in s.iter().enumerate() {
            if k % CHECK_EVERY == 0 && prrrp_core::stop_requested() {
                let what = "estimator run";
                return Err((k, PrrrpError::Interrupted { what }));
            }
            let lam = *est.step(sample).map_err(|e| (k, e))?;
            if !lam.iter().all(|x| x.is_finite()) {
                let what = "estimate λ̂ (the data's magnitudes overflow f64 arithmetic)".into();
                return Err((k, PrrrpError::NonFinite { what, row: None }));
            }
            if let Some(every) = history_every {
                if (k + 1) % every == 0 {
                    history.push(lam);
                }
            }
        }
        Ok(*est.estimate())
    })?;
    let lam = match result {
        Ok(l) => l,
        Err((k, e)) => {
            let e = match e {
                PrrrpError::NonFinite { what, row: None } => {
                    PrrrpError::NonFinite { what, row: Some(k) }
                }
                other => other,
            };
            let err = to_pyerr(py, &e);
            err.value(py).setattr("sample", k)?;
            err.add_note(py, format!("at sample {k} (index along the leading axis)"))?;
            return Err(err);
        }
    };
    let lam = vec8(py, &lam)?;
    match history_every {
        None => Ok(lam),
        Some(_) => {
            let h = rows_to_array(py, &history)?;
            Ok((lam, h).into_pyobject(py)?.into_any())
        }
    }
}

macro_rules! online_methods {
    ($name:ident) => {
        impl $name {
            fn do_step<'py>(
                &self,
                py: Python<'py>,
                q: &Bound<'py, PyAny>,
                qd: &Bound<'py, PyAny>,
                qdd: &Bound<'py, PyAny>,
                tau: &Bound<'py, PyAny>,
            ) -> PyResult<Bound<'py, PyAny>> {
                step_one(py, &mut *lock(py, &self.inner)?, q, qd, qdd, tau)
            }
            fn do_run<'py>(
                &self,
                py: Python<'py>,
                q: &Bound<'py, PyAny>,
                qd: &Bound<'py, PyAny>,
                qdd: &Bound<'py, PyAny>,
                tau: &Bound<'py, PyAny>,
                history_every: Option<UInt<usize>>,
            ) -> PyResult<Bound<'py, PyAny>> {
                let every = history_every.map(|u| u.0);
                run_batch(py, &mut *lock(py, &self.inner)?, q, qd, qdd, tau, every)
            }
        }
    };
}

/// Generates the methods every online estimator shares (pyo3 allows one `#[pymethods]`
/// block per class without the `multiple-pymethods` feature).
macro_rules! estimator_pymethods {
    ($name:ident { $($extra:tt)* }) => {
        #[pymethods]
        impl $name {
        $($extra)*
        /// Consumes one sample (each (5,)) and returns the updated λ̂ (8,).
        fn step<'py>(
            &self,
            py: Python<'py>,
            q: &Bound<'py, PyAny>,
            qd: &Bound<'py, PyAny>,
            qdd: &Bound<'py, PyAny>,
            tau: &Bound<'py, PyAny>,
        ) -> PyResult<Bound<'py, PyAny>> {
            self.do_step(py, q, qd, qdd, tau)
        }
        /// Steps over N samples ((N, 5) each) in Rust with the GIL released, continuing
        /// from the current state. Returns λ̂ (8,), or `(λ̂, history)` with `history`
        /// (M, 8) the estimate after every `history_every` samples.
        #[pyo3(signature = (q, qd, qdd, tau, *, history_every=None))]
        fn run<'py>(
            &self,
            py: Python<'py>,
            q: &Bound<'py, PyAny>,
            qd: &Bound<'py, PyAny>,
            qdd: &Bound<'py, PyAny>,
            tau: &Bound<'py, PyAny>,
            history_every: Option<UInt<usize>>,
        ) -> PyResult<Bound<'py, PyAny>> {
            self.do_run(py, q, qd, qdd, tau, history_every)
        }
        /// The current estimate λ̂, (8,).
        #[getter]
        fn estimate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
            let lam = *lock(py, &self.inner)?.estimate();
            vec8(py, &lam)
        }
        /// Returns to the state right after construction.
        fn reset(&self, py: Python<'_>) -> PyResult<()> {
            lock(py, &self.inner)?.reset();
            Ok(())
        }
        }
    };
}

/// Multi-epoch training of Adaline/Hopfield: returns the RMS equation error per epoch.
fn train_epochs<'py, F>(
    py: Python<'py>,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    qdd: &Bound<'py, PyAny>,
    tau: &Bound<'py, PyAny>,
    f: F,
) -> PyResult<Bound<'py, PyAny>>
where
    F: FnOnce(&CoreSamples<'_, NDOF>) -> Result<prrrp_core::TrainingReport, PrrrpError> + Send,
{
    let cols = Columns::extract(q, qd, qdd, tau)?;
    let report = interruptible(py, || {
        let s = cols.samples()?;
        f(&s)
    })?
    .to_py(py)?;
    let n = report.rms_error.len();
    to_array(py, report.rms_error, None, &[n])
}

/// Adaline network (paper §3.2) whose weights are λ; `rule` "normalised" (NLMS, step size
/// `step_size` in (0, 2)) or "delta" (eq. 11, rate `learning_rate`). `lam0` (8,) defaults
/// to Table 3.
#[pyclass(module = "prrrp", name = "Adaline", frozen)]
struct Adaline {
    inner: Mutex<CoreAdaline<Model, NDOF, NPARAM>>,
}
online_methods!(Adaline);

estimator_pymethods!(Adaline {
    #[new]
    #[pyo3(signature = (lam0=None, *, rule="normalised", learning_rate=5e-3, step_size=1.0,
        epsilon=1e-9, divergence_ratio=1e6))]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        rule: &str,
        learning_rate: f64,
        step_size: f64,
        epsilon: f64,
        divergence_ratio: f64,
    ) -> PyResult<Self> {
        let rule = match rule {
            "normalised" | "normalized" => AdalineRule::Normalised,
            "delta" => AdalineRule::Delta,
            _ => return Err(invalid(py, "rule", "must be \"normalised\" or \"delta\"")),
        };
        let config = AdalineConfig {
            rule,
            learning_rate,
            step_size,
            epsilon,
            divergence_ratio,
        };
        Ok(Self {
            inner: Mutex::new(CoreAdaline::new(model(), lambda0(lam0)?, config).to_py(py)?),
        })
    }
    /// `epochs` passes over the N samples; returns the a-priori RMS equation error of
    /// each epoch, (epochs,). At most 10**7 epochs per call (train in several calls for
    /// more); Ctrl-C stops it with KeyboardInterrupt.
    fn train<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        epochs: UInt<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mut inner = lock(py, &self.inner)?;
        let inner = &mut *inner;
        train_epochs(py, q, qd, qdd, tau, |s| inner.train(s, epochs.0))
    }
});

/// Hopfield network (paper §3.3, Abe's formulation, eq. 19): estimates in (−bound, bound),
/// slope `beta`, each sample integrated over `dt` s. `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Hopfield", frozen)]
struct Hopfield {
    inner: Mutex<CoreHopfield<Model, NDOF, NPARAM>>,
}
online_methods!(Hopfield);

estimator_pymethods!(Hopfield {
    #[new]
    #[pyo3(signature = (lam0=None, *, bound=10.0, beta=100.0, dt=0.02, stability_limit=1.0,
        max_substeps=64))]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        bound: f64,
        beta: f64,
        dt: f64,
        stability_limit: f64,
        max_substeps: u32,
    ) -> PyResult<Self> {
        let config = HopfieldConfig {
            bound,
            beta,
            dt,
            stability_limit,
            max_substeps,
        };
        Ok(Self {
            inner: Mutex::new(CoreHopfield::new(model(), lambda0(lam0)?, config).to_py(py)?),
        })
    }
    /// `epochs` passes over the N samples; returns the RMS equation error per epoch. At
    /// most 10**7 epochs per call; Ctrl-C stops it with KeyboardInterrupt.
    fn train<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        tau: &Bound<'py, PyAny>,
        epochs: UInt<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let mut inner = lock(py, &self.inner)?;
        let inner = &mut *inner;
        train_epochs(py, q, qd, qdd, tau, |s| inner.train(s, epochs.0))
    }
});

/// Recursive least squares with forgetting factor `forgetting` in (0, 1] and P₀ =
/// `initial_covariance`·I. `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Rls", frozen)]
struct Rls {
    inner: Mutex<CoreRls<Model, NDOF, NPARAM>>,
}
online_methods!(Rls);

estimator_pymethods!(Rls {
    #[new]
    #[pyo3(signature = (lam0=None, *, forgetting=1.0, initial_covariance=1e6))]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        forgetting: f64,
        initial_covariance: f64,
    ) -> PyResult<Self> {
        let config = RlsConfig {
            forgetting,
            initial_covariance,
        };
        Ok(Self {
            inner: Mutex::new(CoreRls::new(model(), lambda0(lam0)?, config).to_py(py)?),
        })
    }
});

/// Extended Kalman filter on the state [q, q̇, λ] (paper §3.4): `measurement` "positions"
/// (the paper's) or "positions_velocities"; `discretisation` "euler" (eq. 43) or
/// "second_order". `step`/`run` take (q, qd, qdd, tau) like the other estimators; q̈ is
/// ignored and q̇ used only when measured. Noise settings as the core's `EkfConfig`
/// (SI units). `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Ekf", frozen)]
struct Ekf {
    inner: Mutex<CoreEkf<Model, NDOF, NPARAM, PRRRP_EKF_STATES>>,
}
online_methods!(Ekf);

estimator_pymethods!(Ekf {
    #[new]
    #[pyo3(signature = (lam0=None, *, measurement="positions", discretisation="euler",
        dt=0.02, position_noise=1e-3, velocity_noise=1e-2, process_position_noise=1e-6,
        process_velocity_noise=1e-3, process_parameter_noise=1e-5, initial_position_std=1e-3,
        initial_velocity_std=1.0, initial_parameter_rel_std=0.5, initial_parameter_min_std=1e-3,
        init_from_first_measurement=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        measurement: &str,
        discretisation: &str,
        dt: f64,
        position_noise: f64,
        velocity_noise: f64,
        process_position_noise: f64,
        process_velocity_noise: f64,
        process_parameter_noise: f64,
        initial_position_std: f64,
        initial_velocity_std: f64,
        initial_parameter_rel_std: f64,
        initial_parameter_min_std: f64,
        init_from_first_measurement: bool,
    ) -> PyResult<Self> {
        let measurement = match measurement {
            "positions" => EkfMeasurement::Positions,
            "positions_velocities" => EkfMeasurement::PositionsVelocities,
            _ => {
                return Err(invalid(
                    py,
                    "measurement",
                    "must be \"positions\" or \"positions_velocities\"",
                ))
            }
        };
        let discretisation = match discretisation {
            "euler" => Discretisation::Euler,
            "second_order" => Discretisation::SecondOrder,
            _ => {
                return Err(invalid(
                    py,
                    "discretisation",
                    "must be \"euler\" or \"second_order\"",
                ))
            }
        };
        let config = EkfConfig {
            dt,
            discretisation,
            measurement,
            position_noise,
            velocity_noise,
            process_position_noise,
            process_velocity_noise,
            process_parameter_noise,
            initial_position_std,
            initial_velocity_std,
            initial_parameter_rel_std,
            initial_parameter_min_std,
            init_from_first_measurement,
        };
        Ok(Self {
            inner: Mutex::new(CoreEkf::new(model(), lambda0(lam0)?, config).to_py(py)?),
        })
    }
    /// Standard deviations of λ̂ from the filter covariance, (8,).
    #[getter]
    fn parameter_std<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        vec8(py, &lock(py, &self.inner)?.parameter_std())
    }
    /// Measurement updates skipped because of NaN measurements.
    #[getter]
    fn skipped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(lock(py, &self.inner)?.skipped_updates())
    }
    /// Samples whose update was damped (gain halved) to keep M(q, λ̂) positive definite.
    #[getter]
    fn damped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(lock(py, &self.inner)?.damped_updates())
    }
    /// The state x = [q (5), q̇ (5), λ (8)] predicted for the next sample, (18,).
    #[getter]
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let state = lock(py, &self.inner)?.state().as_slice().to_vec();
        to_array(py, state, None, &[PRRRP_EKF_STATES])
    }
    /// The state covariance P, (18, 18), in the squares of the state's SI units.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut buf = vec![0.0; PRRRP_EKF_STATES * PRRRP_EKF_STATES];
        write_row_major(lock(py, &self.inner)?.covariance(), &mut buf);
        to_array(py, buf, None, &[PRRRP_EKF_STATES, PRRRP_EKF_STATES])
    }
    /// Replaces the initial covariance P₀ (18, 18): symmetric positive definite, squares
    /// of the state units. Also the current P when no sample has been consumed yet.
    fn set_initial_covariance(&self, py: Python<'_>, p0: &Bound<'_, PyAny>) -> PyResult<()> {
        let p0 = fixed_matrix::<PRRRP_EKF_STATES, PRRRP_EKF_STATES>(p0, "p0")?;
        lock(py, &self.inner)?.set_initial_covariance(&p0).to_py(py)
    }
    /// Replaces the process noise Q = diag(variances), (18,), per step, squares of the
    /// state units; each ≥ 0.
    fn set_process_noise(&self, py: Python<'_>, variances: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = fixed_vector::<PRRRP_EKF_STATES>(variances, "variances")?;
        lock(py, &self.inner)?
            .set_process_noise(&SVector::from_column_slice(&v))
            .to_py(py)
    }
    /// Replaces the measurement noise R = diag(positions (5,), velocities (5,)), variances
    /// in m², rad², (m/s)², (rad/s)²; each > 0.
    fn set_measurement_noise(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        velocities: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let p = fixed_vector::<NDOF>(positions, "positions")?;
        let v = fixed_vector::<NDOF>(velocities, "velocities")?;
        lock(py, &self.inner)?
            .set_measurement_noise(
                &SVector::from_column_slice(&p),
                &SVector::from_column_slice(&v),
            )
            .to_py(py)
    }
});

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(least_squares, m)?)?;
    m.add_class::<LeastSquaresResult>()?;
    m.add_class::<Adaline>()?;
    m.add_class::<Hopfield>()?;
    m.add_class::<Rls>()?;
    m.add_class::<Ekf>()?;
    Ok(())
}
