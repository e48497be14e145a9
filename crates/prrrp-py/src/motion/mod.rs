//! Bindings of motion: trajectories and simulation.

pub(crate) mod chain_excitation;
pub(crate) mod chain_simulation;
pub(crate) mod simulation;
pub(crate) mod trajectories;
