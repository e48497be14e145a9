//! What a simulator needs of a robot: inverse dynamics τ = ID(q, q̇, q̈) and forward
//! dynamics q̈ = FD(q, q̇, τ) **at given parameters**, for n joints known at run time,
//! written into caller-owned slices with a workspace sized once ([`Dynamics`]).
//!
//! Implemented by
//! - [`DynChain`]: the full chain, its inertial **and friction** parameters (the "true
//!   robot" of a simulation study);
//! - [`ParameterisedModel`]: any [`LinearModel`] at a parameter vector λ, e.g. the paper's
//!   closed-form [`crate::PrrrpModel`] with λ, or a [`crate::DynChainBaseModel`] with β
//!   (the model a controller or an identification holds).

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OVector, U1};

use crate::error::{check_joints, PrrrpError, Result};
use crate::models::chain::{DynChain, DynWorkspace};
use crate::models::LinearModel;

/// Rigid-body (plus friction) dynamics of n joints at fixed parameters, per sample,
/// allocation-free.
///
/// Slices are in the robot's joint order and units (m, rad; m/s, rad/s; m/s², rad/s²; N,
/// N·m) and each holds exactly [`Dynamics::dof`] entries; a slice of another length is a
/// [`PrrrpError::ShapeMismatch`], never a panic. The workspace comes from
/// [`Dynamics::workspace`] (the one allocation) and is reused for every call.
pub trait Dynamics {
    /// Scratch memory of the per-sample methods.
    type Workspace: Clone + std::fmt::Debug;

    /// Number of joints n.
    fn dof(&self) -> usize;

    /// A workspace for this model.
    fn workspace(&self) -> Self::Workspace;

    /// Inverse dynamics τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q) (+ friction) into `tau` (N, N·m).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a slice that does not have n entries.
    fn inverse_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<()>;

    /// Forward dynamics q̈ = M(q)⁻¹·(τ − C(q, q̇)·q̇ − G(q) − friction) into `qdd`.
    ///
    /// # Errors
    /// As [`Dynamics::inverse_dynamics_into`], and [`PrrrpError::NotPositiveDefinite`] if
    /// M(q) is not positive definite at these parameters.
    fn forward_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<()>;

    /// The magnitudes fc_j ≥ 0 (N, N·m) of the Coulomb terms fc_j·sgn(q̇_j) **with the
    /// exact sign** (sgn(0) = 0) that the two dynamics above include, into `fc` (n
    /// entries, 0 for joints without one); returns whether any is nonzero. The default
    /// has none.
    ///
    /// The exact sign is a set-valued law at q̇_j = 0 (a joint at rest sticks while the
    /// other forces stay within ±fc_j): the simulators' integrator ([`crate::Rk4Integrator`])
    /// treats these terms by stick–slip event handling, and [`crate::DynComputedTorque`]
    /// compensates them from the reference velocity, which neither can do without knowing
    /// them.
    fn exact_coulomb_into(&self, fc: &mut [f64]) -> bool {
        fc.fill(0.0);
        false
    }
}

/// The full chain: its own inertial parameters and friction ([`DynChain::friction`]).
/// A Coulomb term with the exact sign (`coulomb_smoothing` = 0) is reported by
/// [`Dynamics::exact_coulomb_into`] for joints with fc > 0 (a negative fc, which only an
/// unconstrained identification gives, is left in the dynamics as it is) whose actuator
/// drives that joint alone; the friction of a coupled actuator (a wrist motor turning
/// with q5 + q6) stays in the dynamics with its exact sign, so simulate such an arm with
/// a smoothed sign (`coulomb_smoothing` > 0).
impl Dynamics for DynChain {
    type Workspace = DynWorkspace;

    fn dof(&self) -> usize {
        DynChain::dof(self)
    }

    fn workspace(&self) -> DynWorkspace {
        DynChain::workspace(self)
    }

    #[inline]
    fn inverse_dynamics_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<()> {
        DynChain::inverse_dynamics_into(self, ws, q, qd, qdd, tau)
    }

    #[inline]
    fn forward_dynamics_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        DynChain::forward_dynamics_into(self, ws, q, qd, tau, qdd)
    }

    fn exact_coulomb_into(&self, fc: &mut [f64]) -> bool {
        fc.fill(0.0);
        let f = self.friction();
        if !(f.coulomb && f.coulomb_smoothing == 0.0) {
            return false;
        }
        let coupling = self.actuators().coupling.as_deref();
        for (m, (o, p)) in fc.iter_mut().zip(self.friction_params()).enumerate() {
            // Stick–slip events are per joint: an actuator coupled to several joints
            // (a row of C other than e_m) keeps its exact sign in the dynamics.
            let own_joint = match coupling {
                None => true,
                Some(c) => c[m]
                    .iter()
                    .enumerate()
                    .all(|(j, &x)| x == if j == m { 1.0 } else { 0.0 }),
            };
            *o = if own_joint { p[1].max(0.0) } else { 0.0 };
        }
        fc.iter().any(|&x| x > 0.0)
    }
}

