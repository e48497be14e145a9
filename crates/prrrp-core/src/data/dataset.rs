//! The validated identification data set: time stamps and per-sample q, q̇, q̈, τ, one
//! type over the joint count's nalgebra dimension — [`Dataset`] for the paper's 5-joint
//! arm (`Const<5>`), [`DynDataset`] for a robot whose joint count is known at run time
//! (`Dyn`).

use std::ops::Range;

use nalgebra::{Const, Dim, Dyn, SVector};

use crate::bounds::MAX_MAGNITUDE;
use crate::error::{PrrrpError, Result};
use crate::estimators::Samples;
use crate::models::chain::{FRICTION_PARAMETER_NAMES, LINK_PARAMS};
use crate::models::prrrp::types::{Vec5, NDOF, NPARAM};

/// Time stamps plus joint positions, velocities, accelerations and generalised forces of
/// a robot with n joints, checked on creation; `N` is n as a nalgebra dimension
/// (`Const<5>` for the paper's arm, [`Dataset`]; `Dyn` for any robot, [`DynDataset`]).
///
/// The joint columns are stored flat and row-major, numpy's layout for a
/// (samples × n) array: sample k of `q` occupies `q()[k·n..(k+1)·n]`, also returned by
/// [`DatasetOf::q_row`]. With a compile-time n, [`DatasetOf::samples`] reads the same
/// memory as n-vectors (no copy), the input of the fixed-size estimators.
///
/// Invariants (checked by every constructor, so estimators can rely on them):
/// - n ≥ 1 and every joint column holds n·N values for the N time stamps;
/// - N ≥ the minimum sample count given at construction (at least 1):
///   [`Dataset::MIN_SAMPLES`] for the paper's arm, by default
///   [`DynDataset::DEFAULT_MIN_SAMPLES`] otherwise;
/// - every value is finite;
/// - time stamps are strictly increasing.
///
/// Units: t in s; q in m (prismatic) or rad (revolute), q̇ in m/s or rad/s, q̈ in m/s² or
/// rad/s², τ in N or N·m, in the robot's joint order.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetOf<N: Dim> {
    n: N,
    min_samples: usize,
    // `cols.dof` is `n.value()`: the columns travel as one value (into_parts, with_dim).
    cols: DatasetParts,
}

/// The paper's arm: joint order [d1, θ2, θ3, θ4, d5], q in m and rad, q̇ in m/s and
/// rad/s, q̈ in m/s² and rad/s², τ = [F1, τ2, τ3, τ4, F5] in N and N·m.
///
/// ```
/// use prrrp_core::{Dataset, Vec5};
///
/// let n = 10;
/// let t: Vec<f64> = (0..n).map(|k| 0.02 * k as f64).collect();
/// let z = vec![Vec5::zeros(); n];
/// let data = Dataset::new(t, z.clone(), z.clone(), z.clone(), z)?;
/// assert_eq!((data.len(), data.dof()), (n, 5));
/// assert_eq!(data.samples().q()[3], Vec5::zeros());
///
/// // Too few samples is a typed error, not a panic.
/// let short = Dataset::new(vec![0.0], vec![Vec5::zeros()], vec![Vec5::zeros()],
///                          vec![Vec5::zeros()], vec![Vec5::zeros()]);
/// assert!(short.is_err());
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
pub type Dataset = DatasetOf<Const<NDOF>>;

/// A robot with a run-time number of joints.
///
/// ```
/// use prrrp_core::DynDataset;
///
/// let (n, rows) = (7, 20);
/// let t: Vec<f64> = (0..rows).map(|k| 0.001 * k as f64).collect();
/// let z = vec![0.0; n * rows];
/// let data = DynDataset::new(n, t, z.clone(), z.clone(), z.clone(), z)?;
/// assert_eq!((data.len(), data.dof()), (rows, n));
/// assert_eq!(data.q_row(3).len(), n);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
pub type DynDataset = DatasetOf<Dyn>;

/// The columns of a data set, moved out of it by [`DatasetOf::into_parts`].
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetParts {
    /// Number of joints n.
    pub dof: usize,
    /// Time stamps, s.
    pub t: Vec<f64>,
    /// Joint positions (m, rad), row-major samples × n.
    pub q: Vec<f64>,
    /// Joint velocities (m/s, rad/s), row-major samples × n.
    pub qd: Vec<f64>,
    /// Joint accelerations (m/s², rad/s²), row-major samples × n.
    pub qdd: Vec<f64>,
    /// Generalised forces (N, N·m), row-major samples × n.
    pub tau: Vec<f64>,
}

