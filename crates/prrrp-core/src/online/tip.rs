//! The whole-arm RLS's first answer to a detected change: open the covariance along the
//! directions a payload at the tip link moves the base parameters, and a second look that
//! opens every direction when the change was not a payload (docs/design/online.md, "Whole-arm
//! RLS after a change: the tip first").
//!
//! The opening is a congruence P ← T·P·Tᵀ with T = I + K·(A − I)·G·Kᵀ·P⁻¹, K the tip link's
//! 10 columns of the base map (γ units per payload unit), G = (Kᵀ·P⁻¹·K)⁻¹ the covariance of
//! the tip's 10 parameters given the rest of the arm, A = diag(aᵢ). It equals
//! P + K·(A·G·A − G)·Kᵀ: the conditional covariance G becomes A·G·A, and what the data say of
//! the rest of the arm (the P-orthogonal complement of the tip directions) is untouched. In
//! information form it forgets the fraction 1 − 1/aᵢ² of the information along the tip only.
//! Each aᵢ² is `open_factor` capped at the payload prior over Gᵢᵢ, as the all-direction
//! opening caps at the prior variances: P's relative structure is kept (its condition grows
//! by at most `open_factor`). Adding the payload prior K·Σ·Kᵀ itself (tried first) put
//! variances of the prior's size on well-excited directions whose variances were orders
//! smaller, and the RLS lost definiteness after a few repeated alarms.

use nalgebra::{DMatrix, DVector, SMatrix};

use super::payload::{tip_columns, PAYLOAD_PARAMS};
use crate::models::chain::BaseParameters;

type Small = SMatrix<f64, PAYLOAD_PARAMS, PAYLOAD_PARAMS>;

/// At the second look the change is taken not to be a payload when the mean normalised
/// innovation (against the noise levels before the change) is above this many times its
/// level before the change, at least 1 (a model that holds has ≈ 1; the running level of
/// a still-converging model is below): torque errors √1.5 ≈ 1.22 times the noise. Over the
/// look (`noise_window`, 2 s by default, of low-passed errors) the mean of a model that
/// holds scatters by about 0.1 (≈ 280 independent squared errors of 7 joints). Measured
/// (docs/design/online.md): a payload's looks 0.2–0.9, the link before the tip changed 24.
pub(crate) const SECOND_LOOK: f64 = 1.5;

/// The tip opening and its second look (module docs). Allocation-free after construction.
#[derive(Debug, Clone)]
pub(crate) struct TipOpening {
    /// K (B×10, γ per payload unit).
    k: DMatrix<f64>,
    /// Payload prior variances (kg², (kg·m)², (kg·m²)²), the caps of A·G·A.
    prior: [f64; PAYLOAD_PARAMS],
    /// B×B scratch (Cholesky factors).
    work: DMatrix<f64>,
    /// The increment K·(A·G·A − G)·Kᵀ.
    inc: DMatrix<f64>,
    /// B×10 scratch: L⁻¹·D⁻¹·K.
    y: DMatrix<f64>,
    diag: DVector<f64>,
    /// Seconds since the last tip opening (∞: no look pending).
    since: f64,
    /// Integral and duration of the look's normalised innovation.
    look: (f64, f64),
    /// Running mean of the normalised innovation between changes (≈ 1).
    baseline: f64,
    /// Per joint, the noise variances at the opening (units of τ²).
    var0: Vec<f64>,
}

/// What the second look decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Look {
    /// Nothing to do (no look pending, or still looking).
    Wait,
    /// The errors came back: the change was a payload.
    Payload,
    /// The errors stayed up: open every direction.
    OpenAll,
}

impl TipOpening {
    /// For the base analysis `base` of an `n`-joint chain, parameters scaled by `scale`
    /// (θ = scale ⊙ γ), payload prior variances `prior`; `None` if the chain has no tip
    /// link columns.
    pub(crate) fn new(
        base: &BaseParameters,
        n: usize,
        scale: &DVector<f64>,
        prior: [f64; PAYLOAD_PARAMS],
    ) -> Option<Self> {
        let cols = tip_columns(&base.names, n).ok()?;
        let b = base.count();
        let k = DMatrix::from_fn(b, PAYLOAD_PARAMS, |i, c| base.map[(i, cols[c])] / scale[i]);
        Some(Self::with_columns(k, prior, n))
    }

