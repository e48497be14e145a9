//! Reference trajectories with exact position, velocity and acceleration at any time:
//! quintic polynomials (paper eq. 39), piecewise quintics through via-points, sinusoids
//! and finite Fourier series (Swevers et al. 1997).
//!
//! Every type here is `Copy`, fixed-size, and evaluates without touching the heap.
//!
//! Two trajectory traits: [`DynTrajectory`] for any number of joints known at run time
//! (the simulators take it; values written into slices), and [`JointTrajectory`], the
//! paper arm's five joints as [`Vec5`] values. Every [`JointTrajectory`] is a
//! [`DynTrajectory`] of 5 joints, and a slice or `Vec` of one-joint trajectories
//! ([`ScalarTrajectory`]) is a [`DynTrajectory`] of as many joints.

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::types::{Vec5, NDOF};

/// Position, velocity and acceleration of all joints at one instant
/// (m, rad; m/s, rad/s; m/s², rad/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryPoint {
    /// Joint positions q.
    pub q: Vec5,
    /// Joint velocities q̇.
    pub qd: Vec5,
    /// Joint accelerations q̈.
    pub qdd: Vec5,
}

impl TrajectoryPoint {
    /// All joints at rest at zero, the start of a point filled joint by joint.
    const ZERO: Self = Self {
        q: Vec5::new(0.0, 0.0, 0.0, 0.0, 0.0),
        qd: Vec5::new(0.0, 0.0, 0.0, 0.0, 0.0),
        qdd: Vec5::new(0.0, 0.0, 0.0, 0.0, 0.0),
    };
}

/// A one-joint trajectory: position, velocity and acceleration at time t (s).
pub trait ScalarTrajectory {
    /// (q, q̇, q̈) at time `t`, s. Must not allocate.
    fn eval(&self, t: f64) -> (f64, f64, f64);
}

/// A trajectory of all five joints.
pub trait JointTrajectory {
    /// Positions, velocities and accelerations at time `t`, s. Must not allocate.
    fn eval(&self, t: f64) -> TrajectoryPoint;

    /// The last time at which the trajectory is defined, s; `None` (the default) when it
    /// is defined for every t ≥ 0 (e.g. sinusoids). Simulations refuse to run past it
    /// rather than extrapolate a polynomial.
    fn end_time(&self) -> Option<f64> {
        None
    }
}

/// A trajectory of n joints, n known at run time: what the simulators follow.
///
/// Implementations must not allocate in [`DynTrajectory::eval_into`].
pub trait DynTrajectory {
    /// Number of joints n.
    fn dof(&self) -> usize;

    /// Positions, velocities and accelerations of every joint at time `t` (s), written
    /// into `q`, `qd`, `qdd` (m, rad; m/s, rad/s; m/s², rad/s²), each n entries long
    /// (callers check the lengths once; entries beyond the shorter of a slice and n are
    /// left alone rather than panicking).
    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]);

    /// The last time at which the trajectory is defined, s; `None` (the default) when it
    /// is defined for every t ≥ 0. Simulations refuse to run past it.
    fn end_time(&self) -> Option<f64> {
        None
    }
}

/// The paper arm's trajectories are 5-joint [`DynTrajectory`]s.
impl<T: JointTrajectory + ?Sized> DynTrajectory for T {
    #[inline]
    fn dof(&self) -> usize {
        NDOF
    }

    #[inline]
    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let p = self.eval(t);
        for (dst, src) in [(q, &p.q), (qd, &p.qd), (qdd, &p.qdd)] {
            for (d, s) in dst.iter_mut().zip(src.iter()) {
                *d = *s;
            }
        }
    }

    fn end_time(&self) -> Option<f64> {
        JointTrajectory::end_time(self)
    }
}

/// Independent one-joint trajectories, joint i driven by entry i: e.g. a `Vec` of
/// [`Sinusoid`]s or of [`FourierSeries`] for a robot of any size.
impl<S: ScalarTrajectory> DynTrajectory for [S] {
    #[inline]
    fn dof(&self) -> usize {
        self.len()
    }

