//! The causal low-pass's cut-off chosen from the log's own sensor noise.
//!
//! The regression's accelerations are s²·H·q (or s·H·q̇ with measured velocities): white
//! position noise of σ (rad or m) at a row every h s passes into them with variance
//! ≈ σ²·h·ω_c^(2k+1)/(8·sin(3π/8)) (k = 2; k = 1 for velocities), ω_c = 2π·f_c, for the
//! 4th-order Butterworth pattern of [`super::CausalLowPass`] well below the Nyquist
//! frequency ([`acceleration_noise_var`]). Least squares reads that noise in the
//! regressor as a smaller inertia (the attenuation bias, ≈ (noise/signal)² of the
//! acceleration columns). At 10 Hz it is small for the 1 kHz logs of torque-controlled
//! arms, but 0.12 rad/s² for 1e-4 rad at 100 Hz: on a Unitree Z1 simulated so (joint
//! accelerations 0.2–0.7 rad/s² RMS) `prrrp track` ended 2.8–5.1 % off on joints 2–4 at
//! 10 Hz and 0.8–2.0 % (the batch fit's 0.9–2.1 %) at 5 Hz; with 1e-5 rad both cut-offs
//! gave the batch fit's errors (docs/design/online.md, "The cut-off from the sensor
//! noise").
//!
//! So the identifier starts at the highest cut-off and, after [`DECIDE_AFTER`] s of
//! filtered rows, lowers it once to the highest at which every joint's acceleration noise
//! is at most [`NOISE_TO_SIGNAL`] of its acceleration RMS (or of [`SIGNAL_FLOOR`], for a
//! joint that moves less), never below [`LOWEST`] of the highest. The noise comes from the
//! divided differences of the raw samples (third of positions, second of velocities), on
//! each row's own time stamps.

/// Largest acceleration noise allowed, as a fraction of the acceleration RMS: an
/// attenuation bias of about 1 % of the inertias.
pub(crate) const NOISE_TO_SIGNAL: f64 = 0.1;

/// Acceleration RMS (rad/s² or m/s²) assumed for a joint that moves less during the
/// choice: a log that starts at rest must not drive the cut-off down to the lowest.
pub(crate) const SIGNAL_FLOOR: f64 = 0.3;

/// Seconds of filtered rows before the choice.
pub(crate) const DECIDE_AFTER: f64 = 1.0;

/// Lowest cut-off, as a fraction of the highest: below it the filter's departure from a
/// pure delay over the motion's band is no longer negligible.
pub(crate) const LOWEST: f64 = 0.25;

/// Raw samples (differences) needed for the noise estimate.
const MIN_DIFFERENCES: usize = 32;

/// A window of divided differences whose longest spacing exceeds this many times its
/// shortest (a gap, a burst of rows) is left out of the noise estimate: its coefficients
/// weigh the signal's own derivative in.
const SPACING_RATIO: f64 = 4.0;

/// Variance of the acceleration noise (units of the samples per s^k, squared) that white
/// sample noise of variance `var` at a row every `h` s leaves after the low-pass of
/// cut-off `hz`: `order` 3 for positions (k = 2), 2 for velocities (k = 1).
///
/// The filter sees the samples joined by straight lines (its first-order hold), whose
/// spectrum is var·h·sinc⁴(f·h); through s^k·H that is 2·var·h·∫₀^∞ (2πf)^(2k)·|H|²·
/// sinc⁴(f·h) df, |H|² = 1/(1 + (f/f_c)⁸). Integrated numerically (Simpson, 25 points per
/// f_c up to 40 f_c, where the integrand has fallen by 40⁴); far below the Nyquist
/// frequency it is var·h·ω_c^(2k+1)/(8·sin(3π/8)).
pub(crate) fn acceleration_noise_var(var: f64, h: f64, hz: f64, order: usize) -> f64 {
    let k = if order == 3 { 2 } else { 1 };
    let top = 40.0 * hz;
    let steps = 1000;
    let df = top / steps as f64;
    let f = |x: f64| {
        let w = 2.0 * std::f64::consts::PI * x;
        let arg = std::f64::consts::PI * x * h;
        let sinc = if arg == 0.0 { 1.0 } else { arg.sin() / arg };
        w.powi(2 * k) / (1.0 + (x / hz).powi(8)) * sinc.powi(4)
    };
    let mut sum = f(0.0) + f(top);
    for i in 1..steps {
        sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(i as f64 * df);
    }
    2.0 * var * h * sum * df / 3.0
}

