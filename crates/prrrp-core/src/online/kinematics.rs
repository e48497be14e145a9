//! Causal joint velocities and accelerations from raw position samples: one small Kalman
//! filter per joint.
//!
//! Each joint runs a Kalman filter on [q, q̇, q̈] (or [q̇, q̈] when velocities are measured)
//! driven by white jerk, discretised exactly over each sample's own Δt; its steady state is
//! a Butterworth-pattern low-pass set by `cutoff_hz` alone. A tracker rather than a causal
//! low-pass plus differences, because the low-pass's group delay puts the regressor behind
//! the torque (a bias for least squares, a lag in the predictions), while the tracker has
//! no steady-state lag up to constant acceleration. A gap longer than half a cut-off period
//! restarts it.
//!
//! Design and numbers: docs/design/online.md.

use nalgebra::{SMatrix, SVector};

use crate::error::{check_joints, invalid, PrrrpError, Result};

/// Refuses a cut-off (Hz) that is not finite and > 0: NaN gave NaN outputs at every
/// sample without a word.
fn check_cutoff(cutoff_hz: f64) -> Result<()> {
    if !(cutoff_hz.is_finite() && cutoff_hz > 0.0) {
        return Err(invalid(
            "cutoff_hz",
            cutoff_hz,
            "the filter's cut-off must be finite and > 0 (Hz)",
        ));
    }
    Ok(())
}

/// Refuses a time step (s) that is NaN, infinite or negative: a negative step ran the
/// filters backwards in time and returned garbage.
pub(super) fn check_step(dt: f64) -> Result<()> {
    if !(dt.is_finite() && dt >= 0.0) {
        return Err(invalid(
            "dt",
            dt,
            "the time since the previous sample must be finite and >= 0 (s)",
        ));
    }
    Ok(())
}

/// Refuses a sample `v` (named `what`) without exactly `n` entries (a short one panicked
/// indexing it), or with a NaN or infinite one. One pass, allocation-free unless it fails.
fn check_input(what: &str, v: &[f64], n: usize) -> Result<()> {
    check_joints(what, v.len(), n)?;
    if let Some(j) = v.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: format!("{what}[{j}]"),
            row: None,
        });
    }
    Ok(())
}

/// Butterworth polynomial of order 4, s⁴ + c3·s³ + c2·s² + c1·s + 1 (ω_c = 1).
const BUTTER4: [f64; 3] = [
    2.613_125_929_752_753,
    3.414_213_562_373_095,
    2.613_125_929_752_753,
];

/// A causal 4th-order Butterworth low-pass of cut-off f_c applied alike to the positions,
/// the joint forces and (when measured) the velocities, giving the filtered q, q̇, q̈ and
/// τ at each row — the regression data of the online estimators.
///
/// The filter is a state-variable filter: its states are the filtered signal and its
/// first three derivatives (scaled by powers of ω_c), so H·q, s·H·q and s²·H·q come out
/// of one filter and are exactly consistent. It is discretised exactly over each
/// sample's own Δt with the input linear between samples (first-order hold), from the
/// matrix exponential of the augmented system, so irregular clocks need no resampling.
/// Why the same filter on both sides: a causal filter delays (≈ 2.6/ω_c, 42 ms at
/// 10 Hz), but τ = Y(q, q̇, q̈)·β filtered is H·τ = Y(H·q, s·H·q, s²·H·q)·β up to the
/// filter's departure from a pure delay over the motion's band (|H| is flat to
/// (f/f_c)⁸), so the delay cancels in the regression. Its q̈ noise falls off above f_c,
/// where a zero-lag tracker's grows with frequency (0.1 rad/s² against 0.005 for a 1e-5
/// rad encoder at 1 kHz, 10 Hz): a regressor noise that least squares turns into a bias
/// of the inertias.
#[derive(Debug, Clone)]
pub struct CausalLowPass {
    n: usize,
    omega: f64,
    measured_velocity: bool,
    /// Per joint: states of the position, force and velocity filters.
    xq: Vec<SVector<f64, 4>>,
    xt: Vec<SVector<f64, 4>>,
    xv: Vec<SVector<f64, 4>>,
    /// Previous inputs (first-order hold).
    uq: Vec<f64>,
    ut: Vec<f64>,
    uv: Vec<f64>,
    /// Discretisation for `h`: x⁺ = Φ·x + g0·u_k + g1·(u_k+1 − u_k).
    h: f64,
    phi: SMatrix<f64, 4, 4>,
    g0: SVector<f64, 4>,
    g1: SVector<f64, 4>,
    started: bool,
    age: f64,
}