    #[inline]
    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for (((s, q), qd), qdd) in self.iter().zip(q).zip(qd).zip(qdd) {
            (*q, *qd, *qdd) = s.eval(t);
        }
    }
}

/// As the slice: one one-joint trajectory per joint.
impl<S: ScalarTrajectory> DynTrajectory for Vec<S> {
    #[inline]
    fn dof(&self) -> usize {
        self.len()
    }

    #[inline]
    fn eval_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        self.as_slice().eval_into(t, q, qd, qdd)
    }
}

/// Five independent one-joint trajectories of the same kind, joint i driven by entry i.
impl<S: ScalarTrajectory> JointTrajectory for [S; NDOF] {
    #[inline]
    fn eval(&self, t: f64) -> TrajectoryPoint {
        let mut p = TrajectoryPoint::ZERO;
        for (j, s) in self.iter().enumerate() {
            (p.q[j], p.qd[j], p.qdd[j]) = s.eval(t);
        }
        p
    }
}

/// A fifth-order polynomial q(t) = Σ aᵢ·(t − t0)ⁱ, i = 0..5 (paper eq. 39 with t0 = 0).
///
/// ```
/// use prrrp_core::{Quintic, ScalarTrajectory};
/// // Rest-to-rest from 0 to 1 rad in 2 s.
/// let p = Quintic::from_boundary(0.0, 2.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))?;
/// let (q, qd, qdd) = p.eval(2.0);
/// assert!((q - 1.0).abs() < 1e-12 && qd.abs() < 1e-12 && qdd.abs() < 1e-12);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quintic {
    /// Time origin t0, s.
    pub t0: f64,
    /// Coefficients a0..a5 (units of q per sⁱ).
    pub coeffs: [f64; 6],
}

impl Quintic {
    /// The polynomial with the given coefficients a0..a5 about t0 = 0 (eq. 39).
    pub const fn new(coeffs: [f64; 6]) -> Self {
        Self { t0: 0.0, coeffs }
    }

    /// The unique quintic with position, velocity and acceleration `start` at `t0` and
    /// `end` at `t1` (each a tuple (q, q̇, q̈)).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] unless t1 > t0 and every input is finite, or (field
    /// `t1 - t0`) if the interval is so short for the change in (q, q̇, q̈) that the
    /// coefficients or the end values overflow a double.
    pub fn from_boundary(
        t0: f64,
        t1: f64,
        start: (f64, f64, f64),
        end: (f64, f64, f64),
    ) -> Result<Self> {
        let vals = [t0, t1, start.0, start.1, start.2, end.0, end.1, end.2];
        if let Some(&v) = vals.iter().find(|v| !v.is_finite()) {
            return Err(PrrrpError::InvalidParameter {
                field: "quintic boundary conditions".into(),
                value: v,
                reason: "times and boundary values must be finite",
            });
        }
        if t1 <= t0 {
            return Err(PrrrpError::InvalidParameter {
                field: "t1".into(),
                value: t1,
                reason: "the end time must be later than the start time t0",
            });
        }
        let h = t1 - t0;
        let coeffs = hermite_quintic(h, start, end);
        check_segment(|| "t1 - t0".into(), h, &coeffs)?;
        Ok(Self { t0, coeffs })
    }
}

/// [`PrrrpError::InvalidParameter`] naming the interval `field()` of length `h` (s) unless
/// the quintic `coeffs` on [0, h] and its values at h are finite: finite boundary values
/// still overflow over an interval of 1e-200 s (h⁵ underflows to 0 at 1e-320 s). The name
/// is formatted only on the error.
fn check_segment(field: impl FnOnce() -> String, h: f64, coeffs: &[f64; 6]) -> Result<()> {
    let (q, qd, qdd) = Quintic::new(*coeffs).eval(h);
    if coeffs.iter().chain(&[q, qd, qdd]).all(|c| c.is_finite()) {
        return Ok(());
    }
    Err(PrrrpError::InvalidParameter {
        field: field(),
        value: h,
        reason: "too short for the change in (q, q̇, q̈) between its ends: the quintic's \
                 coefficients overflow; lengthen the interval (s) or shrink the change",
    })
}

