//! Change detection on the one-step-ahead torque errors (an innovation test), and the
//! running joint noise levels the online estimators weight their equations with.
//!
//! Per joint j the a-priori error e_j = τ_j − τ̂_j (τ̂ from the estimate before the
//! sample) is compared with its predicted variance S_j = σ̂_j² + v_j: σ̂_j² a slow running
//! noise variance (time constant `noise_window`, updated only by samples that pass the
//! test, so that a jump does not inflate it), v_j = κ·φ_jᵀ·P·φ_j the variance the
//! estimate's own uncertainty adds at this sample (φ_j the joint's regressor row, P the
//! estimator's covariance, κ the errors' correlation factor, [`ErrorCorrelation`]) — the
//! standard innovation test. Without v, a model learned from little data alarms on new
//! excitation (directions it has not seen yet), a false change. The normalised innovation
//! s = (1/N)·Σ_j e_j²/S_j has mean ≈ 1 while the model holds; its
//! fast running mean (time constant `window`) above `threshold` is a change of the
//! dynamics: the caller then opens the estimator's covariance, and the test is held off
//! for `holdoff` seconds while the estimate re-converges. The statistic is scale-free
//! (each joint in its own noise units), so one threshold serves N·m and N alike.

use crate::error::Result;

/// Settings of [`ChangeDetector`] (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChangeDetection {
    /// Time constant of the fast mean of the normalised innovation, s (default `0.05`).
    pub window: f64,
    /// Time constant of the running joint noise variances, s (default `2.0`).
    pub noise_window: f64,
    /// Alarm level of the fast mean (dimensionless, default `9.0`: a torque error three
    /// times the running noise level on every joint, or larger on some).
    pub threshold: f64,
    /// No second alarm within this time after one, s (default `0.5`).
    pub holdoff: f64,
    /// No alarm before this time from the start, s (default `2.0`): the estimate is
    /// still converging then.
    pub warmup: f64,
}

impl Default for ChangeDetection {
    fn default() -> Self {
        Self {
            window: 0.05,
            noise_window: 2.0,
            threshold: 9.0,
            holdoff: 0.5,
            warmup: 2.0,
        }
    }
}

/// The running test of [`ChangeDetection`] (module docs). Allocation-free after
/// construction.
#[derive(Debug, Clone)]
pub struct ChangeDetector {
    config: ChangeDetection,
    /// Running noise variance per joint (units of τ_j²).
    var: Vec<f64>,
    fast: f64,
    age: f64,
    since_alarm: f64,
    started: bool,
    alarms: usize,
    /// Last errors normalised by the noise levels alone.
    last: f64,
    /// No alarm while set ([`ChangeDetector::hold`]).
    held: bool,
}

impl ChangeDetector {
    /// A detector for `n` joints; `initial_sd`: noise standard deviations to start from
    /// (e.g. a prior model's residual RMS), or `None` to start from the first errors.
    ///
    /// # Errors
    /// [`crate::PrrrpError::ShapeMismatch`] unless `initial_sd` has `n` entries (a
    /// longer or shorter one set the detector's joint count instead of `n`);
    /// [`crate::PrrrpError::InvalidParameter`] for an entry that is not finite and >= 0
    /// (units of τ).
    pub fn new(n: usize, config: ChangeDetection, initial_sd: Option<&[f64]>) -> Result<Self> {
        if let Some(s) = initial_sd {
            crate::error::check_joints("initial_sd", s.len(), n)?;
            crate::error::check_non_negative(
                "initial_sd",
                s,
                "a noise standard deviation must be finite and >= 0 (units of τ)",
            )?;
        }
        let var = match initial_sd {
            Some(s) => s.iter().map(|v| v * v).collect(),
            None => vec![0.0; n],
        };
        Ok(Self {
            config,
            started: initial_sd.is_some(),
            var,
            fast: 1.0,
            age: 0.0,
            since_alarm: f64::INFINITY,
            alarms: 0,
            last: 1.0,
            held: false,
        })
    }

    /// While `held`, samples update the statistic and the noise levels but raise no
    /// alarm; a change still present alarms at the first sample after the hold. The
    /// online identifier holds the test while a look at an earlier alarm is pending: its
    /// hold-off and the look have the same length, and an alarm on the look's last row
    /// (a matter of the time stamps' round-off) replaced the look before its verdict.
    pub fn hold(&mut self, held: bool) {
        self.held = held;
    }

    /// Running noise variance of each joint's equation (units of τ²).
    pub fn variances(&self) -> &[f64] {
        &self.var
    }

