//! Numerical base parameters of a chain: which combinations of the standard parameters
//! the joint forces actually depend on (Gautier 1991, "Numerical calculation of the base
//! inertial parameters of robots"; the method of SymPyBotics and BIRDy).
//!
//! 1. The full regressor (inertial and friction columns) is stacked over random states
//!    into W. Its zero columns (norm ≤ 1e-4·tol·the largest) are the **unidentifiable**
//!    parameters.
//! 2. The other columns are scaled to unit norm, so that units (kg against kg·m²) do not
//!    steer the result, and factorised by QR with column pivoting (faer):
//!    W·P = Q·[R₁ R₂]. The numerical rank b counts the pivots |R_kk| above the rank
//!    tolerance.
//! 3. Which b columns become the **independent** ones is a choice; for readable
//!    combinations a greedy pass takes the columns in a fixed order (links from the base
//!    outwards; within a link inertia, first moments, mass — Khalil's regrouping
//!    direction) and keeps each column farther than the tolerance from the span of those
//!    kept before. Should it not find exactly b columns (a borderline case), the first b
//!    pivoted columns are used.
//! 4. The others depend on them: W_d = W_i·K_d, K_d by least squares (exact up to
//!    round-off), scaled back to SI, entries below the tolerance (in scaled form) zeroed.
//!    Hence τ = W·π = W_i·β with the **base parameters** β = π_i + K_d·π_d, i.e. β = K·π
//!    with K = [1 K_d] in the original column order.

use faer::linalg::solvers::SolveLstsq;
use faer::Mat;

use super::actuators::ActuatorLayout;
use super::friction::FrictionModel;
use super::joint::JointGeom;
use super::rnea::{ChainView, LinkState};
use super::serial_chain::{parameter_names, stack_regressor, DynChain, SerialChain};
use crate::error::{PrrrpError, Result};

/// Settings of the numerical base-parameter analysis. `Copy + Default`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseOptions {
    /// Number of random states stacked (default 0 = automatic: enough for four times as
    /// many rows as standard parameters, at least 20 states).
    pub samples: usize,
    /// Seed of the random states (default 0x5EED_BA5E). Revolute joints are drawn
    /// uniformly in [−π, π] rad, prismatic joints in [−1, 1] m, velocities and
    /// accelerations uniformly in [−2, 2] (SI).
    pub seed: u64,
    /// Rank tolerance (default 1e-8, dimensionless). With unit-norm columns, a pivot
    /// |R_kk| ≤ tol means that column k lies within a relative distance tol of the span of
    /// the columns before it; the same tolerance zeroes coefficients |K̂_ij| ≤ tol of the
    /// scaled dependency matrix. Exact structural dependencies give pivots near 1e-15,
    /// independent columns of the robots tested here stay above 1e-4.
    pub rank_tolerance: f64,
}

impl Default for BaseOptions {
    fn default() -> Self {
        Self {
            samples: 0,
            seed: 0x5EED_BA5E,
            rank_tolerance: 1e-8,
        }
    }
}

/// The result of the base-parameter analysis of a chain.
///
/// Indices refer to the chain's standard parameter vector π (see
/// [`SerialChain::parameter_names`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BaseParameters {
    /// Number of joints of the analysed chain.
    pub dof: usize,
    /// Friction model of the analysed chain (with `armature` it fixes the parameter
    /// layout).
    pub friction: FrictionModel,
    /// Whether the analysed chain's actuators have armature columns (`Ia1 … Ian`).
    pub armature: bool,
    /// Names of the standard parameters (length p).
    pub names: Vec<String>,
    /// Standard parameters kept as base parameters, increasing (length b); base
    /// parameter r is `names[independent[r]]` plus its regrouped terms.
    pub independent: Vec<usize>,
    /// Standard parameters regrouped into the independent ones or unidentifiable (length
    /// p − b), increasing.
    pub dependent: Vec<usize>,
    /// Standard parameters that do not affect any joint force (zero regressor column), a
    /// subset of `dependent`.
    pub unidentifiable: Vec<usize>,
    /// K ∈ R^{b×p}: base parameters β = K·π, with `K[(r, independent[r])] = 1`.
    pub map: Mat<f64>,
    /// Each base parameter as a readable linear combination, e.g. `"mx2 + 0.4318*m2"`.
    pub combinations: Vec<String>,
    /// The pivots |R_kk| of the scaled pivoted QR, in pivot order (diagnostic: the gap
    /// between the b-th and the next shows how clear-cut the rank is).
    pub pivots: Vec<f64>,
    /// The rank tolerance used.
    pub rank_tolerance: f64,
}