/// Coefficients of the quintic on [0, h] matching (q, q̇, q̈) at both ends.
#[inline]
pub(crate) fn hermite_quintic(
    h: f64,
    (q0, v0, a0): (f64, f64, f64),
    (q1, v1, a1): (f64, f64, f64),
) -> [f64; 6] {
    let d = q1 - q0;
    let (h2, h3) = (h * h, h * h * h);
    [
        q0,
        v0,
        0.5 * a0,
        (20.0 * d - (8.0 * v1 + 12.0 * v0) * h - (3.0 * a0 - a1) * h2) / (2.0 * h3),
        (-30.0 * d + (14.0 * v1 + 16.0 * v0) * h + (3.0 * a0 - 2.0 * a1) * h2) / (2.0 * h3 * h),
        (12.0 * d - 6.0 * (v1 + v0) * h + (a1 - a0) * h2) / (2.0 * h3 * h2),
    ]
}

impl ScalarTrajectory for Quintic {
    #[inline]
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let s = t - self.t0;
        let [a0, a1, a2, a3, a4, a5] = self.coeffs;
        // Horner's scheme for the polynomial and its two derivatives.
        let q = a0 + s * (a1 + s * (a2 + s * (a3 + s * (a4 + s * a5))));
        let qd = a1 + s * (2.0 * a2 + s * (3.0 * a3 + s * (4.0 * a4 + s * 5.0 * a5)));
        let qdd = 2.0 * a2 + s * (6.0 * a3 + s * (12.0 * a4 + s * 20.0 * a5));
        (q, qd, qdd)
    }
}

/// Piecewise quintic through K via-points: each segment is the quintic matching position,
/// velocity and acceleration at its two knots, so the whole curve is continuous up to
/// the acceleration (C²).
///
/// Outside [t₀, t_{K−1}] the first or last segment's polynomial is extrapolated.
///
/// ```
/// use prrrp_core::{PiecewiseQuintic, ScalarTrajectory};
/// let p = PiecewiseQuintic::new(
///     [0.0, 1.0, 3.0],
///     [0.0, 0.5, -0.2],   // q, rad
///     [0.0, 0.3, 0.0],    // q̇, rad/s
///     [0.0, -1.0, 0.0],   // q̈, rad/s²
/// )?;
/// let (q, qd, qdd) = p.eval(1.0);
/// assert!((q - 0.5).abs() < 1e-12 && (qd - 0.3).abs() < 1e-12 && (qdd + 1.0).abs() < 1e-12);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PiecewiseQuintic<const K: usize> {
    times: [f64; K],
    /// Segment k spans [times[k], times[k+1]]; the last entry repeats segment K−2 so the
    /// array can be sized by K on stable Rust.
    segments: [[f64; 6]; K],
}

