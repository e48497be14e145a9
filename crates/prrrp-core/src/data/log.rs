//! Preprocessing of real joint logs: repeated rows, timestamp jitter, gaps, resampling
//! onto a uniform grid, then the shared zero-phase filtering and differentiation.

use crate::data::dataset::{check_dof, check_finite_flat, check_flat_len, DynDataset};
use crate::data::pipeline::{
    check_nyquist, filter_and_differentiate, FilterSettings, Grid, Signals, Source,
};
use crate::error::{invalid, PrrrpError, Result};
use nalgebra::Dyn;

/// Default low-pass cut-off of [`preprocess_log`], Hz, before the cap at a tenth of the
/// output rate (see [`LogConfig::cutoff_hz`]).
///
/// Identification trajectories of industrial arms are band-limited to a few Hz (joint
/// limits and the wish not to excite structural modes, typically above 15–20 Hz), so
/// 10 Hz passes their harmonics with a gain within 1e-4 of 1 up to 3 Hz (order 4), while
/// it removes the measurement noise that differentiation amplifies as f and f².
pub const DEFAULT_LOG_CUTOFF_HZ: f64 = 10.0;

/// Largest ratio of the resampling rate to the log's median rate (100). It bounds the
/// grid, hence memory, to 100 samples per log row; upsampling further adds no
/// information to a linearly interpolated signal.
pub const LOG_MAX_UPSAMPLING: f64 = 100.0;

/// Relative tolerance on the time steps under which a log counts as already uniform and
/// is used without interpolation (1e-6, the tolerance [`crate::preprocess()`] accepts).
pub const LOG_UNIFORM_TOLERANCE: f64 = 1e-6;

/// Settings of [`preprocess_log`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogConfig {
    /// Rate of the uniform grid the log is resampled onto, Hz. `None` (default): the
    /// median sampling rate of the log (1 / median step after dropping repeated rows),
    /// robust to the occasional long step of a jittery logger; with
    /// [`LogConfig::decimate_to_hz`] set, the smallest whole multiple of that output rate
    /// at or above the median rate, so that decimation is exact. At most
    /// [`LOG_MAX_UPSAMPLING`] × the median rate, at least the median rate over it.
    pub rate_hz: Option<f64>,
    /// Low-pass cut-off, Hz. `None` (default): min([`DEFAULT_LOG_CUTOFF_HZ`], f_out/10)
    /// with f_out the output rate (after decimation). The cap at a tenth of the output
    /// rate leaves |H(f_out/2)|² ≤ 1/(1 + 5^(2·order)) (4e-6 at order 4) at the output
    /// Nyquist frequency, so decimation aliases nothing measurable; it is also the
    /// paper arm's 5 Hz at 50 Hz ([`crate::PreprocessConfig`]).
    pub cutoff_hz: Option<f64>,
    /// Butterworth order, 2/4/6/8 (default 4).
    pub order: usize,
    /// Filter the torques with the same filter (default true), so that τ and q̈ see the
    /// same delay-free attenuation. Constant torque-sensor offsets pass unchanged (unit
    /// DC gain): they are not separable from gravity without a model, so identify them
    /// (an offset parameter per joint) or subtract a calibrated value.
    pub filter_torque: bool,
    /// Time dropped at each end after filtering, s. `None` (default): 3 cut-off periods,
    /// 3/f_c, after which the edge transient of the filter (its slowest pole decays as
    /// exp(−2π·f_c·sin(π/(2·order))·t)) has fallen below 1 % for order 4. Rounded up to
    /// whole grid samples, at least 1 (central differences need a neighbour).
    pub trim_s: Option<f64>,
    /// Output rate after filtering, Hz: every d-th grid sample is kept, d a whole number
    /// (see [`LogConfig::rate_hz`]). `None` (default): keep all. The cut-off must lie
    /// below the output Nyquist frequency.
    pub decimate_to_hz: Option<f64>,
    /// Longest accepted time step between kept rows, s. `None` (default): half a cut-off
    /// period, 1/(2·f_c): a longer gap samples the pass band below its Nyquist rate, so
    /// interpolation across it invents the signal rather than recovering it.
    /// `f64::INFINITY` accepts any gap.
    pub max_gap_s: Option<f64>,
    /// Smallest number of output samples (default [`DynDataset::DEFAULT_MIN_SAMPLES`]).
    pub min_samples: usize,
}

