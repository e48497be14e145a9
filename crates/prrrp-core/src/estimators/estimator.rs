//! The common shape of the online estimators.

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector};

use super::rls::check_lambda0;
use super::samples::{SampleOf, SamplesOf};
use super::stored::StoredRegressors;
use crate::error::{PrrrpError, Result};
use crate::models::LinearModel;

/// An online estimator of the P parameters of an N-joint model.
///
/// N and P are nalgebra dimensions: `Const<5>, Const<8>` (alias `U5, U8`) for the PRRRP
/// arm, [`nalgebra::Dyn`] for models sized at run time. Implemented by
/// [`super::RlsOf`], [`super::AdalineOf`], [`super::HopfieldOf`] and [`super::EkfOf`] for
/// both. `step` never allocates (proven by `tests/alloc_estimators.rs`).
pub trait Estimator<N: Dim, P: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    /// Consumes one sample and returns the updated estimate λ̂.
    ///
    /// # Errors
    /// A typed [`PrrrpError`] for bad input (NaN, out-of-range values) or numerical failure
    /// (divergence, a covariance that is no longer positive definite); see each
    /// implementation. After an error the estimator should be [`reset`](Self::reset).
    fn step(&mut self, sample: SampleOf<'_, N>) -> Result<&OVector<f64, P>>;

    /// The current estimate λ̂.
    fn estimate(&self) -> &OVector<f64, P>;

    /// Returns to the state right after construction (initial λ̂, covariances, counters).
    fn reset(&mut self);

    /// Runs [`step`](Self::step) over every sample of `data` in order and returns the final
    /// estimate. Does not reset first, so successive calls continue (e.g. epochs).
    ///
    /// # Errors
    /// The first error of `step`; a [`PrrrpError::NonFinite`] names the sample index.
    /// A non-finite estimate is [`PrrrpError::NonFinite`]; a raised stop flag
    /// ([`crate::request_stop`]) is [`PrrrpError::Interrupted`].
    fn run(&mut self, data: &SamplesOf<'_, N>) -> Result<OVector<f64, P>> {
        for (k, sample) in data.iter().enumerate() {
            if k % CHECK_EVERY == 0 {
                crate::interrupt::check("estimator run")?;
            }
            self.step(sample).map_err(|e| with_row(e, k))?;
        }
        check_estimate(self.estimate())?;
        Ok(self.estimate().clone())
    }
}

/// Samples between two polls of the stop flag in the batch loops.
const CHECK_EVERY: usize = 1024;

/// Largest `epochs` of one [`super::Adaline::train`] / [`super::Hopfield::train`] call:
/// [`crate::MAX_SAMPLES`] (10 million), since the report keeps one entry per epoch. Train in
/// several calls (each continues from the current weights) for more.
pub(crate) const MAX_EPOCHS: usize = crate::interrupt::MAX_SAMPLES;

/// [`PrrrpError::NonFinite`] for an estimate with NaN or ∞ (an overflow the estimator's own
/// checks did not catch), so that no caller ever receives a non-finite λ̂.
pub(crate) fn check_estimate<P: Dim>(lambda: &OVector<f64, P>) -> Result<()>
where
    DefaultAllocator: Allocator<P>,
{
    if lambda.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(PrrrpError::NonFinite {
            what: "estimate λ̂ (the data's magnitudes overflow f64 arithmetic: remove or \
                   rescale rows with huge values)"
                .into(),
            row: None,
        })
    }
}

/// What the inverse-model estimators ([`super::RlsOf`], [`super::AdalineOf`],
/// [`super::HopfieldOf`]) keep alike: the model and its workspace, λ₀, the estimate λ̂ and
/// the buffer of one sample's regressor Φ (N×P), all sized at construction.
#[derive(Debug, Clone)]
pub(crate) struct ModelFit<M, N: Dim, P: Dim>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    pub(crate) model: M,
    pub(crate) ws: M::Workspace,
    pub(crate) lambda0: OVector<f64, P>,
    pub(crate) lambda: OVector<f64, P>,
    pub(crate) phi: OMatrix<f64, N, P>,
}

