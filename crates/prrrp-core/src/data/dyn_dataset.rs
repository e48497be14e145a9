//! A validated identification data set for a robot with a run-time number of joints.

use std::ops::Range;

use crate::data::dataset::{check_finite_values, check_series, Dataset};
use crate::error::{PrrrpError, Result};
use crate::models::chain::{FRICTION_PARAMETER_NAMES, LINK_PARAMS};
use crate::models::prrrp::types::{Vec5, NDOF};

/// Time stamps plus joint positions, velocities, accelerations and generalised forces of
/// a robot with `n` joints (known at run time), checked on creation.
///
/// The joint columns are stored flat and row-major, numpy's layout for a
/// (samples × n) array: sample k of `q` occupies `q()[k·n..(k+1)·n]`, also returned by
/// [`DynDataset::q_row`].
///
/// Invariants (checked by every constructor, so estimators can rely on them):
/// - n ≥ 1 and every joint column holds n·N values for the N time stamps;
/// - N ≥ the minimum sample count given at construction (at least 1), by default
///   [`DynDataset::DEFAULT_MIN_SAMPLES`];
/// - every value is finite;
/// - time stamps are strictly increasing.
///
/// Units: t in s; q in m (prismatic) or rad (revolute), q̇ in m/s or rad/s, q̈ in m/s² or
/// rad/s², τ in N or N·m, in the robot's joint order.
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
#[derive(Debug, Clone, PartialEq)]
pub struct DynDataset {
    n: usize,
    min_samples: usize,
    t: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
}

/// The columns of a [`DynDataset`], moved out of it by [`DynDataset::into_parts`].
#[derive(Debug, Clone, PartialEq)]
pub struct DynDatasetParts {
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

impl DynDataset {
    /// Default smallest number of samples: 14 = 10 inertial + 3 friction parameters per
    /// joint ([`LINK_PARAMS`] + `FRICTION_PARAMETER_NAMES.len()`) plus one.
    ///
    /// A chain of n joints has at most 13·n base parameters and each sample gives n
    /// equations, so 14 samples keep the stacked system over-determined for any chain,
    /// which the least-squares noise estimate σ² = ‖τ − Wλ‖²/(rows − params) needs.
    pub const DEFAULT_MIN_SAMPLES: usize = LINK_PARAMS + FRICTION_PARAMETER_NAMES.len() + 1;

    /// Builds a data set of `n` joints from flat row-major columns, requiring at least
    /// [`DynDataset::DEFAULT_MIN_SAMPLES`] samples.
    ///
    /// # Errors
    /// As [`DynDataset::with_min_samples`].
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

    /// Builds a data set of `n` joints from flat row-major columns (`t` has N values,
    /// each joint column n·N), requiring at least `min_samples` samples (0 counts as 1:
    /// a data set always has a first and a last time stamp). [`DynDataset::slice`] keeps
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
    /// - [`PrrrpError::NonIncreasingTime`] with the first row whose time stamp is not
    ///   larger than the previous one.
    pub fn with_min_samples(
        n: usize,
        min_samples: usize,
        t: Vec<f64>,
        q: Vec<f64>,
        qd: Vec<f64>,
        qdd: Vec<f64>,
        tau: Vec<f64>,
    ) -> Result<Self> {
        let d = Self {
            n,
            min_samples: min_samples.max(1),
            t,
            q,
            qd,
            qdd,
            tau,
        };
        d.validate()?;
        Ok(d)
    }

    fn validate(&self) -> Result<()> {
        let n = self.n;
        let rows = self.t.len();
        check_dof(n)?;
        for (name, col) in self.joint_columns() {
            check_flat_len(name, col.len(), n, rows)?;
        }
        let columns = self.joint_columns().map(|(name, col)| (name, col.iter()));
        check_series(&self.t, self.min_samples, n, columns)
    }

    fn joint_columns(&self) -> [(&'static str, &[f64]); 4] {
        [
            ("q", &self.q),
            ("qd", &self.qd),
            ("qdd", &self.qdd),
            ("tau", &self.tau),
        ]
    }

    /// Number of samples N (at least [`DynDataset::min_samples`]).
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Always false: a valid data set has at least one sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.n
    }

    /// The smallest sample count this data set was built to require (kept by
    /// [`DynDataset::slice`]).
    pub fn min_samples(&self) -> usize {
        self.min_samples
    }

