//! A chain seen through its base parameters: the model the estimators take,
//! τ = Φ_b(q, q̇, q̈)·β, as one type over nalgebra dimensions — [`ChainBaseModel`] for a
//! [`SerialChain<N>`] with B base parameters fixed at compile time (`Const<N>`,
//! `Const<B>`; stack arrays, a [`LinearDynamics`] model) and [`DynChainBaseModel`] for a
//! [`DynChain`] whose sizes come at run time (`Dyn`; a [`LinearModel`]`<Dyn, Dyn>` with a
//! [`DynBaseWorkspace`] sized once).
//!
//! Why one type: the per-sample mathematics (equivalent chain, Newton–Euler, mass matrix,
//! Cholesky, derivatives) is written once over slices and a [`BaseWorkspaceOf`]; the two
//! trait adapters at the end only check run-time sizes or wrap stack values. The chain
//! itself stays a separate type per size ([`ChainDim::Chain`]): the model only needs its
//! kernel view.

use std::ops::IndexMut;

use nalgebra::allocator::Allocator;
use nalgebra::{
    Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix, SVector, U1,
};

use super::actuators::ActuatorLayout;
use super::base_params::BaseParameters;
use super::crba::{cholesky_in_place, cholesky_solve, inverse_from_factor, minus_inverse_times};
use super::derivatives::LinkTangent;
use super::regressor::RegressorSink;
use super::rnea::{ChainView, LinkState};
use super::serial_chain::{DynChain, SerialChain};
use crate::error::{check_joints, check_len, check_shape, PrrrpError, Result};
use crate::models::{ForwardDerivatives, ForwardDerivativesOf, LinearDynamics, LinearModel};

const NONE: usize = usize::MAX;

/// Where a base parameter lives in the standard layout.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    /// Inertial parameter k of link i.
    Rigid(usize, usize),
    /// Actuator term `kind` (0 viscous, 1 Coulomb, 2 offset, 3 armature) of actuator m.
    Actuator(usize, usize),
}

mod sealed {
    use super::ChainView;

    /// The kernels' view of a chain, behind a type the public trait below may name.
    pub struct View<'a>(pub(crate) ChainView<'a>);

    /// What the base model reads from its chain: the kernels' view of it.
    pub trait Chain {
        fn kernel_view(&self) -> View<'_>;
    }

    /// Only `Const<N>` and `Dyn` are chain dimensions.
    pub trait Sealed {}
}

/// A joint-count dimension N and the chain type with that many joints:
/// [`SerialChain<N>`] at `Const<N>` (arrays, sizes fixed at compile time), [`DynChain`] at
/// [`Dyn`] (sizes known at run time). Sealed: implemented for those two only.
pub trait ChainDim: Dim + sealed::Sealed {
    /// The chain type with N joints.
    type Chain: sealed::Chain + Clone + std::fmt::Debug + PartialEq;
}

impl<const N: usize> sealed::Sealed for Const<N> {}
impl sealed::Sealed for Dyn {}

impl<const N: usize> ChainDim for Const<N> {
    type Chain = SerialChain<N>;
}

impl ChainDim for Dyn {
    type Chain = DynChain;
}

impl<const N: usize> sealed::Chain for SerialChain<N> {
    #[inline(always)]
    fn kernel_view(&self) -> sealed::View<'_> {
        sealed::View(self.view())
    }
}

impl sealed::Chain for DynChain {
    #[inline(always)]
    fn kernel_view(&self) -> sealed::View<'_> {
        sealed::View(self.view())
    }
}

/// The dynamics of a chain with N joints parametrised by its B base parameters β (from
/// [`SerialChain::base_parameters`] or [`DynChain::base_parameters`]), for the
/// estimators; N and B are nalgebra dimensions (`Const` or `Dyn`, see
/// [`ChainBaseModel`] and [`DynChainBaseModel`]). Allocation-free per sample.
///
/// The base regressor Φ_b holds the independent columns of the full regressor. The model
/// at any β is the chain whose independent standard parameters equal β and whose other
/// parameters are zero: since the dependent columns are combinations of the independent
/// ones, this chain has exactly the joint forces Φ_b·β, so inverse and forward dynamics
/// run the O(n) recursions instead of building Φ_b. Such an equivalent chain is
/// generally not physical, but its mass matrix is positive definite whenever β comes
/// from a physical robot (it equals that robot's).
///
/// Actuator columns of the analysis (friction, armature; see [`super::Actuators`]) are
/// base columns like the inertial ones; a Coulomb term uses the chain's
/// [`super::FrictionModel::coulomb_smoothing`] (tanh(q̇ₘ/v_s) when v_s > 0, the exact
/// sign otherwise), in the regressor, the dynamics and the derivatives alike.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainBaseModelOf<N: ChainDim, B: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<B>,
{
    chain: N::Chain,
    rigid_map: OVector<[usize; 10], N>,
    actuator_map: OVector<[usize; 4], N>,
    slots: OVector<Slot, B>,
    beta: OVector<f64, B>,
}