impl CausalLowPass {
    /// Filters for `n` joints with cut-off `cutoff_hz` (> 0).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a `cutoff_hz` that is not finite and > 0.
    pub fn new(n: usize, cutoff_hz: f64, measured_velocity: bool) -> Result<Self> {
        check_cutoff(cutoff_hz)?;
        Ok(Self {
            n,
            omega: 2.0 * std::f64::consts::PI * cutoff_hz,
            measured_velocity,
            xq: vec![SVector::zeros(); n],
            xt: vec![SVector::zeros(); n],
            xv: vec![SVector::zeros(); n],
            uq: vec![0.0; n],
            ut: vec![0.0; n],
            uv: vec![0.0; n],
            h: f64::NAN,
            phi: SMatrix::zeros(),
            g0: SVector::zeros(),
            g1: SVector::zeros(),
            started: false,
            age: 0.0,
        })
    }

    /// Longest step (s) that does not restart the filter: half a cut-off period.
    pub fn max_gap(&self) -> f64 {
        std::f64::consts::PI / self.omega
    }

    /// Whether the start transient has decayed: [`crate::SETTLING_PERIODS`] cut-off
    /// periods (as the batch preprocessing trims) since the last (re)start.
    pub fn ready(&self) -> bool {
        // 2π·3 rounds as 6π did: 2π is exact times a power of two.
        self.started
            && self.age * self.omega >= 2.0 * std::f64::consts::PI * crate::SETTLING_PERIODS
    }

    /// Forgets everything; the next sample restarts the filter.
    pub fn reset(&mut self) {
        self.started = false;
        self.age = 0.0;
    }

    /// Moves the cut-off to `cutoff_hz` (> 0) and restarts the filter at the next sample.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a `cutoff_hz` that is not finite and > 0 (the
    /// filter is left as it was).
    pub fn set_cutoff(&mut self, cutoff_hz: f64) -> Result<()> {
        check_cutoff(cutoff_hz)?;
        self.omega = 2.0 * std::f64::consts::PI * cutoff_hz;
        self.h = f64::NAN;
        self.reset();
        Ok(())
    }

    /// The exact discretisation over `h` (recomputed only when h changes).
    fn discretise(&mut self, h: f64) {
        if h == self.h {
            return;
        }
        self.h = h;
        let w = self.omega;
        // Scaled states z = [y, y'/ω, y''/ω², y'''/ω³]: ż = ω·(C·z + e4·u), C the
        // companion matrix of the normalised Butterworth polynomial. Augmented with the
        // input u and its slope v: d/dt [z, u, v] = [[ω·C, ω·e4, 0], [0, 0, 1], [0, 0, 0]].
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        for i in 0..3 {
            m[(i, i + 1)] = w;
        }
        m[(3, 0)] = -w;
        m[(3, 1)] = -w * BUTTER4[2];
        m[(3, 2)] = -w * BUTTER4[1];
        m[(3, 3)] = -w * BUTTER4[0];
        m[(3, 4)] = w;
        m[(4, 5)] = 1.0;
        let e = (m * h).exp();
        self.phi = e.fixed_view::<4, 4>(0, 0).into_owned();
        self.g0 = e.fixed_view::<4, 1>(0, 4).into_owned();
        // The slope is (u_k+1 − u_k)/h.
        self.g1 = e.fixed_view::<4, 1>(0, 5).into_owned() / h;
    }