    /// Time span `t[N−1] − t[0]`, s.
    pub fn duration(&self) -> f64 {
        match (self.t.first(), self.t.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }

    /// Time stamps, s (strictly increasing).
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Joint positions (m, rad), flat row-major N × n.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Joint velocities (m/s, rad/s), flat row-major N × n.
    pub fn qd(&self) -> &[f64] {
        &self.qd
    }

    /// Joint accelerations (m/s², rad/s²), flat row-major N × n.
    pub fn qdd(&self) -> &[f64] {
        &self.qdd
    }

    /// Generalised forces (N, N·m), flat row-major N × n.
    pub fn tau(&self) -> &[f64] {
        &self.tau
    }

    /// Joint positions of sample `k` (n values, m or rad).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn q_row(&self, k: usize) -> &[f64] {
        &self.q[k * self.n..(k + 1) * self.n]
    }

    /// Joint velocities of sample `k` (n values, m/s or rad/s).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn qd_row(&self, k: usize) -> &[f64] {
        &self.qd[k * self.n..(k + 1) * self.n]
    }

    /// Joint accelerations of sample `k` (n values, m/s² or rad/s²).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn qdd_row(&self, k: usize) -> &[f64] {
        &self.qdd[k * self.n..(k + 1) * self.n]
    }

    /// Generalised forces of sample `k` (n values, N or N·m).
    ///
    /// # Panics
    /// If `k >= self.len()`, as slice indexing does.
    pub fn tau_row(&self, k: usize) -> &[f64] {
        &self.tau[k * self.n..(k + 1) * self.n]
    }

    /// The samples in `range` (indices) as a new validated data set with the same
    /// minimum sample count, e.g. to split estimation and validation parts.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if the range is out of bounds or reversed,
    /// [`PrrrpError::TooFewSamples`] if it holds fewer than [`DynDataset::min_samples`].
    pub fn slice(&self, range: Range<usize>) -> Result<Self> {
        if range.start > range.end || range.end > self.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "range".into(),
                expected: format!("a range within 0..{}", self.len()),
                got: format!("{}..{}", range.start, range.end),
            });
        }
        let flat = range.start * self.n..range.end * self.n;
        Self::with_min_samples(
            self.n,
            self.min_samples,
            self.t[range].to_vec(),
            self.q[flat.clone()].to_vec(),
            self.qd[flat.clone()].to_vec(),
            self.qdd[flat.clone()].to_vec(),
            self.tau[flat].to_vec(),
        )
    }

    /// Moves the columns out.
    pub fn into_parts(self) -> DynDatasetParts {
        DynDatasetParts {
            dof: self.n,
            t: self.t,
            q: self.q,
            qd: self.qd,
            qdd: self.qdd,
            tau: self.tau,
        }
    }
}

/// n = 5 flat copy of a PRRRP data set, keeping its minimum of [`Dataset::MIN_SAMPLES`].
impl From<&Dataset> for DynDataset {
    fn from(d: &Dataset) -> Self {
        let flat = |c: &[Vec5]| -> Vec<f64> { c.iter().flat_map(|v| v.iter().copied()).collect() };
        // A Dataset's invariants are a DynDataset's with n = 5 and its own minimum, so no
        // check can fail and none is repeated.
        Self {
            n: NDOF,
            min_samples: Dataset::MIN_SAMPLES,
            t: d.t().to_vec(),
            q: flat(d.q()),
            qd: flat(d.qd()),
            qdd: flat(d.qdd()),
            tau: flat(d.tau()),
        }
    }
}

impl From<Dataset> for DynDataset {
    fn from(d: Dataset) -> Self {
        Self::from(&d)
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
        if d.n != NDOF {
            return Err(PrrrpError::ShapeMismatch {
                what: "dataset joints".into(),
                expected: format!("{NDOF} joints (the PRRRP arm)"),
                got: format!("{} joints", d.n),
            });
        }
        Dataset::from_row_major(&d.t, &d.q, &d.qd, &d.qdd, &d.tau)
    }
}

impl TryFrom<DynDataset> for Dataset {
    type Error = PrrrpError;

    fn try_from(d: DynDataset) -> Result<Self> {
        Self::try_from(&d)
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
/// overflow so that absurd sizes are an error, not a wrapped length.
pub(crate) fn check_flat_len(name: &str, len: usize, n: usize, rows: usize) -> Result<()> {
    if rows.checked_mul(n) != Some(len) {
        return Err(PrrrpError::ShapeMismatch {
            what: name.into(),
            expected: format!(
                "{n}·{rows} values (row-major, {n} joints per sample, {rows} samples as t)"
            ),
            got: format!("{len} values"),
        });
    }
    Ok(())
}

/// First non-finite value of a flat row-major column, named `"col[j] (joint j+1)"` with
/// its row.
pub(crate) fn check_finite_flat(name: &str, col: &[f64], n: usize) -> Result<()> {
    check_finite_values(name, col.iter(), n)
}