/// A [`SerialChain<N>`] with B base parameters, both fixed at compile time: a
/// [`LinearDynamics<N, B>`] model on stack arrays (from [`SerialChain::base_model`]).
pub type ChainBaseModel<const N: usize, const B: usize> = ChainBaseModelOf<Const<N>, Const<B>>;

/// A [`DynChain`] with B base parameters, N = [`DynChain::dof`] and B =
/// [`BaseParameters::count`] known at run time: a [`LinearModel<Dyn, Dyn>`] whose
/// per-sample methods work in a [`DynBaseWorkspace`] (from [`DynChain::base_model`]).
///
/// ```
/// use prrrp_core::{BaseOptions, LinearModel, SerialChain};
/// let chain = SerialChain::puma560().to_dyn();
/// let base = chain.base_parameters(&BaseOptions::default())?;
/// let model = chain.base_model(&base)?;
/// let (n, b) = model.dims();
/// assert_eq!((n.0, b.0), (6, base.count()));
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
pub type DynChainBaseModel = ChainBaseModelOf<Dyn, Dyn>;

impl<const N: usize, const B: usize> Copy for ChainBaseModel<N, B> {}

/// Scratch memory of the per-sample methods of a [`ChainBaseModelOf`] with N joints: O(N)
/// except for the N×N mass matrix and its inverse. Run-time models hand it out through
/// [`LinearModel::workspace`]; compile-time models keep one on the stack per call.
#[derive(Debug, Clone)]
pub struct BaseWorkspaceOf<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    st: OVector<LinkState, N>,
    comp: OVector<[f64; 10], N>,
    /// Standard parameters of the equivalent chain at the current β.
    rig: OVector<[f64; 10], N>,
    fr: OVector<[f64; 3], N>,
    ia: OVector<f64, N>,
    /// Cholesky factor of M(q, β), column-major.
    m: OMatrix<f64, N, N>,
    zero: OVector<f64, N>,
    /// M⁻¹ (column-major), for the derivatives' 2N + B right-hand sides at once.
    minv: OMatrix<f64, N, N>,
    /// τ of the primal pass, and one column being multiplied by M⁻¹.
    tmp: OVector<f64, N>,
    col: OVector<f64, N>,
    /// Tangents of the derivative kernel.
    tan: OVector<LinkTangent, N>,
}

/// Scratch memory of one [`DynChainBaseModel`] (from [`LinearModel::workspace`]).
pub type DynBaseWorkspace = BaseWorkspaceOf<Dyn>;

impl<N: Dim> BaseWorkspaceOf<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    fn new(n: N) -> Self {
        let v = || OVector::<f64, N>::zeros_generic(n, U1);
        Self {
            st: OVector::from_element_generic(n, U1, LinkState::default()),
            comp: OVector::from_element_generic(n, U1, [0.0; 10]),
            rig: OVector::from_element_generic(n, U1, [0.0; 10]),
            fr: OVector::from_element_generic(n, U1, [0.0; 3]),
            ia: v(),
            m: OMatrix::zeros_generic(n, n),
            zero: v(),
            minv: OMatrix::zeros_generic(n, n),
            tmp: v(),
            col: v(),
            tan: OVector::from_element_generic(n, U1, LinkTangent::default()),
        }
    }
}

/// Writes the base columns of the regressor: standard column (link, k) or (actuator,
/// kind) goes to base column `rigid_map[link][k]` / `actuator_map[act][kind]` (none if
/// [`NONE`]). `O` is the N×B output matrix, at compile-time or run-time size.
struct BaseSink<'a, O> {
    out: &'a mut O,
    rigid_map: &'a [[usize; 10]],
    actuator_map: &'a [[usize; 4]],
}