impl<const K: usize> PiecewiseQuintic<K> {
    /// A piecewise quintic through knots at `times` (s, strictly increasing) with the given
    /// positions, velocities and accelerations.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if K < 2 or a value is not finite, or (field
    /// `times[k+1] - times[k]`) if a segment is so short for its change in (q, q̇, q̈) that
    /// its coefficients overflow; [`PrrrpError::NonIncreasingTime`] with the first knot
    /// whose time is not larger than the previous one.
    pub fn new(times: [f64; K], q: [f64; K], qd: [f64; K], qdd: [f64; K]) -> Result<Self> {
        if K < 2 {
            return Err(PrrrpError::InvalidParameter {
                field: "K (number of knots)".into(),
                value: K as f64,
                reason: "a piecewise quintic needs at least 2 knots",
            });
        }
        for (name, arr) in [("times", &times), ("q", &q), ("qd", &qd), ("qdd", &qdd)] {
            if let Some(k) = arr.iter().position(|v| !v.is_finite()) {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("knot {name}[{k}]"),
                    value: arr[k],
                    reason: "knot values must be finite",
                });
            }
        }
        if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(PrrrpError::NonIncreasingTime { row: k + 1 });
        }
        let mut segments = [[0.0; 6]; K];
        for k in 0..K - 1 {
            let h = times[k + 1] - times[k];
            segments[k] =
                hermite_quintic(h, (q[k], qd[k], qdd[k]), (q[k + 1], qd[k + 1], qdd[k + 1]));
            check_segment(|| format!("times[{}] - times[{k}]", k + 1), h, &segments[k])?;
        }
        segments[K - 1] = segments[K - 2];
        Ok(Self { times, segments })
    }

    /// Knot times, s.
    pub fn times(&self) -> &[f64; K] {
        &self.times
    }

    /// Time span t_{K−1} − t₀, s.
    pub fn duration(&self) -> f64 {
        self.times[K - 1] - self.times[0]
    }

    /// The knots (times, q, q̇, q̈) this curve was built from, e.g. to save or rebuild it
    /// with [`PiecewiseQuintic::new`].
    pub fn knots(&self) -> ([f64; K], [f64; K], [f64; K], [f64; K]) {
        let (mut q, mut qd, mut qdd) = ([0.0; K], [0.0; K], [0.0; K]);
        for k in 0..K {
            (q[k], qd[k], qdd[k]) = self.eval(self.times[k]);
        }
        (self.times, q, qd, qdd)
    }

    /// The polynomial of segment `k` (0 ≤ k ≤ K−2), or `None` if out of range.
    pub fn segment(&self, k: usize) -> Option<Quintic> {
        (k + 1 < K).then(|| Quintic {
            t0: self.times[k],
            coeffs: self.segments[k],
        })
    }
}

impl<const K: usize> ScalarTrajectory for PiecewiseQuintic<K> {
    #[inline]
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        // Index of the segment whose start is the last knot ≤ t, clamped to [0, K−2].
        let k = self.times[1..K - 1].partition_point(|&tk| tk <= t);
        Quintic {
            t0: self.times[k],
            coeffs: self.segments[k],
        }
        .eval(t)
    }
}

/// A sinusoid q(t) = offset + amplitude·sin(omega·t + phase), the paper's reference for the
/// prismatic joints.
///
/// With `phase = −π/2` it starts at rest in velocity (q̇(0) = 0, q̈(0) = amplitude·ω²),
/// and stops at rest after a whole number of periods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sinusoid {
    /// Mean value (m or rad).
    pub offset: f64,
    /// Amplitude (m or rad).
    pub amplitude: f64,
    /// Angular frequency ω, rad/s.
    pub omega: f64,
    /// Phase at t = 0, rad.
    pub phase: f64,
}

impl ScalarTrajectory for Sinusoid {
    #[inline]
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let (s, c) = (self.omega * t + self.phase).sin_cos();
        let w = self.omega;
        (
            self.offset + self.amplitude * s,
            self.amplitude * w * c,
            -self.amplitude * w * w * s,
        )
    }
}

/// A finite Fourier series with H harmonics of the base angular frequency ω_f
/// (Swevers et al. 1997):
///
/// ```text
/// q(t) = q0 + Σ_{l=1..H} [ a_l/(ω_f·l)·sin(ω_f·l·t) − b_l/(ω_f·l)·cos(ω_f·l·t) ]
/// ```
///
/// The series is periodic with period 2π/ω_f. It starts (and, after whole periods, ends)
/// at rest when Σ a_l = 0 (velocity) and Σ l·b_l = 0 (acceleration).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FourierSeries<const H: usize> {
    /// Base angular frequency ω_f, rad/s.
    pub omega: f64,
    /// Constant offset q0 (m or rad).
    pub offset: f64,
    /// Sine coefficients a_l (velocity units: m/s or rad/s).
    pub a: [f64; H],
    /// Cosine coefficients b_l (velocity units: m/s or rad/s).
    pub b: [f64; H],
}

impl<const H: usize> ScalarTrajectory for FourierSeries<H> {
    #[inline]
    fn eval(&self, t: f64) -> (f64, f64, f64) {
        let (mut q, mut qd, mut qdd) = (self.offset, 0.0, 0.0);
        for l in 0..H {
            let w = self.omega * (l + 1) as f64;
            let (s, c) = (w * t).sin_cos();
            let (a, b) = (self.a[l], self.b[l]);
            q += (a * s - b * c) / w;
            qd += a * c + b * s;
            qdd += w * (b * c - a * s);
        }
        (q, qd, qdd)
    }
}