    /// Consumes one sample taken `dt` s after the previous one (a `dt` above
    /// [`CausalLowPass::max_gap`] restarts; ignored for the first sample after a reset)
    /// and writes the filtered q, q̇, q̈ and τ. Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] unless `q`, `tau`, `qd` (when given) and the four
    /// outputs have n entries; [`PrrrpError::NonFinite`] for a NaN or infinite input;
    /// [`PrrrpError::InvalidParameter`] for a `dt` that is not finite and >= 0, or 0 after
    /// the first sample (a repeated time stamp: the first-order hold divides by it). The
    /// filter is left as it was.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        dt: f64,
        q: &[f64],
        tau: &[f64],
        qd: Option<&[f64]>,
        qf: &mut [f64],
        vf: &mut [f64],
        af: &mut [f64],
        tf: &mut [f64],
    ) -> Result<()> {
        let n = self.n;
        check_step(dt)?;
        if self.started && dt == 0.0 {
            return Err(invalid(
                "dt",
                dt,
                "must be > 0 s after the first sample: a repeated time stamp is not a new \
                 sample (skip it)",
            ));
        }
        check_input("q", q, n)?;
        check_input("tau", tau, n)?;
        if let Some(d) = qd {
            check_input("qd", d, n)?;
        }
        for (what, v) in [("qf", &*qf), ("vf", &*vf), ("af", &*af), ("tf", &*tf)] {
            check_joints(what, v.len(), n)?;
        }
        if self.started && dt > self.max_gap() {
            self.started = false;
        }
        if !self.started {
            // As if the signals had been constant before: the steady state.
            for j in 0..self.n {
                self.xq[j] = SVector::from([q[j], 0.0, 0.0, 0.0]);
                self.xt[j] = SVector::from([tau[j], 0.0, 0.0, 0.0]);
                let v = qd.map_or(0.0, |d| d[j]);
                self.xv[j] = SVector::from([v, 0.0, 0.0, 0.0]);
                (self.uq[j], self.ut[j], self.uv[j]) = (q[j], tau[j], v);
            }
            self.started = true;
            self.age = 0.0;
        } else {
            self.discretise(dt);
            let (phi, g0, g1) = (&self.phi, &self.g0, &self.g1);
            let step = |x: &mut SVector<f64, 4>, u0: &mut f64, u1: f64| {
                *x = phi * *x + g0 * *u0 + g1 * (u1 - *u0);
                *u0 = u1;
            };
            for j in 0..self.n {
                step(&mut self.xq[j], &mut self.uq[j], q[j]);
                step(&mut self.xt[j], &mut self.ut[j], tau[j]);
                if let Some(d) = qd {
                    step(&mut self.xv[j], &mut self.uv[j], d[j]);
                }
            }
            self.age += dt;
        }
        let w = self.omega;
        for j in 0..self.n {
            qf[j] = self.xq[j][0];
            tf[j] = self.xt[j][0];
            if self.measured_velocity {
                vf[j] = self.xv[j][0];
                af[j] = w * self.xv[j][1];
            } else {
                vf[j] = w * self.xq[j][1];
                af[j] = w * w * self.xq[j][2];
            }
        }
        Ok(())
    }
}

/// Per-joint causal estimates of q̇ and q̈ (see the module docs). Allocation-free after
/// construction.
#[derive(Debug, Clone)]
pub struct CausalKinematics {
    n: usize,
    omega: f64,
    measured_velocity: bool,
    /// [q, q̇, q̈] (or [q̇, q̈, -]) per joint.
    x: Vec<[f64; 3]>,
    /// Upper triangle of the 3×3 (or 2×2) covariance per joint: p00, p01, p02, p11, p12,
    /// p22.
    p: Vec<[f64; 6]>,
    started: bool,
    /// Time since the last (re)start, s.
    age: f64,
}

/// Seconds × ω_c after which the filter counts as converged.
const READY_AFTER: f64 = 6.0;

