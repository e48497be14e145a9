//! Parameter estimators of the paper's sections 2 and 4: least squares (batch, weighted
//! and recursive), Adaline, Hopfield network and extended Kalman filter.
//!
//! Every online estimator has the same shape ([`Estimator`]): it is built once from a
//! `Copy + Default` config, [`Estimator::step`] consumes one [`Sample`] and updates
//! preallocated fixed-size state without touching the heap, [`Estimator::estimate`]
//! borrows the current λ̂, [`Estimator::reset`] returns to the initial state and
//! [`Estimator::run`] loops `step` over a [`Samples`]. All of them are generic over the
//! model through [`crate::LinearModel`]`<N, P>` (N joints, P parameters, nalgebra
//! dimensions): one implementation serves compile-time sizes (`Const<N>`, aliases
//! [`Rls`], [`Adaline`], [`Hopfield`], [`Samples`], …) and run-time sizes (`Dyn`,
//! aliases [`DynRls`], [`DynAdaline`], [`DynHopfield`], [`DynSamples`], …).

mod adaline;
mod coulomb_scale;
mod ekf;
mod estimator;
mod hopfield;
mod least_squares;
mod physical;
mod rls;
mod samples;
mod stored;

pub use adaline::{Adaline, AdalineConfig, AdalineOf, AdalineRule, DynAdaline};
pub use coulomb_scale::{
    default_coulomb_scales, select_coulomb_scale, CoulombScaleConfig, CoulombScaleReport,
    COULOMB_SCALE_FLAT, COULOMB_SCALE_GRID, COULOMB_SCALE_MAX_WIDENINGS, COULOMB_SCALE_MIN_Z,
    COULOMB_SCALE_RANGE, MAX_COULOMB_CANDIDATES,
};
pub use ekf::ParameterJacobian;
pub use ekf::{
    Discretisation, DynEkf, Ekf, EkfAllocator, EkfConfig, EkfMeasurement, EkfOf, PrrrpEkf,
    PRRRP_EKF_STATES,
};
pub(crate) use estimator::with_row;
pub use estimator::{Estimator, TrainingReport};
pub use hopfield::{DynHopfield, Hopfield, HopfieldConfig, HopfieldOf, MAX_HOPFIELD_SUBSTEPS};
pub use least_squares::{
    least_squares, weighted_least_squares, DynJointNoise, DynLeastSquaresReport, JointNoise,
    JointNoiseOf, LeastSquares, LeastSquaresConfig, LeastSquaresReport, LeastSquaresReportOf,
};
pub use physical::{
    base_feasibility, identify_physical, BaseFeasibility, PhysicalConfig, PhysicalEstimate,
    PhysicalProblem, BASE_FEASIBILITY_TOLERANCE, BASE_MISMATCH_FLOOR, DEFAULT_DIVERGENCE_WEIGHT,
};
pub use rls::{DynRls, Forgetting, Rls, RlsConfig, RlsOf};
pub(crate) use samples::len_mismatch;
pub use samples::{DynSample, DynSamples, Sample, SampleOf, Samples, SamplesOf};
pub use stored::{StoredRegressors, MAX_STORED_REGRESSOR_BYTES};
