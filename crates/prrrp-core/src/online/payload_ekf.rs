//! The EKF of payload mode: a Kalman filter on the payload's 10 parameters alone, whose
//! measurement is the joint-force residual the prior arm does not explain.
//!
//! State π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] (kg, kg·m, kg·m²), a
//! random walk; measurement r = τ − τ_arm(q, q̇, q̈) = Y_p(q, q̇, q̈)·π + e, Y_p the tip
//! link's 10 regressor columns (the payload RLS's), on the causal low-passed row. The
//! measurement is linear in π, so the EKF's linearisation is exact and it is the Kalman
//! filter. Why not the joint-state filter on [q, q̇, π] with forward dynamics: its
//! information per sample is bounded by the velocity measurement noise (about 100× less
//! than this regression's), and its estimate left the region M(q, θ̂) ≻ 0 on real
//! motions (docs/design/online.md).
//!
//! - Q: per second, (`PAYLOAD_DRIFT`·σ₀)² per parameter, σ₀ the prior σ (from
//!   `payload_mass_std` and `payload_size`), plus the random walk (1/ν − 1)·P of
//!   forgetting when it is set.
//! - R: per joint, the running variance of the one-step-ahead errors that pass the change
//!   test (the change detector's, which RLS weights its equations with), in N²·m².
//! - The filter keeps its own unconstrained π̂ (the Gaussian posterior); the identifier
//!   reports its projection onto the rigid bodies. Projecting the filter's own state
//!   rectifies the noise at an empty gripper (π = 0, the apex of the cone of rigid
//!   bodies), so the mass ratchets up on a log without any payload.
//! - It runs on π/σ₀ (P₀ = I), so that P stays well scaled; each joint is a scalar
//!   update (R is diagonal), so the step is allocation-free on stack 10×10 matrices.

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::payload::PAYLOAD_PARAMS;
use super::tracked::{TrackedModel, TrackedWorkspace};
use crate::error::{PrrrpError, Result};
use crate::models::LinearModel;

type Vec10 = SVector<f64, PAYLOAD_PARAMS>;
type Mat10 = SMatrix<f64, PAYLOAD_PARAMS, PAYLOAD_PARAMS>;

/// Random walk of the payload parameters: standard deviation per √s as a fraction of
/// the prior σ (1/√s). 1e-5 of the default 10 kg prior σ is 0.1 g/√s, 6 g over an hour:
/// small against what seconds of motion tell (the mass σ after 10 s was 1.4–4 g), so
/// that σ stays that of the data (1e-4 made σ 2–3× larger and the RMS of the normalised
/// errors 0.6 on `tests/online.rs`'s ten logs, against 0.85 now), yet P never collapses
/// to zero over a long run.
pub(crate) const PAYLOAD_DRIFT: f64 = 1e-5;

/// The payload EKF (module docs). Constant data (σ₀) apart from the per-sample state.
#[derive(Debug, Clone)]
pub(crate) struct PayloadEkf {
    /// Prior σ of each parameter (π units): the filter runs on γ = π/σ₀.
    sd0: Vec10,
    gamma: Vec10,
    /// Covariance of γ (P₀ = I).
    p: Mat10,
    /// Y_p (N×10, π units) of the last row.
    h: DMatrix<f64>,
    ws: TrackedWorkspace,
    /// The estimate in π units (what the identifier reads).
    pi: DVector<f64>,
    /// The a-priori prediction Y_p·π̂ of the last row (units of τ).
    pred: DVector<f64>,
    updates: usize,
}

impl PayloadEkf {
    /// The filter for the payload model `model`, starting from no payload with prior
    /// variances `var0` (π units, all > 0).
    pub(crate) fn new(model: &TrackedModel, var0: &DVector<f64>) -> Self {
        let n = model.dims().0 .0;
        Self {
            sd0: Vec10::from_fn(|i, _| var0[i].sqrt()),
            gamma: Vec10::zeros(),
            p: Mat10::identity(),
            h: DMatrix::zeros(n, PAYLOAD_PARAMS),
            ws: model.workspace(),
            pi: DVector::zeros(PAYLOAD_PARAMS),
            pred: DVector::zeros(n),
            updates: 0,
        }
    }

