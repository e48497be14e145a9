//! The speed scale v_s of smooth Coulomb friction, fc·tanh(q̇/v_s), chosen from the data.
//!
//! Real joint friction turns over within a small speed band rather than jumping at q̇ = 0;
//! a Coulomb column of the wrong width leaves a large torque error wherever a joint
//! reverses. The regressor is linear in fc for a fixed v_s, so the search is a 1-D
//! model selection over v_s (shared by all joints): for each candidate the base
//! observation matrix W_b(v_s) is built and scored by K-fold cross-validation over
//! contiguous blocks of samples (the held-out block is a different stretch of motion, so
//! a width that only fits noise is not rewarded). The folds cost one pass: with the
//! normal equations A_f = W_fᵀW_f, b_f = W_fᵀτ_f of every fold, the fit without fold f is
//! β_f = (A − A_f)⁻¹(b − b_f) and its held-out error is
//! τ_fᵀτ_f − 2β_fᵀb_f + β_fᵀA_fβ_f. The best grid point is refined by a parabola in
//! log v_s through it and its neighbours. v_s = 0 (the exact sign) is always a candidate,
//! so the hard sign is chosen when it predicts best.
//!
//! **Edges and identifiability.** An optimum on the largest candidate (or on the smallest
//! positive one, beating the exact sign) says only that the error still falls beyond the
//! range searched: the range then widens by a decade on that side, at the grid's own
//! spacing, at most [`CoulombScaleConfig::max_widenings`] times (default
//! [`COULOMB_SCALE_MAX_WIDENINGS`]: up to 30 rad/s and down to 10⁻⁵ rad/s from the default
//! range). The report says when the data cannot fix v_s
//! ([`CoulombScaleReport::identifiable`] false, with a [`CoulombScaleReport::note`] why): no
//! speed reversal; a flat cross-validation curve — spread at most [`COULOMB_SCALE_FLAT`],
//! or no candidate worse than the best by more than [`COULOMB_SCALE_MIN_Z`] times the
//! standard error of their paired fold differences; or an optimum still on an edge after
//! the widenings (above the data's speeds the smooth Coulomb term is nearly linear in q̇,
//! i.e. indistinguishable from viscous friction).
//!
//! The search is a loop over candidates, each scored on its own ([`Search::score`]); a
//! faster scorer (updating the normal equations by the Coulomb columns only) can replace
//! that function without changing the search.

use faer::Mat;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::data::DynDataset;
use crate::error::{PrrrpError, Result};
use crate::models::chain::{BaseParameters, DynChain, FrictionModel};

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
    /// Number of contiguous cross-validation folds, ≥ 2 (default 4).
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
/// [`MAX_COULOMB_CANDIDATES`], fewer than 2 folds; [`PrrrpError::ShapeMismatch`] for data
/// of another joint count or a `base` of another chain layout;
/// [`PrrrpError::TooFewSamples`] if a fold has fewer samples than base parameters;
/// [`PrrrpError::RankDeficient`] if no candidate could be fitted; an interrupt.
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
    if data.dof() != n {
        return Err(PrrrpError::ShapeMismatch {
            what: "data".into(),
            expected: format!("{n} joints (the robot's)"),
            got: format!("{} joints", data.dof()),
        });
    }
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
    let b = base.count();
    if samples / config.folds < b.div_ceil(n) + 1 {
        return Err(PrrrpError::TooFewSamples {
            needed: config.folds * (b.div_ceil(n) + 1),
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

    let mut search = Search {
        chain,
        base,
        data,
        folds: config.folds,
        friction,
    };
    let mut scored = Scored::default();
    for &v in &grid {
        scored.add(&mut search, v)?;
    }
    // Widen by a decade past whichever edge the optimum sits on, a bounded number of times.
    let mut widenings = 0;
    while widenings < config.max_widenings {
        let Some(edge) = scored.best().and_then(|best| scored.on_edge(best)) else {
            break;
        };
        for v in widen(&scored.candidates, edge) {
            scored.add(&mut search, v)?;
        }
        widenings += 1;
    }
    let best = scored.best().ok_or(PrrrpError::RankDeficient {
        rank: 0,
        params: b,
        cond: f64::INFINITY,
        directions: vec![],
    })?;
    let range = scored.range();
    let default = friction.coulomb_smoothing;
    let spread = scored.spread(best);
    let z = scored.worst_z(best);
    let kept = if reversals.iter().all(|&r| r == 0) {
        Some(
            "no joint reverses its speed in the data, so the Coulomb speed scale cannot be \
             identified; kept the default"
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
            scored.add(&mut search, v)?;
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
    fn add(&mut self, search: &mut Search<'_>, v: f64) -> Result<()> {
        crate::interrupt::check("Coulomb speed-scale search")?;
        let folds = search.score(v)?;
        self.candidates.push(v);
        self.cv_rms.push(search.rms(&folds));
        self.folds.push(folds);
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

struct Search<'a> {
    chain: &'a DynChain,
    base: &'a BaseParameters,
    data: &'a DynDataset,
    folds: usize,
    friction: FrictionModel,
}

impl Search<'_> {
    /// Held-out sum of squared torque errors of each fold with speed scale `v`
    /// ((N·m)², N²), or `None` if a fold is singular.
    fn score(&mut self, v: f64) -> Result<Option<Vec<f64>>> {
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

    /// The candidate's cross-validated torque RMS (N·m, N) from its fold errors.
    fn rms(&self, folds: &Option<Vec<f64>>) -> Option<f64> {
        let rows = (self.data.len() * self.data.dof()) as f64;
        folds
            .as_ref()
            .map(|f| (f.iter().sum::<f64>() / rows).sqrt())
    }
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

fn invalid(field: &str, value: f64, reason: &'static str) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field: field.into(),
        value,
        reason,
    }
}
