//! # prrrp-core
//!
//! Dynamic models and parameter identification of serial robot manipulators: rigid-body
//! dynamics of any serial chain (read from URDF or TOML, or built in), with friction and
//! coupled, geared actuators; the regressor τ = Φ·β in the base parameters β; excitation
//! design, simulation, preprocessing of logs; batch and online estimators (least squares,
//! RLS, Adaline, Hopfield, the extended Kalman filter, physically consistent fits); and an
//! identified model that predicts torques and saves to JSON ([`identify`],
//! [`IdentifiedModel`]). It began as a reproduction of Urrea & Pascal, "Parameter
//! identification methods for real redundant manipulators", J. Appl. Res. Technol. 15
//! (2017) 320–331, whose 5-DOF PRRRP arm is one robot among many here: as a chain
//! ([`DynChain::paper`]) and in the paper's closed form in 8 grouped parameters λ
//! ([`Robot`], [`PrrrpModel`]), the fast path of its study.
//!
//! Per-sample functions work on stack-allocated nalgebra types and never touch the heap;
//! batch linear algebra uses faer. Constant model data are kept apart from per-call
//! workspaces ([`DynChain`] / [`DynWorkspace`]), and every estimator is generic over
//! [`LinearModel`] with `Const` or `Dyn` sizes, so one implementation serves both.
//! Layers, and where a new robot, estimator or file format goes: docs/architecture.md.
//!
//! ## Conventions
//! - SI units throughout: m and rad for joint positions, N and N·m for joint forces, kg,
//!   kg·m and kg·m² for inertial parameters.
//! - The paper's arm: q = [d1, θ2, θ3, θ4, d5] in m, rad, rad, rad, m; τ = [F1, τ2, τ3, τ4,
//!   F5] in N, N·m, N·m, N·m, N. World z points up; gravity acts along −z with magnitude
//!   `gravity` (9.81 m/s² by default). Joint 1 lifts the arm along +z, joints 2–4 rotate
//!   about vertical axes, joint 5 moves the tool along −z (DH α4 = 180°), so G5 = −m5·g and
//!   M15 = −m5. Inertias of links 2–4 are about their centres of mass.
//!
//! ## Example
//! ```
//! use prrrp_core::{DynChain, Robot, Vec5};
//!
//! let robot = Robot::paper();
//! let lambda = robot.base_parameters();
//! let model = robot.model();
//! let q = Vec5::new(0.1, 0.3, -0.5, 1.2, 0.02);
//! let qd = Vec5::new(0.2, -1.0, 0.5, 2.0, -0.1);
//! let qdd = Vec5::new(1.0, 3.0, -2.0, 0.5, 0.3);
//!
//! // Inverse dynamics equals the regressor times the base parameters.
//! let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
//! let phi = model.regressor(&q, &qd, &qdd);
//! assert!((phi * lambda - tau).norm() < 1e-12);
//!
//! // Forward dynamics inverts it.
//! let qdd_back = model.forward_dynamics(&q, &qd, &tau, &lambda)?;
//! assert!((qdd_back - qdd).norm() < 1e-9);
//!
//! // The same arm as a run-time chain (as a URDF or TOML file would give,
//! // `DynChain::from_file`): Newton–Euler agrees with the closed form.
//! let chain = DynChain::paper();
//! let tau_chain = chain.inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())?;
//! assert!((Vec5::from_column_slice(&tau_chain) - tau).norm() < 1e-9);
//! # Ok::<(), prrrp_core::PrrrpError>(())
//! ```
#![warn(missing_docs)]

mod data;
mod error;
mod estimators;
mod identification;
mod interrupt;
mod models;
mod motion;
mod online;
mod paper;
mod validation;

