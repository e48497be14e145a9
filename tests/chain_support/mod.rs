//! Test data for the estimators on generic chains, generated from physics:
//! - an exciting reference given analytically as a finite Fourier series per joint
//!   (Swevers et al. 1997), coefficients drawn from a seeded generator;
//! - a closed-loop simulation of a [`SerialChain`]: RK4 on the chain's forward dynamics
//!   (composite-rigid-body mass matrix + Newton–Euler bias forces) at a 1 ms step under
//!   computed-torque control held over each step, recorded every 10 ms, with the work done
//!   on the arm integrated alongside so that the run can be checked against the balance
//!   of kinetic energy.
#![allow(dead_code)]

// Each support module is included on its own by tests and benches, so a test that takes
// two of them holds two copies of these free functions.
#[allow(clippy::duplicate_mod)]
#[path = "../seeded_support/mod.rs"]
mod seeded_support;

use prrrp_core::nalgebra::SVector;
use prrrp_core::{
    AdalineConfig, BaseOptions, BaseParameters, ChainBaseModel, HopfieldConfig, Samples,
    SerialChain,
};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A periodic reference q_j(t) = c_j + Σ_k a_jk·sin(k·ω·t + φ_jk).
#[derive(Debug, Clone)]
pub struct Fourier<const N: usize> {
    pub omega: f64,
    pub offset: [f64; N],
    pub amp: [[f64; 5]; N],
    pub phase: [[f64; 5]; N],
}

impl<const N: usize> Fourier<N> {
    /// Five harmonics of a `period`-second fundamental; amplitude of harmonic k of joint
    /// j drawn in `scale[j]`·[0.3, 1]/k/2 (falling with k, so that accelerations stay
    /// moderate), phases uniform.
    pub fn seeded(seed: u64, period: f64, offset: [f64; N], scale: [f64; N]) -> Self {
        let mut amp = [[0.0; 5]; N];
        let mut phase = [[0.0; 5]; N];
        seeded_support::draw(seed, &scale, &mut amp, &mut phase);
        Self {
            omega: 2.0 * std::f64::consts::PI / period,
            offset,
            amp,
            phase,
        }
    }

    /// (q, q̇, q̈) at time t, exact.
    pub fn eval(&self, t: f64) -> [SVector<f64, N>; 3] {
        let mut q = SVector::<f64, N>::from(self.offset);
        let mut qd = SVector::<f64, N>::zeros();
        let mut qdd = SVector::<f64, N>::zeros();
        let (amp, phase) = (&self.amp, &self.phase);
        let (q_, qd_, qdd_) = (q.as_mut_slice(), qd.as_mut_slice(), qdd.as_mut_slice());
        seeded_support::add(self.omega, amp, phase, t, q_, qd_, qdd_);
        [q, qd, qdd]
    }
}

/// Owned columns of a record.
#[derive(Debug, Clone, Default)]
pub struct Record<const N: usize> {
    pub t: Vec<f64>,
    pub q: Vec<SVector<f64, N>>,
    pub qd: Vec<SVector<f64, N>>,
    pub qdd: Vec<SVector<f64, N>>,
    pub tau: Vec<SVector<f64, N>>,
}

impl<const N: usize> Record<N> {
    pub fn samples(&self) -> Samples<'_, N> {
        Samples::new(&self.q, &self.qd, &self.qdd, &self.tau).expect("equal lengths")
    }

    pub fn len(&self) -> usize {
        self.q.len()
    }

    /// RMS of each joint's τ.
    pub fn tau_rms(&self) -> SVector<f64, N> {
        let mut s = SVector::<f64, N>::zeros();
        for t in &self.tau {
            s += t.component_mul(t);
        }
        (s / self.len() as f64).map(f64::sqrt)
    }

    /// A copy with seeded Gaussian noise of standard deviation `sigma[j]` on τ_j.
    pub fn with_tau_noise(&self, sigma: &SVector<f64, N>, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let unit = Normal::new(0.0, 1.0).expect("valid");
        let mut out = self.clone();
        for t in &mut out.tau {
            for j in 0..N {
                t[j] += sigma[j] * unit.sample(&mut rng);
            }
        }
        out
    }
}

