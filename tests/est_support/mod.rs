//! Test data for the estimator tests, generated here from physics (the closed-form model
//! of prrrp-core with the paper's parameters), independently of the trajectory crate:
//! - an excitation trajectory given analytically as a finite Fourier series per joint
//!   (q, q̇, q̈ exact), with τ from the inverse dynamics at the true λ;
//! - a closed-loop simulation (RK4 on the forward dynamics, PD tracking plus feed-forward
//!   held over each sample) for the Kalman filter, which only sees q and τ.
#![allow(dead_code)]

// Each support module is included on its own by tests and benches, so a test that takes
// two of them holds two copies of these free functions.
#[allow(clippy::duplicate_mod)]
#[path = "../seeded_support/mod.rs"]
mod seeded_support;

use prrrp_core::{Lambda, PrrrpModel, Robot, Vec5};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Sample period, s (the paper's).
pub const DT: f64 = 0.02;

/// The paper's robot: its model and its true base parameters.
pub fn paper() -> (PrrrpModel, Lambda) {
    let robot = Robot::paper();
    (robot.model(), robot.base_parameters())
}

/// A smooth periodic excitation: q_j(t) = c_j + Σ_k a_jk·sin(k·ω·t + φ_jk), five
/// harmonics of a 10 s fundamental, coefficients drawn once from a seeded generator.
#[derive(Debug, Clone)]
pub struct Fourier {
    omega: f64,
    offset: [f64; 5],
    amp: [[f64; 5]; 5],
    phase: [[f64; 5]; 5],
}

impl Fourier {
    /// Seeded coefficients; joint amplitudes ≈ 0.1 m (d1), 1 rad (θ2..θ4), 0.05 m (d5).
    pub fn new(seed: u64) -> Self {
        let scale = [0.1, 1.0, 1.0, 1.0, 0.05];
        let offset = [0.2, 0.0, 0.3, -0.4, 0.05];
        let mut amp = [[0.0; 5]; 5];
        let mut phase = [[0.0; 5]; 5];
        seeded_support::draw(seed, &scale, &mut amp, &mut phase);
        Self {
            omega: 2.0 * std::f64::consts::PI / 10.0,
            offset,
            amp,
            phase,
        }
    }

    /// (q, q̇, q̈) at time t.
    pub fn eval(&self, t: f64) -> (Vec5, Vec5, Vec5) {
        let mut q = Vec5::from(self.offset);
        let mut qd = Vec5::zeros();
        let mut qdd = Vec5::zeros();
        let (amp, phase) = (&self.amp, &self.phase);
        let (q_, qd_, qdd_) = (q.as_mut_slice(), qd.as_mut_slice(), qdd.as_mut_slice());
        seeded_support::add(self.omega, amp, phase, t, q_, qd_, qdd_);
        (q, qd, qdd)
    }
}

/// Owned columns of a dataset.
#[derive(Debug, Clone, Default)]
pub struct Data {
    pub q: Vec<Vec5>,
    pub qd: Vec<Vec5>,
    pub qdd: Vec<Vec5>,
    pub tau: Vec<Vec5>,
}

impl Data {
    pub fn dataset(&self) -> prrrp_core::Samples<'_, 5> {
        prrrp_core::Samples::new(&self.q, &self.qd, &self.qdd, &self.tau).unwrap()
    }

    pub fn len(&self) -> usize {
        self.q.len()
    }
}

/// `n` noise-free samples of the excitation at period `DT`, τ = ID(q, q̇, q̈, λ_true).
pub fn excitation(n: usize, seed: u64) -> Data {
    let (model, lambda) = paper();
    let traj = Fourier::new(seed);
    let mut d = Data::default();
    for k in 0..n {
        let (q, qd, qdd) = traj.eval(k as f64 * DT);
        d.tau.push(model.inverse_dynamics(&q, &qd, &qdd, &lambda));
        d.q.push(q);
        d.qd.push(qd);
        d.qdd.push(qdd);
    }
    d
}

/// Measurement noise levels (standard deviations) of [`add_noise`].
#[derive(Debug, Clone, Copy)]
pub struct Noise {
    /// Encoder noise, m or rad.
    pub q: f64,
    /// Velocity after differentiation and zero-phase filtering, m/s or rad/s.
    pub qd: f64,
    /// Acceleration after differentiation and filtering, m/s² or rad/s².
    pub qdd: f64,
    /// Torque noise as a fraction of each joint's RMS torque.
    pub tau_rel: f64,
}