    /// Number of alarms so far.
    pub fn alarms(&self) -> usize {
        self.alarms
    }

    /// The fast mean of the normalised innovation e²/S (≈ 1 while the model holds).
    pub fn statistic(&self) -> f64 {
        self.fast
    }

    /// The last sample's errors normalised by the noise levels alone, (1/N)·Σ_j e_j²/σ̂_j²
    /// (≈ 1 for a converged estimate; the alarm's statistic also adds the model's
    /// variance).
    pub fn last(&self) -> f64 {
        self.last
    }

    /// Whether the warm-up is over and the last sample passed the test: its errors are
    /// the noise of a converged estimate, neither a start transient nor a jump.
    pub fn settled(&self) -> bool {
        self.started && self.age >= self.config.warmup && self.last < self.config.threshold
    }

    /// Consumes the a-priori errors `e` of a sample taken `dt` s after the previous one;
    /// returns whether a change is detected (an alarm). `floor`: smallest variance per
    /// joint (units of τ²), so that exact data do not divide by zero; `model_var`: the
    /// variance the estimate's uncertainty adds to each joint's error (units of τ², ≥ 0;
    /// zeros for a method without a covariance). Allocation-free.
    ///
    /// # Errors
    /// [`crate::PrrrpError::ShapeMismatch`] unless `e`, `floor` and `model_var` have one
    /// entry per joint (the shortest set the joints tested, silently);
    /// [`crate::PrrrpError::InvalidParameter`] for a `dt` that is not finite and >= 0
    /// (s). The detector is left as it was.
    pub fn update(&mut self, dt: f64, e: &[f64], floor: &[f64], model_var: &[f64]) -> Result<bool> {
        let n = self.var.len();
        for (what, v) in [("e", e), ("floor", floor), ("model_var", model_var)] {
            crate::error::check_joints(what, v.len(), n)?;
        }
        super::kinematics::check_step(dt)?;
        let c = &self.config;
        if !self.started {
            for (v, (x, f)) in self.var.iter_mut().zip(e.iter().zip(floor)) {
                *v = (x * x).max(*f);
            }
            self.started = true;
            return Ok(false);
        }
        self.age += dt;
        self.since_alarm += dt;
        let n = e.len().max(1) as f64;
        let (mut stat, mut noise) = (0.0, 0.0);
        for ((x, v), (f, m)) in e.iter().zip(&self.var).zip(floor.iter().zip(model_var)) {
            let v = v.max(*f);
            stat += x * x / (v + m.max(0.0));
            noise += x * x / v;
        }
        let (stat, noise) = (stat / n, noise / n);
        self.last = noise;
        let af = 1.0 - (-dt / c.window).exp();
        self.fast += af * (stat - self.fast);
        // The noise levels take only errors that are noise against the levels alone (the
        // test before the model's variance): errors an uncertain estimate explains are
        // not sensor noise, and taking them lowered a joint's weight exactly while the
        // estimate re-converged (a friction jump then ended 3.6 % off instead of < 3 %).
        // Ungated during the warm-up: a level started from one small error would
        // otherwise refuse every later (normal) error as a jump and never grow.
        if self.age < c.warmup || noise < c.threshold {
            let a = 1.0 - (-dt / c.noise_window).exp();
            for (v, (x, f)) in self.var.iter_mut().zip(e.iter().zip(floor)) {
                *v = (*v + a * (x * x - *v)).max(*f);
            }
        }
        let alarm = !self.held
            && self.age >= c.warmup
            && self.since_alarm >= c.holdoff
            && self.fast > c.threshold;
        if alarm {
            self.alarms += 1;
            self.since_alarm = 0.0;
            self.fast = 1.0;
        }
        Ok(alarm)
    }
}

/// The running integrated autocorrelation time κ of the normalised equation errors
/// u_j = e_j/σ_j, by batch means: κ ≈ L·E[ū²]/E[u²] for blocks of L samples with mean ū
/// (pooled over the joints). A recursive estimator's own covariance assumes white errors;
/// the online estimators regress low-passed signals, whose errors are correlated over
/// about a cut-off period (tens of samples), so their σ is too small by about √κ:
/// measured on 10 seeded 10 s logs of a gripped part (RLS, payload mode), the RMS of
/// (π̂ − π)/σ̂ was 1.5–5 per parameter. The batch counterpart, on a whole residual
/// array, is `identification::ekf_defaults::correlation_time`. Allocation-free after
/// construction.
#[derive(Debug, Clone)]
pub struct ErrorCorrelation {
    /// Block length, s.
    block: f64,
    /// Time constant of the running means over blocks, s.
    memory: f64,
    sum: Vec<f64>,
    squares: f64,
    count: usize,
    elapsed: f64,
    block_mean_sq: f64,
    sample_sq: f64,
    started: bool,
    factor: f64,
}