impl Default for LogConfig {
    fn default() -> Self {
        Self {
            rate_hz: None,
            cutoff_hz: None,
            order: 4,
            filter_torque: true,
            trim_s: None,
            decimate_to_hz: None,
            max_gap_s: None,
            min_samples: DynDataset::DEFAULT_MIN_SAMPLES,
        }
    }
}

/// What [`preprocess_log`] did to the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogReport {
    /// Rows (time stamps) in the log.
    pub rows_in: usize,
    /// Rows dropped because their time stamp equals the previous row's (the first row
    /// of a run is kept).
    pub repeated_rows: usize,
    /// Of [`LogReport::repeated_rows`], those whose values differ from the kept row.
    pub conflicting_repeats: usize,
    /// 1 / median time step of the kept rows, Hz.
    pub median_rate_hz: f64,
    /// Rate of the uniform grid used, Hz.
    pub rate_hz: f64,
    /// Whether the samples were interpolated onto a new grid (false when the log was
    /// already uniform within [`LOG_UNIFORM_TOLERANCE`] at the rate used).
    pub resampled: bool,
    /// Largest time step between kept rows, s.
    pub largest_gap_s: f64,
    /// Log row that ends the largest step.
    pub largest_gap_row: usize,
    /// Low-pass cut-off used, Hz.
    pub cutoff_hz: f64,
    /// Butterworth order used.
    pub order: usize,
    /// Grid samples dropped at each end.
    pub trim_samples: usize,
    /// The same in seconds, s.
    pub trim_s: f64,
    /// Decimation factor: every `decimation`-th grid sample is kept.
    pub decimation: usize,
    /// Rate of the output, `rate_hz / decimation`, Hz.
    pub output_rate_hz: f64,
    /// Whether q̇ comes from measured velocities (else from differentiating q).
    pub measured_velocity: bool,
    /// Samples in the returned data set.
    pub rows_out: usize,
}

