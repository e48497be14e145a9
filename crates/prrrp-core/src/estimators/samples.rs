//! One sample and a borrowed series of samples, the inputs of every estimator.

use nalgebra::SVector;

use crate::error::{PrrrpError, Result};

/// One sample of joint data, borrowed from the caller.
///
/// Units follow the model: for the PRRRP arm q = [d1, θ2, θ3, θ4, d5] in m and rad, q̇ in
/// m/s and rad/s, q̈ in m/s² and rad/s², τ in N and N·m. Estimators that work on the
/// inverse model (least squares, Adaline, Hopfield) use all four; the extended Kalman
/// filter uses q (and q̇) as measurements and τ as its input, and ignores q̈.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a, const N: usize> {
    /// Joint positions.
    pub q: &'a SVector<f64, N>,
    /// Joint velocities.
    pub qd: &'a SVector<f64, N>,
    /// Joint accelerations.
    pub qdd: &'a SVector<f64, N>,
    /// Generalised joint forces.
    pub tau: &'a SVector<f64, N>,
}

impl<'a, const N: usize> Sample<'a, N> {
    /// A sample from its four parts.
    pub fn new(
        q: &'a SVector<f64, N>,
        qd: &'a SVector<f64, N>,
        qdd: &'a SVector<f64, N>,
        tau: &'a SVector<f64, N>,
    ) -> Self {
        Self { q, qd, qdd, tau }
    }

    /// Whether q, q̇, q̈ and τ are all finite (the inverse-model estimators need them all).
    #[inline]
    pub fn is_finite(&self) -> bool {
        all_finite(self.q) && all_finite(self.qd) && all_finite(self.qdd) && all_finite(self.tau)
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
}

#[inline(always)]
pub(crate) fn all_finite<const N: usize>(v: &SVector<f64, N>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// A series of samples: four equally long slices q, q̇, q̈, τ (row k is sample k).
///
/// Built with [`Samples::new`], which checks the lengths once; the values are checked
/// where they are used (each estimator's `step`, or the batch least-squares solver).
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a, const N: usize> {
    q: &'a [SVector<f64, N>],
    qd: &'a [SVector<f64, N>],
    qdd: &'a [SVector<f64, N>],
    tau: &'a [SVector<f64, N>],
}

impl<'a, const N: usize> Samples<'a, N> {
    /// Wraps four slices of equal length.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] naming the first slice whose length differs from q's.
    pub fn new(
        q: &'a [SVector<f64, N>],
        qd: &'a [SVector<f64, N>],
        qdd: &'a [SVector<f64, N>],
        tau: &'a [SVector<f64, N>],
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
    pub fn sample(&self, k: usize) -> Sample<'a, N> {
        Sample {
            q: &self.q[k],
            qd: &self.qd[k],
            qdd: &self.qdd[k],
            tau: &self.tau[k],
        }
    }

    /// Iterator over the samples in order.
    pub fn iter(&self) -> impl Iterator<Item = Sample<'a, N>> + '_ {
        (0..self.len()).map(move |k| self.sample(k))
    }

    /// The positions.
    pub fn q(&self) -> &'a [SVector<f64, N>] {
        self.q
    }

    /// The velocities.
    pub fn qd(&self) -> &'a [SVector<f64, N>] {
        self.qd
    }

    /// The accelerations.
    pub fn qdd(&self) -> &'a [SVector<f64, N>] {
        self.qdd
    }

    /// The generalised forces.
    pub fn tau(&self) -> &'a [SVector<f64, N>] {
        self.tau
    }
}