impl<N: Dim> DatasetOf<N> {
    /// Builds a data set of `n` joints from flat row-major columns (`t` has N values,
    /// each joint column n·N), requiring at least `min_samples` samples (0 counts as 1:
    /// a data set always has a first and a last time stamp). [`DatasetOf::slice`] keeps
    /// this minimum.
    ///
    /// # Errors
    /// - [`PrrrpError::InvalidParameter`] if `n` is 0;
    /// - [`PrrrpError::ShapeMismatch`] naming the first column (q, qd, qdd, tau) that is
    ///   not n·N long;
    /// - [`PrrrpError::TooFewSamples`] if N < `min_samples`;
    /// - [`PrrrpError::NonFinite`] naming the column and joint (e.g. `"qdd[2] (joint 3)"`)
    ///   and the first row holding NaN or ±∞ (columns checked in the order t, q, qd, qdd,
    ///   tau);
    /// - [`PrrrpError::InvalidParameter`] naming the first value at or above
    ///   [`MAX_MAGNITUDE`] (1e100) in magnitude, with its column, joint and row;
    /// - [`PrrrpError::NonIncreasingTime`] with the first row whose time stamp is not
    ///   larger than the previous one.
    pub fn from_columns(
        n: N,
        min_samples: usize,
        t: Vec<f64>,
        q: Vec<f64>,
        qd: Vec<f64>,
        qdd: Vec<f64>,
        tau: Vec<f64>,
    ) -> Result<Self> {
        let dof = n.value();
        let cols = DatasetParts {
            dof,
            t,
            q,
            qd,
            qdd,
            tau,
        };
        let d = Self {
            n,
            min_samples: min_samples.max(1),
            cols,
        };
        d.validate()?;
        Ok(d)
    }

