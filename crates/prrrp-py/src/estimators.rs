//! The estimators: `prrrp.least_squares` (→ `LeastSquaresResult`) and the online estimators
//! `prrrp.Adaline`, `prrrp.Hopfield`, `prrrp.Ekf`, `prrrp.Rls`, each with `step(q, qd,
//! qdd, tau)`, `estimate`, `reset()` and the batch `run(...)` (plus `train(..., epochs)`
//! for Adaline and Hopfield), looping in Rust with the GIL released.

use prrrp_core::nalgebra::{DMatrix, DVector, SVector};
use prrrp_core::{
    least_squares as core_ls, weighted_least_squares as core_wls, Adaline as CoreAdaline,
    AdalineConfig, AdalineRule, Discretisation, Ekf as CoreEkf, EkfConfig, EkfMeasurement,
    Estimator, Hopfield as CoreHopfield, HopfieldConfig, JointNoise, Lambda, LeastSquaresConfig,
    PrrrpError, PrrrpModel, Rls as CoreRls, RlsConfig, Robot, Sample, Samples as CoreSamples, Vec5,
    NDOF, NPARAM, PRRRP_EKF_STATES,
};
use prrrp_core::{
    DynAdaline, DynChainBaseModel, DynEkf, DynHopfield, DynRls, DynSample,
    DynSamples as CoreDynSamples, DynScaledModel,
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

/// The run-time chain model the chain estimators train on: the base-parameter model with
/// columns scaled by `scale` (β = scale·γ; ones unless the user gives a scale).
type Scaled = DynScaledModel<DynChainBaseModel>;

/// An online estimator of the paper's arm (compile-time sizes, the closed-form model) or
/// of any `SerialChain` (run-time sizes, its base-parameter model).
enum Inner<F, D> {
    Paper(F),
    Chain(ChainEst<D>),
}

/// A chain estimator with its sizes and the column scale its estimate is mapped back by.
struct ChainEst<D> {
    est: D,
    scale: DVector<f64>,
    n: usize,
}

impl<D: Estimator<nalgebra::Dyn, nalgebra::Dyn>> ChainEst<D> {
    fn beta(&self) -> Vec<f64> {
        self.est
            .estimate()
            .iter()
            .zip(self.scale.iter())
            .map(|(g, s)| g * s)
            .collect()
    }
}

/// What a chain constructor needs: the base model, β₀ (or None) and the scale.
struct ChainSetup {
    model: DynChainBaseModel,
    beta0: Option<Vec<f64>>,
    scale: DVector<f64>,
}

/// Reads the chain constructor's arguments: `robot` a SerialChain, the analysis `base`
/// (default the chain's), `beta0` (b,) and `scale` (b,) positive.
fn chain_setup(
    py: Python<'_>,
    robot: &Bound<'_, PyAny>,
    base: Option<&crate::models::chain::PyBaseParameters>,
    beta0: Option<&Bound<'_, PyAny>>,
    scale: Option<&Bound<'_, PyAny>>,
) -> PyResult<ChainSetup> {
    let chain = robot.cast::<crate::models::chain::PySerialChain>()?.get();
    let base = match base {
        Some(b) => b.inner.clone(),
        None => chain.default_base(py)?.clone(),
    };
    let model = chain.chain().base_model(&base).to_py(py)?;
    let b = model.count();
    let sized = |o: &Bound<'_, PyAny>, name: &'static str| -> PyResult<Vec<f64>> {
        let v = crate::arrays::vector(o, name)?;
        if v.len() != b {
            return Err(to_pyerr(
                py,
                &PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("({b},): one per base parameter"),
                    got: format!("({},)", v.len()),
                },
            ));
        }
        Ok(v)
    };
    let beta0 = beta0.map(|o| sized(o, "beta0")).transpose()?;
    let scale = match scale {
        Some(o) => DVector::from_vec(sized(o, "scale")?),
        None => DVector::repeat(b, 1.0),
    };
    Ok(ChainSetup {
        model,
        beta0,
        scale,
    })
}

