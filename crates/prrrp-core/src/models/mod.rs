//! The interface every parametric rigid-body model offers to the estimators.
//!
//! A model is linear in its P parameters: τ = Φ(q, q̇, q̈)·λ. Estimators are generic over
//! [`LinearModel`], which every compile-time [`LinearDynamics`] model implements and
//! run-time-size models such as [`crate::DynChainBaseModel`] implement directly, so they
//! work for the PRRRP arm ([`crate::PrrrpModel`]) and for any other robot.

//!
//! The models themselves: `chain` (any serial chain, compile-time or run-time size),
//! `prrrp` (the paper's arm in closed form), `robot_files` (chains read from URDF and
//! TOML files), `scaled` (column-scaled views the gradient estimators train on) and
//! `payload` (a load carried by a link).

pub(crate) mod chain;
pub(crate) mod payload;
pub(crate) mod prrrp;
pub(crate) mod robot_files;
pub(crate) mod scaled;

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix, SVector, U1};

use crate::error::{check_joints, check_shape, Result};

// The module's public API (also at the crate root through `prelude`).
pub use chain::{
    com_and_inertia, inertial_parameters, is_physically_consistent, transform_inertial_parameters,
    BaseOptions, BaseParameters, BaseWorkspaceOf, ChainBaseModel, ChainBaseModelOf,
    ChainDescription, ChainDim, ChainMeta, DhConvention, DhDescription, DynBaseWorkspace, DynChain,
    DynChainBaseModel, DynWorkspace, FrictionModel, Joint, JointDescription, JointInfo, JointLimit,
    JointType, PoseDescription, SerialChain, AXIS_UNIT_TOLERANCE, CHAIN_SCHEMA_VERSION,
    FRICTION_PARAMETER_NAMES, INERTIAL_PARAMETER_NAMES, LINK_PARAMS, MAX_DOF, MAX_MATRIX_ENTRIES,
    PHYSICAL_TOLERANCE,
};
pub use chain::{
    pseudo_inertia, pseudo_inertia_to_parameters, standard_from_base, FeasibilityReport,
    JointFrictionFeasibility, LinkFeasibility,
};
pub use chain::{Actuators, ACTUATOR_PARAMETER_NAMES, COUPLING_CONDITION_LIMIT};
pub use payload::{
    is_physical as is_physical_payload, project_physical, Payload, PayloadIdentifiable,
    PayloadThresholds,
};
pub use prrrp::derivatives::InverseDerivatives;
pub use prrrp::dynamics::{MassCholesky, PrrrpModel};
pub use prrrp::regressor::{condition_number, observation_matrix, singular_values};
pub use prrrp::robot::{DhRow, JointKind, Robot, STANDARD_GRAVITY};
pub use prrrp::types::{Lambda, Mat5, Regressor, Vec5, NDOF, NPARAM};
pub use robot_files::{UrdfOptions, MAX_ROBOT_FILE_BYTES, MAX_URDF_DEPTH, MAX_URDF_ELEMENTS};
pub use scaled::{DynScaledModel, DynScaledWorkspace, ScaledModel};

/// Derivatives of the forward dynamics q̈ = M⁻¹(τ − C·q̇ − G), all at fixed τ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForwardDerivatives<const N: usize, const P: usize> {
    /// The acceleration q̈ itself.
    pub qdd: SVector<f64, N>,
    /// ∂q̈/∂q.
    pub dqdd_dq: SMatrix<f64, N, N>,
    /// ∂q̈/∂q̇.
    pub dqdd_dqd: SMatrix<f64, N, N>,
    /// ∂q̈/∂λ = −M⁻¹·Φ(q, q̇, q̈).
    pub dqdd_dlambda: SMatrix<f64, N, P>,
}

