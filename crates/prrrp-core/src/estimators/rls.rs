//! Recursive least squares: the online form of eqs. 2–4, with an optional forgetting
//! factor.

use nalgebra::allocator::Allocator;
use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OMatrix, OVector};

use super::estimator::{Estimator, ModelFit};
use super::samples::SampleOf;
use crate::error::{PrrrpError, Result};
use crate::models::LinearModel;

/// Recursive least squares for a compile-time-size model (e.g. the PRRRP arm).
pub type Rls<M, const N: usize, const P: usize> = RlsOf<M, Const<N>, Const<P>>;
/// Recursive least squares for a run-time-size model (e.g. [`crate::DynChainBaseModel`]).
pub type DynRls<M> = RlsOf<M, Dyn, Dyn>;

/// Settings of [`Rls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor ν ∈ (0, 1] (dimensionless, default `1.0`: no forgetting, the
    /// estimate converges to the batch least-squares solution). With ν < 1 old samples
    /// weigh ν^age, which tracks slowly varying parameters; the effective memory is
    /// 1/(1 − ν) samples.
    pub forgetting: f64,
    /// Initial covariance P₀ = δ·I (units of λ² per unit of τ², default `1e6`): large means
    /// "λ₀ is barely known"; the estimate then equals batch least squares regularised by
    /// ‖λ − λ₀‖²/δ.
    pub initial_covariance: f64,
}

impl Default for RlsConfig {
    fn default() -> Self {
        Self {
            forgetting: 1.0,
            initial_covariance: 1e6,
        }
    }
}

/// How [`RlsOf::update_weighted`] discounts old data over one sample.
///
/// With ν = exp(−Δt/T) per sample of period Δt, information older than T seconds weighs
/// less than 1/e. Exponential forgetting divides the whole covariance by ν: directions the
/// trajectory does not excite lose information too, so their covariance grows without
/// bound (P/νᵏ) until a sample excites them with a huge gain ("covariance windup").
/// Directional forgetting discounts only the information along each row's regressor φ,
/// R ← R − (1 − ν)·φφᵀ/(φᵀPφ) + φφᵀ in information form (Kulhavý 1987; Bittanti,
/// Bolzern & Campi 1990): the variance of φᵀλ̂ settles at (1 − ν) of the noise variance
/// along what is excited, and unexcited directions keep what they knew.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Forgetting {
    /// Every sample keeps its full weight (batch least squares).
    None,
    /// P ← P/ν after the sample, ν ∈ (0, 1].
    Exponential(f64),
    /// Each row forgets the fraction 1 − ν of the information along its own regressor,
    /// ν ∈ (0, 1].
    Directional(f64),
}

impl Forgetting {
    fn factor(&self) -> f64 {
        match *self {
            Self::None => 1.0,
            Self::Exponential(nu) | Self::Directional(nu) => nu,
        }
    }
}

/// Recursive least squares over the rows of τ = Φ·λ.
///
/// Each of the N joint equations of a sample is one scalar update (exactly equivalent to
/// the vector update with unit noise covariance, and free of any matrix inversion); the
/// forgetting factor is applied once per sample. Cost per sample ≈ N·(2P² + 4P) flops.
/// One implementation for both size worlds (see [`Rls`], [`DynRls`]); all buffers are
/// sized at construction.
#[derive(Debug, Clone)]
pub struct RlsOf<M, N: Dim, P: Dim>
where
    M: LinearModel<N, P>,
    DefaultAllocator:
        Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P> + Allocator<P, P>,
{
    fit: ModelFit<M, N, P>,
    config: RlsConfig,
    cov: OMatrix<f64, P, P>,
    /// P₀ (δ·I unless set by [`RlsOf::set_initial_covariance`]).
    cov0: OMatrix<f64, P, P>,
    p_phi: OVector<f64, P>,
    /// √|c|·P·φ of the rank-1 covariance update ([`sym_rank1_sub`]).
    q_phi: OVector<f64, P>,
    /// Whether the CPU runs the AVX2 copies of the kernels (detected once, at
    /// construction); they compute the same bits as the portable ones (no FMA).
    avx2: bool,
    /// A-priori prediction Φ·λ̂ of the last [`RlsOf::update_weighted`] sample.
    pred: OVector<f64, N>,
    samples: usize,
}