impl<O: IndexMut<(usize, usize), Output = f64>> RegressorSink for BaseSink<'_, O> {
    #[inline(always)]
    fn rigid(&mut self, row: usize, link: usize, k: usize, v: f64) {
        let c = self.rigid_map[link][k];
        if c != NONE {
            self.out[(row, c)] = v;
        }
    }
    #[inline(always)]
    fn actuator(&mut self, row: usize, act: usize, kind: usize, v: f64) {
        let c = self.actuator_map[act][kind];
        if c != NONE {
            self.out[(row, c)] = v;
        }
    }
}

/// Standard parameters of the equivalent chain with base parameters `beta` (base column c
/// in `slots[c]`): inertial `rig`, friction `fr` and armature `ia`, zero where no base
/// parameter lives.
#[inline(always)]
fn load_equivalent(
    slots: &[Slot],
    beta: &[f64],
    rig: &mut [[f64; 10]],
    fr: &mut [[f64; 3]],
    ia: &mut [f64],
) {
    rig.fill([0.0; 10]);
    fr.fill([0.0; 3]);
    ia.fill(0.0);
    for (c, s) in slots.iter().enumerate() {
        match *s {
            Slot::Rigid(i, k) => rig[i][k] = beta[c],
            Slot::Actuator(m, 3) => ia[m] = beta[c],
            Slot::Actuator(m, kind) => fr[m][kind] = beta[c],
        }
    }
}

/// `v` with the standard parameters of an equivalent chain (see [`load_equivalent`]).
#[inline(always)]
fn equivalent_view<'a>(
    mut v: ChainView<'a>,
    rig: &'a [[f64; 10]],
    fr: &'a [[f64; 3]],
    ia: &'a [f64],
) -> ChainView<'a> {
    v.inertial = rig;
    v.friction_params = fr;
    if v.armature.is_some() {
        v.armature = Some(ia);
    }
    v
}

/// Where standard parameter `idx` of a chain with `n` joints and actuator layout `l` lives.
fn slot_of(idx: usize, n: usize, l: &ActuatorLayout) -> Slot {
    if idx < 10 * n {
        Slot::Rigid(idx / 10, idx % 10)
    } else {
        let per = l.per.max(1);
        let off = idx - 10 * n;
        let (m, s) = (off / per, off % per);
        Slot::Actuator(m, l.kind_of(s))
    }
}

