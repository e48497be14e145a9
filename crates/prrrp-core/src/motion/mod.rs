//! Motion: joint trajectories, the paper's excitation design, joint limits, and
//! closed- and open-loop simulation.

pub(crate) mod excitation;
pub(crate) mod limits;
pub(crate) mod simulation;
pub(crate) mod trajectory;