impl<M, N: Dim, P: Dim> ModelFit<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// λ̂ = λ₀ for `model`.
    ///
    /// # Errors
    /// As [`check_lambda0`].
    pub(crate) fn new(model: M, lambda0: OVector<f64, P>) -> Result<Self> {
        let (n, p) = model.dims();
        check_lambda0(&lambda0, n.value(), p.value())?;
        Ok(Self {
            ws: model.workspace(),
            model,
            lambda: lambda0.clone(),
            lambda0,
            phi: OMatrix::zeros_generic(n, p),
        })
    }

    /// Φ(q, q̇, q̈) of `sample` into `phi`.
    #[inline(always)]
    pub(crate) fn load_regressor(&mut self, sample: &SampleOf<'_, N>) -> Result<()> {
        self.model
            .regressor_into(&mut self.ws, sample.q, sample.qd, sample.qdd, &mut self.phi)
    }

    /// λ̂ ← λ₀.
    pub(crate) fn reset(&mut self) {
        self.lambda.copy_from(&self.lambda0);
    }
}

/// Adds the sample index to an error raised by a `step`.
pub(crate) fn with_row(e: PrrrpError, k: usize) -> PrrrpError {
    match e {
        PrrrpError::NonFinite { what, row: None } => PrrrpError::NonFinite { what, row: Some(k) },
        other => other,
    }
}

/// Progress of a multi-epoch training run ([`super::Adaline::train`],
/// [`super::Hopfield::train`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrainingReport {
    /// A-priori RMS equation error τ_i − Φ_i·λ̂ of each epoch, in the units of τ (mixed N
    /// and N·m for PRRRP), computed with the weights before each update.
    pub rms_error: Vec<f64>,
}

/// The epoch loop shared by [`super::Adaline::train`] and [`super::Hopfield::train`]
/// (and their `train_stored`): `step(est, k)` consumes sample k of `len`, and `totals`
/// gives the estimator's running sum of squared a-priori equation errors and its equation
/// count, which are cleared before each epoch and read after it.
///
/// `epochs` above `MAX_EPOCHS` (1e7) is [`PrrrpError::InvalidParameter`] (before anything is
/// allocated); the stop flag is polled every epoch and every [`CHECK_EVERY`] samples
/// ([`PrrrpError::Interrupted`]); a non-finite estimate after an epoch is
/// [`PrrrpError::NonFinite`].
pub(crate) fn train_epochs<E, N: Dim, P: Dim>(
    est: &mut E,
    len: usize,
    epochs: usize,
    totals: fn(&mut E) -> (&mut f64, &mut usize),
    mut step: impl FnMut(&mut E, usize) -> Result<()>,
) -> Result<TrainingReport>
where
    E: Estimator<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    if epochs > MAX_EPOCHS {
        return Err(PrrrpError::InvalidParameter {
            field: "epochs".into(),
            value: epochs as f64,
            reason: "exceeds MAX_EPOCHS (1e7) passes per call: train in several calls, each \
                     continues from the current weights",
        });
    }
    // Grown as the epochs run: an interrupted call never holds a huge empty buffer.
    let mut rms_error = Vec::with_capacity(epochs.min(CHECK_EVERY));
    for _ in 0..epochs {
        crate::interrupt::check("training")?;
        let (sse, equations) = totals(est);
        (*sse, *equations) = (0.0, 0);
        for k in 0..len {
            if k % CHECK_EVERY == CHECK_EVERY - 1 {
                crate::interrupt::check("training")?;
            }
            step(est, k).map_err(|e| with_row(e, k))?;
        }
        check_estimate(est.estimate())?;
        let (sse, equations) = totals(est);
        rms_error.push((*sse / (*equations).max(1) as f64).sqrt());
    }
    Ok(TrainingReport { rms_error })
}

/// [`PrrrpError::ShapeMismatch`] unless the stored regressors are `shape` (N×P, the
/// estimator's).
pub(crate) fn check_stored<N: Dim, P: Dim>(
    data: &StoredRegressors<N, P>,
    shape: (usize, usize),
) -> Result<()>
where
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    let got = data.shape();
    if got == shape {
        return Ok(());
    }
    Err(PrrrpError::ShapeMismatch {
        what: "stored regressors".into(),
        expected: format!("{}×{} (the estimator's model)", shape.0, shape.1),
        got: format!("{}×{}", got.0, got.1),
    })
}

/// [`PrrrpError::ShapeMismatch`] for a model with no joint (`n` = 0) or no parameter
/// (`p` = 0), which no estimator can fit.
pub(crate) fn check_model_size(n: usize, p: usize) -> Result<()> {
    if n == 0 || p == 0 {
        let got = format!("{n} joints, {p} parameters");
        return Err(PrrrpError::shape(
            "model",
            "at least one joint and one parameter",
            got,
        ));
    }
    Ok(())
}