/// The paper's reference trajectory: sinusoids for the prismatic joints 1 and 5 and
/// piecewise quintics with K knots for the revolute joints 2–4 (a single quintic over the
/// horizon, as in eq. 39, is the case K = 2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationTrajectory<const K: usize> {
    /// Joints 1 (d1) and 5 (d5), in that order.
    pub prismatic: [Sinusoid; 2],
    /// Joints 2, 3, 4 (θ2, θ3, θ4), in that order.
    pub revolute: [PiecewiseQuintic<K>; 3],
}

impl<const K: usize> ExcitationTrajectory<K> {
    /// Span of the revolute joints' knots (the longest), s.
    pub fn duration(&self) -> f64 {
        self.revolute
            .iter()
            .map(PiecewiseQuintic::duration)
            .fold(0.0, f64::max)
    }
}

impl<const K: usize> JointTrajectory for ExcitationTrajectory<K> {
    #[inline]
    fn eval(&self, t: f64) -> TrajectoryPoint {
        let mut p = TrajectoryPoint::ZERO;
        (p.q[0], p.qd[0], p.qdd[0]) = self.prismatic[0].eval(t);
        (p.q[4], p.qd[4], p.qdd[4]) = self.prismatic[1].eval(t);
        for (i, r) in self.revolute.iter().enumerate() {
            (p.q[i + 1], p.qd[i + 1], p.qdd[i + 1]) = r.eval(t);
        }
        p
    }

    fn end_time(&self) -> Option<f64> {
        Some(self.duration())
    }
}

/// A rest-to-rest trajectory played forward and backward in turn, so that it is defined
/// for every t ≥ 0: with D the inner trajectory's end, period 2D, q(t) = q_in(u) for
/// u = t mod 2D ≤ D and q_in(2D − u) beyond (q̇ changes sign, q̈ does not). Why this and
/// not repeating it: an excitation generally does not end where it starts, so a repetition
/// jumps, whereas the reflection is twice continuously differentiable at every turn when
/// the inner trajectory starts and ends at rest (q̇ = 0 there; q̈ is even under time
/// reversal). A recording longer than one excitation is then the same excitation seen
/// again, in the same joint ranges and within the same limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reflected<T> {
    inner: T,
    end: f64,
}

/// Largest end speed of a [`Reflected`] trajectory, relative to its peak speed (the
/// polynomials of an excitation reach rest to round-off; their sinusoids to ~1e-7).
pub const REFLECTED_REST_TOLERANCE: f64 = 1e-4;

impl<T: JointTrajectory> Reflected<T> {
    /// Wraps `inner`, which must have a finite end D > 0 (s) and be at rest at t = 0 and
    /// t = D (|q̇| ≤ [`REFLECTED_REST_TOLERANCE`] of its peak speed, checked on 1000 points).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a trajectory without a finite end or not at
    /// rest at its ends.
    pub fn new(inner: T) -> Result<Self> {
        let end = inner.end_time().unwrap_or(f64::NAN);
        if !(end.is_finite() && end > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "end of the reflected trajectory, s".into(),
                value: end,
                reason: "must be finite and > 0: only a trajectory on [0, D] is reflected",
            });
        }
        let peak = (0..=1000)
            .map(|k| inner.eval(end * k as f64 / 1000.0).qd.amax())
            .fold(0.0, f64::max);
        let ends = inner.eval(0.0).qd.amax().max(inner.eval(end).qd.amax());
        if ends > REFLECTED_REST_TOLERANCE * peak.max(f64::MIN_POSITIVE) {
            return Err(PrrrpError::InvalidParameter {
                field: "end speed of the reflected trajectory, rad/s or m/s".into(),
                value: ends,
                reason: "the trajectory must start and end at rest to be played backward \
                         without a jump in velocity",
            });
        }
        Ok(Self { inner, end })
    }

    /// The inner trajectory's end D (s): half the period.
    pub fn half_period(&self) -> f64 {
        self.end
    }
}