/// The choice (module docs). Allocation-free after construction.
#[derive(Debug, Clone)]
pub(crate) struct CutoffChoice {
    /// Highest cut-off, Hz.
    highest: f64,
    /// 3: positions (third differences), 2: velocities (second differences).
    order: usize,
    /// The last `order + 1` time stamps and samples per joint (oldest first).
    times: [f64; 4],
    values: Vec<[f64; 4]>,
    held: usize,
    /// Per joint Σ d²/Σc² over the windows used, and their count.
    noise: Vec<f64>,
    windows: usize,
    /// Σ of the spacings of the windows used (for the mean spacing h).
    spacing: f64,
    /// Per joint ∫ a² dt over the filtered rows, and their duration (s).
    signal: Vec<f64>,
    filtered: f64,
    chosen: Option<f64>,
}

impl CutoffChoice {
    /// For `n` joints, starting at `highest` Hz.
    pub(crate) fn new(n: usize, highest: f64) -> Self {
        Self {
            highest,
            order: 3,
            times: [0.0; 4],
            values: vec![[0.0; 4]; n],
            held: 0,
            noise: vec![0.0; n],
            windows: 0,
            spacing: 0.0,
            signal: vec![0.0; n],
            filtered: 0.0,
            chosen: None,
        }
    }

    /// Sets what the raw samples are: velocities (second differences) or positions.
    pub(crate) fn measured_velocity(&mut self, yes: bool) {
        self.order = if yes { 2 } else { 3 };
    }

    /// One raw sample at time `t` (a new time stamp): positions, or velocities when
    /// measured.
    pub(crate) fn sample(&mut self, t: f64, x: &[f64]) {
        if self.chosen.is_some() {
            return;
        }
        let m = self.order + 1;
        let slot = if self.held < m {
            self.held += 1;
            self.held - 1
        } else {
            self.times.copy_within(1..m, 0);
            for v in &mut self.values {
                v.copy_within(1..m, 0);
            }
            m - 1
        };
        self.times[slot] = t;
        for (v, xi) in self.values.iter_mut().zip(x) {
            v[slot] = *xi;
        }
        if self.held < m {
            return;
        }
        let ts = &self.times[..m];
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for w in ts.windows(2) {
            lo = lo.min(w[1] - w[0]);
            hi = hi.max(w[1] - w[0]);
        }
        // Times strictly increase (repeated rows never get here): lo > 0.
        if hi > SPACING_RATIO * lo {
            return;
        }
        // Divided difference Σ c_i·x_i, c_i = 1/Π_{k≠i}(t_i − t_k): white noise of
        // variance σ² gives it σ²·Σc_i²; a smooth signal x^(m−1)/(m−1)!, far smaller.
        let mut c = [0.0; 4];
        let mut c2 = 0.0;
        for i in 0..m {
            let mut p = 1.0;
            for k in 0..m {
                if k != i {
                    p *= ts[i] - ts[k];
                }
            }
            c[i] = 1.0 / p;
            c2 += c[i] * c[i];
        }
        for (acc, v) in self.noise.iter_mut().zip(&self.values) {
            let d: f64 = (0..m).map(|i| c[i] * v[i]).sum();
            *acc += d * d / c2;
        }
        self.windows += 1;
        self.spacing += (ts[m - 1] - ts[0]) / (m - 1) as f64;
    }

    /// One filtered row `dt` s after the previous one: its accelerations.
    pub(crate) fn filtered(&mut self, dt: f64, a: &[f64]) {
        if self.chosen.is_some() {
            return;
        }
        for (s, ai) in self.signal.iter_mut().zip(a) {
            *s += ai * ai * dt;
        }
        self.filtered += dt;
    }

