//! Parameter estimators of the paper's sections 2 and 4: least squares (batch, weighted
//! and recursive), Adaline, Hopfield network and extended Kalman filter.
//!
//! Every online estimator has the same shape ([`Estimator`]): it is built once from a
//! `Copy + Default` config, [`Estimator::step`] consumes one [`Sample`] and updates
//! preallocated fixed-size state without touching the heap, [`Estimator::estimate`]
//! borrows the current λ̂, [`Estimator::reset`] returns to the initial state and
//! [`Estimator::run`] loops `step` over a [`Samples`]. All of them are generic over the
//! model through [`crate::LinearDynamics`]`<N, P>` (N joints, P parameters).

mod adaline;
mod ekf;
mod estimator;
mod hopfield;
mod least_squares;
mod rls;
mod samples;

pub use adaline::{Adaline, AdalineConfig, AdalineRule};
pub use ekf::{Discretisation, Ekf, EkfConfig, EkfMeasurement, PrrrpEkf, PRRRP_EKF_STATES};
pub(crate) use estimator::with_row;
pub use estimator::{Estimator, TrainingReport};
pub use hopfield::{Hopfield, HopfieldConfig};
pub use least_squares::{
    least_squares, weighted_least_squares, JointNoise, LeastSquares, LeastSquaresConfig,
    LeastSquaresReport,
};
pub use rls::{Rls, RlsConfig};
pub use samples::{Sample, Samples};