/// A rigid-body model with N joints whose dynamics are linear in P parameters.
///
/// All methods are per-sample and must not allocate.
pub trait LinearDynamics<const N: usize, const P: usize> {
    /// Regressor Φ(q, q̇, q̈) ∈ R^{N×P}, so that τ = Φ·λ.
    fn regressor(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SMatrix<f64, N, P>;

    /// Inverse dynamics τ = M(q, λ)·q̈ + C(q, q̇, λ)·q̇ + G(q, λ).
    fn inverse_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> SVector<f64, N> {
        self.regressor(q, qd, qdd) * lambda
    }

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G).
    ///
    /// # Errors
    /// [`crate::PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite.
    fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<SVector<f64, N>>;

    /// Forward dynamics and its derivatives with respect to q, q̇ and λ.
    ///
    /// # Errors
    /// [`crate::PrrrpError::NotPositiveDefinite`] if M(q, λ) is not positive definite.
    fn forward_derivatives(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<ForwardDerivatives<N, P>>;
}

/// [`ForwardDerivatives`] at sizes known at compile time (`Const<N>`) or at run time
/// ([`nalgebra::Dyn`]): the output buffer of [`LinearModel::forward_derivatives_into`],
/// allocated once (by [`ForwardDerivativesOf::zeros`]) and overwritten per sample.
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardDerivativesOf<N: Dim, P: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<N, P>,
{
    /// The acceleration q̈ (m/s², rad/s²).
    pub qdd: OVector<f64, N>,
    /// ∂q̈/∂q (1/s² for revolute/revolute pairs; units of q̈ per unit of q).
    pub dqdd_dq: OMatrix<f64, N, N>,
    /// ∂q̈/∂q̇ (1/s; units of q̈ per unit of q̇).
    pub dqdd_dqd: OMatrix<f64, N, N>,
    /// ∂q̈/∂λ = −M⁻¹·Φ(q, q̇, q̈) (units of q̈ per unit of λ).
    pub dqdd_dlambda: OMatrix<f64, N, P>,
}

impl<N: Dim, P: Dim> ForwardDerivativesOf<N, P>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N> + Allocator<N, P>,
{
    /// Zero-filled buffers for N joints and P parameters (the only allocation, for
    /// run-time sizes).
    pub fn zeros(n: N, p: P) -> Self {
        Self {
            qdd: OVector::zeros_generic(n, U1),
            dqdd_dq: OMatrix::zeros_generic(n, n),
            dqdd_dqd: OMatrix::zeros_generic(n, n),
            dqdd_dlambda: OMatrix::zeros_generic(n, p),
        }
    }
}

impl ForwardDerivativesOf<Dyn, Dyn> {
    /// The [`crate::PrrrpError::ShapeMismatch`] of the first buffer (`out.qdd`,
    /// `out.dqdd_dq`, `out.dqdd_dqd`, `out.dqdd_dlambda`) not sized for n joints and p
    /// parameters.
    pub(crate) fn check_shape(&self, n: usize, p: usize) -> Result<()> {
        check_joints("out.qdd", self.qdd.len(), n)?;
        check_shape("out.dqdd_dq", self.dqdd_dq.shape(), (n, n))?;
        check_shape("out.dqdd_dqd", self.dqdd_dqd.shape(), (n, n))?;
        check_shape("out.dqdd_dlambda", self.dqdd_dlambda.shape(), (n, p))
    }
}

/// The model interface of the estimators, at sizes known at compile time or at run time.
///
/// N (joints) and P (parameters) are nalgebra dimensions: `Const<N>` for models whose
/// sizes are fixed at compile time (every [`LinearDynamics<N, P>`] is a
/// `LinearModel<Const<N>, Const<P>>` through a blanket implementation, with
/// `Workspace = ()`), [`nalgebra::Dyn`] for models whose sizes come from data, such as
/// [`crate::DynChainBaseModel`]. The estimators are written once against this trait.
///
/// Every method writes into caller-owned buffers and a [`LinearModel::Workspace`] made
/// once by [`LinearModel::workspace`], so that no per-sample call allocates at either
/// size. Inputs are in the model's units (m, rad, m/s, rad/s, m/s², rad/s², N, N·m).
pub trait LinearModel<N: Dim, P: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// Scratch memory of the per-sample methods (`()` for compile-time models).
    type Workspace: Clone + std::fmt::Debug;

