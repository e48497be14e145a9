//! Allocation-free per-sample algorithms of a run-time-size chain: a [`DynWorkspace`]
//! sized once for a [`DynChain`] (as Pinocchio's `Data` for its `Model`), and `*_into`
//! methods that write into caller-owned slices. This is what batched callers (the Python
//! bindings, loops over recorded data) use: one workspace per batch, no allocation per
//! sample.

use super::actuators::ActuatorLayout;
use super::base_params::BaseParameters;
use super::crba::{cholesky_in_place, cholesky_solve};
use super::regressor::RegressorSink;
use super::rnea::LinkState;
use super::serial_chain::DynChain;
use crate::error::{check_len, check_lens, PrrrpError, Result};

/// Scratch memory of the per-sample algorithms of one [`DynChain`], from
/// [`DynChain::workspace`]. Its size depends only on the number of joints and the number
/// of parameters; a workspace made for another chain layout is refused with
/// [`PrrrpError::ShapeMismatch`].
#[derive(Debug, Clone)]
pub struct DynWorkspace {
    n: usize,
    p: usize,
    st: Vec<LinkState>,
    comp: Vec<[f64; 10]>,
    /// n×n mass matrix / Cholesky factor (column-major).
    m: Vec<f64>,
    /// n zeros (q̇ = 0 or q̈ = 0 inputs).
    zero: Vec<f64>,
    /// Full regressor of one sample, row-major n × p.
    y: Vec<f64>,
}

/// Sink into a row-major n × p slice (numpy's order).
struct RowMajorSink<'a> {
    data: &'a mut [f64],
    p: usize,
    n: usize,
    layout: ActuatorLayout,
}

impl RegressorSink for RowMajorSink<'_> {
    #[inline(always)]
    fn rigid(&mut self, row: usize, link: usize, k: usize, v: f64) {
        self.data[row * self.p + 10 * link + k] = v;
    }
    #[inline(always)]
    fn actuator(&mut self, row: usize, act: usize, kind: usize, v: f64) {
        let col = 10 * self.n + self.layout.per * act + self.layout.slots[kind];
        self.data[row * self.p + col] = v;
    }
}

fn check(what: &str, len: usize, want: usize, unit: &str) -> Result<()> {
    check_len(what, len, want, unit, "")
}

impl DynChain {
    /// A workspace for the `*_into` methods of this chain (allocates O(n·p) once).
    pub fn workspace(&self) -> DynWorkspace {
        let n = self.dof();
        let p = self.num_params();
        DynWorkspace {
            n,
            p,
            st: vec![LinkState::default(); n],
            comp: vec![[0.0; 10]; n],
            m: vec![0.0; n * n],
            zero: vec![0.0; n],
            y: vec![0.0; n * p],
        }
    }

    fn check_ws(&self, ws: &DynWorkspace) -> Result<()> {
        if ws.n != self.dof() || ws.p != self.num_params() {
            return Err(PrrrpError::ShapeMismatch {
                what: "workspace".into(),
                expected: format!(
                    "a workspace of this chain ({} joints, {} parameters)",
                    self.dof(),
                    self.num_params()
                ),
                got: format!("{} joints, {} parameters", ws.n, ws.p),
            });
        }
        Ok(())
    }

    fn check_joint(&self, pairs: &[(&str, usize)]) -> Result<()> {
        check_lens(pairs, self.dof(), "entries (one per joint)", "")
    }

    /// Inverse dynamics τ (N, N·m; friction included) into `tau` (n entries).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a slice that does not have n entries or a
    /// workspace of another chain.
    pub fn inverse_dynamics_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<()> {
        self.check_ws(ws)?;
        self.check_joint(&[
            ("q", q.len()),
            ("qd", qd.len()),
            ("qdd", qdd.len()),
            ("tau", tau.len()),
        ])?;
        self.view().rnea(q, qd, qdd, &mut ws.st, tau);
        Ok(())
    }

