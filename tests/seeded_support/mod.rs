//! Seeded test signals, written once for the tests and their support modules: the Fourier
//! excitation of the data sets, q_j(t) = c_j + Σ_k a_jk·sin(k·ω·t + φ_jk) with five
//! harmonics (Swevers et al. 1997), and a small LCG for random states independent of
//! every library's sampler.
#![allow(dead_code)]

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Draws the amplitudes and phases of five harmonics per joint from `seed`: amplitude of
/// harmonic k of joint j in `scale[j]`·[0.3, 1]/k/2 (falling with k so that accelerations
/// stay moderate), phase uniform in [0, 2π). `amp` and `phase` have one row per joint.
pub fn draw(seed: u64, scale: &[f64], amp: &mut [[f64; 5]], phase: &mut [[f64; 5]]) {
    let mut rng = StdRng::seed_from_u64(seed);
    for j in 0..scale.len() {
        for k in 0..5 {
            let u: f64 = rng.random();
            let p: f64 = rng.random();
            amp[j][k] = scale[j] * (0.3 + 0.7 * u) / (k as f64 + 1.0) / 2.0;
            phase[j][k] = 2.0 * std::f64::consts::PI * p;
        }
    }
}

/// Adds the series of fundamental `omega` (rad/s) at time t (s) to `q` and its exact
/// derivatives to `qd` and `qdd` (one entry per joint).
pub fn add(
    omega: f64,
    amp: &[[f64; 5]],
    phase: &[[f64; 5]],
    t: f64,
    q: &mut [f64],
    qd: &mut [f64],
    qdd: &mut [f64],
) {
    for j in 0..amp.len() {
        for k in 0..5 {
            let w = (k as f64 + 1.0) * omega;
            let (s, c) = (w * t + phase[j][k]).sin_cos();
            let a = amp[j][k];
            q[j] += a * s;
            qd[j] += a * w * c;
            qdd[j] -= a * w * w * s;
        }
    }
}

/// Uniform numbers in [0, 1) from a 64-bit LCG (Knuth's MMIX constants) seeded with
/// `seed`: 53 high bits per draw.
pub fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}
