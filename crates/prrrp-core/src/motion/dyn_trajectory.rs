//! Trajectories of a robot of any size, with their parameters given at run time: the
//! per-joint finite Fourier series the field excites robots with ([`FourierTrajectory`]),
//! and a recorded trajectory interpolated between its samples ([`DynSampledTrajectory`]).
//! Sinusoids per joint are a `Vec<`[`crate::Sinusoid`]`>` (see [`DynTrajectory`]).

use crate::error::{PrrrpError, Result};
use crate::motion::trajectory::{hermite_quintic, DynTrajectory, Quintic, ScalarTrajectory};

/// Finite Fourier series of H harmonics per joint with a common base angular frequency
/// ω_f (Swevers et al. 1997), for n joints (n and H at run time):
///
/// ```text
/// q_j(t) = q0_j + Σ_{l=1..H} [ a_jl/(ω_f·l)·sin(ω_f·l·t) − b_jl/(ω_f·l)·cos(ω_f·l·t) ]
/// ```
///
/// The same series as [`crate::FourierSeries`] (one joint, H at compile time). Periodic
/// with period 2π/ω_f, so it is defined for every t ([`DynTrajectory::end_time`] is
/// `None`). It starts at rest when Σ_l a_jl = 0 (velocity) and Σ_l l·b_jl = 0
/// (acceleration).
///
/// ```
/// use prrrp_core::{DynTrajectory, FourierTrajectory};
/// // Two joints, two harmonics of 0.1 Hz; row-major (joint, harmonic) coefficients.
/// let f = FourierTrajectory::new(
///     2.0 * std::f64::consts::PI * 0.1,
///     vec![0.0, 0.5],
///     vec![0.3, -0.3, 0.2, 0.1],
///     vec![0.2, -0.1, 0.0, 0.0],
/// )?;
/// let (mut q, mut qd, mut qdd) = ([0.0; 2], [0.0; 2], [0.0; 2]);
/// f.eval_into(0.0, &mut q, &mut qd, &mut qdd);
/// assert!(qd[0].abs() < 1e-12 && qdd[0].abs() < 1e-12); // starts at rest
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FourierTrajectory {
    omega: f64,
    offsets: Vec<f64>,
    harmonics: usize,
    a: Vec<f64>,
    b: Vec<f64>,
}

impl FourierTrajectory {
    /// A series of base angular frequency `omega` (rad/s, > 0), offsets q0 (n entries; m
    /// or rad) and sine and cosine coefficients `a`, `b` (n·H entries, row-major: joint j
    /// harmonic l at `j·H + l`; velocity units, m/s or rad/s).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a non-positive or non-finite ω, no joints or
    /// no harmonics, or (naming the joint's coefficients) a joint whose position, velocity
    /// or acceleration amplitude, Σ(|a|+|b|)/(l·ω), Σ(|a|+|b|) or Σ l·ω·(|a|+|b|), overflows
    /// a double; [`PrrrpError::ShapeMismatch`] if `a` and `b` are not n·H long (H is
    /// `a.len() / n`); [`PrrrpError::NonFinite`] naming the first NaN/∞ coefficient.
    pub fn new(omega: f64, offsets: Vec<f64>, a: Vec<f64>, b: Vec<f64>) -> Result<Self> {
        if !(omega.is_finite() && omega > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "omega".into(),
                value: omega,
                reason: "the base angular frequency must be finite and > 0 rad/s",
            });
        }
        let n = offsets.len();
        if n == 0 {
            return Err(PrrrpError::InvalidParameter {
                field: "offsets".into(),
                value: 0.0,
                reason: "give one offset per joint (at least one joint)",
            });
        }
        let harmonics = a.len() / n;
        if harmonics == 0 || a.len() != n * harmonics {
            return Err(PrrrpError::ShapeMismatch {
                what: "a (Fourier sine coefficients)".into(),
                expected: format!("n·H entries with n = {n} joints and H ≥ 1 harmonics"),
                got: format!("{} entries", a.len()),
            });
        }
        if b.len() != a.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "b (Fourier cosine coefficients)".into(),
                expected: format!("{} entries (as a)", a.len()),
                got: format!("{} entries", b.len()),
            });
        }
        for (name, v) in [("offsets", &offsets), ("a", &a), ("b", &b)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: format!("{name}[{i}]"),
                    row: None,
                });
            }
        }
        // Finite coefficients still overflow q̈ = Σ l·ω·(…) (ω = a = b = 1e300 gave q̈ = ∞)
        // or q = Σ (…)/(l·ω) for a tiny ω; these bounds on |q|, |q̇|, |q̈| keep every
        // evaluation finite.
        for j in 0..n {
            let (mut q, mut qd, mut qdd) = (offsets[j].abs(), 0.0, 0.0);
            for l in 0..harmonics {
                let w = omega * (l + 1) as f64;
                let c = a[j * harmonics + l].abs() + b[j * harmonics + l].abs();
                (q, qd, qdd) = (q + c / w, qd + c, qdd + c * w);
            }
            if !(q.is_finite() && qd.is_finite() && qdd.is_finite()) {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("a, b of joint {j} (with omega)"),
                    value: omega,
                    reason: "the series' position, velocity or acceleration overflows a \
                             double: use smaller coefficients or an omega nearer 1 rad/s",
                });
            }
        }
        Ok(Self {
            omega,
            offsets,
            harmonics,
            a,
            b,
        })
    }

    /// Base angular frequency ω_f, rad/s.
    pub fn omega(&self) -> f64 {
        self.omega
    }

    /// Number of harmonics H.
    pub fn harmonics(&self) -> usize {
        self.harmonics
    }

    /// Offsets q0 (n entries).
    pub fn offsets(&self) -> &[f64] {
        &self.offsets
    }

    /// Sine coefficients, row-major n × H.
    pub fn a(&self) -> &[f64] {
        &self.a
    }

    /// Cosine coefficients, row-major n × H.
    pub fn b(&self) -> &[f64] {
        &self.b
    }
}

