//! One sample and a borrowed series of samples, the inputs of every estimator.

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OVector};

use crate::error::{PrrrpError, Result};

/// One sample of a model whose joint count is fixed at compile time (the PRRRP path).
pub type Sample<'a, const N: usize> = SampleOf<'a, Const<N>>;
/// One sample of a model whose joint count is known only at run time (e.g. a
/// [`crate::DynChain`]); each vector must have the model's n entries.
pub type DynSample<'a> = SampleOf<'a, Dyn>;
/// A series of samples of a compile-time-size model.
pub type Samples<'a, const N: usize> = SamplesOf<'a, Const<N>>;
/// A series of samples of a run-time-size model (all vectors of one length).
pub type DynSamples<'a> = SamplesOf<'a, Dyn>;

/// One sample of joint data, borrowed from the caller.
///
/// Units follow the model: for the PRRRP arm q = [d1, θ2, θ3, θ4, d5] in m and rad, q̇ in
/// m/s and rad/s, q̈ in m/s² and rad/s², τ in N and N·m. Estimators that work on the
/// inverse model (least squares, Adaline, Hopfield) use all four; the extended Kalman
/// filter uses q (and q̇) as measurements and τ as its input, and ignores q̈.
///
/// N is a nalgebra dimension: `Const<N>` ([`Sample`]) or [`Dyn`] ([`DynSample`]).
#[derive(Debug, Clone, Copy)]
pub struct SampleOf<'a, N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    /// Joint positions.
    pub q: &'a OVector<f64, N>,
    /// Joint velocities.
    pub qd: &'a OVector<f64, N>,
    /// Joint accelerations.
    pub qdd: &'a OVector<f64, N>,
    /// Generalised joint forces.
    pub tau: &'a OVector<f64, N>,
}

impl<'a, N: Dim> SampleOf<'a, N>
where
    DefaultAllocator: Allocator<N>,
{
    /// A sample from its four parts.
    pub fn new(
        q: &'a OVector<f64, N>,
        qd: &'a OVector<f64, N>,
        qdd: &'a OVector<f64, N>,
        tau: &'a OVector<f64, N>,
    ) -> Self {
        Self { q, qd, qdd, tau }
    }

    /// Whether q, q̇, q̈ and τ are all finite (the inverse-model estimators need them all).
    #[inline]
    pub fn is_finite(&self) -> bool {
        // As `all_finite`, over the four vectors with one branch.
        finite_sum(self.q) + finite_sum(self.qd) + finite_sum(self.qdd) + finite_sum(self.tau)
            == 0.0
    }

    /// The [`PrrrpError::NonFinite`] naming the first non-finite part, if any.
    #[inline]
    pub(crate) fn check_finite(&self) -> Result<()> {
        if self.is_finite() {
            return Ok(());
        }
        let what = [
            ("q", self.q),
            ("qd", self.qd),
            ("qdd", self.qdd),
            ("tau", self.tau),
        ]
        .into_iter()
        .find(|(_, v)| !all_finite(v))
        .map_or("sample", |(name, _)| name);
        Err(PrrrpError::NonFinite {
            what: what.into(),
            row: None,
        })
    }

    /// The [`PrrrpError::ShapeMismatch`] naming the first part that does not have `n`
    /// entries (always `Ok` at compile-time sizes).
    #[inline(always)]
    pub(crate) fn check_len(&self, n: usize) -> Result<()> {
        for (name, v) in [
            ("q", self.q),
            ("qd", self.qd),
            ("qdd", self.qdd),
            ("tau", self.tau),
        ] {
            if v.nrows() != n {
                return Err(len_mismatch(name, n, v.nrows()));
            }
        }
        Ok(())
    }

    /// Sizes, then finiteness: what the inverse-model estimators check per sample.
    #[inline(always)]
    pub(crate) fn check(&self, n: usize) -> Result<()> {
        self.check_len(n)?;
        self.check_finite()
    }
}

pub(crate) fn len_mismatch(what: &str, want: usize, got: usize) -> PrrrpError {
    PrrrpError::ShapeMismatch {
        what: what.into(),
        expected: format!("{want} entries (one per joint of the model)"),
        got: format!("{got} entries"),
    }
}

