//! What an arm carries: a payload (tool and part) as one rigid body fixed to a link of the
//! chain, usually the tip.
//!
//! Its 10 inertial parameters π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] are
//! expressed in the frame of the link that carries it, about that frame's origin — the
//! layout and order of the chain's per-link parameters (Pinocchio's, see
//! [`crate::inertial_parameters`]). So the payload's torques are the carrying link's 10
//! columns of the chain's standard regressor times π: τ_payload = Y[:, 10ℓ..10ℓ+10]·π.
//! [`Payload`] converts π to mass, centre of mass and inertia about the centre of mass,
//! checks physical consistency through the pseudo-inertia J(π) ⪰ 0 and projects onto it
//! ([`project_physical`]), and carries the σ of each quantity and whether the data that
//! identified it determine it.

use nalgebra::{Matrix4, SMatrix, SVector};
use serde::{Deserialize, Serialize};

use crate::error::{PrrrpError, Result};
use crate::models::chain::{
    com_and_inertia, inertial_parameters, pseudo_inertia, pseudo_inertia_to_parameters,
    LINK_PARAMS, PHYSICAL_TOLERANCE,
};

/// Which payload quantities the identification data determine (see
/// [`PayloadThresholds`]); quantities given by the user count as determined.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PayloadIdentifiable {
    /// The mass.
    pub mass: bool,
    /// Each coordinate of the centre of mass (x, y, z).
    pub com: [bool; 3],
    /// Each entry of the inertia about the centre of mass, [Ixx, Ixy, Iyy, Ixz, Iyz, Izz].
    pub inertia: [bool; 6],
}

impl PayloadIdentifiable {
    /// Everything determined (a payload given, not identified).
    pub fn all() -> Self {
        Self {
            mass: true,
            com: [true; 3],
            inertia: [true; 6],
        }
    }
}

/// When an identified quantity counts as determined by the data: its σ against a scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PayloadThresholds {
    /// The mass and the inertia about the centre of mass are determined when σ is at most
    /// this fraction of the mass, resp. of the moment scale ½·tr(I_C) (dimensionless;
    /// default 0.1).
    pub max_relative_sigma: f64,
    /// A centre-of-mass coordinate is determined when its σ is at most this (m; default
    /// 0.01).
    pub com_tolerance: f64,
}

impl Default for PayloadThresholds {
    fn default() -> Self {
        Self {
            max_relative_sigma: 0.1,
            com_tolerance: 0.01,
        }
    }
}

/// A payload: a rigid body fixed to link `link` of a chain (see the module docs). Units:
/// kg, m, kg·m². Serialises to the JSON of `payload.json` and of the `payload` field of an
/// identified model (`docs/model-schema.md`); the derived fields (mass, com, inertia and
/// their σ) are recomputed from `parameters` and `covariance` on load.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Payload {
    /// Name of the carrying link (the chain's link name, e.g. `wrist_3_link`).
    pub link: String,
    /// Index of the carrying link in the chain, 0-based (n − 1: the tip).
    pub link_index: usize,
    /// π = [m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz] in the link frame, about
    /// its origin (kg, kg·m, kg·m²).
    pub parameters: [f64; LINK_PARAMS],
    /// Covariance of π (10 × 10, row-major) where identified; zero rows and columns for a
    /// quantity given by the user (a known mass).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<f64>>,
    /// Whether the mass was given (`--mass`), not identified.
    #[serde(default)]
    pub mass_given: bool,
    /// Mass m (kg). Derived.
    #[serde(default)]
    pub mass: f64,
    /// Centre of mass in the link frame (m); `None` for m ≤ 0. Derived.
    #[serde(default)]
    pub com: Option<[f64; 3]>,
    /// Inertia about the centre of mass in link-frame axes, [Ixx, Ixy, Iyy, Ixz, Iyz, Izz]
    /// (kg·m²); `None` for m ≤ 0. Derived.
    #[serde(default)]
    pub inertia: Option<[f64; 6]>,
    /// σ of the mass (kg), from the covariance. Derived.
    #[serde(default)]
    pub mass_sigma: Option<f64>,
    /// σ of each centre-of-mass coordinate (m), to first order. Derived.
    #[serde(default)]
    pub com_sigma: Option<[f64; 3]>,
    /// σ of each entry of the inertia about the centre of mass (kg·m²), to first order.
    /// Derived.
    #[serde(default)]
    pub inertia_sigma: Option<[f64; 6]>,
    /// Which quantities the identification data determine (all, for a payload given).
    pub identifiable: PayloadIdentifiable,
    /// Free-form record of how the payload was identified (method, thresholds, samples).
    #[serde(default)]
    pub identification: serde_json::Value,
}

