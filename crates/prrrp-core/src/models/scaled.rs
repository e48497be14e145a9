//! Parameter scaling for the gradient estimators: a model reparametrised by λ = D·γ, D
//! diagonal and positive (column equilibration, Jacobi preconditioning).
//!
//! Adaline and the Hopfield network descend the equation error; their speed in each
//! direction of parameter space is set by the eigenvalues of WᵀW (W the stacked
//! regressor), so they are slow when the columns of W differ in scale — as they do for a
//! 6R arm, whose base parameters mix kg, kg·m and kg·m² and whose wrist parameters are a
//! thousand times smaller than the shoulder's. With λ = D·γ the regressor becomes Φ·D:
//! choosing D_j = 1/RMS(column j of W) ([`ScaledModel::equilibrated`]) gives every column
//! unit RMS, which lowers cond(W) (often by an order of magnitude) and the number of
//! epochs by its square. The estimators then run unchanged on the scaled model, and
//! [`ScaledModel::to_model`] maps their γ̂ back to λ̂ = D·γ̂. Least squares is invariant
//! under the scaling (up to round-off).
//!
//! At run-time sizes one [`LinearModel`] implementation serves every model whose
//! parameters are an affine image of another model's ([`Reparametrisation`]): the scaled
//! models here and the online identifier's payload model.

use nalgebra::allocator::Allocator;
use nalgebra::{
    DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix, SVector, U1,
};

use crate::error::{check_shape, PrrrpError, Result};
use crate::estimators::{DynSamples, Samples, SamplesOf};
use crate::models::{ForwardDerivatives, ForwardDerivativesOf, LinearDynamics, LinearModel};

/// A [`LinearDynamics`] model whose parameters are γ = D⁻¹·λ for the parameters λ of an
/// inner model, with D = diag(`scale`) positive: Φ_γ = Φ·D, and every method at γ equals
/// the inner model's at λ = D·γ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaledModel<M, const P: usize> {
    inner: M,
    scale: SVector<f64, P>,
}

impl<M, const P: usize> ScaledModel<M, P> {
    /// The inner model with parameters λ = diag(`scale`)·γ.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if an entry of `scale` is not finite and > 0.
    pub fn new(inner: M, scale: SVector<f64, P>) -> Result<Self> {
        check_scale(scale.as_slice())?;
        Ok(Self { inner, scale })
    }

    /// The scale D (units of λ per unit of γ).
    pub fn scale(&self) -> &SVector<f64, P> {
        &self.scale
    }

    /// The inner model.
    pub fn inner(&self) -> &M {
        &self.inner
    }

    /// λ = D·γ: the inner model's parameters for scaled parameters γ.
    pub fn to_model(&self, gamma: &SVector<f64, P>) -> SVector<f64, P> {
        gamma.component_mul(&self.scale)
    }

    /// γ = D⁻¹·λ: the scaled parameters of the inner model's λ.
    pub fn from_model(&self, lambda: &SVector<f64, P>) -> SVector<f64, P> {
        lambda.component_div(&self.scale)
    }
}

impl<M, const P: usize> ScaledModel<M, P> {
    /// Column equilibration on `data`: D_j = 1/RMS_k,i(Φ(q_k, q̇_k, q̈_k)_ij), so that every
    /// column of the scaled stacked regressor has unit RMS (norm √(N·n)). Then γ_j is the
    /// RMS joint force (units of τ) that parameter j explains along `data`.
    ///
    /// # Errors
    /// [`PrrrpError::TooFewSamples`] for empty data; [`PrrrpError::NonFinite`] naming the
    /// first sample with a NaN/∞ state; [`PrrrpError::InvalidParameter`] (field
    /// `regressor column j`) if column j of the regressor is zero along the whole of
    /// `data` (that parameter is not excited).
    pub fn equilibrated<const N: usize>(inner: M, data: &Samples<'_, N>) -> Result<Self>
    where
        M: LinearDynamics<N, P>,
    {
        let scale = equilibrating_scale(&inner, data)?;
        Self::new(inner, scale)
    }
}

/// D_j = 1/RMS of column j of the stacked regressor of `inner` along `data`, the scale of
/// both [`ScaledModel::equilibrated`] and [`DynScaledModel::equilibrated`] (their errors).
fn equilibrating_scale<M, N: Dim, P: Dim>(
    inner: &M,
    data: &SamplesOf<'_, N>,
) -> Result<OVector<f64, P>>
where
    M: LinearModel<N, P>,
    DefaultAllocator: Allocator<N> + Allocator<P> + Allocator<N, N> + Allocator<N, P>,
{
    if data.is_empty() {
        return Err(PrrrpError::TooFewSamples { needed: 1, got: 0 });
    }
    let (n, p) = inner.dims();
    let mut ws = inner.workspace();
    let mut phi = OMatrix::<f64, N, P>::zeros_generic(n, p);
    let mut ss = OVector::<f64, P>::zeros_generic(p, U1);
    for (k, s) in data.iter().enumerate() {
        s.check(n.value())
            .map_err(|e| crate::estimators::with_row(e, k))?;
        inner.regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)?;
        for (j, col) in phi.column_iter().enumerate() {
            ss[j] += col.norm_squared();
        }
    }
    let rows = (n.value() * data.len()) as f64;
    if let Some(j) = ss.iter().position(|&v| v <= 0.0) {
        return Err(PrrrpError::InvalidParameter {
            field: format!("regressor column {j}"),
            value: 0.0,
            reason: "is zero along the whole of the data: that parameter is not excited",
        });
    }
    Ok(ss.map(|v| (rows / v).sqrt()))
}

