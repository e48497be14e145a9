//! Identification data: the validated [`DatasetOf`] — [`DynDataset`] for any joint
//! count, [`Dataset`] for the paper's 5-joint arm — and [`preprocess_log`], which turns a
//! real, irregular log into one; the PRRRP's [`preprocess`] runs on the same filtering
//! core.

pub mod csv;
pub(crate) mod dataset;
mod log;
pub(crate) mod pipeline;
pub(crate) mod preprocess;

pub use log::{
    preprocess_log, LogConfig, LogReport, DEFAULT_LOG_CUTOFF_HZ, LOG_MAX_UPSAMPLING,
    LOG_UNIFORM_TOLERANCE,
};
/// Cut-off periods after which a Butterworth low-pass's start or edge transient counts as
/// decayed: 3, i.e. 3/f_c s (its slowest pole decays as exp(−2π·f_c·sin(π/(2·order))·t),
/// below 1 % for order 4). The batch preprocessing trims that much at each end by default;
/// the online identifier's causal filter updates no estimate before it (and `prrrp track`
/// refuses a `--cutoff` whose settling outlasts the log).
pub const SETTLING_PERIODS: f64 = 3.0;

// Kept at its old path too (it was defined here).
pub use crate::bounds::MAX_MAGNITUDE;

// The module's public API (also at the crate root through `prelude`).
pub use dataset::{Dataset, DatasetOf, DatasetParts, DynDataset};
pub use preprocess::{
    central_differences, preprocess, ButterworthLowPass, PreprocessConfig, MAX_BUTTERWORTH_ORDER,
};
