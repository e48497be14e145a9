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

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, MatrixView, OVector, U1};

use super::estimator::{check_stored, train_epochs, Estimator, ModelFit, TrainingReport};
use super::samples::{SampleOf, SamplesOf};
use super::stored::StoredRegressors;
use crate::error::{invalid, PrrrpError, Result};
use crate::models::LinearModel;

/// Hopfield network for a compile-time-size model (e.g. the PRRRP arm).
pub type Hopfield<M, const N: usize, const P: usize> = HopfieldOf<M, Const<N>, Const<P>>;
/// Hopfield network for a run-time-size model (e.g. [`crate::DynChainBaseModel`]).
pub type DynHopfield<M> = HopfieldOf<M, Dyn, Dyn>;

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
    /// Most sub-steps one sample may take (default `64`, at most [`MAX_HOPFIELD_SUBSTEPS`]);
    /// a sample that needs more fails with [`PrrrpError::InvalidParameter`] (raise β or
    /// this limit).
    pub max_substeps: u32,
}

/// Largest [`HopfieldConfig::max_substeps`]: 10⁶ Euler sub-steps per sample, about 0.1 s
/// of one sample of a 5×8 model, so a training of a few thousand samples still ends in
/// minutes. A sample that needs more has a step so long (dt) or a gain so high (c/β) that
/// Euler is the wrong tool; `u32::MAX` let one sample run for hours.
pub const MAX_HOPFIELD_SUBSTEPS: u32 = 1_000_000;

/// The sub-steps of one sample between polls of the stop flag: a sample may take
/// [`MAX_HOPFIELD_SUBSTEPS`], and training polls only every 1024 samples.
const SUBSTEPS_PER_CHECK: u32 = 1 << 16;

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

/// Hopfield-network estimator (Abe formulation, eq. 19). One implementation for both
/// size worlds (see [`Hopfield`], [`DynHopfield`]); all buffers are sized at
/// construction.
#[derive(Debug, Clone)]
pub struct HopfieldOf<M, N: Dim, P: Dim>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    fit: ModelFit<M, N, P>,
    config: HopfieldConfig,
    /// Residual τ − Φ·λ̂ of the current sub-step.
    r: OVector<f64, N>,
    /// Φᵀ·r.
    g: OVector<f64, P>,
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

