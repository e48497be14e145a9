//! Identification data for robots with a run-time number of joints: the validated
//! [`DynDataset`] and [`preprocess_log`], which turns a real, irregular log into one.
//! The PRRRP's fixed-size [`crate::preprocess()`] runs on the same filtering core.

mod dyn_dataset;
mod log;
pub(crate) mod pipeline;

pub use dyn_dataset::{DynDataset, DynDatasetParts};
pub use log::{
    preprocess_log, LogConfig, LogReport, DEFAULT_LOG_CUTOFF_HZ, LOG_MAX_UPSAMPLING,
    LOG_UNIFORM_TOLERANCE,
};
