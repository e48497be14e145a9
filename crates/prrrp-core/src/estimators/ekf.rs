//! Extended Kalman filter on the parameter-augmented state (eqs. 21–29, 41–44).
//!
//! State x = [q (N), q̇ (N), λ (P)] (S = 2N + P; 18 for PRRRP), input τ, Euler
//! discretisation (eq. 43) of ẋ = [q̇, q̈(q, q̇, τ, λ), 0] (eq. 42):
//! ```text
//! q⁺ = q + h·q̇,   q̇⁺ = q̇ + h·q̈(q, q̇, τ, λ),   λ⁺ = λ
//! ```
//! with analytic Jacobians from [`LinearDynamics::forward_derivatives`]
//! (A = [∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂λ = −M⁻¹Φ]). The measurement is the joint positions, or
//! positions and velocities; H selects entries of x.
//!
//! Cost: F = I + h·B with B = [[0, I, 0], [A], [0]], so
//! F·P·Fᵀ = P + h(BP + PBᵀ) + h²·BPBᵀ needs only G = P·Aᵀ (S×N) and A·G (N×N): ≈ S²N +
//! SN² multiply-adds instead of 2S³, and zero entries of A (most of −M⁻¹Φ for PRRRP) are
//! skipped. Because H is a selection, the innovation covariance is a sub-block of P plus
//! R, and the Joseph update (I−KH)P(I−KH)ᵀ + KRKᵀ expands exactly to P − K·P_z· − D·Kᵀ
//! with D = P_·z − K·S_z (zero for the optimal gain, so the form stays first-order
//! insensitive to errors in K). K = P_·z·S_z⁻¹ with S_z⁻¹ from the Cholesky factor. The
//! prediction's upper triangle is mirrored at the end of every step, so the stored P is
//! exactly symmetric. A velocity measurement is processed as a second sequential
//! update, which equals the joint update for uncorrelated position and velocity noise.

use nalgebra::{Const, SMatrix, SVector};

use super::estimator::Estimator;
use super::rls::check_lambda0;
use super::samples::{all_finite, Sample};
use crate::dynamics::PrrrpModel;
use crate::error::{PrrrpError, Result};
use crate::model::{ForwardDerivatives, LinearDynamics};
use crate::types::{NDOF, NPARAM};

/// State dimension of the PRRRP filter: 5 positions, 5 velocities, 8 parameters.
pub const PRRRP_EKF_STATES: usize = 2 * NDOF + NPARAM;

/// The extended Kalman filter for the PRRRP arm.
pub type PrrrpEkf = Ekf<PrrrpModel, NDOF, NPARAM, PRRRP_EKF_STATES>;

/// What the filter measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EkfMeasurement {
    /// Joint positions q (the paper's choice).
    #[default]
    Positions,
    /// Joint positions q and velocities q̇.
    PositionsVelocities,
}

/// How the continuous dynamics ẋ = [q̇, q̈, 0] are discretised over one sample period h.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Discretisation {
    /// Explicit Euler, eq. 43: q⁺ = q + h·q̇, q̇⁺ = q̇ + h·q̈ (the paper's choice). Its
    /// second difference of q is h²·q̈_k, half a sample off the true h²·(q̈_k + q̈_k+1)/2,
    /// which biases λ̂ by O(h) (≈ 1 % on the small PRRRP parameters at 50 Hz).
    #[default]
    Euler,
    /// Adds the h²/2·q̈ term to the position: q⁺ = q + h·q̇ + h²/2·q̈, q̇⁺ = q̇ + h·q̈, exact
    /// when q̈ is constant over the sample (torque held by a zero-order hold). Same cost.
    SecondOrder,
}