impl CausalKinematics {
    /// Filters for `n` joints with bandwidth `cutoff_hz` (> 0); `measured_velocity`: the
    /// samples carry measured q̇ (then q̇ is used as measured and q̈ estimated from it).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a `cutoff_hz` that is not finite and > 0.
    pub fn new(n: usize, cutoff_hz: f64, measured_velocity: bool) -> Result<Self> {
        check_cutoff(cutoff_hz)?;
        Ok(Self {
            n,
            omega: 2.0 * std::f64::consts::PI * cutoff_hz,
            measured_velocity,
            x: vec![[0.0; 3]; n],
            p: vec![[0.0; 6]; n],
            started: false,
            age: 0.0,
        })
    }

    /// Whether the samples are expected to carry measured velocities.
    pub fn measured_velocity(&self) -> bool {
        self.measured_velocity
    }

    /// Longest step (s) that does not restart the filters: half a cut-off period.
    pub fn max_gap(&self) -> f64 {
        std::f64::consts::PI / self.omega
    }

    /// Whether the estimates have converged since the last (re)start.
    pub fn ready(&self) -> bool {
        self.started && self.age * self.omega >= READY_AFTER
    }

    /// Forgets everything; the next sample restarts the filters.
    pub fn reset(&mut self) {
        self.started = false;
        self.age = 0.0;
    }

    /// The bandwidth, Hz.
    pub fn cutoff_hz(&self) -> f64 {
        self.omega / (2.0 * std::f64::consts::PI)
    }

    /// Moves the bandwidth to `cutoff_hz` (> 0) and restarts the filters at the next
    /// sample.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a `cutoff_hz` that is not finite and > 0 (the
    /// filters are left as they were).
    pub fn set_cutoff(&mut self, cutoff_hz: f64) -> Result<()> {
        check_cutoff(cutoff_hz)?;
        self.omega = 2.0 * std::f64::consts::PI * cutoff_hz;
        self.reset();
        Ok(())
    }

    /// Consumes one sample taken `dt` s after the previous one (ignored for the first
    /// sample after a reset; a `dt` above [`CausalKinematics::max_gap`] restarts) and
    /// writes q̇ and q̈ estimates at its time (rad/s, rad/s², or m/s, m/s²).
    /// Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] unless `q`, `qd` (measured velocities, when given)
    /// and the outputs `v`, `a` have n entries; [`PrrrpError::NonFinite`] for a NaN or
    /// infinite input; [`PrrrpError::InvalidParameter`] for a `dt` that is not finite and
    /// >= 0. The filters are left as they were.
    pub fn update(
        &mut self,
        dt: f64,
        q: &[f64],
        qd: Option<&[f64]>,
        v: &mut [f64],
        a: &mut [f64],
    ) -> Result<()> {
        let n = self.n;
        check_step(dt)?;
        check_input("q", q, n)?;
        if let Some(d) = qd {
            check_input("qd", d, n)?;
        }
        check_joints("v", v.len(), n)?;
        check_joints("a", a.len(), n)?;
        if self.started && dt > self.max_gap() {
            self.started = false;
        }
        let w = self.omega;
        if !self.started {
            // Uninformed about the derivatives: variances far above what one cut-off
            // period of data determines (in units of the measurement variance r = 1).
            for j in 0..self.n {
                let z = if self.measured_velocity {
                    qd.map_or(0.0, |d| d[j])
                } else {
                    q[j]
                };
                self.x[j] = [z, 0.0, 0.0];
                self.p[j] = if self.measured_velocity {
                    [1.0, 0.0, 0.0, 1e8 * w * w, 0.0, 0.0]
                } else {
                    [1.0, 0.0, 0.0, 1e8 * w * w, 0.0, 1e8 * w.powi(4)]
                };
            }
            self.started = true;
            self.age = 0.0;
        } else if self.measured_velocity {
            let s = w.powi(4);
            for j in 0..self.n {
                predict2(&mut self.x[j], &mut self.p[j], dt, s);
                update_first(&mut self.x[j], &mut self.p[j], qd.map_or(0.0, |d| d[j]), 2);
            }
            self.age += dt;
        } else {
            let s = w.powi(6);
            for ((x, p), &qj) in self.x.iter_mut().zip(self.p.iter_mut()).zip(q) {
                predict3(x, p, dt, s);
                update_first(x, p, qj, 3);
            }
            self.age += dt;
        }
        for j in 0..self.n {
            if self.measured_velocity {
                v[j] = qd.map_or(self.x[j][0], |d| d[j]);
                a[j] = self.x[j][1];
            } else {
                v[j] = self.x[j][1];
                a[j] = self.x[j][2];
            }
        }
        Ok(())
    }
}

