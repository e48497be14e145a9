//! Validation of identified models: the error indices (RMS, RSD, agreement index) and
//! torque-prediction validation on data the estimators never saw.

pub(crate) mod metrics;
mod prediction;

pub use prediction::*;

// The module's public API (also at the crate root through `prelude`).
pub use metrics::{
    agreement_index, error_indices, relative_errors_percent, rms, rsd, ErrorIndices,
};
