//! The one filtering and differentiation core behind [`crate::preprocess()`] (5 joints,
//! uniform samples) and [`crate::preprocess_log`] (n joints, resampled real logs).

use crate::data::dataset::DynDataset;
use crate::data::preprocess::ButterworthLowPass;
use crate::data::SETTLING_PERIODS;
use crate::error::{PrrrpError, Result};

/// Where grid sample i comes from: rows `a` and `b` of the (row-major) inputs mixed as
/// (1 − w)·x_a + w·x_b. w = 0 takes x_a exactly, so a grid that is the input's own rows
/// passes the values through bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Source {
    pub a: usize,
    pub b: usize,
    pub w: f64,
}

/// A uniform time grid over the input rows.
pub(crate) struct Grid<'a> {
    /// Time of each grid sample, s.
    pub t: &'a [f64],
    /// Input rows of each grid sample (same length as `t`).
    pub src: &'a [Source],
    /// Grid step, s.
    pub dt: f64,
}

/// Flat row-major inputs of n joints.
pub(crate) struct Signals<'a> {
    pub n: usize,
    pub q: &'a [f64],
    /// Measured velocities, filtered like q and differentiated for q̈ when present.
    pub qd: Option<&'a [f64]>,
    pub tau: &'a [f64],
}

/// Filter settings shared by both entry points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FilterSettings {
    pub cutoff_hz: f64,
    pub order: usize,
    pub filter_torque: bool,
    /// Samples dropped at each end; `None` = ⌈3·fs/fc⌉. At least 1 is always dropped.
    pub trim: Option<usize>,
    pub decimate: usize,
    pub min_samples: usize,
}

/// What [`filter_and_differentiate`] decided, for the caller's report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Outcome {
    pub trim: usize,
}

/// `cutoff_hz` must lie below the Nyquist frequency of the output rate (Hz, after
/// decimation).
pub(crate) fn check_nyquist(cutoff_hz: f64, output_rate_hz: f64) -> Result<()> {
    if cutoff_hz >= 0.5 * output_rate_hz {
        return Err(PrrrpError::InvalidParameter {
            field: "cutoff_hz".into(),
            value: cutoff_hz,
            reason: "must be below the Nyquist frequency after decimation, fs/(2·decimate)",
        });
    }
    Ok(())
}

/// Zero-phase low-pass filtering of q (and τ, and the measured q̇ if any) on the grid,
/// derivatives by central differences, edge trimming and decimation.
///
/// Without measured velocities q̇_k = (q_{k+1} − q_{k−1})/(2·dt) and
/// q̈_k = (q_{k+1} − 2·q_k + q_{k−1})/dt², the difference of the half-step velocities
/// (q_{k±1} − q_k)/dt of the filtered q; with them q̇ is the filtered measurement and
/// q̈_k = (q̇_{k+1} − q̇_{k−1})/(2·dt).
///
/// Checks in this order, as `preprocess` always has: decimation factor, filter design,
/// cutoff against the Nyquist frequency after decimation, samples left after trimming.
pub(crate) fn filter_and_differentiate(
    grid: &Grid<'_>,
    sig: &Signals<'_>,
    cfg: &FilterSettings,
) -> Result<(DynDataset, Outcome)> {
    let n = sig.n;
    let m = grid.t.len();
    if cfg.decimate == 0 {
        return Err(PrrrpError::InvalidParameter {
            field: "decimate".into(),
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let fs = 1.0 / grid.dt;
    let filter = ButterworthLowPass::new(cfg.order, cfg.cutoff_hz, fs)?;
    check_nyquist(cfg.cutoff_hz, fs / cfg.decimate as f64)?;
    // A user trim can be anything: compare sizes without overflow before allocating.
    let trim = cfg
        .trim
        .unwrap_or_else(|| (SETTLING_PERIODS * fs / cfg.cutoff_hz).ceil() as usize)
        .max(1);
    let needed = trim
        .checked_mul(2)
        .and_then(|x| x.checked_add(cfg.min_samples))
        .unwrap_or(usize::MAX);
    if m < needed {
        // More than any log holds (`MAX_SAMPLES`, 1e7): the cut-off is what to change (at
        // 1e-300 Hz the count needed read 18446744073709551615).
        if cfg.trim.is_none() && needed > crate::interrupt::MAX_SAMPLES {
            return Err(PrrrpError::InvalidParameter {
                field: "cutoff_hz".into(),
                value: cfg.cutoff_hz,
                reason: "trims its start-up transient, 3/cutoff s, from each end of the log, \
                         more than 1e7 samples: raise the cut-off (Hz)",
            });
        }
        return Err(PrrrpError::TooFewSamples { needed, got: m });
    }
    let keep = (trim..m - trim).step_by(cfg.decimate);
    let rows_out = keep.len();
    let mut t_out = Vec::with_capacity(rows_out);
    t_out.extend(keep.clone().map(|k| grid.t[k]));
    let mut out = [(); 4].map(|_| vec![0.0; rows_out * n]);
    // One column at a time through O(m) scratch buffers reused for every joint.
    let mut col = vec![0.0; m];
    let mut filt = vec![0.0; m];
    let mut ext = Vec::new();
    let dt = grid.dt;
    for j in 0..n {
        gather(grid.src, sig.q, n, j, &mut col);
        filter.filtfilt_into(&col, &mut ext, &mut filt);
        let [q_out, qd_out, qdd_out, tau_out] = &mut out;
        for (r, k) in keep.clone().enumerate() {
            q_out[r * n + j] = filt[k];
        }
        match sig.qd {
            None => {
                for (r, k) in keep.clone().enumerate() {
                    let (a, b, c) = (filt[k - 1], filt[k], filt[k + 1]);
                    qd_out[r * n + j] = (c - a) / (2.0 * dt);
                    qdd_out[r * n + j] = (c - 2.0 * b + a) / (dt * dt);
                }
            }
            Some(qd) => {
                gather(grid.src, qd, n, j, &mut col);
                filter.filtfilt_into(&col, &mut ext, &mut filt);
                for (r, k) in keep.clone().enumerate() {
                    qd_out[r * n + j] = filt[k];
                    qdd_out[r * n + j] = (filt[k + 1] - filt[k - 1]) / (2.0 * dt);
                }
            }
        }
        gather(grid.src, sig.tau, n, j, &mut col);
        let tau_col = if cfg.filter_torque {
            filter.filtfilt_into(&col, &mut ext, &mut filt);
            &filt
        } else {
            &col
        };
        for (r, k) in keep.clone().enumerate() {
            tau_out[r * n + j] = tau_col[k];
        }
    }
    let [q, qd, qdd, tau] = out;
    let data = DynDataset::with_min_samples(n, cfg.min_samples, t_out, q, qd, qdd, tau)?;
    Ok((data, Outcome { trim }))
}

/// Column `j` of a row-major signal on the grid.
fn gather(src: &[Source], x: &[f64], n: usize, j: usize, col: &mut [f64]) {
    for (c, s) in col.iter_mut().zip(src) {
        let xa = x[s.a * n + j];
        *c = if s.w == 0.0 {
            xa
        } else {
            (1.0 - s.w) * xa + s.w * x[s.b * n + j]
        };
    }
}