/// Settings of [`Ekf`]. The paper's eq. 44 cannot be used as printed (λ₀ = 1 makes M
/// singular in some configurations, P₀ = ones is singular, R has 18 entries for a
/// 5-dimensional measurement); these defaults are physically sized for a robot measured
/// by encoders at 50 Hz. Full matrices can be set with [`Ekf::set_initial_covariance`],
/// [`Ekf::set_process_noise`] and [`Ekf::set_measurement_noise`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfConfig {
    /// Sample period h of the discretisation, s (default `0.02`, as the paper).
    pub dt: f64,
    /// Discretisation of the dynamics (default [`Discretisation::Euler`], eq. 43).
    pub discretisation: Discretisation,
    /// Measured quantities (default [`EkfMeasurement::Positions`]).
    pub measurement: EkfMeasurement,
    /// Standard deviation of the position measurement, m or rad (default `1e-3`). R =
    /// σ²·I. Also covers what the model misses per step: with 1e-4 the filter trusts the
    /// positions so much that a start 30 % off can be driven out of the physical region.
    pub position_noise: f64,
    /// Standard deviation of the velocity measurement, m/s or rad/s (default `1e-2`);
    /// used with [`EkfMeasurement::PositionsVelocities`].
    pub velocity_noise: f64,
    /// Process noise on q per step, m or rad (default `1e-6`): the Euler position update
    /// misses h²/2·q̈; most of that is absorbed by q̇, the rest is this noise.
    pub process_position_noise: f64,
    /// Process noise on q̇ per step, m/s or rad/s (default `1e-3`): unmodelled forces
    /// and the discretisation error in q̇ (≈ h²/2·q⃛).
    pub process_velocity_noise: f64,
    /// Random-walk standard deviation of λ per step, relative to |λ₀_i| (default `1e-5`).
    /// Eq. 42 makes λ constant (0 here); a little random walk keeps the filter from
    /// freezing on an early, linearisation-biased estimate (with 0 a start 30 % off can
    /// still be 5 % off after 3000 samples) at the price of a jitter of ≈ 0.3 % at 50 Hz.
    pub process_parameter_noise: f64,
    /// Initial standard deviation of q, m or rad (default `1e-3`).
    pub initial_position_std: f64,
    /// Initial standard deviation of q̇, m/s or rad/s (default `1.0`: with positions
    /// only, the starting velocity is unknown).
    pub initial_velocity_std: f64,
    /// Initial standard deviation of λ_i relative to |λ₀_i| (dimensionless, default
    /// `0.5`: "λ₀ is a guess within ±50 %"), floored at `initial_parameter_min_std`.
    pub initial_parameter_rel_std: f64,
    /// Floor of the initial λ standard deviation, units of λ (default `1e-3`), so that a
    /// λ₀_i = 0 still gets some uncertainty.
    pub initial_parameter_min_std: f64,
    /// Take the initial q (and q̇, when measured) from the first sample instead of zero
    /// (default `true`).
    pub init_from_first_measurement: bool,
}

impl Default for EkfConfig {
    fn default() -> Self {
        Self {
            dt: 0.02,
            discretisation: Discretisation::Euler,
            measurement: EkfMeasurement::Positions,
            position_noise: 1e-3,
            velocity_noise: 1e-2,
            process_position_noise: 1e-6,
            process_velocity_noise: 1e-3,
            process_parameter_noise: 1e-5,
            initial_position_std: 1e-3,
            initial_velocity_std: 1.0,
            initial_parameter_rel_std: 0.5,
            initial_parameter_min_std: 1e-3,
            init_from_first_measurement: true,
        }
    }
}

/// Extended Kalman filter with S = 2N + P states (checked at compile time).
#[derive(Debug, Clone)]
pub struct Ekf<M, const N: usize, const P: usize, const S: usize> {
    model: M,
    config: EkfConfig,
    x: SVector<f64, S>,
    p: SMatrix<f64, S, S>,
    lambda: SVector<f64, P>,
    x0: SVector<f64, S>,
    p0: SMatrix<f64, S, S>,
    q_diag: SVector<f64, S>,
    r_pos: SVector<f64, N>,
    r_vel: SVector<f64, N>,
    initialised: bool,
    samples: usize,
    skipped: usize,
    damped: usize,
    /// Whether the CPU runs the AVX2 copy of the step (detected once, at construction).
    avx2: bool,
}

/// The gain of one measurement update and what its Joseph covariance update needs.
struct Gain<const N: usize, const S: usize> {
    k: SMatrix<f64, S, N>,
    pz: SMatrix<f64, S, N>,
    sz: SMatrix<f64, N, N>,
}