    /// The one implementation of the invariants, in the documented order.
    fn validate(&self) -> Result<()> {
        let rows = self.cols.t.len();
        check_dof(self.dof())?;
        for (name, col) in self.joint_columns() {
            check_flat_len(name, col.len(), self.n, rows)?;
        }
        if rows < self.min_samples {
            return Err(PrrrpError::TooFewSamples {
                needed: self.min_samples,
                got: rows,
            });
        }
        if let Some(row) = self.cols.t.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: "t".into(),
                row: Some(row),
            });
        }
        for (name, col) in self.joint_columns() {
            check_finite_flat(name, col, self.dof())?;
        }
        // As the log readers and the online identifier refuse them: a q of 1e300 overflowed
        // W and read as "'QR factor of W' has a NaN".
        if let Some(row) = self.cols.t.iter().position(|x| x.abs() >= MAX_MAGNITUDE) {
            return Err(too_large(format!("t at row {row}"), self.cols.t[row]));
        }
        for (name, col) in self.joint_columns() {
            if let Some(i) = col.iter().position(|x| x.abs() >= MAX_MAGNITUDE) {
                let n = self.dof().max(1);
                let (row, joint) = (i / n, i % n);
                let what = format!("{name}[{joint}] (joint {}) at row {row}", joint + 1);
                return Err(too_large(what, col[i]));
            }
        }
        if let Some(k) = self.cols.t.windows(2).position(|w| w[1] <= w[0]) {
            return Err(PrrrpError::NonIncreasingTime { row: k + 1 });
        }
        Ok(())
    }

    fn joint_columns(&self) -> [(&'static str, &[f64]); 4] {
        [
            ("q", &self.cols.q),
            ("qd", &self.cols.qd),
            ("qdd", &self.cols.qdd),
            ("tau", &self.cols.tau),
        ]
    }

    /// Number of samples N (at least [`DatasetOf::min_samples`]).
    pub fn len(&self) -> usize {
        self.cols.t.len()
    }

    /// Always false: a valid data set has at least one sample.
    pub fn is_empty(&self) -> bool {
        self.cols.t.is_empty()
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.n.value()
    }

    /// The smallest sample count this data set was built to require (kept by
    /// [`DatasetOf::slice`]).
    pub fn min_samples(&self) -> usize {
        self.min_samples
    }

    /// Time span `t[N−1] − t[0]`, s.
    pub fn duration(&self) -> f64 {
        match (self.cols.t.first(), self.cols.t.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    /// Time stamps, s (strictly increasing).
    pub fn t(&self) -> &[f64] {
        &self.cols.t
    }

    /// Joint positions (m, rad), flat row-major N × n.
    pub fn q(&self) -> &[f64] {
        &self.cols.q
    }

    /// Joint velocities (m/s, rad/s), flat row-major N × n.
    pub fn qd(&self) -> &[f64] {
        &self.cols.qd
    }

    /// Joint accelerations (m/s², rad/s²), flat row-major N × n.
    pub fn qdd(&self) -> &[f64] {
        &self.cols.qdd
    }

    /// Generalised forces (N, N·m), flat row-major N × n.
    pub fn tau(&self) -> &[f64] {
        &self.cols.tau
    }

    /// Joint positions of sample `k` (n values, m or rad).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn q_row(&self, k: usize) -> &[f64] {
        self.row(&self.cols.q, k)
    }

    /// Joint velocities of sample `k` (n values, m/s or rad/s).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn qd_row(&self, k: usize) -> &[f64] {
        self.row(&self.cols.qd, k)
    }

    /// Joint accelerations of sample `k` (n values, m/s² or rad/s²).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn qdd_row(&self, k: usize) -> &[f64] {
        self.row(&self.cols.qdd, k)
    }

    /// Generalised forces of sample `k` (n values, N or N·m).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn tau_row(&self, k: usize) -> &[f64] {
        self.row(&self.cols.tau, k)
    }

    #[inline]
    fn row<'a>(&self, col: &'a [f64], k: usize) -> &'a [f64] {
        let n = self.dof();
        &col[k * n..(k + 1) * n]
    }

    /// The samples in `range` (indices) as a new validated data set with the same
    /// minimum sample count, e.g. to split estimation and validation parts.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if the range is out of bounds or reversed,
    /// [`PrrrpError::TooFewSamples`] if it holds fewer than [`DatasetOf::min_samples`].
    pub fn slice(&self, range: Range<usize>) -> Result<Self> {
        if range.start > range.end || range.end > self.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "range".into(),
                expected: format!("a range within 0..{}", self.len()),
                got: format!("{}..{}", range.start, range.end),
            });
        }
        let n = self.dof();
        let flat = range.start * n..range.end * n;
        Self::from_columns(
            self.n,
            self.min_samples,
            self.cols.t[range].to_vec(),
            self.cols.q[flat.clone()].to_vec(),
            self.cols.qd[flat.clone()].to_vec(),
            self.cols.qdd[flat.clone()].to_vec(),
            self.cols.tau[flat].to_vec(),
        )
    }

    /// The same samples with the generalised forces replaced by `tau` (N, N·m; row-major
    /// samples × n, e.g. torques computed from measured currents), with the same minimum
    /// sample count.
    ///
    /// # Errors
    /// As [`DatasetOf::from_columns`]: [`PrrrpError::ShapeMismatch`] if `tau` is not
    /// samples × n long, [`PrrrpError::NonFinite`] for NaN or ±∞ in it.
    pub fn with_tau(&self, tau: Vec<f64>) -> Result<Self> {
        Self::from_columns(
            self.n,
            self.min_samples,
            self.cols.t.clone(),
            self.cols.q.clone(),
            self.cols.qd.clone(),
            self.cols.qdd.clone(),
            tau,
        )
    }

    /// Moves the columns out.
    pub fn into_parts(self) -> DatasetParts {
        self.cols
    }

    /// The same columns and minimum under another dimension type `m` (same n), e.g.
    /// between [`Dataset`] and [`DynDataset`]: the checks that cannot fail are not
    /// repeated.
    fn with_dim<M: Dim>(self, m: M) -> DatasetOf<M> {
        debug_assert_eq!(m.value(), self.dof());
        DatasetOf {
            n: m,
            min_samples: self.min_samples,
            cols: self.cols,
        }
    }
}

impl<const D: usize> DatasetOf<Const<D>> {
    /// A borrowed view of the samples as D-vectors, the input of every fixed-size
    /// estimator ([`crate::Estimator::run`], [`crate::least_squares`]); it reads the
    /// data set's own memory (no copy).
    pub fn samples(&self) -> Samples<'_, D> {
        // A column holds D·N values (invariant) and an SVector<f64, D> is D contiguous
        // f64s (nalgebra's Pod), so the cast cannot fail.
        fn rows<const D: usize>(c: &[f64]) -> &[SVector<f64, D>] {
            bytemuck::cast_slice(c)
        }
        Samples::new(
            rows(&self.cols.q),
            rows(&self.cols.qd),
            rows(&self.cols.qdd),
            rows(&self.cols.tau),
        )
        .expect("a data set's columns have equal lengths by construction")
    }
}

