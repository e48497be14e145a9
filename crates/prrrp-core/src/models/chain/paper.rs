//! The PRRRP arm of the paper as a generic chain (Table 1 geometry, Table 2 inertia).

use std::sync::OnceLock;

use nalgebra::DMatrix;

use super::dh::DhConvention;
use super::inertia::inertial_parameters;
use super::meta::{ChainMeta, JointLimit};
use super::regressor::RegressorSink;
use super::rnea::ChainView;
use super::serial_chain::{DynChain, SerialChain};
use crate::error::Result;
use crate::models::prrrp::extended::{self, ExtLambda, NEXT};
use crate::models::prrrp::robot::Robot;
use crate::models::prrrp::terms::Trig;
use crate::models::prrrp::types::Vec5;
use crate::motion::limits::JointLimits;

impl SerialChain<5> {
    /// The paper's robot (Tables 1–2, g = 9.81 m/s²) as a generic chain; see
    /// [`SerialChain::from_robot`]. It is evaluated in closed form
    /// ([`SerialChain::is_closed_form`]).
    pub fn paper() -> Self {
        let mut chain = Self::from_robot_unchecked(&Robot::paper());
        chain.closed = ClosedBackend(paper_closed_form());
        chain
    }

    /// A PRRRP robot as a generic chain: standard DH from [`Robot::dh_table`], gravity
    /// (0, 0, −g), and the link parameters converted to the 10-parameter form about each
    /// link-frame origin (standard DH: frame i at the distal end of link i):
    /// - link 1 (translates only): a point mass m1 at its frame origin;
    /// - links 2–4: centre of mass on the link's x axis at lcᵢ from joint i, i.e. at
    ///   x = lcᵢ − lᵢ in frame i; inertia about the centre of mass Izz = Iyy = `inertia_zz`,
    ///   Ixx = 0 (a thin rod along x: the paper gives only Izz, and Ixx, Iyy do not act
    ///   on this planar arm);
    /// - link 5: a point mass m5 at the origin of frame 5, i.e. at the end of link 4,
    ///   moving with d5 along −z (DH α4 = 180°).
    ///
    /// With the paper's lengths and gravity (any masses, centres of mass and inertias) the
    /// chain is evaluated in closed form ([`SerialChain::is_closed_form`]).
    ///
    /// # Errors
    /// [`crate::PrrrpError::InvalidParameter`] if the robot fails [`Robot::validate`].
    pub fn from_robot(robot: &Robot) -> Result<Self> {
        robot.validate()?;
        let mut chain = Self::from_robot_unchecked(robot);
        let paper = Robot::paper();
        if robot.length == paper.length && robot.gravity == paper.gravity {
            chain.closed = ClosedBackend(paper_closed_form());
        }
        Ok(chain)
    }

    fn from_robot_unchecked(robot: &Robot) -> Self {
        let m = robot.mass;
        let l = robot.length;
        let rod = |k: usize| {
            let i = k + 1;
            let izz = robot.inertia_zz[k];
            inertial_parameters(
                m[i],
                [robot.com[k] - l[i], 0.0, 0.0],
                [0.0, 0.0, izz, 0.0, 0.0, izz],
            )
        };
        let point = |mass: f64| inertial_parameters(mass, [0.0; 3], [0.0; 6]);
        SerialChain::from_parts_unchecked(
            robot.dh_table(),
            DhConvention::Standard,
            [point(m[0]), rod(0), rod(1), rod(2), point(m[4])],
            [0.0, 0.0, -robot.gravity],
        )
    }
}

impl DynChain {
    /// The paper's robot as a run-time chain ([`SerialChain::paper`]) whose joints carry the
    /// limits its excitation is designed within ([`JointLimits::default`]: m and rad,
    /// /s, /s²; no effort limit), so that it runs through everything that takes a robot
    /// (the command line's `--robot paper`).
    pub fn paper() -> Self {
        let l = JointLimits::default();
        let mut meta = ChainMeta::numbered(5);
        meta.name = "paper-prrrp".into();
        for (i, j) in meta.joints.iter_mut().enumerate() {
            j.limit = JointLimit {
                lower: l.q_min[i],
                upper: l.q_max[i],
                velocity: l.qd_max[i],
                acceleration: l.qdd_max[i],
                effort: f64::NAN,
            };
        }
        SerialChain::paper()
            .to_dyn()
            .with_meta(meta)
            .expect("five joints and links")
    }
}