impl<M, N: Dim, P: Dim> RlsOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator:
        Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P> + Allocator<P, P>,
{
    /// A filter starting from λ₀ with covariance `config.initial_covariance`·I (see also
    /// [`RlsOf::set_initial_covariance`]).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] for a forgetting factor outside (0, 1], a
    /// non-positive initial covariance, or a non-finite λ₀; [`PrrrpError::ShapeMismatch`]
    /// if λ₀ does not have one entry per model parameter.
    pub fn new(model: M, lambda0: OVector<f64, P>, config: RlsConfig) -> Result<Self> {
        let nu = config.forgetting;
        if !(nu > 0.0 && nu <= 1.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "forgetting".into(),
                value: nu,
                reason: "must be in (0, 1]",
            });
        }
        let d = config.initial_covariance;
        if !(d.is_finite() && d > 0.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "initial_covariance".into(),
                value: d,
                reason: "must be finite and > 0",
            });
        }
        let fit = ModelFit::new(model, lambda0)?;
        let (n, p) = fit.phi.shape_generic();
        let cov = OMatrix::identity_generic(p, p) * d;
        Ok(Self {
            fit,
            config,
            cov0: cov.clone(),
            cov,
            p_phi: OVector::zeros_generic(p, nalgebra::U1),
            q_phi: OVector::zeros_generic(p, nalgebra::U1),
            avx2: cpu_has_avx2(),
            pred: OVector::zeros_generic(n, nalgebra::U1),
            samples: 0,
        })
    }

    /// The covariance P (units of λ² per unit of τ²); σ²·P approximates the covariance of
    /// λ̂ when the equation noise has variance σ².
    pub fn covariance(&self) -> &OMatrix<f64, P, P> {
        &self.cov
    }

    /// Number of samples consumed since construction or the last reset.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Replaces P₀ (and P, when no sample has been consumed since construction or reset),
    /// e.g. with the covariance of a prior estimate. Units: λ² per unit of the weighted
    /// equation error squared.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if P₀ is not P×P, [`PrrrpError::NonFinite`] for
    /// NaN/∞, [`PrrrpError::InvalidParameter`] if it is not symmetric,
    /// [`PrrrpError::NotPositiveDefinite`] if it is not positive definite.
    pub fn set_initial_covariance(&mut self, p0: &OMatrix<f64, P, P>) -> Result<()> {
        let p = self.fit.lambda.nrows();
        if p0.nrows() != p || p0.ncols() != p {
            return Err(PrrrpError::ShapeMismatch {
                what: "initial covariance".into(),
                expected: format!("{p}×{p}"),
                got: format!("{}×{}", p0.nrows(), p0.ncols()),
            });
        }
        check_initial_covariance(p0)?;
        self.cov0.copy_from(p0);
        if self.samples == 0 {
            self.cov.copy_from(p0);
        }
        Ok(())
    }

    /// The a-priori prediction Φ·λ̂ of the last sample given to
    /// [`RlsOf::update_weighted`], with the estimate before that sample (units of τ).
    pub fn prediction(&self) -> &OVector<f64, N> {
        &self.pred
    }

    /// Replaces the estimate λ̂ (e.g. by its projection onto a constraint set); P is kept.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] / [`PrrrpError::InvalidParameter`] as for λ₀.
    pub fn set_estimate(&mut self, lambda: &OVector<f64, P>) -> Result<()> {
        let (n, p) = self.fit.model.dims();
        check_lambda0(lambda, n.value(), p.value())?;
        self.fit.lambda.copy_from(lambda);
        Ok(())
    }

    /// Takes `other`'s estimate, covariance and sample count (a filter of the same model
    /// and sizes); allocation-free.
    pub fn copy_state_from(&mut self, other: &Self) {
        self.fit.lambda.copy_from(&other.fit.lambda);
        self.cov.copy_from(&other.cov);
        self.samples = other.samples;
    }

    /// P ← D·P·D with D = diag(`d`), d ≥ 0 (a congruence: P stays positive
    /// semidefinite). Opens the covariance after a detected change of the dynamics (d > 1
    /// on the parameters that may have changed), allocation-free.
    pub fn scale_covariance(&mut self, d: &OVector<f64, P>) {
        let p = self.fit.lambda.nrows();
        for j in 0..p {
            for i in 0..p {
                self.cov[(i, j)] *= d[i] * d[j];
            }
        }
    }

    /// P ← P + `m` (units of P), `m` symmetric: opens the covariance along chosen
    /// directions after a detected change. The caller keeps P positive definite (e.g. `m`
    /// from a congruence, T·P·Tᵀ − P). Allocation-free.
    pub fn add_covariance(&mut self, m: &OMatrix<f64, P, P>) {
        self.cov += m;
    }

    /// One sample with joint weights and forgetting: each joint's equation is weighted by
    /// `weights[j]` (1/σ_j² for a joint force noise σ_j: the weighted errors have unit
    /// variance, so P is the covariance of λ̂), then old data are discounted by
    /// `forgetting`. Also records the a-priori prediction ([`RlsOf::prediction`]). A joint
    /// of weight 0 is skipped. Allocation-free.
    ///
    /// # Errors
    /// As [`Estimator::step`], and [`PrrrpError::InvalidParameter`] for a negative or
    /// non-finite weight or a forgetting factor outside (0, 1].
    pub fn update_weighted(
        &mut self,
        sample: SampleOf<'_, N>,
        weights: &OVector<f64, N>,
        forgetting: Forgetting,
    ) -> Result<&OVector<f64, P>> {
        let n = self.fit.phi.nrows();
        sample.check(n)?;
        let nu = forgetting.factor();
        if !(nu > 0.0 && nu <= 1.0) {
            return Err(PrrrpError::InvalidParameter {
                field: "forgetting".into(),
                value: nu,
                reason: "must be in (0, 1]",
            });
        }
        if weights.nrows() != n {
            return Err(super::samples::len_mismatch("weights", n, weights.nrows()));
        }
        if let Some(&w) = weights.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
            return Err(PrrrpError::InvalidParameter {
                field: "weights".into(),
                value: w,
                reason: "joint weights must be finite and >= 0",
            });
        }
        self.fit.load_regressor(&sample)?;
        self.pred.gemv(1.0, &self.fit.phi, &self.fit.lambda, 0.0);
        let directional = match forgetting {
            Forgetting::Directional(nu) if nu < 1.0 => Some(nu),
            _ => None,
        };
        for i in 0..n {
            let w = weights[i];
            if w == 0.0 {
                continue;
            }
            let s = w.sqrt();
            if s != 1.0 {
                self.fit.phi.row_mut(i).scale_mut(s);
            }
            let ok = match directional {
                Some(nu) => self.update_row_directional(i, sample.tau[i] * s, nu),
                None => self.update_row(i, sample.tau[i] * s),
            };
            if !ok {
                return Err(diverged(self.samples));
            }
        }
        if let Forgetting::Exponential(nu) = forgetting {
            if nu != 1.0 {
                self.cov /= nu;
            }
        }
        if !(self.fit.lambda.iter().all(|x| x.is_finite()) && self.cov[(0, 0)].is_finite()) {
            return Err(diverged(self.samples));
        }
        self.samples += 1;
        Ok(&self.fit.lambda)
    }

    /// The scalar update with row `row` and directional forgetting ν (see
    /// [`Forgetting`]): with p = P·φ and r = φᵀ·p, λ ← λ + p·e/(r + ν) and
    /// P ← P − β·p·pᵀ/(r + ν), β = 1 − (1 − ν)/r. A row with r = 0 (no regressor, or a
    /// direction already known exactly) is the plain update.
    #[inline(always)]
    fn update_row_directional(&mut self, row: usize, tau: f64, nu: f64) -> bool {
        let np = self.fit.lambda.nrows();
        let (phi, cov, p_phi) = (&self.fit.phi, &mut self.cov, &mut self.p_phi);
        cov_times_row(self.avx2, cov.as_slice(), phi, row, p_phi.as_mut_slice());
        let (mut r, mut pred) = (0.0, 0.0);
        for j in 0..np {
            r += phi[(row, j)] * p_phi[j];
            pred += phi[(row, j)] * self.fit.lambda[j];
        }
        if !r.is_finite() || r < 0.0 {
            return false;
        }
        let (den, beta) = if r > 0.0 {
            (r + nu, 1.0 - (1.0 - nu) / r)
        } else {
            (1.0 + r, 1.0)
        };
        let e = tau - pred;
        self.fit.lambda.axpy(e / den, p_phi, 1.0);
        sym_rank1_sub(
            self.avx2,
            cov.as_mut_slice(),
            p_phi.as_slice(),
            beta / den,
            self.q_phi.as_mut_slice(),
        );
        true
    }

    /// The scalar update with row `row` of the stored regressor.
    #[inline(always)]
    fn update_row(&mut self, row: usize, tau: f64) -> bool {
        let np = self.fit.lambda.nrows();
        let (phi, cov, p_phi) = (&self.fit.phi, &mut self.cov, &mut self.p_phi);
        cov_times_row(self.avx2, cov.as_slice(), phi, row, p_phi.as_mut_slice());
        let (mut den, mut pred) = (1.0, 0.0);
        for j in 0..np {
            den += phi[(row, j)] * p_phi[j];
            pred += phi[(row, j)] * self.fit.lambda[j];
        }
        if !(den > 0.0 && den.is_finite()) {
            return false;
        }
        let e = tau - pred;
        let inv = 1.0 / den;
        self.fit.lambda.axpy(e * inv, p_phi, 1.0);
        sym_rank1_sub(
            self.avx2,
            cov.as_mut_slice(),
            p_phi.as_slice(),
            inv,
            self.q_phi.as_mut_slice(),
        );
        true
    }
}

