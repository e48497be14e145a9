//! Bindings of validation: error indices and torque-prediction validation.

pub(crate) mod metrics;
pub(crate) mod prediction;
