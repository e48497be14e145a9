//! The speed scale v_s of smooth Coulomb friction, fc·tanh(q̇/v_s), chosen from the data.
//!
//! A Coulomb column of the wrong width leaves a large torque error wherever a joint
//! reverses, and the regressor is linear in fc for a fixed v_s: so v_s (shared by all
//! joints, v_s = 0 the exact sign) is a 1-D model selection by K-fold cross-validation over
//! contiguous blocks, which does not reward a width that only fits noise. An optimum on an
//! edge widens the range (at most [`CoulombScaleConfig::max_widenings`] times); when the
//! data cannot fix v_s the report says so ([`CoulombScaleReport::identifiable`], with a
//! [`CoulombScaleReport::note`] why). A candidate costs only its Coulomb columns.
//!
//! Design: docs/design/coulomb-scale.md.

use std::ops::Range;

use faer::linalg::matmul::triangular::{self as tri, BlockStructure};
use faer::linalg::solvers::Solve;
use faer::linalg::triangular_solve;
use faer::{Accum, Mat, Par, Side};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::data::DynDataset;
use crate::error::{invalid, PrrrpError, Result};
use crate::models::chain::{BaseParameters, DynChain, FrictionModel};
use crate::models::LinearModel;

/// Smallest and largest default candidate v_s, rad/s (m/s for prismatic joints).
pub const COULOMB_SCALE_RANGE: (f64, f64) = (1e-3, 0.3);
/// Number of log-spaced default candidates in [`COULOMB_SCALE_RANGE`] (plus v_s = 0).
pub const COULOMB_SCALE_GRID: usize = 16;
/// Most candidates a search accepts (each builds one observation matrix).
pub const MAX_COULOMB_CANDIDATES: usize = 1000;
/// Default [`CoulombScaleConfig::max_widenings`]: a decade each, so the default range
/// [`COULOMB_SCALE_RANGE`] grows to at most 10⁻⁵..30 rad/s. Beyond that the smooth term is
/// either the exact sign at any sampling rate a log has, or linear over any speed an arm
/// reaches (30 rad/s).
pub const COULOMB_SCALE_MAX_WIDENINGS: usize = 2;
/// Relative spread (max − min)/min of the cross-validated torque RMS at or below which the
/// speed scale is not identified (dimensionless): a v_s that changes the torque error by
/// less than 0.1 % is not worth choosing, whatever the statistics say.
pub const COULOMB_SCALE_FLAT: f64 = 1e-3;
/// Smallest paired z = mean(d)/(sd(d)/√F) over the F folds' error differences d between
/// some candidate and the best for which the data are said to tell scales apart
/// (dimensionless): with the default 4 folds, a Student t of 3 degrees of freedom, 3 is
/// ≈ 97 % one-sided. On the README's Panda tour, whose simulated arm has no friction, the
/// curve spans 0.1024–0.1025 N·m (0.11 %) with z = 2.1; on data with Coulomb friction
/// z ran from 22 to 2250.
pub const COULOMB_SCALE_MIN_Z: f64 = 3.0;

/// Settings of [`select_coulomb_scale`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoulombScaleConfig {
    /// Candidate v_s, rad/s or m/s, each finite and ≥ 0 (0 = the exact sign). `None`
    /// (default): 0 and [`COULOMB_SCALE_GRID`] log-spaced values over
    /// [`COULOMB_SCALE_RANGE`].
    pub candidates: Option<Vec<f64>>,
    /// Number of contiguous cross-validation folds, ≥ 2 and at most the number of samples
    /// (default 4).
    pub folds: usize,
    /// Refine the best grid point by a parabola in log v_s (default `true`).
    pub refine: bool,
    /// Most times the range widens by a decade when the optimum sits on its edge
    /// (default [`COULOMB_SCALE_MAX_WIDENINGS`]; 0: never). See the module docs.
    pub max_widenings: usize,
}

impl Default for CoulombScaleConfig {
    fn default() -> Self {
        Self {
            candidates: None,
            folds: 4,
            refine: true,
            max_widenings: COULOMB_SCALE_MAX_WIDENINGS,
        }
    }
}

/// The default candidates: 0 and [`COULOMB_SCALE_GRID`] log-spaced values, rad/s.
pub fn default_coulomb_scales() -> Vec<f64> {
    let (lo, hi) = COULOMB_SCALE_RANGE;
    let k = COULOMB_SCALE_GRID;
    std::iter::once(0.0)
        .chain((0..k).map(|i| lo * (hi / lo).powf(i as f64 / (k - 1) as f64)))
        .collect()
}

/// Result of [`select_coulomb_scale`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoulombScaleReport {
    /// The chosen v_s, rad/s or m/s (0 = the exact sign).
    pub chosen: f64,
    /// Every scored v_s, in the order scored (the grid, then the refined point if any).
    pub candidates: Vec<f64>,
    /// Cross-validated torque RMS of each candidate over all joints (N·m, N); `None`
    /// where a fold's fit was singular for that candidate.
    pub cv_rms: Vec<Option<f64>>,
    /// Speed reversals (sign changes of q̇) per joint in the data.
    pub reversals: Vec<usize>,
    /// Whether the data fix v_s: false for data without a speed reversal, a flat
    /// cross-validation curve (the chain's own scale is then kept), or an optimum still
    /// on the edge of the search after the widenings (the best candidate is then chosen:
    /// it predicts best, but the true scale lies beyond it).
    #[serde(default = "yes")]
    pub identifiable: bool,
    /// Why v_s is not identifiable, in a sentence a report can print; `None` when the data
    /// decided.
    pub note: Option<String>,
    /// How often the range widened by a decade (≤ [`CoulombScaleConfig::max_widenings`]).
    #[serde(default)]
    pub widenings: usize,
    /// Smallest and largest positive candidate scored, rad/s or m/s (the range searched).
    #[serde(default)]
    pub range: [f64; 2],
}

fn yes() -> bool {
    true
}

/// Which edge of the searched range an optimum sits on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Edge {
    /// The largest candidate.
    Top,
    /// The smallest positive candidate, better than the exact sign (or no 0 scored).
    Bottom,
}

