//! Identification data: the validated [`DynDataset`] of any joint count and
//! [`preprocess_log`], which turns a real, irregular log into one; the PRRRP's fixed-size
//! [`Dataset`](dataset::Dataset) and [`preprocess`](crate::preprocess) run on the same
//! filtering core.

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