    /// The number of joints N and of parameters P.
    fn dims(&self) -> (N, P);

    /// A workspace for this model (the one allocation of run-time models).
    fn workspace(&self) -> Self::Workspace;

    /// Regressor Φ(q, q̇, q̈) ∈ R^{N×P} into `out`, so that τ = Φ·λ.
    ///
    /// # Errors
    /// [`crate::PrrrpError::ShapeMismatch`] if a run-time size does not match
    /// [`LinearModel::dims`] (compile-time models cannot fail).
    fn regressor_into(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        qdd: &OVector<f64, N>,
        out: &mut OMatrix<f64, N, P>,
    ) -> Result<()>;

    /// Calls `f` with the regressor Φ(q, q̇, q̈) and returns its result. The default
    /// writes Φ into `buf` ([`LinearModel::regressor_into`]); compile-time models hand `f`
    /// a stack value instead, which the optimiser keeps in registers (the estimators' hot
    /// loops read Φ several times per sample).
    ///
    /// # Errors
    /// As [`LinearModel::regressor_into`].
    #[inline(always)]
    fn with_regressor<R>(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        qdd: &OVector<f64, N>,
        buf: &mut OMatrix<f64, N, P>,
        f: impl FnOnce(&OMatrix<f64, N, P>) -> R,
    ) -> Result<R> {
        self.regressor_into(ws, q, qd, qdd, buf)?;
        Ok(f(buf))
    }

    /// Inverse dynamics τ = M(q, λ)·q̈ + C(q, q̇, λ)·q̇ + G(q, λ) (+ friction) into `out`.
    ///
    /// # Errors
    /// As [`LinearModel::regressor_into`].
    fn inverse_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        qdd: &OVector<f64, N>,
        lambda: &OVector<f64, P>,
        out: &mut OVector<f64, N>,
    ) -> Result<()>;

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G) at parameters λ into `out`.
    ///
    /// # Errors
    /// As [`LinearModel::regressor_into`], and [`crate::PrrrpError::NotPositiveDefinite`]
    /// if M(q, λ) is not positive definite.
    fn forward_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        tau: &OVector<f64, N>,
        lambda: &OVector<f64, P>,
        out: &mut OVector<f64, N>,
    ) -> Result<()>;

    /// Forward dynamics and its derivatives with respect to q, q̇ and λ into `out`.
    ///
    /// # Errors
    /// As [`LinearModel::forward_dynamics_into`].
    fn forward_derivatives_into(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        tau: &OVector<f64, N>,
        lambda: &OVector<f64, P>,
        out: &mut ForwardDerivativesOf<N, P>,
    ) -> Result<()>;

    /// The forward dynamics at τ into `out.qdd`, and the derivatives of
    /// [`LinearModel::forward_derivatives_into`] taken at the acceleration `qdd_lin`
    /// instead (at the torque τ_lin = τ_ID(q, q̇, q̈_lin, λ) that produces it: ∂q̈/∂λ =
    /// −M⁻¹·Φ(q, q̇, q̈_lin)). What the EKF linearised at the data's acceleration needs.
    /// The default is those three calls (τ_lin into `tau_lin`); a model that keeps the
    /// factor of M overrides it with one mass matrix and no inverse dynamics (the same
    /// values to round-off).
    ///
    /// # Errors
    /// As [`LinearModel::forward_dynamics_into`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn forward_derivatives_at_into(
        &self,
        ws: &mut Self::Workspace,
        q: &OVector<f64, N>,
        qd: &OVector<f64, N>,
        qdd_lin: &OVector<f64, N>,
        tau: &OVector<f64, N>,
        lambda: &OVector<f64, P>,
        tau_lin: &mut OVector<f64, N>,
        out: &mut ForwardDerivativesOf<N, P>,
    ) -> Result<()> {
        self.inverse_dynamics_into(ws, q, qd, qdd_lin, lambda, tau_lin)?;
        self.forward_derivatives_into(ws, q, qd, tau_lin, lambda, out)?;
        self.forward_dynamics_into(ws, q, qd, tau, lambda, &mut out.qdd)
    }

    /// The forward dynamics at τ and the derivatives at `qdd_lin` (as
    /// [`LinearModel::forward_derivatives_at_into`]; at that q̈ when `None`, as
    /// [`LinearModel::forward_derivatives_into`]) with ∂q̈/∂λ = −M⁻¹·Φ left as its
    /// factors: Φ(q, q̇, q̈_lin) into `out.dqdd_dlambda`, M(q, λ)⁻¹ into `minv` (units of
    /// q̈ per unit of τ). A chain's Φ is about half zeros (row j holds only the parameters
    /// of links ≥ j and of joint j's actuator), which a product with it can skip. Returns
    /// `Ok(false)`, computing nothing, when the model does not provide the factors (the
    /// default).
    ///
    /// # Errors
    /// As [`LinearModel::forward_dynamics_into`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn forward_derivatives_factored_into(
        &self,
        _ws: &mut Self::Workspace,
        _q: &OVector<f64, N>,
        _qd: &OVector<f64, N>,
        _qdd_lin: Option<&OVector<f64, N>>,
        _tau: &OVector<f64, N>,
        _lambda: &OVector<f64, P>,
        _minv: &mut OMatrix<f64, N, N>,
        _out: &mut ForwardDerivativesOf<N, P>,
    ) -> Result<bool> {
        Ok(false)
    }
}