/// Chooses the Coulomb speed scale v_s of `chain`'s friction model from `data` by
/// cross-validated least squares on the base parameters `base` (see the module docs).
/// The chain's own `coulomb_smoothing` is the default kept when the data cannot decide.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] if the chain has no Coulomb term, for a negative or
/// non-finite candidate, an empty candidate list or one longer than
/// [`MAX_COULOMB_CANDIDATES`], fewer than 2 folds or more folds than samples;
/// [`PrrrpError::ShapeMismatch`] for data
/// of another joint count or a `base` of another chain layout;
/// [`PrrrpError::TooFewSamples`] if a fold has fewer samples than base parameters; an
/// interrupt. When no candidate can be fitted in every fold, the default is kept (with
/// `identifiable` false and a `note`): whether the whole data are rank deficient is then
/// the identification's error to give, with the rank and the directions it misses.
pub fn select_coulomb_scale(
    chain: &DynChain,
    base: &BaseParameters,
    data: &DynDataset,
    config: &CoulombScaleConfig,
) -> Result<CoulombScaleReport> {
    let friction = chain.friction();
    if !friction.coulomb {
        return Err(invalid(
            "friction",
            f64::NAN,
            "has no Coulomb term, so there is no speed scale to choose: enable coulomb",
        ));
    }
    let n = chain.dof();
    data.check_dof(n, "the robot's")?;
    let grid = config
        .candidates
        .clone()
        .unwrap_or_else(default_coulomb_scales);
    if grid.is_empty() || grid.len() > MAX_COULOMB_CANDIDATES {
        return Err(invalid(
            "coulomb_scale candidates",
            grid.len() as f64,
            "must be between 1 and MAX_COULOMB_CANDIDATES (1000) values",
        ));
    }
    if let Some(&v) = grid.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(invalid(
            "coulomb_scale candidate",
            v,
            "must be finite and >= 0 (rad/s or m/s; 0 = the exact sign)",
        ));
    }
    if config.folds < 2 {
        return Err(invalid(
            "folds",
            config.folds as f64,
            "cross-validation needs at least 2 folds",
        ));
    }
    let samples = data.len();
    if config.folds > samples {
        return Err(invalid(
            "folds",
            config.folds as f64,
            "more folds than samples leaves folds empty: use a few (default 4)",
        ));
    }
    let b = base.count();
    if samples / config.folds < b.div_ceil(n) + 1 {
        return Err(PrrrpError::TooFewSamples {
            // Saturating: the bound above keeps it small, but the error must never panic.
            needed: config.folds.saturating_mul(b.div_ceil(n) + 1),
            got: samples,
        });
    }

    let reversals: Vec<usize> = (0..n)
        .map(|j| {
            let mut last = 0.0f64;
            let mut count = 0;
            for k in 0..samples {
                let v = data.qd()[k * n + j];
                if v != 0.0 {
                    if last != 0.0 && v.signum() != last.signum() {
                        count += 1;
                    }
                    last = v;
                }
            }
            count
        })
        .collect();

    let mut search = Search::new(chain, base, data, config.folds)?;
    let default = friction.coulomb_smoothing;
    run(&mut search, &grid, config, reversals, data, default)
}

/// The search over `grid` with `scorer` (see the module docs), after the checks of
/// [`select_coulomb_scale`]; `default` is the v_s kept when the data cannot decide.
fn run(
    scorer: &mut impl Scorer,
    grid: &[f64],
    config: &CoulombScaleConfig,
    reversals: Vec<usize>,
    data: &DynDataset,
    default: f64,
) -> Result<CoulombScaleReport> {
    let rows = data.len() * data.dof();
    let mut scored = Scored::default();
    scored.add(scorer, rows, grid)?;
    // Widen by a decade past whichever edge the optimum sits on, a bounded number of times.
    let mut widenings = 0;
    while widenings < config.max_widenings {
        let Some(edge) = scored.best().and_then(|best| scored.on_edge(best)) else {
            break;
        };
        scored.add(scorer, rows, &widen(&scored.candidates, edge))?;
        widenings += 1;
    }
    let Some(best) = scored.best() else {
        // Whether the whole data determine the parameters, and which directions they
        // miss, is the identification's to say at the default scale: a fold may miss a
        // direction (a joint that stands still in part of the log) that the whole data
        // have.
        return Ok(CoulombScaleReport {
            chosen: default,
            range: scored.range(),
            candidates: scored.candidates,
            cv_rms: scored.cv_rms,
            reversals,
            identifiable: false,
            note: Some(
                "no candidate could be fitted in every fold of the cross-validation (a \
                 fold's data do not excite every base parameter: a joint that does not \
                 move in part of the log, or too little motion); kept the default"
                    .to_string(),
            ),
            widenings,
        });
    };
    let range = scored.range();
    let spread = scored.spread(best);
    let z = scored.worst_z(best);
    let kept = if reversals.iter().all(|&r| r == 0) {
        Some(
            "no joint reverses its speed in the data, so the Coulomb speed scale cannot be \
             identified; kept the default"
                .to_string(),
        )
    } else if spread.is_nan() {
        // 0/0: every candidate's error is 0 (torques that read 0 throughout).
        Some(
            "the cross-validated torque error is the same (0) for every candidate: the \
             torques do not depend on the Coulomb speed scale (do they read 0?); kept the \
             default"
                .to_string(),
        )
    } else if spread <= COULOMB_SCALE_FLAT || z.is_nan() || z <= COULOMB_SCALE_MIN_Z {
        Some(format!(
            "the cross-validated torque error changes by only {} % over v_s = 0 and \
             {}..{} rad/s, and no candidate is worse than the best by more than {} \
             standard errors of their paired fold differences (needed: \
             {COULOMB_SCALE_MIN_Z}), so the data do not identify the Coulomb speed scale \
             (nor does it matter for prediction); kept the default",
            sig3(100.0 * spread),
            sig3(range[0]),
            sig3(range[1]),
            sig3(z)
        ))
    } else {
        None
    };
    let edge = scored.on_edge(best);
    let note = kept.clone().or_else(|| {
        let at = sig3(scored.candidates[best]);
        edge.map(|edge| match edge {
            Edge::Top => {
                let peak = data.qd().iter().fold(0.0f64, |m, v| m.max(v.abs()));
                format!(
                    "the cross-validated torque error still falls at v_s = {at} rad/s, the \
                     top of the search after {widenings} widening(s); the data's speeds reach \
                     only {} rad/s, over which fc·tanh(q̇/v_s) is then nearly linear, i.e. \
                     indistinguishable from viscous friction: the Coulomb speed scale is not \
                     identifiable (chose the best scored)",
                    sig3(peak)
                )
            }
            Edge::Bottom => format!(
                "the cross-validated torque error still falls at v_s = {at} rad/s, the bottom \
                 of the search after {widenings} widening(s), yet the exact sign predicts \
                 worse: the Coulomb speed scale is below what these data resolve and not \
                 identifiable (chose the best scored)"
            ),
        })
    });
    let mut chosen = if kept.is_some() {
        default
    } else {
        scored.candidates[best]
    };
    if note.is_none() && config.refine && chosen > 0.0 {
        if let Some(v) = refine(&scored.candidates, &scored.cv_rms, best) {
            scored.add(scorer, rows, &[v])?;
            let last = scored.cv_rms.len() - 1;
            if matches!((scored.cv_rms[last], scored.cv_rms[best]), (Some(a), Some(b)) if a < b) {
                chosen = v;
            }
        }
    }
    Ok(CoulombScaleReport {
        chosen,
        candidates: scored.candidates,
        cv_rms: scored.cv_rms,
        reversals,
        identifiable: note.is_none(),
        note,
        widenings,
        range,
    })
}