impl BaseParameters {
    /// Number of base parameters b.
    pub fn count(&self) -> usize {
        self.independent.len()
    }

    /// Number of standard parameters p.
    pub fn num_standard(&self) -> usize {
        self.names.len()
    }

    /// β = K·π for a standard parameter vector π of length p.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if π does not have p entries.
    pub fn base_values(&self, pi: &[f64]) -> Result<Vec<f64>> {
        let p = self.num_standard();
        if pi.len() != p {
            return Err(PrrrpError::ShapeMismatch {
                what: "standard parameters π".into(),
                expected: format!("{p} entries"),
                got: format!("{} entries", pi.len()),
            });
        }
        Ok((0..self.count())
            .map(|r| (0..p).map(|j| self.map[(r, j)] * pi[j]).sum())
            .collect())
    }

    /// K as a flat row-major b×p vector (for bindings).
    pub fn map_row_major(&self) -> Vec<f64> {
        let (b, p) = (self.count(), self.num_standard());
        let mut v = Vec::with_capacity(b * p);
        for r in 0..b {
            for j in 0..p {
                v.push(self.map[(r, j)]);
            }
        }
        v
    }

    /// Selects the base columns of a stacked full observation matrix W (rows × p): the
    /// base observation matrix W_b with W·π = W_b·β.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if W does not have p columns.
    pub fn select_columns(&self, w: &Mat<f64>) -> Result<Mat<f64>> {
        if w.ncols() != self.num_standard() {
            return Err(PrrrpError::ShapeMismatch {
                what: "W".into(),
                expected: format!("{} columns (standard parameters)", self.num_standard()),
                got: format!("{} columns", w.ncols()),
            });
        }
        Ok(Mat::from_fn(w.nrows(), self.count(), |i, r| {
            w[(i, self.independent[r])]
        }))
    }

    /// Where the actuator parameters of the analysed chain sit.
    pub(crate) fn layout(&self) -> ActuatorLayout {
        ActuatorLayout::new(&self.friction, self.armature)
    }

    pub(crate) fn check_layout(&self, dof: usize, layout: &ActuatorLayout) -> Result<()> {
        // The Coulomb speed scale changes a column's values, not which columns exist or
        // which combinations are identifiable, so one analysis serves every v_s (the
        // Coulomb speed-scale search relies on it).
        if self.dof != dof || self.layout() != *layout {
            let terms = |l: &ActuatorLayout| {
                let on: Vec<&str> = ["viscous", "coulomb", "offset", "armature"]
                    .into_iter()
                    .zip(l.enabled())
                    .filter_map(|(t, on)| on.then_some(t))
                    .collect();
                if on.is_empty() {
                    "none".to_string()
                } else {
                    on.join("+")
                }
            };
            return Err(PrrrpError::ShapeMismatch {
                what: "base parameters".into(),
                expected: format!(
                    "an analysis of this chain ({dof} joints, actuator terms [{}])",
                    terms(layout)
                ),
                got: format!(
                    "an analysis of {} joints, actuator terms [{}]",
                    self.dof,
                    terms(&self.layout())
                ),
            });
        }
        Ok(())
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny seeded generator, enough to draw
/// generic states.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let u = (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        lo + (hi - lo) * u
    }
}

/// Largest stacked regressor the base-parameter analysis builds, in doubles (2.5·10⁸,
/// 2 GB).
pub const MAX_MATRIX_ENTRIES: f64 = 2.5e8;