    /// The cut-off (Hz) once [`DECIDE_AFTER`] s of filtered rows are in, `None` before
    /// (and after: the choice is made once).
    pub(crate) fn decide(&mut self) -> Option<f64> {
        if self.chosen.is_some() || self.filtered < DECIDE_AFTER || self.windows < MIN_DIFFERENCES {
            return None;
        }
        let h = self.spacing / self.windows as f64;
        // The noise is var_j·g(f_c) with g rising in f_c: the cut-off is where g meets the
        // tightest joint's allowance.
        let g = |hz: f64| acceleration_noise_var(1.0, h, hz, self.order);
        let g_top = g(self.highest);
        let mut budget = f64::INFINITY;
        for j in 0..self.noise.len() {
            let var = self.noise[j] / self.windows as f64;
            let rms = (self.signal[j] / self.filtered - var * g_top)
                .max(0.0)
                .sqrt();
            let allowed = NOISE_TO_SIGNAL * rms.max(SIGNAL_FLOOR);
            if var > 0.0 {
                budget = budget.min(allowed * allowed / var);
            }
        }
        let (mut lo, mut hi) = (LOWEST * self.highest, self.highest);
        if g(hi) > budget {
            if g(lo) >= budget {
                hi = lo;
            } else {
                // 16 halvings: within 1e-4 Hz. The row that decides costs ≈ 0.6 ms (18
                // integrals; timed once on the development machine, against ≈ 4 ms with
                // 4000 points and 30 halvings): a one-off step in a real-time loop.
                for _ in 0..16 {
                    let mid = 0.5 * (lo + hi);
                    if g(mid) > budget {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                hi = lo;
            }
        }
        let hz = hi;
        self.chosen = Some(hz);
        Some(hz)
    }

    /// What the choice saw, for the settings record: per joint the noise σ of the raw
    /// samples (their units) and the acceleration RMS of the filtered rows.
    pub(crate) fn report(&self) -> serde_json::Value {
        let w = self.windows.max(1) as f64;
        let f = self.filtered.max(f64::MIN_POSITIVE);
        serde_json::json!({
            "highest_hz": self.highest,
            "chosen_hz": self.chosen,
            "noise_of": if self.order == 3 { "positions" } else { "velocities" },
            "sample_noise": self.noise.iter().map(|v| (v / w).sqrt()).collect::<Vec<_>>(),
            "acceleration_rms": self.signal.iter().map(|v| (v / f).sqrt()).collect::<Vec<_>>(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::online::CausalLowPass;
    use rand::rngs::StdRng;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// The noise formula against white noise through the filter itself (Monte Carlo), for
    /// positions and velocities, at two cut-offs.
    #[test]
    fn acceleration_noise_matches_the_filtered_white_noise() {
        let mut rng = StdRng::seed_from_u64(3);
        let d = Normal::new(0.0, 1.0).unwrap();
        let (h, rows) = (0.01, 200_000);
        for (order, hz) in [(3, 10.0), (3, 5.0), (2, 10.0), (2, 4.0)] {
            let velocity = order == 2;
            let mut lp = CausalLowPass::new(1, hz, velocity).unwrap();
            let (mut qf, mut vf, mut af, mut tf) = ([0.0], [0.0], [0.0], [0.0]);
            let mut sum = 0.0;
            let mut count = 0usize;
            for k in 0..rows {
                let x = [d.sample(&mut rng)];
                let (q, qd) = if velocity {
                    ([0.0], Some(&x[..]))
                } else {
                    (x, None)
                };
                lp.update(h, &q, &[0.0], qd, &mut qf, &mut vf, &mut af, &mut tf)
                    .unwrap();
                if k > 1000 {
                    sum += af[0] * af[0];
                    count += 1;
                }
            }
            let measured = sum / count as f64;
            let predicted = acceleration_noise_var(1.0, h, hz, order);
            let rel = (measured / predicted - 1.0).abs();
            assert!(
                rel < 0.05,
                "order {order}, {hz} Hz: {measured} against {predicted}"
            );
        }
    }

    /// The noise estimate on a moving signal with jittered time stamps, and the choice
    /// against the rule it states.
    #[test]
    fn noise_estimate_and_choice() {
        let mut rng = StdRng::seed_from_u64(5);
        let d = Normal::new(0.0f64, 1.0).unwrap();
        for (sigma, expect_lower) in [(1e-4, true), (1e-6, false)] {
            let mut c = CutoffChoice::new(2, 10.0);
            let mut t = 0.0f64;
            for _ in 0..300 {
                t += 0.01 * (1.0 + 0.2 * d.sample(&mut rng).clamp(-2.0, 2.0));
                // 0.5 rad/s² RMS-ish motion at 0.4 and 0.7 Hz.
                let q = [
                    0.8 * (2.5 * t).sin() + sigma * d.sample(&mut rng),
                    0.3 * (4.4 * t).cos() + sigma * d.sample(&mut rng),
                ];
                c.sample(t, &q);
                c.filtered(0.01, &[0.5, 0.1]);
            }
            let report = c.report();
            for s in report["sample_noise"].as_array().unwrap() {
                let s = s.as_f64().unwrap();
                assert!(
                    (s / sigma - 1.0).abs() < 0.15 || sigma < 1e-5 && s < 1e-5,
                    "{s}"
                );
            }
            let hz = c.decide().unwrap();
            assert_eq!(hz < 10.0, expect_lower, "{hz}");
            if expect_lower {
                // Joint 2 (0.1 rad/s² < the floor) binds: its noise at the chosen cut-off
                // is the floor's tenth, unless the lowest cut-off is reached.
                let var = report["sample_noise"][1].as_f64().unwrap().powi(2);
                let noise = acceleration_noise_var(var, 0.01, hz, 3).sqrt();
                let bound = NOISE_TO_SIGNAL * SIGNAL_FLOOR;
                assert!(
                    hz == 2.5 || (noise / bound - 1.0).abs() < 0.05,
                    "{noise} {hz}"
                );
            }
        }
    }
}