impl<M, N: Dim, P: Dim> HopfieldOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// A network whose state starts at λ₀ (zeros are fine: no prior is needed).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite c, β or dt, a
    /// stability limit outside (0, 2), zero sub-steps or more than
    /// [`MAX_HOPFIELD_SUBSTEPS`], or a λ₀ outside (−c, c);
    /// [`PrrrpError::ShapeMismatch`] if λ₀ does not have one entry per model parameter.
    pub fn new(model: M, lambda0: OVector<f64, P>, config: HopfieldConfig) -> Result<Self> {
        let c = &config;
        for (name, v) in [("bound", c.bound), ("beta", c.beta), ("dt", c.dt)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(name, v, "must be finite and > 0"));
            }
        }
        if !(c.stability_limit > 0.0 && c.stability_limit < 2.0) {
            return Err(invalid(
                "stability_limit",
                c.stability_limit,
                "must be in (0, 2): explicit Euler is unstable beyond 2",
            ));
        }
        if c.max_substeps == 0 {
            return Err(invalid("max_substeps", 0.0, "must be at least 1"));
        }
        if c.max_substeps > MAX_HOPFIELD_SUBSTEPS {
            return Err(invalid(
                "max_substeps",
                f64::from(c.max_substeps),
                "more than MAX_HOPFIELD_SUBSTEPS (1e6) Euler sub-steps per sample: shorten \
                 dt or raise beta instead",
            ));
        }
        let fit = ModelFit::new(model, lambda0)?;
        for (i, &l) in fit.lambda0.iter().enumerate() {
            if !(l.is_finite() && l.abs() < c.bound) {
                return Err(invalid(
                    format!("lambda0[{i}]"),
                    l,
                    "must be finite and inside (−bound, bound)",
                ));
            }
        }
        let (n, p) = fit.phi.shape_generic();
        Ok(Self {
            fit,
            config,
            r: OVector::zeros_generic(n, U1),
            g: OVector::zeros_generic(p, U1),
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
    pub fn train(&mut self, data: &SamplesOf<'_, N>, epochs: usize) -> Result<TrainingReport> {
        train_epochs(self, data.len(), epochs, totals, |e, k| {
            e.step(data.sample(k)).map(|_| ())
        })
    }

    /// [`Self::train`] on regressors built once ([`StoredRegressors::new`] with this
    /// network's model on the same data): the same trajectory, errors and report, to the
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
        let shape = self.fit.phi.shape_generic();
        train_epochs(self, data.len(), epochs, totals, |e, k| {
            let net = Net {
                cfg: &e.config,
                gain_dt: e.gain_dt,
                inner: e.inner,
            };
            let tau = data.tau(k);
            let n = net.integrate(
                &mut e.fit.lambda,
                &mut e.r,
                &mut e.g,
                &mut e.sse,
                data.regressor_slice(k),
                shape,
                tau.as_slice(),
            )?;
            e.count(n);
            Ok(())
        })
    }

    /// Advances the counters after a sample integrated in `n` sub-steps.
    #[inline(always)]
    fn count(&mut self, n: u32) {
        self.equations += self.fit.phi.nrows();
        self.substeps += u64::from(n);
        self.samples += 1;
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

impl<M, N: Dim, P: Dim> Estimator<N, P> for HopfieldOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// Integrates eq. 19 over one sample period with Φ and τ held.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a sample whose vectors do not have one entry per
    /// joint; [`PrrrpError::NonFinite`] for NaN/∞ in the sample; [`PrrrpError::InvalidParameter`]
    /// (field `beta`) if the sample needs more than `max_substeps` sub-steps for a stable
    /// integration; [`PrrrpError::Interrupted`] on a stop request during a sample of many
    /// sub-steps.
    fn step(&mut self, sample: SampleOf<'_, N>) -> Result<&OVector<f64, P>> {
        sample.check(self.fit.phi.nrows())?;
        let Self {
            fit:
                ModelFit {
                    model,
                    ws,
                    lambda,
                    phi: buf,
                    ..
                },
            config,
            r,
            g,
            gain_dt,
            inner,
            sse,
            ..
        } = self;
        let shape = buf.shape_generic();
        let n = model.with_regressor(ws, sample.q, sample.qd, sample.qdd, buf, |phi| {
            let net = Net {
                cfg: config,
                gain_dt: *gain_dt,
                inner: *inner,
            };
            net.integrate(
                lambda,
                r,
                g,
                sse,
                phi.as_slice(),
                shape,
                sample.tau.as_slice(),
            )
        })??;
        self.count(n);
        Ok(&self.fit.lambda)
    }

    fn estimate(&self) -> &OVector<f64, P> {
        &self.fit.lambda
    }

    fn reset(&mut self) {
        self.fit.reset();
        self.sse = 0.0;
        self.equations = 0;
        self.samples = 0;
        self.substeps = 0;
    }
}

/// The running error totals of a network, for [`train_epochs`].
fn totals<M, N: Dim, P: Dim>(e: &mut HopfieldOf<M, N, P>) -> (&mut f64, &mut usize)
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    (&mut e.sse, &mut e.equations)
}

/// The constants of one integration of eq. 19.
struct Net<'a> {
    cfg: &'a HopfieldConfig,
    gain_dt: f64,
    inner: f64,
}