/// The [`PrrrpError::InvalidParameter`] of the first entry of a scale D that is not finite
/// and > 0.
fn check_scale(scale: &[f64]) -> Result<()> {
    if let Some((j, &s)) = scale
        .iter()
        .enumerate()
        .find(|(_, &s)| !(s.is_finite() && s > 0.0))
    {
        return Err(PrrrpError::InvalidParameter {
            field: format!("scale[{j}]"),
            value: s,
            reason: "must be finite and > 0",
        });
    }
    Ok(())
}

impl<M: LinearDynamics<N, P>, const N: usize, const P: usize> LinearDynamics<N, P>
    for ScaledModel<M, P>
{
    #[inline]
    fn regressor(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
    ) -> SMatrix<f64, N, P> {
        let mut phi = self.inner.regressor(q, qd, qdd);
        for (mut col, &s) in phi.column_iter_mut().zip(self.scale.iter()) {
            col *= s;
        }
        phi
    }

    #[inline]
    fn inverse_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        qdd: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> SVector<f64, N> {
        self.inner
            .inverse_dynamics(q, qd, qdd, &self.to_model(lambda))
    }

    #[inline]
    fn forward_dynamics(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<SVector<f64, N>> {
        self.inner
            .forward_dynamics(q, qd, tau, &self.to_model(lambda))
    }

    /// The inner model's derivatives at λ = D·γ, with ∂q̈/∂γ = ∂q̈/∂λ·D.
    fn forward_derivatives(
        &self,
        q: &SVector<f64, N>,
        qd: &SVector<f64, N>,
        tau: &SVector<f64, N>,
        lambda: &SVector<f64, P>,
    ) -> Result<ForwardDerivatives<N, P>> {
        let mut d = self
            .inner
            .forward_derivatives(q, qd, tau, &self.to_model(lambda))?;
        for (mut col, &s) in d.dqdd_dlambda.column_iter_mut().zip(self.scale.iter()) {
            col *= s;
        }
        Ok(d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Robot, Vec5};

    fn state(k: f64) -> (Vec5, Vec5, Vec5) {
        let v = |a: f64| Vec5::from_fn(|i, _| (a * (i as f64 + 1.0) + k).sin());
        (v(0.7), v(1.3), v(2.1))
    }

    #[test]
    fn scaled_model_is_the_inner_model_at_d_gamma() {
        let robot = Robot::paper();
        let (model, lambda) = (robot.model(), robot.base_parameters());
        let scale = SVector::<f64, 8>::from_fn(|j, _| 0.1 * (j as f64 + 1.0));
        let sm = ScaledModel::new(model, scale).unwrap();
        let gamma = sm.from_model(&lambda);
        assert!((sm.to_model(&gamma) - lambda).norm() < 1e-14 * lambda.norm());
        let (q, qd, qdd) = state(0.3);
        let phi = model.regressor(&q, &qd, &qdd);
        let phis = sm.regressor(&q, &qd, &qdd);
        for j in 0..8 {
            for i in 0..5 {
                assert_eq!(phis[(i, j)], phi[(i, j)] * scale[j]);
            }
        }
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
        assert!((phis * gamma - tau).norm() < 1e-12 * tau.norm());
        assert!((sm.inverse_dynamics(&q, &qd, &qdd, &gamma) - tau).norm() < 1e-12 * tau.norm());
        let fd = sm.forward_dynamics(&q, &qd, &tau, &gamma).unwrap();
        assert!((fd - qdd).norm() < 1e-9 * qdd.norm());
        // ∂q̈/∂γ against central differences in γ (independent of the chain rule used).
        let d = sm.forward_derivatives(&q, &qd, &tau, &gamma).unwrap();
        for j in 0..8 {
            let h = 1e-6 * gamma[j].abs().max(1e-3);
            let (mut gp, mut gm) = (gamma, gamma);
            gp[j] += h;
            gm[j] -= h;
            let num = (sm.forward_dynamics(&q, &qd, &tau, &gp).unwrap()
                - sm.forward_dynamics(&q, &qd, &tau, &gm).unwrap())
                / (2.0 * h);
            let err = (d.dqdd_dlambda.column(j) - num).norm();
            assert!(err < 1e-6 * (1.0 + num.norm()), "column {j}: {err}");
        }
    }

    #[test]
    fn equilibrated_columns_have_unit_rms() {
        let robot = Robot::paper();
        let model = robot.model();
        let (mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![]);
        for k in 0..50 {
            let (a, b, c) = state(0.1 * k as f64);
            q.push(a);
            qd.push(b);
            qdd.push(c);
            tau.push(Vec5::zeros());
        }
        let data = Samples::new(&q, &qd, &qdd, &tau).unwrap();
        let sm = ScaledModel::equilibrated(model, &data).unwrap();
        let mut ss = SVector::<f64, 8>::zeros();
        for s in data.iter() {
            let phi = sm.regressor(s.q, s.qd, s.qdd);
            for j in 0..8 {
                ss[j] += phi.column(j).norm_squared();
            }
        }
        for j in 0..8 {
            assert!((ss[j] / 250.0 - 1.0).abs() < 1e-12, "column {j}: {}", ss[j]);
        }
        // Bad input is a typed error.
        let empty = Samples::new(&q[..0], &qd[..0], &qdd[..0], &tau[..0]).unwrap();
        assert!(matches!(
            ScaledModel::equilibrated(model, &empty),
            Err(PrrrpError::TooFewSamples { .. })
        ));
        // At rest only gravity acts: λ1 (via F1 = λ1·g + …) stays, the planar inertia
        // columns vanish.
        let z = vec![Vec5::zeros(); 3];
        let rest = Samples::new(&z, &z, &z, &z).unwrap();
        assert!(matches!(
            ScaledModel::equilibrated(model, &rest),
            Err(PrrrpError::InvalidParameter { .. })
        ));
        let mut bad = scale_ones();
        bad[3] = 0.0;
        assert!(matches!(
            ScaledModel::new(model, bad),
            Err(PrrrpError::InvalidParameter { .. })
        ));
    }

    fn scale_ones() -> SVector<f64, 8> {
        SVector::repeat(1.0)
    }
}

/// [`ScaledModel`] for a run-time-size model (e.g. [`crate::DynChainBaseModel`]): the
/// parameters are γ = D⁻¹·λ of the inner model's λ, D = diag(`scale`) positive, so that
/// Φ_γ = Φ·D and every method at γ equals the inner model's at λ = D·γ. Use it, as
/// [`ScaledModel`], to equilibrate the columns for Adaline and the Hopfield network.
///
/// [`DynScaledModel::whitened`] goes one step further for the gradient methods: λ = D·T·γ
/// with T upper triangular, chosen from the data so that the columns of the stacked
/// regressor W·D·T are orthogonal with unit RMS (cond = 1).
#[derive(Debug, Clone, PartialEq)]
pub struct DynScaledModel<M> {
    inner: M,
    scale: DVector<f64>,
    /// T and T⁻¹ of a whitened model (λ = D·T·γ); `None`: T = 1.
    mix: Option<(DMatrix<f64>, DMatrix<f64>)>,
}

/// Workspace of [`DynScaledModel`]: the inner model's, λ, and the inner model's regressor and
/// derivatives before the map to γ.
pub type DynScaledWorkspace<W> = ReparametrisedWorkspace<W>;

impl<M: LinearModel<Dyn, Dyn>> DynScaledModel<M> {
    /// The inner model with parameters λ = diag(`scale`)·γ.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `scale` does not have one entry per parameter of
    /// the inner model; [`PrrrpError::InvalidParameter`] if an entry is not finite and > 0.
    pub fn new(inner: M, scale: DVector<f64>) -> Result<Self> {
        let p = inner.dims().1.value();
        if scale.len() != p {
            return Err(PrrrpError::ShapeMismatch {
                what: "scale".into(),
                expected: format!("{p} entries (one per model parameter)"),
                got: format!("{} entries", scale.len()),
            });
        }
        check_scale(scale.as_slice())?;
        Ok(Self {
            inner,
            scale,
            mix: None,
        })
    }

    /// Column equilibration on `data`, as [`ScaledModel::equilibrated`]: D_j = 1/RMS of
    /// column j of the stacked regressor, so that γ_j is the RMS joint force (units of τ)
    /// that parameter j explains along `data`.
    ///
    /// # Errors
    /// [`PrrrpError::TooFewSamples`] for empty data; [`PrrrpError::ShapeMismatch`] or
    /// [`PrrrpError::NonFinite`] naming the first sample of the wrong size or with a NaN/∞;
    /// [`PrrrpError::InvalidParameter`] (field `regressor column j`) if column j is zero
    /// along the whole of `data` (that parameter is not excited).
    pub fn equilibrated(inner: M, data: &DynSamples<'_>) -> Result<Self> {
        let scale = equilibrating_scale(&inner, data)?;
        Self::new(inner, scale)
    }

    /// Whitening on `data`: the equilibrated model ([`Self::equilibrated`], scale D) with
    /// λ = D·T·γ, T = L⁻ᵀ for the Cholesky factor L of the Gram G = (W·D)ᵀ(W·D)/rows of
    /// the equilibrated stacked regressor, so that (W·D·T)ᵀ(W·D·T) = rows·1: the columns
    /// are orthogonal with unit RMS and cond(W·D·T) = 1.
    ///
    /// Why: a gradient method's error in the direction of an eigenvector of WᵀW decays
    /// as (1 − μ·e_i/e_max) per pass, so it needs ≈ cond(W)² passes; column equilibration
    /// removes the spread of units, but a trajectory that excites two parameters alike
    /// (cond(W·D) ≈ 100 on gentle motions of the paper's arm) still costs 10⁴ passes.
    /// After whitening every direction decays at the same rate. The estimators run
    /// unchanged on the new parameters γ (each γ_i is the RMS joint force of one
    /// orthogonal direction of the data), and [`Self::to_model`] maps γ̂ back. The
    /// least-squares solution is the same in any coordinates, so the methods' fixed
    /// points do not move.
    ///
    /// Data whose Gram is not positive definite in floating point (a parameter the data
    /// do not excite) keep the equilibrated model (T = 1).
    ///
    /// # Errors
    /// As [`Self::equilibrated`].
    pub fn whitened(inner: M, data: &DynSamples<'_>) -> Result<Self> {
        let mut out = Self::equilibrated(inner, data)?;
        let (n, p) = out.inner.dims();
        let (n, p) = (n.value(), p.value());
        let mut ws = out.inner.workspace();
        let mut phi = DMatrix::zeros(n, p);
        let mut gram = DMatrix::<f64>::zeros(p, p);
        for (k, s) in data.iter().enumerate() {
            if k % 1024 == 0 {
                crate::interrupt::check("whitening")?;
            }
            out.inner
                .regressor_into(&mut ws, s.q, s.qd, s.qdd, &mut phi)?;
            for (mut col, &d) in phi.column_iter_mut().zip(out.scale.iter()) {
                col *= d;
            }
            gram.gemm_tr(1.0, &phi, &phi, 1.0);
        }
        gram /= (n * data.len()) as f64;
        let Some(chol) = gram.cholesky() else {
            return Ok(out);
        };
        let l = chol.l();
        let t_inv = l.transpose();
        let Some(t) = t_inv.clone().try_inverse() else {
            return Ok(out);
        };
        if !t.iter().all(|v| v.is_finite()) {
            return Ok(out);
        }
        out.mix = Some((t, t_inv));
        Ok(out)
    }

    /// Whether the model is whitened (λ = D·T·γ with T ≠ 1, see [`Self::whitened`]).
    pub fn is_whitened(&self) -> bool {
        self.mix.is_some()
    }

    /// The scale D (units of λ per unit of γ; per unit of T·γ when whitened).
    pub fn scale(&self) -> &DVector<f64> {
        &self.scale
    }

    /// The inner model.
    pub fn inner(&self) -> &M {
        &self.inner
    }

    /// λ = D·γ (D·T·γ when whitened): the inner model's parameters for scaled
    /// parameters γ.
    pub fn to_model(&self, gamma: &DVector<f64>) -> DVector<f64> {
        match &self.mix {
            Some((t, _)) => (t * gamma).component_mul(&self.scale),
            None => gamma.component_mul(&self.scale),
        }
    }

    /// γ = D⁻¹·λ (T⁻¹·D⁻¹·λ when whitened): the scaled parameters of the inner model's λ.
    pub fn from_model(&self, lambda: &DVector<f64>) -> DVector<f64> {
        let g = lambda.component_div(&self.scale);
        match &self.mix {
            Some((_, t_inv)) => t_inv * g,
            None => g,
        }
    }
}

/// λ = D·γ (D·T·γ when whitened).
impl<M: LinearModel<Dyn, Dyn>> Reparametrisation for DynScaledModel<M> {
    type Inner = M;

    fn inner(&self) -> &M {
        &self.inner
    }

    fn count(&self) -> usize {
        self.scale.len()
    }

    fn to_inner(&self, gamma: &DVector<f64>, lambda: &mut DVector<f64>) -> Result<()> {
        let what = "lambda (scaled parameters)";
        crate::error::check_len(what, gamma.len(), self.scale.len(), "entries", "")?;
        match &self.mix {
            Some((t, _)) => lambda.gemv(1.0, t, gamma, 0.0),
            None => lambda.copy_from(gamma),
        }
        lambda.component_mul_assign(&self.scale);
        Ok(())
    }

    fn map_columns(&self, m: &mut DMatrix<f64>, out: &mut DMatrix<f64>) {
        for (mut col, &s) in m.column_iter_mut().zip(self.scale.iter()) {
            col *= s;
        }
        match &self.mix {
            Some((t, _)) => out.gemm(1.0, m, t, 0.0),
            None => out.copy_from(m),
        }
    }
}

/// A run-time-size model whose parameters θ are an affine image of an inner model's:
/// λ = a + J·θ. Then Φ_θ = Φ·J, ∂q̈/∂θ = ∂q̈/∂λ·J, and every other quantity is the inner
/// model's at λ, so one [`LinearModel`] implementation (below) serves every such model:
/// [`DynScaledModel`] (a = 0, J = D·T) and the online identifier's payload model
/// (a = β_arm, J = K_tip).
pub trait Reparametrisation {
    /// The model whose parameters λ are mapped to.
    type Inner: LinearModel<Dyn, Dyn>;

    /// The inner model.
    fn inner(&self) -> &Self::Inner;

    /// The number of parameters θ.
    fn count(&self) -> usize;

    /// λ = a + J·θ into `lambda` (the inner model's parameter count).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if θ does not have [`Self::count`] entries.
    fn to_inner(&self, theta: &DVector<f64>, lambda: &mut DVector<f64>) -> Result<()>;

    /// `out` = `m`·J for `m` with the inner model's parameter columns (`m` may be
    /// overwritten).
    fn map_columns(&self, m: &mut DMatrix<f64>, out: &mut DMatrix<f64>);

    /// Whether λ = θ: then every call is the inner model's own, its fast paths
    /// ([`LinearModel::forward_derivatives_at_into`],
    /// [`LinearModel::forward_derivatives_factored_into`]) included.
    fn is_identity(&self) -> bool {
        false
    }
}

/// Workspace of a [`Reparametrisation`]: the inner model's, λ, and the inner model's
/// regressor and derivatives before the map to θ.
#[derive(Debug, Clone)]
pub struct ReparametrisedWorkspace<W> {
    pub(crate) inner: W,
    lambda: DVector<f64>,
    phi: DMatrix<f64>,
    fd: ForwardDerivativesOf<Dyn, Dyn>,
}

impl<R: Reparametrisation> LinearModel<Dyn, Dyn> for R {
    type Workspace = ReparametrisedWorkspace<<R::Inner as LinearModel<Dyn, Dyn>>::Workspace>;

    fn dims(&self) -> (Dyn, Dyn) {
        (self.inner().dims().0, Dyn(self.count()))
    }

    fn workspace(&self) -> Self::Workspace {
        let (n, q) = self.inner().dims();
        ReparametrisedWorkspace {
            inner: self.inner().workspace(),
            lambda: DVector::zeros(q.value()),
            phi: DMatrix::zeros(n.value(), q.value()),
            fd: ForwardDerivativesOf::zeros(n, q),
        }
    }

    fn regressor_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DMatrix<f64>,
    ) -> Result<()> {
        if self.is_identity() {
            return self.inner().regressor_into(&mut ws.inner, q, qd, qdd, out);
        }
        let shape = (ws.phi.nrows(), self.count());
        check_shape("regressor output", out.shape(), shape)?;
        self.inner()
            .regressor_into(&mut ws.inner, q, qd, qdd, &mut ws.phi)?;
        self.map_columns(&mut ws.phi, out);
        Ok(())
    }

    fn inverse_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        theta: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<()> {
        let lambda = load(self, &mut ws.lambda, theta)?;
        self.inner()
            .inverse_dynamics_into(&mut ws.inner, q, qd, qdd, lambda, out)
    }

    fn forward_dynamics_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        tau: &DVector<f64>,
        theta: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<()> {
        let lambda = load(self, &mut ws.lambda, theta)?;
        self.inner()
            .forward_dynamics_into(&mut ws.inner, q, qd, tau, lambda, out)
    }

    /// ∂q̈/∂θ = ∂q̈/∂λ·J; the other derivatives are the inner model's at λ.
    fn forward_derivatives_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        tau: &DVector<f64>,
        theta: &DVector<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        let inner = self.inner();
        if self.is_identity() {
            return inner.forward_derivatives_into(&mut ws.inner, q, qd, tau, theta, out);
        }
        out.check_shape(ws.phi.nrows(), self.count())?;
        let lambda = load(self, &mut ws.lambda, theta)?;
        inner.forward_derivatives_into(&mut ws.inner, q, qd, tau, lambda, &mut ws.fd)?;
        out.qdd.copy_from(&ws.fd.qdd);
        out.dqdd_dq.copy_from(&ws.fd.dqdd_dq);
        out.dqdd_dqd.copy_from(&ws.fd.dqdd_dqd);
        self.map_columns(&mut ws.fd.dqdd_dlambda, &mut out.dqdd_dlambda);
        Ok(())
    }

    fn forward_derivatives_at_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd_lin: &DVector<f64>,
        tau: &DVector<f64>,
        theta: &DVector<f64>,
        tau_lin: &mut DVector<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<()> {
        if self.is_identity() {
            let inner = self.inner();
            let ws = &mut ws.inner;
            return inner.forward_derivatives_at_into(ws, q, qd, qdd_lin, tau, theta, tau_lin, out);
        }
        // The three calls of the default (a payload filter's bits unchanged: its test log
        // is sensitive to round-off, see docs/online-speed.md).
        self.inverse_dynamics_into(ws, q, qd, qdd_lin, theta, tau_lin)?;
        self.forward_derivatives_into(ws, q, qd, tau_lin, theta, out)?;
        self.forward_dynamics_into(ws, q, qd, tau, theta, &mut out.qdd)
    }

    fn forward_derivatives_factored_into(
        &self,
        ws: &mut Self::Workspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd_lin: Option<&DVector<f64>>,
        tau: &DVector<f64>,
        theta: &DVector<f64>,
        minv: &mut DMatrix<f64>,
        out: &mut ForwardDerivativesOf<Dyn, Dyn>,
    ) -> Result<bool> {
        if !self.is_identity() {
            return Ok(false);
        }
        let ws = &mut ws.inner;
        let inner = self.inner();
        inner.forward_derivatives_factored_into(ws, q, qd, qdd_lin, tau, theta, minv, out)
    }
}

/// λ of θ: θ itself for an identity, else written into `lambda`.
fn load<'a, R: Reparametrisation>(
    r: &R,
    lambda: &'a mut DVector<f64>,
    theta: &'a DVector<f64>,
) -> Result<&'a DVector<f64>> {
    if r.is_identity() {
        return Ok(theta);
    }
    r.to_inner(theta, lambda)?;
    Ok(lambda)
}