impl Dataset {
    /// Smallest accepted number of samples: one per base parameter (8).
    ///
    /// Each sample gives two equations for the vertical parameters (λ1, λ8) and three for
    /// the six planar ones (λ2..λ7), so two samples can at best determine λ exactly and
    /// leave no residual; asking for eight keeps every block over-determined, which the
    /// least-squares noise estimate σ² = ‖τ − Wλ‖²/(rows − params) needs.
    pub const MIN_SAMPLES: usize = NPARAM;

    /// Builds a data set from per-sample columns, validating them.
    ///
    /// # Errors
    /// - [`PrrrpError::ShapeMismatch`] naming the first column whose length differs from
    ///   `t`'s;
    /// - otherwise as [`Dataset::from_row_major`] (too few samples, NaN or ±∞, time
    ///   stamps not increasing).
    pub fn new(
        t: Vec<f64>,
        q: Vec<Vec5>,
        qd: Vec<Vec5>,
        qdd: Vec<Vec5>,
        tau: Vec<Vec5>,
    ) -> Result<Self> {
        let n = t.len();
        for (name, col) in [("q", &q), ("qd", &qd), ("qdd", &qdd), ("tau", &tau)] {
            if col.len() != n {
                return Err(PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("{n} samples (as t)"),
                    got: format!("{} samples", col.len()),
                });
            }
        }
        let flat = |c: Vec<Vec5>| -> Vec<f64> { bytemuck::cast_slice(&c).to_vec() };
        Self::from_columns(
            Const,
            Self::MIN_SAMPLES,
            t,
            flat(q),
            flat(qd),
            flat(qdd),
            flat(tau),
        )
    }

    /// Builds a data set from flat row-major arrays, as numpy or a CSV reader delivers
    /// them: `t` has N values and each of `q`, `qd`, `qdd`, `tau` has 5·N values, sample k
    /// occupying entries 5k..5k+5 in joint order [d1, θ2, θ3, θ4, d5].
    ///
    /// # Errors
    /// As [`DatasetOf::from_columns`] with n = 5 and [`Dataset::MIN_SAMPLES`].
    pub fn from_row_major(
        t: &[f64],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &[f64],
    ) -> Result<Self> {
        Self::from_columns(
            Const,
            Self::MIN_SAMPLES,
            t.to_vec(),
            q.to_vec(),
            qd.to_vec(),
            qdd.to_vec(),
            tau.to_vec(),
        )
    }
}

impl DynDataset {
    /// Default smallest number of samples: 14 = 10 inertial + 3 friction parameters per
    /// joint ([`LINK_PARAMS`] + `FRICTION_PARAMETER_NAMES.len()`) plus one.
    ///
    /// A chain of n joints has at most 13·n base parameters and each sample gives n
    /// equations, so 14 samples keep the stacked system over-determined for any chain,
    /// which the least-squares noise estimate σ² = ‖τ − Wλ‖²/(rows − params) needs.
    pub const DEFAULT_MIN_SAMPLES: usize = LINK_PARAMS + FRICTION_PARAMETER_NAMES.len() + 1;

    /// [`PrrrpError::ShapeMismatch`] unless the data have the `n` joints of what they are
    /// used with (`whose` names it in the message, e.g. "the robot's").
    pub(crate) fn check_dof(&self, n: usize, whose: &str) -> Result<()> {
        if self.dof() != n {
            return Err(PrrrpError::ShapeMismatch {
                what: "data".into(),
                expected: format!("{n} joints ({whose})"),
                got: format!("{} joints", self.dof()),
            });
        }
        Ok(())
    }

    /// Builds a data set of `n` joints from flat row-major columns, requiring at least
    /// [`DynDataset::DEFAULT_MIN_SAMPLES`] samples.
    ///
    /// # Errors
    /// As [`DatasetOf::from_columns`].
    pub fn new(
        n: usize,
        t: Vec<f64>,
        q: Vec<f64>,
        qd: Vec<f64>,
        qdd: Vec<f64>,
        tau: Vec<f64>,
    ) -> Result<Self> {
        Self::with_min_samples(n, Self::DEFAULT_MIN_SAMPLES, t, q, qd, qdd, tau)
    }

