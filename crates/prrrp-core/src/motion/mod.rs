//! Motion: joint trajectories (the paper arm's and any robot's), the paper's excitation
//! design and the excitation design of any robot, joint limits, the dynamics a simulator needs, and closed- and open-loop
//! simulation.

pub(crate) mod chain_excitation;
pub(crate) mod dyn_trajectory;
pub(crate) mod dynamics;
pub(crate) mod excitation;
pub(crate) mod limits;
pub(crate) mod simulation;
pub(crate) mod trajectory;
