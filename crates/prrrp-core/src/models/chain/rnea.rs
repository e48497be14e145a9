//! Recursive Newton–Euler inverse dynamics of a serial chain (Luh, Walker & Paul 1980),
//! written once over slices so that the fixed-size and the run-time-size chains share it.
//!
//! Every quantity of link i is expressed in frame i; moments are about the origin of frame
//! i. Gravity enters as an upward acceleration of the base (a₀ = −g).

use nalgebra::{Matrix3, Vector3};

use super::friction::FrictionModel;
use super::inertia::{first_moment, inertia_times};
use super::joint::JointGeom;
use super::paper::PaperClosedForm;

/// A borrowed view of a chain: what every algorithm needs, whatever the storage.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ChainView<'a> {
    pub(crate) geom: &'a [JointGeom],
    pub(crate) inertial: &'a [[f64; 10]],
    pub(crate) friction_params: &'a [[f64; 3]],
    pub(crate) friction: FrictionModel,
    pub(crate) gravity: Vector3<f64>,
    /// The actuator coupling C (row-major n×n, q̇ₘ = C·q̇; see [`super::Actuators`]);
    /// `None` = the identity.
    pub(crate) coupling: Option<&'a [f64]>,
    /// Reflected rotor inertias Ia (one per actuator) when the armature term is on.
    pub(crate) armature: Option<&'a [f64]>,
    /// The closed form of the paper's arm, when the chain is that arm: Newton–Euler, the
    /// mass matrix and the regressor then dispatch to it (see `super::paper`).
    pub(crate) closed: Option<&'static PaperClosedForm>,
}

/// Per-link kinematic state of one sample, in frame i.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinkState {
    /// ⁱ⁻¹Rᵢ.
    pub(crate) r: Matrix3<f64>,
    /// Origin of frame i in frame i−1 (m).
    pub(crate) p: Vector3<f64>,
    /// Angular velocity ωᵢ (rad/s).
    pub(crate) w: Vector3<f64>,
    /// Angular acceleration ω̇ᵢ (rad/s²).
    pub(crate) wd: Vector3<f64>,
    /// Classical linear acceleration of the origin of frame i, gravity included (m/s²).
    pub(crate) a: Vector3<f64>,
    /// Regressor scratch: the motion subspace of joint i re-expressed in a later frame.
    pub(crate) s_ang: Vector3<f64>,
    /// Linear part of `s_ang`'s motion vector.
    pub(crate) s_lin: Vector3<f64>,
    /// Force that link i−1 exerts on link i, in frame i (N), left by the backward pass of
    /// [`ChainView::rnea_with`] for the derivative kernels.
    pub(crate) f: Vector3<f64>,
    /// Moment about the origin of frame i that goes with `f` (N·m).
    pub(crate) nm: Vector3<f64>,
}

impl Default for LinkState {
    fn default() -> Self {
        Self {
            r: Matrix3::identity(),
            p: Vector3::zeros(),
            w: Vector3::zeros(),
            wd: Vector3::zeros(),
            a: Vector3::zeros(),
            s_ang: Vector3::zeros(),
            s_lin: Vector3::zeros(),
            f: Vector3::zeros(),
            nm: Vector3::zeros(),
        }
    }
}

