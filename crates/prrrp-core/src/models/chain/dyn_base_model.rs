//! A run-time-size chain seen through its base parameters: the [`LinearModel`]`<Dyn, Dyn>`
//! the estimators take for a robot whose joint count N and base-parameter count B are
//! known only at run time (a URDF, a Python call), τ = Φ_b(q, q̇, q̈)·β.
//!
//! Same construction as the compile-time [`super::ChainBaseModel`]: the model at any β is
//! the equivalent chain whose independent standard parameters equal β and whose others
//! are zero, so inverse dynamics, M(β) and the bias forces at an arbitrary β come from the
//! O(n) recursions. Every per-sample method works in a [`DynBaseWorkspace`] sized once.

use nalgebra::{DMatrix, DVector, Dyn};

use super::base_model::{
    base_regressor_into, equivalent_view, fill_maps, load_equivalent, Slot, NONE,
};
use super::base_params::BaseParameters;
use super::crba::{cholesky_in_place, cholesky_solve, inverse_from_factor, minus_inverse_times};
use super::derivatives::LinkTangent;
use super::rnea::{ChainView, LinkState};
use super::serial_chain::DynChain;
use crate::error::{check_joints, check_len, PrrrpError, Result};
use crate::models::{ForwardDerivativesOf, LinearModel};

/// The dynamics of a [`DynChain`] parametrised by its B base parameters β (from
/// [`DynChain::base_parameters`]), for the estimators: it implements
/// [`LinearModel<Dyn, Dyn>`] with N = [`DynChain::dof`] joints and B =
/// [`BaseParameters::count`] parameters, allocation-free per sample.
///
/// Actuator columns of the analysis (friction, armature; see [`super::Actuators`]) are
/// base columns like the inertial ones; a Coulomb term uses the chain's
/// [`super::FrictionModel::coulomb_smoothing`] (tanh(q̇ₘ/v_s) when v_s > 0, the exact
/// sign otherwise), in the regressor, the dynamics and the derivatives alike.
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
#[derive(Debug, Clone, PartialEq)]
pub struct DynChainBaseModel {
    chain: DynChain,
    rigid_map: Vec<[usize; 10]>,
    actuator_map: Vec<[usize; 4]>,
    slots: Vec<Slot>,
    beta: DVector<f64>,
}

/// Scratch memory of the per-sample methods of one [`DynChainBaseModel`] (from
/// [`LinearModel::workspace`]); O(N) except for the N×N mass matrix.
#[derive(Debug, Clone)]
pub struct DynBaseWorkspace {
    n: usize,
    st: Vec<LinkState>,
    comp: Vec<[f64; 10]>,
    /// Standard parameters of the equivalent chain at the current β.
    rig: Vec<[f64; 10]>,
    fr: Vec<[f64; 3]>,
    ia: Vec<f64>,
    /// Cholesky factor of M(q, β), column-major.
    m: Vec<f64>,
    zero: Vec<f64>,
    /// M⁻¹ (column-major), for the derivatives' 2N + B right-hand sides at once.
    minv: Vec<f64>,
    /// τ of the primal pass, and one column being multiplied by M⁻¹.
    tmp: Vec<f64>,
    col: Vec<f64>,
    /// Tangents of the derivative kernel.
    tan: Vec<LinkTangent>,
}

impl DynChain {
    /// The run-time base-parameter model of this chain for the analysis `base` (from
    /// [`DynChain::base_parameters`] of this chain).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `base` was computed for a chain with another
    /// number of joints or friction model, or has no base parameter.
    pub fn base_model(&self, base: &BaseParameters) -> Result<DynChainBaseModel> {
        let n = self.dof();
        let layout = self.layout();
        base.check_layout(n, &layout)?;
        if base.count() == 0 {
            return Err(PrrrpError::shape(
                "base parameters",
                "at least one identifiable parameter",
                "0 (the chain has no dynamics to identify)",
            ));
        }
        let p = self.num_params();
        if let Some(&bad) = base.independent.iter().find(|&&i| i >= p) {
            return Err(PrrrpError::shape(
                "base parameter index",
                format!("< {p} (standard parameters of this chain)"),
                format!("{bad}"),
            ));
        }
        let mut rigid_map = vec![[NONE; 10]; n];
        let mut actuator_map = vec![[NONE; 4]; n];
        let mut slots = vec![Slot::Rigid(0, 0); base.count()];
        fill_maps(
            base,
            n,
            &layout,
            &mut rigid_map,
            &mut actuator_map,
            &mut slots,
        );
        let beta = DVector::from_vec(base.base_values(&self.parameters())?);
        Ok(DynChainBaseModel {
            chain: self.clone(),
            rigid_map,
            actuator_map,
            slots,
            beta,
        })
    }
}