/// a·b + c, fused when the caller is compiled with FMA (then one rounding), plain
/// otherwise (`mul_add` without hardware FMA is a slow library call).
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

fn cpu_has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// How often a measurement update is retried with half the gain before the step fails.
const MAX_GAIN_HALVINGS: u32 = 10;

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize, const S: usize> Ekf<M, N, P, S> {
    const STATE_CHECK: () = assert!(S == 2 * N + P, "Ekf needs S = 2N + P states");

    /// A filter starting from λ₀ with the covariances of `config`.
    ///
    /// λ₀ must make M(q, λ₀) positive definite (e.g. a CAD estimate or a least-squares
    /// solution); the filter then refines it.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite dt, noise or
    /// initial standard deviation (process noises may be 0), or a non-finite λ₀.
    pub fn new(model: M, lambda0: SVector<f64, P>, config: EkfConfig) -> Result<Self> {
        #[allow(clippy::let_unit_value)]
        let () = Self::STATE_CHECK;
        let c = &config;
        let positive = [
            ("dt", c.dt),
            ("position_noise", c.position_noise),
            ("velocity_noise", c.velocity_noise),
            ("initial_position_std", c.initial_position_std),
            ("initial_velocity_std", c.initial_velocity_std),
            ("initial_parameter_min_std", c.initial_parameter_min_std),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: name.into(),
                    value: v,
                    reason: "must be finite and > 0",
                });
            }
        }
        let non_negative = [
            ("process_position_noise", c.process_position_noise),
            ("process_velocity_noise", c.process_velocity_noise),
            ("process_parameter_noise", c.process_parameter_noise),
            ("initial_parameter_rel_std", c.initial_parameter_rel_std),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: name.into(),
                    value: v,
                    reason: "must be finite and >= 0",
                });
            }
        }
        check_lambda0(&lambda0, N, P)?;

        let mut x0 = SVector::<f64, S>::zeros();
        x0.fixed_rows_mut::<P>(2 * N).copy_from(&lambda0);
        let mut p0_diag = SVector::<f64, S>::zeros();
        let mut q_diag = SVector::<f64, S>::zeros();
        for i in 0..N {
            p0_diag[i] = c.initial_position_std.powi(2);
            p0_diag[N + i] = c.initial_velocity_std.powi(2);
            q_diag[i] = c.process_position_noise.powi(2);
            q_diag[N + i] = c.process_velocity_noise.powi(2);
        }
        for i in 0..P {
            let l = lambda0[i].abs();
            p0_diag[2 * N + i] = (c.initial_parameter_rel_std * l)
                .max(c.initial_parameter_min_std)
                .powi(2);
            q_diag[2 * N + i] = (c.process_parameter_noise * l).powi(2);
        }
        let p0 = SMatrix::from_diagonal(&p0_diag);
        Ok(Self {
            model,
            config,
            x: x0,
            p: p0,
            lambda: lambda0,
            x0,
            p0,
            q_diag,
            r_pos: SVector::repeat(c.position_noise.powi(2)),
            r_vel: SVector::repeat(c.velocity_noise.powi(2)),
            initialised: false,
            samples: 0,
            skipped: 0,
            damped: 0,
            avx2: cpu_has_avx2_fma(),
        })
    }

    /// Replaces the initial covariance P₀ (and the current one, when no sample has been
    /// consumed since construction or reset). Units: the squares of the state's.
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] for NaN/∞, [`PrrrpError::InvalidParameter`] if P₀ is not
    /// symmetric, [`PrrrpError::NotPositiveDefinite`] if it is not positive definite.
    pub fn set_initial_covariance(&mut self, p0: &SMatrix<f64, S, S>) -> Result<()> {
        if !p0.iter().all(|v| v.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "initial covariance".into(),
                row: None,
            });
        }
        let asym = (p0 - p0.transpose()).amax();
        if asym > 1e-12 * p0.amax() {
            return Err(PrrrpError::InvalidParameter {
                field: "initial covariance".into(),
                value: asym,
                reason: "must be symmetric",
            });
        }
        if p0.cholesky().is_none() {
            return Err(PrrrpError::NotPositiveDefinite {
                what: "initial covariance P0",
            });
        }
        self.p0 = *p0;
        if self.samples == 0 {
            self.p = *p0;
        }
        Ok(())
    }

    /// Replaces the process noise Q = diag(`variances`) (squares of the state units, per
    /// step).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a negative or non-finite variance.
    pub fn set_process_noise(&mut self, variances: &SVector<f64, S>) -> Result<()> {
        check_variances("process noise", variances, true)?;
        self.q_diag = *variances;
        Ok(())
    }

    /// Replaces the measurement noise R = diag(positions, velocities) (variances, squares
    /// of m, rad, m/s, rad/s).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite variance.
    pub fn set_measurement_noise(
        &mut self,
        positions: &SVector<f64, N>,
        velocities: &SVector<f64, N>,
    ) -> Result<()> {
        check_variances("position noise", positions, false)?;
        check_variances("velocity noise", velocities, false)?;
        self.r_pos = *positions;
        self.r_vel = *velocities;
        Ok(())
    }

    /// The state x = [q, q̇, λ] predicted for the next sample.
    pub fn state(&self) -> &SVector<f64, S> {
        &self.x
    }

    /// The state covariance P (squares of the state units).
    pub fn covariance(&self) -> &SMatrix<f64, S, S> {
        &self.p
    }

    /// Standard deviation of each λ̂_i from the diagonal of P (units of λ).
    pub fn parameter_std(&self) -> SVector<f64, P> {
        SVector::from_fn(|i, _| self.p[(2 * N + i, 2 * N + i)].max(0.0).sqrt())
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Number of measurement updates skipped because a measurement was NaN or ∞.
    pub fn skipped_updates(&self) -> usize {
        self.skipped
    }

    /// Number of samples whose measurement update had to be damped (gain halved) to keep
    /// M(q, λ̂) positive definite.
    pub fn damped_updates(&self) -> usize {
        self.damped
    }

    /// The body of [`Estimator::step`], inlined into a portable and an AVX2 copy.
    #[inline(always)]
    fn step_impl<const FMA: bool>(&mut self, sample: Sample<'_, N>) -> Result<()> {
        if !all_finite(sample.tau) {
            return Err(PrrrpError::NonFinite {
                what: "tau".into(),
                row: None,
            });
        }
        let with_vel = self.config.measurement == EkfMeasurement::PositionsVelocities;
        if !self.initialised {
            if self.config.init_from_first_measurement {
                if all_finite(sample.q) {
                    self.x.fixed_rows_mut::<N>(0).copy_from(sample.q);
                }
                if with_vel && all_finite(sample.qd) {
                    self.x.fixed_rows_mut::<N>(N).copy_from(sample.qd);
                }
            }
            self.initialised = true;
        }
        let q_ok = all_finite(sample.q);
        let qd_ok = with_vel && all_finite(sample.qd);
        self.skipped += usize::from(!q_ok) + usize::from(with_vel && !qd_ok);
        // A posterior λ̂ that makes M(q, λ̂) indefinite (an overshoot of a large early gain)
        // is retried with the gain halved; the Joseph form keeps P exact for that gain. On
        // final failure the filter is left at its prior.
        let mut alpha = 1.0;
        let mut attempt = 0;
        let fd = if with_vel {
            // Two sequential updates: keep the prior to retry both.
            let (x_prior, p_prior) = (self.x, self.p);
            loop {
                if q_ok {
                    let r = self.r_pos;
                    self.update::<FMA>(0, sample.q, &r, alpha)?;
                }
                if qd_ok {
                    let r = self.r_vel;
                    self.update::<FMA>(N, sample.qd, &r, alpha)?;
                }
                match self.derivatives(&self.x, sample.tau) {
                    Ok(fd) => break fd,
                    Err(e) => {
                        self.x = x_prior;
                        self.p = p_prior;
                        if attempt == MAX_GAIN_HALVINGS || !(q_ok || qd_ok) {
                            return Err(e);
                        }
                    }
                }
                alpha *= 0.5;
                attempt += 1;
            }
        } else {
            // One update: try the candidate state before touching P.
            let gain = if q_ok {
                let r = self.r_pos;
                Some(self.gain::<FMA>(0, &r)?)
            } else {
                None
            };
            let step = match &gain {
                Some(g) => g.k * (sample.q - self.x.fixed_rows::<N>(0)),
                None => SVector::zeros(),
            };
            let fd = loop {
                let candidate = self.x + step * alpha;
                match self.derivatives(&candidate, sample.tau) {
                    Ok(fd) => {
                        self.x = candidate;
                        break fd;
                    }
                    Err(e) if attempt == MAX_GAIN_HALVINGS || gain.is_none() => return Err(e),
                    Err(_) => {
                        alpha *= 0.5;
                        attempt += 1;
                    }
                }
            };
            if let Some(g) = &gain {
                self.update_covariance::<FMA>(g, alpha);
            }
            fd
        };
        self.damped += usize::from(attempt > 0);
        self.lambda.copy_from(&self.x.fixed_rows::<P>(2 * N));
        self.predict::<FMA>(&fd);
        if !(all_finite(&self.x) && self.p[(0, 0)].is_finite()) {
            return Err(PrrrpError::Diverged {
                what: "extended Kalman filter",
                at: self.samples,
                hint: "the state became non-finite: check the noise covariances and λ0",
            });
        }
        self.samples += 1;
        Ok(())
    }

    /// [`Self::step_impl`] compiled for AVX2 and FMA (wider vectors for the 18-long
    /// columns, fused multiply-adds in the covariance products).
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn step_avx2(&mut self, sample: Sample<'_, N>) -> Result<()> {
        self.step_impl::<true>(sample)
    }

    /// Gain of a measurement z = x[o..o+N] + noise of variances r (H a selection):
    /// S_z = P_zz + R, K = P_·z·S_z⁻¹.
    #[inline(always)]
    fn gain<const FMA: bool>(&self, o: usize, r: &SVector<f64, N>) -> Result<Gain<N, S>> {
        let mut sz = SMatrix::<f64, N, N>::zeros();
        for j in 0..N {
            for i in 0..N {
                sz[(i, j)] = self.p[(o + i, o + j)];
            }
            sz[(j, j)] += r[j];
        }
        let l = cholesky(&sz).ok_or(PrrrpError::NotPositiveDefinite {
            what: "EKF innovation covariance H·P·Hᵀ + R",
        })?;
        // S_z⁻¹ = L⁻ᵀ·L⁻¹ from the Cholesky factor (N×N, cheap), then K = P_·z·S_z⁻¹ as
        // N independent column sums over whole S-long columns: the two triangular solves
        // on K would chain every column to the previous one.
        let linv = lower_triangular_inverse(&l);
        let sinv = linv.transpose() * linv;
        let pz: SMatrix<f64, S, N> = self.p.fixed_columns::<N>(o).into_owned();
        let mut k = SMatrix::<f64, S, N>::zeros();
        {
            let ps = pz.as_slice();
            let ks = k.as_mut_slice();
            for m in 0..N {
                let pc = &ps[m * S..m * S + S];
                for j in 0..N {
                    let f = sinv[(m, j)];
                    for (kv, &pv) in ks[j * S..j * S + S].iter_mut().zip(pc) {
                        *kv = madd::<FMA>(f, pv, *kv);
                    }
                }
            }
        }
        Ok(Gain { k, pz, sz })
    }

    /// Joseph-form covariance update for the gain α·K: with K' = α·K and
    /// D = P_·z − K'·S_z (≈ 0 for α = 1), P ← P − K'·P_z· − D·K'ᵀ. Exact for any gain, so
    /// also for a damped one.
    #[inline(always)]
    fn update_covariance<const FMA: bool>(&mut self, g: &Gain<N, S>, alpha: f64) {
        // Borrowed when undamped: K is S×N, and copying it is not free at this size.
        let damped_k;
        let k = if alpha == 1.0 {
            &g.k
        } else {
            damped_k = g.k * alpha;
            &damped_k
        };
        let mut d = g.pz;
        {
            let ks = k.as_slice();
            let dsm = d.as_mut_slice();
            for j in 0..N {
                let dc = &mut dsm[j * S..j * S + S];
                for m in 0..N {
                    let f = g.sz[(m, j)];
                    let kc = &ks[m * S..m * S + S];
                    for (a, &b) in dc.iter_mut().zip(kc) {
                        *a = madd::<FMA>(-f, b, *a);
                    }
                }
            }
        }
        let ks = k.as_slice();
        let ds = d.as_slice();
        let pzs = g.pz.as_slice();
        let p = self.p.as_mut_slice();
        // Whole columns of the compile-time length S: fully unrolled and vectorised, which
        // is faster than the triangle's ragged loops although it does twice the flops.
        for j in 0..S {
            let mut acc = [0.0f64; S];
            for m in 0..N {
                let a = pzs[m * S + j];
                let b = ks[m * S + j];
                let kc = &ks[m * S..m * S + S];
                let dc = &ds[m * S..m * S + S];
                for r in 0..S {
                    acc[r] = madd::<FMA>(a, kc[r], madd::<FMA>(b, dc[r], acc[r]));
                }
            }
            for (c, v) in p[j * S..j * S + S].iter_mut().zip(acc) {
                *c -= v;
            }
        }
        // The two triangles now differ by rounding; the prediction that always follows
        // mirrors its upper triangle, so the stored P is exactly symmetric.
    }

    /// Full measurement update (state and covariance) with the gain α·K.
    #[inline(always)]
    fn update<const FMA: bool>(
        &mut self,
        o: usize,
        z: &SVector<f64, N>,
        r: &SVector<f64, N>,
        alpha: f64,
    ) -> Result<()> {
        let g = self.gain::<FMA>(o, r)?;
        let innovation = z - self.x.fixed_rows::<N>(o);
        self.x += (g.k * innovation) * alpha;
        self.update_covariance::<FMA>(&g, alpha);
        Ok(())
    }

    /// The model's forward dynamics and derivatives at a state.
    #[inline(always)]
    fn derivatives(
        &self,
        x: &SVector<f64, S>,
        tau: &SVector<f64, N>,
    ) -> Result<ForwardDerivatives<N, P>> {
        let q: SVector<f64, N> = x.fixed_rows::<N>(0).into_owned();
        let v: SVector<f64, N> = x.fixed_rows::<N>(N).into_owned();
        let lam: SVector<f64, P> = x.fixed_rows::<P>(2 * N).into_owned();
        self.model
            .forward_derivatives(&q, &v, tau, &lam)
            .map_err(|_| PrrrpError::Diverged {
                what: "extended Kalman filter",
                at: self.samples,
                hint: "M(q, λ̂) is not positive definite: the parameter estimate left the \
                       physical region; start from a better λ0, lower the initial \
                       parameter uncertainty or raise the measurement noise",
            })
    }

    /// Time update with the derivatives at the current state: x ← f(x, τ),
    /// P ← F·P·Fᵀ + Q.
    #[inline(always)]
    fn predict<const FMA: bool>(&mut self, fd: &ForwardDerivatives<N, P>) {
        let h = self.config.dt;
        let q: SVector<f64, N> = self.x.fixed_rows::<N>(0).into_owned();
        let v: SVector<f64, N> = self.x.fixed_rows::<N>(N).into_owned();

        // A = ∂q̈/∂x (N×S), then G = P·Aᵀ (S×N), skipping zero entries of A.
        let mut a = SMatrix::<f64, N, S>::zeros();
        a.fixed_columns_mut::<N>(0).copy_from(&fd.dqdd_dq);
        a.fixed_columns_mut::<N>(N).copy_from(&fd.dqdd_dqd);
        a.fixed_columns_mut::<P>(2 * N).copy_from(&fd.dqdd_dlambda);
        let mut g = SMatrix::<f64, S, N>::zeros();
        {
            let ps = self.p.as_slice();
            let gs = g.as_mut_slice();
            for kk in 0..S {
                let pc = &ps[kk * S..kk * S + S];
                for i in 0..N {
                    let f = a[(i, kk)];
                    if f != 0.0 {
                        let gc = &mut gs[i * S..i * S + S];
                        for (gv, &pv) in gc.iter_mut().zip(pc) {
                            *gv = madd::<FMA>(f, pv, *gv);
                        }
                    }
                }
            }
        }
        // A·P·Aᵀ = A·G (N×N). Column kk of A outer, so that the N column sums advance
        // side by side instead of one dependent chain at a time; zero columns of A (joints
        // the dynamics do not depend on) are skipped.
        let mut apa = SMatrix::<f64, N, N>::zeros();
        for kk in 0..S {
            let ac = a.column(kk);
            if ac.iter().all(|&v| v == 0.0) {
                continue;
            }
            for j in 0..N {
                let gv = g[(kk, j)];
                for i in 0..N {
                    apa[(i, j)] = madd::<FMA>(ac[i], gv, apa[(i, j)]);
                }
            }
        }

        // F = I + E with E_q = [c·h·A_q, h·I + c·h·A_v, c·h·A_λ], E_v = h·A, E_λ = 0
        // (c = h/2 for the second-order position update, 0 for Euler), so
        // P ← P + EP + PEᵀ + EPEᵀ needs only P, G = P·Aᵀ and A·P·Aᵀ. Block by block on the
        // upper triangle, in an order that reads every block before it is overwritten:
        // qq, qλ, qv, vv, vλ. G_q, G_v, G_λ are the row blocks of G.
        let c = match self.config.discretisation {
            Discretisation::Euler => 0.0,
            Discretisation::SecondOrder => 0.5 * h,
        };
        let h2 = h * h;
        let (hc, h2c, h2c2) = (h * c, h2 * c, h2 * c * c);
        let gs = g.as_slice();
        let p = self.p.as_mut_slice();
        let at = |i: usize, j: usize| j * S + i;
        for j in 0..N {
            for i in 0..=j {
                p[at(i, j)] += h * (p[at(N + i, j)] + p[at(i, N + j)])
                    + h2 * p[at(N + i, N + j)]
                    + hc * (gs[j * S + i] + gs[i * S + j])
                    + h2c * (gs[j * S + N + i] + gs[i * S + N + j])
                    + h2c2 * apa[(i, j)];
            }
        }
        for j in 2 * N..S {
            for i in 0..N {
                p[at(i, j)] += h * p[at(N + i, j)] + hc * gs[i * S + j];
            }
        }
        for j in 0..N {
            for i in 0..N {
                p[at(i, N + j)] += h * (p[at(N + i, N + j)] + gs[j * S + i])
                    + hc * gs[i * S + N + j]
                    + h2 * gs[j * S + N + i]
                    + h2c * apa[(i, j)];
            }
        }
        for j in 0..N {
            for i in 0..=j {
                p[at(N + i, N + j)] +=
                    h * (gs[i * S + N + j] + gs[j * S + N + i]) + h2 * apa[(i, j)];
            }
        }
        for j in 2 * N..S {
            for i in 0..N {
                p[at(N + i, j)] += h * gs[i * S + j];
            }
        }
        for i in 0..S {
            p[at(i, i)] += self.q_diag[i];
        }
        mirror_upper(&mut self.p);

        for i in 0..N {
            self.x[i] = q[i] + h * v[i] + hc * fd.qdd[i];
            self.x[N + i] = v[i] + h * fd.qdd[i];
        }
    }
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize, const S: usize>
    Estimator<Const<N>, Const<P>> for Ekf<M, N, P, S>
{
    /// One sample k: update with the measurement (q, and q̇ if configured), then predict
    /// to k+1 with τ_k held over the period. The returned λ̂ is the posterior at k (the
    /// prediction does not change λ). A NaN or ∞ in a measurement skips that update (see
    /// [`Ekf::skipped_updates`]); q̈ is ignored. If the posterior λ̂ makes M(q, λ̂)
    /// indefinite, the update is repeated with the gain halved, up to 10 times (see
    /// [`Ekf::damped_updates`]).
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] for NaN/∞ in τ; [`PrrrpError::NotPositiveDefinite`] if the
    /// innovation covariance cannot be factorised; [`PrrrpError::Diverged`] if M(q, λ̂) is
    /// not positive definite even with the smallest gain (λ₀ itself not physical) — the
    /// filter is then left at its prior for this sample — or the state became non-finite.
    fn step(&mut self, sample: Sample<'_, N>) -> Result<&SVector<f64, P>> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set at construction only when the CPU reports AVX2 and FMA.
            unsafe { self.step_avx2(sample)? };
            return Ok(&self.lambda);
        }
        self.step_impl::<false>(sample)?;
        Ok(&self.lambda)
    }

    fn estimate(&self) -> &SVector<f64, P> {
        &self.lambda
    }

    fn reset(&mut self) {
        self.x = self.x0;
        self.p = self.p0;
        self.lambda = self.x0.fixed_rows::<P>(2 * N).into_owned();
        self.initialised = false;
        self.samples = 0;
        self.skipped = 0;
        self.damped = 0;
    }
}