impl Payload {
    /// A payload known in advance: mass (kg), centre of mass in the link frame (m) and
    /// inertia about the centre of mass ([Ixx, Ixy, Iyy, Ixz, Iyz, Izz], kg·m²).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] when the body is not physical (m ≤ 0, or an
    /// inertia no mass distribution has), [`PrrrpError::NonFinite`] for NaN/∞.
    pub fn new(
        link: &str,
        link_index: usize,
        mass: f64,
        com: [f64; 3],
        inertia_com: [f64; 6],
    ) -> Result<Self> {
        Self::from_parameters(
            link,
            link_index,
            inertial_parameters(mass, com, inertia_com),
            None,
        )
    }

    /// A payload from its 10 inertial parameters about the link origin and, optionally,
    /// their covariance (100 values, row-major).
    ///
    /// # Errors
    /// As [`Payload::new`]; [`PrrrpError::ShapeMismatch`] for a covariance that is not
    /// 10 × 10.
    pub fn from_parameters(
        link: &str,
        link_index: usize,
        parameters: [f64; LINK_PARAMS],
        covariance: Option<Vec<f64>>,
    ) -> Result<Self> {
        let mut p = Self {
            link: link.to_string(),
            link_index,
            parameters,
            covariance,
            mass_given: false,
            mass: 0.0,
            com: None,
            inertia: None,
            mass_sigma: None,
            com_sigma: None,
            inertia_sigma: None,
            identifiable: PayloadIdentifiable::all(),
            identification: serde_json::Value::Null,
        };
        p.validate()?;
        p.derive();
        Ok(p)
    }