impl DynTrajectory for FourierTrajectory {
    fn dof(&self) -> usize {
        self.offsets.len()
    }

    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let h = self.harmonics;
        for (j, ((q, qd), qdd)) in q.iter_mut().zip(qd).zip(qdd).enumerate().take(self.dof()) {
            let (mut p, mut v, mut acc) = (self.offsets[j], 0.0, 0.0);
            for l in 0..h {
                let w = self.omega * (l + 1) as f64;
                let (s, c) = (w * t).sin_cos();
                let (a, b) = (self.a[j * h + l], self.b[j * h + l]);
                p += (a * s - b * c) / w;
                v += a * c + b * s;
                acc += w * (b * c - a * s);
            }
            (*q, *qd, *qdd) = (p, v, acc);
        }
    }
}

/// A recorded trajectory of n joints: time stamps with positions, velocities and
/// accelerations, interpolated between samples by the quintic that matches (q, q̇, q̈)
/// at both ends of each interval, so the reference a controller sees is C² and exact at
/// every sample.
///
/// Times are taken relative to the first sample (a log starting at t = 12.5 s is
/// followed from t = 0), and the trajectory ends at the last sample
/// ([`DynTrajectory::end_time`]).
#[derive(Debug, Clone, PartialEq)]
pub struct DynSampledTrajectory {
    n: usize,
    t: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
}

impl DynSampledTrajectory {
    /// From time stamps `t` (s, strictly increasing, at least 2) and row-major
    /// (samples × n) q, q̇, q̈.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for n = 0; [`PrrrpError::TooFewSamples`] for fewer
    /// than 2 samples; [`PrrrpError::ShapeMismatch`] naming a column that is not n per
    /// time stamp; [`PrrrpError::NonFinite`] naming the column and row of a NaN/∞;
    /// [`PrrrpError::NonIncreasingTime`] with the first row whose time is not larger than
    /// the previous one.
    pub fn new(n: usize, t: Vec<f64>, q: Vec<f64>, qd: Vec<f64>, qdd: Vec<f64>) -> Result<Self> {
        if n == 0 {
            return Err(PrrrpError::InvalidParameter {
                field: "n (joints)".into(),
                value: 0.0,
                reason: "a trajectory needs at least one joint",
            });
        }
        let rows = t.len();
        if rows < 2 {
            return Err(PrrrpError::TooFewSamples {
                needed: 2,
                got: rows,
            });
        }
        for (name, v) in [("q", &q), ("qd", &qd), ("qdd", &qdd)] {
            if v.len() != rows * n {
                return Err(PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("{rows} × {n} values (one row per time stamp)"),
                    got: format!("{} values", v.len()),
                });
            }
        }
        if let Some(row) = t.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "t".into(),
                row: Some(row),
            });
        }
        for (name, v) in [("q", &q), ("qd", &qd), ("qdd", &qdd)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: format!("{name}[{}] (joint {})", i % n, i % n + 1),
                    row: Some(i / n),
                });
            }
        }
        if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(PrrrpError::NonIncreasingTime { row: k + 1 });
        }
        let t0 = t[0];
        let t = t.into_iter().map(|x| x - t0).collect();
        Ok(Self { n, t, q, qd, qdd })
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Always false (a sampled trajectory has at least 2 samples).
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Time stamps relative to the first, s.
    pub fn t(&self) -> &[f64] {
        &self.t
    }
}

impl DynTrajectory for DynSampledTrajectory {
    fn dof(&self) -> usize {
        self.n
    }

    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let (n, k_max) = (self.n, self.t.len() - 1);
        // The interval [t_k, t_{k+1}] holding t; before the start or after the end, the
        // first or last interval's quintic is extrapolated.
        let k = self.t[1..k_max].partition_point(|&tk| tk <= t);
        let (t0, t1) = (self.t[k], self.t[k + 1]);
        let h = t1 - t0;
        for (j, ((q, qd), qdd)) in q.iter_mut().zip(qd).zip(qdd).enumerate().take(n) {
            let (a, b) = (k * n + j, (k + 1) * n + j);
            let coeffs = hermite_quintic(
                h,
                (self.q[a], self.qd[a], self.qdd[a]),
                (self.q[b], self.qd[b], self.qdd[b]),
            );
            (*q, *qd, *qdd) = Quintic { t0, coeffs }.eval(t);
        }
    }

    fn end_time(&self) -> Option<f64> {
        self.t.last().copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fourier_series_that_overflow_are_refused() {
        for (omega, c) in [(1e300, 1e300), (1e-300, 1e10)] {
            let got = FourierTrajectory::new(omega, vec![0.0], vec![c], vec![c]);
            assert!(
                matches!(&got, Err(PrrrpError::InvalidParameter { field, .. })
                    if field == "a, b of joint 0 (with omega)"),
                "ω {omega}, a = b = {c}: {got:?}"
            );
        }
        assert!(FourierTrajectory::new(1e3, vec![0.0; 2], vec![1e3; 6], vec![1e3; 6]).is_ok());
    }
}