/// Compile-time models: the fixed-size methods, copied into the buffers (a few dozen
/// stack values; the copies are what the estimators did before with the returned values).
impl<T, const N: usize, const P: usize> LinearModel<Const<N>, Const<P>> for T
where
    T: LinearDynamics<N, P>,
{
    type Workspace = ();

    #[inline(always)]
    fn dims(&self) -> (Const<N>, Const<P>) {
        (Const, Const)
    }

    #[inline(always)]
    fn workspace(&self) {}

    #[inline(always)]
    fn regressor_into(
        &self,
        _: &mut (),
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        out: &mut SMatrix<f64, N, P>,
    ) -> Result<()> {
        *out = self.regressor(q, qd, qdd);
        Ok(())
    }

    #[inline(always)]
    fn with_regressor<R>(
        &self,
        _: &mut (),
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        _: &mut SMatrix<f64, N, P>,
        f: impl FnOnce(&SMatrix<f64, N, P>) -> R,
    ) -> Result<R> {
        let phi = self.regressor(q, qd, qdd);
        Ok(f(&phi))
    }

    #[inline(always)]
    fn inverse_dynamics_into(
        &self,
        _: &mut (),
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
        out: &mut SVector<f64, N>,
    ) -> Result<()> {
        *out = self.inverse_dynamics(q, qd, qdd, lambda);
        Ok(())
    }

    #[inline(always)]
    fn forward_dynamics_into(
        &self,
        _: &mut (),
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
        out: &mut SVector<f64, N>,
    ) -> Result<()> {
        *out = self.forward_dynamics(q, qd, tau, lambda)?;
        Ok(())
    }

    #[inline(always)]
    fn forward_derivatives_into(
        &self,
        _: &mut (),
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
        out: &mut ForwardDerivativesOf<Const<N>, Const<P>>,
    ) -> Result<()> {
        let fd = self.forward_derivatives(q, qd, tau, lambda)?;
        out.qdd = fd.qdd;
        out.dqdd_dq = fd.dqdd_dq;
        out.dqdd_dqd = fd.dqdd_dqd;
        out.dqdd_dlambda = fd.dqdd_dlambda;
        Ok(())
    }
}