impl Noise {
    /// Levels typical of a lab arm: 16-bit encoders, filtered derivatives, current-based
    /// torques with a few percent noise.
    pub fn realistic() -> Self {
        Self {
            q: 1e-4,
            qd: 5e-3,
            qdd: 5e-2,
            tau_rel: 0.03,
        }
    }

    /// Torque noise only, `tau_rel` times each joint's RMS torque; exact q, q̇, q̈.
    pub fn torque_only(tau_rel: f64) -> Self {
        Self {
            q: 0.0,
            qd: 0.0,
            qdd: 0.0,
            tau_rel,
        }
    }
}

/// Adds seeded Gaussian noise; returns the noisy copy and the per-joint τ noise σ used.
pub fn add_noise(d: &Data, noise: Noise, seed: u64) -> (Data, Vec5) {
    let mut rng = StdRng::seed_from_u64(seed);
    let n = d.len() as f64;
    let mut rms = Vec5::zeros();
    for t in &d.tau {
        rms += t.component_mul(t);
    }
    let sigma_tau = (rms / n).map(|v| v.sqrt() * noise.tau_rel);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut draw = |s: f64| s * unit.sample(&mut rng);
    let mut out = d.clone();
    for k in 0..d.len() {
        for j in 0..5 {
            out.q[k][j] += draw(noise.q);
            out.qd[k][j] += draw(noise.qd);
            out.qdd[k][j] += draw(noise.qdd);
            out.tau[k][j] += draw(sigma_tau[j]);
        }
    }
    (out, sigma_tau)
}

/// A closed-loop run of the true robot tracking the excitation under computed-torque
/// control: every `dt` the controller computes τ = ID(q, q̇, q̈_ref + Kp·e + Kd·ė; λ) from
/// the measured state (e = q_ref − q, 5 rad/s bandwidth, critically damped) and holds it;
/// the plant integrates the forward dynamics by RK4 with `substeps` steps per sample.
/// Returns the sampled q, q̇ (true, noise-free), the held τ, and q̈ = 0 placeholders (the
/// Kalman filter ignores q̈).
pub fn closed_loop(n: usize, seed: u64, substeps: usize, dt: f64) -> Data {
    let (model, lambda) = paper();
    let traj = Fourier::new(seed);
    let (wn, zeta) = (5.0, 1.0);
    let (mut q, mut qd, _) = traj.eval(0.0);
    let h = dt / substeps as f64;
    let f = |q: &Vec5, qd: &Vec5, tau: &Vec5| -> (Vec5, Vec5) {
        (*qd, model.forward_dynamics(q, qd, tau, &lambda).unwrap())
    };
    let mut d = Data::default();
    for k in 0..n {
        let (qr, qdr, qddr) = traj.eval(k as f64 * dt);
        let a = qddr + wn * wn * (qr - q) + 2.0 * zeta * wn * (qdr - qd);
        let tau = model.inverse_dynamics(&q, &qd, &a, &lambda);
        d.q.push(q);
        d.qd.push(qd);
        d.qdd.push(Vec5::zeros());
        d.tau.push(tau);
        for _ in 0..substeps {
            let (k1q, k1v) = f(&q, &qd, &tau);
            let (k2q, k2v) = f(&(q + 0.5 * h * k1q), &(qd + 0.5 * h * k1v), &tau);
            let (k3q, k3v) = f(&(q + 0.5 * h * k2q), &(qd + 0.5 * h * k2v), &tau);
            let (k4q, k4v) = f(&(q + h * k3q), &(qd + h * k3v), &tau);
            q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
            qd += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
    }
    d
}

/// Largest relative error max_i |λ̂_i − λ_i|/|λ_i| and the vector of relative errors.
pub fn rel_errors(est: &Lambda, truth: &Lambda) -> (f64, Lambda) {
    let e = est.zip_map(truth, |a, b| (a - b).abs() / b.abs());
    (e.max(), e)
}

/// A vector as one line, e.g. for accuracy tables in test output.
pub fn line<const D: usize>(v: &prrrp_core::nalgebra::SVector<f64, D>) -> String {
    v.iter()
        .map(|x| format!("{x:.2e}"))
        .collect::<Vec<_>>()
        .join(" ")
}
