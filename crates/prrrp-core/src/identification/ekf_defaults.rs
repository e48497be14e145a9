//! What the defaults of `identify` take from the data (see [`super::identify`]): the
//! EKF's measurement noise of the positions and velocities, and how many samples the
//! least-squares residuals stay correlated over (for the LS and EKF covariances). Kept out
//! of the filter's per-step code ([`crate::DynEkf`]), which only receives the numbers.
//!
//! - **Measurement noise R** per joint from the third difference of the signal, which
//!   annihilates quadratics: σ̂² = mean(Δ³x²)/20, so the filter trusts smooth data and
//!   does not trust noisy data.
//! - **Correlation time κ** of the least-squares residuals (Geyer's initial positive
//!   sequence): a zero-phase low-pass makes n samples worth ≈ n/κ independent ones, so
//!   the reported covariance is P_λ·κ.
//!
//! Derivations: docs/design/identify-methods.md.

/// Per-joint noise standard deviation of a flat row-major signal (samples × n) from its
/// third difference (see the module docs), in the signal's units; `floor` for fewer than
/// 4 samples or a zero result.
pub(super) fn third_difference_noise(x: &[f64], n: usize, floor: f64) -> Vec<f64> {
    let samples = x.len() / n.max(1);
    (0..n)
        .map(|j| {
            if samples < 4 {
                return floor;
            }
            let at = |k: usize| x[k * n + j];
            let mut sum = 0.0;
            for k in 2..samples - 1 {
                let d = at(k + 1) - 3.0 * at(k) + 3.0 * at(k - 1) - at(k - 2);
                sum += d * d;
            }
            let s = (sum / (samples - 3) as f64 / 20.0).sqrt();
            if s.is_finite() {
                s.max(floor)
            } else {
                floor
            }
        })
        .collect()
}

/// Correlation time κ ≥ 1 (samples) of flat row-major residuals (samples × n), see the
/// module docs. Lags up to samples/4 (and at most 5000) are summed.
pub(super) fn correlation_time(r: &[f64], n: usize) -> f64 {
    let samples = r.len() / n.max(1);
    if samples < 8 {
        return 1.0;
    }
    let var: Vec<f64> = (0..n)
        .map(|j| (0..samples).map(|k| r[k * n + j].powi(2)).sum::<f64>() / samples as f64)
        .collect();
    let joints: Vec<usize> = (0..n).filter(|&j| var[j] > 0.0).collect();
    if joints.is_empty() {
        return 1.0;
    }
    let rho = |lag: usize| -> f64 {
        joints
            .iter()
            .map(|&j| {
                let c: f64 = (0..samples - lag)
                    .map(|k| r[k * n + j] * r[(k + lag) * n + j])
                    .sum();
                c / (samples as f64 * var[j])
            })
            .sum::<f64>()
            / joints.len() as f64
    };
    let max_lag = (samples / 4).min(5000);
    // Geyer's initial positive sequence: pairs Γ_m = ρ(2m+1) + ρ(2m+2) while positive.
    let mut kappa = 1.0;
    let mut lag = 1;
    while lag < max_lag {
        let pair = rho(lag) + rho(lag + 1);
        if pair.is_nan() || pair <= 0.0 {
            break;
        }
        kappa += 2.0 * pair;
        lag += 2;
    }
    kappa.max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic uniform noise of unit variance (an LCG), so that the test needs no
    /// RNG crate.
    fn noise(len: usize) -> Vec<f64> {
        let mut s: u64 = 0x2545_f491_4f6c_dd1d;
        (0..len)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
            })
            .collect()
    }

    #[test]
    fn third_difference_recovers_white_noise_on_a_smooth_signal() {
        let h = 1e-3;
        let e = noise(20000);
        let x: Vec<f64> = (0..20000)
            .map(|k| (k as f64 * h).sin() + 1e-4 * e[k])
            .collect();
        let s = third_difference_noise(&x, 1, 1e-15)[0];
        assert!((s / 1e-4 - 1.0).abs() < 0.05, "{s}");
        // A smooth signal alone: ≈ h³·x⃛/√20, far below any sensor noise.
        let smooth: Vec<f64> = (0..20000).map(|k| (k as f64 * h).sin()).collect();
        assert!(third_difference_noise(&smooth, 1, 0.0)[0] < 1e-9);
    }

    #[test]
    fn correlation_time_of_white_and_averaged_noise() {
        let e = noise(40000);
        let white = correlation_time(&e, 1);
        assert!((white - 1.0).abs() < 0.1, "{white}");
        // A moving sum of m white samples has κ = m (triangular autocorrelation).
        let m = 10;
        let avg: Vec<f64> = (0..e.len() - m).map(|k| e[k..k + m].iter().sum()).collect();
        let k = correlation_time(&avg, 1);
        assert!((k / m as f64 - 1.0).abs() < 0.15, "{k}");
    }
}