/// The candidates scored so far, in the order scored.
#[derive(Default)]
struct Scored {
    candidates: Vec<f64>,
    /// Cross-validated torque RMS of each (N·m, N).
    cv_rms: Vec<Option<f64>>,
    /// Held-out squared error of each fold, per candidate.
    folds: Vec<Option<Vec<f64>>>,
}

impl Scored {
    /// Scores `scales` together (one pass over the data for all of them) and records
    /// them; `rows` is the number of equations.
    fn add(&mut self, scorer: &mut impl Scorer, rows: usize, scales: &[f64]) -> Result<()> {
        crate::interrupt::check("Coulomb speed-scale search")?;
        let folds = scorer.score(scales)?;
        for (&v, folds) in scales.iter().zip(folds) {
            self.candidates.push(v);
            self.cv_rms.push(rms(rows, &folds));
            self.folds.push(folds);
        }
        Ok(())
    }

    fn best(&self) -> Option<usize> {
        argmin(&self.cv_rms)
    }

    /// Smallest and largest positive candidate ([0, 0] if none).
    fn range(&self) -> [f64; 2] {
        let positive = self.candidates.iter().copied().filter(|v| *v > 0.0);
        let lo = positive.clone().fold(f64::INFINITY, f64::min);
        let hi = positive.fold(0.0, f64::max);
        if lo.is_finite() {
            [lo, hi]
        } else {
            [0.0, 0.0]
        }
    }

    /// (max − min)/min of the cross-validated RMS over the scored candidates.
    fn spread(&self, best: usize) -> f64 {
        let lo = self.cv_rms[best].unwrap_or(f64::NAN);
        let hi = self.cv_rms.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
        (hi - lo) / lo
    }

    /// Largest paired z = mean(d)/(sd(d)/√F) of a candidate's fold errors against the best's.
    fn worst_z(&self, best: usize) -> f64 {
        let Some(b) = &self.folds[best] else {
            return f64::NAN;
        };
        let f = b.len() as f64;
        self.folds
            .iter()
            .flatten()
            .map(|c| {
                let d: Vec<f64> = c.iter().zip(b).map(|(x, y)| x - y).collect();
                let mean = d.iter().sum::<f64>() / f;
                let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (f - 1.0);
                // Worse by the same amount in every fold: certainly worse (+∞); the best
                // itself or a copy of it: 0/0, left out.
                mean / (var.sqrt() / f.sqrt())
            })
            .filter(|z| !z.is_nan())
            .fold(0.0f64, f64::max)
    }

    /// The edge of the scored range the candidate `best` sits on, if any: the largest
    /// candidate, or the smallest positive one when it beats v_s = 0 by more than
    /// [`COULOMB_SCALE_FLAT`] (or 0 was not scored) — within that it is the exact sign.
    fn on_edge(&self, best: usize) -> Option<Edge> {
        let (candidates, scores) = (&self.candidates, &self.cv_rms);
        let v = candidates[best];
        if v <= 0.0 {
            return None;
        }
        let positive = || candidates.iter().copied().filter(|x| *x > 0.0);
        if positive().all(|x| x <= v) {
            return Some(Edge::Top);
        }
        if positive().all(|x| x >= v) {
            let sign = candidates
                .iter()
                .zip(scores)
                .filter(|(c, _)| **c == 0.0)
                .filter_map(|(_, s)| *s)
                .fold(f64::INFINITY, f64::min);
            let at = scores[best]?;
            if sign.is_finite() && sign - at <= COULOMB_SCALE_FLAT * at {
                return None;
            }
            return Some(Edge::Bottom);
        }
        None
    }
}

/// One decade of new candidates past `edge` of the scored ones, spaced as the outermost
/// two positive candidates there (the default grid's spacing, ≈ 6 per decade).
fn widen(candidates: &[f64], edge: Edge) -> Vec<f64> {
    let mut positive: Vec<f64> = candidates.iter().copied().filter(|x| *x > 0.0).collect();
    positive.sort_by(f64::total_cmp);
    positive.dedup();
    let (lo, hi) = COULOMB_SCALE_RANGE;
    let default_ratio = (hi / lo).powf(1.0 / (COULOMB_SCALE_GRID - 1) as f64);
    let k = positive.len();
    let (edge_value, ratio) = match edge {
        Edge::Top if k >= 2 => (positive[k - 1], positive[k - 1] / positive[k - 2]),
        Edge::Bottom if k >= 2 => (positive[0], positive[1] / positive[0]),
        Edge::Top => (positive[k - 1], default_ratio),
        Edge::Bottom => (positive[0], default_ratio),
    };
    // A grid much finer or coarser than the default's would widen by too many or too few
    // points: keep between 2 and 20 per decade.
    let ratio = if ratio.is_finite() && ratio > 1.0 {
        ratio.clamp(10f64.powf(1.0 / 20.0), 10f64.sqrt())
    } else {
        default_ratio
    };
    let steps = ((10f64.ln() / ratio.ln()).round() as usize).max(1);
    (1..=steps)
        .map(|i| {
            let f = ratio.powi(i as i32);
            match edge {
                Edge::Top => edge_value * f,
                Edge::Bottom => edge_value / f,
            }
        })
        .collect()
}

/// Scores candidate speed scales.
trait Scorer {
    /// Held-out sum of squared torque errors of each fold ((N·m)², N²) for each of
    /// `scales`, `None` where a fold's fit is singular.
    fn score(&mut self, scales: &[f64]) -> Result<Vec<Option<Vec<f64>>>>;
}