/// x ← F·x, P ← F·P·Fᵀ + Q for the triple integrator over `h` with jerk density `s`.
#[inline]
fn predict3(x: &mut [f64; 3], p: &mut [f64; 6], h: f64, s: f64) {
    let (h2, h3) = (h * h, h * h * h);
    x[0] += h * x[1] + 0.5 * h2 * x[2];
    x[1] += h * x[2];
    let [p00, p01, p02, p11, p12, p22] = *p;
    // F = [[1, h, h²/2], [0, 1, h], [0, 0, 1]].
    let a02 = p02 + h * p12 + 0.5 * h2 * p22;
    let a01 = p01 + h * p11 + 0.5 * h2 * p12;
    let a00 = p00 + h * p01 + 0.5 * h2 * p02;
    let a12 = p12 + h * p22;
    let a11 = p11 + h * p12;
    let n00 = a00 + h * a01 + 0.5 * h2 * a02;
    let n01 = a01 + h * a02;
    let n11 = a11 + h * a12;
    let q00 = s * h3 * h2 / 20.0;
    let q01 = s * h2 * h2 / 8.0;
    let q02 = s * h3 / 6.0;
    let q11 = s * h3 / 3.0;
    let q12 = s * h2 / 2.0;
    let q22 = s * h;
    *p = [
        n00 + q00,
        n01 + q01,
        a02 + q02,
        n11 + q11,
        a12 + q12,
        p22 + q22,
    ];
}

/// The double integrator [v, a] over `h` with jerk density `s` (entries 0, 1, 3 of p).
#[inline]
fn predict2(x: &mut [f64; 3], p: &mut [f64; 6], h: f64, s: f64) {
    x[0] += h * x[1];
    let (p00, p01, p11) = (p[0], p[1], p[3]);
    let a01 = p01 + h * p11;
    p[0] = p00 + 2.0 * h * p01 + h * h * p11 + s * h * h * h / 3.0;
    p[1] = a01 + s * h * h / 2.0;
    p[3] = p11 + s * h;
}

