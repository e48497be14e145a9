//! Adaline neural networks (eqs. 5–11, 40, Fig. 4) trained by the delta rule, or by its
//! normalised form (normalised LMS), which needs no learning rate tuned to the robot.
//!
//! Each joint equation τ_i = Φ_i·λ is one linear neuron (eq. 5 with θ = 0): its inputs
//! are the entries of row i of the regressor, its weights are λ, its desired output is
//! τ_i. Rows whose regressor entries touch disjoint sets of parameters are independent
//! networks. For the PRRRP arm these are exactly the two networks of eq. 40 / Fig. 4:
//! network 1 (outputs F1 and F5, weights λ1, λ8) and network 2 (outputs τ2, τ3, τ4,
//! weights λ2..λ7): a row's update only changes the weights its inputs touch, because
//! the delta rule moves weight j in proportion to input j (eq. 11), which is zero for
//! every parameter outside its network.

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, MatrixView, OVector};

use super::estimator::{check_stored, train_epochs, Estimator, ModelFit, TrainingReport};
use super::samples::{SampleOf, SamplesOf};
use super::stored::StoredRegressors;
use crate::error::{invalid, PrrrpError, Result};
use crate::models::LinearModel;

/// Adaline for a compile-time-size model (e.g. the PRRRP arm).
pub type Adaline<M, const N: usize, const P: usize> = AdalineOf<M, Const<N>, Const<P>>;
/// Adaline for a run-time-size model (e.g. [`crate::DynChainBaseModel`]).
pub type DynAdaline<M> = AdalineOf<M, Dyn, Dyn>;

/// Weight update rule of [`Adaline`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AdalineRule {
    /// The delta rule of eq. 11: Δλ = γ·δ·x with δ = τ_i − x·λ. Stable only for
    /// γ·‖x‖² < 2, so γ depends on the robot's scale.
    Delta,
    /// Normalised LMS: Δλ = μ·δ·x/(ε + ‖x‖²), stable for any robot when 0 < μ < 2. With
    /// μ = 1 each update makes the current equation exact (the Kaczmarz projection).
    #[default]
    Normalised,
}

/// Settings of [`Adaline`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdalineConfig {
    /// Update rule (default [`AdalineRule::Normalised`]).
    pub rule: AdalineRule,
    /// Learning rate γ of the delta rule (units of 1/x², i.e. λ per (τ·x); default
    /// `5e-3`, sized for the PRRRP arm, whose force rows have ‖x‖² ≈ 2g² ≈ 190, so that
    /// γ·‖x‖² ≈ 1 < 2). Ignored by the normalised rule.
    pub learning_rate: f64,
    /// Step size μ of the normalised rule (dimensionless, in (0, 2), default `1.0`).
    /// Smaller values average noise better and converge more slowly.
    pub step_size: f64,
    /// Regulariser ε added to ‖x‖² by the normalised rule (units of x², default `1e-9`),
    /// so that an all-zero input row does nothing instead of dividing by zero.
    pub epsilon: f64,
    /// Divergence threshold (dimensionless, default `1e6`): the step fails with
    /// [`PrrrpError::Diverged`] when an equation error exceeds this many times the largest
    /// |τ_i| seen so far, or a weight becomes non-finite.
    pub divergence_ratio: f64,
}

impl Default for AdalineConfig {
    fn default() -> Self {
        Self {
            rule: AdalineRule::Normalised,
            learning_rate: 5e-3,
            step_size: 1.0,
            epsilon: 1e-9,
            divergence_ratio: 1e6,
        }
    }
}

/// Adaline networks whose weights are the parameters λ. One implementation for both size
/// worlds (see [`Adaline`], [`DynAdaline`]); all buffers are sized at construction.
#[derive(Debug, Clone)]
pub struct AdalineOf<M, N: Dim, P: Dim>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    fit: ModelFit<M, N, P>,
    config: AdalineConfig,
    progress: Progress,
}

impl<M, N: Dim, P: Dim> AdalineOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// Networks with initial weights λ₀ (zeros are fine: Adaline needs no prior).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive learning rate, a step size
    /// outside (0, 2), a negative ε, a divergence ratio ≤ 1 or a non-finite λ₀;
    /// [`PrrrpError::ShapeMismatch`] if λ₀ does not have one entry per model parameter.
    pub fn new(model: M, lambda0: OVector<f64, P>, config: AdalineConfig) -> Result<Self> {
        let c = &config;
        if !(c.learning_rate.is_finite() && c.learning_rate > 0.0) {
            return Err(invalid(
                "learning_rate",
                c.learning_rate,
                "must be finite and > 0",
            ));
        }
        if !(c.step_size > 0.0 && c.step_size < 2.0) {
            return Err(invalid(
                "step_size",
                c.step_size,
                "must be in (0, 2) for stability",
            ));
        }
        if !(c.epsilon.is_finite() && c.epsilon >= 0.0) {
            return Err(invalid("epsilon", c.epsilon, "must be finite and >= 0"));
        }
        if c.divergence_ratio.is_nan() || c.divergence_ratio <= 1.0 {
            return Err(invalid(
                "divergence_ratio",
                c.divergence_ratio,
                "must be > 1",
            ));
        }
        Ok(Self {
            fit: ModelFit::new(model, lambda0)?,
            config,
            progress: Progress::default(),
        })
    }

    /// Trains for `epochs` passes over `data` (continuing from the current weights) and
    /// reports the a-priori RMS equation error of each epoch.
    ///
    /// # Errors
    /// As [`Estimator::step`], with the sample index in [`PrrrpError::NonFinite`];
    /// [`PrrrpError::InvalidParameter`] for more than 10⁷ epochs ([`crate::MAX_SAMPLES`]; train
    /// in several calls instead); [`PrrrpError::Interrupted`] once [`crate::request_stop`]
    /// is called (polled every epoch and every 1024 samples).
    pub fn train(&mut self, data: &SamplesOf<'_, N>, epochs: usize) -> Result<TrainingReport> {
        train_epochs(self, data.len(), epochs, totals, |e, k| {
            e.step(data.sample(k)).map(|_| ())
        })
    }

    /// [`Self::train`] on regressors built once ([`StoredRegressors::new`] with this
    /// estimator's model on the same data): the same weights, errors and report, to the
    /// bit, without building each sample's regressor in every epoch.
    ///
    /// # Errors
    /// As [`Self::train`]; [`PrrrpError::ShapeMismatch`] if the regressors are not N×P.
    pub fn train_stored(
        &mut self,
        data: &StoredRegressors<N, P>,
        epochs: usize,
    ) -> Result<TrainingReport> {
        check_stored(data, self.fit.phi.shape())?;
        train_epochs(self, data.len(), epochs, totals, |e, k| {
            let tau = data.tau(k);
            learn(
                &e.config,
                &mut e.fit.lambda,
                &mut e.progress,
                data.regressor(k),
                tau.as_slice(),
            )
        })
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.progress.samples
    }
}