    /// Checks values and sizes (see [`Payload::new`]).
    ///
    /// # Errors
    /// As [`Payload::from_parameters`].
    pub fn validate(&self) -> Result<()> {
        if let Some(k) = self.parameters.iter().position(|x| !x.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!("payload parameter {k}"),
                row: None,
            });
        }
        if self.parameters[0] <= 0.0 {
            return Err(PrrrpError::InvalidParameter {
                field: "payload mass".into(),
                value: self.parameters[0],
                reason: "a payload has a positive mass (kg)",
            });
        }
        if !self.is_physical() {
            return Err(PrrrpError::InvalidParameter {
                field: "payload inertia".into(),
                value: min_eigenvalue(&self.parameters),
                reason: "no rigid body has this mass distribution (pseudo-inertia not \
                         positive semidefinite: an inertia about the centre of mass that \
                         breaks the triangle inequality or has a negative moment)",
            });
        }
        if let Some(c) = &self.covariance {
            if c.len() != LINK_PARAMS * LINK_PARAMS {
                return Err(PrrrpError::ShapeMismatch {
                    what: "payload covariance".into(),
                    expected: "100 values (10 × 10, row-major)".into(),
                    got: format!("{} values", c.len()),
                });
            }
            if let Some(k) = c.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: "payload covariance".into(),
                    row: Some(k),
                });
            }
        }
        Ok(())
    }

    /// The payload's torque (N·m, or N at a prismatic joint) at one joint: the carrying
    /// link's 10 columns of that joint's row of the chain's standard regressor (`row`: the
    /// whole row, 10 inertial columns per link first, as
    /// `DynChain::regressor_row_major_into` writes it) times π. `None` when `row` is too
    /// short for the carrying link.
    pub fn torque_from_regressor_row(&self, row: &[f64]) -> Option<f64> {
        let first = LINK_PARAMS * self.link_index;
        let cols = row.get(first..first + LINK_PARAMS)?;
        Some(cols.iter().zip(&self.parameters).map(|(y, x)| y * x).sum())
    }

    /// Whether π is a rigid body: J(π) ⪰ 0 within [`PHYSICAL_TOLERANCE`] of its largest
    /// parameter, and m > 0.
    pub fn is_physical(&self) -> bool {
        is_physical(&self.parameters)
    }

    /// Recomputes the derived fields (mass, centre of mass, inertia about it and their σ)
    /// from `parameters` and `covariance`.
    pub fn derive(&mut self) {
        self.mass = self.parameters[0];
        match com_and_inertia(&self.parameters) {
            Some((_, c, i)) => {
                self.com = Some(c);
                self.inertia = Some(i);
            }
            None => {
                self.com = None;
                self.inertia = None;
            }
        }
        let Some(cov) = self
            .covariance
            .as_ref()
            .map(|c| SMatrix::<f64, 10, 10>::from_row_slice(c))
        else {
            self.mass_sigma = None;
            self.com_sigma = None;
            self.inertia_sigma = None;
            return;
        };
        let Some(jac) = derived_jacobian(&self.parameters) else {
            self.mass_sigma = Some(cov[(0, 0)].max(0.0).sqrt());
            self.com_sigma = None;
            self.inertia_sigma = None;
            return;
        };
        let c = jac * cov * jac.transpose();
        let s = |k: usize| c[(k, k)].max(0.0).sqrt();
        self.mass_sigma = Some(s(0));
        self.com_sigma = Some([s(1), s(2), s(3)]);
        self.inertia_sigma = Some([s(4), s(5), s(6), s(7), s(8), s(9)]);
    }

    /// Sets [`Payload::identifiable`] from the σ of each quantity and `thresholds`
    /// (a given mass counts as determined). Without a covariance nothing changes.
    pub fn classify(&mut self, thresholds: &PayloadThresholds) {
        let (Some(ms), Some(cs), Some(is)) = (self.mass_sigma, self.com_sigma, self.inertia_sigma)
        else {
            if self.covariance.is_some() {
                // m ≤ 0: nothing but the mass's own σ is defined.
                self.identifiable = PayloadIdentifiable {
                    mass: false,
                    com: [false; 3],
                    inertia: [false; 6],
                };
            }
            return;
        };
        let m = self.mass;
        let inertia = self.inertia.unwrap_or([0.0; 6]);
        let scale = 0.5 * (inertia[0] + inertia[2] + inertia[5]);
        let rel = thresholds.max_relative_sigma;
        self.identifiable = PayloadIdentifiable {
            mass: self.mass_given || (m > 0.0 && ms <= rel * m),
            com: cs.map(|s| s <= thresholds.com_tolerance),
            inertia: is.map(|s| scale > 0.0 && s <= rel * scale),
        };
    }

    /// The payload as JSON (`payload.json`).
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] if a value is not finite (JSON has no NaN).
    pub fn to_json(&self) -> Result<String> {
        let mut out = self.clone();
        out.derive();
        crate::json::to_pretty(&out, "payload")
    }

    /// A payload from the JSON of [`Payload::to_json`], checked.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the JSON problem, and as [`Payload::new`].
    pub fn from_json(text: &str) -> Result<Self> {
        let mut p: Self = crate::json::parse(
            text,
            "payload",
            "not a prrrp payload; write it with Payload::to_json",
        )?;
        p.validate()?;
        p.derive();
        Ok(p)
    }
}

/// Whether π (10 inertial parameters) is a rigid body of positive mass: J(π) ⪰ 0 within
/// [`PHYSICAL_TOLERANCE`] × its largest parameter.
pub fn is_physical(params: &[f64; LINK_PARAMS]) -> bool {
    let scale = params.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    params[0] > 0.0 && min_eigenvalue(params) >= -PHYSICAL_TOLERANCE * scale
}