impl ChainSetup {
    /// The scaled model and γ₀ = β₀/scale (β₀ defaulting to zeros).
    fn scaled(self, py: Python<'_>) -> PyResult<(Scaled, DVector<f64>, DVector<f64>)> {
        let b = self.model.count();
        let beta0 = DVector::from_vec(self.beta0.unwrap_or_else(|| vec![0.0; b]));
        let gamma0 = beta0.component_div(&self.scale);
        let scale = self.scale.clone();
        let model = DynScaledModel::new(self.model, self.scale).to_py(py)?;
        Ok((model, gamma0, scale))
    }
}

/// The SerialChain in the first positional argument of an estimator constructor, if any.
fn chain_arg<'a, 'py>(first: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    first.filter(|o| o.is_instance_of::<crate::models::chain::PySerialChain>())
}

/// The chain-only keywords given to a paper-arm constructor are an error.
fn paper_only(
    py: Python<'_>,
    beta0: Option<&Bound<'_, PyAny>>,
    base: Option<&crate::models::chain::PyBaseParameters>,
    scale: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    if beta0.is_some() || base.is_some() || scale.is_some() {
        return Err(invalid(
            py,
            "beta0/base/scale",
            "are for an estimator of a SerialChain (pass the chain first); the paper's arm \
             takes lam0",
        ));
    }
    Ok(())
}

/// One sample ((n,) arrays) into the preallocated row buffers.
fn dyn_rows(rows: &mut [DVector<f64>; 4], args: [&Bound<'_, PyAny>; 4], n: usize) -> PyResult<()> {
    const NAMES: [&str; 4] = ["q", "qd", "qdd", "tau"];
    for ((buf, obj), name) in rows.iter_mut().zip(args).zip(NAMES) {
        let s = crate::arrays::DynSamples::extract(obj, name, n)?;
        if crate::arrays::batch_len(obj.py(), &[&s])?.is_some() {
            return Err(to_pyerr(
                obj.py(),
                &PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("({n},): one sample (use run for a batch)"),
                    got: "a batch".into(),
                },
            ));
        }
        buf.as_mut_slice().copy_from_slice(s.at(0));
    }
    Ok(())
}

/// `step` of a chain estimator: one sample, returns β̂ (b,).
fn step_chain<'py, D: Estimator<nalgebra::Dyn, nalgebra::Dyn>>(
    py: Python<'py>,
    c: &mut ChainEst<D>,
    args: [&Bound<'py, PyAny>; 4],
) -> PyResult<Bound<'py, PyAny>> {
    let n = c.n;
    let mut rows: [DVector<f64>; 4] = std::array::from_fn(|_| DVector::zeros(n));
    dyn_rows(&mut rows, args, n)?;
    let [q, qd, qdd, tau] = &rows;
    c.est.step(DynSample::new(q, qd, qdd, tau)).to_py(py)?;
    let beta = c.beta();
    if !beta.iter().all(|x| x.is_finite()) {
        let what = "estimate β̂ (the sample's magnitudes overflow f64 arithmetic)".into();
        return Err(to_pyerr(py, &PrrrpError::NonFinite { what, row: None }));
    }
    let b = beta.len();
    to_array(py, beta, None, &[b])
}

/// The four (N, n) columns of a chain batch as run-time vectors.
struct DynColumns {
    q: Vec<DVector<f64>>,
    qd: Vec<DVector<f64>>,
    qdd: Vec<DVector<f64>>,
    tau: Vec<DVector<f64>>,
}

impl DynColumns {
    fn extract(args: [&Bound<'_, PyAny>; 4], n: usize) -> PyResult<Self> {
        const NAMES: [&str; 4] = ["q", "qd", "qdd", "tau"];
        let mut cols: [Vec<DVector<f64>>; 4] = Default::default();
        for ((col, obj), name) in cols.iter_mut().zip(args).zip(NAMES) {
            let (shape, data) = crate::arrays::any_array(obj, name, &format!("(N, {n})"))?;
            if shape.len() != 2 || shape[1] != n {
                return Err(to_pyerr(
                    obj.py(),
                    &PrrrpError::ShapeMismatch {
                        what: name.into(),
                        expected: format!("(N, {n})"),
                        got: crate::arrays::fmt_shape(&shape),
                    },
                ));
            }
            *col = data
                .chunks_exact(n)
                .map(DVector::from_column_slice)
                .collect();
        }
        let [q, qd, qdd, tau] = cols;
        Ok(Self { q, qd, qdd, tau })
    }

    fn samples(&self) -> Result<CoreDynSamples<'_>, PrrrpError> {
        CoreDynSamples::new(&self.q, &self.qd, &self.qdd, &self.tau)
    }
}

