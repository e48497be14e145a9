//! Preprocessing of measured data as the identification field does it: zero-phase
//! Butterworth low-pass filtering (forward and backward) of positions and torques,
//! velocities and accelerations by central differences, edge trimming and decimation.

use crate::data::dataset::Dataset;
use crate::data::pipeline::{filter_and_differentiate, FilterSettings, Grid, Signals, Source};
use crate::error::{PrrrpError, Result};
use crate::models::prrrp::types::{Vec5, NDOF};

/// Largest supported filter order.
pub const MAX_BUTTERWORTH_ORDER: usize = 8;

/// One second-order section in transposed direct form II, normalised so that a0 = 1.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    /// State (z1, z2) for which a constant input x0 gives the constant output x0 (the
    /// sections have unit gain at DC).
    fn steady_state(&self, x0: f64) -> [f64; 2] {
        let z2 = (self.b[2] - self.a[1]) * x0;
        [(self.b[1] - self.a[0]) * x0 + z2, z2]
    }

    #[inline]
    fn step(&self, z: &mut [f64; 2], x: f64) -> f64 {
        let y = self.b[0] * x + z[0];
        z[0] = self.b[1] * x - self.a[0] * y + z[1];
        z[1] = self.b[2] * x - self.a[1] * y;
        y
    }
}

/// A digital Butterworth low-pass filter of even order (2, 4, 6 or 8), designed by the
/// bilinear transform with the cutoff pre-warped, as a cascade of second-order sections.
///
/// Applied forward and backward by [`ButterworthLowPass::filtfilt`], the magnitude
/// response is |H(f)|² = 1 / (1 + (tan(πf/fs) / tan(πfc/fs))^(2·order)): 0.5 at the
/// cutoff, no phase shift.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ButterworthLowPass {
    sections: [Biquad; MAX_BUTTERWORTH_ORDER / 2],
    n_sections: usize,
}

impl ButterworthLowPass {
    /// Designs the filter for cutoff `cutoff_hz` at sampling rate `sample_rate_hz`.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if the order is not 2, 4, 6 or 8, or the cutoff is
    /// not strictly between 0 and the Nyquist frequency fs/2.
    pub fn new(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> Result<Self> {
        if order == 0 || order % 2 != 0 || order > MAX_BUTTERWORTH_ORDER {
            return Err(PrrrpError::InvalidParameter {
                field: "order".into(),
                value: order as f64,
                reason: "the Butterworth order must be 2, 4, 6 or 8",
            });
        }
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "sample_rate_hz".into(),
                value: sample_rate_hz,
                reason: "must be finite and > 0 Hz",
            });
        }
        if !(cutoff_hz.is_finite() && cutoff_hz > 0.0 && cutoff_hz < 0.5 * sample_rate_hz) {
            return Err(PrrrpError::InvalidParameter {
                field: "cutoff_hz".into(),
                value: cutoff_hz,
                reason: "the cutoff must lie strictly between 0 and the Nyquist frequency fs/2",
            });
        }
        // Analogue prototype poles come in conjugate pairs at angles θ_k from the
        // negative real axis; each pair is a section s² + 2cos(θ_k)·s + 1, here mapped
        // with s = (1/K)·(1 − z⁻¹)/(1 + z⁻¹), K = tan(π·fc/fs) (pre-warped cutoff).
        let k = (std::f64::consts::PI * cutoff_hz / sample_rate_hz).tan();
        let n_sections = order / 2;
        let mut sections = [Biquad {
            b: [0.0; 3],
            a: [0.0; 2],
        }; MAX_BUTTERWORTH_ORDER / 2];
        for (i, s) in sections.iter_mut().take(n_sections).enumerate() {
            let theta = std::f64::consts::PI * (2 * i + 1) as f64 / (2 * order) as f64;
            let c = 2.0 * theta.cos();
            let norm = 1.0 / (1.0 + c * k + k * k);
            let b0 = k * k * norm;
            *s = Biquad {
                b: [b0, 2.0 * b0, b0],
                a: [2.0 * (k * k - 1.0) * norm, (1.0 - c * k + k * k) * norm],
            };
        }
        Ok(Self {
            sections,
            n_sections,
        })
    }

    /// Filter order.
    pub fn order(&self) -> usize {
        2 * self.n_sections
    }

    /// Number of samples of odd-symmetric extension added at each end before filtering
    /// (3·(order + 1), as scipy's `filtfilt`), capped at len − 1.
    pub fn pad_len(&self, len: usize) -> usize {
        (3 * (self.order() + 1)).min(len.saturating_sub(1))
    }

    /// Zero-phase filtering: forward then backward pass over the signal extended at each
    /// end by its point reflection (2·x₀ − x_k), each pass started in the steady state of
    /// its first value, as scipy's `filtfilt` does. Returns a signal of the same length.
    pub fn filtfilt(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; x.len()];
        self.filtfilt_into(x, &mut Vec::new(), &mut out);
        out
    }

    /// [`Self::filtfilt`] into `out` (as long as `x`), with `ext` as reusable scratch for
    /// the padded signal so that filtering many columns allocates once.
    pub(crate) fn filtfilt_into(&self, x: &[f64], ext: &mut Vec<f64>, out: &mut [f64]) {
        let n = x.len();
        if n < 2 {
            out.copy_from_slice(x);
            return;
        }
        let pad = self.pad_len(n);
        ext.clear();
        ext.reserve(n + 2 * pad);
        ext.extend((1..=pad).rev().map(|k| 2.0 * x[0] - x[k]));
        ext.extend_from_slice(x);
        ext.extend((1..=pad).map(|k| 2.0 * x[n - 1] - x[n - 1 - k]));
        self.pass(ext);
        ext.reverse();
        self.pass(ext);
        ext.reverse();
        out.copy_from_slice(&ext[pad..pad + n]);
    }

    fn pass(&self, x: &mut [f64]) {
        for s in &self.sections[..self.n_sections] {
            let mut z = s.steady_state(x[0]);
            for v in x.iter_mut() {
                *v = s.step(&mut z, *v);
            }
        }
    }
}

