//! Exact first derivatives of the recursive Newton–Euler inverse dynamics with respect to
//! q and q̇ at fixed q̈: ∂τ/∂q and ∂τ/∂q̇ (rigid body only; the actuator friction slope
//! is added by the caller in closed form, and the armature does not depend on q or q̇).
//!
//! Tangent-linear (forward-mode) differentiation of the recursion of [`super::rnea`], one
//! direction per joint coordinate and rate, reusing the primal kinematics and joint forces
//! that [`ChainView::rnea_with`] leaves in its [`LinkState`]s: no trigonometry, no
//! perturbation step. Moving q_k (or q̇_k) leaves links 0..k unchanged, so the forward
//! tangent pass starts at link k and the backward one only carries the child's force
//! below it. O(N²) in all, about the cost of N/2 inverse dynamics for the 2N directions
//! (central differences took 4N).
//!
//! The derivative of a joint transform: ⁱ⁻¹Rᵢ(q) = R₀·Rot(u, q) gives
//! ∂R/∂q = R·[s_ang]× and ∂p/∂q = R·s_lin, with S = (s_ang, s_lin) the joint's motion
//! subspace in frame i (u and u × ρ for a revolute joint, 0 and u for a prismatic one).

use nalgebra::Vector3;

use super::inertia::{first_moment, inertia_times};
use super::rnea::{ChainView, LinkState};

/// Tangents of one link's motion along one direction (frame i), and the terms of the
/// link's primal state that every direction reads (set once per call of
/// [`ChainView::rnea_derivatives`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinkTangent {
    w: Vector3<f64>,
    wd: Vector3<f64>,
    a: Vector3<f64>,
    /// ω_{i−1} × p_i (zero for the first link).
    wxp: Vector3<f64>,
    /// (u·q̇_i) × ρ_i (revolute joints).
    v_rel: Vector3<f64>,
    /// ω_i × h_i and I_i·ω_i.
    wh: Vector3<f64>,
    iw: Vector3<f64>,
}

impl Default for LinkTangent {
    fn default() -> Self {
        let z = Vector3::zeros();
        Self {
            w: z,
            wd: z,
            a: z,
            wxp: z,
            v_rel: z,
            wh: z,
            iw: z,
        }
    }
}