    /// For the tip columns `k` (B×10) of an `n`-joint chain, no look pending.
    fn with_columns(k: DMatrix<f64>, prior: [f64; PAYLOAD_PARAMS], n: usize) -> Self {
        let b = k.nrows();
        Self {
            k,
            prior,
            work: DMatrix::zeros(b, b),
            inc: DMatrix::zeros(b, b),
            y: DMatrix::zeros(b, PAYLOAD_PARAMS),
            diag: DVector::zeros(b),
            since: f64::INFINITY,
            look: (0.0, 0.0),
            baseline: 1.0,
            var0: vec![0.0; n],
        }
    }

    /// Whether a second look is pending.
    pub(crate) fn looking(&self) -> bool {
        self.since.is_finite()
    }

    /// Ends a pending look (every direction is being opened).
    pub(crate) fn cancel(&mut self) {
        self.since = f64::INFINITY;
        self.look = (0.0, 0.0);
    }

    /// The increment of the tip opening of `p` (γ units) by `factor` (module docs), in
    /// [`TipOpening::increment`]; starts the second look with the noise variances `var`.
    /// `false` (nothing computed, no look) when P, P + increment or Kᵀ·P⁻¹·K is not
    /// numerically positive definite: the caller then opens every direction.
    pub(crate) fn prepare(&mut self, p: &DMatrix<f64>, factor: f64, var: &[f64]) -> bool {
        let b = p.nrows();
        self.work.copy_from(p);
        if !cholesky_scaled(&mut self.work, &mut self.diag) {
            return false;
        }
        // Y = L⁻¹·D⁻¹·K, so that H = Kᵀ·P⁻¹·K = Yᵀ·Y.
        for c in 0..PAYLOAD_PARAMS {
            for i in 0..b {
                let mut v = self.k[(i, c)] / self.diag[i];
                for r in 0..i {
                    v -= self.work[(i, r)] * self.y[(r, c)];
                }
                self.y[(i, c)] = v / self.work[(i, i)];
            }
        }
        let h = Small::from_fn(|r, c| self.y.column(r).dot(&self.y.column(c)));
        let h = (h + h.transpose()) * 0.5;
        // G = H⁺: a payload direction K·v = 0 moves no base parameter and has no
        // information (eigenvalue 0); it is left out.
        let Some(eig) = crate::linalg::symmetric_eigen(h) else {
            return false;
        };
        let top = eig.eigenvalues.amax();
        if !(top.is_finite() && top > 0.0) {
            return false;
        }
        let mut g = Small::zeros();
        for (e, v) in eig.eigenvalues.iter().zip(eig.eigenvectors.column_iter()) {
            if *e > 1e-12 * top {
                g += v * v.transpose() / *e;
            }
        }
        let mut a = [1.0; PAYLOAD_PARAMS];
        for (i, ai) in a.iter_mut().enumerate() {
            if g[(i, i)] > 0.0 && self.prior[i] > g[(i, i)] {
                *ai = factor.min(self.prior[i] / g[(i, i)]).sqrt().max(1.0);
            }
        }
        let m = Small::from_fn(|r, c| (a[r] * a[c] - 1.0) * g[(r, c)]);
        // inc = K·M·Kᵀ, each entry once for both triangles (exactly symmetric).
        for j in 0..b {
            for i in j..b {
                let mut v = 0.0;
                for r in 0..PAYLOAD_PARAMS {
                    let kr = self.k[(i, r)];
                    if kr == 0.0 {
                        continue;
                    }
                    for c in 0..PAYLOAD_PARAMS {
                        v += kr * m[(r, c)] * self.k[(j, c)];
                    }
                }
                self.inc[(i, j)] = v;
                self.inc[(j, i)] = v;
            }
        }
        // In exact arithmetic P + inc = T·P·Tᵀ is positive definite; refuse it if round-off
        // says otherwise.
        self.work.copy_from(p);
        self.work += &self.inc;
        if !cholesky_scaled(&mut self.work, &mut self.diag) {
            return false;
        }
        self.since = 0.0;
        self.look = (0.0, 0.0);
        self.var0.copy_from_slice(var);
        true
    }

    /// The increment computed by the last successful [`TipOpening::prepare`] (γ units).
    pub(crate) fn increment(&self) -> &DMatrix<f64> {
        &self.inc
    }

