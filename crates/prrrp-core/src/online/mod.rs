//! Identification while the arm runs: [`OnlineIdentifier`] takes one raw sample at a time
//! (time stamp, positions, joint forces, optionally velocities) and returns the current
//! estimate, with σ where the method has one, and the one-step-ahead torque prediction
//! of the row from the estimate before it.
//!
//! - **Causal preprocessing** ([`CausalKinematics`]): a per-joint Kalman tracker gives q̇
//!   and q̈ at each row's own time from this and earlier rows only (irregular time stamps
//!   welcome; repeated rows are predicted and skipped; gaps restart it). Changing a
//!   future sample never changes a past estimate.
//! - **Methods** ([`OnlineMethod`]): RLS (joint-weighted by the running noise levels,
//!   with exponential or directional [`crate::Forgetting`]), the EKF of the paper on
//!   [q, q̇, θ] (started inside the physical region: from a prior model, or from an RLS
//!   warm-up once M(q, θ̂) has stayed positive definite; anchored, stiff-safe), Adaline
//!   and the Hopfield network (one step per sample, no σ). RLS, Adaline and Hopfield run
//!   on parameters equilibrated on random states within the robot's limits, fixed before
//!   the first sample.
//! - **Change detection** ([`ChangeDetector`]): a jump of the one-step-ahead errors over
//!   their running level opens the covariance (RLS, EKF) so that the estimate follows a
//!   gripped part within a fraction of a second.
//! - **Payload mode** (`OnlineConfig::payload`, with a prior arm model): only the 10
//!   inertial parameters of a payload at the tip link are estimated, projected
//!   onto the rigid bodies after every update.
//!
//! [`OnlineIdentifier::estimate`] returns an [`crate::IdentifiedModel`] at any moment
//! (the arm, plus the payload in payload mode), which predicts and saves like any other.
//! Per-sample cost is allocation-free (`tests/alloc_online.rs`).

mod detector;
mod identifier;
mod kinematics;
mod payload;
mod tracked;

pub use detector::{ChangeDetection, ChangeDetector};
pub use identifier::{
    OnlineConfig, OnlineIdentifier, OnlineMethod, OnlineUpdate, ONLINE_METHOD_NAMES,
};
pub use kinematics::{CausalKinematics, CausalLowPass};
