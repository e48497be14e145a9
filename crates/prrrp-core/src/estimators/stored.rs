//! The regressors of a data set built once, for the estimators that pass over the same
//! data many times (the epochs of Adaline and of the Hopfield network).
//!
//! Why: an epoch's update costs a few multiply-adds per regressor entry, while building
//! the regressor of a 6-joint chain costs tens of times more; rebuilt in every epoch it
//! was over 90 % of a training run. Stored once, an epoch reads it from memory. The
//! entries are those of the model's own [`LinearModel::regressor_into`], so an estimator
//! fed from here computes the same numbers, to the bit, as one fed the samples.

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, MatrixView, OMatrix, VectorView, U1};

use super::estimator::with_row;
use super::samples::SamplesOf;
use crate::error::{PrrrpError, Result};
use crate::models::LinearModel;

/// Default memory bound of [`StoredRegressors::new`] in `identify`'s gradient methods:
/// 1 GiB, about 400 000 samples of a 6-joint arm with 52 base parameters. Larger data
/// sets build each sample's regressor in every epoch instead (the same numbers, slower).
pub const MAX_STORED_REGRESSOR_BYTES: usize = 1 << 30;

/// The regressor Φ_k (N×P) and the generalised forces τ_k of every sample k of a data
/// set, built once ([`Self::new`]); fed to [`super::AdalineOf::train_stored`] or
/// [`super::HopfieldOf::train_stored`].
#[derive(Debug, Clone)]
pub struct StoredRegressors<N: Dim, P: Dim> {
    n: N,
    p: P,
    /// Φ_k column-major at `k·N·P..(k + 1)·N·P`.
    phi: Vec<f64>,
    /// τ_k at `k·N..(k + 1)·N`.
    tau: Vec<f64>,
}

impl<N: Dim, P: Dim> StoredRegressors<N, P>
where
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// Bytes that `samples` samples of a `joints`×`params` regressor take (with τ), or
    /// `None` when that overflows `usize`.
    pub fn bytes(joints: usize, params: usize, samples: usize) -> Option<usize> {
        joints
            .checked_mul(params.checked_add(1)?)?
            .checked_mul(samples)?
            .checked_mul(std::mem::size_of::<f64>())
    }

    /// The regressors of `model` on every sample of `data`, in at most `max_bytes`
    /// ([`Self::bytes`]).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] (field `max_bytes`) when the data need more than
    /// `max_bytes`, or the allocation fails (pass the samples to the estimator instead);
    /// [`PrrrpError::ShapeMismatch`] or [`PrrrpError::NonFinite`] naming the first bad
    /// sample, and the model's errors, as the estimators' `step`;
    /// [`PrrrpError::Interrupted`] once [`crate::request_stop`] is called (polled every
    /// 1024 samples).
    pub fn new<M: LinearModel<N, P>>(
        model: &M,
        data: &SamplesOf<'_, N>,
        max_bytes: usize,
    ) -> Result<Self> {
        let (n, p) = model.dims();
        let (nv, pv, m) = (n.value(), p.value(), data.len());
        let too_big = |need: f64| PrrrpError::InvalidParameter {
            field: "max_bytes".into(),
            value: need,
            reason: "the stored regressors of these data need more memory than this \
                     (value: bytes needed): train on the samples, which builds each \
                     regressor when it is used",
        };
        let need = Self::bytes(nv, pv, m).ok_or_else(|| too_big(f64::INFINITY))?;
        if need > max_bytes {
            return Err(too_big(need as f64));
        }
        let (mut phi, mut tau) = (Vec::new(), Vec::new());
        phi.try_reserve_exact(nv * pv * m)
            .and_then(|()| tau.try_reserve_exact(nv * m))
            .map_err(|_| too_big(need as f64))?;
        let mut ws = model.workspace();
        let mut buf = OMatrix::<f64, N, P>::zeros_generic(n, p);
        for (k, s) in data.iter().enumerate() {
            if k % 1024 == 0 {
                crate::interrupt::check("storing regressors")?;
            }
            s.check(nv).map_err(|e| with_row(e, k))?;
            model.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut buf)?;
            phi.extend_from_slice(buf.as_slice());
            tau.extend_from_slice(s.tau.as_slice());
        }
        Ok(Self { n, p, phi, tau })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.tau.len() / self.n.value().max(1)
    }

    /// Size N×P of each regressor.
    pub fn shape(&self) -> (usize, usize) {
        (self.n.value(), self.p.value())
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.tau.is_empty()
    }

    /// Regressor Φ_k of sample k (N×P).
    ///
    /// # Panics
    /// If `k >= self.len()` (an index bug in the caller, not bad data).
    #[inline]
    pub fn regressor(&self, k: usize) -> MatrixView<'_, f64, N, P> {
        MatrixView::from_slice_generic(self.regressor_slice(k), self.n, self.p)
    }

    /// Regressor Φ_k of sample k, column-major.
    ///
    /// # Panics
    /// If `k >= self.len()`.
    #[inline]
    pub fn regressor_slice(&self, k: usize) -> &[f64] {
        let size = self.n.value() * self.p.value();
        &self.phi[k * size..(k + 1) * size]
    }

    /// Generalised forces τ_k of sample k (N).
    ///
    /// # Panics
    /// If `k >= self.len()`.
    #[inline]
    pub fn tau(&self, k: usize) -> VectorView<'_, f64, N> {
        let n = self.n.value();
        VectorView::from_slice_generic(&self.tau[k * n..(k + 1) * n], self.n, U1)
    }
}