impl ErrorCorrelation {
    /// For `n` joints, blocks of `block` s, running means over `memory` s (both > 0).
    pub fn new(n: usize, block: f64, memory: f64) -> Self {
        Self {
            block,
            memory,
            sum: vec![0.0; n],
            squares: 0.0,
            count: 0,
            elapsed: 0.0,
            block_mean_sq: 0.0,
            sample_sq: 0.0,
            started: false,
            factor: 1.0,
        }
    }

    /// κ (≥ 1; 1 until the first block is complete): the factor on the variances of a
    /// filter that treats these errors as white.
    pub fn factor(&self) -> f64 {
        self.factor
    }

    /// Consumes the errors `e` of a sample `dt` s after the previous one, normalised by
    /// the variances `var` (units of e², at least `floor`).
    pub fn update(&mut self, dt: f64, e: &[f64], var: &[f64], floor: &[f64]) {
        let n = self.sum.len();
        for j in 0..n {
            let u = e[j] / var[j].max(floor[j]).sqrt();
            self.sum[j] += u;
            self.squares += u * u;
        }
        self.count += 1;
        self.elapsed += dt;
        if self.elapsed < self.block {
            return;
        }
        let l = self.count as f64;
        let mean_sq = self.sum.iter().map(|s| (s / l).powi(2)).sum::<f64>() / n as f64;
        let (m, s) = (l * mean_sq, self.squares / (l * n as f64));
        if self.started {
            let a = 1.0 - (-self.elapsed / self.memory).exp();
            self.block_mean_sq += a * (m - self.block_mean_sq);
            self.sample_sq += a * (s - self.sample_sq);
        } else {
            (self.block_mean_sq, self.sample_sq, self.started) = (m, s, true);
        }
        if self.sample_sq > 0.0 && self.block_mean_sq.is_finite() {
            self.factor = (self.block_mean_sq / self.sample_sq).max(1.0);
        }
        self.sum.fill(0.0);
        (self.squares, self.count, self.elapsed) = (0.0, 0, 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PrrrpError;

    /// Seeded zero-mean, unit-variance uniform noise (an LCG).
    fn uniform_noise(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
        }
    }

    /// A two-joint detector that has learned white errors of 0.1 over 5 s at 1 kHz (no
    /// alarm on the way), with the noise source that continues them.
    fn settled_on_white_errors(seed: u64) -> (ChangeDetector, impl FnMut() -> f64) {
        let mut d = ChangeDetector::new(2, ChangeDetection::default(), Some(&[0.1, 0.1])).unwrap();
        let mut noise = uniform_noise(seed);
        for _ in 0..5000 {
            let e = [0.1 * noise(), 0.1 * noise()];
            assert!(!d.update(1e-3, &e, &[1e-12; 2], &[0.0; 2]).unwrap());
        }
        (d, noise)
    }

    /// White errors of constant size never alarm; a jump to ten times the size alarms
    /// within a few windows, and the noise level has not absorbed the jump by then.
    #[test]
    fn alarms_on_a_jump_only() {
        let mut d = ChangeDetector::new(3, ChangeDetection::default(), None).unwrap();
        let mut noise = uniform_noise(7);
        let floor = [1e-12; 3];
        let dt = 1e-3;
        for _ in 0..20000 {
            let e = [0.1 * noise(), 0.01 * noise(), 2.0 * noise()];
            assert!(!d.update(dt, &e, &floor, &[0.0; 3]).unwrap());
        }
        assert!((d.variances()[0] / 0.01 - 1.0).abs() < 0.3);
        let mut first = None;
        for k in 0..2000 {
            let e = [1.0 * noise() + 0.5, 0.01 * noise(), 2.0 * noise()];
            if d.update(dt, &e, &floor, &[0.0; 3]).unwrap() && first.is_none() {
                first = Some((k, d.variances()[0]));
            }
        }
        let (k, var) = first.expect("no alarm");
        assert!(k < 100, "{k}");
        // Until the alarm the level has not absorbed the jump (a sustained one is
        // absorbed over the 2 s memory afterwards: the estimator has re-converged by then).
        assert!(var < 0.02, "{var}");
    }

    /// A held detector raises no alarm however large the errors, and a jump still present
    /// alarms at the first sample after the hold; the same errors without the hold alarm
    /// during it.
    #[test]
    fn a_held_test_alarms_after_the_hold() {
        for held in [true, false] {
            let (mut d, _) = settled_on_white_errors(5);
            let floor = [1e-12; 2];
            let dt = 1e-3;
            d.hold(held);
            let during = (0..300).any(|_| d.update(dt, &[2.0, -2.0], &floor, &[0.0; 2]).unwrap());
            assert_eq!(during, !held);
            if held {
                d.hold(false);
                assert!(d.update(dt, &[2.0, -2.0], &floor, &[0.0; 2]).unwrap());
                assert_eq!(d.alarms(), 1);
            }
        }
    }

    /// The estimate's own prediction variance is part of the test: errors ten times the
    /// noise level alarm when the model claims to know the sample (v = 0), and not when
    /// its covariance predicts them (v = 100·σ², an unexcited direction of a model learned
    /// from little data).
    #[test]
    fn model_variance_widens_the_test() {
        for (v, want) in [(0.0, true), (1.0, false)] {
            let (mut d, mut noise) = settled_on_white_errors(3);
            let floor = [1e-12; 2];
            let dt = 1e-3;
            let alarmed = (0..2000).any(|_| {
                let e = [1.0 * noise(), 1.0 * noise()];
                d.update(dt, &e, &floor, &[v; 2]).unwrap()
            });
            assert_eq!(alarmed, want, "v = {v}");
        }
    }

    /// κ of white errors is 1; of AR(1) errors e_k = ρ·e_k−1 + w_k it is the integrated
    /// autocorrelation time (1 + ρ)/(1 − ρ) (19 for ρ = 0.9), within the batch-means
    /// estimator's spread.
    #[test]
    fn correlation_time_of_white_and_ar1_errors() {
        let mut s: u64 = 11;
        let mut normal = || {
            // Sum of 12 uniforms − 6: unit variance, close enough to normal here.
            (0..12)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (s >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let dt = 1e-3;
        for (rho, want) in [(0.0, 1.0), (0.9, 19.0)] {
            let mut c = ErrorCorrelation::new(2, 0.5, 20.0);
            let (mut e1, mut e2) = (0.0, 0.0);
            for _ in 0..200_000 {
                e1 = rho * e1 + normal();
                e2 = rho * e2 + 3.0 * normal();
                let var = [1.0 / (1.0 - rho * rho), 9.0 / (1.0 - rho * rho)];
                c.update(dt, &[e1, e2], &var, &[1e-12; 2]);
            }
            let k = c.factor();
            assert!(
                k / want > 0.6 && k / want < 1.5,
                "ρ = {rho}: κ = {k}, want {want}"
            );
        }
    }

    /// Mismatched lengths are refused: a short initial σ set the joint count, and short
    /// errors, floors or model variances made `update` test only the joints they covered.
    #[test]
    fn mismatched_lengths_are_refused() {
        let cfg = ChangeDetection::default();
        let short = ChangeDetector::new(3, cfg, Some(&[0.1, 0.1]));
        assert!(
            matches!(&short, Err(PrrrpError::ShapeMismatch { what, .. }) if what == "initial_sd"),
            "{short:?}"
        );
        let nan = ChangeDetector::new(2, cfg, Some(&[0.1, f64::NAN]));
        let named = matches!(&nan, Err(PrrrpError::InvalidParameter { field, .. })
            if field == "initial_sd[1]");
        assert!(named, "{nan:?}");
        let mut d = ChangeDetector::new(3, cfg, None).unwrap();
        let f = [1e-12; 3];
        for (e, floor, m, what) in [
            (&[1.0; 2][..], &f[..], &[0.0; 3][..], "e"),
            (&[1.0; 3][..], &f[..2], &[0.0; 3][..], "floor"),
            (&[1.0; 3][..], &f[..], &[0.0; 4][..], "model_var"),
        ] {
            let got = d.update(1e-3, e, floor, m);
            assert!(
                matches!(&got, Err(PrrrpError::ShapeMismatch { what: w, .. }) if w == what),
                "{what}: {got:?}"
            );
        }
        let back = d.update(-1.0, &[1.0; 3], &f, &[0.0; 3]);
        assert!(
            matches!(back, Err(PrrrpError::InvalidParameter { .. })),
            "{back:?}"
        );
        assert!(!d.update(1e-3, &[1.0; 3], &f, &[0.0; 3]).unwrap());
        assert_eq!(d.variances(), &[1.0; 3]);
    }
}