/// Settings of [`preprocess`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreprocessConfig {
    /// Low-pass cutoff, Hz (default 5: well above the content of a 10 s excitation, well
    /// below the 25 Hz Nyquist frequency of the paper's 0.02 s sampling, where the
    /// differentiated position noise lives).
    pub cutoff_hz: f64,
    /// Butterworth order, 2/4/6/8 (default 4).
    pub order: usize,
    /// Filter the torques with the same filter (default true), so that τ and the
    /// filtered q̈ see the same delay-free attenuation, as the field does.
    pub filter_torque: bool,
    /// Samples dropped at each end after filtering and differentiation. `None` (default)
    /// drops ⌈3·fs/fc⌉ samples (3 cutoff periods: 30 samples = 0.6 s at 50 Hz and 5 Hz),
    /// by which the edge transient has decayed: the point reflection used to pad the
    /// signal flips the sign of q̈ there, and the filter spreads that jump over a few
    /// cutoff periods (its slowest pole decays as exp(−2π·fc·sin(π/(2·order))·t)). At
    /// least 1 sample is always dropped since the central differences need a neighbour
    /// on each side.
    pub trim: Option<usize>,
    /// Keep every `decimate`-th sample after filtering (default 1 = keep all). The
    /// cutoff must stay below the new Nyquist frequency.
    pub decimate: usize,
}

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self {
            cutoff_hz: 5.0,
            order: 4,
            filter_torque: true,
            trim: None,
            decimate: 1,
        }
    }
}

/// Second-order central differences of uniformly sampled vectors:
/// ẋ_k = (x_{k+1} − x_{k−1})/(2·dt), ẍ_k = (x_{k+1} − 2x_k + x_{k−1})/dt², for the
/// interior samples k = 1..n−1 (the returned vectors have n − 2 entries; empty if n < 3).
/// Truncation errors: x⁽³⁾·dt²/6 and x⁽⁴⁾·dt²/12.
pub fn central_differences(x: &[Vec5], dt: f64) -> (Vec<Vec5>, Vec<Vec5>) {
    let (mut d1, mut d2) = (Vec::new(), Vec::new());
    for w in x.windows(3) {
        d1.push((w[2] - w[0]) / (2.0 * dt));
        d2.push((w[2] - 2.0 * w[1] + w[0]) / (dt * dt));
    }
    (d1, d2)
}