/// Measurement of the first state with unit variance; `m` states.
#[inline]
fn update_first(x: &mut [f64; 3], p: &mut [f64; 6], z: f64, m: usize) {
    // Column 0 of P: p00, p01, p02 (p02 unused for m = 2).
    let c = [p[0], p[1], if m == 3 { p[2] } else { 0.0 }];
    let s = c[0] + 1.0;
    let e = z - x[0];
    for i in 0..m {
        x[i] += c[i] / s * e;
    }
    // P ← P − c·cᵀ/s on the upper triangle (indices as in `predict3`; for m = 2 the
    // entries 0, 1, 3).
    p[0] -= c[0] * c[0] / s;
    p[1] -= c[0] * c[1] / s;
    p[3] -= c[1] * c[1] / s;
    if m == 3 {
        p[2] -= c[0] * c[2] / s;
        p[4] -= c[1] * c[2] / s;
        p[5] -= c[2] * c[2] / s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On q = sin(ωt) sampled at jittered times, the estimates converge to the true q̇ and
    /// q̈ with the small lag of a tracker whose bandwidth is far above the motion.
    #[test]
    fn tracks_a_sinusoid_on_an_irregular_clock() {
        let mut k = CausalKinematics::new(1, 10.0, false).unwrap();
        let w = 2.0 * std::f64::consts::PI * 0.5;
        let (mut t, mut v, mut a) = (0.0, [0.0], [0.0]);
        let mut s: u64 = 1;
        let mut worst: (f64, f64) = (0.0, 0.0);
        for i in 0..4000 {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            let dt = 5e-4 + 1e-3 * ((s >> 11) as f64 / (1u64 << 53) as f64);
            t += dt;
            k.update(dt, &[(w * t).sin()], None, &mut v, &mut a)
                .unwrap();
            if i > 500 {
                worst.0 = worst.0.max((v[0] - w * (w * t).cos()).abs() / w);
                worst.1 = worst.1.max((a[0] + w * w * (w * t).sin()).abs() / (w * w));
            }
        }
        assert!(k.ready());
        // A third-order tracker follows q to (f/f_c)³ of the amplitude, and loses one
        // order per derivative: q̇ to (f/f_c)² = 2.5e-3, q̈ to f/f_c = 5e-2 (relative).
        assert!(worst.0 < 2.5e-3 && worst.1 < 5e-2, "{worst:?}");
    }

    /// With measured velocities, q̇ passes through and q̈ is its derivative.
    #[test]
    fn measured_velocity_passes_through() {
        let mut k = CausalKinematics::new(2, 10.0, true).unwrap();
        let (mut v, mut a) = ([0.0; 2], [0.0; 2]);
        let mut worst: f64 = 0.0;
        for i in 0..2000 {
            let t = i as f64 * 1e-3;
            let qd = [3.0 * t, -1.0 + 0.5 * t];
            k.update(1e-3, &[0.0, 0.0], Some(&qd), &mut v, &mut a)
                .unwrap();
            assert_eq!(v, qd);
            if i > 300 {
                worst = worst.max((a[0] - 3.0).abs()).max((a[1] - 0.5).abs());
            }
        }
        assert!(worst < 1e-6, "{worst}");
    }

    /// The low-pass's q̇ and q̈ are the derivatives of its q (one filter), and on a slow
    /// sinusoid it is a delay: H·q(t) ≈ q(t − t_d) with t_d the group delay at DC.
    #[test]
    fn low_pass_is_a_consistent_delay() {
        let fc = 10.0;
        let mut f = CausalLowPass::new(1, fc, false).unwrap();
        let w = 2.0 * std::f64::consts::PI * 0.5;
        // Group delay of the 4th-order Butterworth at DC: c3/ω_c.
        let td = BUTTER4[0] / (2.0 * std::f64::consts::PI * fc);
        let (mut qf, mut vf, mut af, mut tf) = ([0.0], [0.0], [0.0], [0.0]);
        let mut t = 0.0;
        let mut s: u64 = 3;
        let mut worst: [f64; 3] = [0.0; 3];
        for i in 0..6000 {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1);
            let dt = 5e-4 + 1e-3 * ((s >> 11) as f64 / (1u64 << 53) as f64);
            t += dt;
            let q = (w * t).sin();
            f.update(
                dt,
                &[q],
                &[2.0 * q],
                None,
                &mut qf,
                &mut vf,
                &mut af,
                &mut tf,
            )
            .unwrap();
            if i > 2000 {
                let d = t - td;
                worst[0] = worst[0].max((qf[0] - (w * d).sin()).abs());
                worst[1] = worst[1].max((vf[0] - w * (w * d).cos()).abs() / w);
                worst[2] = worst[2].max((af[0] + w * w * (w * d).sin()).abs() / (w * w));
                assert!((tf[0] - 2.0 * qf[0]).abs() < 1e-12);
            }
        }
        assert!(f.ready());
        // The departure from a pure delay is O((f/f_c)³) = 1.25e-4.
        assert!(worst.iter().all(|e| *e < 1e-3), "{worst:?}");
    }

    /// A gap restarts the filter (not ready right after it).
    #[test]
    fn a_gap_restarts() {
        let mut k = CausalKinematics::new(1, 10.0, false).unwrap();
        let (mut v, mut a) = ([0.0], [0.0]);
        for _ in 0..500 {
            k.update(1e-3, &[0.0], None, &mut v, &mut a).unwrap();
        }
        assert!(k.ready());
        k.update(1.0, &[0.0], None, &mut v, &mut a).unwrap();
        assert!(!k.ready());
    }

    /// Bad settings and samples are refused with the field to fix, and leave the filters
    /// as they were: a short `q` panicked indexing it, a NaN cut-off gave NaN outputs, a
    /// negative step ran the tracker backwards.
    #[test]
    fn bad_cutoffs_steps_and_samples_are_refused() {
        for hz in [f64::NAN, f64::INFINITY, 0.0, -1.0] {
            let lp = CausalLowPass::new(2, hz, false);
            let named = matches!(&lp, Err(PrrrpError::InvalidParameter { field, .. })
                if field == "cutoff_hz");
            assert!(named, "{hz}: {lp:?}");
            let k = CausalKinematics::new(2, hz, false);
            assert!(
                matches!(k, Err(PrrrpError::InvalidParameter { .. })),
                "{hz}"
            );
        }
        let mut k = CausalKinematics::new(2, 10.0, false).unwrap();
        assert!(k.set_cutoff(f64::NAN).is_err());
        assert_eq!(k.cutoff_hz(), 10.0);
        let (mut v, mut a) = ([0.0; 2], [0.0; 2]);
        let short = k.update(1e-3, &[0.0], None, &mut v, &mut a);
        assert!(matches!(&short, Err(PrrrpError::ShapeMismatch { what, .. }) if what == "q"));
        let nan = k.update(1e-3, &[0.0, f64::NAN], None, &mut v, &mut a);
        assert!(matches!(&nan, Err(PrrrpError::NonFinite { what, .. }) if what == "q[1]"));
        for _ in 0..100 {
            k.update(1e-3, &[0.1, 0.2], None, &mut v, &mut a).unwrap();
        }
        let before = (k.x.clone(), k.age);
        for dt in [-1e-3, f64::NAN] {
            let back = k.update(dt, &[0.1, 0.2], None, &mut v, &mut a);
            assert!(
                matches!(&back, Err(PrrrpError::InvalidParameter { field, .. }) if field == "dt"),
                "{dt}: {back:?}"
            );
        }
        assert_eq!((k.x.clone(), k.age), before);
        let mut short_out = [0.0; 1];
        assert!(k
            .update(1e-3, &[0.1, 0.2], None, &mut short_out, &mut a)
            .is_err());

        let mut lp = CausalLowPass::new(2, 10.0, false).unwrap();
        assert!(lp.set_cutoff(-1.0).is_err());
        let mut o = [[0.0; 2]; 4];
        let [qf, vf, af, tf] = &mut o;
        let short = lp.update(1e-3, &[0.0], &[0.0, 0.0], None, qf, vf, af, tf);
        assert!(matches!(&short, Err(PrrrpError::ShapeMismatch { what, .. }) if what == "q"));
        let short = lp.update(1e-3, &[0.0, 0.0], &[0.0], None, qf, vf, af, tf);
        assert!(matches!(&short, Err(PrrrpError::ShapeMismatch { what, .. }) if what == "tau"));
        let nan = lp.update(
            1e-3,
            &[0.0, 0.0],
            &[f64::INFINITY, 0.0],
            None,
            qf,
            vf,
            af,
            tf,
        );
        assert!(matches!(&nan, Err(PrrrpError::NonFinite { what, .. }) if what == "tau[0]"));
        lp.update(1e-3, &[0.1, 0.2], &[1.0, 2.0], None, qf, vf, af, tf)
            .unwrap();
        // A repeated time stamp divided the hold's slope by 0 (NaN outputs).
        let again = lp.update(0.0, &[0.1, 0.2], &[1.0, 2.0], None, qf, vf, af, tf);
        assert!(
            matches!(again, Err(PrrrpError::InvalidParameter { .. })),
            "{again:?}"
        );
        lp.update(1e-3, &[0.1, 0.2], &[1.0, 2.0], None, qf, vf, af, tf)
            .unwrap();
        assert!(o.iter().flatten().all(|x| x.is_finite()));
    }
}
