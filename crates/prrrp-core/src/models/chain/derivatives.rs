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

/// Tangents of one link's motion along one direction (frame i).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinkTangent {
    w: Vector3<f64>,
    wd: Vector3<f64>,
    a: Vector3<f64>,
}

impl Default for LinkTangent {
    fn default() -> Self {
        Self {
            w: Vector3::zeros(),
            wd: Vector3::zeros(),
            a: Vector3::zeros(),
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
        for k in 0..n {
            self.tangent(inertial, qd, st, k, false, tan, &mut dq[k * n..k * n + n]);
            self.tangent(inertial, qd, st, k, true, tan, &mut dqd[k * n..k * n + n]);
        }
    }

    /// ∂τ/∂q_k (`velocity` false) or ∂τ/∂q̇_k (true) into `out` (N entries).
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
            // Parent's motion seen in frame i (its tangent), and the joint's own rate
            // tangent δ(u·q̇_i).
            let (dw_pi, dwd_pi, da_rigid, dxr, w_pi) = if i == k {
                let w_pi = rt * w_p;
                if velocity {
                    (zero, zero, zero, u, w_pi)
                } else {
                    // δ(Rᵀx) = −s_ang × Rᵀx for a constant x; δp = R·s_lin.
                    let a_p = if i > 0 { st[i - 1].a } else { -self.gravity };
                    let p = s.p;
                    let a_rigid = rt * (a_p + wd_p.cross(&p) + w_p.cross(&w_p.cross(&p)));
                    let dp = s.r * g.s_lin;
                    let sa = g.s_ang;
                    (
                        -sa.cross(&w_pi),
                        -sa.cross(&(rt * wd_p)),
                        -sa.cross(&a_rigid) + rt * (wd_p.cross(&dp) + w_p.cross(&w_p.cross(&dp))),
                        zero,
                        w_pi,
                    )
                }
            } else {
                let t = &tan[i - 1];
                let p = s.p;
                (
                    rt * t.w,
                    rt * t.wd,
                    rt * (t.a
                        + t.wd.cross(&p)
                        + t.w.cross(&w_p.cross(&p))
                        + w_p.cross(&t.w.cross(&p))),
                    zero,
                    // Only multiplies dxr = 0 below.
                    zero,
                )
            };
            let tn = if g.revolute {
                let v_rel = xr.cross(&g.rho);
                let dv_rel = dxr.cross(&g.rho);
                LinkTangent {
                    w: dw_pi + dxr,
                    wd: dwd_pi + dw_pi.cross(&xr) + w_pi.cross(&dxr),
                    a: da_rigid
                        + dxr.cross(&v_rel)
                        + xr.cross(&dv_rel)
                        + 2.0 * (dw_pi.cross(&v_rel) + w_pi.cross(&dv_rel)),
                }
            } else {
                LinkTangent {
                    w: dw_pi,
                    wd: dwd_pi,
                    a: da_rigid + 2.0 * (dw_pi.cross(&xr) + w_pi.cross(&dxr)),
                }
            };
            tan[i] = tn;
        }
        // Backward pass: forces of the moving links, then their transmission down to the
        // base (a link below k only passes its child's force tangent on).
        let mut df_c = zero;
        let mut dn_c = zero;
        for i in (0..n).rev() {
            let (mut df, mut dn) = if i >= k {
                let s = &st[i];
                let t = &tan[i];
                let pi = &inertial[i];
                let h = first_moment(pi);
                (
                    t.a * pi[0]
                        + t.wd.cross(&h)
                        + t.w.cross(&s.w.cross(&h))
                        + s.w.cross(&t.w.cross(&h)),
                    inertia_times(pi, &t.wd)
                        + t.w.cross(&inertia_times(pi, &s.w))
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
                if !velocity && i + 1 == k {
                    // The child's frame turns (δR = R·[s_ang]×) and moves (δp = R·s_lin).
                    let gc = &self.geom[k];
                    dfr += c.r * gc.s_ang.cross(&c.f);
                    dnr += c.r * gc.s_ang.cross(&c.nm);
                    dn += (c.r * gc.s_lin).cross(&(c.r * c.f));
                }
                df += dfr;
                dn += dnr + c.p.cross(&dfr);
            }
            let g = &self.geom[i];
            out[i] = g.s_ang.dot(&dn) + g.s_lin.dot(&df);
            df_c = df;
            dn_c = dn;
        }
    }
}