/// Turns a real joint log of `n` joints into a [`DynDataset`] of q, q̇, q̈, τ on a
/// uniform time grid, and says what it did.
///
/// Inputs are flat row-major (rows × n, numpy's layout): `t` holds one time stamp (s)
/// per row, `q` (m, rad), `tau` (N, N·m) and the optional measured velocities `qd`
/// (m/s, rad/s) n values per row. Steps:
/// 1. rows whose time stamp equals the previous row's are dropped (a logger writing
///    the same sample twice); when the values differ the first row is kept; both are
///    counted;
/// 2. the kept rows are resampled onto a uniform grid from the first time stamp at
///    [`LogConfig::rate_hz`] by linear interpolation between the surrounding rows
///    (error at most max|ẍ|·h²/8 for a step h, mostly far above the cut-off and removed
///    by the filter). A log already uniform at that rate is used as it is;
/// 3. zero-phase Butterworth low-pass of q, of the measured q̇ if given, and of τ;
/// 4. q̇ by central differences of the filtered q, or the filtered measured q̇; q̈ by
///    differentiating the filtered q̇ (for a differentiated q̇, the second difference
///    (q_{k+1} − 2q_k + q_{k−1})/dt², the difference of its half-step values);
/// 5. [`LogConfig::trim_s`] dropped at each end, then decimation to
///    [`LogConfig::decimate_to_hz`].
///
/// Memory: a few buffers of O(rows + grid) values plus the output; nothing is allocated
/// per sample, and sizes are checked before allocating.
///
/// ```
/// use prrrp_core::{preprocess_log, LogConfig};
/// // Two joints logged for 3 s with jittery steps of 0.8 and 1.4 ms, the 4th row twice.
/// let n = 2;
/// let mut t: Vec<f64> = (0..3000).map(|k| 1e-3 * k as f64 + 2e-4 * ((2 * k) % 3) as f64).collect();
/// t.insert(4, t[3]);
/// let q: Vec<f64> = t.iter().flat_map(|&t| [(2.0 * t).sin(), t * t]).collect();
/// let tau = vec![0.5; q.len()];
/// let (data, report) = preprocess_log(&t, &q, &tau, None, n, &LogConfig::default())?;
/// assert_eq!(report.repeated_rows, 1);
/// // Resampled at the median rate, 1/0.8 ms, and filtered at 10 Hz.
/// assert!(report.resampled && (report.rate_hz - 1250.0).abs() < 1e-6);
/// let k = data.len() / 2;
/// assert!((data.qdd_row(k)[1] - 2.0).abs() < 1e-3);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
///
/// # Errors
/// - [`PrrrpError::InvalidParameter`] for n = 0; a non-finite or non-positive
///   `rate_hz`, `cutoff_hz`, `decimate_to_hz`, `max_gap_s` or negative `trim_s`; a
///   `rate_hz` above [`LOG_MAX_UPSAMPLING`] × the median rate (or below it over that) or
///   whose grid would not fit that bound; a `decimate_to_hz` that is not `rate_hz` over a
///   whole number; a cut-off not below the output Nyquist frequency or a bad order; a
///   time step longer than `max_gap_s` (field `t[row]`, value the step in s);
/// - [`PrrrpError::ShapeMismatch`] if `q`, `tau` or `qd` does not hold n values per time
///   stamp;
/// - [`PrrrpError::NonFinite`] naming the column and joint (e.g. `"q[2] (joint 3)"`)
///   and the row of the first NaN or ±∞;
/// - [`PrrrpError::NonIncreasingTime`] naming the first row whose time stamp is smaller
///   than the previous one;
/// - [`PrrrpError::TooFewSamples`] if fewer than 3 distinct time stamps remain, or fewer
///   than `min_samples` after trimming and decimation.
pub fn preprocess_log(
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    qd: Option<&[f64]>,
    n: usize,
    config: &LogConfig,
) -> Result<(DynDataset, LogReport)> {
    check_dof(n)?;
    let rows = t.len();
    check_flat_len("q", q.len(), Dyn(n), rows)?;
    check_flat_len("tau", tau.len(), Dyn(n), rows)?;
    if let Some(qd) = qd {
        check_flat_len("qd", qd.len(), Dyn(n), rows)?;
    }
    if let Some(row) = t.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "t".into(),
            row: Some(row),
        });
    }
    check_finite_flat("q", q, n)?;
    if let Some(qd) = qd {
        check_finite_flat("qd", qd, n)?;
    }
    check_finite_flat("tau", tau, n)?;
    check_config(config)?;

    // 1. Repeated time stamps.
    let row = |k: usize| k * n..(k + 1) * n;
    let mut kept: Vec<usize> = Vec::with_capacity(rows);
    let (mut repeated, mut conflicting) = (0, 0);
    for k in 0..rows {
        let Some(&p) = kept.last() else {
            kept.push(k);
            continue;
        };
        if t[k] == t[p] {
            repeated += 1;
            let same = |x: &[f64]| x[row(k)] == x[row(p)];
            if !(same(q) && same(tau) && qd.map_or(true, same)) {
                conflicting += 1;
            }
        } else if t[k] < t[p] {
            return Err(PrrrpError::NonIncreasingTime { row: k });
        } else {
            kept.push(k);
        }
    }
    let len = kept.len();
    if len < 3 && repeated > 0 {
        // "Too few samples; record a longer trajectory" misled for a long log whose rows
        // all carry one time stamp (a clock column that was never filled in).
        return Err(PrrrpError::InvalidParameter {
            field: format!(
                "t (its {} rows hold {len} distinct time stamp{})",
                t.len(),
                if len == 1 { "" } else { "s" }
            ),
            value: t[kept[0]],
            reason: "rows that share a time stamp are one sample; give each sample its own \
                     time, in s",
        });
    }
    if len < 3 {
        return Err(PrrrpError::TooFewSamples {
            needed: 3,
            got: len,
        });
    }

    // 2. Steps: median rate, largest gap, uniformity.
    let (t0, t_last) = (t[kept[0]], t[kept[len - 1]]);
    let mut steps: Vec<f64> = kept.windows(2).map(|w| t[w[1]] - t[w[0]]).collect();
    let (mut gap, mut gap_row) = (0.0, kept[1]);
    for (i, &s) in steps.iter().enumerate() {
        if s > gap {
            (gap, gap_row) = (s, kept[i + 1]);
        }
    }
    let mean_step = (t_last - t0) / (len - 1) as f64;
    let uniform = steps
        .iter()
        .all(|&s| (s - mean_step).abs() <= LOG_UNIFORM_TOLERANCE * mean_step);
    let mid = steps.len() / 2;
    let (_, &mut median_step, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
    drop(steps);
    let median_rate = 1.0 / median_step;
    if !(median_rate.is_finite() && median_rate > 0.0 && mean_step.is_finite()) {
        return Err(invalid(
            "t",
            median_step,
            "time steps must be representable: a median step whose inverse is finite and a finite time span",
        ));
    }

    // Grid rate and decimation factor.
    let (mut rate, decimation) = match config.decimate_to_hz {
        None => (config.rate_hz.unwrap_or(median_rate), 1),
        Some(f_out) => {
            let (rate, factor) = match config.rate_hz {
                Some(r) => {
                    let factor = (r / f_out).round();
                    if !(factor >= 1.0 && (r / factor - f_out).abs() <= 1e-9 * f_out) {
                        return Err(invalid(
                            "decimate_to_hz",
                            f_out,
                            "must be rate_hz divided by a whole number >= 1",
                        ));
                    }
                    (r, factor)
                }
                // Just above 1 is still 1: rounding must not double the grid.
                None => {
                    let factor = (median_rate / f_out * (1.0 - 1e-9)).ceil().max(1.0);
                    (f_out * factor, factor)
                }
            };
            if factor > len as f64 {
                return Err(invalid(
                    "decimate_to_hz",
                    f_out,
                    "too low: decimation would keep less than one sample of the log",
                ));
            }
            (rate, factor as usize)
        }
    };
    // Below a hundredth of the log's rate too: at 1e-300 Hz a 5 s log became one sample,
    // and the error said "too few samples; record a longer trajectory".
    if rate.is_nan()
        || rate > LOG_MAX_UPSAMPLING * median_rate
        || rate < median_rate / LOG_MAX_UPSAMPLING
    {
        return Err(invalid(
            "rate_hz",
            rate,
            "must be between 1/LOG_MAX_UPSAMPLING and LOG_MAX_UPSAMPLING (100) times the \
             log's median rate",
        ));
    }
    let passthrough = uniform && (rate * mean_step - 1.0).abs() <= LOG_UNIFORM_TOLERANCE;
    if passthrough {
        rate = 1.0 / mean_step;
    }
    let output_rate = rate / decimation as f64;
    let cutoff = config
        .cutoff_hz
        .unwrap_or_else(|| DEFAULT_LOG_CUTOFF_HZ.min(0.1 * output_rate));
    // Before the gaps, whose default bound is half a cut-off period: a cut-off above the
    // Nyquist frequency made every step a "gap", and the error named the step at
    // t[804] that was 1.6e-15 s longer than the others.
    check_nyquist(cutoff, output_rate)?;
    let max_gap = config.max_gap_s.unwrap_or(0.5 / cutoff);
    if gap > max_gap {
        return Err(invalid(
            format!("t[{gap_row}]"),
            gap,
            "the time step ending at this row exceeds max_gap_s (default half a cut-off \
             period, 1/(2·cutoff_hz)); split the log there or raise max_gap_s",
        ));
    }

    // The grid: the kept rows themselves, or t0 + i/rate interpolated.
    let (grid_t, src, dt) = if passthrough {
        let src: Vec<Source> = kept
            .iter()
            .map(|&k| Source { a: k, b: k, w: 0.0 })
            .collect();
        let grid_t: Vec<f64> = kept.iter().map(|&k| t[k]).collect();
        (grid_t, src, mean_step)
    } else {
        let m = ((t_last - t0) * rate).floor() + 1.0;
        if m.is_nan() || m > LOG_MAX_UPSAMPLING * len as f64 {
            return Err(invalid(
                "rate_hz",
                rate,
                "the grid would exceed LOG_MAX_UPSAMPLING (100) samples per log row; lower \
                 rate_hz or split the log at its gaps",
            ));
        }
        let m = m as usize;
        let dt = 1.0 / rate;
        let mut grid_t = Vec::with_capacity(m);
        let mut src = Vec::with_capacity(m);
        let mut p = 0;
        for i in 0..m {
            let tg = t0 + i as f64 * dt;
            while p + 2 < len && t[kept[p + 1]] <= tg {
                p += 1;
            }
            let (a, b) = (kept[p], kept[p + 1]);
            // Rounding can put the last grid point a hair past the last row: clamp.
            let w = ((tg - t[a]) / (t[b] - t[a])).clamp(0.0, 1.0);
            grid_t.push(tg);
            src.push(Source { a, b, w });
        }
        (grid_t, src, dt)
    };
    drop(kept);

    let trim = match config.trim_s {
        None => None,
        Some(s) => {
            let samples = (s * rate).ceil();
            // Anything longer than the grid fails the size check downstream anyway.
            Some(if samples <= grid_t.len() as f64 {
                samples as usize
            } else {
                grid_t.len()
            })
        }
    };
    let settings = FilterSettings {
        cutoff_hz: cutoff,
        order: config.order,
        filter_torque: config.filter_torque,
        trim,
        decimate: decimation,
        min_samples: config.min_samples,
    };
    let grid = Grid {
        t: &grid_t,
        src: &src,
        dt,
    };
    let signals = Signals { n, q, qd, tau };
    let (data, outcome) = filter_and_differentiate(&grid, &signals, &settings)?;
    let report = LogReport {
        rows_in: rows,
        repeated_rows: repeated,
        conflicting_repeats: conflicting,
        median_rate_hz: median_rate,
        rate_hz: rate,
        resampled: !passthrough,
        largest_gap_s: gap,
        largest_gap_row: gap_row,
        cutoff_hz: cutoff,
        order: config.order,
        trim_samples: outcome.trim,
        trim_s: outcome.trim as f64 * dt,
        decimation,
        output_rate_hz: output_rate,
        measured_velocity: qd.is_some(),
        rows_out: data.len(),
    };
    Ok((data, report))
}

/// Scalar settings that must be finite and positive (or, for `max_gap_s`, +∞).
fn check_config(c: &LogConfig) -> Result<()> {
    let positive = |name: &str, v: Option<f64>| -> Result<()> {
        match v {
            Some(x) if !(x.is_finite() && x > 0.0) => Err(invalid(
                name,
                x,
                "must be finite and > 0 (or None for the default)",
            )),
            _ => Ok(()),
        }
    };
    positive("rate_hz", c.rate_hz)?;
    positive("cutoff_hz", c.cutoff_hz)?;
    positive("decimate_to_hz", c.decimate_to_hz)?;
    if let Some(g) = c.max_gap_s {
        if g.is_nan() || g <= 0.0 {
            return Err(invalid(
                "max_gap_s",
                g,
                "must be > 0 s (f64::INFINITY accepts any gap)",
            ));
        }
    }
    if let Some(s) = c.trim_s {
        if !(s.is_finite() && s >= 0.0) {
            return Err(invalid("trim_s", s, "must be finite and >= 0 s"));
        }
    }
    Ok(())
}