/// Turns measured positions and torques at a uniform sampling rate into a [`Dataset`]
/// with q, q̇, q̈, τ: zero-phase low-pass filtering of q (and τ), central differences,
/// edge trimming and decimation (see [`PreprocessConfig`]).
///
/// This is [`crate::preprocess_log`]'s filtering core with n = 5 on the samples as they
/// are; for logs with jitter, repeated rows or another number of joints use that.
///
/// ```
/// use prrrp_core::{preprocess, PreprocessConfig, Vec5};
/// let dt = 0.02;
/// let t: Vec<f64> = (0..500).map(|k| dt * k as f64).collect();
/// let q: Vec<Vec5> = t.iter().map(|&t| Vec5::repeat((1.3 * t).sin())).collect();
/// let tau = vec![Vec5::zeros(); t.len()];
/// let data = preprocess(&t, &q, &tau, &PreprocessConfig::default())?;
/// let k = data.len() / 2;
/// let want = -1.69 * (1.3 * data.t()[k]).sin();
/// assert!((data.qdd_row(k)[2] - want).abs() < 1e-3);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
///
/// # Errors
/// - [`PrrrpError::ShapeMismatch`] if q or τ is not as long as t;
/// - [`PrrrpError::NonFinite`] naming the column (t, q, tau) and first bad row;
/// - [`PrrrpError::NonIncreasingTime`] for non-increasing time stamps;
/// - [`PrrrpError::InvalidParameter`] for non-uniform sampling (jitter above 1e-6·dt),
///   a bad filter setting, a zero decimation factor, or a cutoff above the Nyquist
///   frequency after decimation;
/// - [`PrrrpError::TooFewSamples`] if too little remains after trimming and decimation.
pub fn preprocess(
    t: &[f64],
    q: &[Vec5],
    tau: &[Vec5],
    config: &PreprocessConfig,
) -> Result<Dataset> {
    crate::models::prrrp::regressor::check_lengths(t.len(), &[("q", q.len()), ("tau", tau.len())])
        .map_err(|e| match e {
            PrrrpError::ShapeMismatch { what, got, .. } => PrrrpError::ShapeMismatch {
                what,
                expected: format!("{} samples (as t)", t.len()),
                got,
            },
            other => other,
        })?;
    if let Some(row) = t.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "t".into(),
            row: Some(row),
        });
    }
    for (name, col) in [("q", q), ("tau", tau)] {
        if let Some(row) = col.iter().position(|v| !v.iter().all(|x| x.is_finite())) {
            return Err(PrrrpError::NonFinite {
                what: name.into(),
                row: Some(row),
            });
        }
    }
    let n = t.len();
    if n < 3 {
        return Err(PrrrpError::TooFewSamples { needed: 3, got: n });
    }
    if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(PrrrpError::NonIncreasingTime { row: k + 1 });
    }
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    if let Some(k) = t
        .windows(2)
        .position(|w| ((w[1] - w[0]) - dt).abs() > 1e-6 * dt)
    {
        return Err(PrrrpError::InvalidParameter {
            field: format!("t[{}]", k + 1),
            value: t[k + 1],
            reason: "sampling must be uniform (jitter <= 1e-6·dt); resample the data first",
        });
    }
    // The shared n-joint core (also behind `preprocess_log`), on the samples as they are:
    // the grid is the input's own rows, so nothing is interpolated.
    let flat = |c: &[Vec5]| -> Vec<f64> { c.iter().flat_map(|v| v.iter().copied()).collect() };
    let (q_flat, tau_flat) = (flat(q), flat(tau));
    let src: Vec<Source> = (0..n).map(|k| Source { a: k, b: k, w: 0.0 }).collect();
    let grid = Grid { t, src: &src, dt };
    let signals = Signals {
        n: NDOF,
        q: &q_flat,
        qd: None,
        tau: &tau_flat,
    };
    let settings = FilterSettings {
        cutoff_hz: config.cutoff_hz,
        order: config.order,
        filter_torque: config.filter_torque,
        trim: config.trim,
        decimate: config.decimate,
        min_samples: Dataset::MIN_SAMPLES,
    };
    let (data, _) = filter_and_differentiate(&grid, &signals, &settings)?;
    Dataset::try_from(data)
}
