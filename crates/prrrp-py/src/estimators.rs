//! The estimators: `prrrp.least_squares` (→ `LeastSquaresResult`) and the online estimators
//! `prrrp.Adaline`, `prrrp.Hopfield`, `prrrp.Ekf`, `prrrp.Rls`, each with `step(q, qd,
//! qdd, tau)`, `estimate`, `reset()` and the batch `run(...)` (plus `train(..., epochs)`
//! for Adaline and Hopfield), looping in Rust with the GIL released.

use prrrp_core::nalgebra::allocator::Allocator;
use prrrp_core::nalgebra::{
    Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SVector,
};
use prrrp_core::{
    least_squares as core_ls, weighted_least_squares as core_wls, Adaline as CoreAdaline,
    AdalineConfig, AdalineRule, Discretisation, Ekf as CoreEkf, EkfConfig, EkfMeasurement,
    Estimator, Hopfield as CoreHopfield, HopfieldConfig, JointNoise, Lambda, LeastSquaresConfig,
    PrrrpError, PrrrpModel, Rls as CoreRls, RlsConfig, Robot, SampleOf, SamplesOf, TrainingReport,
    Vec5, NDOF, NPARAM, PRRRP_EKF_STATES,
};
use prrrp_core::{DynAdaline, DynChainBaseModel, DynEkf, DynHopfield, DynRls, DynScaledModel};
use std::sync::{Mutex, MutexGuard, TryLockError};

use pyo3::prelude::*;

use crate::arrays::{
    any_array, batch_len, fixed_matrix, fixed_or, fixed_vector, fmt_shape, to_array, vector,
    vector_of_len, DynSamples, Out, Samples, UInt,
};
use crate::errors::{shape_error, to_pyerr, Exc, ToPyResult};
use crate::interrupt::interruptible;

type Model = PrrrpModel;

fn model() -> Model {
    Robot::paper().model()
}

fn lambda0(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Lambda> {
    fixed_or::<NPARAM>(obj, "lam0", Robot::paper().base_parameters())
}

fn vec8<'py>(py: Python<'py>, v: &Lambda) -> Out<'py> {
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

/// The EKF's measurement settings by their Python names, for the `Ekf` class and for
/// `identify`'s EKF settings alike.
pub(crate) const EKF_MEASUREMENTS: [(&str, EkfMeasurement); 2] = [
    ("positions", EkfMeasurement::Positions),
    ("positions_velocities", EkfMeasurement::PositionsVelocities),
];
/// What a measurement setting not in [`EKF_MEASUREMENTS`] is told.
pub(crate) const EKF_MEASUREMENT_REASON: &str = "must be \"positions\" or \"positions_velocities\"";
/// Adaline's learning rules by their Python names (either spelling of "normalised").
pub(crate) const ADALINE_RULES: [(&str, AdalineRule); 3] = [
    ("normalised", AdalineRule::Normalised),
    ("normalized", AdalineRule::Normalised),
    ("delta", AdalineRule::Delta),
];
/// What a rule not in [`ADALINE_RULES`] is told.
pub(crate) const ADALINE_RULE_REASON: &str = "must be \"normalised\" or \"delta\"";

/// The value `name` stands for among `options` (Python name, value), if any.
pub(crate) fn choose<T: Copy>(name: &str, options: &[(&str, T)]) -> Option<T> {
    options.iter().find(|(k, _)| *k == name).map(|&(_, t)| t)
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
    Paper(Est<F>),
    Chain(Est<D>),
}

/// An estimator with its joint count and the column scale its estimate is mapped back by.
struct Est<E> {
    est: E,
    /// β = scale·γ for a chain trained on scaled columns; None: the estimate as it is.
    scale: Option<DVector<f64>>,
    n: usize,
    /// The estimate's symbol in error messages: λ̂ (the paper's arm) or β̂ (a chain).
    sym: &'static str,
}