/// The closed-form evaluation a chain carries while it is exactly the paper's arm
/// ([`SerialChain::paper`], [`DynChain::paper`], [`SerialChain::from_robot`] with the
/// paper's lengths and gravity); `None` everywhere else. It is how the chain is evaluated,
/// not part of the model: chains with the same parameters compare equal with or without it.
#[derive(Clone, Copy, Default)]
pub(crate) struct ClosedBackend(pub(crate) Option<&'static PaperClosedForm>);

impl PartialEq for ClosedBackend {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for ClosedBackend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "closed form"
        } else {
            "recursive"
        })
    }
}

/// The arm's dynamics in closed form ([`extended`]) for any inertial parameters π of its
/// links: the extended parameters are l = G·π with a constant 11×50 map G. The arm has
/// 9 rigid base parameters (m1, Izz2, mx3, my3, Izz3, mx4, my4, Izz4, m5), not the paper's
/// 8: λ6 = l2·mx4′ and λ7 = l3·mx4′ are one parameter for a rigid link 4 (their ratio is
/// the geometry's l2/l3), and the paper leaves out the first moments across links 3 and 4
/// (my3, my4), which the μk of the extension carry.
///
/// G is fitted once by least squares of the extended regressor against the recursive
/// Newton–Euler regressor over fixed states, and accepted only if it reproduces the
/// recursive regressor on other states to [`FIT_TOLERANCE`]: it is a property of the
/// geometry and gravity, so every chain evaluated through it (the arm at its own π, a
/// base model's equivalent chain at any β) gets the recursive algorithms' values.
#[derive(Debug)]
pub(crate) struct PaperClosedForm {
    /// Gravity along world −z, m/s².
    gravity: f64,
    /// The nonzeros of G: (extended index, link, parameter k, coefficient), ordered by
    /// (link, k), i.e. by standard column.
    map: Vec<(usize, usize, usize, f64)>,
}

/// Largest deviation accepted between the closed form through G and the recursive
/// regressor, relative to the regressor's largest entry.
pub(crate) const FIT_TOLERANCE: f64 = 1e-12;

/// A chain column's entries below this fraction of G's largest are round-off of the fit
/// (e.g. the Ixx columns, which act nowhere on this arm): exact zeros then.
const MAP_ZERO: f64 = 1e-11;

#[inline(always)]
fn v5(x: &[f64]) -> Vec5 {
    Vec5::from_column_slice(&x[..5])
}

/// Joint states for the fit and its check: `k` picks a quasi-random state (rad, m, /s,
/// /s²) spread over a few turns, away from any special configuration.
fn fit_state(k: usize) -> [Vec5; 3] {
    let f = |a: usize, s: f64| {
        Vec5::from_fn(|i, _| s * ((k * 13 + a * 7 + i * 3) as f64 * 0.618).sin())
    };
    [f(0, 3.0), f(1, 2.0), f(2, 5.0)]
}

/// G for `chain` (the arm's geometry and gravity), or `None` if the closed form does
/// not reproduce its recursive regressor.
fn fit(chain: &SerialChain<5>, gravity: f64) -> Option<PaperClosedForm> {
    const K: usize = 16;
    let mut recursive = chain.view();
    recursive.closed = None;
    let stack = |states: std::ops::Range<usize>| {
        let rows = 5 * states.len();
        let mut y = DMatrix::<f64>::zeros(rows, NEXT);
        let mut full = DMatrix::<f64>::zeros(rows, 50);
        for (s, k) in states.enumerate() {
            let [q, qd, qdd] = fit_state(k);
            let ext = extended::regressor(gravity, &Trig::new(&q), &qd, &qdd);
            y.view_mut((5 * s, 0), (5, NEXT)).copy_from(&ext);
            let mut block = [0.0; 250];
            recursive.column_major_regressor_into::<5>(
                q.as_slice(),
                qd.as_slice(),
                qdd.as_slice(),
                false,
                &mut block,
            );
            full.view_mut((5 * s, 0), (5, 50))
                .copy_from(&DMatrix::from_column_slice(5, 50, &block));
        }
        (y, full)
    };
    let (y, full) = stack(0..K);
    let mut g = y.svd(true, true).solve(&full, 1e-14).ok()?;
    let scale = g.amax();
    g.iter_mut()
        .filter(|x| x.abs() < MAP_ZERO * scale)
        .for_each(|x| *x = 0.0);
    let (y, full) = stack(K..2 * K);
    if (&y * &g - &full).amax() > FIT_TOLERANCE * full.amax() {
        return None;
    }
    let mut map = Vec::new();
    for col in 0..50 {
        for e in 0..NEXT {
            if g[(e, col)] != 0.0 {
                map.push((e, col / 10, col % 10, g[(e, col)]));
            }
        }
    }
    Some(PaperClosedForm { gravity, map })
}

