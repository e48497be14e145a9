//! Identification while the arm runs: [`OnlineIdentifier`] takes one raw sample at a time
//! (time stamp, positions, joint forces, optionally velocities) and returns the current
//! estimate, with σ where the method has one, and the one-step-ahead torque prediction
//! of the row from the estimate before it.
//!
//! Everything is causal (a future sample never changes a past estimate): velocities and
//! accelerations come from a per-joint Kalman tracker ([`CausalKinematics`]); RLS, the EKF,
//! Adaline and Hopfield step once per sample ([`OnlineMethod`]); a jump of the prediction
//! errors ([`ChangeDetector`]) reopens the covariance so that the estimate follows a gripped
//! part (the whole-arm RLS first along the tip link's directions, `tip`); payload mode (`OnlineConfig::payload`) estimates only a tip payload on a prior arm; from no knowledge
//! the Coulomb speed scale can be chosen online ([`CoulombSearch`]).
//! [`OnlineIdentifier::estimate`] is an [`crate::IdentifiedModel`] at any moment. Per-sample
//! cost is allocation-free (`tests/alloc_online.rs`).
//!
//! Design: docs/design/online.md; speed: docs/online-speed.md.

mod coulomb_search;
mod cutoff;
mod detector;
mod guard;
mod identifier;
mod kinematics;
mod payload;
mod payload_ekf;
mod tip;
mod tracked;

pub use coulomb_search::{CoulombSearch, ONLINE_COULOMB_SCALES};
pub use detector::{ChangeDetection, ChangeDetector};
pub use identifier::{
    OnlineConfig, OnlineIdentifier, OnlineMethod, OnlineUpdate, ONLINE_METHOD_NAMES,
};
pub use kinematics::{CausalKinematics, CausalLowPass};