    /// Nonlinear effects C(q, q̇)·q̇ + G(q) + τ_friction(q̇) (N, N·m): the torque at q̈ = 0,
    /// into `out` (n entries).
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics_into`].
    pub fn nonlinear_effects_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        self.check_ws(ws)?;
        self.check_joint(&[("q", q.len()), ("qd", qd.len()), ("out", out.len())])?;
        self.view().rnea(q, qd, &ws.zero, &mut ws.st, out);
        Ok(())
    }

    /// Gravity torques G(q) (N, N·m; no friction) into `out` (n entries).
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics_into`].
    pub fn gravity_torques_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        self.check_ws(ws)?;
        self.check_joint(&[("q", q.len()), ("out", out.len())])?;
        let view = self.view().rigid();
        view.rnea(q, &ws.zero, &ws.zero, &mut ws.st, out);
        Ok(())
    }

    /// Mass matrix M(q) (kg, kg·m, kg·m² by joint kinds) into `out` (n·n entries; M is
    /// symmetric, so row- and column-major agree).
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics_into`].
    pub fn mass_matrix_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        self.check_ws(ws)?;
        self.check_joint(&[("q", q.len())])?;
        let n = self.dof();
        check("mass matrix output", out.len(), n * n, "entries (n·n)")?;
        self.view()
            .mass_matrix_with(self.inertial(), q, &mut ws.st, &mut ws.comp, out);
        Ok(())
    }

    /// Forward dynamics q̈ = M⁻¹·(τ − C·q̇ − G − τ_friction) (m/s², rad/s²) into `qdd`
    /// (n entries), by a Cholesky factorisation of M(q).
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics_into`], [`PrrrpError::InvalidParameter`] naming the
    /// link for a non-physical link ([`DynChain::require_physical`]), and
    /// [`PrrrpError::NotPositiveDefinite`] if M(q) is singular (e.g. massless distal links).
    pub fn forward_dynamics_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        tau: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        self.require_physical()?;
        self.check_ws(ws)?;
        self.check_joint(&[
            ("q", q.len()),
            ("qd", qd.len()),
            ("tau", tau.len()),
            ("qdd", qdd.len()),
        ])?;
        let n = self.dof();
        let view = self.view();
        view.mass_matrix_with(self.inertial(), q, &mut ws.st, &mut ws.comp, &mut ws.m);
        cholesky_in_place(&mut ws.m, n)?;
        view.rnea(q, qd, &ws.zero, &mut ws.st, qdd);
        for (x, t) in qdd.iter_mut().zip(tau) {
            *x = t - *x;
        }
        cholesky_solve(&ws.m, n, qdd);
        Ok(())
    }

    /// The full regressor (friction columns included) of one sample, **row-major**
    /// n × [`DynChain::num_params`] (numpy's order), into `out`: τ = Y·π with
    /// π = [`DynChain::parameters`].
    ///
    /// # Errors
    /// As [`DynChain::inverse_dynamics_into`].
    pub fn regressor_row_major_into(
        &self,
        ws: &mut DynWorkspace,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        self.check_ws(ws)?;
        self.check_joint(&[("q", q.len()), ("qd", qd.len()), ("qdd", qdd.len())])?;
        let (n, p) = (self.dof(), self.num_params());
        check(
            "regressor output",
            out.len(),
            n * p,
            "entries (n·num_params)",
        )?;
        out.fill(0.0);
        let mut sink = RowMajorSink {
            data: out,
            p,
            n,
            layout: self.layout(),
        };
        self.view()
            .regressor_into(q, qd, qdd, true, &mut ws.st, &mut sink);
        Ok(())
    }

    /// The base regressor of one sample, row-major n × b (b = `base.count()`), into
    /// `out`: the columns `base.independent` of the full regressor, so that τ = Y_b·β with
    /// β = `base.base_values(π)`.
    ///
    /// # Errors
    /// As [`DynChain::regressor_row_major_into`], and [`PrrrpError::ShapeMismatch`] if
    /// `base` was computed for another chain layout.
    pub fn base_regressor_row_major_into(
        &self,
        ws: &mut DynWorkspace,
        base: &BaseParameters,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        out: &mut [f64],
    ) -> Result<()> {
        base.check_layout(self.dof(), &self.layout())?;
        let (n, p, b) = (self.dof(), self.num_params(), base.count());
        check(
            "base regressor output",
            out.len(),
            n * b,
            "entries (n·count)",
        )?;
        let mut y = std::mem::take(&mut ws.y);
        let r = self.regressor_row_major_into(ws, q, qd, qdd, &mut y);
        if r.is_ok() {
            for i in 0..n {
                for (c, &j) in base.independent.iter().enumerate() {
                    out[i * b + c] = y[i * p + j];
                }
            }
        }
        ws.y = y;
        r
    }

    /// Nonlinear effects C(q, q̇)·q̇ + G(q) + τ_friction(q̇) (allocating; see
    /// [`DynChain::nonlinear_effects_into`]).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if an input does not have n entries.
    pub fn nonlinear_effects(&self, q: &[f64], qd: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.dof()];
        self.nonlinear_effects_into(&mut self.workspace(), q, qd, &mut out)?;
        Ok(out)
    }

    /// Gravity torques G(q) (allocating; see [`DynChain::gravity_torques_into`]).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `q` does not have n entries.
    pub fn gravity_torques(&self, q: &[f64]) -> Result<Vec<f64>> {
        let mut out = vec![0.0; self.dof()];
        self.gravity_torques_into(&mut self.workspace(), q, &mut out)?;
        Ok(out)
    }
}
