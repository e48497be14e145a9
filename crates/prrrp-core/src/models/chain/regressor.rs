//! The standard regressor Y(q, q̇, q̈) ∈ R^{n×10n} with τ = Y·π (Khalil & Dombre 2002,
//! Atkeson, An & Hollerbach 1986), plus the actuator columns (friction and armature, see
//! [`super::Actuators`]).
//!
//! Link i's wrench about its frame origin is linear in its own 10 parameters,
//! w_i = A(ωᵢ, ω̇ᵢ, aᵢ)·πᵢ (a 6×10 matrix); joint j ≤ i feels it through the chain of
//! frame changes from i down to j. Y is block upper triangular: column block i is zero
//! in the rows of joints after i.

use std::ops::IndexMut;

use nalgebra::{Const, Dyn, MatrixViewMut, Vector3};

use super::actuators::ActuatorLayout;
use super::rnea::{ChainView, LinkState};

/// Receives the entries of a regressor as they are computed. Entries never reported are
/// zero; the caller zeroes the storage first.
pub(crate) trait RegressorSink {
    /// Entry of joint row `row` for parameter `k` (0..10) of link `link`.
    fn rigid(&mut self, row: usize, link: usize, k: usize, v: f64);
    /// Entry of joint row `row` for term `kind` (0 viscous, 1 Coulomb, 2 offset, 3
    /// armature) of actuator `act`; reported only for enabled terms.
    fn actuator(&mut self, row: usize, act: usize, kind: usize, v: f64);
}

/// Sink into a matrix in the chain's parameter order (10 columns per link, then the
/// enabled actuator terms), writing rows `row0 + joint`. `O` is any storage indexed by
/// (row, column): an nalgebra matrix or view (column- or row-major), or a faer matrix
/// that stacks samples.
pub(crate) struct StandardSink<'a, O> {
    pub(crate) out: &'a mut O,
    pub(crate) row0: usize,
    pub(crate) n: usize,
    pub(crate) layout: ActuatorLayout,
}

impl<O: IndexMut<(usize, usize), Output = f64>> RegressorSink for StandardSink<'_, O> {
    #[inline(always)]
    fn rigid(&mut self, row: usize, link: usize, k: usize, v: f64) {
        self.out[(self.row0 + row, 10 * link + k)] = v;
    }
    #[inline(always)]
    fn actuator(&mut self, row: usize, act: usize, kind: usize, v: f64) {
        let col = 10 * self.n + self.layout.per * act + self.layout.slots[kind];
        self.out[(self.row0 + row, col)] = v;
    }
}

/// The wrench of one link per unit of each of its 10 parameters, in its own frame:
/// moment about the frame origin and force, for m, mx, my, mz (`n`, `f`); moment only for
/// Ixx..Izz (`ni`).
struct LinkColumns {
    n: [Vector3<f64>; 4],
    f: [Vector3<f64>; 4],
    ni: [Vector3<f64>; 6],
}

impl LinkColumns {
    #[inline(always)]
    fn new(s: &LinkState) -> Self {
        let (w, wd, a) = (s.w, s.wd, s.a);
        // f = m·a + ω̇ × h + ω × (ω × h), n = I·ω̇ + ω × (I·ω) + h × a.
        let k = wd.cross_matrix() + w.cross_matrix() * w.cross_matrix();
        let f = [
            a,
            k.column(0).into(),
            k.column(1).into(),
            k.column(2).into(),
        ];
        let n = [
            Vector3::zeros(),
            Vector3::x().cross(&a),
            Vector3::y().cross(&a),
            Vector3::z().cross(&a),
        ];
        // L(v)·[Ixx, Ixy, Iyy, Ixz, Iyz, Izz] = I·v.
        let l = |v: &Vector3<f64>| {
            [
                Vector3::new(v.x, 0.0, 0.0),
                Vector3::new(v.y, v.x, 0.0),
                Vector3::new(0.0, v.y, 0.0),
                Vector3::new(v.z, 0.0, v.x),
                Vector3::new(0.0, v.z, v.y),
                Vector3::new(0.0, 0.0, v.z),
            ]
        };
        let (lwd, lw) = (l(&wd), l(&w));
        let ni = std::array::from_fn(|c| lwd[c] + w.cross(&lw[c]));
        Self { n, f, ni }
    }