    /// One row without an alarm: `resid` the filtered a-priori errors, `floor` the
    /// smallest variances, `last` the detector's normalised innovation of the row,
    /// `settled` whether it counts as noise; the look runs over (`holdoff`, `holdoff` +
    /// `window`] s after the opening (the first hold-off lets the estimate re-converge).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn row(
        &mut self,
        dt: f64,
        resid: &[f64],
        floor: &[f64],
        last: f64,
        settled: bool,
        holdoff: f64,
        window: f64,
    ) -> Look {
        if !self.looking() {
            if settled {
                self.baseline += (dt / window).min(1.0) * (last - self.baseline);
            }
            return Look::Wait;
        }
        self.since += dt;
        if self.since > holdoff {
            let n = resid.len().max(1) as f64;
            let s = resid
                .iter()
                .zip(&self.var0)
                .zip(floor)
                .map(|((e, v), f)| e * e / v.max(*f))
                .sum::<f64>()
                / n;
            self.look.0 += s * dt;
            self.look.1 += dt;
        }
        if self.since > holdoff + window {
            let mean = self.look.0 / self.look.1.max(f64::MIN_POSITIVE);
            self.cancel();
            return if mean > SECOND_LOOK * self.baseline.max(1.0) {
                Look::OpenAll
            } else {
                Look::Payload
            };
        }
        Look::Wait
    }
}

/// In place: `w` (symmetric) ← the lower Cholesky factor L of D⁻¹·w·D⁻¹, D = diag(√wᵢᵢ) in
/// `d` (Jacobi scaling: a covariance whose variances span many decades factors as well as
/// its correlation matrix). `false` if w is not numerically positive definite. Only the
/// lower triangle is meaningful afterwards. Allocation-free.
fn cholesky_scaled(w: &mut DMatrix<f64>, d: &mut DVector<f64>) -> bool {
    let b = w.nrows();
    for i in 0..b {
        let v = w[(i, i)];
        if !(v.is_finite() && v > 0.0) {
            return false;
        }
        d[i] = v.sqrt();
    }
    for j in 0..b {
        for i in j..b {
            w[(i, j)] /= d[i] * d[j];
        }
    }
    for j in 0..b {
        let mut s = w[(j, j)];
        for r in 0..j {
            s -= w[(j, r)] * w[(j, r)];
        }
        // A correlation matrix's pivots are ≤ 1; one below 1e-14 (or NaN) is round-off.
        if s.is_nan() || s <= 1e-14 {
            return false;
        }
        let l = s.sqrt();
        w[(j, j)] = l;
        for i in j + 1..b {
            let mut v = w[(i, j)];
            for r in 0..j {
                v -= w[(i, r)] * w[(j, r)];
            }
            w[(i, j)] = v / l;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The increment is the congruence T·P·Tᵀ − P of the module docs, computed
    /// independently with P⁻¹ (a random P of widely spread variances and a random K): the
    /// conditional covariance of the tip parameters becomes A·G·A, the complement's
    /// covariance and its cross-covariance with them stay.
    #[test]
    fn increment_is_the_congruence() {
        let (b, n) = (16, 3);
        let mut st = 0x9E37_79B9u64;
        let mut u = || {
            st ^= st << 13;
            st ^= st >> 7;
            st ^= st << 17;
            (st >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        };
        let a = DMatrix::from_fn(b, b, |_, _| u());
        let spread = DVector::from_fn(b, |i, _| 10f64.powi(i as i32 % 5 - 2));
        let p = DMatrix::from_diagonal(&spread)
            * (&a * a.transpose() + DMatrix::identity(b, b))
            * DMatrix::from_diagonal(&spread);
        let p = (&p + p.transpose()) * 0.5;
        let k = DMatrix::from_fn(
            b,
            PAYLOAD_PARAMS,
            |i, c| if (i + c) % 3 == 0 { 0.0 } else { u() },
        );
        let prior = [1e3, 1e3, 1e3, 1e3, 1e-9, 1e3, 1e3, 1e3, 1e3, 1e3];
        let mut t = TipOpening::with_columns(k.clone(), prior, n);
        let factor = 100.0;
        assert!(t.prepare(&p, factor, &[1.0; 3]));
        let pinv = p.clone().try_inverse().unwrap();
        let g = (k.transpose() * &pinv * &k).try_inverse().unwrap();
        let aa: Vec<f64> = (0..PAYLOAD_PARAMS)
            .map(|i| factor.min(prior[i] / g[(i, i)]).max(1.0).sqrt())
            .collect();
        assert!(aa[4] == 1.0 && aa[0] == 10.0, "{aa:?}");
        let am = DMatrix::from_diagonal(&DVector::from_column_slice(&aa));
        let tm = DMatrix::identity(b, b)
            + &k * (&am - DMatrix::identity(PAYLOAD_PARAMS, PAYLOAD_PARAMS))
                * &g
                * k.transpose()
                * &pinv;
        let want = &tm * &p * tm.transpose() - &p;
        let err = (t.increment() - &want).amax();
        assert!(err < 1e-8 * want.amax(), "{err} of {}", want.amax());
        assert_eq!(t.increment(), &t.increment().transpose());
    }
}
