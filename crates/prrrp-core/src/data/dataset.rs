//! A validated identification data set: time stamps and per-sample q, q̇, q̈, τ.

use crate::error::{PrrrpError, Result};
use crate::models::prrrp::types::{Vec5, NDOF, NPARAM};

/// Time stamps plus joint positions, velocities, accelerations and generalised forces,
/// one [`Vec5`] per sample, checked on creation.
///
/// Invariants (checked by every constructor, so estimators can rely on them):
/// - all five columns have the same length N ≥ [`Dataset::MIN_SAMPLES`];
/// - every value is finite;
/// - time stamps are strictly increasing.
///
/// Units: t in s; q in m/rad, q̇ in m/s, rad/s; q̈ in m/s², rad/s²; τ in N, N·m (joint
/// order [d1, θ2, θ3, θ4, d5]).
///
/// ```
/// use prrrp_core::{Dataset, Vec5};
///
/// let n = 10;
/// let t: Vec<f64> = (0..n).map(|k| 0.02 * k as f64).collect();
/// let z = vec![Vec5::zeros(); n];
/// let data = Dataset::new(t, z.clone(), z.clone(), z.clone(), z)?;
/// assert_eq!(data.len(), n);
///
/// // Too few samples is a typed error, not a panic.
/// let short = Dataset::new(vec![0.0], vec![Vec5::zeros()], vec![Vec5::zeros()],
///                          vec![Vec5::zeros()], vec![Vec5::zeros()]);
/// assert!(short.is_err());
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    t: Vec<f64>,
    q: Vec<Vec5>,
    qd: Vec<Vec5>,
    qdd: Vec<Vec5>,
    tau: Vec<Vec5>,
}

/// The checks of a data set after its shapes, in this order: at least `min` samples (time
/// stamps `t`), finite time stamps, finite values of each joint column (row-major, `n`
/// per sample; the first bad value named `"col[j] (joint j+1)"` with its row), strictly
/// increasing time stamps.
pub(crate) fn check_series<'a, I: Iterator<Item = &'a f64>>(
    t: &[f64],
    min: usize,
    n: usize,
    columns: [(&str, I); 4],
) -> Result<()> {
    if t.len() < min {
        return Err(PrrrpError::TooFewSamples {
            needed: min,
            got: t.len(),
        });
    }
    if let Some(row) = t.iter().position(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "t".into(),
            row: Some(row),
        });
    }
    for (name, col) in columns {
        check_finite_values(name, col, n)?;
    }
    if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(PrrrpError::NonIncreasingTime { row: k + 1 });
    }
    Ok(())
}

/// The first non-finite value of a row-major column of `n` values per row, named
/// `"name[j] (joint j+1)"` with its row.
pub(crate) fn check_finite_values<'a>(
    name: &str,
    mut values: impl Iterator<Item = &'a f64>,
    n: usize,
) -> Result<()> {
    if let Some(i) = values.position(|x| !x.is_finite()) {
        let n = n.max(1);
        let (row, joint) = (i / n, i % n);
        return Err(PrrrpError::NonFinite {
            what: format!("{name}[{joint}] (joint {})", joint + 1),
            row: Some(row),
        });
    }
    Ok(())
}

