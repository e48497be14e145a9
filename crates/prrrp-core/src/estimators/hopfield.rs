//! Hopfield neural network in Abe's formulation (eqs. 12–20) as an online estimator.
//!
//! The network has one neuron per parameter; its state S(t) is the estimate λ̂(t), the
//! weights are W = ΦᵀΦ and the bias I = −Φᵀτ, and with α = c the dynamics reduce to
//! eq. 19:
//! ```text
//! dλ̂/dt = 1/(c·β) · D_c(λ̂) · Φᵀ(τ − Φ·λ̂),    D_c(λ̂) = diag(c² − λ̂_i²)
//! ```
//! λ̂ stays inside the box (−c, c) (assumption (d) of the paper: every |λ_i| < c), and no
//! matrix is inverted. Each sample is integrated over the sample period `dt` by explicit
//! Euler sub-steps h. Linearised, one sub-step multiplies the error by I − h·K·ΦᵀΦ with
//! K = D_c/(c·β) ≤ (c/β)·I, so it is stable when h·(c/β)·λmax(ΦᵀΦ) < 2; λmax is bounded by
//! ‖Φ‖_F² (a trace, 40 multiply-adds for a 5×8 Φ), and the sample is split into as many
//! sub-steps as that bound requires.

use nalgebra::SVector;

use super::estimator::{train_epochs, Estimator, TrainingReport};
use super::samples::{Sample, Samples};
use crate::error::{PrrrpError, Result};
use crate::model::LinearDynamics;

/// Settings of [`Hopfield`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HopfieldConfig {
    /// Bound c = α of the activation (units of λ, default `10.0`): estimates live in
    /// (−c, c), so c must exceed every |λ_i| (for PRRRP the largest is λ1 ≈ 4.3 kg). The
    /// factor c² − λ̂_i² slows a parameter near the bound: keep c a few times max |λ_i|.
    pub bound: f64,
    /// Slope parameter β of the activation S = c·tanh(u/β) (units of λ, default `100.0`).
    /// The gain of eq. 19 near λ̂ = 0 is c/β per second per unit of Φ²; smaller β learns
    /// faster but needs more sub-steps per sample.
    pub beta: f64,
    /// Sample period over which each sample is integrated, s (default `0.02`, the paper's
    /// sampling time).
    pub dt: f64,
    /// Largest allowed h·(c/β)·‖Φ‖_F² of one Euler sub-step (dimensionless, default
    /// `1.0`, in (0, 2)): below 1 the error decays without oscillation in every direction.
    pub stability_limit: f64,
    /// Most sub-steps one sample may take (default `64`); a sample that needs more fails
    /// with [`PrrrpError::InvalidParameter`] (raise β or this limit).
    pub max_substeps: u32,
}

impl Default for HopfieldConfig {
    fn default() -> Self {
        Self {
            bound: 10.0,
            beta: 100.0,
            dt: 0.02,
            stability_limit: 1.0,
            max_substeps: 64,
        }
    }
}