fn min_eigenvalue(params: &[f64; LINK_PARAMS]) -> f64 {
    if !params.iter().all(|x| x.is_finite()) {
        return f64::NAN;
    }
    pseudo_inertia(params)
        .symmetric_eigenvalues()
        .iter()
        .fold(f64::INFINITY, |a, &b| a.min(b))
}

/// d(m, c, I_C)/dπ at π (10 × 10), `None` for m ≤ 0; by central differences scaled to
/// each parameter (the map is rational and smooth for m > 0).
fn derived_jacobian(params: &[f64; LINK_PARAMS]) -> Option<SMatrix<f64, 10, 10>> {
    let f = |p: &[f64; LINK_PARAMS]| -> Option<SVector<f64, 10>> {
        let (m, c, i) = com_and_inertia(p)?;
        Some(SVector::<f64, 10>::from_column_slice(&[
            m, c[0], c[1], c[2], i[0], i[1], i[2], i[3], i[4], i[5],
        ]))
    };
    f(params)?;
    let m = params[0];
    // Step sizes in each parameter's own unit scale: kg, kg·m, kg·m².
    let len = (params[1].hypot(params[2]).hypot(params[3]) / m).max(0.01);
    let steps = [
        m,
        m * len,
        m * len,
        m * len,
        m * len * len,
        m * len * len,
        m * len * len,
        m * len * len,
        m * len * len,
        m * len * len,
    ];
    let mut jac = SMatrix::<f64, 10, 10>::zeros();
    for (k, step) in steps.iter().enumerate() {
        let h = 1e-6 * step;
        let (mut up, mut down) = (*params, *params);
        up[k] += h;
        down[k] -= h;
        let col = (f(&up)? - f(&down)?) / (2.0 * h);
        jac.set_column(k, &col);
    }
    Some(jac)
}