impl<N: ChainDim, B: Dim> ChainBaseModelOf<N, B>
where
    DefaultAllocator: Allocator<N> + Allocator<B> + Allocator<N, N>,
{
    /// The model of `chain` (N = `n` joints, standard parameters `params`) for the
    /// analysis `base` with B = `b` base parameters.
    fn build(chain: N::Chain, n: N, b: B, base: &BaseParameters, params: &[f64]) -> Result<Self> {
        use sealed::Chain as _;
        let layout = chain.kernel_view().0.layout();
        base.check_layout(n.value(), &layout)?;
        if base.count() != b.value() {
            return Err(PrrrpError::ShapeMismatch {
                what: "base parameter count B".into(),
                expected: format!("{} (from the analysis)", base.count()),
                got: format!("{}", b.value()),
            });
        }
        if base.count() == 0 {
            return Err(PrrrpError::shape(
                "base parameters",
                "at least one identifiable parameter",
                "0 (the chain has no dynamics to identify)",
            ));
        }
        let p = params.len();
        if let Some(&bad) = base.independent.iter().find(|&&i| i >= p) {
            return Err(PrrrpError::shape(
                "base parameter index",
                format!("< {p} (standard parameters of this chain)"),
                format!("{bad}"),
            ));
        }
        let mut rigid_map = OVector::from_element_generic(n, U1, [NONE; 10]);
        let mut actuator_map = OVector::from_element_generic(n, U1, [NONE; 4]);
        let mut slots = OVector::from_element_generic(b, U1, Slot::Rigid(0, 0));
        for (c, &idx) in base.independent.iter().enumerate() {
            let slot = slot_of(idx, n.value(), &layout);
            match slot {
                Slot::Rigid(i, k) => rigid_map[i][k] = c,
                Slot::Actuator(j, kind) => actuator_map[j][kind] = c,
            }
            slots[c] = slot;
        }
        let beta = OVector::from_vec_generic(b, U1, base.base_values(params)?);
        Ok(Self {
            chain,
            rigid_map,
            actuator_map,
            slots,
            beta,
        })
    }

    /// Number of joints N.
    pub fn dof(&self) -> usize {
        self.rigid_map.nrows()
    }

    /// Number of base parameters B.
    pub fn count(&self) -> usize {
        self.slots.nrows()
    }

    /// The chain this model was built from ([`SerialChain<N>`] or [`DynChain`]).
    pub fn chain(&self) -> &N::Chain {
        &self.chain
    }

    fn scratch(&self) -> BaseWorkspaceOf<N> {
        BaseWorkspaceOf::new(self.rigid_map.shape_generic().0)
    }

    /// The chain's own view, with its standard parameters.
    #[inline(always)]
    fn chain_view(&self) -> ChainView<'_> {
        use sealed::Chain as _;
        self.chain.kernel_view().0
    }

    /// Loads the standard parameters of the equivalent chain at β (B entries) into `ws`.
    #[inline(always)]
    fn load(&self, beta: &[f64], ws: &mut BaseWorkspaceOf<N>) {
        let (rig, fr, ia) = (
            ws.rig.as_mut_slice(),
            ws.fr.as_mut_slice(),
            ws.ia.as_mut_slice(),
        );
        load_equivalent(self.slots.as_slice(), beta, rig, fr, ia);
    }

    /// The base regressor Φ_b(q, q̇, q̈) (`x` = [q, q̇, q̈]) into `out` (N×B, zero on entry);
    /// `kinematics_done`: `st` holds the kinematics at `x` already (a Newton–Euler pass's).
    #[inline(always)]
    fn regressor_in<O>(
        &self,
        x: [&[f64]; 3],
        st: &mut [LinkState],
        out: &mut O,
        kinematics_done: bool,
    ) where
        O: IndexMut<(usize, usize), Output = f64>,
    {
        let mut sink = BaseSink {
            out,
            rigid_map: self.rigid_map.as_slice(),
            actuator_map: self.actuator_map.as_slice(),
        };
        let view = self.chain_view();
        if kinematics_done {
            view.regressor_at_kinematics(x[1], x[2], true, st, &mut sink);
        } else {
            view.regressor_into(x[0], x[1], x[2], true, st, &mut sink);
        }
    }

    /// τ = Φ_b·β (`x` = [q, q̇, q̈]) into `tau` by Newton–Euler on the equivalent chain.
    #[inline(always)]
    fn inverse_in(
        &self,
        ws: &mut BaseWorkspaceOf<N>,
        x: [&[f64]; 3],
        beta: &[f64],
        tau: &mut [f64],
    ) {
        self.load(beta, ws);
        let BaseWorkspaceOf {
            st, rig, fr, ia, ..
        } = ws;
        let view = equivalent_view(
            self.chain_view(),
            rig.as_slice(),
            fr.as_slice(),
            ia.as_slice(),
        );
        view.rnea(x[0], x[1], x[2], st.as_mut_slice(), tau);
    }

    /// M(q, β) (column-major N×N) into `m`.
    #[inline(always)]
    fn mass_matrix_in(&self, ws: &mut BaseWorkspaceOf<N>, q: &[f64], beta: &[f64], m: &mut [f64]) {
        self.load(beta, ws);
        let BaseWorkspaceOf {
            st,
            comp,
            rig,
            fr,
            ia,
            ..
        } = ws;
        let (rig, fr, ia) = (rig.as_slice(), fr.as_slice(), ia.as_slice());
        let view = equivalent_view(self.chain_view(), rig, fr, ia);
        view.mass_matrix_with(rig, q, st.as_mut_slice(), comp.as_mut_slice(), m);
    }

    /// q̈ = M(q, β)⁻¹·(τ − bias) (`x` = [q, q̇, τ]) into `qdd`.
    #[inline(always)]
    fn forward_in(
        &self,
        ws: &mut BaseWorkspaceOf<N>,
        x: [&[f64]; 3],
        beta: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        self.load(beta, ws);
        self.forward_loaded(ws, x[0], x[1], x[2], qdd)
    }

    /// q̈ = M⁻¹(τ − bias) at the β already loaded into `ws`; leaves the factor of M in
    /// `ws.m`.
    #[inline(always)]
    fn forward_loaded(
        &self,
        ws: &mut BaseWorkspaceOf<N>,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        let n = self.dof();
        let BaseWorkspaceOf {
            st,
            comp,
            rig,
            fr,
            ia,
            m,
            zero,
            ..
        } = ws;
        let (rig, fr, ia) = (rig.as_slice(), fr.as_slice(), ia.as_slice());
        let (st, m) = (st.as_mut_slice(), m.as_mut_slice());
        let view = equivalent_view(self.chain_view(), rig, fr, ia);
        view.mass_matrix_with(rig, q, st, comp.as_mut_slice(), m);
        cholesky_in_place(m, n).map_err(|_| PrrrpError::NotPositiveDefinite {
            what: "mass matrix M(q, β) of the base-parameter model",
        })?;
        view.rnea(q, qd, zero.as_slice(), st, out);
        for (x, t) in out.iter_mut().zip(tau) {
            *x = t - *x;
        }
        cholesky_solve(m, n, out);
        Ok(())
    }

    /// ∂q̈/∂q, ∂q̈/∂q̇ and ∂q̈/∂β at the acceleration `qdd`, with β loaded and M factorised
    /// in `ws` (by [`Self::forward_loaded`]). With `minv_out`, M⁻¹ goes there (column-major)
    /// and `dqdd_dlambda` keeps Φ_b, not multiplied by −M⁻¹.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn derivatives_loaded(
        &self,
        ws: &mut BaseWorkspaceOf<N>,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        dqdd_dq: &mut OMatrix<f64, N, N>,
        dqdd_dqd: &mut OMatrix<f64, N, N>,
        dqdd_dlambda: &mut OMatrix<f64, N, B>,
        minv_out: Option<&mut [f64]>,
    ) where
        DefaultAllocator: Allocator<N, B>,
    {
        let n = self.dof();
        let BaseWorkspaceOf {
            st,
            rig,
            fr,
            ia,
            m,
            minv,
            tmp,
            col,
            tan,
            ..
        } = ws;
        let (rig, fr, ia) = (rig.as_slice(), fr.as_slice(), ia.as_slice());
        let (st, minv, col) = (st.as_mut_slice(), minv.as_mut_slice(), col.as_mut_slice());
        let full = equivalent_view(self.chain_view(), rig, fr, ia);
        // Recursive even for the paper's arm: the tangent passes read its link states.
        let rigid = full.rigid().recursive();
        // The primal pass at q̈ leaves the kinematics and joint forces that the tangent
        // passes differentiate.
        rigid.rnea(q, qd, qdd, st, tmp.as_mut_slice());
        let dq = dqdd_dq.as_mut_slice();
        let dqd = dqdd_dqd.as_mut_slice();
        rigid.rnea_derivatives(rig, qd, st, tan.as_mut_slice(), dq, dqd);
        full.add_actuator_slope(fr, qd, dqd);
        // Φ_b at q̈, from the primal pass's kinematics (the tangent passes leave them).
        dqdd_dlambda.fill(0.0);
        self.regressor_in([q, qd, qdd], st, dqdd_dlambda, true);
        // −M⁻¹ times the 2N + B columns.
        inverse_from_factor(m.as_slice(), n, minv);
        minus_inverse_times(minv, n, dqdd_dq.as_mut_slice(), col);
        minus_inverse_times(minv, n, dqdd_dqd.as_mut_slice(), col);
        match minv_out {
            Some(out) => out.copy_from_slice(minv),
            None => minus_inverse_times(minv, n, dqdd_dlambda.as_mut_slice(), col),
        }
    }

    /// Loads β, then q̈ = M⁻¹·(τ − bias) into `out.qdd` and the derivatives at `qdd_lin`
    /// (at that q̈ if `None`) into the rest of `out`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn forward_and_derivatives(
        &self,
        ws: &mut BaseWorkspaceOf<N>,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        lambda: &[f64],
        qdd_lin: Option<&[f64]>,
        minv: Option<&mut [f64]>,
        out: &mut ForwardDerivativesOf<N, B>,
    ) -> Result<()>
    where
        DefaultAllocator: Allocator<N, B>,
    {
        self.load(lambda, ws);
        self.forward_loaded(ws, q, qd, tau, out.qdd.as_mut_slice())?;
        let ForwardDerivativesOf {
            qdd,
            dqdd_dq,
            dqdd_dqd,
            dqdd_dlambda,
        } = out;
        let at = qdd_lin.unwrap_or(qdd.as_slice());
        self.derivatives_loaded(ws, q, qd, at, dqdd_dq, dqdd_dqd, dqdd_dlambda, minv);
        Ok(())
    }
}