/// Hopfield-network estimator (Abe formulation, eq. 19).
#[derive(Debug, Clone)]
pub struct Hopfield<M, const N: usize, const P: usize> {
    model: M,
    config: HopfieldConfig,
    lambda0: SVector<f64, P>,
    lambda: SVector<f64, P>,
    /// Largest |λ̂_i| allowed: c shrunk by a relative 1e-9, so that D_c never reaches 0 and
    /// a clamped parameter can still move back.
    inner: f64,
    /// (c/β)·dt: the gain bound per sample per unit of ‖Φ‖_F².
    gain_dt: f64,
    sse: f64,
    equations: usize,
    samples: usize,
    substeps: u64,
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize> Hopfield<M, N, P> {
    /// A network whose state starts at λ₀ (zeros are fine: no prior is needed).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite c, β or dt, a
    /// stability limit outside (0, 2), zero sub-steps, or a λ₀ outside (−c, c).
    pub fn new(model: M, lambda0: SVector<f64, P>, config: HopfieldConfig) -> Result<Self> {
        let bad = |field: String, value: f64, reason: &'static str| {
            Err(PrrrpError::InvalidParameter {
                field,
                value,
                reason,
            })
        };
        let c = &config;
        for (name, v) in [("bound", c.bound), ("beta", c.beta), ("dt", c.dt)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name.into(), v, "must be finite and > 0");
            }
        }
        if !(c.stability_limit > 0.0 && c.stability_limit < 2.0) {
            return bad(
                "stability_limit".into(),
                c.stability_limit,
                "must be in (0, 2): explicit Euler is unstable beyond 2",
            );
        }
        if c.max_substeps == 0 {
            return bad("max_substeps".into(), 0.0, "must be at least 1");
        }
        for (i, &l) in lambda0.iter().enumerate() {
            if !(l.is_finite() && l.abs() < c.bound) {
                return bad(
                    format!("lambda0[{i}]"),
                    l,
                    "must be finite and inside (−bound, bound)",
                );
            }
        }
        Ok(Self {
            model,
            config,
            lambda0,
            lambda: lambda0,
            inner: c.bound * (1.0 - 1e-9),
            gain_dt: c.bound / c.beta * c.dt,
            sse: 0.0,
            equations: 0,
            samples: 0,
            substeps: 0,
        })
    }

    /// Trains for `epochs` passes over `data` (continuing from the current state) and
    /// reports the a-priori RMS equation error of each epoch.
    ///
    /// # Errors
    /// As [`Estimator::step`], with the sample index in [`PrrrpError::NonFinite`].
    pub fn train(&mut self, data: &Samples<'_, N>, epochs: usize) -> Result<TrainingReport> {
        train_epochs(self, data, epochs, |e| (&mut e.sse, &mut e.equations))
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Total Euler sub-steps taken since construction or the last reset.
    pub fn substeps(&self) -> u64 {
        self.substeps
    }
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize> Estimator<N, P>
    for Hopfield<M, N, P>
{
    /// Integrates eq. 19 over one sample period with Φ and τ held.
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] for NaN/∞ in the sample; [`PrrrpError::InvalidParameter`]
    /// (field `beta`) if the sample needs more than `max_substeps` sub-steps for a stable
    /// integration.
    fn step(&mut self, sample: Sample<'_, N>) -> Result<&SVector<f64, P>> {
        sample.check_finite()?;
        let phi = self.model.regressor(sample.q, sample.qd, sample.qdd);
        let bound = self.gain_dt * phi.norm_squared();
        let cfg = &self.config;
        let n = if bound <= cfg.stability_limit {
            1
        } else {
            let n = (bound / cfg.stability_limit).ceil();
            if n.is_nan() || n > f64::from(cfg.max_substeps) {
                return Err(PrrrpError::InvalidParameter {
                    field: "beta".into(),
                    value: cfg.beta,
                    reason: "this sample needs more than max_substeps Euler sub-steps for a \
                             stable integration: raise beta (slower learning) or max_substeps",
                });
            }
            n as u32
        };
        let k = cfg.dt / f64::from(n) / (cfg.bound * cfg.beta);
        let c2 = cfg.bound * cfg.bound;
        let inner = self.inner;
        for s in 0..n {
            let r = sample.tau - phi * self.lambda;
            if s == 0 {
                self.sse += r.norm_squared();
            }
            let g = phi.tr_mul(&r);
            for i in 0..P {
                let l = self.lambda[i];
                let next = l + k * (c2 - l * l) * g[i];
                self.lambda[i] = next.clamp(-inner, inner);
            }
        }
        self.equations += N;
        self.substeps += u64::from(n);
        self.samples += 1;
        Ok(&self.lambda)
    }

    fn estimate(&self) -> &SVector<f64, P> {
        &self.lambda
    }

    fn reset(&mut self) {
        self.lambda = self.lambda0;
        self.sse = 0.0;
        self.equations = 0;
        self.samples = 0;
        self.substeps = 0;
    }
}
