//! The paper's 5-DOF PRRRP arm in closed form: its DH table and physical parameters
//! ([`robot`]), the Lagrange–Euler model as a function of its 8 base parameters
//! ([`dynamics`], [`terms`]), the 5×8 regressor and observation matrix ([`regressor`]) and
//! the analytic derivatives the EKF needs ([`derivatives`]), and the form extended to
//! first moments across the links that the arm's chain evaluates through ([`extended`]).

pub(crate) mod derivatives;
pub(crate) mod dynamics;
pub(crate) mod extended;
pub(crate) mod regressor;
pub(crate) mod robot;
pub(crate) mod terms;
pub(crate) mod types;
