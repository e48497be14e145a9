//! Bindings of the models: any serial chain, the paper's closed-form arm, its regressor
//! and derivatives.

pub(crate) mod chain;
pub(crate) mod derivatives;
pub(crate) mod regressor;
pub(crate) mod robot;