/// `run` of a chain estimator, GIL released; β̂ (b,) or (β̂, history (M, b)).
fn run_chain<'py, D: Estimator<nalgebra::Dyn, nalgebra::Dyn> + Send>(
    py: Python<'py>,
    c: &mut ChainEst<D>,
    args: [&Bound<'py, PyAny>; 4],
    history_every: Option<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    if history_every == Some(0) {
        return Err(invalid(py, "history_every", "must be >= 1 (or None)"));
    }
    let cols = DynColumns::extract(args, c.n)?;
    let mut history: Vec<f64> = Vec::new();
    let result = interruptible(py, || -> Result<(), (usize, PrrrpError)> {
        let s = cols.samples().map_err(|e| (0, e))?;
        for (k, sample) in s.iter().enumerate() {
            if k % CHECK_EVERY == 0 && prrrp_core::stop_requested() {
                let what = "estimator run";
                return Err((k, PrrrpError::Interrupted { what }));
            }
            c.est.step(sample).map_err(|e| (k, e))?;
            let beta = c.beta();
            if !beta.iter().all(|x| x.is_finite()) {
                let what = "estimate β̂ (the data's magnitudes overflow f64 arithmetic)".into();
                return Err((k, PrrrpError::NonFinite { what, row: None }));
            }
            if let Some(every) = history_every {
                if (k + 1) % every == 0 {
                    history.extend_from_slice(&beta);
                }
            }
        }
        Ok(())
    })?;
    if let Err((k, e)) = result {
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
    let beta = c.beta();
    let b = beta.len();
    let beta = to_array(py, beta, None, &[b])?;
    match history_every {
        None => Ok(beta),
        Some(_) => {
            let m = history.len() / b.max(1);
            let h = to_array(py, history, None, &[m, b])?;
            Ok((beta, h).into_pyobject(py)?.into_any())
        }
    }
}

/// `train` of a chain Adaline/Hopfield: RMS equation error per epoch.
fn train_chain<'py, D: Send>(
    py: Python<'py>,
    c: &mut ChainEst<D>,
    args: [&Bound<'py, PyAny>; 4],
    f: impl FnOnce(&mut D, &CoreDynSamples<'_>) -> Result<prrrp_core::TrainingReport, PrrrpError> + Send,
) -> PyResult<Bound<'py, PyAny>> {
    let cols = DynColumns::extract(args, c.n)?;
    let est = &mut c.est;
    let report = interruptible(py, || f(est, &cols.samples()?))?.to_py(py)?;
    let n = report.rms_error.len();
    to_array(py, report.rms_error, None, &[n])
}

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
                match &mut *lock(py, &self.inner)? {
                    Inner::Paper(e) => step_one(py, e, q, qd, qdd, tau),
                    Inner::Chain(c) => step_chain(py, c, [q, qd, qdd, tau]),
                }
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
                match &mut *lock(py, &self.inner)? {
                    Inner::Paper(e) => run_batch(py, e, q, qd, qdd, tau, every),
                    Inner::Chain(c) => run_chain(py, c, [q, qd, qdd, tau], every),
                }
            }
            fn do_estimate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
                match &*lock(py, &self.inner)? {
                    Inner::Paper(e) => vec8(py, e.estimate()),
                    Inner::Chain(c) => {
                        let beta = c.beta();
                        let b = beta.len();
                        to_array(py, beta, None, &[b])
                    }
                }
            }
            fn do_reset(&self, py: Python<'_>) -> PyResult<()> {
                match &mut *lock(py, &self.inner)? {
                    Inner::Paper(e) => e.reset(),
                    Inner::Chain(c) => c.est.reset(),
                }
                Ok(())
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
            self.do_estimate(py)
        }
        /// Returns to the state right after construction.
        fn reset(&self, py: Python<'_>) -> PyResult<()> {
            self.do_reset(py)
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
    inner: Mutex<Inner<CoreAdaline<Model, NDOF, NPARAM>, DynAdaline<Scaled>>>,
}
online_methods!(Adaline);

