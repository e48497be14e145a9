//! Fixed-size vector and matrix aliases used throughout the crate (all on the stack).

use nalgebra::{SMatrix, SVector};

/// Number of joints of the PRRRP arm.
pub const NDOF: usize = 5;
/// Number of grouped base parameters λ of the PRRRP arm.
pub const NPARAM: usize = 8;

/// A joint-space vector: q = [d1, θ2, θ3, θ4, d5] (m, rad, rad, rad, m), its derivatives,
/// or generalised forces τ = [F1, τ2, τ3, τ4, F5] (N, N·m, N·m, N·m, N).
pub type Vec5 = SVector<f64, NDOF>;
/// A 5×5 joint-space matrix (mass matrix, Jacobians of joint quantities).
pub type Mat5 = SMatrix<f64, NDOF, NDOF>;
/// The 8 grouped base parameters λ (see [`crate::Robot::base_parameters`]).
pub type Lambda = SVector<f64, NPARAM>;
/// The 5×8 regressor Φ(q, q̇, q̈) with τ = Φ·λ.
pub type Regressor = SMatrix<f64, NDOF, NPARAM>;