impl DynChainBaseModel {
    /// Number of joints N.
    pub fn dof(&self) -> usize {
        self.chain.dof()
    }

    /// Number of base parameters B.
    pub fn count(&self) -> usize {
        self.slots.len()
    }

    /// The base parameters β = K·π of the chain this model was built from (its true
    /// values, e.g. for simulation studies; units of the standard parameters: kg, kg·m,
    /// kg·m², N·s/m or N·m·s/rad, N or N·m).
    pub fn chain_base_values(&self) -> &DVector<f64> {
        &self.beta
    }

    /// The chain this model was built from.
    pub fn chain(&self) -> &DynChain {
        &self.chain
    }

    /// Mass matrix M(q, β) of the equivalent chain (kg, kg·m, kg·m² by joint kinds).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if q does not have N entries or β not B.
    pub fn mass_matrix(&self, q: &DVector<f64>, beta: &DVector<f64>) -> Result<DMatrix<f64>> {
        self.check_joint("q", q.len())?;
        self.check_beta(beta.len())?;
        let mut ws = self.workspace();
        self.equivalent(beta, &mut ws);
        let DynBaseWorkspace {
            st,
            comp,
            rig,
            fr,
            ia,
            ..
        } = &mut ws;
        let view = self.view_with(rig, fr, ia);
        let n = self.dof();
        let mut m = DMatrix::zeros(n, n);
        view.mass_matrix_with(rig, q.as_slice(), st, comp, m.as_mut_slice());
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
        if let Some(out) = out {
            let n = self.dof();
            self.check_matrix("out.dqdd_dq", &out.dqdd_dq, n)?;
            self.check_matrix("out.dqdd_dqd", &out.dqdd_dqd, n)?;
            self.check_matrix("out.dqdd_dlambda", &out.dqdd_dlambda, self.count())?;
        }
        Ok(())
    }

    fn check_ws(&self, ws: &DynBaseWorkspace) -> Result<()> {
        if ws.n != self.dof() {
            return Err(PrrrpError::shape(
                "workspace",
                format!("a workspace of this model ({} joints)", self.dof()),
                format!("{} joints", ws.n),
            ));
        }
        Ok(())
    }

    fn check_matrix(&self, what: &str, m: &DMatrix<f64>, cols: usize) -> Result<()> {
        let n = self.dof();
        if m.shape() != (n, cols) {
            return Err(PrrrpError::shape(
                what,
                format!("{n}×{cols}"),
                format!("{}×{}", m.nrows(), m.ncols()),
            ));
        }
        Ok(())
    }

    /// Standard parameters of the equivalent chain with base parameters β, into `ws`.
    #[inline]
    fn equivalent(&self, beta: &DVector<f64>, ws: &mut DynBaseWorkspace) {
        let slots = &self.slots;
        load_equivalent(slots, beta.as_slice(), &mut ws.rig, &mut ws.fr, &mut ws.ia);
    }