/// Settings of [`simulate`].
#[derive(Debug, Clone, Copy)]
pub struct SimConfig {
    /// Integration (and control) step, s.
    pub h: f64,
    /// Integration steps per recorded sample.
    pub steps_per_sample: usize,
    /// Number of recorded samples.
    pub samples: usize,
    /// Closed-loop bandwidth of the computed-torque controller, rad/s (critically damped).
    pub bandwidth: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            h: 1e-3,
            steps_per_sample: 10,
            samples: 1000,
            bandwidth: 20.0,
        }
    }
}

/// A simulated run and the energy account of the whole run.
#[derive(Debug, Clone)]
pub struct Run<const N: usize> {
    pub record: Record<N>,
    /// Kinetic energy ½·q̇ᵀM(q)·q̇ at the start and at the end of the run, J.
    pub kinetic: (f64, f64),
    /// Work of τ − G(q) (the non-gravitational joint forces) over the run, J, integrated
    /// alongside the state by the same RK4 stages.
    pub work: f64,
    /// ∫|q̇ᵀ(τ − G)|dt, J: the scale of the energy exchanged, for relative tolerances.
    pub work_abs: f64,
    /// Largest tracking error |q_ref − q| over the run, rad.
    pub max_tracking_error: f64,
}

/// Closed-loop simulation of `chain` tracking `reference` from its initial state.
///
/// Every step h the computed-torque controller sets
/// τ = M(q)·(q̈_r + Kp·(q_r − q) + Kd·(q̇_r − q̇)) + C(q, q̇)·q̇ + G(q) from the state and holds it
/// over the step (zero-order hold); the plant integrates q̈ = M⁻¹(τ − C·q̇ − G) by classical
/// RK4. Every `steps_per_sample` steps the state, the torque applied from that instant
/// and the acceleration it produces are recorded. No friction is simulated (the chain's
/// friction terms, if any, enter the forward dynamics and are compensated by the
/// controller, but the energy account assumes none).
pub fn simulate<const N: usize>(
    chain: &SerialChain<N>,
    reference: &Fourier<N>,
    cfg: &SimConfig,
) -> Run<N> {
    let h = cfg.h;
    let (kp, kd) = (cfg.bandwidth * cfg.bandwidth, 2.0 * cfg.bandwidth);
    let [mut q, mut qd, _] = reference.eval(0.0);
    let kinetic =
        |q: &SVector<f64, N>, qd: &SVector<f64, N>| 0.5 * qd.dot(&(chain.mass_matrix(q) * qd));
    let k0 = kinetic(&q, &qd);
    // State derivative: (q̇, q̈, power of τ − G).
    let f = |q: &SVector<f64, N>, qd: &SVector<f64, N>, tau: &SVector<f64, N>| {
        let qdd = chain
            .forward_dynamics(q, qd, tau)
            .expect("PUMA mass matrix is PD");
        let p = qd.dot(&(tau - chain.gravity_torques(q)));
        (*qd, qdd, p)
    };
    let (mut work, mut work_abs, mut max_err) = (0.0, 0.0, 0.0f64);
    let mut rec = Record::default();
    let total = cfg.samples * cfg.steps_per_sample;
    for step in 0..total {
        let t = step as f64 * h;
        let [qr, qdr, qddr] = reference.eval(t);
        max_err = max_err.max((qr - q).amax());
        let a = qddr + kp * (qr - q) + kd * (qdr - qd);
        let tau = chain.inverse_dynamics(&q, &qd, &a);
        if step % cfg.steps_per_sample == 0 {
            rec.t.push(t);
            rec.q.push(q);
            rec.qd.push(qd);
            rec.qdd
                .push(chain.forward_dynamics(&q, &qd, &tau).expect("PD"));
            rec.tau.push(tau);
        }
        let (k1q, k1v, k1p) = f(&q, &qd, &tau);
        let (k2q, k2v, k2p) = f(&(q + 0.5 * h * k1q), &(qd + 0.5 * h * k1v), &tau);
        let (k3q, k3v, k3p) = f(&(q + 0.5 * h * k2q), &(qd + 0.5 * h * k2v), &tau);
        let (k4q, k4v, k4p) = f(&(q + h * k3q), &(qd + h * k3v), &tau);
        q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
        qd += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        let dw = h / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p);
        work += dw;
        work_abs += dw.abs();
    }
    Run {
        kinetic: (k0, kinetic(&q, &qd)),
        work,
        work_abs,
        max_tracking_error: max_err,
        record: rec,
    }
}

