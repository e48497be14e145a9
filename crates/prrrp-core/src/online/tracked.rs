//! The model the online identifier estimates: the arm's base parameters, or only a
//! payload's 10 inertial parameters on an arm known from a prior model.
//!
//! In payload mode θ = π and β = β_arm + K_tip·π, where K_tip is the base map's block of
//! the tip link's 10 standard parameters (Y_tip = Y_b·K_tip, since Y = Y_b·K for every
//! state). The model is affine in θ: its regressor is the payload's Φ = Y_b·K_tip and
//! its dynamics are the base model's at that β, so τ = τ_arm + Φ·π. The EKF only uses
//! the dynamics and their derivatives; the inverse-model estimators (RLS, Adaline,
//! Hopfield) are given τ − τ_arm ([`TrackedModel::arm_torque_into`]), for which the
//! model is linear (why not a fixed unit parameter: docs/design/online.md). Every method
//! of the base model is evaluated at β, so whatever columns it has (friction, actuators)
//! flow through unchanged.

use nalgebra::{DMatrix, DVector};

use super::payload::{tip_columns, PAYLOAD_PARAMS};
use crate::error::{check_len, Result};
use crate::models::chain::{BaseParameters, DynBaseWorkspace, DynChainBaseModel};
use crate::models::scaled::{Reparametrisation, ReparametrisedWorkspace};
use crate::models::LinearModel;

/// The arm's base model, or the payload model on top of it (module docs).
#[derive(Debug, Clone)]
pub(crate) enum TrackedModel {
    /// θ = β, the base parameters.
    Full(DynChainBaseModel),
    /// θ = π; β = β_arm + K_tip·π (affine, see the module docs).
    Payload {
        base: DynChainBaseModel,
        arm: DVector<f64>,
        /// K_tip (B×10).
        k_tip: DMatrix<f64>,
        /// The non-zero entries (row, value) of each column of K_tip, in row order: a
        /// payload parameter enters few base parameters.
        k_nz: Vec<Vec<(usize, f64)>>,
    },
}

/// Workspace of [`TrackedModel`].
pub(crate) type TrackedWorkspace = ReparametrisedWorkspace<DynBaseWorkspace>;

impl TrackedModel {
    /// The payload model on `base` (the analysis `analysis` of its chain) with the arm at
    /// `arm` (its base parameters).
    pub(crate) fn payload(
        base: DynChainBaseModel,
        analysis: &BaseParameters,
        arm: DVector<f64>,
    ) -> Result<Self> {
        let cols = tip_columns(&analysis.names, base.dof())?;
        let b = base.count();
        let k_tip = DMatrix::from_fn(b, PAYLOAD_PARAMS, |r, k| analysis.map[(r, cols[k])]);
        let k_nz = (0..PAYLOAD_PARAMS)
            .map(|k| {
                (0..b)
                    .filter(|&r| k_tip[(r, k)] != 0.0)
                    .map(|r| (r, k_tip[(r, k)]))
                    .collect()
            })
            .collect();
        Ok(Self::Payload {
            base,
            arm,
            k_tip,
            k_nz,
        })
    }

    pub(crate) fn base(&self) -> &DynChainBaseModel {
        match self {
            Self::Full(b) | Self::Payload { base: b, .. } => b,
        }
    }

    /// β of θ into `out` (B).
    pub(crate) fn beta_into(&self, theta: &DVector<f64>, out: &mut DVector<f64>) {
        match self {
            Self::Full(_) => out.copy_from(theta),
            Self::Payload { arm, k_tip, .. } => {
                out.copy_from(arm);
                out.gemv(1.0, k_tip, theta, 1.0);
            }
        }
    }

    /// The arm's joint forces without the payload (payload mode; zero otherwise), the
    /// offset of the affine model.
    pub(crate) fn arm_torque_into(
        &self,
        ws: &mut TrackedWorkspace,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        out: &mut DVector<f64>,
    ) -> Result<()> {
        match self {
            Self::Full(_) => {
                out.fill(0.0);
                Ok(())
            }
            Self::Payload { base, arm, .. } => {
                base.inverse_dynamics_into(&mut ws.inner, q, qd, qdd, arm, out)
            }
        }
    }
}

/// Full: λ = θ; payload: β = β_arm + K_tip·π.
impl Reparametrisation for TrackedModel {
    type Inner = DynChainBaseModel;

    fn inner(&self) -> &DynChainBaseModel {
        self.base()
    }

    fn count(&self) -> usize {
        match self {
            Self::Full(b) => b.count(),
            Self::Payload { .. } => PAYLOAD_PARAMS,
        }
    }

    fn to_inner(&self, theta: &DVector<f64>, beta: &mut DVector<f64>) -> Result<()> {
        let what = "lambda (model parameters)";
        check_len(what, theta.len(), self.count(), "entries", "")?;
        self.beta_into(theta, beta);
        Ok(())
    }

    /// The payload columns of a matrix of B columns: out = m·K_tip. A plain loop:
    /// nalgebra's `gemm` hands dynamic matrices to matrixmultiply, which allocates its
    /// packing buffers on every call (one allocation per sample, `tests/alloc_online.rs`).
    /// Over the non-zero entries of K_tip only: the same sums (a zero product adds
    /// nothing) over a few of the B terms.
    fn map_columns(&self, m: &mut DMatrix<f64>, out: &mut DMatrix<f64>) {
        if let Self::Payload { k_nz, .. } = self {
            for (k, nz) in k_nz.iter().enumerate() {
                for i in 0..m.nrows() {
                    let mut acc = 0.0;
                    for &(r, v) in nz {
                        acc += m[(i, r)] * v;
                    }
                    out[(i, k)] = acc;
                }
            }
        }
    }

    fn is_identity(&self) -> bool {
        matches!(self, Self::Full(_))
    }
}
