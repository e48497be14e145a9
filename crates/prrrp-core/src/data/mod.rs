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
// Kept at its old path too (it was defined here).
pub use crate::bounds::MAX_MAGNITUDE;

// The module's public API (also at the crate root through `prelude`).
pub use dataset::{Dataset, DatasetOf, DatasetParts, DynDataset};
pub use preprocess::{
    central_differences, preprocess, ButterworthLowPass, PreprocessConfig, MAX_BUTTERWORTH_ORDER,
};