impl Net<'_> {
    /// Integrates eq. 19 over one sample period with Φ (N×P, column-major in `ps`) and τ
    /// held, adding the first sub-step's ‖τ − Φ·λ̂‖² to `sse`; returns the sub-steps taken.
    /// Both [`HopfieldOf::step`] and [`HopfieldOf::train_stored`] run it, so that they
    /// compute the same numbers.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn integrate<N: Dim, P: Dim>(
        &self,
        lambda: &mut OVector<f64, P>,
        r: &mut OVector<f64, N>,
        g: &mut OVector<f64, P>,
        sse: &mut f64,
        ps: &[f64],
        (n_dim, p_dim): (N, P),
        tau: &[f64],
    ) -> Result<u32>
    where
        DefaultAllocator: Allocator<N> + Allocator<P>,
    {
        let cfg = self.cfg;
        let n_joints = n_dim.value();
        let phi = MatrixView::<f64, N, P>::from_slice_generic(ps, n_dim, p_dim);
        let bound = self.gain_dt * phi.norm_squared();
        let n = if bound <= cfg.stability_limit {
            1
        } else {
            let n = (bound / cfg.stability_limit).ceil();
            if n.is_nan() || n > f64::from(cfg.max_substeps) {
                return Err(PrrrpError::InvalidParameter {
                    field: "beta".into(),
                    value: cfg.beta,
                    reason: "this sample needs more than max_substeps Euler sub-steps for \
                             a stable integration: raise beta (slower learning) or \
                             max_substeps",
                });
            }
            n as u32
        };
        let k = cfg.dt / f64::from(n) / (cfg.bound * cfg.beta);
        let c2 = cfg.bound * cfg.bound;
        let inner = self.inner;
        // At compile-time sizes r and g are stack temporaries, which the optimiser keeps
        // in registers (the buffers of `self` may alias λ for all it knows); at run-time
        // sizes the preallocated buffers.
        let (mut r_local, mut g_local);
        let (r, g) = if N::try_to_usize().is_some() && P::try_to_usize().is_some() {
            r_local = OVector::<f64, N>::zeros_generic(n_dim, U1);
            g_local = OVector::<f64, P>::zeros_generic(p_dim, U1);
            (r_local.as_mut_slice(), g_local.as_mut_slice())
        } else {
            (r.as_mut_slice(), g.as_mut_slice())
        };
        let lambda = lambda.as_mut_slice();
        for s in 0..n {
            if s % SUBSTEPS_PER_CHECK == SUBSTEPS_PER_CHECK - 1 {
                crate::interrupt::check("Hopfield sample")?;
            }
            let e2 = residual(ps, tau, lambda, r);
            if s == 0 {
                *sse += e2;
            }
            // g = Φᵀ·r, column by column (contiguous).
            for (gj, col) in g.iter_mut().zip(ps.chunks_exact(n_joints)) {
                *gj = col.iter().zip(r.iter()).map(|(a, b)| a * b).sum();
            }
            for (l, &gi) in lambda.iter_mut().zip(g.iter()) {
                let next = *l + k * (c2 - *l * *l) * gi;
                *l = next.clamp(-inner, inner);
            }
        }
        Ok(n)
    }
}

/// r = τ − Φ·λ (Φ column-major, one contiguous column per parameter); returns ‖r‖².
#[inline(always)]
fn residual(phi: &[f64], tau: &[f64], lambda: &[f64], r: &mut [f64]) -> f64 {
    r.copy_from_slice(tau);
    for (col, &l) in phi.chunks_exact(r.len()).zip(lambda) {
        for (ri, &p) in r.iter_mut().zip(col) {
            *ri -= p * l;
        }
    }
    r.iter().map(|v| v * v).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimators::Sample;
    use crate::models::prrrp::types::Vec5;
    use crate::{Robot, StopFlag};

    #[test]
    fn max_substeps_beyond_the_bound_are_refused() {
        let config = HopfieldConfig {
            dt: 1e6,
            max_substeps: MAX_HOPFIELD_SUBSTEPS + 1,
            ..HopfieldConfig::default()
        };
        let got =
            Hopfield::<_, 5, 8>::new(Robot::paper().model(), nalgebra::SVector::zeros(), config);
        assert!(
            matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "max_substeps"),
            "{:?}",
            got.map(|_| ())
        );
    }

    #[test]
    fn a_sample_of_many_substeps_polls_the_stop_flag() {
        let model = Robot::paper().model();
        let z = Vec5::zeros();
        let tau = Vec5::repeat(1.0);
        // At rest Φ holds only gravity; dt such that the sample needs about 2e5 sub-steps.
        let phi2 = model.regressor(&z, &z, &z).norm_squared();
        let base = HopfieldConfig::default();
        let config = HopfieldConfig {
            dt: 2e5 * base.stability_limit * base.beta / (base.bound * phi2),
            max_substeps: MAX_HOPFIELD_SUBSTEPS,
            ..base
        };
        let net = || Hopfield::<_, 5, 8>::new(model, nalgebra::SVector::zeros(), config).unwrap();
        let mut free = net();
        free.step(Sample::new(&z, &z, &z, &tau)).unwrap();
        assert!(
            free.substeps() > u64::from(SUBSTEPS_PER_CHECK),
            "{}",
            free.substeps()
        );
        let flag = StopFlag::new();
        flag.raise();
        let mut stopped = net();
        let got = flag.run(|| stopped.step(Sample::new(&z, &z, &z, &tau)).map(|_| ()));
        assert!(
            matches!(got, Err(PrrrpError::Interrupted { .. })),
            "{got:?}"
        );
    }
}
