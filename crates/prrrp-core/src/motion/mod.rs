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

// The module's public API (also at the crate root through `prelude`).
pub use chain_excitation::{
    optimise_chain_excitation, ChainExcitation, ChainExcitationConfig, MAX_EXCITATION_EVALUATIONS,
    MAX_HARMONICS,
};
pub use dyn_trajectory::{DynSampledTrajectory, FourierTrajectory};
pub use dynamics::{Dynamics, ParameterisedModel, ParameterisedWorkspace};
pub use excitation::{
    excitation_variables, optimise_excitation, ExcitationConfig, ExcitationProgress,
    ExcitationResult, DEFAULT_EXCITATION_KNOTS,
};
pub use limits::{limit_usage, JointLimits, LimitUsage};
pub use simulation::{
    rk4_step, rk4_step_into, simulate_closed_loop, simulate_dyn_closed_loop,
    simulate_dyn_open_loop, simulate_open_loop, ComputedTorque, DynComputedTorque, DynSensorNoise,
    DynSimulationConfig, DynSimulationRecord, Rk4Integrator, SensorNoise, SimulationConfig,
    SimulationRecord, MAX_INTEGRATION_STEPS, RK4_SCRATCH_PER_JOINT,
};
pub use trajectory::{
    sample_trajectory, DynTrajectory, ExcitationTrajectory, FourierSeries, JointTrajectory,
    PiecewiseQuintic, Quintic, Reflected, SampledTrajectory, ScalarTrajectory, Sinusoid,
    TrajectoryPoint, REFLECTED_REST_TOLERANCE,
};
