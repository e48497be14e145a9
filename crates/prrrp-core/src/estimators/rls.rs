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
/// the vector update with unit noise covariance, and free of any matrix inversion); their
/// N rank-1 covariance terms are applied in one pass over P at the end of the sample (the
/// later rows see the earlier ones' terms through P·φ − Σ q·(qᵀ·φ)); the forgetting factor
/// is applied once per sample. Cost per sample ≈ N·(2P² + 4P) flops.
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
    /// The rank-1 terms of one sample's rows, applied to P in one pass at its end
    /// ([`sym_rank_sub`]): q_k = √|c_k|·P_k·φ_k (P entries each, row after row) and the
    /// sign of c_k.
    q_rows: Vec<f64>,
    q_sign: Vec<f64>,
    /// The non-zero entries of a regressor row: their columns and values.
    nz_cols: Vec<usize>,
    nz_vals: Vec<f64>,
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
            q_rows: vec![0.0; p.value() * n.value()],
            q_sign: vec![0.0; n.value()],
            nz_cols: vec![0; p.value()],
            nz_vals: vec![0.0; p.value()],
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

    /// `out[j]` = φ_jᵀ·P·φ_j for each row φ_j of `phi` (units of τ² per unit of the
    /// weighted equation error squared; ≥ 0): the variance the covariance gives each
    /// joint's prediction at that regressor. Over the non-zero entries of each row, in the
    /// update's vectorised kernel (`phi` in the estimator's parameter units).
    /// Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `phi` does not have P columns or `out` one entry
    /// per row.
    pub fn row_variances(&mut self, phi: &OMatrix<f64, N, P>, out: &mut [f64]) -> Result<()> {
        let np = self.fit.lambda.nrows();
        if phi.ncols() != np || out.len() != phi.nrows() {
            return Err(PrrrpError::ShapeMismatch {
                what: "row_variances".into(),
                expected: format!("a regressor of {np} columns and one output per row"),
                got: format!("{}×{} and {} outputs", phi.nrows(), phi.ncols(), out.len()),
            });
        }
        let p_phi = self.p_phi.as_mut_slice();
        for (j, v) in out.iter_mut().enumerate() {
            let nz = gather_row(phi, j, &mut self.nz_cols, &mut self.nz_vals);
            let (cols, vals) = (&self.nz_cols[..nz], &self.nz_vals[..nz]);
            cov_times(self.avx2, self.cov.as_slice(), cols, vals, p_phi);
            let mut acc = 0.0;
            for (&c, &f) in cols.iter().zip(vals) {
                acc += f * p_phi[c];
            }
            *v = acc.max(0.0);
        }
        Ok(())
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

    /// P ← D·P·D with D = diag(`d`), d ≥ 0 (dimensionless; a congruence: P stays positive
    /// semidefinite). Opens the covariance after a detected change of the dynamics (d > 1
    /// on the parameters that may have changed), allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] unless `d` has one entry per parameter;
    /// [`PrrrpError::InvalidParameter`] for a negative, NaN or infinite entry (P is left
    /// unchanged).
    pub fn scale_covariance(&mut self, d: &OVector<f64, P>) -> Result<()> {
        let p = self.fit.lambda.nrows();
        crate::error::check_len(
            "scale_covariance d",
            d.nrows(),
            p,
            "entries",
            " (one factor per parameter)",
        )?;
        // NaN or ∞ would poison P for good: refuse before touching it.
        crate::error::check_non_negative(
            "scale_covariance d",
            d.as_slice(),
            "each covariance scale factor must be finite and >= 0 (dimensionless)",
        )?;
        for j in 0..p {
            for i in 0..p {
                self.cov[(i, j)] *= d[i] * d[j];
            }
        }
        Ok(())
    }

    /// P ← P + `m` (units of P), `m` symmetric: opens the covariance along chosen
    /// directions after a detected change. The caller keeps P positive definite (e.g. `m`
    /// from a congruence, T·P·Tᵀ − P). Allocation-free.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] unless `m` is P×P; [`PrrrpError::NonFinite`] for a NaN
    /// or infinite entry (P is left unchanged). `m` may be indefinite, so its sign is the
    /// caller's to keep.
    pub fn add_covariance(&mut self, m: &OMatrix<f64, P, P>) -> Result<()> {
        let p = self.fit.lambda.nrows();
        crate::error::check_shape("add_covariance m", m.shape(), (p, p))?;
        if let Some(i) = m.iter().position(|v| !v.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("add_covariance m[({}, {})]", i % p, i / p),
                row: None,
            });
        }
        self.cov += m;
        Ok(())
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
        let mut m = 0;
        for i in 0..n {
            let w = weights[i];
            if w == 0.0 {
                continue;
            }
            let s = w.sqrt();
            if s != 1.0 {
                self.fit.phi.row_mut(i).scale_mut(s);
            }
            if !self.update_row(i, sample.tau[i] * s, directional, &mut m) {
                return Err(diverged(self.samples));
            }
        }
        self.apply_row_terms(m);
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

    /// P ← P − Σ_k s_k·q_k·q_kᵀ over the `m` rank-1 terms the sample's rows stored.
    #[inline(always)]
    fn apply_row_terms(&mut self, m: usize) {
        let np = self.fit.lambda.nrows();
        let (q, sign) = (&self.q_rows[..m * np], &self.q_sign[..m]);
        sym_rank_sub(self.avx2, self.cov.as_mut_slice(), q, sign);
    }

    /// The scalar update with row `row` of the stored regressor, the `m`-th of its sample
    /// to update: with p = P·φ and r = φᵀ·p, λ ← λ + p·e/d and P ← P − c·p·pᵀ. Without
    /// forgetting (`directional` `None`) d = 1 + r, c = 1/d. With directional forgetting ν
    /// (see [`Forgetting`]) d = r + ν, c = β/d, β = 1 − (1 − ν)/r (a row with r = 0: no
    /// regressor, or a direction already known exactly, is the plain update). P is the
    /// covariance after the sample's earlier rows: the one stored less their rank-1 terms,
    /// which are applied at the end of the sample in one pass ([`sym_rank_sub`]); this row's
    /// term is added to them. `false` if P lost positive definiteness.
    #[inline(always)]
    fn update_row(
        &mut self,
        row: usize,
        tau: f64,
        directional: Option<f64>,
        m: &mut usize,
    ) -> bool {
        let np = self.fit.lambda.nrows();
        let nz = gather_row(&self.fit.phi, row, &mut self.nz_cols, &mut self.nz_vals);
        let (cols, vals) = (&self.nz_cols[..nz], &self.nz_vals[..nz]);
        let p_phi = self.p_phi.as_mut_slice();
        cov_times(self.avx2, self.cov.as_slice(), cols, vals, p_phi);
        // P_k·φ = P·φ − Σ_k s_k·q_k·(q_kᵀ·φ) over the earlier rows k of the sample.
        for k in 0..*m {
            let qk = &self.q_rows[k * np..(k + 1) * np];
            let mut a = 0.0;
            for (&c, &f) in cols.iter().zip(vals) {
                a += f * qk[c];
            }
            axpy(self.avx2, -self.q_sign[k] * a, qk, p_phi);
        }
        let (mut r, mut pred) = (0.0, 0.0);
        for (&c, &f) in cols.iter().zip(vals) {
            r += f * p_phi[c];
            pred += f * self.fit.lambda[c];
        }
        let (den, beta) = match directional {
            Some(nu) => {
                if !r.is_finite() || r < 0.0 {
                    return false;
                }
                if r > 0.0 {
                    (r + nu, 1.0 - (1.0 - nu) / r)
                } else {
                    (1.0 + r, 1.0)
                }
            }
            None => {
                let den = 1.0 + r;
                if !(den > 0.0 && den.is_finite()) {
                    return false;
                }
                (den, 1.0)
            }
        };
        let e = tau - pred;
        let inv = 1.0 / den;
        self.fit.lambda.axpy(e * inv, &self.p_phi, 1.0);
        let c = beta * inv;
        if c != 0.0 {
            let root = c.abs().sqrt();
            let q = &mut self.q_rows[*m * np..(*m + 1) * np];
            for (qv, &pv) in q.iter_mut().zip(self.p_phi.iter()) {
                *qv = root * pv;
            }
            self.q_sign[*m] = c.signum();
            *m += 1;
        }
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

/// The non-zero entries of row `row` of `phi` into `cols` and `vals` (each at least as long
/// as a row); returns their count. Regressor rows are sparse: a joint's row has no entries
/// of the links before it.
#[inline(always)]
fn gather_row<N: Dim, P: Dim>(
    phi: &OMatrix<f64, N, P>,
    row: usize,
    cols: &mut [usize],
    vals: &mut [f64],
) -> usize
where
    DefaultAllocator: Allocator<N, P>,
{
    let mut nz = 0;
    for c in 0..phi.ncols() {
        let f = phi[(row, c)];
        if f != 0.0 {
            cols[nz] = c;
            vals[nz] = f;
            nz += 1;
        }
    }
    nz
}

/// Rows per register block of the kernels below: 32 f64, eight AVX2 registers, summed in
/// registers and stored once (the column-by-column axpy they replace stored every partial
/// sum, and the stores bounded its speed). Eight independent sums, not four: each sum
/// waits for its previous add, and four left the adder idle half the time (perf).
const BLOCK: usize = 32;

/// The register blocks of a column of `d` entries, (start, length): [`BLOCK`] entries while
/// they fit, then 4 (one AVX2 register), then single entries.
#[inline(always)]
fn blocks(d: usize) -> impl Iterator<Item = (usize, usize)> {
    let mut start = 0;
    std::iter::from_fn(move || {
        let len = [BLOCK, 4, 1].into_iter().find(|&l| start + l <= d)?;
        start += len;
        Some((start - len, len))
    })
}

/// p = P·φ over the non-zero entries of φ (`cols`, `vals`), P column-major d×d, d =
/// `p.len()`. Each entry sums the products in the order of `cols`, from 0.
#[inline(always)]
fn cov_times(avx2: bool, cov: &[f64], cols: &[usize], vals: &[f64], p: &mut [f64]) {
    /// Entries `start..start + L` of p.
    #[inline(always)]
    fn block<const L: usize>(
        cov: &[f64],
        cols: &[usize],
        vals: &[f64],
        start: usize,
        p: &mut [f64],
    ) {
        let d = p.len();
        let mut acc = [0.0; L];
        for (&c, &f) in cols.iter().zip(vals) {
            let col: &[f64; L] = cov[c * d + start..c * d + start + L]
                .try_into()
                .expect("a block of L entries");
            for l in 0..L {
                acc[l] += f * col[l];
            }
        }
        p[start..start + L].copy_from_slice(&acc);
    }
    #[inline(always)]
    fn body(cov: &[f64], cols: &[usize], vals: &[f64], p: &mut [f64]) {
        for (start, len) in blocks(p.len()) {
            match len {
                BLOCK => block::<BLOCK>(cov, cols, vals, start, p),
                4 => block::<4>(cov, cols, vals, start, p),
                _ => block::<1>(cov, cols, vals, start, p),
            }
        }
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn wide(cov: &[f64], cols: &[usize], vals: &[f64], p: &mut [f64]) {
        body(cov, cols, vals, p)
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is set only when the CPU reports AVX2.
        return unsafe { wide(cov, cols, vals, p) };
    }
    let _ = avx2;
    body(cov, cols, vals, p)
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

/// P ← P − Σ_k s_k·q_k·q_kᵀ (P column-major d×d, symmetric; `q` the q_k one after the
/// other, d entries each; `sign` the s_k = ±1), one pass over P whatever the number of
/// terms. Entry (i, j) subtracts Σ_k q_k,i·(s_k·q_k,j) and entry (j, i) the same products
/// in the same order (s_k only flips signs), so P stays exactly symmetric without
/// mirroring.
#[inline(always)]
fn sym_rank_sub(avx2: bool, cov: &mut [f64], q: &[f64], sign: &[f64]) {
    #[inline(always)]
    fn body(cov: &mut [f64], q: &[f64], sign: &[f64]) {
        let m = sign.len();
        if m == 0 {
            return;
        }
        let d = q.len() / m;
        let mut t = [0.0; 64];
        if m > t.len() {
            // More rows than a sample of any arm has: one term at a time.
            for k in 0..m {
                sym_rank_sub_body(cov, &q[k * d..(k + 1) * d], &sign[k..k + 1], d, &mut t);
            }
            return;
        }
        sym_rank_sub_body(cov, q, sign, d, &mut t);
    }
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn wide(cov: &mut [f64], q: &[f64], sign: &[f64]) {
        body(cov, q, sign)
    }
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` is set only when the CPU reports AVX2.
        return unsafe { wide(cov, q, sign) };
    }
    let _ = avx2;
    body(cov, q, sign)
}

/// [`sym_rank_sub`] for at most `t.len()` terms.
#[inline(always)]
fn sym_rank_sub_body(cov: &mut [f64], q: &[f64], sign: &[f64], d: usize, t: &mut [f64]) {
    /// Entries `start..start + L` of a column, `t` its factors s_k·q_k,j.
    #[inline(always)]
    fn block<const L: usize>(col: &mut [f64], q: &[f64], t: &[f64], d: usize, start: usize) {
        let mut acc = [0.0; L];
        for (k, &tk) in t.iter().enumerate() {
            let qk: &[f64; L] = q[k * d + start..k * d + start + L]
                .try_into()
                .expect("a block of L entries");
            for l in 0..L {
                acc[l] += qk[l] * tk;
            }
        }
        let out: &mut [f64; L] = (&mut col[start..start + L])
            .try_into()
            .expect("a block of L entries");
        for l in 0..L {
            out[l] -= acc[l];
        }
    }
    let m = sign.len();
    for j in 0..d {
        for k in 0..m {
            t[k] = sign[k] * q[k * d + j];
        }
        let t = &t[..m];
        let col = &mut cov[j * d..(j + 1) * d];
        for (start, len) in blocks(d) {
            match len {
                BLOCK => block::<BLOCK>(col, q, t, d, start),
                4 => block::<4>(col, q, t, d, start),
                _ => block::<1>(col, q, t, d, start),
            }
        }
    }
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
        let mut m = 0;
        for i in 0..n {
            if !self.update_row(i, sample.tau[i], None, &mut m) {
                return Err(diverged(self.samples));
            }
        }
        self.apply_row_terms(m);
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
        // The initial covariance too: a δ of 1e300 cancelled to round-off in the first
        // updates and diverged at sample 5, where only the other two causes were named.
        hint: "the covariance is no longer positive definite or finite: use a forgetting \
               factor closer to 1, a smaller initial covariance (1e6 by default) or a \
               trajectory that excites every parameter",
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

    /// The kernels against nalgebra on random data: p = P·φ over φ's non-zeros (φ with
    /// zeros, as regressor rows have) and P − Σ_k s_k·q_k·q_kᵀ for terms of both signs; the
    /// AVX2 copies give the portable ones' bits, and P stays exactly symmetric.
    #[test]
    fn kernels_match_the_straightforward_formulas() {
        let mut st = 0x2545_F491_4F6C_DD1Du64;
        for d in [1usize, 3, 8, 16, 64, 67, 70] {
            let a = DMatrix::from_fn(d, d, |_, _| uniform(&mut st));
            let cov = &a * a.transpose() + DMatrix::identity(d, d);
            let phi =
                DMatrix::from_fn(1, d, |_, j| if j % 3 == 1 { 0.0 } else { uniform(&mut st) });
            let want_p = &cov * phi.row(0).transpose();
            let (mut cols, mut vals) = (vec![0; d], vec![0.0; d]);
            let nz = gather_row(&phi, 0, &mut cols, &mut vals);
            assert_eq!(nz, (0..d).filter(|j| j % 3 != 1).count());
            let mut first = None;
            for avx2 in [false, cpu_has_avx2()] {
                let mut p = vec![0.0; d];
                cov_times(avx2, cov.as_slice(), &cols[..nz], &vals[..nz], &mut p);
                for i in 0..d {
                    let tol = 1e-14 * (cov.column(i).amax() * phi.amax() * d as f64);
                    assert!((p[i] - want_p[i]).abs() <= tol, "d {d} p[{i}]");
                }
                assert_eq!(
                    *first.get_or_insert_with(|| p.clone()),
                    p,
                    "d {d}: AVX2 differs"
                );
            }
            for m in [1usize, 2, 7] {
                let q: Vec<f64> = (0..m * d).map(|_| uniform(&mut st)).collect();
                let sign: Vec<f64> = (0..m)
                    .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
                    .collect();
                let mut want = cov.clone();
                for k in 0..m {
                    let qk = DVector::from_column_slice(&q[k * d..(k + 1) * d]);
                    want -= &qk * qk.transpose() * sign[k];
                }
                let mut portable = cov.clone();
                sym_rank_sub(false, portable.as_mut_slice(), &q, &sign);
                let mut got = cov.clone();
                sym_rank_sub(cpu_has_avx2(), got.as_mut_slice(), &q, &sign);
                assert_eq!(got, got.transpose(), "d {d} m {m}: not symmetric");
                assert_eq!(got, portable, "d {d} m {m}: AVX2 and portable differ");
                let err = (&got - &want).amax();
                let scale = cov.amax() + m as f64;
                assert!(err <= 8.0 * f64::EPSILON * scale, "d {d} m {m}: {err}");
            }
        }
    }

    /// A sample's rows applied to P in one pass at its end give the textbook sequence of
    /// scalar updates (each row with P after the rows before it), without forgetting and
    /// with directional forgetting whose β is negative on some rows (P grows along
    /// them), on the PUMA 560's regressor rows with weights (one joint skipped).
    #[test]
    fn one_pass_update_equals_the_sequential_updates() {
        use crate::{BaseOptions, SerialChain};
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let (n, p) = (chain.dof(), base.count());
        let mut st = 0x1234_5678_9ABC_DEF1u64;
        let a = DMatrix::from_fn(p, p, |_, _| uniform(&mut st));
        let mut negative_beta = false;
        for (forgetting, scale) in [
            (Forgetting::None, 1.0),
            (Forgetting::Directional(0.9), 1.0),
            (Forgetting::Directional(0.9), 1e-4),
        ] {
            let p0 = (&a * a.transpose() / p as f64 + DMatrix::identity(p, p)) * scale;
            let p0 = (&p0 + p0.transpose()) * 0.5;
            let lam0 = DVector::from_fn(p, |_, _| uniform(&mut st));
            let model = chain.base_model(&base).unwrap();
            let mut rls = RlsOf::new(model, lam0.clone(), RlsConfig::default()).unwrap();
            rls.set_initial_covariance(&p0).unwrap();
            let (mut want_cov, mut want_lam) = (p0.clone(), lam0.clone());
            for sample in 0..3 {
                let q = DVector::from_fn(n, |_, _| uniform(&mut st));
                let qd = DVector::from_fn(n, |_, _| uniform(&mut st));
                let qdd = DVector::from_fn(n, |_, _| uniform(&mut st));
                let tau = DVector::from_fn(n, |_, _| 10.0 * uniform(&mut st));
                let w = DVector::from_fn(n, |j, _| if j == 2 { 0.0 } else { 0.5 + j as f64 });
                rls.update_weighted(SampleOf::new(&q, &qd, &qdd, &tau), &w, forgetting)
                    .unwrap();
                // The rows the update used (scaled by √w).
                let phi = rls.fit.phi.clone();
                for i in (0..n).filter(|&i| w[i] != 0.0) {
                    let f = phi.row(i).transpose();
                    let pf = &want_cov * &f;
                    let r = f.dot(&pf);
                    let (den, beta) = match forgetting {
                        Forgetting::Directional(nu) if r > 0.0 => (r + nu, 1.0 - (1.0 - nu) / r),
                        _ => (1.0 + r, 1.0),
                    };
                    negative_beta |= beta < 0.0;
                    let e = tau[i] * w[i].sqrt() - f.dot(&want_lam);
                    want_lam += &pf * (e / den);
                    want_cov -= &pf * pf.transpose() * (beta / den);
                }
                let cov = rls.covariance();
                assert_eq!(cov, &cov.transpose(), "sample {sample}: not symmetric");
                let err = (cov - &want_cov).amax() / want_cov.amax();
                assert!(
                    err < 1e-10,
                    "{forgetting:?} sample {sample}: P off by {err:e}"
                );
                let err = (rls.estimate() - &want_lam).amax() / want_lam.amax();
                assert!(
                    err < 1e-10,
                    "{forgetting:?} sample {sample}: λ off by {err:e}"
                );
            }
        }
        assert!(negative_beta, "no row took the β < 0 branch");
    }

    /// φ_jᵀ·P·φ_j of every regressor row against nalgebra's products, on a random SPD P
    /// and rows with zeros (as a chain's have), in both kernels.
    #[test]
    fn row_variances_are_the_quadratic_forms() {
        use crate::{BaseOptions, SerialChain};
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let (n, p) = (chain.dof(), base.count());
        let mut rls = RlsOf::new(model, DVector::zeros(p), RlsConfig::default()).unwrap();
        let mut st = 0x9E37_79B9_7F4A_7C15u64;
        let a = DMatrix::from_fn(p, p, |_, _| uniform(&mut st));
        let cov = &a * a.transpose() + DMatrix::identity(p, p) * 0.1;
        let cov = (&cov + cov.transpose()) * 0.5;
        rls.set_initial_covariance(&cov).unwrap();
        let phi = DMatrix::from_fn(n, p, |j, c| if c < 2 * j { 0.0 } else { uniform(&mut st) });
        for avx2 in [false, cpu_has_avx2()] {
            rls.avx2 = avx2;
            let mut out = vec![0.0; n];
            rls.row_variances(&phi, &mut out).unwrap();
            for (j, got) in out.iter().enumerate() {
                let r = phi.row(j).transpose();
                let want = (r.transpose() * &cov * &r)[(0, 0)];
                let scale = (r.abs().transpose() * cov.abs() * r.abs())[(0, 0)];
                assert!(
                    (got - want).abs() <= 1e-13 * scale,
                    "row {j}: {got} vs {want}"
                );
                assert!(want > 0.0);
            }
        }
        let mut short = vec![0.0; n - 1];
        assert!(rls.row_variances(&phi, &mut short).is_err());
    }

    /// A covariance opening of the wrong size, or with NaN, is refused and leaves P as it
    /// was (a short `d` panicked indexing it, a wrong-size `m` failed nalgebra's assertion,
    /// and NaN went into P).
    #[test]
    fn covariance_openings_refuse_wrong_sizes_and_non_finite_values() {
        use crate::{BaseOptions, SerialChain};
        let chain = SerialChain::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let p = base.count();
        let mut rls = RlsOf::new(model, DVector::zeros(p), RlsConfig::default()).unwrap();
        let before = rls.covariance().clone();
        let short = rls.scale_covariance(&DVector::from_element(2, 1.0));
        assert!(
            matches!(short, Err(PrrrpError::ShapeMismatch { .. })),
            "{short:?}"
        );
        for bad in [f64::NAN, f64::INFINITY, -1.0] {
            let mut d = DVector::from_element(p, 2.0);
            d[p - 1] = bad;
            let err = rls.scale_covariance(&d);
            assert!(
                matches!(&err, Err(PrrrpError::InvalidParameter { field, .. })
                    if *field == format!("scale_covariance d[{}]", p - 1)),
                "{bad}: {err:?}"
            );
        }
        let wrong = rls.add_covariance(&DMatrix::identity(2, 2));
        assert!(
            matches!(wrong, Err(PrrrpError::ShapeMismatch { .. })),
            "{wrong:?}"
        );
        let mut m = DMatrix::identity(p, p);
        m[(1, 0)] = f64::NAN;
        let nan = rls.add_covariance(&m);
        assert!(matches!(nan, Err(PrrrpError::NonFinite { .. })), "{nan:?}");
        assert_eq!(rls.covariance(), &before);
        // Valid openings still apply.
        rls.scale_covariance(&DVector::from_element(p, 2.0))
            .unwrap();
        rls.add_covariance(&DMatrix::identity(p, p)).unwrap();
        assert_eq!(rls.covariance()[(0, 0)], 4.0 * before[(0, 0)] + 1.0);
    }
}
