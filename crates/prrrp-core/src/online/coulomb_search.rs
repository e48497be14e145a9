//! The Coulomb speed scale v_s of fc·tanh(q̇/v_s) chosen online, causally: identifiers
//! of a few candidate scales run side by side over the first seconds of the log, and the
//! one whose one-step-ahead torque predictions were best over a scoring window takes over.
//!
//! Why: from no knowledge the scale of the robot description decides most of the error
//! where a joint reverses (exact sign against 0.01 rad/s: 8.3 % against 3.2 % of RMS
//! torque on a UR5 stand-in), and `prrrp identify` chooses it by cross-validation over the
//! whole log, which an online estimate cannot see. The window starts late enough for the
//! estimates to have converged (scored from the start, wider scales won while all were
//! still transient). Estimates before the choice are those of the robot's own scale; after
//! it, the chosen identifier's, which has seen every row: nothing later changes an
//! earlier estimate. The errors scored are a whole-arm RLS's of each scale whatever the
//! method (an EKF's also carry its filter's start and restarts). Measurements:
//! docs/design/online.md, "The Coulomb scale online".

use serde_json::{json, Value};

/// Candidate speed scales, rad/s (m/s for prismatic joints); 0 = the exact sign. An
/// octave apart over the range `prrrp identify` searches (0.001–0.3): the error of a
/// model is sharply V-shaped in v_s (a UR5 stand-in: 2.3 % at the best 0.014, 3.2 % at
/// 0.01 and 0.02), and candidates half a decade apart (0.003, 0.01, 0.03, 0.1) left the
/// stand-ins 2.8–4.5 % off at the end, against 2.0–2.7 % now (docs/design/online.md).
pub const ONLINE_COULOMB_SCALES: [f64; 10] = [
    0.0, 0.001, 0.002, 0.004, 0.008, 0.016, 0.032, 0.064, 0.128, 0.256,
];

/// Settings of the online choice of the Coulomb scale (s from the first row).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoulombSearch {
    /// Start of the scoring window, s (default `5.0`).
    pub from: f64,
    /// End of the scoring window: the choice is made at the first row at or after it, s
    /// (default `10.0`). Until then every candidate runs (a few times the per-row cost).
    pub at: f64,
}

impl Default for CoulombSearch {
    fn default() -> Self {
        Self {
            from: 5.0,
            at: 10.0,
        }
    }
}

impl CoulombSearch {
    pub(crate) fn validate(&self) -> crate::error::Result<()> {
        if !(self.from.is_finite() && self.from >= 0.0) {
            return Err(crate::error::invalid(
                "coulomb_search.from",
                self.from,
                "must be finite and >= 0 s",
            ));
        }
        if !(self.at.is_finite() && self.at > self.from) {
            return Err(crate::error::invalid(
                "coulomb_search.at",
                self.at,
                "must be finite and after `from`",
            ));
        }
        Ok(())
    }
}

/// The running scores of the candidates (the identifier's own scale first).
/// Allocation-free after construction.
#[derive(Debug, Clone)]
pub(crate) struct Scores {
    pub(crate) search: CoulombSearch,
    /// v_s of each candidate, rad/s.
    pub(crate) scales: Vec<f64>,
    /// Σ over the scored rows of each candidate's squared one-step-ahead errors, per joint
    /// (candidate-major; units of τ²). A candidate that failed is `None`.
    sums: Vec<Option<Vec<f64>>>,
    rows: usize,
    t0: Option<f64>,
}

impl Scores {
    pub(crate) fn new(search: CoulombSearch, scales: Vec<f64>, n: usize) -> Self {
        Self {
            search,
            sums: vec![Some(vec![0.0; n]); scales.len()],
            scales,
            rows: 0,
            t0: None,
        }
    }

    /// Seconds since the first row at time `t`.
    pub(crate) fn elapsed(&mut self, t: f64) -> f64 {
        t - *self.t0.get_or_insert(t)
    }

    /// Whether a row `elapsed` s after the first is scored.
    pub(crate) fn scored(&self, elapsed: f64) -> bool {
        elapsed >= self.search.from && elapsed < self.search.at
    }

    /// Adds candidate `c`'s errors τ − τ̂ of a scored row.
    pub(crate) fn add(&mut self, c: usize, tau: &[f64], pred: &[f64]) {
        if let Some(s) = &mut self.sums[c] {
            for (v, (a, b)) in s.iter_mut().zip(tau.iter().zip(pred)) {
                *v += (a - b) * (a - b);
            }
        }
    }

    /// One more scored row (after every candidate's `add`).
    pub(crate) fn row(&mut self) {
        self.rows += 1;
    }

    /// Drops a candidate whose identifier failed.
    pub(crate) fn fail(&mut self, c: usize) {
        self.sums[c] = None;
    }

    /// Candidate `c`'s score: Σ_j ln(mean squared error of joint j), so that each joint
    /// counts by its relative error whatever its units and size (`None`: failed, or no
    /// scored row).
    fn score(&self, c: usize) -> Option<f64> {
        let s = self.sums[c].as_ref().filter(|_| self.rows > 0)?;
        let rows = self.rows as f64;
        Some(s.iter().map(|v| (v / rows).max(1e-300).ln()).sum())
    }

    /// Every candidate's score (allocates).
    pub(crate) fn scores(&self) -> Vec<Option<f64>> {
        (0..self.sums.len()).map(|c| self.score(c)).collect()
    }

    /// The best candidate (the own scale, 0, when nothing was scored). Allocation-free.
    pub(crate) fn best(&self) -> usize {
        let mut best = (0, f64::INFINITY);
        for c in 0..self.sums.len() {
            if let Some(s) = self.score(c).filter(|s| s.is_finite()) {
                if s < best.1 {
                    best = (c, s);
                }
            }
        }
        best.0
    }

    /// The choice for the settings: candidates, scores, the chosen scale and the window.
    pub(crate) fn report(&self, chosen: Option<usize>) -> Value {
        json!({
            "candidates": self.scales,
            "scores": self.scores(),
            "scored_rows": self.rows,
            "window_s": [self.search.from, self.search.at],
            "chosen": chosen.map(|c| self.scales[c]),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_candidate_with_the_smaller_relative_errors_wins() {
        let mut s = Scores::new(CoulombSearch::default(), vec![0.0, 0.01, 0.1], 2);
        // Joint 1 is 100 times larger: candidate 1 is 2x better on joint 0 and 1.2x worse
        // on joint 1, so it wins on relative errors although its absolute sum is larger.
        for _ in 0..10 {
            s.add(0, &[1.0, 100.0], &[0.0, 0.0]);
            s.add(1, &[0.5, 120.0], &[0.0, 0.0]);
            s.add(2, &[2.0, 200.0], &[0.0, 0.0]);
            s.row();
        }
        assert_eq!(s.best(), 1);
        s.fail(1);
        assert_eq!(s.best(), 0);
        assert_eq!(s.report(Some(0))["chosen"], json!(0.0));
    }

    #[test]
    fn nothing_scored_keeps_the_own_scale_and_bad_windows_are_refused() {
        let s = Scores::new(CoulombSearch::default(), vec![0.02, 0.0], 3);
        assert_eq!(s.best(), 0);
        assert!(s.scores().iter().all(Option::is_none));
        for (from, at) in [(-1.0, 2.0), (3.0, 3.0), (0.0, f64::NAN)] {
            assert!(CoulombSearch { from, at }.validate().is_err());
        }
    }
}
