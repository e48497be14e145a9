//! A chain seen through its base parameters: the [`LinearDynamics`] model the estimators
//! take, τ = Φ_b(q, q̇, q̈)·β.

use std::ops::IndexMut;

use nalgebra::{SMatrix, SVector};

use super::actuators::ActuatorLayout;
use super::base_params::BaseParameters;
use super::crba::{cholesky_in_place, cholesky_solve, inverse_from_factor, minus_inverse_times};
use super::derivatives::LinkTangent;
use super::regressor::RegressorSink;
use super::rnea::{ChainView, LinkState};
use super::serial_chain::SerialChain;
use crate::error::{PrrrpError, Result};
use crate::models::{ForwardDerivatives, LinearDynamics};

pub(super) const NONE: usize = usize::MAX;

/// Where a base parameter lives in the standard layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Slot {
    /// Inertial parameter k of link i.
    Rigid(usize, usize),
    /// Actuator term `kind` (0 viscous, 1 Coulomb, 2 offset, 3 armature) of actuator m.
    Actuator(usize, usize),
}

/// The dynamics of a [`SerialChain<N>`] parametrised by its `B` base parameters β
/// (from [`SerialChain::base_parameters`]), for the estimators: it implements
/// [`LinearDynamics<N, B>`], allocation-free.
///
/// The base regressor Φ_b holds the independent columns of the full regressor. The model
/// at any β is the chain whose independent standard parameters equal β and whose other
/// parameters are zero: since the dependent columns are combinations of the independent
/// ones, this chain has exactly the joint forces Φ_b·β, so inverse and forward dynamics
/// run the O(n) recursions instead of building Φ_b. Such an equivalent chain is
/// generally not physical, but its mass matrix is positive definite whenever β comes
/// from a physical robot (it equals that robot's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainBaseModel<const N: usize, const B: usize> {
    chain: SerialChain<N>,
    rigid_map: [[usize; 10]; N],
    actuator_map: [[usize; 4]; N],
    slots: [Slot; B],
    beta: SVector<f64, B>,
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

/// The base regressor Φ_b(q, q̇, q̈) (`x` = [q, q̇, q̈]) of `view`'s chain into `out` (N×B,
/// zero on entry), through the column maps `maps` = (rigid, actuator) of [`BaseSink`];
/// `kinematics_done`: `st` holds the kinematics at `x` already.
#[inline(always)]
pub(super) fn base_regressor_into<O: IndexMut<(usize, usize), Output = f64>>(
    view: ChainView<'_>,
    maps: (&[[usize; 10]], &[[usize; 4]]),
    x: [&[f64]; 3],
    st: &mut [LinkState],
    out: &mut O,
    kinematics_done: bool,
) {
    let (rigid_map, actuator_map) = maps;
    let mut sink = BaseSink {
        out,
        rigid_map,
        actuator_map,
    };
    if kinematics_done {
        view.regressor_at_kinematics(x[1], x[2], true, st, &mut sink);
    } else {
        view.regressor_into(x[0], x[1], x[2], true, st, &mut sink);
    }
}

/// The column maps of a base model: for base column c (standard parameter
/// `base.independent[c]` of a chain with `n` joints and actuator layout `layout`), its
/// slot in `slots[c]` and c in `rigid_map` / `actuator_map` (the other entries stay as
/// they are, [`NONE`]).
pub(super) fn fill_maps(
    base: &BaseParameters,
    n: usize,
    layout: &ActuatorLayout,
    rigid_map: &mut [[usize; 10]],
    actuator_map: &mut [[usize; 4]],
    slots: &mut [Slot],
) {
    for (c, &idx) in base.independent.iter().enumerate() {
        let slot = slot_of(idx, n, layout);
        match slot {
            Slot::Rigid(i, k) => rigid_map[i][k] = c,
            Slot::Actuator(j, kind) => actuator_map[j][kind] = c,
        }
        slots[c] = slot;
    }
}

