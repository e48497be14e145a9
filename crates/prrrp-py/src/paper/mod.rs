//! Bindings of the paper's study.

pub(crate) mod study;