#[inline(always)]
pub(crate) fn all_finite<N: Dim>(v: &OVector<f64, N>) -> bool
where
    DefaultAllocator: Allocator<N>,
{
    // x − x is 0 for a finite x and NaN for NaN or ±∞, and a sum with a NaN stays NaN:
    // one branch per vector instead of one per entry (the check runs on every sample of
    // every estimator).
    finite_sum(v) == 0.0
}

/// Σ (x − x) over `v`: 0 when every entry is finite, NaN otherwise.
#[inline(always)]
#[allow(clippy::eq_op)]
fn finite_sum<N: Dim>(v: &OVector<f64, N>) -> f64
where
    DefaultAllocator: Allocator<N>,
{
    v.iter().fold(0.0, |acc, &x| acc + (x - x))
}

/// A series of samples: four equally long slices q, q̇, q̈, τ (row k is sample k).
///
/// Built with [`Samples::new`], which checks the lengths once; the values are checked
/// where they are used (each estimator's `step`, or the batch least-squares solver).
/// N is `Const<N>` ([`Samples`]) or [`Dyn`] ([`DynSamples`]).
#[derive(Debug, Clone, Copy)]
pub struct SamplesOf<'a, N: Dim>
where
    DefaultAllocator: Allocator<N>,
{
    q: &'a [OVector<f64, N>],
    qd: &'a [OVector<f64, N>],
    qdd: &'a [OVector<f64, N>],
    tau: &'a [OVector<f64, N>],
}

impl<'a, N: Dim> SamplesOf<'a, N>
where
    DefaultAllocator: Allocator<N>,
{
    /// Wraps four slices of equal length.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] naming the first slice whose length differs from q's,
    /// or (run-time sizes) the first vector whose length differs from `q[0]`'s.
    pub fn new(
        q: &'a [OVector<f64, N>],
        qd: &'a [OVector<f64, N>],
        qdd: &'a [OVector<f64, N>],
        tau: &'a [OVector<f64, N>],
    ) -> Result<Self> {
        for (name, len) in [("qd", qd.len()), ("qdd", qdd.len()), ("tau", tau.len())] {
            if len != q.len() {
                return Err(PrrrpError::ShapeMismatch {
                    what: name.into(),
                    expected: format!("{} samples (as q)", q.len()),
                    got: format!("{len} samples"),
                });
            }
        }
        if let Some(first) = q.first() {
            let n = first.nrows();
            // Compile-time sizes make this loop a no-op; run-time vectors can differ.
            if N::try_to_usize().is_none() {
                for (name, s) in [("q", q), ("qd", qd), ("qdd", qdd), ("tau", tau)] {
                    if let Some((k, v)) = s.iter().enumerate().find(|(_, v)| v.nrows() != n) {
                        return Err(PrrrpError::ShapeMismatch {
                            what: format!("{name}[{k}]"),
                            expected: format!("{n} entries (as q[0])"),
                            got: format!("{} entries", v.nrows()),
                        });
                    }
                }
            }
        }
        Ok(Self { q, qd, qdd, tau })
    }

    /// Number of samples.
    #[inline]
    pub fn len(&self) -> usize {
        self.q.len()
    }

    /// Whether there are no samples.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }

    /// Sample k.
    ///
    /// # Panics
    /// If `k >= self.len()` (an index bug in the caller, not bad data).
    #[inline]
    pub fn sample(&self, k: usize) -> SampleOf<'a, N> {
        SampleOf {
            q: &self.q[k],
            qd: &self.qd[k],
            qdd: &self.qdd[k],
            tau: &self.tau[k],
        }
    }

    /// Iterator over the samples in order.
    pub fn iter(&self) -> impl Iterator<Item = SampleOf<'a, N>> + '_ {
        (0..self.len()).map(move |k| self.sample(k))
    }

    /// The positions.
    pub fn q(&self) -> &'a [OVector<f64, N>] {
        self.q
    }

    /// The velocities.
    pub fn qd(&self) -> &'a [OVector<f64, N>] {
        self.qd
    }

    /// The accelerations.
    pub fn qdd(&self) -> &'a [OVector<f64, N>] {
        self.qdd
    }

    /// The generalised forces.
    pub fn tau(&self) -> &'a [OVector<f64, N>] {
        self.tau
    }
}