impl<M, N: Dim, P: Dim> Estimator<N, P> for AdalineOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// Presents the N equations of the sample one after the other (pattern by pattern).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a sample whose vectors do not have one entry per
    /// joint; [`PrrrpError::NonFinite`] for NaN/∞ in the sample, or for weights that
    /// overflow under the normalised rule (data of huge magnitude, e.g. τ = 1e308);
    /// [`PrrrpError::Diverged`] when an error grows past the divergence threshold or a
    /// delta-rule weight becomes non-finite (lower the learning rate, or use the
    /// normalised rule).
    fn step(&mut self, sample: SampleOf<'_, N>) -> Result<&OVector<f64, P>> {
        let (n, p) = self.fit.phi.shape_generic();
        sample.check(n.value())?;
        self.fit.load_regressor(&sample)?;
        let phi = MatrixView::from_slice_generic(self.fit.phi.as_slice(), n, p);
        learn(
            &self.config,
            &mut self.fit.lambda,
            &mut self.progress,
            phi,
            sample.tau.as_slice(),
        )?;
        Ok(&self.fit.lambda)
    }

    fn estimate(&self) -> &OVector<f64, P> {
        &self.fit.lambda
    }

    fn reset(&mut self) {
        self.fit.reset();
        self.progress = Progress::default();
    }
}

/// The running error totals of an Adaline, for [`train_epochs`].
fn totals<M, N: Dim, P: Dim>(e: &mut AdalineOf<M, N, P>) -> (&mut f64, &mut usize)
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    (&mut e.progress.sse, &mut e.progress.equations)
}

/// Counters of [`AdalineOf`] that the update advances.
#[derive(Debug, Clone, Copy, Default)]
struct Progress {
    /// Largest |τ_i| seen (the divergence test's scale).
    tau_scale: f64,
    /// Sum of squared a-priori equation errors, and their count, since the last clear.
    sse: f64,
    equations: usize,
    /// Samples consumed.
    samples: usize,
}

/// Adaline's [`PrrrpError::Diverged`] at sample `at`.
fn diverged(at: usize, hint: &'static str) -> PrrrpError {
    PrrrpError::Diverged {
        what: "Adaline",
        at,
        hint,
    }
}

/// The delta-rule update of one sample given its regressor Φ (N×P) and forces τ (N):
/// the N equations one after the other (pattern by pattern). Both [`AdalineOf::step`]
/// and [`AdalineOf::train_stored`] run it, so that they compute the same numbers.
#[inline(always)]
fn learn<N: Dim, P: Dim>(
    c: &AdalineConfig,
    lambda: &mut OVector<f64, P>,
    st: &mut Progress,
    phi: MatrixView<'_, f64, N, P>,
    tau: &[f64],
) -> Result<()>
where
    DefaultAllocator: Allocator<P>,
{
    let (n, np) = phi.shape();
    for (i, &tau) in tau.iter().enumerate().take(n) {
        st.tau_scale = st.tau_scale.max(tau.abs());
        let (mut pred, mut norm2) = (0.0, 0.0);
        for j in 0..np {
            let x = phi[(i, j)];
            pred += x * lambda[j];
            norm2 += x * x;
        }
        let delta = tau - pred;
        st.sse += delta * delta;
        let gain = match c.rule {
            AdalineRule::Delta => c.learning_rate,
            AdalineRule::Normalised => c.step_size / (c.epsilon + norm2),
        };
        if gain.is_finite() {
            let g = gain * delta;
            for j in 0..np {
                lambda[j] += g * phi[(i, j)];
            }
        }
        if !(delta.abs() <= c.divergence_ratio * st.tau_scale || delta.abs() <= f64::MIN_POSITIVE) {
            return Err(diverged(
                st.samples,
                "the equation error grows: lower the learning rate \
                 (the delta rule needs γ·‖Φ_i‖² < 2) or use the normalised rule",
            ));
        }
    }
    st.equations += n;
    if !lambda.iter().all(|x| x.is_finite()) {
        if c.rule == AdalineRule::Normalised {
            // The normalised rule cannot diverge (μ < 2): the sample's values overflowed.
            return Err(PrrrpError::NonFinite {
                what: "Adaline weights (the sample's magnitudes overflow f64 arithmetic: \
                       remove or rescale rows with huge values)"
                    .into(),
                row: None,
            });
        }
        let hint = "a weight became non-finite: lower the learning rate";
        return Err(diverged(st.samples, hint));
    }
    st.samples += 1;
    Ok(())
}