    /// Builds a data set of `n` joints from flat row-major columns, requiring at least
    /// `min_samples` samples.
    ///
    /// # Errors
    /// As [`DatasetOf::from_columns`].
    pub fn with_min_samples(
        n: usize,
        min_samples: usize,
        t: Vec<f64>,
        q: Vec<f64>,
        qd: Vec<f64>,
        qdd: Vec<f64>,
        tau: Vec<f64>,
    ) -> Result<Self> {
        Self::from_columns(Dyn(n), min_samples, t, q, qd, qdd, tau)
    }
}

/// n = 5 data set of a PRRRP data set, keeping its minimum of [`Dataset::MIN_SAMPLES`].
impl From<&Dataset> for DynDataset {
    fn from(d: &Dataset) -> Self {
        d.clone().with_dim(Dyn(NDOF))
    }
}

impl From<Dataset> for DynDataset {
    fn from(d: Dataset) -> Self {
        d.with_dim(Dyn(NDOF))
    }
}

/// Back to the PRRRP's fixed-size form.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] if the data set does not have 5 joints;
/// [`PrrrpError::TooFewSamples`] if it has fewer than [`Dataset::MIN_SAMPLES`] samples.
impl TryFrom<&DynDataset> for Dataset {
    type Error = PrrrpError;

    fn try_from(d: &DynDataset) -> Result<Self> {
        Self::try_from(d.clone())
    }
}

impl TryFrom<DynDataset> for Dataset {
    type Error = PrrrpError;

    fn try_from(d: DynDataset) -> Result<Self> {
        if d.dof() != NDOF {
            return Err(PrrrpError::ShapeMismatch {
                what: "dataset joints".into(),
                expected: format!("{NDOF} joints (the PRRRP arm)"),
                got: format!("{} joints", d.dof()),
            });
        }
        if d.len() < Self::MIN_SAMPLES {
            return Err(PrrrpError::TooFewSamples {
                needed: Self::MIN_SAMPLES,
                got: d.len(),
            });
        }
        let mut d = d.with_dim(Const::<NDOF>);
        d.min_samples = Self::MIN_SAMPLES;
        Ok(d)
    }
}

/// n must be at least 1: a robot has joints.
pub(crate) fn check_dof(n: usize) -> Result<()> {
    if n == 0 {
        return Err(PrrrpError::InvalidParameter {
            field: "n".into(),
            value: 0.0,
            reason: "the number of joints must be at least 1",
        });
    }
    Ok(())
}

/// A flat row-major column must hold n values per time stamp; n·rows is computed without
/// overflow so that absurd sizes are an error, not a wrapped length. A compile-time n
/// (the paper's arm) states the product, a run-time one its factors.
pub(crate) fn check_flat_len<N: Dim>(name: &str, len: usize, n: N, rows: usize) -> Result<()> {
    let (n, want) = (n.value(), rows.checked_mul(n.value()));
    if want != Some(len) {
        let count = match (N::try_to_usize(), want) {
            (Some(_), Some(want)) => want.to_string(),
            _ => format!("{n}·{rows}"),
        };
        return Err(PrrrpError::ShapeMismatch {
            what: name.into(),
            expected: format!(
                "{count} values (row-major, {n} joints per sample, {rows} samples as t)"
            ),
            got: format!("{len} values"),
        });
    }
    Ok(())
}

/// The error of a value at or above [`MAX_MAGNITUDE`] in a data set's column `what`.
fn too_large(what: String, v: f64) -> PrrrpError {
    PrrrpError::InvalidParameter {
        field: what,
        value: v,
        reason: "is at or above MAX_MAGNITUDE (1e100) in magnitude: no robot log holds it; \
                 check the data's units (s, rad, m, N·m, N)",
    }
}

/// First non-finite value of a flat row-major column of `n` values per row, named
/// `"col[j] (joint j+1)"` with its row.
pub(crate) fn check_finite_flat(name: &str, col: &[f64], n: usize) -> Result<()> {
    if let Some(i) = col.iter().position(|x| !x.is_finite()) {
        let n = n.max(1);
        let (row, joint) = (i / n, i % n);
        return Err(PrrrpError::NonFinite {
            what: format!("{name}[{joint}] (joint {})", joint + 1),
            row: Some(row),
        });
    }
    Ok(())
}