impl<const N: usize> SerialChain<N> {
    /// The base-parameter model of this chain for an analysis `base` with B base
    /// parameters (B is checked against `base.count()`).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if B ≠ `base.count()`, `base` has no base parameter
    /// or was computed for a chain with another number of joints or friction model.
    pub fn base_model<const B: usize>(
        &self,
        base: &BaseParameters,
    ) -> Result<ChainBaseModel<N, B>> {
        ChainBaseModelOf::build(*self, Const, Const, base, &self.parameters())
    }
}

impl<const N: usize, const B: usize> ChainBaseModel<N, B> {
    /// The base parameters β = K·π of the chain this model was built from (its true
    /// values, e.g. for simulation studies; units of the standard parameters: kg, kg·m,
    /// kg·m², N·s/m or N·m·s/rad, N or N·m).
    pub fn chain_base_values(&self) -> SVector<f64, B> {
        self.beta
    }

    /// Mass matrix M(q, β) of the equivalent chain (kg, kg·m, kg·m² by joint kinds).
    pub fn mass_matrix(&self, q: &SVector<f64, N>, beta: &SVector<f64, B>) -> SMatrix<f64, N, N> {
        let mut ws = self.scratch();
        let mut m = SMatrix::<f64, N, N>::zeros();
        self.mass_matrix_in(&mut ws, q.as_slice(), beta.as_slice(), m.as_mut_slice());
        m
    }
}

