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
}

impl Default for CoulombScaleConfig {
    fn default() -> Self {
        Self {
            candidates: None,
            folds: 4,
            refine: true,
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
    /// Why the default was kept, when v_s could not be identified (no speed reversal, or
    /// a flat residual curve); `None` when the data decided.
    pub note: Option<String>,
}

/// Relative spread of the CV curve below which the data cannot tell scales apart.
const FLAT_CURVE: f64 = 1e-9;

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
    let mut candidates = Vec::with_capacity(grid.len() + 1);
    let mut cv_rms = Vec::with_capacity(grid.len() + 1);
    for &v in &grid {
        crate::interrupt::check("Coulomb speed-scale search")?;
        candidates.push(v);
        cv_rms.push(search.score(v)?);
    }
    let best = argmin(&cv_rms).ok_or(PrrrpError::RankDeficient {
        rank: 0,
        params: b,
        cond: f64::INFINITY,
        directions: vec![],
    })?;

    let default = friction.coulomb_smoothing;
    let scored: Vec<f64> = cv_rms.iter().flatten().copied().collect();
    let (lo, hi) = scored
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    let note = if reversals.iter().all(|&r| r == 0) {
        Some(
            "no joint reverses its speed in the data, so the Coulomb speed scale cannot be \
             identified; kept the default"
                .to_string(),
        )
    } else if hi - lo <= FLAT_CURVE * hi {
        Some(
            "the cross-validated error does not depend on the Coulomb speed scale; kept the \
             default"
                .to_string(),
        )
    } else {
        None
    };
    if note.is_some() {
        return Ok(CoulombScaleReport {
            chosen: default,
            candidates,
            cv_rms,
            reversals,
            note,
        });
    }

    let mut chosen = candidates[best];
    if config.refine && chosen > 0.0 {
        if let Some(v) = refine(&grid, &cv_rms[..grid.len()], best) {
            crate::interrupt::check("Coulomb speed-scale search")?;
            let s = search.score(v)?;
            candidates.push(v);
            cv_rms.push(s);
            if matches!((s, cv_rms[best]), (Some(a), Some(b)) if a < b) {
                chosen = v;
            }
        }
    }
    Ok(CoulombScaleReport {
        chosen,
        candidates,
        cv_rms,
        reversals,
        note: None,
    })
}

struct Search<'a> {
    chain: &'a DynChain,
    base: &'a BaseParameters,
    data: &'a DynDataset,
    folds: usize,
    friction: FrictionModel,
}

impl Search<'_> {
    /// Cross-validated torque RMS with speed scale `v`, or `None` if a fold is singular.
    fn score(&mut self, v: f64) -> Result<Option<f64>> {
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
        let mut sse = 0.0;
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
            sse += e.max(0.0);
        }
        let rms = (sse / (s * n) as f64).sqrt();
        Ok(rms.is_finite().then_some(rms))
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

fn invalid(field: &str, value: f64, reason: &'static str) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field: field.into(),
        value,
        reason,
    }
}
