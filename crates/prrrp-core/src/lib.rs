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

pub mod bounds;
pub mod data;
mod error;
pub mod estimators;
pub mod identification;
pub mod interrupt;
mod json;
mod linalg;
pub mod models;
pub mod motion;
pub mod online;
pub mod paper;
#[cfg(test)]
mod test_support;
pub mod validation;

pub use error::{PrrrpError, Result};

/// Every public item of the modules in one flat namespace, for glob imports
/// (`use prrrp_core::prelude::*;`): the crate root's list before the modules were public.
pub mod prelude {
    pub use crate::bounds::*;
    pub use crate::data::*;
    pub use crate::error::{PrrrpError, Result};
    pub use crate::estimators::*;
    pub use crate::identification::*;
    pub use crate::interrupt::*;
    pub use crate::models::*;
    pub use crate::motion::*;
    pub use crate::online::*;
    pub use crate::paper::*;
    pub use crate::validation::*;
}
// The flat names stay importable from the root for code written against it.
#[doc(hidden)]
pub use prelude::*;

/// Re-exported so that users name the same nalgebra and faer versions as the crate.
pub use faer;
pub use nalgebra;

/// The README's Rust example is compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
