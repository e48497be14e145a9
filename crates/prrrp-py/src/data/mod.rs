//! Bindings of identification data: datasets and preprocessing.

pub(crate) mod csv;
pub(crate) mod dataset;
pub(crate) mod preprocessing;