impl<E> Est<E> {
    fn paper(est: E) -> Self {
        Self {
            est,
            scale: None,
            n: NDOF,
            sym: "λ̂",
        }
    }

    fn chain(est: E, scale: DVector<f64>, n: usize) -> Self {
        Self {
            est,
            scale: Some(scale),
            n,
            sym: "β̂",
        }
    }

    /// The estimate in the user's units (β = scale·γ for a chain).
    fn value<N: Dim, P: Dim>(&self) -> Vec<f64>
    where
        E: Estimator<N, P>,
        DefaultAllocator: Allocator<N> + Allocator<P>,
    {
        let est = self.est.estimate().iter();
        match &self.scale {
            Some(scale) => est.zip(scale.iter()).map(|(g, s)| g * s).collect(),
            None => est.copied().collect(),
        }
    }
}

/// Runs `$body` with `$c` bound to the `Est` of either kind: one text, type-checked for
/// the compile-time and the run-time sizes.
macro_rules! each {
    ($inner:expr, $c:ident => $body:expr) => {
        match $inner {
            Inner::Paper($c) => $body,
            Inner::Chain($c) => $body,
        }
    };
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
    let sized = |o, name| vector_of_len(o, name, b, ": one per base parameter");
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

type Any<'py> = Bound<'py, PyAny>;

/// How the arguments of one size family are read. The paper's arm reads fixed (5,) rows
/// and (N, 5) batches, a chain rows of its own length; each keeps its own checks and
/// error messages.
trait Read: Dim
where
    DefaultAllocator: Allocator<Self> + Allocator<Self, Self>,
{
    /// One sample's (n,) row of argument `name`.
    fn one(obj: &Any<'_>, name: &'static str, n: usize) -> PyResult<OVector<f64, Self>>;
    /// The (N, n) rows of a batch argument.
    fn rows(obj: &Any<'_>, name: &'static str, n: usize) -> PyResult<Vec<OVector<f64, Self>>>;
    /// A vector argument of this dimension.
    fn vector(obj: &Any<'_>, name: &'static str) -> PyResult<OVector<f64, Self>>;
    /// A square (s, s) matrix argument.
    fn square(obj: &Any<'_>, name: &'static str, s: usize) -> PyResult<OMatrix<f64, Self, Self>>;
}

impl<const D: usize> Read for Const<D> {
    fn one(obj: &Any<'_>, name: &'static str, _: usize) -> PyResult<OVector<f64, Self>> {
        fixed_or::<D>(Some(obj), name, SVector::zeros())
    }

    fn rows(obj: &Any<'_>, name: &'static str, _: usize) -> PyResult<Vec<OVector<f64, Self>>> {
        Samples::<D>::extract_rows(obj, name)
    }

    fn vector(obj: &Any<'_>, name: &'static str) -> PyResult<OVector<f64, Self>> {
        Ok(OVector::from(fixed_vector::<D>(obj, name)?))
    }

    fn square(obj: &Any<'_>, name: &'static str, _: usize) -> PyResult<OMatrix<f64, Self, Self>> {
        fixed_matrix::<D, D>(obj, name)
    }
}

impl Read for Dyn {
    fn one(obj: &Any<'_>, name: &'static str, n: usize) -> PyResult<DVector<f64>> {
        let s = DynSamples::extract(obj, name, n)?;
        if batch_len(obj.py(), &[&s])?.is_some() {
            let want = format!("({n},): one sample (use run for a batch)");
            return Err(shape_error(obj.py(), name, want, "a batch"));
        }
        Ok(DVector::from_column_slice(s.at(0)))
    }

    fn rows(obj: &Any<'_>, name: &'static str, n: usize) -> PyResult<Vec<DVector<f64>>> {
        let want = format!("(N, {n})");
        let (shape, data) = any_array(obj, name, &want)?;
        if shape.len() != 2 || shape[1] != n {
            return Err(shape_error(obj.py(), name, want, fmt_shape(&shape)));
        }
        let rows = data.chunks_exact(n).map(DVector::from_column_slice);
        Ok(rows.collect())
    }

    fn vector(obj: &Any<'_>, name: &'static str) -> PyResult<DVector<f64>> {
        Ok(DVector::from_vec(vector(obj, name)?))
    }

    fn square(obj: &Any<'_>, name: &'static str, s: usize) -> PyResult<DMatrix<f64>> {
        let want = format!("({s}, {s})");
        let (shape, data) = any_array(obj, name, &want)?;
        if shape != [s, s] {
            return Err(shape_error(obj.py(), name, want, fmt_shape(&shape)));
        }
        Ok(DMatrix::from_row_slice(s, s, &data))
    }
}

const NAMES: [&str; 4] = ["q", "qd", "qdd", "tau"];

/// The four (N, n) columns of a batch call.
struct Columns<N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    cols: [Vec<OVector<f64, N>>; 4],
}