fn cpu_has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// p = P·φ for row `row` of `phi` (P column-major, d×d), over the non-zero entries of φ
/// only (regressor rows are sparse: a joint's row has no entries of the links before it).
#[inline(always)]
fn cov_times_row<N: Dim, P: Dim>(
    avx2: bool,
    cov: &[f64],
    phi: &OMatrix<f64, N, P>,
    row: usize,
    p: &mut [f64],
) where
    DefaultAllocator: Allocator<N, P>,
{
    p.fill(0.0);
    let d = p.len();
    for j in 0..d {
        let f = phi[(row, j)];
        if f != 0.0 {
            axpy(avx2, f, &cov[j * d..j * d + d], p);
        }
    }
}

/// y ← y + f·x.
#[inline(always)]
fn axpy(avx2: bool, f: f64, x: &[f64], y: &mut [f64]) {
    #[inline(always)]
    fn body(f: f64, x: &[f64], y: &mut [f64]) {
        for (yv, &xv) in y.iter_mut().zip(x) {
            *yv += f * xv;
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn wide(f: f64, x: &[f64], y: &mut [f64]) {
        body(f, x, y)
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is set only when the CPU reports AVX2.
        return unsafe { wide(f, x, y) };
    }
    let _ = avx2;
    body(f, x, y)
}

/// P ← P − c·p·pᵀ (P column-major d×d, symmetric) on whole columns, as P − s·q·qᵀ with
/// q = √|c|·p and s the sign of c: entries (i, j) and (j, i) subtract the same product
/// q_i·q_j, so P stays exactly symmetric without mirroring. Contiguous columns vectorise,
/// where the upper triangle with its strided mirror writes (half the multiplies) did not
/// and cost twice as much. `q` is scratch of length d.
#[inline(always)]
fn sym_rank1_sub(avx2: bool, cov: &mut [f64], p: &[f64], c: f64, q: &mut [f64]) {
    #[inline(always)]
    fn body(cov: &mut [f64], p: &[f64], c: f64, q: &mut [f64]) {
        let d = p.len();
        let r = c.abs().sqrt();
        for (qv, &pv) in q.iter_mut().zip(p) {
            *qv = r * pv;
        }
        for j in 0..d {
            let qj = if c < 0.0 { -q[j] } else { q[j] };
            for (x, &qi) in cov[j * d..j * d + d].iter_mut().zip(q.iter()) {
                *x -= qi * qj;
            }
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn wide(cov: &mut [f64], p: &[f64], c: f64, q: &mut [f64]) {
        body(cov, p, c, q)
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is set only when the CPU reports AVX2.
        return unsafe { wide(cov, p, c, q) };
    }
    let _ = avx2;
    body(cov, p, c, q)
}

impl<M, N: Dim, P: Dim> Estimator<N, P> for RlsOf<M, N, P>
where
    M: LinearModel<N, P>,
    DefaultAllocator:
        Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P> + Allocator<P, P>,
{
    /// One sample: N scalar updates, then P ← P/ν.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for a sample whose vectors do not have one entry per
    /// joint; [`PrrrpError::NonFinite`] for NaN/∞ in the sample; [`PrrrpError::Diverged`] if the
    /// covariance lost positive definiteness or the estimate became non-finite (with
    /// ν < 1 and poor excitation P grows without bound: raise ν or excite more).
    fn step(&mut self, sample: SampleOf<'_, N>) -> Result<&OVector<f64, P>> {
        let n = self.fit.phi.nrows();
        sample.check(n)?;
        self.fit.load_regressor(&sample)?;
        for i in 0..n {
            if !self.update_row(i, sample.tau[i]) {
                return Err(diverged(self.samples));
            }
        }
        if self.config.forgetting != 1.0 {
            self.cov /= self.config.forgetting;
        }
        if !(self.fit.lambda.iter().all(|x| x.is_finite()) && self.cov[(0, 0)].is_finite()) {
            return Err(diverged(self.samples));
        }
        self.samples += 1;
        Ok(&self.fit.lambda)
    }

    fn estimate(&self) -> &OVector<f64, P> {
        &self.fit.lambda
    }

    fn reset(&mut self) {
        self.fit.reset();
        self.cov.copy_from(&self.cov0);
        self.samples = 0;
    }
}

fn diverged(at: usize) -> PrrrpError {
    PrrrpError::Diverged {
        what: "recursive least squares",
        at,
        hint: "the covariance is no longer positive definite or finite: use a forgetting \
               factor closer to 1 or a trajectory that excites every parameter",
    }
}

/// Checks the model's sizes and λ₀ (length, then values) before any buffer is allocated.
/// Checks an initial covariance P₀ (shape checked by the caller): finite, symmetric (to
/// 1e-12 of its largest entry) and positive definite; shared by RLS and the EKF.
pub(crate) fn check_initial_covariance<D: Dim>(p0: &OMatrix<f64, D, D>) -> Result<()>
where
    DefaultAllocator: Allocator<D, D>,
{
    if !p0.iter().all(|v| v.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "initial covariance".into(),
            row: None,
        });
    }
    let asym = (p0 - p0.transpose()).amax();
    if asym > 1e-12 * p0.amax() {
        return Err(PrrrpError::InvalidParameter {
            field: "initial covariance".into(),
            value: asym,
            reason: "must be symmetric",
        });
    }
    if p0.clone().cholesky().is_none() {
        return Err(PrrrpError::NotPositiveDefinite {
            what: "initial covariance P0",
        });
    }
    Ok(())
}

pub(crate) fn check_lambda0<P: Dim>(lambda0: &OVector<f64, P>, n: usize, p: usize) -> Result<()>
where
    DefaultAllocator: Allocator<P>,
{
    if n == 0 || p == 0 {
        return Err(PrrrpError::ShapeMismatch {
            what: "model".into(),
            expected: "at least one joint and one parameter".into(),
            got: format!("{n} joints, {p} parameters"),
        });
    }
    if lambda0.nrows() != p {
        return Err(PrrrpError::ShapeMismatch {
            what: "lambda0".into(),
            expected: format!("{p} entries (one per model parameter)"),
            got: format!("{} entries", lambda0.nrows()),
        });
    }
    if let Some((i, &v)) = lambda0.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(PrrrpError::InvalidParameter {
            field: format!("lambda0[{i}]"),
            value: v,
            reason: "the initial estimate must be finite",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Uniform in [−1, 1) from a seeded xorshift (no test needs a statistical generator).
    fn uniform(state: &mut u64) -> f64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The kernels of the scalar update against the textbook formulas on random data:
    /// p = P·φ (φ with zeros, as regressor rows have), P − c·p·pᵀ for c of both signs;
    /// the AVX2 copies give the portable ones' bits, and P stays exactly symmetric.
    #[test]
    fn kernels_match_the_straightforward_formulas() {
        let mut st = 0x2545_F491_4F6C_DD1Du64;
        for d in [1usize, 3, 8, 64, 67] {
            let a = DMatrix::from_fn(d, d, |_, _| uniform(&mut st));
            let cov = &a * a.transpose() + DMatrix::identity(d, d);
            let phi =
                DMatrix::from_fn(1, d, |_, j| if j % 3 == 1 { 0.0 } else { uniform(&mut st) });
            let want_p = &cov * phi.row(0).transpose();
            for avx2 in [false, cpu_has_avx2()] {
                let mut p = vec![0.0; d];
                cov_times_row(avx2, cov.as_slice(), &phi, 0, &mut p);
                for i in 0..d {
                    let tol = 1e-14 * (cov.column(i).amax() * phi.amax() * d as f64);
                    assert!((p[i] - want_p[i]).abs() <= tol, "d {d} p[{i}]");
                }
                for c in [0.37, -0.21] {
                    let pv = DVector::from_column_slice(&p);
                    let want = &cov - &pv * pv.transpose() * c;
                    let mut got = cov.clone();
                    let mut q = vec![0.0; d];
                    sym_rank1_sub(avx2, got.as_mut_slice(), &p, c, &mut q);
                    assert_eq!(got, got.transpose(), "d {d} c {c}: not symmetric");
                    let scale = cov.amax() + c.abs() * pv.amax().powi(2);
                    let err = (&got - &want).amax();
                    assert!(err <= 4.0 * f64::EPSILON * scale, "d {d} c {c}: {err}");
                    let mut portable = cov.clone();
                    sym_rank1_sub(false, portable.as_mut_slice(), &p, c, &mut q);
                    assert_eq!(got, portable, "d {d} c {c}: AVX2 and portable differ");
                }
            }
        }
    }
}
