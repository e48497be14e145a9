//! # prrrp-core
//!
//! Dynamic model and parameter identification of the 5-DOF PRRRP redundant manipulator of
//! Urrea & Pascal, "Parameter identification methods for real redundant manipulators",
//! J. Appl. Res. Technol. 15 (2017) 320–331.
//!
//! The crate gives the closed-form Lagrange–Euler model of the arm **as a function of its
//! 8 grouped base parameters λ**: mass matrix, Coriolis/centrifugal vector, gravity,
//! inverse and forward dynamics, the 5×8 regressor Φ with τ = Φ·λ, the stacked observation
//! matrix W and its condition number, and the analytic derivatives an extended Kalman
//! filter needs. Every per-sample function works on stack-allocated nalgebra types and
//! never touches the heap; batch linear algebra uses faer.
//!
//! ## Conventions
//! - q = [d1, θ2, θ3, θ4, d5] in m, rad, rad, rad, m; τ = [F1, τ2, τ3, τ4, F5] in N, N·m,
//!   N·m, N·m, N.
//! - World z points up; gravity acts along −z with magnitude `gravity` (9.81 m/s² by
//!   default). Joint 1 lifts the arm along +z, joints 2–4 rotate about vertical axes,
//!   joint 5 moves the tool along −z (DH α4 = 180°), so G5 = −m5·g and M15 = −m5.
//! - Inertias of links 2–4 are about their centres of mass.
//!
//! ## Example
//! ```
//! use prrrp_core::{Robot, Vec5};
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