fn check_variances<const D: usize>(what: &str, v: &SVector<f64, D>, zero_ok: bool) -> Result<()> {
    for (i, &x) in v.iter().enumerate() {
        let ok = x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0));
        if !ok {
            return Err(PrrrpError::InvalidParameter {
                field: format!("{what}[{i}]"),
                value: x,
                reason: if zero_ok {
                    "variances must be finite and >= 0"
                } else {
                    "variances must be finite and > 0"
                },
            });
        }
    }
    Ok(())
}

/// Lower Cholesky factor of a small SPD matrix, `None` if a pivot is not positive.
#[inline(always)]
fn cholesky<const D: usize>(a: &SMatrix<f64, D, D>) -> Option<SMatrix<f64, D, D>> {
    let mut l = SMatrix::<f64, D, D>::zeros();
    for j in 0..D {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= l[(j, k)] * l[(j, k)];
        }
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let djj = d.sqrt();
        l[(j, j)] = djj;
        let inv = 1.0 / djj;
        for i in j + 1..D {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= l[(i, k)] * l[(j, k)];
            }
            l[(i, j)] = s * inv;
        }
    }
    Some(l)
}

/// Inverse of a lower-triangular matrix with a positive diagonal, by forward substitution.
#[inline(always)]
fn lower_triangular_inverse<const D: usize>(l: &SMatrix<f64, D, D>) -> SMatrix<f64, D, D> {
    let mut inv = SMatrix::<f64, D, D>::zeros();
    for j in 0..D {
        inv[(j, j)] = 1.0 / l[(j, j)];
        for i in j + 1..D {
            let mut s = 0.0;
            for k in j..i {
                s += l[(i, k)] * inv[(k, j)];
            }
            inv[(i, j)] = -s / l[(i, i)];
        }
    }
    inv
}