/// The compile-time adapter: each method runs the shared implementation in a workspace on
/// the stack and returns its result by value.
impl<const N: usize, const B: usize> LinearDynamics<N, B> for ChainBaseModel<N, B> {
    #[inline]
    fn regressor(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SMatrix<f64, N, B> {
        let mut out = SMatrix::<f64, N, B>::zeros();
        let mut st = [LinkState::default(); N];
        let x = [q.as_slice(), qd.as_slice(), qdd.as_slice()];
        self.regressor_in(x, &mut st, &mut out, false);
        out
    }

    #[inline]
    fn inverse_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        lambda: &SVector<f64, B>,
    ) -> SVector<f64, N> {
        let mut ws = self.scratch();
        let mut tau = SVector::<f64, N>::zeros();
        let x = [q.as_slice(), qd.as_slice(), qdd.as_slice()];
        self.inverse_in(&mut ws, x, lambda.as_slice(), tau.as_mut_slice());
        tau
    }

    #[inline]
    fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, B>,
    ) -> Result<SVector<f64, N>> {
        let mut ws = self.scratch();
        let mut x = SVector::<f64, N>::zeros();
        let x3 = [q.as_slice(), qd.as_slice(), tau.as_slice()];
        self.forward_in(&mut ws, x3, lambda.as_slice(), x.as_mut_slice())?;
        Ok(x)
    }

    /// ∂q̈/∂β = −M⁻¹·Φ_b(q, q̇, q̈); ∂q̈/∂q and ∂q̈/∂q̇ = −M⁻¹ times the exact
    /// derivatives of the rigid-body inverse dynamics at fixed q̈ (tangent-linear
    /// Newton–Euler, as [`DynChainBaseModel`]), plus the friction slope in closed form
    /// (the exact Coulomb sign contributes 0; use `coulomb_smoothing` > 0 for a smooth
    /// model).
    fn forward_derivatives(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, B>,
    ) -> Result<ForwardDerivatives<N, B>> {
        let mut ws = self.scratch();
        let mut out = ForwardDerivativesOf::zeros(Const::<N>, Const::<B>);
        let (q, qd, tau) = (q.as_slice(), qd.as_slice(), tau.as_slice());
        self.forward_and_derivatives(&mut ws, q, qd, tau, lambda.as_slice(), None, None, &mut out)?;
        Ok(ForwardDerivatives {
            qdd: out.qdd,
            dqdd_dq: out.dqdd_dq,
            dqdd_dqd: out.dqdd_dqd,
            dqdd_dlambda: out.dqdd_dlambda,
        })
    }
}