/// The closed form of the paper's geometry and gravity, fitted on first use.
pub(crate) fn paper_closed_form() -> Option<&'static PaperClosedForm> {
    static FORM: OnceLock<Option<PaperClosedForm>> = OnceLock::new();
    FORM.get_or_init(|| {
        let robot = Robot::paper();
        fit(&SerialChain::from_robot_unchecked(&robot), robot.gravity)
    })
    .as_ref()
}

impl PaperClosedForm {
    /// The extended parameters l = G·π of the links' inertial parameters π.
    #[inline(always)]
    fn lambda(&self, inertial: &[[f64; 10]]) -> ExtLambda {
        let mut l = [0.0; NEXT];
        for &(e, i, k, c) in &self.map {
            l[e] += c * inertial[i][k];
        }
        l
    }

    /// The rigid-body part of [`ChainView::rnea_with`] in closed form: τ (N, N·m) with the
    /// inertial parameters `inertial` (gravity if `gravity`); the view adds its actuator
    /// terms.
    #[inline]
    pub(crate) fn rnea(
        &self,
        inertial: &[[f64; 10]],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        gravity: bool,
    ) -> Vec5 {
        let g = if gravity { self.gravity } else { 0.0 };
        extended::inverse_dynamics(
            g,
            &Trig::new(&v5(q)),
            &v5(qd),
            &v5(qdd),
            &self.lambda(inertial),
        )
    }

    /// [`ChainView::mass_matrix_with`] in closed form (column-major 5×5 into `m`), plus
    /// the view's armature.
    #[inline]
    pub(crate) fn mass_matrix(
        &self,
        view: &ChainView<'_>,
        inertial: &[[f64; 10]],
        q: &[f64],
        m: &mut [f64],
    ) {
        let mm = extended::mass_matrix(&Trig::new(&v5(q)), &self.lambda(inertial));
        m[..25].copy_from_slice(mm.as_slice());
        view.add_armature_inertia(m);
    }

    /// [`ChainView::regressor_into`] in closed form: each rigid column of the chain is
    /// Y·G's column (the columns G maps to nothing are zero and not written), then the
    /// actuator columns if `friction`.
    #[inline]
    pub(crate) fn regressor<S: RegressorSink>(
        &self,
        view: &ChainView<'_>,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        friction: bool,
        sink: &mut S,
    ) {
        let y = extended::regressor(self.gravity, &Trig::new(&v5(q)), &v5(qd), &v5(qdd));
        // G's nonzeros come ordered by chain column: sum each column's, then emit it.
        let mut col = [0.0; 5];
        for (n, &(e, i, k, c)) in self.map.iter().enumerate() {
            for (r, v) in col.iter_mut().enumerate() {
                *v += y[(r, e)] * c;
            }
            if self.map.get(n + 1).map_or(true, |x| (x.1, x.2) != (i, k)) {
                for (r, v) in col.iter_mut().enumerate() {
                    sink.rigid(r, i, k, *v);
                    *v = 0.0;
                }
            }
        }
        if friction {
            view.actuator_columns(qd, qdd, sink);
        }
    }
}

impl<const N: usize> SerialChain<N> {
    /// Whether this chain is evaluated in closed form (the paper's arm, see
    /// [`SerialChain::paper`]): inverse dynamics, mass matrix, forward dynamics and the
    /// regressor then cost a fraction of the recursive algorithms, with the same values
    /// to round-off. Any change of its inertial parameters, gravity or actuators returns
    /// it to the recursive algorithms.
    pub fn is_closed_form(&self) -> bool {
        self.closed.0.is_some()
    }
}

impl DynChain {
    /// Whether this chain is evaluated in closed form; see [`SerialChain::is_closed_form`].
    pub fn is_closed_form(&self) -> bool {
        self.closed.0.is_some()
    }
}

impl<const N: usize> SerialChain<N> {
    /// The same chain evaluated by the recursive algorithms (Newton–Euler, composite rigid
    /// body) even if it is the paper's arm: for comparisons and benchmarks.
    pub fn recursive(mut self) -> Self {
        self.closed = ClosedBackend::default();
        self
    }
}

impl DynChain {
    /// The same chain evaluated by the recursive algorithms; see [`SerialChain::recursive`].
    pub fn recursive(mut self) -> Self {
        self.closed = ClosedBackend::default();
        self
    }
}
