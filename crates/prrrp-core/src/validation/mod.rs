//! Validation of identified models: the error indices (RMS, RSD, agreement index) and
//! torque-prediction validation on data the estimators never saw.

pub(crate) mod metrics;
mod prediction;

pub use prediction::*;