pub(crate) fn analyse(view: &ChainView<'_>, opts: &BaseOptions) -> Result<BaseParameters> {
    let tol = opts.rank_tolerance;
    if !(tol.is_finite() && tol > 0.0 && tol < 1.0) {
        return Err(PrrrpError::InvalidParameter {
            field: "rank_tolerance (base-parameter analysis)".into(),
            value: tol,
            reason: "must be in (0, 1); the default is 1e-8",
        });
    }
    let n = view.dof();
    super::check_dof("chain joints", n)?;
    let layout = view.layout();
    let p = n * (10 + layout.per);
    let samples = if opts.samples == 0 {
        (4 * p).div_ceil(n).max(20)
    } else {
        opts.samples
    };
    // W is (n·samples) × p doubles: refuse what would not fit comfortably in memory.
    let entries = n as f64 * samples as f64 * p as f64;
    if entries > MAX_MATRIX_ENTRIES || samples > crate::interrupt::MAX_SAMPLES {
        return Err(PrrrpError::InvalidParameter {
            field: "samples (base-parameter analysis)".into(),
            value: samples as f64,
            reason: "the stacked regressor would exceed MAX_MATRIX_ENTRIES (2.5e8 doubles, \
                     2 GB) or MAX_SAMPLES: use fewer samples (0 = automatic, 4 rows per \
                     parameter)",
        });
    }
    if n * samples < p {
        return Err(PrrrpError::TooFewSamples {
            needed: p.div_ceil(n),
            got: samples,
        });
    }
    let mut rng = SplitMix64(opts.seed);
    let mut states = vec![0.0; 3 * n * samples];
    for k in 0..samples {
        for (i, g) in view.geom.iter().enumerate() {
            states[3 * n * k + i] = random_position(&mut rng, g);
            states[3 * n * k + n + i] = rng.uniform(-2.0, 2.0);
            states[3 * n * k + 2 * n + i] = rng.uniform(-2.0, 2.0);
        }
    }
    let mut st = vec![LinkState::default(); n];
    let w = stack_regressor(
        view,
        samples,
        |k| {
            let s = &states[3 * n * k..3 * n * (k + 1)];
            (&s[..n], &s[n..2 * n], &s[2 * n..])
        },
        &mut st,
    )?;

    // Unit-norm scaling; exactly (or numerically) zero columns are unidentifiable.
    let norms: Vec<f64> = (0..p).map(|j| w.col(j).norm_l2()).collect();
    let max_norm = norms.iter().fold(0.0f64, |a, &b| a.max(b));
    if max_norm <= 0.0 || max_norm.is_nan() {
        return Err(PrrrpError::RankDeficient {
            rank: 0,
            params: p,
            cond: f64::INFINITY,
            directions: Vec::new(),
        });
    }
    let nonzero: Vec<usize> = (0..p)
        .filter(|&j| norms[j] > tol * 1e-4 * max_norm)
        .collect();
    let ws = Mat::from_fn(w.nrows(), nonzero.len(), |i, c| {
        w[(i, nonzero[c])] / norms[nonzero[c]]
    });
    crate::interrupt::check("base-parameter analysis")?;
    let qr = ws.col_piv_qr();
    let r = qr.R();
    let (perm, _) = qr.P().arrays();
    let m = nonzero.len();
    let pivots: Vec<f64> = (0..m.min(ws.nrows())).map(|k| r[(k, k)].abs()).collect();
    let b = pivots.iter().take_while(|&&d| d > tol).count();

    // Which b columns to keep: the rank comes from the pivoted QR, the choice from a
    // greedy pass in a fixed order (falling back to the pivot order if the two disagree
    // on a borderline column).
    let position: Vec<Option<usize>> = {
        let mut pos = vec![None; p];
        for (c, &j) in nonzero.iter().enumerate() {
            pos[j] = Some(c);
        }
        pos
    };
    let order: Vec<usize> = preference_order(n, p).filter_map(|j| position[j]).collect();
    crate::interrupt::check("base-parameter analysis")?;
    let mut kept = greedy_independent(&ws, &order, tol)?;
    if kept.len() != b {
        kept = perm[..b].to_vec();
    }
    // `nonzero` is increasing, so sorting positions sorts standard indices.
    kept.sort_unstable();
    let independent: Vec<usize> = kept.iter().map(|&c| nonzero[c]).collect();
    let dep_cols: Vec<usize> = (0..m).filter(|c| kept.binary_search(c).is_err()).collect();

    // Ŵ_d = Ŵ_i·X̂ (exact up to round-off), then K_d = X̂ scaled back to SI.
    let ws_i = Mat::from_fn(ws.nrows(), b, |i, r| ws[(i, kept[r])]);
    let ws_d = Mat::from_fn(ws.nrows(), dep_cols.len(), |i, c| ws[(i, dep_cols[c])]);
    crate::interrupt::check("base-parameter analysis")?;
    let x = if b > 0 && !dep_cols.is_empty() {
        ws_i.qr().solve_lstsq(&ws_d)
    } else {
        Mat::zeros(b, dep_cols.len())
    };
    let mut map = Mat::<f64>::zeros(b, p);
    for (row, &ji) in independent.iter().enumerate() {
        map[(row, ji)] = 1.0;
        for (c, &dc) in dep_cols.iter().enumerate() {
            let coef = x[(row, c)];
            if coef.abs() > tol {
                let jd = nonzero[dc];
                map[(row, jd)] = coef * norms[jd] / norms[ji];
            }
        }
    }
    let dependent: Vec<usize> = (0..p)
        .filter(|j| independent.binary_search(j).is_err())
        .collect();
    let unidentifiable: Vec<usize> = dependent
        .iter()
        .copied()
        .filter(|&j| (0..b).all(|r| map[(r, j)] == 0.0))
        .collect();
    let names = parameter_names(n, &layout);
    let combinations = (0..b)
        .map(|r| combination(&names, (0..p).map(|j| map[(r, j)])))
        .collect();
    Ok(BaseParameters {
        dof: n,
        friction: view.friction,
        armature: view.armature.is_some(),
        names,
        independent,
        dependent,
        unidentifiable,
        map,
        combinations,
        pivots,
        rank_tolerance: tol,
    })
}

