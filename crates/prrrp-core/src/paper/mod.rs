//! The paper's study on top of the library: the whole protocol of Urrea & Pascal 2017
//! ([`study`]) and the sensitivity of the estimates to sensor noise ([`sensitivity`]).

pub(crate) mod sensitivity;
pub(crate) mod study;