estimator_pymethods!(Adaline {
    #[new]
    #[pyo3(signature = (lam0=None, *, rule="normalised", learning_rate=5e-3, step_size=1.0,
        epsilon=1e-9, divergence_ratio=1e6, beta0=None, base=None, scale=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        rule: &str,
        learning_rate: f64,
        step_size: f64,
        epsilon: f64,
        divergence_ratio: f64,
        beta0: Option<&Bound<'_, PyAny>>,
        base: Option<&crate::models::chain::PyBaseParameters>,
        scale: Option<&Bound<'_, PyAny>>,
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
        if let Some(robot) = chain_arg(lam0) {
            let setup = chain_setup(py, robot, base, beta0, scale)?;
            let n = setup.model.dof();
            let (model, gamma0, scale) = setup.scaled(py)?;
            let est = DynAdaline::new(model, gamma0, config).to_py(py)?;
            return Ok(Self {
                inner: Mutex::new(Inner::Chain(ChainEst { est, scale, n })),
            });
        }
        paper_only(py, beta0, base, scale)?;
        Ok(Self {
            inner: Mutex::new(Inner::Paper(
                CoreAdaline::new(model(), lambda0(lam0)?, config).to_py(py)?,
            )),
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
        match &mut *lock(py, &self.inner)? {
            Inner::Paper(e) => train_epochs(py, q, qd, qdd, tau, |s| e.train(s, epochs.0)),
            Inner::Chain(c) => {
                train_chain(py, c, [q, qd, qdd, tau], |e, s| e.train(s, epochs.0))
            }
        }
    }
});

/// Hopfield network (paper §3.3, Abe's formulation, eq. 19): estimates in (−bound, bound),
/// slope `beta`, each sample integrated over `dt` s. `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Hopfield", frozen)]
struct Hopfield {
    inner: Mutex<Inner<CoreHopfield<Model, NDOF, NPARAM>, DynHopfield<Scaled>>>,
}
online_methods!(Hopfield);

estimator_pymethods!(Hopfield {
    #[new]
    #[pyo3(signature = (lam0=None, *, bound=10.0, beta=100.0, dt=0.02, stability_limit=1.0,
        max_substeps=64, beta0=None, base=None, scale=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        bound: f64,
        beta: f64,
        dt: f64,
        stability_limit: f64,
        max_substeps: u32,
        beta0: Option<&Bound<'_, PyAny>>,
        base: Option<&crate::models::chain::PyBaseParameters>,
        scale: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let config = HopfieldConfig {
            bound,
            beta,
            dt,
            stability_limit,
            max_substeps,
        };
        if let Some(robot) = chain_arg(lam0) {
            let setup = chain_setup(py, robot, base, beta0, scale)?;
            let n = setup.model.dof();
            let (model, gamma0, scale) = setup.scaled(py)?;
            let est = DynHopfield::new(model, gamma0, config).to_py(py)?;
            return Ok(Self {
                inner: Mutex::new(Inner::Chain(ChainEst { est, scale, n })),
            });
        }
        paper_only(py, beta0, base, scale)?;
        Ok(Self {
            inner: Mutex::new(Inner::Paper(
                CoreHopfield::new(model(), lambda0(lam0)?, config).to_py(py)?,
            )),
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
        match &mut *lock(py, &self.inner)? {
            Inner::Paper(e) => train_epochs(py, q, qd, qdd, tau, |s| e.train(s, epochs.0)),
            Inner::Chain(c) => {
                train_chain(py, c, [q, qd, qdd, tau], |e, s| e.train(s, epochs.0))
            }
        }
    }
});

/// Recursive least squares with forgetting factor `forgetting` in (0, 1] and P₀ =
/// `initial_covariance`·I. `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Rls", frozen)]
struct Rls {
    inner: Mutex<Inner<CoreRls<Model, NDOF, NPARAM>, DynRls<Scaled>>>,
}
online_methods!(Rls);

estimator_pymethods!(Rls {
    #[new]
    #[pyo3(signature = (lam0=None, *, forgetting=1.0, initial_covariance=1e6, beta0=None,
        base=None, scale=None))]
    fn new(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        forgetting: f64,
        initial_covariance: f64,
        beta0: Option<&Bound<'_, PyAny>>,
        base: Option<&crate::models::chain::PyBaseParameters>,
        scale: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let config = RlsConfig {
            forgetting,
            initial_covariance,
        };
        if let Some(robot) = chain_arg(lam0) {
            let setup = chain_setup(py, robot, base, beta0, scale)?;
            let n = setup.model.dof();
            let (model, gamma0, scale) = setup.scaled(py)?;
            let est = DynRls::new(model, gamma0, config).to_py(py)?;
            return Ok(Self {
                inner: Mutex::new(Inner::Chain(ChainEst { est, scale, n })),
            });
        }
        paper_only(py, beta0, base, scale)?;
        Ok(Self {
            inner: Mutex::new(Inner::Paper(
                CoreRls::new(model(), lambda0(lam0)?, config).to_py(py)?,
            )),
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
    inner: Mutex<Inner<CoreEkf<Model, NDOF, NPARAM, PRRRP_EKF_STATES>, DynEkf<DynChainBaseModel>>>,
}
online_methods!(Ekf);

estimator_pymethods!(Ekf {
    #[new]
    #[pyo3(signature = (lam0=None, *, measurement="positions", discretisation="euler",
        dt=0.02, position_noise=1e-3, velocity_noise=1e-2, process_position_noise=1e-6,
        process_velocity_noise=1e-3, process_parameter_noise=1e-5, initial_position_std=1e-3,
        initial_velocity_std=1.0, initial_parameter_rel_std=0.5, initial_parameter_min_std=1e-3,
        init_from_first_measurement=true, beta0=None, base=None))]
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
        beta0: Option<&Bound<'_, PyAny>>,
        base: Option<&crate::models::chain::PyBaseParameters>,
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
            ..EkfConfig::default()
        };
        if let Some(robot) = chain_arg(lam0) {
            let setup = chain_setup(py, robot, base, beta0, None)?;
            let n = setup.model.dof();
            let b = setup.model.count();
            // The chain's own parameters (its CAD / URDF values) unless β0 is given: the
            // filter needs M(q, β0) positive definite, which zeros are not.
            let beta0 = match setup.beta0 {
                Some(v) => DVector::from_vec(v),
                None => setup.model.chain_base_values().clone(),
            };
            let est = DynEkf::new(setup.model, beta0, config).to_py(py)?;
            let scale = DVector::repeat(b, 1.0);
            return Ok(Self {
                inner: Mutex::new(Inner::Chain(ChainEst { est, scale, n })),
            });
        }
        paper_only(py, beta0, base, None)?;
        Ok(Self {
            inner: Mutex::new(Inner::Paper(
                CoreEkf::new(model(), lambda0(lam0)?, config).to_py(py)?,
            )),
        })
    }
    /// Standard deviations of λ̂ (β̂ for a chain) from the filter covariance, (P,).
    #[getter]
    fn parameter_std<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &*lock(py, &self.inner)? {
            Inner::Paper(e) => vec8(py, &e.parameter_std()),
            Inner::Chain(c) => {
                let v: Vec<f64> = c.est.parameter_std().iter().copied().collect();
                let b = v.len();
                to_array(py, v, None, &[b])
            }
        }
    }
    /// Measurement updates skipped because of NaN measurements.
    #[getter]
    fn skipped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(match &*lock(py, &self.inner)? {
            Inner::Paper(e) => e.skipped_updates(),
            Inner::Chain(c) => c.est.skipped_updates(),
        })
    }
    /// Samples whose update was damped (gain halved) to keep M(q, λ̂) positive definite.
    #[getter]
    fn damped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(match &*lock(py, &self.inner)? {
            Inner::Paper(e) => e.damped_updates(),
            Inner::Chain(c) => c.est.damped_updates(),
        })
    }
    /// The state x = [q (n), q̇ (n), λ (P)] predicted for the next sample, (S,).
    #[getter]
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let state = match &*lock(py, &self.inner)? {
            Inner::Paper(e) => e.state().as_slice().to_vec(),
            Inner::Chain(c) => c.est.state().as_slice().to_vec(),
        };
        let s = state.len();
        to_array(py, state, None, &[s])
    }
    /// The state covariance P, (S, S), in the squares of the state's SI units.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &*lock(py, &self.inner)? {
            Inner::Paper(e) => {
                let mut buf = vec![0.0; PRRRP_EKF_STATES * PRRRP_EKF_STATES];
                write_row_major(e.covariance(), &mut buf);
                to_array(py, buf, None, &[PRRRP_EKF_STATES, PRRRP_EKF_STATES])
            }
            Inner::Chain(c) => {
                let p = c.est.covariance();
                let s = p.nrows();
                to_array(py, p.transpose().as_slice().to_vec(), None, &[s, s])
            }
        }
    }
    /// Replaces the initial covariance P₀ (S, S): symmetric positive definite, squares
    /// of the state units. Also the current P when no sample has been consumed yet.
    fn set_initial_covariance(&self, py: Python<'_>, p0: &Bound<'_, PyAny>) -> PyResult<()> {
        match &mut *lock(py, &self.inner)? {
            Inner::Paper(e) => {
                let p0 = fixed_matrix::<PRRRP_EKF_STATES, PRRRP_EKF_STATES>(p0, "p0")?;
                e.set_initial_covariance(&p0).to_py(py)
            }
            Inner::Chain(c) => {
                let s = c.est.state().len();
                let (shape, data) = crate::arrays::any_array(p0, "p0", &format!("({s}, {s})"))?;
                if shape != [s, s] {
                    return Err(to_pyerr(
                        py,
                        &PrrrpError::ShapeMismatch {
                            what: "p0".into(),
                            expected: format!("({s}, {s})"),
                            got: crate::arrays::fmt_shape(&shape),
                        },
                    ));
                }
                let m = DMatrix::from_row_slice(s, s, &data);
                c.est.set_initial_covariance(&m).to_py(py)
            }
        }
    }
    /// Replaces the process noise Q = diag(variances), (S,), per step, squares of the
    /// state units; each ≥ 0.
    fn set_process_noise(&self, py: Python<'_>, variances: &Bound<'_, PyAny>) -> PyResult<()> {
        match &mut *lock(py, &self.inner)? {
            Inner::Paper(e) => {
                let v = fixed_vector::<PRRRP_EKF_STATES>(variances, "variances")?;
                e.set_process_noise(&SVector::from_column_slice(&v)).to_py(py)
            }
            Inner::Chain(c) => {
                let v = DVector::from_vec(crate::arrays::vector(variances, "variances")?);
                c.est.set_process_noise(&v).to_py(py)
            }
        }
    }
    /// Replaces the measurement noise R = diag(positions (n,), velocities (n,)), variances
    /// in m², rad², (m/s)², (rad/s)²; each > 0.
    fn set_measurement_noise(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        velocities: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        match &mut *lock(py, &self.inner)? {
            Inner::Paper(e) => {
                let p = fixed_vector::<NDOF>(positions, "positions")?;
                let v = fixed_vector::<NDOF>(velocities, "velocities")?;
                e.set_measurement_noise(
                    &SVector::from_column_slice(&p),
                    &SVector::from_column_slice(&v),
                )
                .to_py(py)
            }
            Inner::Chain(c) => {
                let p = DVector::from_vec(crate::arrays::vector(positions, "positions")?);
                let v = DVector::from_vec(crate::arrays::vector(velocities, "velocities")?);
                c.est.set_measurement_noise(&p, &v).to_py(py)
            }
        }
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