/// The cross-validation with everything that does not depend on v_s built once (see the
/// module docs): per fold the normal equations of the other base columns, their training
/// factor and τ's moments; per call only the Coulomb columns' blocks.
struct Search {
    friction: FrictionModel,
    /// Sample ranges of the contiguous folds.
    folds: Vec<Range<usize>>,
    /// Number of base columns that do not depend on v_s (the "fixed" ones).
    nf: usize,
    /// Each joint's equations in the fixed columns.
    joints: Vec<JointRows>,
    /// The Coulomb columns of W_b, in base order.
    coulomb: Vec<CoulombColumn>,
    /// Σ_j c_aj·c_bj of Coulomb columns a and b (row-major): their columns' products
    /// sample by sample.
    overlap: Vec<f64>,
    fixed: Vec<FoldFixed>,
}

/// The equations of one joint (rows: samples) in the fixed columns they involve.
struct JointRows {
    /// Fixed-column indices the joint's equations can involve, increasing.
    cols: Vec<usize>,
    /// The equations, sample by sample (`cols.len()` entries each).
    rows: Vec<f64>,
}

impl JointRows {
    /// The transposed equations of samples `range`: `cols.len()` × samples.
    fn transposed(&self, range: &Range<usize>) -> faer::MatRef<'_, f64> {
        let m = self.cols.len();
        faer::MatRef::from_column_major_slice(
            &self.rows[range.start * m..range.end * m],
            m,
            range.len(),
        )
    }
}

/// A Coulomb column of W_b: actuator m's entry in joint j's equation of sample k is
/// c_mj·sgn_vs((C·q̇_k)_m) (c_mj = δ_mj without coupling).
struct CoulombColumn {
    /// (C·q̇)_m per sample, rad/s or m/s.
    rate: Vec<f64>,
    /// The joints the actuator reaches and c_mj.
    joints: Vec<(usize, f64)>,
    /// Σ_j c_mj·τ_j per sample (N·m, N).
    torque: Vec<f64>,
}

/// One fold's v_s-independent parts.
struct FoldFixed {
    /// W_Fᵀ·W_F over the fold's samples (fixed columns).
    gram: Mat<f64>,
    /// W_Fᵀ·τ over the fold's samples.
    rhs: Vec<f64>,
    /// τᵀτ over the fold's samples.
    tt: f64,
    /// The fit without the fold, fixed block; `None` when singular.
    train: Option<Train>,
}

/// The fixed block P = A − A_f of a fold's training normal equations, scaled to unit
/// diagonal (D·P·D = L·Lᵀ), and y = L⁻¹·D·(b − b_f).
struct Train {
    l: Mat<f64>,
    scale: Vec<f64>,
    y: Mat<f64>,
}