/// A [`LinearModel`] (τ = Φ(q, q̇, q̈)·λ) frozen at one parameter vector λ, as a
/// [`Dynamics`]: the paper's arm is `ParameterisedModel::new(PrrrpModel, λ)`, a chain seen
/// through its base parameters is `ParameterisedModel::new(chain.base_model(&base)?, β)`.
///
/// ```
/// use prrrp_core::{Dynamics, ParameterisedModel, Robot};
/// let robot = Robot::paper();
/// let arm = ParameterisedModel::new(robot.model(), robot.base_parameters())?;
/// let mut ws = arm.workspace();
/// let (q, qd, qdd) = ([0.1, 0.2, -0.3, 0.4, 0.02], [0.0; 5], [0.5; 5]);
/// let mut tau = [0.0; 5];
/// arm.inverse_dynamics_into(&mut ws, &q, &qd, &qdd, &mut tau)?;
/// let mut back = [0.0; 5];
/// arm.forward_dynamics_into(&mut ws, &q, &qd, &tau, &mut back)?;
/// assert!(back.iter().zip(&qdd).all(|(a, b)| (a - b).abs() < 1e-9));
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterisedModel<M, N: Dim, P: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    model: M,
    lambda: OVector<f64, P>,
    n: N,
}

impl<M, N: Dim, P: Dim> ParameterisedModel<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    /// `model` at the parameters `lambda` (units of the model's parameters).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if λ does not have the model's parameter count,
    /// [`PrrrpError::NonFinite`] naming the first NaN/∞ entry.
    pub fn new(model: M, lambda: OVector<f64, P>) -> Result<Self> {
        let (n, p) = model.dims();
        if lambda.len() != p.value() {
            return Err(PrrrpError::ShapeMismatch {
                what: "parameters".into(),
                expected: format!("{} entries (the model's parameters)", p.value()),
                got: format!("{} entries", lambda.len()),
            });
        }
        if let Some(i) = lambda.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("parameters[{i}]"),
                row: None,
            });
        }
        Ok(Self { model, lambda, n })
    }

    /// The model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The parameters λ.
    pub fn parameters(&self) -> &OVector<f64, P> {
        &self.lambda
    }

    /// Checks that the three inputs and the output each have n entries (the first wrong
    /// one, in that order, is the error), copies the inputs into the workspace's vectors,
    /// runs `method` of the model on them at λ and copies its result into `out`.
    #[inline]
    fn run(
        &self,
        ws: &mut ParameterisedWorkspace<M::Workspace, N>,
        inputs: [(&'static str, &[f64]); 3],
        output: &'static str,
        out: &mut [f64],
        method: impl FnOnce(
            &M,
            &mut M::Workspace,
            &OVector<f64, N>,
            &OVector<f64, N>,
            &OVector<f64, N>,
            &OVector<f64, P>,
            &mut OVector<f64, N>,
        ) -> Result<()>,
    ) -> Result<()> {
        let n = self.n.value();
        for (what, len) in inputs.map(|(what, v)| (what, v.len())) {
            check_joints(what, len, n)?;
        }
        check_joints(output, out.len(), n)?;
        let [a, b, c] = inputs.map(|(_, v)| v);
        ws.a.as_mut_slice().copy_from_slice(a);
        ws.b.as_mut_slice().copy_from_slice(b);
        ws.c.as_mut_slice().copy_from_slice(c);
        method(
            &self.model,
            &mut ws.model,
            &ws.a,
            &ws.b,
            &ws.c,
            &self.lambda,
            &mut ws.out,
        )?;
        out.copy_from_slice(ws.out.as_slice());
        Ok(())
    }
}

/// Workspace of a [`ParameterisedModel`]: the model's own plus the vectors the slices are
/// copied through (stack values for compile-time sizes).
#[derive(Debug, Clone)]
pub struct ParameterisedWorkspace<W, N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    model: W,
    a: OVector<f64, N>,
    b: OVector<f64, N>,
    c: OVector<f64, N>,
    out: OVector<f64, N>,
}

impl<M, N: Dim, P: Dim> Dynamics for ParameterisedModel<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
    OVector<f64, P>: std::fmt::Debug,
{
    type Workspace = ParameterisedWorkspace<M::Workspace, N>;

    #[inline]
    fn dof(&self) -> usize {
        self.n.value()
    }

    fn workspace(&self) -> Self::Workspace {
        let z = || OVector::zeros_generic(self.n, U1);
        ParameterisedWorkspace {
            model: self.model.workspace(),
            a: z(),
            b: z(),
            c: z(),
            out: z(),
        }
    }

    #[inline]
    fn inverse_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<()> {
        let inputs = [("q", q), ("qd", qd), ("qdd", qdd)];
        self.run(ws, inputs, "tau", tau, M::inverse_dynamics_into)
    }

    #[inline]
    fn forward_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        let inputs = [("q", q), ("qd", qd), ("tau", tau)];
        self.run(ws, inputs, "qdd", qdd, M::forward_dynamics_into)
    }
}