impl<T: JointTrajectory> JointTrajectory for Reflected<T> {
    #[inline]
    fn eval(&self, t: f64) -> TrajectoryPoint {
        let u = t.rem_euclid(2.0 * self.end);
        if u <= self.end {
            self.inner.eval(u)
        } else {
            let mut p = self.inner.eval(2.0 * self.end - u);
            p.qd = -p.qd;
            p
        }
    }
}

/// A trajectory sampled on a time grid: one [`Vec5`] per sample.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SampledTrajectory {
    /// Time stamps, s.
    pub t: Vec<f64>,
    /// Positions (m, rad).
    pub q: Vec<Vec5>,
    /// Velocities (m/s, rad/s).
    pub qd: Vec<Vec5>,
    /// Accelerations (m/s², rad/s²).
    pub qdd: Vec<Vec5>,
}

/// Samples `traj` at t = t0 + k·dt for k = 0..n.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] if `dt` is not finite and positive, `t0` is not finite
/// or `n` exceeds [`crate::MAX_SAMPLES`] (10⁷; checked before anything is allocated);
/// [`PrrrpError::NonFinite`] naming the first sample where the trajectory is NaN/∞.
pub fn sample_trajectory<T: JointTrajectory + ?Sized>(
    traj: &T,
    t0: f64,
    dt: f64,
    n: usize,
) -> Result<SampledTrajectory> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "dt".into(),
            value: dt,
            reason: "the sampling period must be finite and > 0 s",
        });
    }
    if !t0.is_finite() {
        return Err(PrrrpError::InvalidParameter {
            field: "t0".into(),
            value: t0,
            reason: "the start time must be finite",
        });
    }
    // The four buffers are reserved up front: 1e8 samples aborted on allocation.
    crate::interrupt::check_count(
        "n",
        n as f64,
        "asks for more than MAX_SAMPLES (1e7) samples: sample fewer points or split the span",
    )?;
    let mut out = SampledTrajectory {
        t: Vec::with_capacity(n),
        q: Vec::with_capacity(n),
        qd: Vec::with_capacity(n),
        qdd: Vec::with_capacity(n),
    };
    for k in 0..n {
        let t = t0 + dt * k as f64;
        let p = traj.eval(t);
        let finite = |v: &Vec5| v.iter().all(|x| x.is_finite());
        if !(finite(&p.q) && finite(&p.qd) && finite(&p.qdd)) {
            return Err(PrrrpError::NonFinite {
                what: "trajectory".into(),
                row: Some(k),
            });
        }
        out.t.push(t);
        out.q.push(p.q);
        out.qd.push(p.qd);
        out.qdd.push(p.qdd);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validation::default_validation_reference;

    #[test]
    fn more_samples_than_max_samples_are_refused_before_allocating() {
        let traj = default_validation_reference();
        // Unbounded, usize::MAX panicked on reserving (first, so that the test fails fast).
        for n in [usize::MAX, crate::MAX_SAMPLES + 1] {
            let got = sample_trajectory(&traj, 0.0, 0.01, n);
            assert!(
                matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "n"),
                "{n}: {got:?}"
            );
        }
    }

    #[test]
    fn quintics_whose_coefficients_overflow_are_refused() {
        let got = Quintic::from_boundary(0.0, 1e-200, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0));
        assert!(
            matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "t1 - t0"),
            "{got:?}"
        );
        assert!(Quintic::from_boundary(0.0, 1e-3, (0.0, 0.0, 0.0), (1e-3, 0.0, 0.0)).is_ok());
        let got =
            PiecewiseQuintic::<3>::new([-1.0, 0.0, 1e-320], [0.0, 1.0, 0.0], [0.0; 3], [0.0; 3]);
        assert!(
            matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "times[2] - times[1]"),
            "{got:?}"
        );
        let got = PiecewiseQuintic::<2>::new([0.0, 1e-320], [0.0, 1.0], [0.0; 2], [0.0; 2]);
        assert!(
            matches!(got, Err(PrrrpError::InvalidParameter { .. })),
            "{got:?}"
        );
    }
}
