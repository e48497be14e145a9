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
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OMatrix, OVector};

use super::estimator::{train_epochs, Estimator, TrainingReport};
use super::rls::check_lambda0;
use super::samples::{SampleOf, SamplesOf};
use crate::error::{PrrrpError, Result};
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
    model: M,
    ws: M::Workspace,
    config: AdalineConfig,
    lambda0: OVector<f64, P>,
    lambda: OVector<f64, P>,
    phi: OMatrix<f64, N, P>,
    tau_scale: f64,
    sse: f64,
    equations: usize,
    samples: usize,
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
        let bad = |field: &str, value: f64, reason: &'static str| {
            Err(PrrrpError::InvalidParameter {
                field: field.into(),
                value,
                reason,
            })
        };
        let c = &config;
        if !(c.learning_rate.is_finite() && c.learning_rate > 0.0) {
            return bad("learning_rate", c.learning_rate, "must be finite and > 0");
        }
        if !(c.step_size > 0.0 && c.step_size < 2.0) {
            return bad("step_size", c.step_size, "must be in (0, 2) for stability");
        }
        if !(c.epsilon.is_finite() && c.epsilon >= 0.0) {
            return bad("epsilon", c.epsilon, "must be finite and >= 0");
        }
        if c.divergence_ratio.is_nan() || c.divergence_ratio <= 1.0 {
            return bad("divergence_ratio", c.divergence_ratio, "must be > 1");
        }
        let (n, p) = model.dims();
        check_lambda0(&lambda0, n.value(), p.value())?;
        Ok(Self {
            ws: model.workspace(),
            model,
            config,
            lambda: lambda0.clone(),
            lambda0,
            phi: OMatrix::zeros_generic(n, p),
            tau_scale: 0.0,
            sse: 0.0,
            equations: 0,
            samples: 0,
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
        train_epochs(self, data, epochs, |e| (&mut e.sse, &mut e.equations))
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
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
        let (n, np) = self.phi.shape();
        sample.check(n)?;
        self.model
            .regressor_into(&mut self.ws, sample.q, sample.qd, sample.qdd, &mut self.phi)?;
        let c = self.config;
        let phi = &self.phi;
        for i in 0..n {
            let tau = sample.tau[i];
            self.tau_scale = self.tau_scale.max(tau.abs());
            let (mut pred, mut norm2) = (0.0, 0.0);
            for j in 0..np {
                let x = phi[(i, j)];
                pred += x * self.lambda[j];
                norm2 += x * x;
            }
            let delta = tau - pred;
            self.sse += delta * delta;
            let gain = match c.rule {
                AdalineRule::Delta => c.learning_rate,
                AdalineRule::Normalised => c.step_size / (c.epsilon + norm2),
            };
            if gain.is_finite() {
                let g = gain * delta;
                for j in 0..np {
                    self.lambda[j] += g * phi[(i, j)];
                }
            }
            if !(delta.abs() <= c.divergence_ratio * self.tau_scale
                || delta.abs() <= f64::MIN_POSITIVE)
            {
                return Err(PrrrpError::Diverged {
                    what: "Adaline",
                    at: self.samples,
                    hint: "the equation error grows: lower the learning rate \
                           (the delta rule needs γ·‖Φ_i‖² < 2) or use the normalised rule",
                });
            }
        }
        self.equations += n;
        if !self.lambda.iter().all(|x| x.is_finite()) {
            if c.rule == AdalineRule::Normalised {
                // The normalised rule cannot diverge (μ < 2): the sample's values overflowed.
                return Err(PrrrpError::NonFinite {
                    what: "Adaline weights (the sample's magnitudes overflow f64 arithmetic: \
                           remove or rescale rows with huge values)"
                        .into(),
                    row: None,
                });
            }
            return Err(PrrrpError::Diverged {
                what: "Adaline",
                at: self.samples,
                hint: "a weight became non-finite: lower the learning rate",
            });
        }
        self.samples += 1;
        Ok(&self.lambda)
    }

    fn estimate(&self) -> &OVector<f64, P> {
        &self.lambda
    }

    fn reset(&mut self) {
        self.lambda.copy_from(&self.lambda0);
        self.tau_scale = 0.0;
        self.sse = 0.0;
        self.equations = 0;
        self.samples = 0;
    }
}