impl<N: Read> Columns<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    fn extract(args: [&Bound<'_, PyAny>; 4], n: usize) -> PyResult<Self> {
        let mut cols: [Vec<OVector<f64, N>>; 4] = Default::default();
        for ((col, obj), name) in cols.iter_mut().zip(args).zip(NAMES) {
            *col = N::rows(obj, name, n)?;
        }
        Ok(Self { cols })
    }

    fn samples(&self) -> Result<SamplesOf<'_, N>, PrrrpError> {
        let [q, qd, qdd, tau] = &self.cols;
        SamplesOf::new(q, qd, qdd, tau)
    }
}

/// A (len,) vector as a numpy array.
fn vec_out(py: Python<'_>, v: Vec<f64>) -> PyResult<Bound<'_, PyAny>> {
    let len = v.len();
    to_array(py, v, None, &[len])
}

/// `step`: one sample ((n,) arrays), returns the updated estimate.
fn step<'py, N: Read, P: Dim, E: Estimator<N, P>>(
    py: Python<'py>,
    c: &mut Est<E>,
    args: [&Bound<'py, PyAny>; 4],
) -> Out<'py>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<P>,
{
    let rows = args
        .into_iter()
        .zip(NAMES)
        .map(|(obj, name)| N::one(obj, name, c.n))
        .collect::<PyResult<Vec<_>>>()?;
    let [q, qd, qdd, tau] = [&rows[0], &rows[1], &rows[2], &rows[3]];
    c.est.step(SampleOf::new(q, qd, qdd, tau)).to_py(py)?;
    let value = c.value();
    if !value.iter().all(|x| x.is_finite()) {
        let what = format!(
            "estimate {} (the sample's magnitudes overflow f64 arithmetic)",
            c.sym
        );
        return Err(to_pyerr(py, &PrrrpError::NonFinite { what, row: None }));
    }
    vec_out(py, value)
}

/// `run`: steps over every sample with the GIL released. Returns the estimate (P,), or
/// `(estimate, history)` with history (M, P) = the estimate after every `history_every`
/// samples.
fn run<'py, N: Read, P: Dim, E: Estimator<N, P> + Send>(
    py: Python<'py>,
    c: &mut Est<E>,
    args: [&Bound<'py, PyAny>; 4],
    history_every: Option<usize>,
) -> Out<'py>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<P>,
    OVector<f64, N>: Sync,
{
    if history_every == Some(0) {
        return Err(invalid(py, "history_every", "must be >= 1 (or None)"));
    }
    let cols = Columns::<N>::extract(args, c.n)?;
    let mut history: Vec<f64> = Vec::new();
    let result = interruptible(py, || -> Result<(), (usize, PrrrpError)> {
        let s = cols.samples().map_err(|e| (0, e))?;
        for (k, sample) in s.iter().enumerate() {
            if k % CHECK_EVERY == 0 && prrrp_core::stop_requested() {
                let what = "estimator run";
                return Err((k, PrrrpError::Interrupted { what }));
            }
            c.est.step(sample).map_err(|e| (k, e))?;
            let value = c.value();
            if !value.iter().all(|x| x.is_finite()) {
                let what = format!(
                    "estimate {} (the data's magnitudes overflow f64 arithmetic)",
                    c.sym
                );
                return Err((k, PrrrpError::NonFinite { what, row: None }));
            }
            if let Some(every) = history_every {
                if (k + 1) % every == 0 {
                    history.extend_from_slice(&value);
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
    let value = c.value();
    let b = value.len();
    let value = vec_out(py, value)?;
    match history_every {
        None => Ok(value),
        Some(_) => {
            let m = history.len() / b.max(1);
            let h = to_array(py, history, Some(m), &[b])?;
            Ok((value, h).into_pyobject(py)?.into_any())
        }
    }
}

/// `train` of Adaline/Hopfield: the RMS equation error per epoch.
fn train<'py, N: Read, E: Send>(
    py: Python<'py>,
    c: &mut Est<E>,
    args: [&Bound<'py, PyAny>; 4],
    f: impl FnOnce(&mut E, &SamplesOf<'_, N>) -> Result<TrainingReport, PrrrpError> + Send,
) -> Out<'py>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
    OVector<f64, N>: Sync,
{
    let cols = Columns::<N>::extract(args, c.n)?;
    let est = &mut c.est;
    let report = interruptible(py, || f(est, &cols.samples()?))?.to_py(py)?;
    vec_out(py, report.rms_error)
}

/// Generates the `#[pymethods]` of an online estimator: its own items, `train` when
/// given (Adaline, Hopfield: its doc comment follows `train`), and the methods every
/// online estimator shares (pyo3 allows one `#[pymethods]` block per class without the
/// `multiple-pymethods` feature). The first rule names the sample arguments of `step`,
/// `run` and `train` (twice: macro_rules cannot repeat the first list inside the optional
/// `train` group).
macro_rules! estimator_pymethods {
    ($name:ident { $($extra:tt)* } $(train: $(#[$train_doc:meta])+)?) => {
        estimator_pymethods!(@ [q, qd, qdd, tau] $name { $($extra)* }
            $(train: [q, qd, qdd, tau] $(#[$train_doc])+)?);
    };
    (@ [$($s:ident),+] $name:ident { $($extra:tt)* }
        $(train: [$($ts:ident),+] $(#[$train_doc:meta])+)?) => {
        #[pymethods]
        impl $name {
        $($extra)*
        $(
        $(#[$train_doc])+
        fn train<'py>(
            &self,
            py: Python<'py>,
            $($ts: &Bound<'py, PyAny>,)+
            epochs: UInt<usize>,
        ) -> Out<'py> {
            each!(&mut *lock(py, &self.inner)?, c => {
                train(py, c, [$($ts),+], |e, s| e.train(s, epochs.0))
            })
        }
        )?
        /// Consumes one sample (each (5,)) and returns the updated λ̂ (8,).
        fn step<'py>(&self, py: Python<'py>, $($s: &Bound<'py, PyAny>),+) -> Out<'py> {
            each!(&mut *lock(py, &self.inner)?, c => step(py, c, [$($s),+]))
        }
        /// Steps over N samples ((N, 5) each) in Rust with the GIL released, continuing
        /// from the current state. Returns λ̂ (8,), or `(λ̂, history)` with `history`
        /// (M, 8) the estimate after every `history_every` samples.
        #[pyo3(signature = ($($s),+, *, history_every=None))]
        fn run<'py>(
            &self,
            py: Python<'py>,
            $($s: &Bound<'py, PyAny>,)+
            history_every: Option<UInt<usize>>,
        ) -> Out<'py> {
            let every = history_every.map(|u| u.0);
            each!(&mut *lock(py, &self.inner)?, c => run(py, c, [$($s),+], every))
        }
        /// The current estimate λ̂, (8,).
        #[getter]
        fn estimate<'py>(&self, py: Python<'py>) -> Out<'py> {
            each!(&*lock(py, &self.inner)?, c => vec_out(py, c.value()))
        }
        /// Returns to the state right after construction.
        fn reset(&self, py: Python<'_>) -> PyResult<()> {
            each!(&mut *lock(py, &self.inner)?, c => c.est.reset());
            Ok(())
        }
        }
    };
}

impl<F, D> Inner<F, D> {
    /// The estimator of a constructor call: of the SerialChain given first (on its scaled
    /// base-parameter model, from β₀/scale), or else of the paper's arm from `lam0`.
    #[allow(clippy::too_many_arguments)]
    fn build(
        py: Python<'_>,
        lam0: Option<&Bound<'_, PyAny>>,
        beta0: Option<&Bound<'_, PyAny>>,
        base: Option<&crate::models::chain::PyBaseParameters>,
        scale: Option<&Bound<'_, PyAny>>,
        paper: impl FnOnce(Model, Lambda) -> Result<F, PrrrpError>,
        chain: impl FnOnce(Scaled, DVector<f64>) -> Result<D, PrrrpError>,
    ) -> PyResult<Mutex<Self>> {
        if let Some(robot) = chain_arg(lam0) {
            let setup = chain_setup(py, robot, base, beta0, scale)?;
            let n = setup.model.dof();
            let (model, gamma0, scale) = setup.scaled(py)?;
            let est = chain(model, gamma0).to_py(py)?;
            return Ok(Mutex::new(Inner::Chain(Est::chain(est, scale, n))));
        }
        paper_only(py, beta0, base, scale)?;
        let est = paper(model(), lambda0(lam0)?).to_py(py)?;
        Ok(Mutex::new(Inner::Paper(Est::paper(est))))
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

array_pyfunctions! {
/// Least-squares estimate of λ from N samples (q, qd, qdd, tau each (N, 5)), eq. 36.
/// `weighted=True` divides each joint's equations by its noise standard deviation:
/// `noise_variances` (5,) if given, else estimated from an ordinary pass.
/// Raises `RankDeficientError` (with `.directions`, `.cond`) when the data do not excite
/// every parameter and `TooFewSamplesError` for fewer than 8 samples.
#[pyfunction]
#[pyo3(signature = (q, qd, qdd, tau, *, weighted=false, noise_variances=None,
    rank_tolerance=1e-10))]
fn least_squares(py, q, qd, qdd, tau;
    weighted: bool,
    noise_variances: Option<&Bound<'py, PyAny>>,
    rank_tolerance: f64,
) -> PyResult<LeastSquaresResult> {
    let cols = Columns::<Const<NDOF>>::extract([q, qd, qdd, tau], NDOF)?;
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
}

/// One online estimator class of the paper's arm or of a chain: the struct, its
/// constructor (`lam0` or a SerialChain first, the class's own settings, which `$make`
/// turns into its config, then `beta0`, `base`, `scale` for a chain) and the shared
/// methods (`train` too when the trailing `train:` doc is given).
macro_rules! online_estimator {
    (
        $(#[$doc:meta])*
        $name:ident($paper:ident, $chain:ident) {
            #[pyo3(signature = (lam0=None, *, $($sig:tt)*))]
            fn new($py:ident, $($arg:ident: $ty:ty),* $(,)?) $make:block
        }
        $($train:tt)*
    ) => {
        $(#[$doc])*
        #[pyclass(module = "prrrp", frozen)]
        struct $name {
            inner: Mutex<Inner<$paper<Model, NDOF, NPARAM>, $chain<Scaled>>>,
        }

        estimator_pymethods!($name {
            #[new]
            #[pyo3(signature = (lam0=None, *, $($sig)*, beta0=None, base=None, scale=None))]
            #[allow(clippy::too_many_arguments)]
            fn new(
                $py: Python<'_>,
                lam0: Option<&Bound<'_, PyAny>>,
                $($arg: $ty,)*
                beta0: Option<&Bound<'_, PyAny>>,
                base: Option<&crate::models::chain::PyBaseParameters>,
                scale: Option<&Bound<'_, PyAny>>,
            ) -> PyResult<Self> {
                let config = $make;
                let paper = |m, l| $paper::new(m, l, config);
                let chain = |m, g| $chain::new(m, g, config);
                let inner = Inner::build($py, lam0, beta0, base, scale, paper, chain)?;
                Ok(Self { inner })
            }
        } $($train)*);
    };
}

online_estimator! {
    /// Adaline network (paper §3.2) whose weights are λ; `rule` "normalised" (NLMS, step size
    /// `step_size` in (0, 2)) or "delta" (eq. 11, rate `learning_rate`). `lam0` (8,) defaults
    /// to Table 3.
    Adaline(CoreAdaline, DynAdaline) {
        #[pyo3(signature = (lam0=None, *, rule="normalised", learning_rate=5e-3, step_size=1.0,
            epsilon=1e-9, divergence_ratio=1e6))]
        fn new(py, rule: &str, learning_rate: f64, step_size: f64, epsilon: f64,
            divergence_ratio: f64) {
            let rule = choose(rule, &ADALINE_RULES)
                .ok_or_else(|| invalid(py, "rule", ADALINE_RULE_REASON))?;
            AdalineConfig { rule, learning_rate, step_size, epsilon, divergence_ratio }
        }
    }
    train:
    /// `epochs` passes over the N samples; returns the a-priori RMS equation error of
    /// each epoch, (epochs,). At most 10**7 epochs per call (train in several calls for
    /// more); Ctrl-C stops it with KeyboardInterrupt.
}

online_estimator! {
    /// Hopfield network (paper §3.3, Abe's formulation, eq. 19): estimates in (−bound, bound),
    /// slope `beta`, each sample integrated over `dt` s. `lam0` (8,) defaults to Table 3.
    Hopfield(CoreHopfield, DynHopfield) {
        #[pyo3(signature = (lam0=None, *, bound=10.0, beta=100.0, dt=0.02, stability_limit=1.0,
            max_substeps=64))]
        fn new(py, bound: f64, beta: f64, dt: f64, stability_limit: f64, max_substeps: u32) {
            HopfieldConfig { bound, beta, dt, stability_limit, max_substeps }
        }
    }
    train:
    /// `epochs` passes over the N samples; returns the RMS equation error per epoch. At
    /// most 10**7 epochs per call; Ctrl-C stops it with KeyboardInterrupt.
}

online_estimator! {
    /// Recursive least squares with forgetting factor `forgetting` in (0, 1] and P₀ =
    /// `initial_covariance`·I. `lam0` (8,) defaults to Table 3.
    Rls(CoreRls, DynRls) {
        #[pyo3(signature = (lam0=None, *, forgetting=1.0, initial_covariance=1e6))]
        fn new(py, forgetting: f64, initial_covariance: f64) {
            RlsConfig { forgetting, initial_covariance }
        }
    }
}

/// Extended Kalman filter on the state [q, q̇, λ] (paper §3.4): `measurement` "positions"
/// (the paper's) or "positions_velocities"; `discretisation` "euler" (eq. 43) or
/// "second_order". `step`/`run` take (q, qd, qdd, tau) like the other estimators; q̈ is
/// ignored and q̇ used only when measured. Noise settings as the core's `EkfConfig`
/// (SI units). `lam0` (8,) defaults to Table 3.
#[pyclass(module = "prrrp", name = "Ekf", frozen)]
struct Ekf {
    inner: Mutex<Inner<CoreEkf<Model, NDOF, NPARAM, PRRRP_EKF_STATES>, DynEkf<DynChainBaseModel>>>,
}
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
        let measurement = choose(measurement, &EKF_MEASUREMENTS)
            .ok_or_else(|| invalid(py, "measurement", EKF_MEASUREMENT_REASON))?;
        let discretisation = choose(
            discretisation,
            &[
                ("euler", Discretisation::Euler),
                ("second_order", Discretisation::SecondOrder),
            ],
        )
        .ok_or_else(|| invalid(py, "discretisation", "must be \"euler\" or \"second_order\""))?;
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
            return Ok(Self {
                inner: Mutex::new(Inner::Chain(Est::chain(est, DVector::repeat(b, 1.0), n))),
            });
        }
        paper_only(py, beta0, base, None)?;
        let est = CoreEkf::new(model(), lambda0(lam0)?, config).to_py(py)?;
        Ok(Self {
            inner: Mutex::new(Inner::Paper(Est::paper(est))),
        })
    }
    /// Standard deviations of λ̂ (β̂ for a chain) from the filter covariance, (P,).
    #[getter]
    fn parameter_std<'py>(&self, py: Python<'py>) -> Out<'py> {
        each!(&*lock(py, &self.inner)?, c => {
            vec_out(py, c.est.parameter_std().as_slice().to_vec())
        })
    }
    /// Measurement updates skipped because of NaN measurements.
    #[getter]
    fn skipped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(each!(&*lock(py, &self.inner)?, c => c.est.skipped_updates()))
    }
    /// Samples whose update was damped (gain halved) to keep M(q, λ̂) positive definite.
    #[getter]
    fn damped_updates(&self, py: Python<'_>) -> PyResult<usize> {
        Ok(each!(&*lock(py, &self.inner)?, c => c.est.damped_updates()))
    }
    /// The state x = [q (n), q̇ (n), λ (P)] predicted for the next sample, (S,).
    #[getter]
    fn state<'py>(&self, py: Python<'py>) -> Out<'py> {
        each!(&*lock(py, &self.inner)?, c => vec_out(py, c.est.state().as_slice().to_vec()))
    }
    /// The state covariance P, (S, S), in the squares of the state's SI units.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Out<'py> {
        each!(&*lock(py, &self.inner)?, c => {
            let p = c.est.covariance();
            let s = p.nrows();
            to_array(py, p.transpose().as_slice().to_vec(), None, &[s, s])
        })
    }
    /// Replaces the initial covariance P₀ (S, S): symmetric positive definite, squares
    /// of the state units. Also the current P when no sample has been consumed yet.
    fn set_initial_covariance(&self, py: Python<'_>, p0: &Bound<'_, PyAny>) -> PyResult<()> {
        each!(&mut *lock(py, &self.inner)?, c => {
            let p0 = Read::square(p0, "p0", c.est.state().len())?;
            c.est.set_initial_covariance(&p0).to_py(py)
        })
    }
    /// Replaces the process noise Q = diag(variances), (S,), per step, squares of the
    /// state units; each ≥ 0.
    fn set_process_noise(&self, py: Python<'_>, variances: &Bound<'_, PyAny>) -> PyResult<()> {
        each!(&mut *lock(py, &self.inner)?, c => {
            let v = Read::vector(variances, "variances")?;
            c.est.set_process_noise(&v).to_py(py)
        })
    }
    /// Replaces the measurement noise R = diag(positions (n,), velocities (n,)), variances
    /// in m², rad², (m/s)², (rad/s)²; each > 0.
    fn set_measurement_noise(
        &self,
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        velocities: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        each!(&mut *lock(py, &self.inner)?, c => {
            let p = Read::vector(positions, "positions")?;
            let v = Read::vector(velocities, "velocities")?;
            c.est.set_measurement_noise(&p, &v).to_py(py)
        })
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
