//! Sensitivity of the simulated robot to its parameters (paper Table 6 and Fig. 8).
//!
//! Each λᵢ in turn is scaled over a range around its nominal value (default ±50 %) while
//! the others stay nominal; the robot with the varied λ follows the validation reference
//! under the nominal controller, and the RMS of its joint trajectories against the
//! nominal run measures how much the motion depends on λᵢ.

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::types::{Lambda, NDOF, NPARAM};
use crate::motion::simulation::{simulate_closed_loop, SensorNoise, SimulationConfig};
use crate::validation::metrics::rms;
use crate::validation::ValidationConfig;

/// Settings of [`sensitivity`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensitivityConfig {
    /// Relative half-range of the variation (default 0.5, i.e. ±50 % as in the paper).
    pub range: f64,
    /// Points per parameter, including both ends and the nominal value when odd
    /// (default 11: steps of 10 %).
    pub points: usize,
    /// Reference, duration and controller of the runs (default
    /// [`ValidationConfig::default`]); sensor noise is not used.
    pub validation: ValidationConfig,
    /// Worker threads (default 0 = all available cores).
    pub threads: usize,
}

impl Default for SensitivityConfig {
    fn default() -> Self {
        Self {
            range: 0.5,
            points: 11,
            validation: ValidationConfig::default(),
            threads: 0,
        }
    }
}

/// Result of [`sensitivity`].
#[derive(Debug, Clone, PartialEq)]
pub struct SensitivityReport {
    /// Scale factors applied to each λᵢ (e.g. 0.5, 0.6, …, 1.5).
    pub factors: Vec<f64>,
    /// The range of each λᵢ actually used: (minimum, maximum) (Table 6).
    pub ranges: [(f64, f64); NPARAM],
    /// `rms[i][k][j]`: trajectory RMS of joint j (m or rad) against the nominal run when λᵢ
    /// is scaled by `factors[k]`; `None` where the varied λ is not physical (M(q, λ) not
    /// positive definite somewhere along the motion), so that no robot has it.
    pub rms: Vec<Vec<Option<[f64; NDOF]>>>,
}

/// Runs the sensitivity sweep around `nominal`, in parallel over the available cores.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] for a range outside (0, 1) or fewer than 2 points;
/// errors of the nominal simulation (e.g. a non-physical nominal λ). Non-physical varied
/// λ are reported as `None` in the result, not as errors.
pub fn sensitivity(
    model: &PrrrpModel,
    nominal: &Lambda,
    config: &SensitivityConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SensitivityReport> {
    if !(config.range > 0.0 && config.range < 1.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "range".into(),
            value: config.range,
            reason:
                "the relative half-range must lie in (0, 1) so that every varied λ stays positive",
        });
    }
    if config.points < 2 {
        return Err(PrrrpError::InvalidParameter {
            field: "points".into(),
            value: config.points as f64,
            reason: "need at least 2 points per parameter",
        });
    }
    crate::interrupt::check_count(
        "points",
        config.points as f64 * NPARAM as f64,
        "points × 8 parameters exceeds MAX_SAMPLES (1e7) runs: use fewer points",
    )?;
    let v = &config.validation;
    let sim = SimulationConfig {
        noise: SensorNoise::none(),
        ..v.simulation
    };
    let nominal_run =
        simulate_closed_loop(model, nominal, nominal, &v.reference, v.duration, &sim)?;
    let factors: Vec<f64> = (0..config.points)
        .map(|k| 1.0 - config.range + 2.0 * config.range * k as f64 / (config.points - 1) as f64)
        .collect();
    let mut ranges = [(0.0, 0.0); NPARAM];
    for (i, r) in ranges.iter_mut().enumerate() {
        let (a, b) = (
            nominal[i] * factors[0],
            nominal[i] * factors[config.points - 1],
        );
        *r = (a.min(b), a.max(b));
    }

    // One job per (parameter, factor); workers take jobs by index.
    let jobs: Vec<(usize, usize)> = (0..NPARAM)
        .flat_map(|i| (0..config.points).map(move |k| (i, k)))
        .collect();
    let threads = match config.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .min(jobs.len());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let run_job = |(i, k): (usize, usize)| -> Result<Option<[f64; NDOF]>> {
        let mut lambda = *nominal;
        lambda[i] *= factors[k];
        match simulate_closed_loop(model, &lambda, nominal, &v.reference, v.duration, &sim) {
            Ok(run) => {
                let mut out = [0.0; NDOF];
                for (j, o) in out.iter_mut().enumerate() {
                    let a: Vec<f64> = nominal_run.q.iter().map(|x| x[j]).collect();
                    let b: Vec<f64> = run.q.iter().map(|x| x[j]).collect();
                    *o = rms(&a, &b)?;
                }
                Ok(Some(out))
            }
            Err(PrrrpError::NotPositiveDefinite { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    };
    type JobResult = (usize, Result<Option<[f64; NDOF]>>);
    // Workers stop with the caller's stop flag.
    let flag = crate::interrupt::current();
    let results: Vec<Vec<JobResult>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                let flag = flag.clone();
                s.spawn(|| {
                    crate::interrupt::within(flag, || {
                        let mut mine = Vec::new();
                        loop {
                            let idx = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            if idx >= jobs.len() {
                                break;
                            }
                            mine.push((idx, run_job(jobs[idx])));
                            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                            progress(d, jobs.len());
                        }
                        mine
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_default())
            .collect()
    });
    // Workers drain the remaining jobs quickly once interrupted; report that, not the
    // first job's error.
    crate::interrupt::check("sensitivity")?;
    let mut rms_table = vec![vec![None; config.points]; NPARAM];
    let mut seen = 0;
    for (idx, r) in results.into_iter().flatten() {
        let (i, k) = jobs[idx];
        rms_table[i][k] = r?;
        seen += 1;
    }
    if seen != jobs.len() {
        return Err(PrrrpError::Diverged {
            what: "sensitivity sweep",
            at: seen,
            hint: "a worker thread stopped early; this is a bug, please report it",
        });
    }
    Ok(SensitivityReport {
        factors,
        ranges,
        rms: rms_table,
    })
}