pub use data::dataset::{Dataset, DatasetParts};
pub use data::preprocess::{
    central_differences, preprocess, ButterworthLowPass, PreprocessConfig, MAX_BUTTERWORTH_ORDER,
};
pub use data::{
    preprocess_log, DynDataset, DynDatasetParts, LogConfig, LogReport, DEFAULT_LOG_CUTOFF_HZ,
    LOG_MAX_UPSAMPLING, LOG_UNIFORM_TOLERANCE,
};
pub use error::{PrrrpError, Result};
pub use estimators::ParameterJacobian;
pub use estimators::{
    base_feasibility, default_coulomb_scales, identify_physical, select_coulomb_scale,
    BaseFeasibility, CoulombScaleConfig, CoulombScaleReport, PhysicalConfig, PhysicalEstimate,
    PhysicalProblem, BASE_FEASIBILITY_TOLERANCE, BASE_MISMATCH_FLOOR, COULOMB_SCALE_FLAT,
    COULOMB_SCALE_GRID, COULOMB_SCALE_MAX_WIDENINGS, COULOMB_SCALE_MIN_Z, COULOMB_SCALE_RANGE,
    DEFAULT_DIVERGENCE_WEIGHT, MAX_COULOMB_CANDIDATES,
};
pub use estimators::{
    least_squares, weighted_least_squares, Adaline, AdalineConfig, AdalineOf, AdalineRule,
    Discretisation, DynAdaline, DynEkf, DynHopfield, DynJointNoise, DynLeastSquaresReport, DynRls,
    DynSample, DynSamples, Ekf, EkfAllocator, EkfConfig, EkfMeasurement, EkfOf, Estimator,
    Forgetting, Hopfield, HopfieldConfig, HopfieldOf, JointNoise, JointNoiseOf, LeastSquares,
    LeastSquaresConfig, LeastSquaresReport, LeastSquaresReportOf, PrrrpEkf, Rls, RlsConfig, RlsOf,
    Sample, SampleOf, Samples, SamplesOf, TrainingReport, PRRRP_EKF_STATES,
};
pub use identification::{
    identify, identify_least_squares, identify_robot, BaseDescription, EkfSettings, EkfStart,
    GradientSettings, IdentifiedModel, LsSettings, Method, PhysicalSettings, Predictor,
    RlsSettings, METHOD_NAMES, MODEL_SCHEMA_VERSION,
};
pub use identification::{
    identify_drive_gains, identify_payload, DriveGainSettings, DriveGains, DriveGainsFit,
    PayloadSettings,
};
pub use identification::{ActuatorEstimate, TermEstimate};
pub use interrupt::{check_count, clear_stop, request_stop, stop_requested, StopFlag, MAX_SAMPLES};
pub use models::chain::{
    com_and_inertia, inertial_parameters, is_physically_consistent, transform_inertial_parameters,
    BaseOptions, BaseParameters, ChainBaseModel, ChainDescription, ChainMeta, DhConvention,
    DhDescription, DynBaseWorkspace, DynChain, DynChainBaseModel, DynWorkspace, FrictionModel,
    Joint, JointDescription, JointInfo, JointLimit, JointType, PoseDescription, SerialChain,
    AXIS_UNIT_TOLERANCE, CHAIN_SCHEMA_VERSION, FRICTION_PARAMETER_NAMES, INERTIAL_PARAMETER_NAMES,
    LINK_PARAMS, MAX_DOF, MAX_MATRIX_ENTRIES, PHYSICAL_TOLERANCE,
};
pub use models::chain::{
    pseudo_inertia, pseudo_inertia_to_parameters, standard_from_base, FeasibilityReport,
    JointFrictionFeasibility, LinkFeasibility,
};
pub use models::chain::{Actuators, ACTUATOR_PARAMETER_NAMES, COUPLING_CONDITION_LIMIT};
pub use models::payload::{
    is_physical as is_physical_payload, project_physical, Payload, PayloadIdentifiable,
    PayloadThresholds,
};
pub use models::prrrp::derivatives::InverseDerivatives;
pub use models::prrrp::dynamics::{MassCholesky, PrrrpModel};
pub use models::prrrp::regressor::{condition_number, observation_matrix, singular_values};
pub use models::prrrp::robot::{DhRow, JointKind, Robot, STANDARD_GRAVITY};
pub use models::prrrp::types::{Lambda, Mat5, Regressor, Vec5, NDOF, NPARAM};
pub use models::robot_files::{
    UrdfOptions, MAX_ROBOT_FILE_BYTES, MAX_URDF_DEPTH, MAX_URDF_ELEMENTS,
};
pub use models::scaled::{DynScaledModel, DynScaledWorkspace, ScaledModel};
pub use models::{ForwardDerivatives, ForwardDerivativesOf, LinearDynamics, LinearModel};
pub use motion::chain_excitation::{
    optimise_chain_excitation, ChainExcitation, ChainExcitationConfig, MAX_EXCITATION_EVALUATIONS,
};
pub use motion::dyn_trajectory::{DynSampledTrajectory, FourierTrajectory};
pub use motion::dynamics::{Dynamics, ParameterisedModel, ParameterisedWorkspace};
pub use motion::excitation::{
    excitation_variables, optimise_excitation, ExcitationConfig, ExcitationProgress,
    ExcitationResult, DEFAULT_EXCITATION_KNOTS,
};
pub use motion::limits::{limit_usage, JointLimits, LimitUsage};
pub use motion::simulation::{
    rk4_step, rk4_step_into, simulate_closed_loop, simulate_dyn_closed_loop,
    simulate_dyn_open_loop, simulate_open_loop, ComputedTorque, DynComputedTorque, DynSensorNoise,
    DynSimulationConfig, DynSimulationRecord, Rk4Integrator, SensorNoise, SimulationConfig,
    SimulationRecord, MAX_INTEGRATION_STEPS, RK4_SCRATCH_PER_JOINT,
};
pub use motion::trajectory::{
    sample_trajectory, DynTrajectory, ExcitationTrajectory, FourierSeries, JointTrajectory,
    PiecewiseQuintic, Quintic, Reflected, SampledTrajectory, ScalarTrajectory, Sinusoid,
    TrajectoryPoint, REFLECTED_REST_TOLERANCE,
};
pub use online::{
    CausalKinematics, CausalLowPass, ChangeDetection, ChangeDetector, OnlineConfig,
    OnlineIdentifier, OnlineMethod, OnlineUpdate, ONLINE_METHOD_NAMES,
};
pub use paper::sensitivity::{sensitivity, SensitivityConfig, SensitivityReport};
pub use paper::study::{
    run_study, EstimationData, ExcitationSummary, History, MethodEstimate, MethodValidationSummary,
    SensitivitySummary, StudyConfig, StudyProgress, StudyResult, Timings, ValidationSummary,
    METHODS,
};
pub use validation::metrics::{
    agreement_index, error_indices, relative_errors_percent, rms, rsd, ErrorIndices,
};
pub use validation::{
    default_validation_reference, joint_indices, per_joint_indices, torque_prediction, validate,
    validate_identified_model, validate_torque_prediction, MethodValidation, TorquePrediction,
    TorqueValidation, ValidationConfig, ValidationReport,
};

/// Re-exported so that users name the same nalgebra and faer versions as the crate.
pub use faer;
pub use nalgebra;

/// The README's Rust example is compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