    /// Row `row` of link `link`'s block: S·A with S = (s_ang, s_lin) in the link frame.
    #[inline(always)]
    fn emit<S: RegressorSink>(
        &self,
        row: usize,
        link: usize,
        s_ang: &Vector3<f64>,
        s_lin: &Vector3<f64>,
        revolute: bool,
        sink: &mut S,
    ) {
        for c in 0..4 {
            sink.rigid(row, link, c, s_ang.dot(&self.n[c]) + s_lin.dot(&self.f[c]));
        }
        if revolute {
            for (c, x) in self.ni.iter().enumerate() {
                sink.rigid(row, link, 4 + c, s_ang.dot(x));
            }
        }
    }
}

impl ChainView<'_> {
    /// Computes Y (and, if `friction`, the enabled actuator columns) of this N-joint view
    /// into `out`, column-major with N rows in the chain's parameter order; `out` must be
    /// zero on entry.
    #[inline]
    pub(crate) fn column_major_regressor_into<const N: usize>(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        friction: bool,
        out: &mut [f64],
    ) {
        debug_assert_eq!(self.dof(), N);
        let mut st = [LinkState::default(); N];
        let cols = out.len() / N;
        let mut sink = StandardSink {
            out: &mut MatrixViewMut::from_slice_generic(out, Const::<N>, Dyn(cols)),
            row0: 0,
            n: N,
            layout: self.layout(),
        };
        self.regressor_into(q, qd, qdd, friction, &mut st, &mut sink);
    }

    /// Computes Y (and, if `friction`, the enabled actuator columns: friction and armature)
    /// into `sink`.
    #[inline]
    pub(crate) fn regressor_into<S: RegressorSink>(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        friction: bool,
        st: &mut [LinkState],
        sink: &mut S,
    ) {
        if let Some(cf) = self.closed {
            return cf.regressor(self, q, qd, qdd, friction, sink);
        }
        self.kinematics(q, qd, qdd, true, st);
        self.regressor_at_kinematics(qd, qdd, friction, st, sink);
    }

    /// [`Self::regressor_into`] with the kinematics at (q, q̇, q̈) in `st` already (e.g. of
    /// the Newton–Euler pass at that state).
    #[inline]
    pub(crate) fn regressor_at_kinematics<S: RegressorSink>(
        &self,
        qd: &[f64],
        qdd: &[f64],
        friction: bool,
        st: &mut [LinkState],
        sink: &mut S,
    ) {
        let n = self.dof();
        // Joint j's motion subspace S_j, re-expressed frame by frame as i grows (kept in
        // st[j].s_*): the entry of row j and link i is S_jᵀ·A_i in frame i, one motion
        // transform per (i, j) instead of moving the ten columns of A_i down to every j.
        for i in 0..n {
            let (rt, p) = (st[i].r.transpose(), st[i].p);
            for sj in st[..i].iter_mut() {
                // From frame i−1 to frame i: ω' = Rᵀω, v' = Rᵀ(v + ω × p).
                sj.s_lin = rt * (sj.s_lin + sj.s_ang.cross(&p));
                sj.s_ang = rt * sj.s_ang;
            }
            st[i].s_ang = self.geom[i].s_ang;
            st[i].s_lin = self.geom[i].s_lin;
            let cols = LinkColumns::new(&st[i]);
            for (j, sj) in st[..=i].iter().enumerate() {
                cols.emit(j, i, &sj.s_ang, &sj.s_lin, self.geom[j].revolute, sink);
            }
        }
        if friction {
            self.actuator_columns(qd, qdd, sink);
        }
    }

    /// The enabled actuator columns (friction and armature) into `sink`.
    #[inline]
    pub(crate) fn actuator_columns<S: RegressorSink>(&self, qd: &[f64], qdd: &[f64], sink: &mut S) {
        let n = self.dof();
        // Actuator m's column of term k is Cᵀ times its feature at (C·q̇)ₘ, (C·q̈)ₘ:
        // rows j with C[m][j] ≠ 0.
        let en = self.friction.enabled();
        let arm = self.armature.is_some();
        for m in 0..n {
            let f = self.friction.features(self.actuator_rate(m, qd));
            let feat = [f[0], f[1], f[2], self.actuator_rate(m, qdd)];
            let on = [en[0], en[1], en[2], arm];
            for kind in 0..4 {
                if !on[kind] {
                    continue;
                }
                match self.coupling {
                    None => sink.actuator(m, m, kind, feat[kind]),
                    Some(c) => {
                        for (j, &cj) in c[m * n..m * n + n].iter().enumerate() {
                            if cj != 0.0 {
                                sink.actuator(j, m, kind, cj * feat[kind]);
                            }
                        }
                    }
                }
            }
        }
    }
}