/// Standard parameters of the equivalent chain with base parameters `beta` (base column c
/// in `slots[c]`): inertial `rig`, friction `fr` and armature `ia`, zero where no base
/// parameter lives.
#[inline(always)]
pub(super) fn load_equivalent(
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
pub(super) fn equivalent_view<'a>(
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

impl<const N: usize> SerialChain<N> {
    /// The base-parameter model of this chain for an analysis `base` with B base
    /// parameters (B is checked against `base.count()`).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if B ≠ `base.count()` or `base` was computed for a
    /// chain with another number of joints or friction model.
    pub fn base_model<const B: usize>(
        &self,
        base: &BaseParameters,
    ) -> Result<ChainBaseModel<N, B>> {
        let layout = self.layout();
        base.check_layout(N, &layout)?;
        if base.count() != B {
            return Err(PrrrpError::ShapeMismatch {
                what: "base parameter count B".into(),
                expected: format!("{} (from the analysis)", base.count()),
                got: format!("{B}"),
            });
        }
        let mut rigid_map = [[NONE; 10]; N];
        let mut actuator_map = [[NONE; 4]; N];
        let mut slots = [Slot::Rigid(0, 0); B];
        fill_maps(
            base,
            N,
            &layout,
            &mut rigid_map,
            &mut actuator_map,
            &mut slots,
        );
        let beta = SVector::from_vec(base.base_values(&self.parameters())?);
        Ok(ChainBaseModel {
            chain: *self,
            rigid_map,
            actuator_map,
            slots,
            beta,
        })
    }
}

impl<const N: usize, const B: usize> ChainBaseModel<N, B> {
    /// The base parameters β = K·π of the chain this model was built from (its true
    /// values, e.g. for simulation studies).
    pub fn chain_base_values(&self) -> SVector<f64, B> {
        self.beta
    }

    /// The chain this model was built from.
    pub fn chain(&self) -> &SerialChain<N> {
        &self.chain
    }

    /// Standard parameters of the equivalent chain with base parameters β: inertial,
    /// friction and armature.
    #[inline(always)]
    fn equivalent(&self, beta: &SVector<f64, B>) -> Equivalent<N> {
        let mut e = Equivalent {
            rig: [[0.0; 10]; N],
            fr: [[0.0; 3]; N],
            ia: [0.0; N],
        };
        load_equivalent(
            &self.slots,
            beta.as_slice(),
            &mut e.rig,
            &mut e.fr,
            &mut e.ia,
        );
        e
    }

    #[inline(always)]
    fn view_with<'a>(&'a self, e: &'a Equivalent<N>) -> ChainView<'a> {
        equivalent_view(self.chain.view(), &e.rig, &e.fr, &e.ia)
    }

    /// τ at β, by recursive Newton–Euler (rigid part only if `friction` is false).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn rnea_at(
        &self,
        view: &ChainView<'_>,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        friction: bool,
        st: &mut [LinkState; N],
    ) -> SVector<f64, N> {
        let mut v = *view;
        if !friction {
            v = v.rigid();
        }
        let mut tau = SVector::<f64, N>::zeros();
        v.rnea(
            q.as_slice(),
            qd.as_slice(),
            qdd.as_slice(),
            st,
            tau.as_mut_slice(),
        );
        tau
    }

    /// Cholesky factor of M(q, β) (column-major, lower).
    #[inline(always)]
    fn mass_factor(
        &self,
        view: &ChainView<'_>,
        q: &SVector<f64, N>,
        st: &mut [LinkState; N],
    ) -> Result<SMatrix<f64, N, N>> {
        let mut comp = [[0.0; 10]; N];
        let mut m = SMatrix::<f64, N, N>::zeros();
        view.mass_matrix_with(view.inertial, q.as_slice(), st, &mut comp, m.as_mut_slice());
        cholesky_in_place(m.as_mut_slice(), N)?;
        Ok(m)
    }

    /// Mass matrix M(q, β) of the equivalent chain.
    pub fn mass_matrix(&self, q: &SVector<f64, N>, beta: &SVector<f64, B>) -> SMatrix<f64, N, N> {
        let e = self.equivalent(beta);
        let view = self.view_with(&e);
        let mut st = [LinkState::default(); N];
        let mut comp = [[0.0; 10]; N];
        let mut m = SMatrix::<f64, N, N>::zeros();
        view.mass_matrix_with(&e.rig, q.as_slice(), &mut st, &mut comp, m.as_mut_slice());
        m
    }
}

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
        let maps = (&self.rigid_map[..], &self.actuator_map[..]);
        base_regressor_into(self.chain.view(), maps, x, &mut st, &mut out, false);
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
        let e = self.equivalent(lambda);
        let view = self.view_with(&e);
        let mut st = [LinkState::default(); N];
        self.rnea_at(&view, q, qd, qdd, true, &mut st)
    }

    #[inline]
    fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, B>,
    ) -> Result<SVector<f64, N>> {
        let e = self.equivalent(lambda);
        let view = self.view_with(&e);
        let mut st = [LinkState::default(); N];
        let l = self.mass_factor(&view, q, &mut st)?;
        let mut x = tau - self.rnea_at(&view, q, qd, &SVector::zeros(), true, &mut st);
        cholesky_solve(l.as_slice(), N, x.as_mut_slice());
        Ok(x)
    }

    /// ∂q̈/∂β = −M⁻¹·Φ_b(q, q̇, q̈); ∂q̈/∂q and ∂q̈/∂q̇ = −M⁻¹ times the exact
    /// derivatives of the rigid-body inverse dynamics at fixed q̈ (tangent-linear
    /// Newton–Euler, as [`super::DynChainBaseModel`]), plus the friction slope in closed
    /// form (the exact Coulomb sign contributes 0; use `coulomb_smoothing` > 0 for a
    /// smooth model).
    fn forward_derivatives(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, B>,
    ) -> Result<ForwardDerivatives<N, B>> {
        let e = self.equivalent(lambda);
        let view = self.view_with(&e);
        let mut st = [LinkState::default(); N];
        let l = self.mass_factor(&view, q, &mut st)?;
        let mut qdd = tau - self.rnea_at(&view, q, qd, &SVector::zeros(), true, &mut st);
        cholesky_solve(l.as_slice(), N, qdd.as_mut_slice());

        // The primal pass at q̈ leaves what the tangent passes differentiate.
        self.rnea_at(&view, q, qd, &qdd, false, &mut st);
        let mut dq = SMatrix::<f64, N, N>::zeros();
        let mut dqd = SMatrix::<f64, N, N>::zeros();
        let mut tan = [LinkTangent::default(); N];
        view.rnea_derivatives(
            &e.rig,
            qd.as_slice(),
            &st,
            &mut tan,
            dq.as_mut_slice(),
            dqd.as_mut_slice(),
        );
        view.add_actuator_slope(&e.fr, qd.as_slice(), dqd.as_mut_slice());
        let mut dl = self.regressor(q, qd, &qdd);
        let mut inv = SMatrix::<f64, N, N>::zeros();
        let mut tmp = SVector::<f64, N>::zeros();
        inverse_from_factor(l.as_slice(), N, inv.as_mut_slice());
        for m in [dq.as_mut_slice(), dqd.as_mut_slice(), dl.as_mut_slice()] {
            minus_inverse_times(inv.as_slice(), N, m, tmp.as_mut_slice());
        }
        Ok(ForwardDerivatives {
            qdd,
            dqdd_dq: dq,
            dqdd_dqd: dqd,
            dqdd_dlambda: dl,
        })
    }
}

/// Standard parameters of an equivalent chain (see [`ChainBaseModel`]).
#[derive(Debug, Clone, Copy)]
struct Equivalent<const N: usize> {
    rig: [[f64; 10]; N],
    fr: [[f64; 3]; N],
    ia: [f64; N],
}

/// Where standard parameter `idx` of a chain with `n` joints and actuator layout `l` lives.
pub(super) fn slot_of(idx: usize, n: usize, l: &ActuatorLayout) -> Slot {
    if idx < 10 * n {
        Slot::Rigid(idx / 10, idx % 10)
    } else {
        let per = l.per.max(1);
        let off = idx - 10 * n;
        let (m, s) = (off / per, off % per);
        Slot::Actuator(m, l.kind_of(s))
    }
}