impl ChainView<'_> {
    #[inline(always)]
    pub(crate) fn dof(&self) -> usize {
        self.geom.len()
    }

    /// Link placements ⁱ⁻¹Tᵢ(q) only.
    #[inline]
    pub(crate) fn placements(&self, q: &[f64], st: &mut [LinkState]) {
        for ((g, s), &qi) in self.geom.iter().zip(st.iter_mut()).zip(q) {
            let (r, p) = g.transform(qi);
            s.r = r;
            s.p = p;
        }
    }

    /// Forward pass: velocities and accelerations of every link. `gravity` false gives the
    /// accelerations without the fictitious base acceleration.
    #[inline]
    pub(crate) fn kinematics(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        gravity: bool,
        st: &mut [LinkState],
    ) {
        let mut w_p = Vector3::zeros();
        let mut wd_p = Vector3::zeros();
        let mut a_p = if gravity {
            -self.gravity
        } else {
            Vector3::zeros()
        };
        for (i, (g, s)) in self.geom.iter().zip(st.iter_mut()).enumerate() {
            let (r, p) = g.transform(q[i]);
            let rt = r.transpose();
            // Acceleration of the point of link i−1 that coincides with the origin of frame i.
            let a_rigid = rt * (a_p + wd_p.cross(&p) + w_p.cross(&w_p.cross(&p)));
            let w_pi = rt * w_p;
            let wd_pi = rt * wd_p;
            let u = g.axis;
            let (w, wd, a) = if g.revolute {
                let wr = u * qd[i];
                let v_rel = wr.cross(&g.rho);
                (
                    w_pi + wr,
                    wd_pi + u * qdd[i] + w_pi.cross(&wr),
                    a_rigid
                        + (u * qdd[i]).cross(&g.rho)
                        + wr.cross(&v_rel)
                        + 2.0 * w_pi.cross(&v_rel),
                )
            } else {
                (
                    w_pi,
                    wd_pi,
                    a_rigid + u * qdd[i] + 2.0 * w_pi.cross(&(u * qd[i])),
                )
            };
            s.r = r;
            s.p = p;
            s.w = w;
            s.wd = wd;
            s.a = a;
            w_p = w;
            wd_p = wd;
            a_p = a;
        }
    }

    /// Inverse dynamics τ = M·q̈ + C·q̇ + G (+ friction if `friction`) with the inertial
    /// parameters `inertial` (one 10-vector per link) and friction parameters `fric`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn rnea_with(
        &self,
        inertial: &[[f64; 10]],
        fric: &[[f64; 3]],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        gravity: bool,
        st: &mut [LinkState],
        tau: &mut [f64],
    ) {
        if let Some(cf) = self.closed {
            tau[..5].copy_from_slice(cf.rnea(inertial, q, qd, qdd, gravity).as_slice());
            return self.add_actuator_torques(fric, qd, qdd, tau);
        }
        self.kinematics(q, qd, qdd, gravity, st);
        let n = self.dof();
        let mut f_c = Vector3::zeros();
        let mut n_c = Vector3::zeros();
        for i in (0..n).rev() {
            let s = &st[i];
            let pi = &inertial[i];
            let h = first_moment(pi);
            let mut f = s.a * pi[0] + s.wd.cross(&h) + s.w.cross(&s.w.cross(&h));
            let mut nm =
                inertia_times(pi, &s.wd) + s.w.cross(&inertia_times(pi, &s.w)) + h.cross(&s.a);
            if i + 1 < n {
                let c = &st[i + 1];
                let fr = c.r * f_c;
                f += fr;
                nm += c.r * n_c + c.p.cross(&fr);
            }
            let g = &self.geom[i];
            tau[i] = g.s_ang.dot(&nm) + g.s_lin.dot(&f);
            st[i].f = f;
            st[i].nm = nm;
            f_c = f;
            n_c = nm;
        }
        self.add_actuator_torques(fric, qd, qdd, tau);
    }

    /// Where the actuator parameters sit in the standard parameter vector.
    #[inline(always)]
    pub(crate) fn layout(&self) -> super::actuators::ActuatorLayout {
        super::actuators::ActuatorLayout::new(&self.friction, self.armature.is_some())
    }

    /// The view without actuator terms (no friction, no armature): the rigid body alone.
    #[inline(always)]
    pub(crate) fn rigid(mut self) -> Self {
        self.friction = FrictionModel::default();
        self.armature = None;
        self
    }

    /// The view evaluated by the recursive algorithms even for the paper's arm: for the
    /// kernels that read the link states a Newton–Euler pass leaves (the derivatives).
    #[inline(always)]
    pub(crate) fn recursive(mut self) -> Self {
        self.closed = None;
        self
    }

    /// Actuator m's joint-side rate (C·v)ₘ of a joint-space rate v (velocity or
    /// acceleration).
    #[inline(always)]
    pub(crate) fn actuator_rate(&self, m: usize, v: &[f64]) -> f64 {
        match self.coupling {
            None => v[m],
            Some(c) => {
                let n = self.dof();
                c[m * n..m * n + n].iter().zip(v).map(|(a, b)| a * b).sum()
            }
        }
    }

    /// Adds the actuator torques reflected to the joints, Cᵀ·(diag(Ia)·C·q̈ + f(C·q̇)),
    /// with friction parameters `fric` (one row per actuator) and the view's armature.
    #[inline]
    pub(crate) fn add_actuator_torques(
        &self,
        fric: &[[f64; 3]],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) {
        let friction = self.friction.columns_per_joint() > 0;
        if !friction && self.armature.is_none() {
            return;
        }
        let n = self.dof();
        for m in 0..n {
            let mut t = 0.0;
            if friction {
                t += self.friction.torque(self.actuator_rate(m, qd), &fric[m]);
            }
            if let Some(ia) = self.armature {
                t += ia[m] * self.actuator_rate(m, qdd);
            }
            match self.coupling {
                None => tau[m] += t,
                Some(c) => {
                    for (tj, &cj) in tau[..n].iter_mut().zip(&c[m * n..m * n + n]) {
                        *tj += cj * t;
                    }
                }
            }
        }
    }

    /// Adds ∂/∂q̇ of the actuator friction, Cᵀ·diag(f'(C·q̇))·C, to the column-major n×n
    /// `dqd` (the exact Coulomb sign contributes 0).
    #[inline]
    pub(crate) fn add_actuator_slope(&self, fric: &[[f64; 3]], qd: &[f64], dqd: &mut [f64]) {
        if self.friction.columns_per_joint() == 0 {
            return;
        }
        let n = self.dof();
        for m in 0..n {
            let s = friction_slope(&self.friction, self.actuator_rate(m, qd), &fric[m]);
            if s == 0.0 {
                continue;
            }
            match self.coupling {
                None => dqd[m * n + m] += s,
                Some(c) => {
                    let row = &c[m * n..m * n + n];
                    for (k, &ck) in row.iter().enumerate() {
                        if ck != 0.0 {
                            for (j, &cj) in row.iter().enumerate() {
                                dqd[k * n + j] += cj * s * ck;
                            }
                        }
                    }
                }
            }
        }
    }

    /// Adds Cᵀ·diag(Ia)·C to the column-major n×n mass matrix `m` when the armature term
    /// is on.
    #[inline]
    pub(crate) fn add_armature_inertia(&self, m: &mut [f64]) {
        let Some(ia) = self.armature else {
            return;
        };
        let n = self.dof();
        match self.coupling {
            None => {
                for (i, &a) in ia.iter().enumerate().take(n) {
                    m[i + n * i] += a;
                }
            }
            Some(c) => {
                for (k, &a) in ia.iter().enumerate().take(n) {
                    let row = &c[k * n..k * n + n];
                    for (i, &ci) in row.iter().enumerate() {
                        if ci != 0.0 {
                            for (j, &cj) in row.iter().enumerate() {
                                m[i + n * j] += ci * a * cj;
                            }
                        }
                    }
                }
            }
        }
    }

    /// Inverse dynamics with the chain's own parameters, gravity and friction included.
    #[inline]
    pub(crate) fn rnea(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        st: &mut [LinkState],
        tau: &mut [f64],
    ) {
        self.rnea_with(
            self.inertial,
            self.friction_params,
            q,
            qd,
            qdd,
            true,
            st,
            tau,
        );
    }
}

/// ∂f/∂v of one actuator's friction at rate v with parameters [fv, fc, fo].
#[inline(always)]
pub(crate) fn friction_slope(f: &FrictionModel, v: f64, p: &[f64; 3]) -> f64 {
    let mut s = 0.0;
    if f.viscous {
        s += p[0];
    }
    if f.coulomb && f.coulomb_smoothing > 0.0 {
        let t = (v / f.coulomb_smoothing).tanh();
        s += p[1] * (1.0 - t * t) / f.coulomb_smoothing;
    }
    s
}
