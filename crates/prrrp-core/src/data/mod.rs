//! Identification data: the validated [`DynDataset`] of any joint count and
//! [`preprocess_log`], which turns a real, irregular log into one; the PRRRP's fixed-size
//! [`Dataset`] and [`preprocess`] run on the same
//! filtering core.

pub mod csv;
pub(crate) mod dataset;
mod dyn_dataset;
mod log;
pub(crate) mod pipeline;
pub(crate) mod preprocess;

pub use dyn_dataset::{DynDataset, DynDatasetParts};
pub use log::{
    preprocess_log, LogConfig, LogReport, DEFAULT_LOG_CUTOFF_HZ, LOG_MAX_UPSAMPLING,
    LOG_UNIFORM_TOLERANCE,
};

// The module's public API (also at the crate root through `prelude`).
pub use dataset::{Dataset, DatasetParts};
pub use preprocess::{
    central_differences, preprocess, ButterworthLowPass, PreprocessConfig, MAX_BUTTERWORTH_ORDER,
};
