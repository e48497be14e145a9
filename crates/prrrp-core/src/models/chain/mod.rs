//! Any serial manipulator of revolute and prismatic joints, from a Denavit–Hartenberg
//! table: recursive Newton–Euler inverse dynamics, composite-rigid-body mass matrix,
//! forward dynamics, the standard regressor (10 inertial parameters per link, plus
//! optional friction), numerical base parameters, and a base-parameter model the
//! estimators accept (paper section 4.1, eqs. 32–34, for any chain).
//!
//! Start with [`SerialChain`] (size fixed at compile time, allocation-free) or
//! [`DynChain`] (size known at run time). [`SerialChain::paper`] is the PRRRP arm of the
//! paper as a chain; it reproduces the closed-form [`crate::PrrrpModel`].

mod actuators;
mod base_model;
mod base_params;
mod crba;
mod derivatives;
mod description;
mod dh;
mod feasibility;
mod friction;
mod inertia;
mod joint;
mod meta;
mod paper;
mod regressor;
mod rnea;
mod robots;
mod serial_chain;
mod workspace;

pub use actuators::{Actuators, ACTUATOR_PARAMETER_NAMES, COUPLING_CONDITION_LIMIT};
pub use base_model::{
    BaseWorkspaceOf, ChainBaseModel, ChainBaseModelOf, ChainDim, DynBaseWorkspace,
    DynChainBaseModel,
};
pub use base_params::{BaseOptions, BaseParameters, MAX_MATRIX_ENTRIES};
pub(crate) use crba::{cholesky_in_place, cholesky_solve};
pub use description::{
    ChainDescription, DhDescription, JointDescription, PoseDescription, CHAIN_SCHEMA_VERSION,
};
pub use dh::DhConvention;
pub use feasibility::{
    standard_from_base, FeasibilityReport, JointFrictionFeasibility, LinkFeasibility,
};
pub use friction::{FrictionModel, FRICTION_PARAMETER_NAMES};
pub use inertia::{
    com_and_inertia, inertial_parameters, is_physically_consistent, pseudo_inertia,
    pseudo_inertia_to_parameters, transform_inertial_parameters, INERTIAL_PARAMETER_NAMES,
    LINK_PARAMS,
};
pub use joint::{Joint, JointType, AXIS_UNIT_TOLERANCE};
pub use meta::{ChainMeta, JointInfo, JointLimit};
pub(crate) use serial_chain::{check_dof, flat_samples};
pub use serial_chain::{DynChain, SerialChain, MAX_DOF, PHYSICAL_TOLERANCE};
pub use workspace::DynWorkspace;