    /// The estimate π̂ (unconstrained; kg, kg·m, kg·m²).
    pub(crate) fn estimate(&self) -> &DVector<f64> {
        &self.pi
    }

    /// The a-priori prediction Y_p·π̂ of the last row given to [`PayloadEkf::update`],
    /// with the estimate before it (units of τ).
    pub(crate) fn prediction(&self) -> &DVector<f64> {
        &self.pred
    }

    /// Takes `other`'s estimate and covariance (a filter of the same model); allocation-free.
    pub(crate) fn copy_state_from(&mut self, other: &Self) {
        self.gamma = other.gamma;
        self.p = other.p;
        self.pi.copy_from(&other.pi);
        self.updates = other.updates;
    }

    /// Covariance entry (i, j) of π̂ (π units), the filter's own.
    pub(crate) fn covariance(&self, i: usize, j: usize) -> f64 {
        self.p[(i, j)] * self.sd0[i] * self.sd0[j]
    }

    /// Variance of parameter i relative to its prior variance (the opening's units).
    pub(crate) fn relative_variance(&self, i: usize) -> f64 {
        self.p[(i, i)]
    }

    /// P ← D·P·D with D = diag(`d`) (a congruence: P stays positive semidefinite).
    pub(crate) fn scale_covariance(&mut self, d: &DVector<f64>) {
        for i in 0..PAYLOAD_PARAMS {
            for j in 0..PAYLOAD_PARAMS {
                self.p[(i, j)] *= d[i] * d[j];
            }
        }
    }

    /// One step over a row `dt` s after the previous one: the random walk (ν: forgetting
    /// factor of the row, 1 without), then one scalar update per joint with the
    /// residual `r` (N·m or N) of the row (`q`, `qd`, `qdd`), weighted by `weights`
    /// (1/R per joint, 1/(N·m)² or 1/N²).
    ///
    /// # Errors
    /// [`PrrrpError::Diverged`] if the state became non-finite (the state is then left
    /// as it was before the row).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn update(
        &mut self,
        model: &TrackedModel,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        qdd: &DVector<f64>,
        r: &DVector<f64>,
        weights: &DVector<f64>,
        dt: f64,
        nu: f64,
    ) -> Result<()> {
        model.regressor_into(&mut self.ws, q, qd, qdd, &mut self.h)?;
        self.h.mul_to(&self.pi, &mut self.pred);
        let (gamma0, p0) = (self.gamma, self.p);
        let walk = PAYLOAD_DRIFT * PAYLOAD_DRIFT * dt;
        let forget = 1.0 / nu - 1.0;
        for i in 0..PAYLOAD_PARAMS {
            self.p[(i, i)] += walk + forget.max(0.0) * self.p[(i, i)];
        }
        for (j, &w) in weights.iter().enumerate() {
            let h = Vec10::from_fn(|k, _| self.h[(j, k)] * self.sd0[k]);
            let ph = self.p * h;
            let s = h.dot(&ph) + 1.0 / w;
            // A joint without information (or a NaN weight) updates nothing.
            if s.is_nan() || s <= 0.0 {
                continue;
            }
            let innovation = r[j] - h.dot(&self.gamma);
            self.gamma.axpy(innovation / s, &ph, 1.0);
            self.p.ger(-1.0 / s, &ph, &ph, 1.0);
        }
        // Round-off symmetry and a non-negative diagonal (the subtraction of a rank-one
        // term from a nearly singular P can overshoot by an ulp).
        for i in 0..PAYLOAD_PARAMS {
            for j in 0..i {
                let m = 0.5 * (self.p[(i, j)] + self.p[(j, i)]);
                self.p[(i, j)] = m;
                self.p[(j, i)] = m;
            }
            self.p[(i, i)] = self.p[(i, i)].max(0.0);
        }
        if !(self.gamma.iter().all(|v| v.is_finite()) && self.p.iter().all(|v| v.is_finite())) {
            (self.gamma, self.p) = (gamma0, p0);
            return Err(PrrrpError::Diverged {
                what: "payload EKF",
                at: self.updates,
                hint: "check the prior arm model and the torque data (non-finite state)",
            });
        }
        self.updates += 1;
        for i in 0..PAYLOAD_PARAMS {
            self.pi[i] = self.gamma[i] * self.sd0[i];
        }
        Ok(())
    }
}