/// Copies the upper triangle onto the lower one.
#[inline(always)]
fn mirror_upper<const D: usize>(p: &mut SMatrix<f64, D, D>) {
    let s = p.as_mut_slice();
    for j in 0..D {
        for i in j + 1..D {
            s[j * D + i] = s[i * D + j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Robot;

    /// The AVX2/FMA copy of the step and the portable one compute the same filter (up to
    /// the rounding of fused multiply-adds).
    #[test]
    fn portable_and_avx2_paths_agree() {
        let robot = Robot::paper();
        let (model, lambda) = (robot.model(), robot.base_parameters());
        let cfg = EkfConfig::default();
        let mut fast = PrrrpEkf::new(model, lambda * 1.2, cfg).unwrap();
        let mut portable = fast.clone();
        portable.avx2 = false;
        let zero = crate::Vec5::zeros();
        // The true arm under gravity compensation plus a small sinusoidal torque,
        // integrated with 20 Euler sub-steps per sample.
        let (mut q, mut v) = (zero, zero);
        for k in 0..200 {
            let t = k as f64 * cfg.dt;
            let tau = model.inverse_dynamics(&q, &zero, &zero, &lambda)
                + crate::Vec5::from_fn(|j, _| 0.05 * (t * (1.0 + j as f64)).sin());
            let s = Sample::new(&q, &v, &zero, &tau);
            let a = *fast.step(s).unwrap();
            let b = *portable.step(s).unwrap();
            assert!((a - b).amax() <= 1e-9 * lambda.amax(), "k {k}: {a} vs {b}");
            let h = cfg.dt / 20.0;
            for _ in 0..20 {
                let acc = model.forward_dynamics(&q, &v, &tau, &lambda).unwrap();
                q += h * v;
                v += h * acc;
            }
        }
        let dp = (fast.covariance() - portable.covariance()).amax();
        assert!(dp <= 1e-9 * fast.covariance().amax(), "{dp}");
    }
}