    #[inline]
    fn view_with<'a>(
        &'a self,
        rig: &'a [[f64; 10]],
        fr: &'a [[f64; 3]],
        ia: &'a [f64],
    ) -> ChainView<'a> {
        equivalent_view(self.chain.view(), rig, fr, ia)
    }

    /// q̈ = M⁻¹(τ − bias) at the β already loaded into `ws`; leaves the factor of M in
    /// `ws.m`.
    fn forward_loaded(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        let n = self.dof();
        let DynBaseWorkspace {
            st,
            comp,
            rig,
            fr,
            ia,
            m,
            zero,
            ..
        } = ws;
        let view = self.view_with(rig, fr, ia);
        view.mass_matrix_with(rig, q, st, comp, m);
        cholesky_in_place(m, n).map_err(|_| PrrrpError::NotPositiveDefinite {
            what: "mass matrix M(q, β) of the base-parameter model",
        })?;
        view.rnea(q, qd, zero, st, out);
        for (x, t) in out.iter_mut().zip(tau) {
            *x = t - *x;
        }
        cholesky_solve(m, n, out);
        Ok(())
    }

    /// ∂q̈/∂q, ∂q̈/∂q̇ and ∂q̈/∂β at the acceleration `qdd`, with β loaded and M factorised
    /// in `ws` (by [`Self::forward_loaded`]).
    #[allow(clippy::too_many_arguments)]
    fn derivatives_loaded(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        dqdd_dq: &mut DMatrix<f64>,
        dqdd_dqd: &mut DMatrix<f64>,
        dqdd_dlambda: &mut DMatrix<f64>,
        minv_out: Option<&mut DMatrix<f64>>,
    ) {
        let n = self.dof();
        let DynBaseWorkspace {
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
        let full = self.view_with(rig, fr, ia);
        let rigid = full.rigid();
        // The primal pass at q̈ leaves the kinematics and joint forces that the tangent
        // passes differentiate.
        rigid.rnea(q, qd, qdd, st, tmp);
        let dq = dqdd_dq.as_mut_slice();
        let dqd = dqdd_dqd.as_mut_slice();
        rigid.rnea_derivatives(rig, qd, st, tan, dq, dqd);
        full.add_actuator_slope(fr, qd, dqd);
        // Φ_b at q̈, from the primal pass's kinematics (the tangent passes leave them).
        dqdd_dlambda.fill(0.0);
        let maps = (&self.rigid_map[..], &self.actuator_map[..]);
        base_regressor_into(
            self.chain.view(),
            maps,
            [q, qd, qdd],
            st,
            dqdd_dlambda,
            true,
        );
        // −M⁻¹ times the 2N + B columns.
        inverse_from_factor(m, n, minv);
        minus_inverse_times(minv, n, dqdd_dq.as_mut_slice(), col);
        minus_inverse_times(minv, n, dqdd_dqd.as_mut_slice(), col);
        match minv_out {
            Some(out) => out.as_mut_slice().copy_from_slice(minv),
            None => minus_inverse_times(minv, n, dqdd_dlambda.as_mut_slice(), col),
        }
    }

    /// Loads β, then q̈ = M⁻¹·(τ − bias) into `out.qdd` and the derivatives at `qdd_lin`
    /// (at that q̈ if `None`) into the rest of `out`; the arguments are checked.
    #[allow(clippy::too_many_arguments)]
    fn forward_and_derivatives(
        &self,
        ws: &mut DynBaseWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        tau: &DVector<f64>,
        lambda: &DVector<f64>,
        qdd_lin: Option<&DVector<f64>>,
        minv: Option<&mut DMatrix<f64>>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        self.equivalent(lambda, ws);
        let (q, qd) = (q.as_slice(), qd.as_slice());
        self.forward_loaded(ws, q, qd, tau.as_slice(), out.qdd.as_mut_slice())?;
        let ForwardDerivativesOf {
            qdd,
            dqdd_dq,
            dqdd_dqd,
            dqdd_dlambda,
        } = out;
        let at = qdd_lin.map_or(qdd.as_slice(), |v| v.as_slice());
        self.derivatives_loaded(ws, q, qd, at, dqdd_dq, dqdd_dqd, dqdd_dlambda, minv);
        Ok(())
    }
}

impl LinearModel<Dyn, Dyn> for DynChainBaseModel {
    type Workspace = DynBaseWorkspace;

    fn dims(&self) -> (Dyn, Dyn) {
        (Dyn(self.dof()), Dyn(self.count()))
    }

    fn workspace(&self) -> DynBaseWorkspace {
        let n = self.dof();
        DynBaseWorkspace {
            n,
            st: vec![LinkState::default(); n],
            comp: vec![[0.0; 10]; n],
            rig: vec![[0.0; 10]; n],
            fr: vec![[0.0; 3]; n],
            ia: vec![0.0; n],
            m: vec![0.0; n * n],
            zero: vec![0.0; n],
            minv: vec![0.0; n * n],
            tmp: vec![0.0; n],
            col: vec![0.0; n],
            tan: vec![LinkTangent::default(); n],
        }
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
        let maps = (&self.rigid_map[..], &self.actuator_map[..]);
        base_regressor_into(self.chain.view(), maps, x, &mut ws.st, out, false);
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
        self.equivalent(lambda, ws);
        let DynBaseWorkspace {
            st, rig, fr, ia, ..
        } = ws;
        self.view_with(rig, fr, ia).rnea(
            q.as_slice(),
            qd.as_slice(),
            qdd.as_slice(),
            st,
            out.as_mut_slice(),
        );
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
        self.equivalent(lambda, ws);
        self.forward_loaded(
            ws,
            q.as_slice(),
            qd.as_slice(),
            tau.as_slice(),
            out.as_mut_slice(),
        )
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
        self.forward_and_derivatives(ws, q, qd, tau, lambda, None, None, out)
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
        self.forward_and_derivatives(ws, q, qd, tau, lambda, Some(qdd_lin), None, out)
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
        self.forward_and_derivatives(ws, q, qd, tau, lambda, qdd_lin, Some(minv), out)?;
        Ok(true)
    }
}