impl DynChain {
    /// The run-time base-parameter model of this chain for the analysis `base` (from
    /// [`DynChain::base_parameters`] of this chain).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `base` was computed for a chain with another
    /// number of joints or friction model, or has no base parameter.
    pub fn base_model(&self, base: &BaseParameters) -> Result<DynChainBaseModel> {
        let (n, b) = (Dyn(self.dof()), Dyn(base.count()));
        ChainBaseModelOf::build(self.clone(), n, b, base, &self.parameters())
    }
}

impl DynChainBaseModel {
    /// The base parameters β = K·π of the chain this model was built from (its true
    /// values, e.g. for simulation studies; units of the standard parameters: kg, kg·m,
    /// kg·m², N·s/m or N·m·s/rad, N or N·m).
    pub fn chain_base_values(&self) -> &DVector<f64> {
        &self.beta
    }

    /// Mass matrix M(q, β) of the equivalent chain (kg, kg·m, kg·m² by joint kinds).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if q does not have N entries or β not B.
    pub fn mass_matrix(&self, q: &DVector<f64>, beta: &DVector<f64>) -> Result<DMatrix<f64>> {
        self.check_joint("q", q.len())?;
        self.check_beta(beta.len())?;
        let mut ws = self.scratch();
        let n = self.dof();
        let mut m = DMatrix::zeros(n, n);
        self.mass_matrix_in(&mut ws, q.as_slice(), beta.as_slice(), m.as_mut_slice());
        Ok(m)
    }

    fn check_joint(&self, what: &str, len: usize) -> Result<()> {
        check_joints(what, len, self.dof())
    }

    fn check_beta(&self, len: usize) -> Result<()> {
        let note = " (one per base parameter)";
        check_len(
            "lambda (base parameters)",
            len,
            self.count(),
            "entries",
            note,
        )
    }

    /// The checks of a per-sample call: the workspace, each vector of `joints` (one entry
    /// per joint), the derivatives' output `out` if any, and λ (B entries).
    fn check_call(
        &self,
        ws: &DynBaseWorkspace,
        joints: &[(&str, &DVector<f64>)],
        lambda: &DVector<f64>,
        out: Option<&ForwardDerivativesOf<Dyn, Dyn>>,
    ) -> Result<()> {
        self.check_ws(ws)?;
        for &(what, v) in joints {
            self.check_joint(what, v.len())?;
        }
        if let Some(out) = out {
            self.check_joint("out.qdd", out.qdd.len())?;
        }
        self.check_beta(lambda.len())?;
        match out {
            Some(out) => out.check_shape(self.dof(), self.count()),
            None => Ok(()),
        }
    }

    /// [`ChainBaseModelOf::forward_and_derivatives`] on the vectors of a checked call
    /// (`x` = q, q̇, τ).
    #[inline(always)]
    fn derivatives_of(
        &self,
        ws: &mut DynBaseWorkspace,
        x: [&DVector<f64>; 3],
        lambda: &DVector<f64>,
        qdd_lin: Option<&DVector<f64>>,
        minv: Option<&mut DMatrix<f64>>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        let [q, qd, tau] = x.map(|v| v.as_slice());
        let at = qdd_lin.map(|v| v.as_slice());
        let minv = minv.map(|m| m.as_mut_slice());
        self.forward_and_derivatives(ws, q, qd, tau, lambda.as_slice(), at, minv, out)
    }

    fn check_ws(&self, ws: &DynBaseWorkspace) -> Result<()> {
        let got = ws.st.nrows();
        if got != self.dof() {
            return Err(PrrrpError::shape(
                "workspace",
                format!("a workspace of this model ({} joints)", self.dof()),
                format!("{got} joints"),
            ));
        }
        Ok(())
    }

    fn check_matrix(&self, what: &str, m: &DMatrix<f64>, cols: usize) -> Result<()> {
        check_shape(what, m.shape(), (self.dof(), cols))
    }
}

/// The run-time adapter: each method checks the sizes, then runs the shared
/// implementation in the caller's workspace.
impl LinearModel<Dyn, Dyn> for DynChainBaseModel {
    type Workspace = DynBaseWorkspace;

    fn dims(&self) -> (Dyn, Dyn) {
        (Dyn(self.dof()), Dyn(self.count()))
    }

    fn workspace(&self) -> DynBaseWorkspace {
        self.scratch()
    }