/// The physically consistent π closest to `estimate` in the metric `metric` (10 × 10,
/// row-major, symmetric positive semidefinite; e.g. the information matrix of a
/// least-squares fit, so that the projection costs the least in fit):
/// argmin (π − π̂)ᵀ·S·(π − π̂) subject to J(π) ⪰ 0. With `fixed_mass` the mass stays at
/// `estimate[0]` (which must then be > 0). `estimate` itself when it is physical.
///
/// Method: J = U·Uᵀ with U upper triangular (10 entries, U₄₄² = m, so a fixed mass fixes
/// one entry), Levenberg–Marquardt on U; a tiny proximal term in each parameter's scale
/// keeps directions S does not see at the estimate's value.
///
/// # Errors
/// [`PrrrpError::NonFinite`] for NaN/∞ input, [`PrrrpError::ShapeMismatch`] for a metric
/// that is not 10 × 10, [`PrrrpError::InvalidParameter`] for a fixed mass ≤ 0.
pub fn project_physical(
    estimate: &[f64; LINK_PARAMS],
    metric: &[f64],
    fixed_mass: bool,
) -> Result<[f64; LINK_PARAMS]> {
    if estimate.iter().any(|x| !x.is_finite()) || metric.iter().any(|x| !x.is_finite()) {
        return Err(PrrrpError::NonFinite {
            what: "payload projection input".into(),
            row: None,
        });
    }
    if metric.len() != 100 {
        return Err(PrrrpError::ShapeMismatch {
            what: "payload projection metric".into(),
            expected: "100 values (10 × 10)".into(),
            got: format!("{} values", metric.len()),
        });
    }
    if fixed_mass && estimate[0] <= 0.0 {
        return Err(PrrrpError::InvalidParameter {
            field: "payload mass".into(),
            value: estimate[0],
            reason: "a given payload mass must be > 0 kg",
        });
    }
    if is_physical(estimate) {
        return Ok(*estimate);
    }
    let s = SMatrix::<f64, 10, 10>::from_row_slice(metric);
    let s = (s + s.transpose()) * 0.5;
    // Scales of the parameters (kg, kg·m, kg·m²) from the estimate, floored so that a
    // vanishing estimate still has a unit.
    let m_scale = estimate[0].abs().max(1e-6);
    let len = (estimate[1].hypot(estimate[2]).hypot(estimate[3]) / m_scale).max(0.05);
    let scale: [f64; 10] = std::array::from_fn(|k| match k {
        0 => m_scale,
        1..=3 => m_scale * len,
        _ => m_scale * len * len,
    });
    // Metric in scaled units, plus a proximal term 1e-8 of its largest diagonal.
    let mut a = SMatrix::<f64, 10, 10>::zeros();
    for r in 0..10 {
        for c in 0..10 {
            a[(r, c)] = s[(r, c)] * scale[r] * scale[c];
        }
    }
    let top = (0..10).fold(0.0f64, |x, k| x.max(a[(k, k)])).max(1e-300);
    for k in 0..10 {
        a[(k, k)] += 1e-8 * top;
    }
    let cost = |p: &[f64; 10]| -> f64 {
        let d = SVector::<f64, 10>::from_fn(|k, _| (p[k] - estimate[k]) / scale[k]);
        (d.transpose() * a * d)[(0, 0)]
    };
    // Start: J(π̂) with its eigenvalues raised to a small positive floor, factored.
    let mut j0 = pseudo_inertia(estimate);
    if fixed_mass {
        j0[(3, 3)] = estimate[0];
    } else {
        j0[(3, 3)] = j0[(3, 3)].max(1e-3 * m_scale);
    }
    let eig = j0.symmetric_eigen();
    let floor = 1e-4 * m_scale * len * len;
    let mut d = eig.eigenvalues;
    for v in d.iter_mut() {
        *v = v.max(floor);
    }
    let mut start = eig.eigenvectors * Matrix4::from_diagonal(&d) * eig.eigenvectors.transpose();
    if fixed_mass {
        // Keep m exact: rescale the first moment so the Schur complement stays PSD.
        start[(3, 3)] = estimate[0];
    }
    let mut u = upper_factor(&start).unwrap_or_else(|| {
        let mut u = Matrix4::zeros();
        for k in 0..3 {
            u[(k, k)] = (floor).sqrt();
        }
        u[(3, 3)] = estimate[0].abs().max(1e-3 * m_scale).sqrt();
        u
    });
    if fixed_mass {
        u[(3, 3)] = estimate[0].sqrt();
    }
    let free: Vec<(usize, usize)> = (0..4)
        .flat_map(|r| (r..4).map(move |c| (r, c)))
        .filter(|&(r, c)| !(fixed_mass && r == 3 && c == 3))
        .collect();
    let params_of = |u: &Matrix4<f64>| pseudo_inertia_to_parameters(&(u * u.transpose()));
    let mut lambda = 1e-3;
    let mut best = cost(&params_of(&u));
    for _ in 0..500 {
        let p = params_of(&u);
        // Jacobian of the scaled parameters with respect to the free entries of U:
        // dJ = E·Uᵀ + U·Eᵀ, and π is linear in J.
        let k = free.len();
        let mut jac = nalgebra::DMatrix::<f64>::zeros(10, k);
        for (col, &(r, c)) in free.iter().enumerate() {
            let mut e = Matrix4::zeros();
            e[(r, c)] = 1.0;
            let dj = e * u.transpose() + u * e.transpose();
            let dp = pseudo_inertia_to_parameters(&dj);
            for row in 0..10 {
                jac[(row, col)] = dp[row] / scale[row];
            }
        }
        let a_dyn = nalgebra::DMatrix::<f64>::from_fn(10, 10, |r, c| a[(r, c)]);
        let resid = nalgebra::DVector::<f64>::from_fn(10, |r, _| (p[r] - estimate[r]) / scale[r]);
        let g = jac.transpose() * &a_dyn * &resid;
        let h = jac.transpose() * &a_dyn * &jac;
        let mut improved = false;
        for _ in 0..30 {
            let mut hl = h.clone();
            for q in 0..k {
                hl[(q, q)] += lambda * (h[(q, q)].max(1e-300));
            }
            let Some(step) = hl.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let mut trial = u;
            for (col, &(r, c)) in free.iter().enumerate() {
                trial[(r, c)] += step[col];
            }
            let f = cost(&params_of(&trial));
            if f.is_finite() && f < best {
                let gain = (best - f) / best.max(1e-300);
                u = trial;
                best = f;
                lambda = (lambda * 0.3).max(1e-12);
                improved = gain > 1e-14;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let mut out = params_of(&u);
    if fixed_mass {
        out[0] = estimate[0];
    }
    Ok(out)
}

/// U upper triangular with U·Uᵀ = J for a positive definite J (the "reverse" Cholesky
/// factor), `None` otherwise.
fn upper_factor(j: &Matrix4<f64>) -> Option<Matrix4<f64>> {
    // Reverse the index order, take the lower Cholesky factor, reverse back.
    let p = Matrix4::new(
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
    );
    let l = (p * j * p).cholesky()?.l();
    Some(p * l * p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity_metric() -> Vec<f64> {
        let mut m = vec![0.0; 100];
        for k in 0..10 {
            m[k * 11] = 1.0;
        }
        m
    }

    #[test]
    fn conversions_round_trip() {
        let p = Payload::new(
            "tool",
            5,
            2.8,
            [0.01, -0.02, 0.05],
            [0.004, 0.0001, 0.005, 0.0, 0.0002, 0.003],
        )
        .unwrap();
        assert!((p.mass - 2.8).abs() < 1e-12);
        let c = p.com.unwrap();
        assert!((c[2] - 0.05).abs() < 1e-12 && (c[1] + 0.02).abs() < 1e-12);
        let i = p.inertia.unwrap();
        assert!((i[0] - 0.004).abs() < 1e-12 && (i[4] - 0.0002).abs() < 1e-12);
        let back = Payload::from_json(&p.to_json().unwrap()).unwrap();
        assert_eq!(back.parameters, p.parameters);
    }

    #[test]
    fn non_physical_payloads_are_refused_and_projected() {
        // Inertia about the COM breaking the triangle inequality (Izz > Ixx + Iyy).
        let bad = inertial_parameters(1.0, [0.0, 0.0, 0.1], [0.001, 0.0, 0.001, 0.0, 0.0, 0.01]);
        assert!(Payload::from_parameters("tool", 0, bad, None).is_err());
        let fixed = project_physical(&bad, &identity_metric(), true).unwrap();
        assert!(is_physical(&fixed), "{fixed:?}");
        assert_eq!(fixed[0], 1.0);
        let free = project_physical(&bad, &identity_metric(), false).unwrap();
        assert!(is_physical(&free));
        // The projection moves no further than needed: close to the estimate.
        let dist: f64 = free.iter().zip(&bad).map(|(a, b)| (a - b).powi(2)).sum();
        assert!(dist.sqrt() < 0.01, "{dist}");
        // A negative mass goes to a (near-)zero one, never below.
        let mut neg = bad;
        neg[0] = -0.5;
        let p = project_physical(&neg, &identity_metric(), false).unwrap();
        assert!(p[0] >= 0.0);
    }

    #[test]
    fn sigma_of_the_com_matches_the_first_order_formula() {
        // First-order σ of the COM from the covariance of π against the formula by hand.
        let base = inertial_parameters(2.0, [0.02, 0.0, 0.08], [0.01, 0.0, 0.012, 0.0, 0.0, 0.008]);
        let mut cov = vec![0.0; 100];
        let sd = [
            0.02, 0.002, 0.002, 0.002, 1e-4, 1e-5, 1e-4, 1e-5, 1e-5, 1e-4,
        ];
        for k in 0..10 {
            cov[k * 11] = sd[k] * sd[k];
        }
        let p = Payload::from_parameters("t", 0, base, Some(cov)).unwrap();
        let cs = p.com_sigma.unwrap();
        // c_z = mz/m: σ² ≈ (σ_mz/m)² + (c_z·σ_m/m)².
        let want = ((0.002f64 / 2.0).powi(2) + (0.08 * 0.02 / 2.0f64).powi(2)).sqrt();
        assert!((cs[2] - want).abs() < 1e-3 * want, "{} vs {want}", cs[2]);
    }
}