/// Whether β_i is structurally zero: |β_i| ≤ 1e-12·max|β| (a parameter that vanishes for
/// the chain's geometry, up to round-off of the base-parameter map).
pub fn is_zero(beta: &[f64], i: usize) -> bool {
    let max = beta.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    beta[i].abs() <= 1e-12 * max
}

/// Worst relative error over the nonzero β_i, and worst absolute error over the zero ones.
pub fn errors(est: &[f64], beta: &[f64]) -> (f64, f64) {
    let (mut rel, mut abs) = (0.0f64, 0.0f64);
    for i in 0..beta.len() {
        let e = (est[i] - beta[i]).abs();
        if is_zero(beta, i) {
            abs = abs.max(e);
        } else {
            rel = rel.max(e / beta[i].abs());
        }
    }
    (rel, abs)
}

/// Smallest |β_i| among the nonzero ones.
pub fn smallest_nonzero(beta: &[f64]) -> f64 {
    (0..beta.len())
        .filter(|&i| !is_zero(beta, i))
        .map(|i| beta[i].abs())
        .fold(f64::INFINITY, f64::min)
}

/// The PUMA 560, its base-parameter analysis (default options) and its base model with B
/// base parameters (36 for the PUMA).
pub fn puma_base_model<const B: usize>() -> (SerialChain<6>, BaseParameters, ChainBaseModel<6, B>) {
    let chain = SerialChain::puma560();
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    let model = chain.base_model::<B>(&base).expect("B base parameters");
    (chain, base, model)
}

/// The PUMA's excitation of seed `seed`: a 10 s fundamental (1000 samples per period at
/// 10 ms) about Corke's "ready" pose (0, 1.57, −1.57, 0, 0, 0) rad with amplitude scale
/// 1.5 rad, so harmonic amplitudes ≤ 0.75/k rad and |q − offset| ≤ 1.71 rad — inside the
/// PUMA's ±160°/±110°/±135°/±266°/±100°/±266° joint ranges about the pose.
pub fn puma_reference(seed: u64) -> Fourier<6> {
    Fourier::seeded(seed, 10.0, [0.0, 1.57, -1.57, 0.0, 0.0, 0.0], [1.5; 6])
}

/// Adaline on the PUMA's equilibrated base model: the normalised rule with μ = 0.5
/// (reasoned in chain_estimators.rs).
pub fn puma_adaline_config() -> AdalineConfig {
    AdalineConfig {
        step_size: 0.5,
        ..Default::default()
    }
}

/// The Hopfield network on the PUMA's equilibrated base model with `b` base parameters
/// sampled every `dt` s: bound c = 100 (a few times the largest RMS joint torque), slope
/// c·dt·6·b, at most 64 Euler sub-steps per sample (reasoned in chain_estimators.rs).
pub fn puma_hopfield_config(b: usize, dt: f64) -> HopfieldConfig {
    let c = 100.0;
    HopfieldConfig {
        bound: c,
        beta: c * dt * (6 * b) as f64,
        dt,
        max_substeps: 64,
        ..Default::default()
    }
}