/// The columns of a [`Dataset`], moved out of it by [`Dataset::into_parts`].
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetParts {
    /// Time stamps, s.
    pub t: Vec<f64>,
    /// Joint positions (m, rad).
    pub q: Vec<Vec5>,
    /// Joint velocities (m/s, rad/s).
    pub qd: Vec<Vec5>,
    /// Joint accelerations (m/s², rad/s²).
    pub qdd: Vec<Vec5>,
    /// Generalised forces (N, N·m).
    pub tau: Vec<Vec5>,
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
    /// - [`PrrrpError::TooFewSamples`] if there are fewer than [`Dataset::MIN_SAMPLES`];
    /// - [`PrrrpError::NonFinite`] naming the column and joint (e.g. `"qdd[2] (joint 3)"`)
    ///   and the first row holding NaN or ±∞ (columns checked in the order t, q, qd, qdd,
    ///   tau);
    /// - [`PrrrpError::NonIncreasingTime`] with the first row whose time stamp is not
    ///   larger than the previous one.
    pub fn new(
        t: Vec<f64>,
        q: Vec<Vec5>,
        qd: Vec<Vec5>,
        qdd: Vec<Vec5>,
        tau: Vec<Vec5>,
    ) -> Result<Self> {
        let d = Self { t, q, qd, qdd, tau };
        d.validate()?;
        Ok(d)
    }

    /// Builds a data set from flat row-major arrays, as numpy or a CSV reader delivers
    /// them: `t` has N values and each of `q`, `qd`, `qdd`, `tau` has 5·N values, sample k
    /// occupying entries 5k..5k+5 in joint order [d1, θ2, θ3, θ4, d5].
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if an array is not 5·N long; otherwise as
    /// [`Dataset::new`].
    pub fn from_row_major(
        t: &[f64],
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &[f64],
    ) -> Result<Self> {
        let n = t.len();
        let rows = |name: &str, flat: &[f64]| -> Result<Vec<Vec5>> {
            if flat.len() != NDOF * n {
                return Err(PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!(
                        "{} values (row-major, {NDOF} joints per sample, {n} samples as t)",
                        NDOF * n
                    ),
                    got: format!("{} values", flat.len()),
                });
            }
            Ok(flat.chunks_exact(NDOF).map(Vec5::from_row_slice).collect())
        };
        Self::new(
            t.to_vec(),
            rows("q", q)?,
            rows("qd", qd)?,
            rows("qdd", qdd)?,
            rows("tau", tau)?,
        )
    }

    fn validate(&self) -> Result<()> {
        let n = self.t.len();
        for (name, col) in self.joint_columns() {
            if col.len() != n {
                return Err(PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("{n} samples (as t)"),
                    got: format!("{} samples", col.len()),
                });
            }
        }
        let columns = self
            .joint_columns()
            .map(|(name, col)| (name, col.iter().flat_map(|v| v.iter())));
        check_series(&self.t, Self::MIN_SAMPLES, NDOF, columns)
    }

    fn joint_columns(&self) -> [(&'static str, &[Vec5]); 4] {
        [
            ("q", &self.q),
            ("qd", &self.qd),
            ("qdd", &self.qdd),
            ("tau", &self.tau),
        ]
    }

    /// Number of samples N (at least [`Dataset::MIN_SAMPLES`]).
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Always false: a valid data set has at least [`Dataset::MIN_SAMPLES`] samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Time stamps, s (strictly increasing).
    pub fn t(&self) -> &[f64] {
        &self.t
    }

    /// Joint positions [d1, θ2, θ3, θ4, d5] (m, rad).
    pub fn q(&self) -> &[Vec5] {
        &self.q
    }

    /// Joint velocities (m/s, rad/s).
    pub fn qd(&self) -> &[Vec5] {
        &self.qd
    }

    /// Joint accelerations (m/s², rad/s²).
    pub fn qdd(&self) -> &[Vec5] {
        &self.qdd
    }

    /// Generalised forces [F1, τ2, τ3, τ4, F5] (N, N·m).
    pub fn tau(&self) -> &[Vec5] {
        &self.tau
    }

    /// Time span `t[N−1] − t[0]`, s.
    pub fn duration(&self) -> f64 {
        self.t[self.t.len() - 1] - self.t[0]
    }

    /// A borrowed view of the samples, the input of every estimator
    /// ([`crate::Estimator::run`], [`crate::least_squares`]).
    pub fn samples(&self) -> crate::Samples<'_, NDOF> {
        crate::Samples::new(self.q(), self.qd(), self.qdd(), self.tau())
            .expect("a Dataset's columns have equal lengths by construction")
    }

    /// The samples in `range` (indices) as a new validated data set, e.g. to split
    /// estimation and validation parts.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if the range is out of bounds or reversed,
    /// [`PrrrpError::TooFewSamples`] if it holds fewer than [`Dataset::MIN_SAMPLES`].
    pub fn slice(&self, range: std::ops::Range<usize>) -> Result<Self> {
        if range.start > range.end || range.end > self.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "range".into(),
                expected: format!("a range within 0..{}", self.len()),
                got: format!("{}..{}", range.start, range.end),
            });
        }
        Self::new(
            self.t[range.clone()].to_vec(),
            self.q[range.clone()].to_vec(),
            self.qd[range.clone()].to_vec(),
            self.qdd[range.clone()].to_vec(),
            self.tau[range].to_vec(),
        )
    }

    /// Moves the columns out.
    pub fn into_parts(self) -> DatasetParts {
        DatasetParts {
            t: self.t,
            q: self.q,
            qd: self.qd,
            qdd: self.qdd,
            tau: self.tau,
        }
    }
}