    /// Base regressor Φ_b (N×B): the independent columns of the chain's full regressor,
    /// friction columns included.
    fn regressor_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        self.check_ws(ws)?;
        for (what, v) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            self.check_joint(what, v.len())?;
        }
        self.check_matrix("regressor output", out, self.count())?;
        out.fill(0.0);
        let x = [q.as_slice(), qd.as_slice(), qdd.as_slice()];
        self.regressor_in(x, ws.st.as_mut_slice(), out, false);
        Ok(())
    }

    /// τ = Φ_b·β by recursive Newton–Euler on the equivalent chain (O(N), Φ_b never
    /// built).
    fn inverse_dynamics_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        lambda: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<()> {
        let joints = [("q", q), ("qd", qd), ("qdd", qdd), ("out", &*out)];
        self.check_call(ws, &joints, lambda, None)?;
        let x = [q.as_slice(), qd.as_slice(), qdd.as_slice()];
        self.inverse_in(ws, x, lambda.as_slice(), out.as_mut_slice());
        Ok(())
    }

    /// q̈ = M(q, β)⁻¹·(τ − C(q, q̇, β)·q̇ − G(q, β) − τ_f(q̇, β)), with M by the
    /// composite-rigid-body algorithm and the bias by Newton–Euler at q̈ = 0.
    fn forward_dynamics_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        tau: &DVector<f64>,
        lambda: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<()> {
        let joints = [("q", q), ("qd", qd), ("tau", tau), ("out", &*out)];
        self.check_call(ws, &joints, lambda, None)?;
        let x = [q.as_slice(), qd.as_slice(), tau.as_slice()];
        self.forward_in(ws, x, lambda.as_slice(), out.as_mut_slice())
    }

    /// ∂q̈/∂β = −M⁻¹·Φ_b(q, q̇, q̈); ∂q̈/∂q and ∂q̈/∂q̇ = −M⁻¹ times the exact derivatives
    /// of the rigid-body inverse dynamics at fixed q̈ (tangent-linear Newton–Euler, O(N²),
    /// no perturbation step), plus the friction slope in closed form (the exact Coulomb
    /// sign contributes 0; set `coulomb_smoothing` > 0 for a smooth model). Costs a mass
    /// matrix, three recursions and the tangent passes (about N/2 recursions).
    fn forward_derivatives_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        tau: &DVector<f64>,
        lambda: &DVector<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        let joints = [("q", q), ("qd", qd), ("tau", tau)];
        self.check_call(ws, &joints, lambda, Some(out))?;
        self.derivatives_of(ws, [q, qd, tau], lambda, None, None, out)
    }

    /// One mass matrix and its factor for both: q̈ = M⁻¹·(τ − bias) as
    /// [`LinearModel::forward_dynamics_into`], and the derivatives at `qdd_lin` directly
    /// (the default's τ_lin would only reproduce `qdd_lin` through M⁻¹·(τ_lin − bias),
    /// to round-off); `tau_lin` is not used.
    fn forward_derivatives_at_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd_lin: &DVector<f64>,
        tau: &DVector<f64>,
        lambda: &DVector<f64>,
        _tau_lin: &mut DVector<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        let joints = [("q", q), ("qd", qd), ("qdd_lin", qdd_lin), ("tau", tau)];
        self.check_call(ws, &joints, lambda, Some(out))?;
        self.derivatives_of(ws, [q, qd, tau], lambda, Some(qdd_lin), None, out)
    }

    /// As [`Self::forward_derivatives_at_into`] (or [`Self::forward_derivatives_into`]
    /// without `qdd_lin`), with Φ_b in `out.dqdd_dlambda` and M⁻¹ in `minv`.
    fn forward_derivatives_factored_into(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd_lin: Option<&DVector<f64>>,
        tau: &DVector<f64>,
        lambda: &DVector<f64>,
        minv: &mut DMatrix<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<bool> {
        let joints = [("q", q), ("qd", qd), ("tau", tau)];
        self.check_call(ws, &joints, lambda, Some(out))?;
        if let Some(v) = qdd_lin {
            self.check_joint("qdd_lin", v.len())?;
        }
        self.check_matrix("minv", minv, self.dof())?;
        self.derivatives_of(ws, [q, qd, tau], lambda, qdd_lin, Some(minv), out)?;
        Ok(true)
    }
}
