//! The paper's λ as a view of the paper robot's base parameters.
//!
//! The built-in `paper` robot as a chain ([`DynChain::paper`]) has 9 rigid base parameters
//! β, not the paper's 8 λ: λ6 = l2·MX4R and λ7 = l3·MX4R are one parameter of a rigid
//! link 4, and the first moments across links 3 and 4 (which the paper sets to 0) are two
//! more. Both parametrisations describe the same torques, τ = Y_b·β = Φ·λ + Y_μ·μ, with Y_μ
//! the first-moment columns of the closed form's extension ([`crate::models::prrrp`]), so
//! λ = T·β for a fixed T: the λ rows of the exact solution of [Φ | Y_μ]·X = Y_b over states.

use nalgebra::{DMatrix, DVector};

use crate::error::{PrrrpError, Result};
use crate::models::chain::DynChainBaseModel;
use crate::models::prrrp::extended::{self, NEXT};
use crate::models::prrrp::terms::Trig;
use crate::models::prrrp::types::{Vec5, NDOF, NPARAM};
use crate::models::LinearModel;

/// λ = T·β for the base parameters β of a model of the paper's arm.
#[derive(Debug, Clone, PartialEq)]
pub struct PaperLambdaView {
    /// T, 8 × b (b base parameters of the model).
    map: DMatrix<f64>,
}

/// Largest residual of [Φ | Y_μ]·X = Y_b accepted, relative to Y_b's largest entry: the
/// map is an identity of the two models, not a fit.
const MAP_TOLERANCE: f64 = 1e-9;

/// A quasi-random joint state `k` (m, rad; /s; /s²) away from special configurations.
fn state(k: usize) -> [Vec5; 3] {
    let f =
        |a: usize, s: f64| Vec5::from_fn(|i, _| s * ((k * 11 + a * 5 + i * 3) as f64 * 0.7).sin());
    [f(0, 2.0), f(1, 1.5), f(2, 4.0)]
}

impl PaperLambdaView {
    /// The view of `model`'s base parameters (a base model of a PRRRP arm with gravity
    /// `gravity`, m/s², e.g. `DynChain::paper().base_model(&base)` with 9.81; rigid columns
    /// only: the paper's model has no friction or armature).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if `model` is not a model of such an arm (its
    /// regressor is not spanned by the closed form's).
    pub fn new(model: &DynChainBaseModel, gravity: f64) -> Result<Self> {
        const STATES: usize = 24;
        let (n, b) = (model.dof(), model.count());
        let not_paper = || PrrrpError::InvalidParameter {
            field: "model".into(),
            value: b as f64,
            reason: "the paper's λ exists only for models of the paper's arm (DynChain::paper)",
        };
        if n != NDOF {
            return Err(not_paper());
        }
        let rows = NDOF * STATES;
        let (mut y, mut yb) = (DMatrix::zeros(rows, NEXT), DMatrix::zeros(rows, b));
        let mut ws = model.workspace();
        let mut block = DMatrix::zeros(n, b);
        for k in 0..STATES {
            let [q, qd, qdd] = state(k);
            let ext = extended::regressor(gravity, &Trig::new(&q), &qd, &qdd);
            y.view_mut((NDOF * k, 0), (NDOF, NEXT)).copy_from(&ext);
            let dv = |v: &Vec5| DVector::from_column_slice(v.as_slice());
            model.regressor_into(&mut ws, &dv(&q), &dv(&qd), &dv(&qdd), &mut block)?;
            yb.view_mut((NDOF * k, 0), (NDOF, b)).copy_from(&block);
        }
        let x = y
            .clone()
            .svd(true, true)
            .solve(&yb, 1e-14)
            .map_err(|_| not_paper())?;
        if (&y * &x - &yb).amax() > MAP_TOLERANCE * yb.amax().max(f64::MIN_POSITIVE) {
            return Err(not_paper());
        }
        Ok(Self {
            map: x.rows(0, NPARAM).into_owned(),
        })
    }

    /// T (8 × b).
    pub fn map(&self) -> &DMatrix<f64> {
        &self.map
    }

    /// λ1..λ8 of base parameters β (b entries; units of λ: kg, kg·m²).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if β does not have b entries.
    pub fn lambda(&self, beta: &[f64]) -> Result<[f64; NPARAM]> {
        if beta.len() != self.map.ncols() {
            return Err(PrrrpError::ShapeMismatch {
                what: "base parameters β".into(),
                expected: format!("{} entries", self.map.ncols()),
                got: format!("{} entries", beta.len()),
            });
        }
        let l = &self.map * DVector::from_column_slice(beta);
        Ok(std::array::from_fn(|i| l[i]))
    }

    /// σ of λ1..λ8 from β's covariance `cov` (b × b, row- or column-major: it is
    /// symmetric): √diag(T·C·Tᵀ).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] if `cov` does not have b² entries.
    pub fn sigma(&self, cov: &[f64]) -> Result<[f64; NPARAM]> {
        let b = self.map.ncols();
        if cov.len() != b * b {
            return Err(PrrrpError::ShapeMismatch {
                what: "covariance of β".into(),
                expected: format!("{} entries ({b} × {b})", b * b),
                got: format!("{} entries", cov.len()),
            });
        }
        let c = DMatrix::from_column_slice(b, b, cov);
        let v = &self.map * c * self.map.transpose();
        Ok(std::array::from_fn(|i| v[(i, i)].max(0.0).sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chain::{BaseOptions, DynChain};

    /// T maps the paper robot's true base parameters to the paper's λ (Table 3 with
    /// Table 2, computed by the closed form's own formulas, not by T).
    #[test]
    fn maps_the_true_base_parameters_to_the_true_lambda() {
        let chain = DynChain::paper();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        let view = PaperLambdaView::new(&model, 9.81).unwrap();
        let lam = view.lambda(model.chain_base_values().as_slice()).unwrap();
        let truth = crate::Robot::paper().base_parameters();
        for i in 0..NPARAM {
            assert!(
                (lam[i] - truth[i]).abs() < 1e-10 * truth[i].abs(),
                "λ{}",
                i + 1
            );
        }
        assert!(view.lambda(&[1.0]).is_err());
    }

    /// A robot that is not the paper's arm has no λ view.
    #[test]
    fn refuses_other_robots() {
        let chain = crate::SerialChain::<6>::puma560().to_dyn();
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let model = chain.base_model(&base).unwrap();
        assert!(PaperLambdaView::new(&model, 9.81).is_err());
    }
}