/// The order in which columns are offered to the greedy selection: links from the base
/// outwards, and within a link the inertia entries, then the first moments, then the mass
/// — so that, as in Khalil's regrouping rules, the mass and first moments of a link are
/// folded into the parameters of the links before it, and each base parameter is named
/// after the earliest parameter it contains. Actuator terms (friction, armature) come
/// last: an armature that moves with one joint only, such as the first joint's about a
/// fixed vertical axis, is folded into that link's inertia (`Izz1 + Ia1`).
fn preference_order(n: usize, p: usize) -> impl Iterator<Item = usize> {
    (0..n)
        .flat_map(|i| [4, 5, 6, 7, 8, 9, 1, 2, 3, 0].map(|k| 10 * i + k))
        .chain(10 * n..p)
}

/// Greedy column selection: keeps a (unit-norm) column if its distance to the span of
/// the columns kept before it exceeds `tol` (Gram–Schmidt with re-orthogonalisation).
fn greedy_independent(w: &Mat<f64>, order: &[usize], tol: f64) -> Result<Vec<usize>> {
    let rows = w.nrows();
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut kept = Vec::new();
    for &c in order {
        // O(rows·b) per column: as long as the QR for large chains, so it polls for a stop.
        crate::interrupt::check("base-parameter analysis")?;
        let mut v: Vec<f64> = (0..rows).map(|i| w[(i, c)]).collect();
        for _ in 0..2 {
            for q in &basis {
                let d: f64 = q.iter().zip(&v).map(|(a, b)| a * b).sum();
                for (x, a) in v.iter_mut().zip(q) {
                    *x -= d * a;
                }
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > tol {
            v.iter_mut().for_each(|x| *x /= norm);
            basis.push(v);
            kept.push(c);
        }
    }
    Ok(kept)
}

fn random_position(rng: &mut SplitMix64, g: &JointGeom) -> f64 {
    if g.revolute {
        rng.uniform(-std::f64::consts::PI, std::f64::consts::PI)
    } else {
        rng.uniform(-1.0, 1.0)
    }
}

/// `"a + c·x - …"` in parameter order, with ASCII operators so that the string pastes
/// into Python/SymPy.
fn combination(names: &[String], row: impl Iterator<Item = f64>) -> String {
    let mut s = String::new();
    for (j, c) in row.enumerate() {
        if c == 0.0 {
            continue;
        }
        if s.is_empty() {
            if c < 0.0 {
                s.push('-');
            }
        } else {
            s.push_str(if c < 0.0 { " - " } else { " + " });
        }
        let a = c.abs();
        if (a - 1.0).abs() > 1e-9 {
            s.push_str(&format_coefficient(a));
            s.push('*');
        }
        s.push_str(&names[j]);
    }
    s
}

/// Six significant digits, trailing zeros trimmed; scientific notation outside
/// [1e-4, 1e6).
pub(crate) fn format_coefficient(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && !(1e-4..1e6).contains(&a) {
        let s = format!("{x:.5e}");
        let (mant, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mant = mant.trim_end_matches('0').trim_end_matches('.');
        return format!("{mant}e{exp}");
    }
    let digits = if a == 0.0 {
        0
    } else {
        (5 - a.log10().floor() as i32).max(0) as usize
    };
    let s = format!("{x:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

impl<const N: usize> SerialChain<N> {
    /// Numerical base parameters of this chain (see the module docs of the method and
    /// [`BaseOptions`] for the tolerance). Depends only on the geometry, gravity
    /// direction and friction model, not on the inertial values.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a bad tolerance,
    /// [`PrrrpError::TooFewSamples`] if `samples`·N < number of parameters.
    pub fn base_parameters(&self, opts: &BaseOptions) -> Result<BaseParameters> {
        analyse(&self.view().recursive(), opts)
    }

    /// The base observation matrix W_b (N·samples × b): the base columns of
    /// [`SerialChain::observation_matrix`], so that stacked τ = W_b·β.
    ///
    /// # Errors
    /// As [`SerialChain::observation_matrix`], and [`PrrrpError::ShapeMismatch`] if
    /// `base` was computed for another chain layout.
    pub fn base_observation_matrix(
        &self,
        base: &BaseParameters,
        q: &[nalgebra::SVector<f64, N>],
        qd: &[nalgebra::SVector<f64, N>],
        qdd: &[nalgebra::SVector<f64, N>],
    ) -> Result<Mat<f64>> {
        base.check_layout(N, &self.layout())?;
        base.select_columns(&self.observation_matrix(q, qd, qdd)?)
    }
}

impl DynChain {
    /// Numerical base parameters of this chain; see [`SerialChain::base_parameters`].
    ///
    /// # Errors
    /// As [`SerialChain::base_parameters`].
    pub fn base_parameters(&self, opts: &BaseOptions) -> Result<BaseParameters> {
        analyse(&self.view().recursive(), opts)
    }

    /// The base observation matrix W_b from flat row-major (samples × n) inputs.
    ///
    /// # Errors
    /// As [`DynChain::observation_matrix`], and [`PrrrpError::ShapeMismatch`] if `base`
    /// was computed for another chain layout.
    pub fn base_observation_matrix(
        &self,
        base: &BaseParameters,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<Mat<f64>> {
        base.check_layout(self.dof(), &self.layout())?;
        base.select_columns(&self.observation_matrix(q, qd, qdd)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficients_read_well() {
        assert_eq!(format_coefficient(0.2), "0.2");
        assert_eq!(format_coefficient(0.4318), "0.4318");
        assert_eq!(format_coefficient(0.18645124), "0.186451");
        assert_eq!(format_coefficient(12.5), "12.5");
        assert_eq!(format_coefficient(2.0), "2");
        assert_eq!(format_coefficient(3.2e-6), "3.2e-6");
        let names: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        assert_eq!(
            combination(&names, [1.0, -1.0, 0.25].into_iter()),
            "a - b + 0.25*c"
        );
        assert_eq!(
            combination(&names, [0.0, -2.0, 1.0].into_iter()),
            "-2*b + c"
        );
    }
}