impl Search {
    fn new(
        chain: &DynChain,
        base: &BaseParameters,
        data: &DynDataset,
        folds: usize,
    ) -> Result<Self> {
        let model = chain.base_model(base)?;
        let (n, s, b) = (chain.dof(), data.len(), model.count());
        let layout = base.layout();
        let view = chain.view();
        // Which base columns are Coulomb columns (of which actuator); the rest are fixed.
        let mut fixed_index = vec![None; b];
        let mut actuators = Vec::new();
        let mut nf = 0;
        for (c, &idx) in base.independent.iter().enumerate() {
            let coulomb_of = idx
                .checked_sub(10 * n)
                .filter(|off| layout.per > 0 && off % layout.per == layout.slots[1])
                .map(|off| off / layout.per);
            match coulomb_of {
                Some(m) => actuators.push(m),
                None => {
                    fixed_index[c] = Some(nf);
                    nf += 1;
                }
            }
        }

        // A joint's equations involve only the links from it outwards and the actuators
        // that reach it (the regressor writes nothing else): the other columns are zero
        // throughout and left out, exactly, which halves the work below.
        let coupling = view.coupling;
        let reaches = |j: usize, idx: usize| match idx.checked_sub(10 * n) {
            None => j <= idx / 10,
            Some(off) => {
                let m = off / layout.per.max(1);
                coupling.map_or(j == m, |c| c[m * n + j] != 0.0)
            }
        };
        let fixed_cols: Vec<usize> = (0..b).filter(|&c| fixed_index[c].is_some()).collect();
        let joint_cols: Vec<Vec<usize>> = (0..n)
            .map(|j| {
                (0..nf)
                    .filter(|&f| reaches(j, base.independent[fixed_cols[f]]))
                    .collect()
            })
            .collect();
        // Each sample's entries of a joint kept together, so that stacking writes in order.
        let mut stacked: Vec<Vec<f64>> = joint_cols
            .iter()
            .map(|cols| Vec::with_capacity(s * cols.len()))
            .collect();
        let mut ws = model.workspace();
        let mut phi = DMatrix::zeros(n, b);
        let (mut q, mut qd, mut qdd) = (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
        for k in 0..s {
            if k % 1024 == 0 {
                crate::interrupt::check("Coulomb speed-scale search")?;
            }
            q.copy_from_slice(data.q_row(k));
            qd.copy_from_slice(data.qd_row(k));
            qdd.copy_from_slice(data.qdd_row(k));
            model.regressor_into(&mut ws, &q, &qd, &qdd, &mut phi)?;
            let ph = phi.as_slice();
            for (j, (dst, cols)) in stacked.iter_mut().zip(&joint_cols).enumerate() {
                dst.extend(cols.iter().map(|&f| ph[fixed_cols[f] * n + j]));
            }
        }
        let joints: Vec<JointRows> = joint_cols
            .into_iter()
            .zip(stacked)
            .map(|(cols, rows)| JointRows { cols, rows })
            .collect();

        let ranges: Vec<Range<usize>> = (0..folds)
            .map(|f| f * s / folds..(f + 1) * s / folds)
            .collect();
        let tau = data.tau();
        let tau_j: Vec<Mat<f64>> = (0..n)
            .map(|j| Mat::<f64>::from_fn(s, 1, |k, _| tau[k * n + j]))
            .collect();
        let mut fixed = Vec::with_capacity(folds);
        for range in &ranges {
            crate::interrupt::check("Coulomb speed-scale search")?;
            let (k0, len) = (range.start, range.len());
            let mut gram = Mat::<f64>::zeros(nf, nf);
            let mut rhs = vec![0.0; nf];
            for (j, jr) in joints.iter().enumerate() {
                let gt = jr.transposed(range);
                let m = jr.cols.len();
                let mut part = Mat::<f64>::zeros(m, m);
                tri::matmul(
                    part.as_mut(),
                    BlockStructure::TriangularLower,
                    Accum::Replace,
                    gt,
                    BlockStructure::Rectangular,
                    gt.transpose(),
                    BlockStructure::Rectangular,
                    1.0,
                    Par::Seq,
                );
                let gt = gt * tau_j[j].as_ref().subrows(k0, len);
                // `cols` increases, so the lower triangle lands in the lower triangle.
                for (r, &cr) in jr.cols.iter().enumerate() {
                    rhs[cr] += gt[(r, 0)];
                    for (r2, &cr2) in jr.cols[..=r].iter().enumerate() {
                        gram[(cr, cr2)] += part[(r, r2)];
                    }
                }
            }
            for i in 0..nf {
                for i2 in 0..i {
                    gram[(i2, i)] = gram[(i, i2)];
                }
            }
            let tt = tau[k0 * n..range.end * n].iter().map(|x| x * x).sum();
            fixed.push(FoldFixed {
                gram,
                rhs,
                tt,
                train: None,
            });
        }
        let total = fixed
            .iter()
            .fold(Mat::<f64>::zeros(nf, nf), |acc, f| acc + &f.gram);
        let total_rhs: Vec<f64> = (0..nf)
            .map(|i| fixed.iter().map(|f| f.rhs[i]).sum())
            .collect();
        for fold in &mut fixed {
            let train = &total - &fold.gram;
            let rhs: Vec<f64> = total_rhs
                .iter()
                .zip(&fold.rhs)
                .map(|(a, b)| a - b)
                .collect();
            fold.train = factor(train, &rhs);
        }

        let coulomb: Vec<CoulombColumn> = actuators
            .iter()
            .map(|&m| {
                let joints: Vec<(usize, f64)> = match coupling {
                    None => vec![(m, 1.0)],
                    Some(c) => (0..n)
                        .map(|j| (j, c[m * n + j]))
                        .filter(|&(_, w)| w != 0.0)
                        .collect(),
                };
                let rate = (0..s)
                    .map(|k| view.actuator_rate(m, data.qd_row(k)))
                    .collect();
                let torque = (0..s)
                    .map(|k| joints.iter().map(|&(j, w)| w * tau[k * n + j]).sum())
                    .collect();
                CoulombColumn {
                    rate,
                    joints,
                    torque,
                }
            })
            .collect();
        let nc = coulomb.len();
        let mut overlap = vec![0.0; nc * nc];
        for (a, ca) in coulomb.iter().enumerate() {
            for (b, cb) in coulomb.iter().enumerate() {
                overlap[a * nc + b] = ca
                    .joints
                    .iter()
                    .flat_map(|&(j, wa)| {
                        cb.joints
                            .iter()
                            .filter(move |x| x.0 == j)
                            .map(move |x| wa * x.1)
                    })
                    .sum();
            }
        }
        Ok(Self {
            friction: chain.friction(),
            folds: ranges,
            nf,
            joints,
            coulomb,
            overlap,
            fixed,
        })
    }
}

/// 1/√m_ii per row of the square `m`, the scaling to a unit diagonal; `None` if a diagonal
/// entry is not positive and finite (the matrix is then not positive definite).
fn unit_diagonal_scale(m: &Mat<f64>) -> Option<Vec<f64>> {
    let scale: Vec<f64> = (0..m.nrows())
        .map(|i| {
            let x = m[(i, i)];
            if x > 0.0 {
                1.0 / x.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    (!scale.contains(&0.0)).then_some(scale)
}

/// The unit-diagonal Cholesky factor of `p` and L⁻¹·D·`rhs`, or `None` if `p` is not
/// positive definite.
fn factor(p: Mat<f64>, rhs: &[f64]) -> Option<Train> {
    let nf = p.nrows();
    // Unit-diagonal scaling keeps the Cholesky factor accurate when columns differ by
    // orders of magnitude (inertia vs friction).
    let scale = unit_diagonal_scale(&p)?;
    let scaled = Mat::<f64>::from_fn(nf, nf, |i, j| p[(i, j)] * scale[i] * scale[j]);
    let l = scaled.as_ref().llt(Side::Lower).ok()?.L().to_owned();
    let mut y = Mat::<f64>::from_fn(nf, 1, |i, _| rhs[i] * scale[i]);
    triangular_solve::solve_lower_triangular_in_place(l.as_ref(), y.as_mut(), Par::Seq);
    Some(Train { l, scale, y })
}

impl Scorer for Search {
    fn score(&mut self, scales: &[f64]) -> Result<Vec<Option<Vec<f64>>>> {
        let (kc, nc, nf, nfold) = (scales.len(), self.coulomb.len(), self.nf, self.folds.len());
        // Per fold: W_Fᵀ·W_C (nf × nc·kc, candidate c of column a at a·kc + c), W_Cᵀ·W_C
        // (nc × nc per candidate) and W_Cᵀ·τ (nc per candidate).
        let mut cross: Vec<Mat<f64>> = (0..nfold).map(|_| Mat::<f64>::zeros(nf, nc * kc)).collect();
        let mut cc: Vec<Vec<Mat<f64>>> = (0..nfold)
            .map(|_| (0..kc).map(|_| Mat::<f64>::zeros(nc, nc)).collect())
            .collect();
        let mut ct: Vec<Mat<f64>> = (0..nfold).map(|_| Mat::<f64>::zeros(nc, kc)).collect();
        // The Coulomb columns' entries over one fold (samples × candidates per column),
        // reused fold after fold.
        let longest = self.folds.iter().map(|r| r.len()).max().unwrap_or(0);
        let mut features: Vec<Mat<f64>> = (0..nc).map(|_| Mat::zeros(longest, kc)).collect();
        for (f, range) in self.folds.iter().enumerate() {
            let len = range.len();
            for (col, feat) in self.coulomb.iter().zip(&mut features) {
                crate::interrupt::check("Coulomb speed-scale search")?;
                for (c, &v) in scales.iter().enumerate() {
                    let model = FrictionModel {
                        coulomb_smoothing: v,
                        ..self.friction
                    };
                    for (x, &rate) in feat.col_as_slice_mut(c)[..len]
                        .iter_mut()
                        .zip(&col.rate[range.clone()])
                    {
                        *x = model.features(rate)[1];
                    }
                }
            }
            for (a, col) in self.coulomb.iter().enumerate() {
                let sa = features[a].as_ref().subrows(0, len);
                for &(j, w) in &col.joints {
                    let jr = &self.joints[j];
                    let part = jr.transposed(range) * sa;
                    for c in 0..kc {
                        for (r, &cr) in jr.cols.iter().enumerate() {
                            cross[f][(cr, a * kc + c)] += w * part[(r, c)];
                        }
                    }
                }
                for c in 0..kc {
                    let fa = &features[a].col_as_slice(c)[..len];
                    ct[f][(a, c)] = dot(fa, &col.torque[range.clone()]);
                    for b in 0..=a {
                        let o = self.overlap[a * nc + b];
                        if o != 0.0 {
                            let fb = &features[b].col_as_slice(c)[..len];
                            let x = o * dot(fa, fb);
                            cc[f][c][(a, b)] = x;
                            cc[f][c][(b, a)] = x;
                        }
                    }
                }
            }
        }

        let mut out = Vec::with_capacity(kc);
        for c in 0..kc {
            crate::interrupt::check("Coulomb speed-scale search")?;
            let cross_c = |f: usize, r: usize, a: usize| cross[f][(r, a * kc + c)];
            let total_cross = Mat::<f64>::from_fn(nf, nc, |r, a| {
                (0..nfold).map(|f| cross_c(f, r, a)).sum::<f64>()
            });
            let total_cc = Mat::<f64>::from_fn(nc, nc, |a, b| {
                (0..nfold).map(|f| cc[f][c][(a, b)]).sum::<f64>()
            });
            let total_ct: Vec<f64> = (0..nc)
                .map(|a| (0..nfold).map(|f| ct[f][(a, c)]).sum())
                .collect();
            let mut sse = Vec::with_capacity(nfold);
            for (f, fold) in self.fixed.iter().enumerate() {
                let Some(train) = &fold.train else { break };
                let r = Mat::<f64>::from_fn(nc, nc, |a, b| total_cc[(a, b)] - cc[f][c][(a, b)]);
                let Some(dc) = unit_diagonal_scale(&r) else {
                    break;
                };
                // Block Cholesky of the scaled training matrix [P Q; Qᵀ R]: X = L⁻¹·Q̃, the
                // Schur complement R̃ − XᵀX, then back substitution.
                let mut x = Mat::<f64>::from_fn(nf, nc, |i, a| {
                    train.scale[i] * (total_cross[(i, a)] - cross_c(f, i, a)) * dc[a]
                });
                triangular_solve::solve_lower_triangular_in_place(
                    train.l.as_ref(),
                    x.as_mut(),
                    Par::Seq,
                );
                let schur = Mat::<f64>::from_fn(nc, nc, |a, b| r[(a, b)] * dc[a] * dc[b])
                    - x.transpose() * &x;
                let Ok(schur) = schur.as_ref().llt(Side::Lower) else {
                    break;
                };
                let mut beta_c =
                    Mat::<f64>::from_fn(nc, 1, |a, _| (total_ct[a] - ct[f][(a, c)]) * dc[a])
                        - x.transpose() * &train.y;
                schur.solve_in_place(beta_c.as_mut());
                let mut beta_f = &train.y - &x * &beta_c;
                triangular_solve::solve_upper_triangular_in_place(
                    train.l.transpose(),
                    beta_f.as_mut(),
                    Par::Seq,
                );
                let bf: Vec<f64> = (0..nf).map(|i| beta_f[(i, 0)] * train.scale[i]).collect();
                let bc: Vec<f64> = (0..nc).map(|a| beta_c[(a, 0)] * dc[a]).collect();
                // ‖τ_f − W_f·β‖² = τᵀτ − 2βᵀW_fᵀτ + βᵀ(W_fᵀW_f)β over the fold's blocks.
                let af = Mat::<f64>::from_fn(nf, 1, |i, _| bf[i]);
                let gf = &fold.gram * &af;
                let mut e = fold.tt
                    - 2.0
                        * (dot(&bf, &fold.rhs)
                            + (0..nc).map(|a| bc[a] * ct[f][(a, c)]).sum::<f64>());
                e += (0..nf).map(|i| bf[i] * gf[(i, 0)]).sum::<f64>();
                for a in 0..nc {
                    let wfc: f64 = (0..nf).map(|i| bf[i] * cross_c(f, i, a)).sum();
                    let wcc: f64 = (0..nc).map(|b| cc[f][c][(a, b)] * bc[b]).sum();
                    e += bc[a] * (2.0 * wfc + wcc);
                }
                sse.push(e.max(0.0));
            }
            out.push((sse.len() == nfold && sse.iter().all(|x| x.is_finite())).then_some(sse));
        }
        Ok(out)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The candidate's cross-validated torque RMS (N·m, N) from its fold errors over `rows`
/// equations.
fn rms(rows: usize, folds: &Option<Vec<f64>>) -> Option<f64> {
    folds
        .as_ref()
        .map(|f| (f.iter().sum::<f64>() / rows as f64).sqrt())
}

fn argmin(values: &[Option<f64>]) -> Option<usize> {
    values
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.map(|x| (i, x)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// The vertex of the parabola in log v through the best positive grid point and its
/// positive neighbours, if it is a minimum strictly between them.
fn refine(grid: &[f64], scores: &[Option<f64>], best: usize) -> Option<f64> {
    let mut order: Vec<usize> = (0..grid.len()).filter(|&i| grid[i] > 0.0).collect();
    order.sort_by(|&a, &b| grid[a].total_cmp(&grid[b]));
    let at = order.iter().position(|&i| i == best)?;
    if at == 0 || at + 1 >= order.len() {
        return None;
    }
    let (i0, i1, i2) = (order[at - 1], order[at], order[at + 1]);
    let (x0, x1, x2) = (grid[i0].ln(), grid[i1].ln(), grid[i2].ln());
    let (y0, y1, y2) = (scores[i0]?, scores[i1]?, scores[i2]?);
    let d0 = (y1 - y0) / (x1 - x0);
    let d1 = (y2 - y1) / (x2 - x1);
    let curvature = (d1 - d0) / (x2 - x0);
    if curvature <= 0.0 {
        return None;
    }
    // Newton form p(x) = y0 + d0·(x − x0) + c·(x − x0)(x − x1); p'(x) = 0 at the vertex.
    let x = 0.5 * (x0 + x1) - d0 / (2.0 * curvature);
    (x > x0 && x < x2).then(|| x.exp())
}

/// `x` with three significant digits (as `%.3g` without the exponent form).
fn sig3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let decimals = (2 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chain::BaseOptions;
    use crate::motion::{DynTrajectory, FourierTrajectory};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    /// The straightforward scorer the fast one replaced: W_b rebuilt for every candidate,
    /// the full normal equations of every fold solved from scratch.
    struct Rebuild<'a> {
        chain: &'a DynChain,
        base: &'a BaseParameters,
        data: &'a DynDataset,
        folds: usize,
        friction: FrictionModel,
    }

    impl Rebuild<'_> {
        fn score_one(&self, v: f64) -> Result<Option<Vec<f64>>> {
            let model = FrictionModel {
                coulomb_smoothing: v,
                ..self.friction
            };
            let chain = self
                .chain
                .clone()
                .with_friction(model, self.chain.friction_params().to_vec())?;
            let d = self.data;
            let w = chain.base_observation_matrix(self.base, d.q(), d.qd(), d.qdd())?;
            let n = chain.dof();
            let s = d.len();
            let b = w.ncols();
            let tau = d.tau();
            // Per-fold normal equations over contiguous blocks of samples.
            let mut a_f = Vec::with_capacity(self.folds);
            let mut b_f = Vec::with_capacity(self.folds);
            let mut tt_f = Vec::with_capacity(self.folds);
            for f in 0..self.folds {
                let (k0, k1) = (f * s / self.folds, (f + 1) * s / self.folds);
                let rows = w.subrows(k0 * n, (k1 - k0) * n);
                let gram: Mat<f64> = rows.transpose() * rows;
                let t = &tau[k0 * n..k1 * n];
                let mut bv = DVector::zeros(b);
                for (i, &ti) in t.iter().enumerate() {
                    for c in 0..b {
                        bv[c] += rows[(i, c)] * ti;
                    }
                }
                a_f.push(DMatrix::from_fn(b, b, |i, j| gram[(i, j)]));
                b_f.push(bv);
                tt_f.push(t.iter().map(|x| x * x).sum::<f64>());
            }
            let a: DMatrix<f64> = a_f.iter().fold(DMatrix::zeros(b, b), |acc, m| acc + m);
            let bt: DVector<f64> = b_f.iter().fold(DVector::zeros(b), |acc, v| acc + v);
            let mut sse = Vec::with_capacity(self.folds);
            for f in 0..self.folds {
                let train = &a - &a_f[f];
                // Unit-diagonal scaling keeps the Cholesky factor accurate when columns differ
                // by orders of magnitude (inertia vs friction).
                let dscale = DVector::from_fn(b, |i, _| {
                    let x = train[(i, i)];
                    if x > 0.0 {
                        1.0 / x.sqrt()
                    } else {
                        0.0
                    }
                });
                if dscale.iter().any(|&x| x == 0.0) {
                    return Ok(None);
                }
                let scaled = DMatrix::from_fn(b, b, |i, j| train[(i, j)] * dscale[i] * dscale[j]);
                let Some(chol) = scaled.cholesky() else {
                    return Ok(None);
                };
                let rhs = (&bt - &b_f[f]).component_mul(&dscale);
                let beta = chol.solve(&rhs).component_mul(&dscale);
                let e = tt_f[f] - 2.0 * beta.dot(&b_f[f]) + (&a_f[f] * &beta).dot(&beta);
                sse.push(e.max(0.0));
            }
            Ok(sse.iter().all(|x| x.is_finite()).then_some(sse))
        }
    }

    impl Scorer for Rebuild<'_> {
        fn score(&mut self, scales: &[f64]) -> Result<Vec<Option<Vec<f64>>>> {
            scales.iter().map(|&v| self.score_one(v)).collect()
        }
    }

    fn puma(coupled: bool) -> DynChain {
        crate::test_support::puma(coupled)
    }

    /// Random states (speeds reversing often, some small against the scales tried) and
    /// random torques: nothing a fit would favour.
    fn random_data(samples: usize, seed: u64) -> DynDataset {
        crate::test_support::random_data(samples, seed, |i| if i % 3 == 0 { 0.05 } else { 2.0 })
    }

    /// Held-out squared errors of each fold from a QR fit of the other folds' rows and the
    /// held-out residuals themselves (no normal equations, no cancellation).
    fn exact_fold_errors(
        chain: &DynChain,
        base: &BaseParameters,
        data: &DynDataset,
        folds: usize,
        v: f64,
    ) -> Vec<f64> {
        use faer::linalg::solvers::SolveLstsq;
        let friction = FrictionModel {
            coulomb_smoothing: v,
            ..chain.friction()
        };
        let chain = chain
            .clone()
            .with_friction(friction, chain.friction_params().to_vec())
            .unwrap();
        let w = chain
            .base_observation_matrix(base, data.q(), data.qd(), data.qdd())
            .unwrap();
        let (n, s, b) = (data.dof(), data.len(), w.ncols());
        let tau = data.tau();
        (0..folds)
            .map(|f| {
                let (r0, r1) = (f * s / folds * n, (f + 1) * s / folds * n);
                let train: Vec<usize> = (0..s * n).filter(|&r| r < r0 || r >= r1).collect();
                let a = Mat::<f64>::from_fn(train.len(), b, |i, j| w[(train[i], j)]);
                let y = Mat::<f64>::from_fn(train.len(), 1, |i, _| tau[train[i]]);
                let beta = a.qr().solve_lstsq(&y);
                (r0..r1)
                    .map(|r| {
                        let e = tau[r] - (0..b).map(|j| w[(r, j)] * beta[(j, 0)]).sum::<f64>();
                        e * e
                    })
                    .sum()
            })
            .collect()
    }

    fn relative(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        (a - b).abs() / a.abs().max(b.abs())
    }

    /// On random data (held-out errors as large as the torques: no cancellation in
    /// τᵀτ − 2βᵀb + βᵀAβ) the fast scorer's fold errors are the rebuild's to 1e-9 over the
    /// default grid and a widening below it. At 3 and 30 rad/s, far above the data's
    /// speeds, tanh(q̇/v_s) is the viscous column q̇/v_s within (q̇/v_s)³/3, so the normal
    /// equations lose cond²·ε in both scorers alike: there the fast one must be as close as
    /// the rebuild to an exact reference (QR fit, held-out residuals summed directly).
    #[test]
    fn fold_errors_equal_a_rebuild() {
        let grid: Vec<f64> = default_coulomb_scales().into_iter().chain([1e-5]).collect();
        for (coupled, folds) in [(false, 4), (true, 3)] {
            let chain = puma(coupled);
            let base = chain.base_parameters(&BaseOptions::default()).unwrap();
            let data = random_data(400, 7 + folds as u64);
            let mut rebuild = Rebuild {
                chain: &chain,
                base: &base,
                data: &data,
                folds,
                friction: chain.friction(),
            };
            let mut fast = Search::new(&chain, &base, &data, folds).unwrap();
            // The Coulomb columns are among the base columns (else there is nothing to test).
            assert_eq!(fast.coulomb.len(), 6);
            let want = rebuild.score(&grid).unwrap();
            let got = fast.score(&grid).unwrap();
            assert_eq!(got.len(), grid.len());
            for (v, (g, w)) in grid.iter().zip(got.iter().zip(&want)) {
                let (g, w) = (g.as_ref().unwrap(), w.as_ref().unwrap());
                assert_eq!(g.len(), folds);
                for (x, y) in g.iter().zip(w) {
                    assert!(
                        relative(*x, *y) < 1e-9,
                        "v_s = {v}, coupled {coupled}: {x} vs {y}"
                    );
                }
            }
            let high = [3.0, 30.0];
            let want = rebuild.score(&high).unwrap();
            let got = fast.score(&high).unwrap();
            for (v, (g, w)) in high.iter().zip(got.iter().zip(&want)) {
                let exact = exact_fold_errors(&chain, &base, &data, folds, *v);
                let (g, w) = (g.as_ref().unwrap(), w.as_ref().unwrap());
                // Round-off varies with the folds' summation order: bound each fold by the
                // rebuild's worst fold at this scale (the same conditioning).
                let rebuild_err = w
                    .iter()
                    .zip(&exact)
                    .map(|(y, z)| relative(*y, *z))
                    .fold(0.0, f64::max);
                for ((x, y), z) in g.iter().zip(w).zip(&exact) {
                    let fast_err = relative(*x, *z);
                    println!("v_s = {v}, coupled {coupled}: fast {fast_err:.1e}, rebuild {rebuild_err:.1e}");
                    assert!(
                        fast_err <= 10.0 * rebuild_err + 1e-12,
                        "v_s = {v}, coupled {coupled}: fast {x}, rebuild {y}, exact {z}"
                    );
                }
            }
        }
    }

    /// A multi-sine of `truth` (smooth Coulomb of scale `v_s`) at 100 Hz with torque noise.
    fn excited(v_s: f64, samples: usize, seed: u64) -> DynDataset {
        let n = 6;
        let friction = FrictionModel {
            coulomb_smoothing: v_s,
            ..FrictionModel::all()
        };
        let truth = puma(false)
            .with_friction(friction, vec![[0.5, 0.3, 0.02]; n])
            .unwrap();
        let mut rng = StdRng::seed_from_u64(seed);
        let coef: Vec<f64> = (0..n * 6).map(|_| rng.random::<f64>() - 0.5).collect();
        // q_j = Σ_h α·sin(ω_h·t) + β·cos(ω_h·t), ω_h = 2π·0.25·h Hz, in the velocity
        // coefficients of the Fourier series (a = α·ω_h, b = −β·ω_h).
        let w0 = 2.0 * std::f64::consts::PI * 0.25;
        let w = |i: usize| w0 * (i % 3 + 1) as f64;
        let a = (0..n * 3).map(|i| coef[2 * i] * w(i)).collect();
        let b = (0..n * 3).map(|i| -coef[2 * i + 1] * w(i)).collect();
        let series = FourierTrajectory::new(w0, vec![0.0; n], a, b).unwrap();
        let (mut t, mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![], vec![]);
        for k in 0..samples {
            let tk = k as f64 * 0.01;
            let (mut qk, mut qdk, mut qddk) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            series.eval_into(tk, &mut qk, &mut qdk, &mut qddk);
            let tk_tau = truth.inverse_dynamics(&qk, &qdk, &qddk).unwrap();
            t.push(tk);
            q.extend(qk);
            qd.extend(qdk);
            qdd.extend(qddk);
            tau.extend(
                tk_tau
                    .iter()
                    .map(|x| x + 0.01 * (rng.random::<f64>() - 0.5)),
            );
        }
        DynDataset::new(n, t, q, qd, qdd, tau).unwrap()
    }

    /// The whole search (grid, widening, refinement, verdict) with the fast scorer reports
    /// what it reports with the rebuild.
    #[test]
    fn the_search_is_unchanged() {
        let chain = puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let config = CoulombScaleConfig::default();
        let grid = default_coulomb_scales();
        // A scale inside the default range, one above it (widening), the exact sign.
        for (seed, v_s) in [(1, 0.02), (2, 0.6), (3, 0.0)] {
            let data = excited(v_s, 1200, seed);
            let reversals = vec![1; 6];
            let mut rebuild = Rebuild {
                chain: &chain,
                base: &base,
                data: &data,
                folds: config.folds,
                friction: chain.friction(),
            };
            let want = run(&mut rebuild, &grid, &config, reversals.clone(), &data, 0.0).unwrap();
            let mut fast = Search::new(&chain, &base, &data, config.folds).unwrap();
            let got = run(&mut fast, &grid, &config, reversals, &data, 0.0).unwrap();
            // Good fits leave held-out errors 1e-7 of the torques' energy, below which
            // τᵀτ − 2βᵀb + βᵀAβ cancels in either scorer: compare the errors on that scale.
            let energy: f64 = data.tau().iter().map(|x| x * x).sum();
            let rows = data.tau().len() as f64;
            let k = want.candidates.len();
            assert_eq!(got.candidates.len(), k, "{got:?}\n{want:?}");
            // The grid and its widenings alike; a refined point (last) within round-off.
            assert_eq!(got.candidates[..k - 1], want.candidates[..k - 1]);
            assert!(relative(got.candidates[k - 1], want.candidates[k - 1]) <= 1e-6);
            for (x, y) in got.cv_rms.iter().zip(&want.cv_rms) {
                let (x, y) = (x.unwrap(), y.unwrap());
                assert!(
                    (x * x - y * y).abs() * rows <= 1e-9 * energy,
                    "{got:?}\n{want:?}"
                );
            }
            assert!(
                relative(got.chosen, want.chosen) <= 1e-6,
                "{got:?}\n{want:?}"
            );
            assert_eq!(
                (got.identifiable, &got.note, got.widenings),
                (want.identifiable, &want.note, want.widenings)
            );
            println!(
                "v_s = {v_s}: chose {} ({} widenings)",
                got.chosen, got.widenings
            );
        }
    }

    #[test]
    fn more_folds_than_samples_are_refused() {
        let chain = puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let data = random_data(50, 3);
        // usize::MAX / 2 overflowed the TooFewSamples message's product.
        for folds in [usize::MAX / 2, usize::MAX, 51] {
            let config = CoulombScaleConfig {
                folds,
                ..Default::default()
            };
            let got = select_coulomb_scale(&chain, &base, &data, &config);
            assert!(
                matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "folds"),
                "{folds}: {got:?}"
            );
        }
    }
}