impl ChainView<'_> {
    /// ∂τ/∂q (`dq`) and ∂τ/∂q̇ (`dqd`), column-major N×N (column k: derivative with
    /// respect to q_k or q̇_k), of the rigid-body inverse dynamics with the inertial
    /// parameters `inertial`, at the (q, q̇, q̈) of the last [`ChainView::rnea_with`] call
    /// on `st` (with gravity; the friction terms of that call are not differentiated).
    /// `tan` is scratch of length N.
    pub(crate) fn rnea_derivatives(
        &self,
        inertial: &[[f64; 10]],
        qd: &[f64],
        st: &[LinkState],
        tan: &mut [LinkTangent],
        dq: &mut [f64],
        dqd: &mut [f64],
    ) {
        let n = self.dof();
        // The primal terms the 2N directions share, formed once.
        for i in 0..n {
            let (g, s, pi) = (&self.geom[i], &st[i], &inertial[i]);
            let w_p = if i > 0 { st[i - 1].w } else { Vector3::zeros() };
            let t = &mut tan[i];
            t.wxp = w_p.cross(&s.p);
            t.v_rel = (g.axis * qd[i]).cross(&g.rho);
            t.wh = s.w.cross(&first_moment(pi));
            t.iw = inertia_times(pi, &s.w);
        }
        for k in 0..n {
            self.tangent(inertial, qd, st, k, false, tan, &mut dq[k * n..k * n + n]);
            self.tangent(inertial, qd, st, k, true, tan, &mut dqd[k * n..k * n + n]);
        }
    }

    /// ∂τ/∂q_k (`velocity` false) or ∂τ/∂q̇_k (true) into `out` (N entries). The terms
    /// the tangent-linear recursion multiplies by an exact zero (a link above k does not
    /// feel q_k's rate, the joint's own rate tangent vanishes for q_k, …) are left out:
    /// adding them added zeros, so the sums are the same.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn tangent(
        &self,
        inertial: &[[f64; 10]],
        qd: &[f64],
        st: &[LinkState],
        k: usize,
        velocity: bool,
        tan: &mut [LinkTangent],
        out: &mut [f64],
    ) {
        let n = self.dof();
        let zero = Vector3::zeros();
        // Forward pass over the links that move: k..n.
        for i in k..n {
            let g = &self.geom[i];
            let s = &st[i];
            let rt = s.r.transpose();
            let (w_p, wd_p) = if i > 0 {
                (st[i - 1].w, st[i - 1].wd)
            } else {
                (zero, zero)
            };
            let u = g.axis;
            let xr = u * qd[i];
            let v_rel = tan[i].v_rel;
            let (w, wd, a) = if i == k && velocity {
                // The joint's own rate tangent δ(u·q̇_i) = u; the parent does not move.
                let w_pi = rt * w_p;
                if g.revolute {
                    let dv_rel = u.cross(&g.rho);
                    let a = u.cross(&v_rel) + xr.cross(&dv_rel) + 2.0 * w_pi.cross(&dv_rel);
                    (u, w_pi.cross(&u), a)
                } else {
                    (zero, zero, 2.0 * w_pi.cross(&u))
                }
            } else {
                // Parent's motion seen in frame i (its tangent).
                let (dw_pi, dwd_pi, da_rigid) = if i == k {
                    // δ(Rᵀx) = −s_ang × Rᵀx for a constant x; δp = R·s_lin.
                    let w_pi = rt * w_p;
                    let a_p = if i > 0 { st[i - 1].a } else { -self.gravity };
                    let p = s.p;
                    let a_rigid = rt * (a_p + wd_p.cross(&p) + w_p.cross(&w_p.cross(&p)));
                    let dp = s.r * g.s_lin;
                    let sa = g.s_ang;
                    (
                        -sa.cross(&w_pi),
                        -sa.cross(&(rt * wd_p)),
                        -sa.cross(&a_rigid) + rt * (wd_p.cross(&dp) + w_p.cross(&w_p.cross(&dp))),
                    )
                } else {
                    let t = &tan[i - 1];
                    let p = s.p;
                    (
                        rt * t.w,
                        rt * t.wd,
                        rt * (t.a
                            + t.wd.cross(&p)
                            + t.w.cross(&tan[i].wxp)
                            + w_p.cross(&t.w.cross(&p))),
                    )
                };
                if g.revolute {
                    let a = da_rigid + 2.0 * dw_pi.cross(&v_rel);
                    (dw_pi, dwd_pi + dw_pi.cross(&xr), a)
                } else {
                    (dw_pi, dwd_pi, da_rigid + 2.0 * dw_pi.cross(&xr))
                }
            };
            let t = &mut tan[i];
            t.w = w;
            t.wd = wd;
            t.a = a;
        }
        // Backward pass: forces of the moving links, then their transmission down to the
        // base (a link below k only passes its child's force tangent on).
        let mut df_c = zero;
        let mut dn_c = zero;
        for i in (0..n).rev() {
            let moving = i >= k;
            let (mut df, mut dn) = if moving {
                let s = &st[i];
                let t = &tan[i];
                let pi = &inertial[i];
                let h = first_moment(pi);
                (
                    t.a * pi[0] + t.wd.cross(&h) + t.w.cross(&t.wh) + s.w.cross(&t.w.cross(&h)),
                    inertia_times(pi, &t.wd)
                        + t.w.cross(&t.iw)
                        + s.w.cross(&inertia_times(pi, &t.w))
                        + h.cross(&t.a),
                )
            } else {
                (zero, zero)
            };
            if i + 1 < n {
                let c = &st[i + 1];
                let mut dfr = c.r * df_c;
                let mut dnr = c.r * dn_c;
                let turns = !velocity && i + 1 == k;
                if turns {
                    // The child's frame turns (δR = R·[s_ang]×) and moves (δp = R·s_lin).
                    let gc = &self.geom[k];
                    dfr += c.r * gc.s_ang.cross(&c.f);
                    dnr += c.r * gc.s_ang.cross(&c.nm);
                    let x = (c.r * gc.s_lin).cross(&(c.r * c.f));
                    dn = if moving { dn + x } else { x };
                }
                let dnt = dnr + c.p.cross(&dfr);
                if moving {
                    df += dfr;
                    dn += dnt;
                } else {
                    df = dfr;
                    dn = if turns { dn + dnt } else { dnt };
                }
            }
            let g = &self.geom[i];
            out[i] = g.s_ang.dot(&dn) + g.s_lin.dot(&df);
            df_c = df;
            dn_c = dn;
        }
    }
}
