//! What an arm carries, on a known arm: the payload's inertial parameters from the torque
//! the arm model does not explain ([`identify_payload`]), and the drive gains of current
//! logs from an unloaded and a loaded run with a payload of known mass
//! ([`identify_drive_gains`], Gautier & Briot's protocol).
//!
//! Both fit linear systems with one equation per joint and sample, weighted per joint by
//! the inverse residual variance (as `wls`), with σ from the sandwich covariance that
//! accounts for each joint's residual variance and correlation time (as `identify`).
//!
//! Drive gains: with currents i (A) and gains K, τ = Cᵀ·(K∘i), so each run gives
//! Cᵀ·(K∘i) − Y_b·β − Y_pl·π_pl = 0, homogeneous in (K, β, π_pl) — only the payload's
//! known mass m fixes the scale: moving m·Y_m to the right-hand side leaves
//! W·x = m·Y_m. Ordinary least squares on it is biased: the noise of the currents is in
//! W, and it shrinks the gains (errors in variables). The estimate here is instrumental
//! variables (IDIM-IV): the current columns are instrumented by the currents the model
//! predicts from the positions alone, which correlate with the true currents but not with
//! their noise, so the estimate is consistent whatever the current noise; three
//! iterations from the least-squares start. The naive least-squares gains are recorded
//! beside, as a check.

use nalgebra::{DMatrix, DVector};
use serde_json::json;

use super::IdentifiedModel;
use crate::data::DynDataset;
use crate::error::{PrrrpError, Result};
use crate::models::chain::{DynChain, DynWorkspace, LINK_PARAMS};
use crate::models::payload::{project_physical, Payload, PayloadThresholds};

use super::ekf_defaults::correlation_time;
use super::DriveGains;

/// Settings of [`identify_payload`].
#[derive(Debug, Clone, PartialEq)]
pub struct PayloadSettings {
    /// Index (0-based) of the link that carries the payload; `None`: the tip (n − 1).
    pub link: Option<usize>,
    /// A known payload mass (kg): only the centre of mass and the inertia are fitted.
    pub mass: Option<f64>,
    /// Re-fit the arm's friction terms (viscous, Coulomb, offset) on the loaded run, as the
    /// arm model has them (default true: friction and offsets change with load and
    /// temperature).
    pub refit_friction: bool,
    /// When a payload quantity counts as determined by the data.
    pub thresholds: PayloadThresholds,
}

impl Default for PayloadSettings {
    fn default() -> Self {
        Self {
            link: None,
            mass: None,
            refit_friction: true,
            thresholds: PayloadThresholds::default(),
        }
    }
}

/// Largest [`DriveGainSettings::iterations`]: 1000. The instrumental-variable estimate
/// settles within a few iterations (the default is 3), and each one re-reads both runs, so
/// more than 300 times the default only burns time (1000 took 30 s on two 400-sample UR5
/// runs in a debug build; `usize::MAX` never returned).
pub const MAX_DRIVE_GAIN_ITERATIONS: usize = 1000;

/// Settings of [`identify_drive_gains`].
#[derive(Debug, Clone, PartialEq)]
pub struct DriveGainSettings {
    /// The payload's link (0-based; `None`: the tip) and the payload's mass (kg,
    /// [`crate::MIN_FACTOR`] to [`crate::MAX_FACTOR`]).
    pub link: Option<usize>,
    /// The payload's known mass (kg).
    pub mass: f64,
    /// Separate friction terms for the loaded run (default true).
    pub refit_friction: bool,
    /// Instrumental-variable iterations after the least-squares start (default 3; 0 gives
    /// the naive least-squares estimate; at most [`MAX_DRIVE_GAIN_ITERATIONS`]).
    pub iterations: usize,
    /// A gain counts as determined when σ is at most this fraction of it (default 0.05).
    pub max_relative_sigma: f64,
    /// Payload thresholds (its centre of mass and inertia are identified too).
    pub thresholds: PayloadThresholds,
}

impl DriveGainSettings {
    /// Defaults for a payload of `mass` kg at the tip.
    pub fn new(mass: f64) -> Self {
        Self {
            link: None,
            mass,
            refit_friction: true,
            iterations: 3,
            max_relative_sigma: 0.05,
            thresholds: PayloadThresholds::default(),
        }
    }
}

/// The result of [`identify_drive_gains`].
#[derive(Debug, Clone, PartialEq)]
pub struct DriveGainsFit {
    /// The arm identified from the unloaded run in joint torque units (N·m, N), with
    /// [`IdentifiedModel::drive_gains`] set.
    pub model: IdentifiedModel,
    /// The payload of the loaded run (its mass the given one).
    pub payload: Payload,
    /// The naive least-squares gains (currents in the regressor), for comparison.
    pub naive_gains: Vec<f64>,
}

/// Per-joint normal equations of A·x = y (Z = A for least squares, the instruments for
/// IV), accumulated one sample (n rows) at a time.
struct Normal {
    za: Vec<DMatrix<f64>>,
    zz: Vec<DMatrix<f64>>,
    zy: Vec<DVector<f64>>,
    aa: Vec<DMatrix<f64>>,
    ay: Vec<DVector<f64>>,
    yy: Vec<f64>,
    samples: usize,
}

impl Normal {
    fn new(n: usize, k: usize) -> Self {
        Self {
            za: vec![DMatrix::zeros(k, k); n],
            zz: vec![DMatrix::zeros(k, k); n],
            zy: vec![DVector::zeros(k); n],
            aa: vec![DMatrix::zeros(k, k); n],
            ay: vec![DVector::zeros(k); n],
            yy: vec![0.0; n],
            samples: 0,
        }
    }

    fn add(&mut self, a: &DMatrix<f64>, z: &DMatrix<f64>, y: &DVector<f64>) {
        for j in 0..a.nrows() {
            let ar = a.row(j).transpose();
            let zr = z.row(j).transpose();
            self.za[j].ger(1.0, &zr, &ar, 1.0);
            self.zz[j].ger(1.0, &zr, &zr, 1.0);
            self.aa[j].ger(1.0, &ar, &ar, 1.0);
            self.zy[j].axpy(y[j], &zr, 1.0);
            self.ay[j].axpy(y[j], &ar, 1.0);
            self.yy[j] += y[j] * y[j];
        }
        self.samples += 1;
    }

    /// Residual variance of each joint's equations at x (dof shared among the joints).
    fn variances(&self, x: &DVector<f64>) -> Vec<f64> {
        let n = self.yy.len();
        let dof = (self.samples as f64 - x.len() as f64 / n as f64).max(1.0);
        (0..n)
            .map(|j| {
                let v = self.yy[j] - 2.0 * self.ay[j].dot(x) + x.dot(&(&self.aa[j] * x));
                v.max(0.0) / dof
            })
            .collect()
    }

    /// x = prior + (Σ w_j Z_jᵀA_j)⁺ Σ w_j Z_jᵀ(y_j − A_j·prior), the pseudo-inverse taken in
    /// column-equilibrated coordinates with directions below `tol` of the largest
    /// singular value dropped (held at the prior). Returns x, the inverse used, and the
    /// dropped directions (unit vectors in x's coordinates).
    fn solve(&self, w: &[f64], prior: &DVector<f64>, tol: f64) -> Result<Solved> {
        let k = prior.len();
        let mut m = DMatrix::zeros(k, k);
        let mut rhs = DVector::zeros(k);
        for (j, wj) in w.iter().enumerate() {
            m += &self.za[j] * *wj;
            rhs += (&self.zy[j] - &self.za[j] * prior) * *wj;
        }
        let d: Vec<f64> = (0..k)
            .map(|c| {
                let s = m[(c, c)].abs().sqrt();
                if s > 0.0 && s.is_finite() {
                    s
                } else {
                    1.0
                }
            })
            .collect();
        let ms = DMatrix::from_fn(k, k, |r, c| m[(r, c)] / (d[r] * d[c]));
        let svd = crate::linalg::svd(ms.clone()).ok_or_else(|| PrrrpError::NonFinite {
            what: "normal equations of the payload fit (overflowed or did not converge: check \
                   the logs' units)"
                .into(),
            row: None,
        })?;
        let top = svd.singular_values.max();
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let mut pinv = DMatrix::zeros(k, k);
        let mut dropped = Vec::new();
        let mut null_scaled = Vec::new();
        for (s, sv) in svd.singular_values.iter().enumerate() {
            if *sv > tol * top && *sv > 0.0 {
                pinv += vt.row(s).transpose() * u.column(s).transpose() / *sv;
            } else {
                let v: DVector<f64> = vt.row(s).transpose();
                null_scaled.push(v.clone());
                let v = DVector::from_fn(k, |r, _| v[r] / d[r]);
                dropped.push(&v / v.norm().max(1e-300));
            }
        }
        // Back to x's coordinates: M⁺ = D⁻¹·Ms⁺·D⁻¹.
        let inv = DMatrix::from_fn(k, k, |r, c| pinv[(r, c)] / (d[r] * d[c]));
        let x = prior + &inv * rhs;
        let cond = svd
            .singular_values
            .iter()
            .filter(|s| **s > tol * top)
            .fold(f64::INFINITY, |a, b| a.min(*b));
        Ok(Solved {
            x,
            inv,
            dropped,
            null_scaled,
            cond: top / cond,
        })
    }

    /// Sandwich covariance M⁻¹·(Σ w_j²·κ_j·s_j²·Z_jᵀZ_j)·M⁻ᵀ.
    fn covariance(
        &self,
        w: &[f64],
        inv: &DMatrix<f64>,
        var: &[f64],
        kappa: &[f64],
    ) -> DMatrix<f64> {
        let k = inv.nrows();
        let mut meat = DMatrix::zeros(k, k);
        for j in 0..w.len() {
            meat += &self.zz[j] * (w[j] * w[j] * kappa[j] * var[j]);
        }
        inv * meat * inv.transpose()
    }
}

struct Solved {
    x: DVector<f64>,
    inv: DMatrix<f64>,
    dropped: Vec<DVector<f64>>,
    /// The dropped directions as orthonormal vectors in the column-equilibrated
    /// coordinates (where every unknown has the same information scale).
    null_scaled: Vec<DVector<f64>>,
    cond: f64,
}

impl Solved {
    /// Whether unknown `c` is not determined by the data: its unit vector has more than
    /// 0.1 of its length in the dropped subspace (equilibrated coordinates), so the data
    /// cannot tell it apart from a combination of the others. Its σ from the
    /// pseudo-inverse is then meaningless (the dropped directions get none).
    fn undetermined(&self, c: usize) -> bool {
        self.null_scaled
            .iter()
            .map(|v| v[c] * v[c])
            .sum::<f64>()
            .sqrt()
            > 0.1
    }

    /// The error for data that do not determine what the caller needs: the rank of the
    /// solve and its dropped directions, in x's coordinates.
    fn rank_deficient(&self) -> PrrrpError {
        let k = self.x.len();
        PrrrpError::RankDeficient {
            rank: k - self.dropped.len(),
            params: k,
            cond: f64::INFINITY,
            directions: self
                .dropped
                .iter()
                .map(|v| v.iter().copied().collect())
                .collect(),
        }
    }
}

/// Directions of the equilibrated normal matrix below this fraction of the largest
/// singular value are not determined by the data (cond(W)² ≈ 10¹², as `identify`'s
/// rank tolerance on W).
const RANK_TOLERANCE: f64 = 1e-12;

/// The full regressor of sample `s` of `data`, row-major n × num_params, into `yf`;
/// returns that sample's `tau` row (n). One place for the slicing that every row
/// builder of this module needs.
fn sample_regressor<'d>(
    chain: &DynChain,
    ws: &mut DynWorkspace,
    data: &'d DynDataset,
    s: usize,
    yf: &mut [f64],
) -> Result<&'d [f64]> {
    let n = chain.dof();
    let r = n * s..n * s + n;
    chain.regressor_row_major_into(
        ws,
        &data.q()[r.clone()],
        &data.qd()[r.clone()],
        &data.qdd()[r.clone()],
        yf,
    )?;
    Ok(&data.tau()[r])
}

fn check_link(link: Option<usize>, n: usize) -> Result<usize> {
    let l = link.unwrap_or(n - 1);
    if l >= n {
        return Err(PrrrpError::InvalidParameter {
            field: "payload link".into(),
            value: l as f64,
            reason: "the payload's link must be one of the robot's links (0-based index \
                     below the number of joints)",
        });
    }
    Ok(l)
}

/// A mass of 1e-300 kg was taken, and the fitted inertia came out at hundreds of kg·m².
fn check_mass(m: f64) -> Result<()> {
    if !crate::bounds::is_factor(m) {
        return Err(PrrrpError::InvalidParameter {
            field: "payload mass".into(),
            value: m,
            reason: "a payload mass is between MIN_FACTOR (1e-6) and MAX_FACTOR (1e6) kg",
        });
    }
    Ok(())
}

/// The base parameters a loaded run re-fits: with `refit`, the ones that are friction
/// terms only (viscous, Coulomb, offset); none without.
fn refit_rows(model: &IdentifiedModel, refit: bool) -> Vec<usize> {
    if refit {
        friction_rows(model)
    } else {
        Vec::new()
    }
}

/// Base parameters that are friction terms only (viscous, Coulomb, offset).
fn friction_rows(model: &IdentifiedModel) -> Vec<usize> {
    let names = &model.base.standard_names;
    let p = names.len();
    let n = model.robot.joints.len();
    let b = model.base.independent.len();
    (0..b)
        .filter(|&r| {
            let row = &model.base.map[r * p..(r + 1) * p];
            let mut any = false;
            let only = row.iter().enumerate().all(|(j, &v)| {
                if v == 0.0 {
                    return true;
                }
                any = true;
                j >= LINK_PARAMS * n && ["fv", "fc", "fo"].iter().any(|f| names[j].starts_with(f))
            });
            any && only
        })
        .collect()
}

/// Fills one sample's rows: (sample, A (n × k), instruments Z (n × k), y (n)).
type RowFill<'a> =
    dyn FnMut(usize, &mut DMatrix<f64>, &mut DMatrix<f64>, &mut DVector<f64>) -> Result<()> + 'a;

/// Per-joint residual correlation times of A·x − y over the samples `fill` gives.
fn kappas(
    n: usize,
    k: usize,
    samples: usize,
    x: &DVector<f64>,
    fill: &mut RowFill<'_>,
) -> Result<Vec<f64>> {
    let (mut a, mut z, mut y) = (
        DMatrix::zeros(n, k),
        DMatrix::zeros(n, k),
        DVector::zeros(n),
    );
    let mut r = vec![Vec::with_capacity(samples); n];
    for s in 0..samples {
        fill(s, &mut a, &mut z, &mut y)?;
        let e = &a * x - &y;
        for j in 0..n {
            r[j].push(e[j]);
        }
    }
    Ok(r.iter().map(|rj| correlation_time(rj, 1)).collect())
}

fn accumulate(n: usize, k: usize, samples: usize, fill: &mut RowFill<'_>) -> Result<Normal> {
    let mut acc = Normal::new(n, k);
    let (mut a, mut z, mut y) = (
        DMatrix::zeros(n, k),
        DMatrix::zeros(n, k),
        DVector::zeros(n),
    );
    for s in 0..samples {
        if s % 1024 == 0 {
            crate::interrupt::check("payload identification")?;
        }
        fill(s, &mut a, &mut z, &mut y)?;
        acc.add(&a, &z, &y);
    }
    Ok(acc)
}

fn inverse_variances(var: &[f64]) -> Vec<f64> {
    let top = var.iter().fold(0.0f64, |a, b| a.max(*b));
    // A joint whose residual is exactly zero (no torque at all) keeps a finite weight.
    let floor = (top * 1e-12).max(1e-300);
    var.iter().map(|v| 1.0 / v.max(floor)).collect()
}

/// Identifies the payload that `model`'s arm carries in `data` (a run with the payload;
/// torques in the units the model was identified in). The payload's 10 inertial
/// parameters (9 with [`PayloadSettings::mass`]) at the carrying link are fitted to the
/// torque the arm model does not explain, by joint-weighted least squares, with the arm's
/// friction terms re-fitted (see [`PayloadSettings`]); a non-physical fit is projected
/// onto the physical set (J ⪰ 0) in the fit's own metric, so the cost in fit is the least.
/// σ of each quantity from the sandwich covariance of the unconstrained fit plus the arm
/// model's own uncertainty carried through (its covariance, or its σ); each is
/// flagged determined or not ([`Payload::identifiable`]).
///
/// Returns the arm + payload model: `model` with the re-fitted friction, the payload and
/// the residual RMS on `data`; it predicts the loaded arm.
///
/// # Errors
/// [`PrrrpError::ShapeMismatch`] for data of another joint count or a model whose base
/// analysis does not fit its robot; [`PrrrpError::InvalidParameter`] for a link or mass
/// out of range; [`PrrrpError::TooFewSamples`] for fewer equations than unknowns + 1;
/// [`PrrrpError::RankDeficient`] when the data do not determine the payload's mass (it
/// never moved against gravity); [`PrrrpError::Interrupted`].
pub fn identify_payload(
    model: &IdentifiedModel,
    data: &DynDataset,
    settings: &PayloadSettings,
) -> Result<IdentifiedModel> {
    let (chain, n, p) = checked_chain(model, &[data])?;
    let l = check_link(settings.link, n)?;
    if let Some(m) = settings.mass {
        check_mass(m)?;
    }
    let refit = refit_rows(model, settings.refit_friction);
    let np = if settings.mass.is_some() { 9 } else { 10 };
    let first = 10 - np;
    let k = np + refit.len();
    check_samples(k, n, data.len())?;
    let indep = &model.base.independent;
    let fixed: Vec<usize> = (0..indep.len()).filter(|r| !refit.contains(r)).collect();
    let mut ws = chain.workspace();
    let mut yf = vec![0.0; n * p];
    let mass = settings.mass.unwrap_or(0.0);
    let mut fill = |s: usize,
                    a: &mut DMatrix<f64>,
                    z: &mut DMatrix<f64>,
                    y: &mut DVector<f64>|
     -> Result<()> {
        let tau = sample_regressor(&chain, &mut ws, data, s, &mut yf)?;
        for i in 0..n {
            let row = &yf[i * p..(i + 1) * p];
            let known: f64 = fixed.iter().map(|&b| row[indep[b]] * model.beta[b]).sum();
            y[i] = tau[i] - known - mass * row[10 * l];
            for c in 0..np {
                a[(i, c)] = row[10 * l + first + c];
            }
            for (c, &b) in refit.iter().enumerate() {
                a[(i, np + c)] = row[indep[b]];
            }
        }
        z.copy_from(a);
        Ok(())
    };
    let mut prior = DVector::zeros(k);
    for (c, &b) in refit.iter().enumerate() {
        prior[np + c] = model.beta[b];
    }
    let acc = accumulate(n, k, data.len(), &mut fill)?;
    let ones = vec![1.0; n];
    let ols = acc.solve(&ones, &prior, RANK_TOLERANCE)?;
    let w = inverse_variances(&acc.variances(&ols.x));
    let fit = acc.solve(&w, &prior, RANK_TOLERANCE)?;
    let var = acc.variances(&fit.x);
    let kap = kappas(n, k, data.len(), &fit.x, &mut fill)?;
    let mut cov = acc.covariance(&w, &fit.inv, &var, &kap);
    // The arm model is itself an estimate: its error in the base parameters held fixed
    // moves the payload by dx/dβ = −M⁺·Σ w_j A_jᵀ·Y_j,fixed. Without this term σ would
    // say how well the loaded run fits, not how well the payload is known.
    let arm_cov = arm_covariance(model, &fixed);
    if let Some(cb) = &arm_cov {
        let mut ws = chain.workspace();
        let mut yf = vec![0.0; n * p];
        let mut cross = DMatrix::<f64>::zeros(k, fixed.len());
        let (mut a, mut z, mut y) = (
            DMatrix::zeros(n, k),
            DMatrix::zeros(n, k),
            DVector::zeros(n),
        );
        for s in 0..data.len() {
            if s % 1024 == 0 {
                crate::interrupt::check("payload identification")?;
            }
            fill(s, &mut a, &mut z, &mut y)?;
            sample_regressor(&chain, &mut ws, data, s, &mut yf)?;
            for i in 0..n {
                let row = &yf[i * p..(i + 1) * p];
                for (c, &b) in fixed.iter().enumerate() {
                    let v = w[i] * row[indep[b]];
                    if v != 0.0 {
                        for r in 0..k {
                            cross[(r, c)] += a[(i, r)] * v;
                        }
                    }
                }
            }
        }
        let g = -(&fit.inv * cross);
        cov += &g * cb * g.transpose();
    }
    // The mass must be seen: a payload that never moved against gravity or accelerated
    // has no identifiable mass, and then nothing else is.
    if settings.mass.is_none() && fit.undetermined(0) {
        return Err(fit.rank_deficient());
    }

    // Information of the payload block with the friction terms eliminated (their Schur
    // complement): the metric of the physical projection.
    let mut info = DMatrix::zeros(k, k);
    for (j, wj) in w.iter().enumerate() {
        info += &acc.aa[j] * *wj;
    }
    let (ipp, ipf, iff) = (
        info.view((0, 0), (np, np)).into_owned(),
        info.view((0, np), (np, k - np)).into_owned(),
        info.view((np, np), (k - np, k - np)).into_owned(),
    );
    let iff_inv = if k > np {
        crate::linalg::svd(iff.clone())
            .and_then(|s| s.pseudo_inverse(1e-14 * iff.norm().max(1e-300)).ok())
            .unwrap_or_else(|| DMatrix::zeros(k - np, k - np))
    } else {
        DMatrix::zeros(0, 0)
    };
    let schur = &ipp - &ipf * &iff_inv * ipf.transpose();
    let mut pi_hat = [0.0; 10];
    pi_hat[0] = mass;
    for c in 0..np {
        pi_hat[first + c] = fit.x[c];
    }
    let metric = payload_block(first, np, |r, c| schur[(r, c)]);
    let physical_fit = crate::models::payload::is_physical(&pi_hat);
    let pi = if pi_hat[0] <= 0.0 && settings.mass.is_none() {
        // A non-positive mass: the projection would give a massless "payload".
        pi_hat
    } else {
        project_physical(&pi_hat, &metric, settings.mass.is_some())?
    };
    // Friction at its conditional optimum given the projected payload.
    let mut x = fit.x.clone();
    if k > np {
        let dpi = DVector::from_fn(np, |c, _| pi[first + c] - pi_hat[first + c]);
        let df = -&iff_inv * ipf.transpose() * dpi;
        for c in 0..k - np {
            x[np + c] += df[c];
        }
    }
    for c in 0..np {
        x[c] = pi[first + c];
    }
    let pcov = payload_block(first, np, |r, c| cov[(r, c)]);
    let mut payload = if pi[0] > 0.0 {
        Payload::from_parameters(&link_name(&chain, l), l, pi, Some(pcov))?
    } else {
        return Err(PrrrpError::InvalidParameter {
            field: "payload mass".into(),
            value: pi[0],
            reason: "the data show no payload: the fitted mass is <= 0 kg (check that the \
                     run carries the payload and that the arm model is of the same arm)",
        });
    };
    payload.mass_given = settings.mass.is_some();
    payload.classify(&settings.thresholds);
    let mut undetermined = [false; LINK_PARAMS];
    for c in 0..np {
        undetermined[first + c] = fit.undetermined(c);
    }
    flag_undetermined(&mut payload, &undetermined);
    payload.identification = json!({
        "method": "joint-weighted least squares on the torque the arm model does not explain",
        "refit": refit.iter().map(|&b| model.base.combinations[b].clone()).collect::<Vec<_>>(),
        "projected": !physical_fit,
        "unconstrained_parameters": pi_hat,
        "cond": fit.cond,
        "undetermined_directions": fit.dropped.len(),
        "arm_uncertainty_included": arm_cov.is_some(),
        "samples": data.len(),
        "joint_residual_variances": var,
        "correlation_time_samples": kap,
        "thresholds": {
            "max_relative_sigma": settings.thresholds.max_relative_sigma,
            "com_tolerance_m": settings.thresholds.com_tolerance,
        },
    });

    let mut out = model.clone();
    let mut sigma = out.sigma.clone();
    for (c, &b) in refit.iter().enumerate() {
        out.beta[b] = x[np + c];
        if let Some(s) = sigma.as_mut() {
            s[b] = cov[(np + c, np + c)].max(0.0).sqrt();
        }
    }
    out.sigma = sigma;
    out.rsd_percent = out.sigma.as_ref().map(|s| {
        s.iter()
            .zip(&out.beta)
            .map(|(s, b)| (*b != 0.0).then(|| 100.0 * s / b.abs()))
            .collect()
    });
    // The arm's full-covariance no longer matches the re-fitted friction entries.
    out.covariance = None;
    out.payload = Some(payload);
    out.residual_rms = residual_rms(&out, data)?;
    out.actuators = out.actuator_estimates();
    Ok(out)
}

/// Flags as not identifiable the payload quantities that depend on a parameter the data do
/// not determine (`undetermined[k]` for π_k; the pseudo-inverse gives such directions no
/// σ, so the σ test alone would pass them): the mass on m; a centre-of-mass coordinate on
/// m and m·c_k; an entry of the inertia about the centre of mass, I_C = I_O − S(h)ᵀS(h)/m
/// with h = m·c, on m, h and the same entry of I_O.
fn flag_undetermined(p: &mut Payload, undetermined: &[bool; LINK_PARAMS]) {
    let m = undetermined[0] && !p.mass_given;
    let h = undetermined[1] || undetermined[2] || undetermined[3];
    p.identifiable.mass &= !m;
    for k in 0..3 {
        p.identifiable.com[k] &= !(m || undetermined[1 + k]);
    }
    for k in 0..6 {
        p.identifiable.inertia[k] &= !(m || h || undetermined[4 + k]);
    }
}

/// Covariance of the arm model's base parameters `rows` (its full covariance, or its σ²
/// on the diagonal when only those were kept), `None` when the model has neither.
fn arm_covariance(model: &IdentifiedModel, rows: &[usize]) -> Option<DMatrix<f64>> {
    let b = model.beta.len();
    let f = rows.len();
    if let Some(c) = model.covariance.as_ref().filter(|c| c.len() == b * b) {
        return Some(DMatrix::from_fn(f, f, |r, q| c[rows[r] * b + rows[q]]));
    }
    let s = model.sigma.as_ref().filter(|s| s.len() == b)?;
    Some(DMatrix::from_fn(f, f, |r, q| {
        if r == q {
            s[rows[r]] * s[rows[r]]
        } else {
            0.0
        }
    }))
}

/// [`PrrrpError::TooFewSamples`] unless `got` samples of n equations each give at least
/// one more equation than the `k` unknowns.
fn check_samples(k: usize, n: usize, got: usize) -> Result<()> {
    let needed = (k + 1).div_ceil(n);
    if got < needed {
        return Err(PrrrpError::TooFewSamples { needed, got });
    }
    Ok(())
}

/// The model's chain with its joint count n and standard parameter count p, checked
/// against each run's joint count and the model's base analysis.
fn checked_chain(
    model: &IdentifiedModel,
    runs: &[&DynDataset],
) -> Result<(DynChain, usize, usize)> {
    let chain = model.chain()?;
    let (n, p) = (chain.dof(), chain.num_params());
    for data in runs {
        data.check_dof(n, "the model's robot")?;
        if p != model.base.standard_names.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "model base.standard_names".into(),
                expected: format!("{p} (the robot's standard parameters)"),
                got: format!("{}", model.base.standard_names.len()),
            });
        }
    }
    Ok((chain, n, p))
}

fn residual_rms(model: &IdentifiedModel, data: &DynDataset) -> Result<Vec<f64>> {
    let pred = model.predict(data.q(), data.qd(), data.qdd())?;
    let n = data.dof();
    let mut per = vec![0.0; n];
    for (k, (p, t)) in pred.iter().zip(data.tau()).enumerate() {
        per[k % n] += (p - t) * (p - t);
    }
    let s = data.len().max(1) as f64;
    Ok(per.iter().map(|v| (v / s).sqrt()).collect())
}

/// Drive gains, the arm and the payload from motor currents (Gautier & Briot's protocol;
/// see the module docs): `unloaded` and `loaded` are runs of the same arm (ideally the same
/// trajectory) whose `tau` columns hold the actuators' currents (A), the loaded one
/// carrying a payload of the known mass [`DriveGainSettings::mass`] at the link
/// [`DriveGainSettings::link`]. `model` is the arm's identification in current units —
/// only its robot and base analysis are used (identify the unloaded run with any gains,
/// e.g. 1).
///
/// Returns the arm model in torque units with its gains (σ, and whether the data
/// determine each: a gain whose σ exceeds [`DriveGainSettings::max_relative_sigma`], as
/// on a vertical first axis that the payload's weight never loads, is flagged, not
/// trusted), the payload, and the naive least-squares gains.
///
/// # Errors
/// As [`identify_payload`]; [`PrrrpError::InvalidParameter`] for a mass outside 1e-6..1e6 kg
/// or more than [`MAX_DRIVE_GAIN_ITERATIONS`] iterations; [`PrrrpError::RankDeficient`] when
/// the runs determine no gain at all; [`PrrrpError::Interrupted`] on a stop request.
pub fn identify_drive_gains(
    model: &IdentifiedModel,
    unloaded: &DynDataset,
    loaded: &DynDataset,
    settings: &DriveGainSettings,
) -> Result<DriveGainsFit> {
    let (chain, n, p) = checked_chain(model, &[unloaded, loaded])?;
    check_mass(settings.mass)?;
    if settings.iterations > MAX_DRIVE_GAIN_ITERATIONS {
        return Err(PrrrpError::InvalidParameter {
            field: "iterations".into(),
            value: settings.iterations as f64,
            reason: "more than MAX_DRIVE_GAIN_ITERATIONS (1000) instrumental-variable \
                     iterations: the estimate settles within a few (default 3)",
        });
    }
    let l = check_link(settings.link, n)?;
    let coupling = chain.actuators().coupling_row_major(n);
    let indep = model.base.independent.clone();
    let b = indep.len();
    let refit = refit_rows(model, settings.refit_friction);
    let nf = refit.len();
    // x = [K (n) | β (b) | loaded-run friction (nf) | payload without its mass (9)].
    let k = n + b + nf + 9;
    let (nu, nl) = (unloaded.len(), loaded.len());
    check_samples(k, n, nu + nl)?;
    let mut ws = chain.workspace();
    let mut yf = vec![0.0; n * p];
    let mass = settings.mass;
    // Rows of one sample: Cᵀ·(K∘i) − Y_b·β − … = m·Y_m; the instruments replace each
    // current by `predicted` (A) when given.
    let mut rows = |s: usize,
                    a: &mut DMatrix<f64>,
                    z: &mut DMatrix<f64>,
                    y: &mut DVector<f64>,
                    x: Option<&DVector<f64>>|
     -> Result<()> {
        let (data, s, is_loaded) = if s < nu {
            (unloaded, s, false)
        } else {
            (loaded, s - nu, true)
        };
        let cur = sample_regressor(&chain, &mut ws, data, s, &mut yf)?;
        a.fill(0.0);
        y.fill(0.0);
        for i in 0..n {
            let row = &yf[i * p..(i + 1) * p];
            for m in 0..n {
                a[(i, m)] = coupling[m * n + i] * cur[m];
            }
            for (c, &j) in indep.iter().enumerate() {
                a[(i, n + c)] = -row[j];
            }
            if is_loaded {
                for (f, &c) in refit.iter().enumerate() {
                    a[(i, n + b + f)] = -row[indep[c]];
                    a[(i, n + c)] = 0.0;
                }
                for c in 0..9 {
                    a[(i, n + b + nf + c)] = -row[10 * l + 1 + c];
                }
                y[i] = mass * row[10 * l];
            }
        }
        z.copy_from(a);
        if let Some(x) = x {
            // The torque the model predicts from the positions alone, as currents.
            let tau: DVector<f64> = &*y - a.columns(n, k - n) * x.rows(n, k - n);
            // Actuator currents from joint torques: solve Cᵀ·(K∘i) = τ.
            let ct = DMatrix::from_fn(n, n, |i, m| coupling[m * n + i] * x[m]);
            let ihat = ct.lu().solve(&tau).unwrap_or_else(|| DVector::zeros(n));
            for i in 0..n {
                for m in 0..n {
                    z[(i, m)] = coupling[m * n + i] * ihat[m];
                }
            }
        }
        Ok(())
    };
    let total = nu + nl;
    let ones = vec![1.0; n];
    let mut prior = DVector::zeros(k);
    for m in 0..n {
        prior[m] = 1.0;
    }
    let acc = accumulate(n, k, total, &mut |s, a, z, y| rows(s, a, z, y, None))?;
    let ols = acc.solve(&ones, &prior, RANK_TOLERANCE)?;
    let mut w = inverse_variances(&acc.variances(&ols.x));
    let mut fit = acc.solve(&w, &prior, RANK_TOLERANCE)?;
    let naive: Vec<f64> = fit.x.rows(0, n).iter().copied().collect();
    let mut acc = acc;
    for _ in 0..settings.iterations {
        crate::interrupt::check("drive-gain identification")?;
        let x_prev = fit.x.clone();
        acc = accumulate(n, k, total, &mut |s, a, z, y| {
            rows(s, a, z, y, Some(&x_prev))
        })?;
        fit = acc.solve(&w, &x_prev, RANK_TOLERANCE)?;
        w = inverse_variances(&acc.variances(&fit.x));
    }
    let var = acc.variances(&fit.x);
    let x_fin = fit.x.clone();
    let instrumented = settings.iterations > 0;
    let kap = kappas(n, k, total, &fit.x, &mut |s, a, z, y| {
        rows(s, a, z, y, instrumented.then_some(&x_fin))
    })?;
    let cov = acc.covariance(&w, &fit.inv, &var, &kap);
    let x = &fit.x;
    let gains: Vec<f64> = (0..n).map(|m| x[m]).collect();
    let gsig: Vec<f64> = (0..n).map(|m| cov[(m, m)].max(0.0).sqrt()).collect();
    let undetermined: Vec<bool> = (0..n).map(|m| fit.undetermined(m)).collect();
    if undetermined.iter().all(|u| *u) {
        return Err(fit.rank_deficient());
    }
    let identifiable: Vec<bool> = (0..n)
        .map(|m| {
            !undetermined[m]
                && gains[m] != 0.0
                && gsig[m] <= settings.max_relative_sigma * gains[m].abs()
        })
        .collect();

    // The arm in torque units: the unloaded run with currents turned into torques.
    let beta: Vec<f64> = (0..b).map(|c| x[n + c]).collect();
    let bsig: Vec<f64> = (0..b)
        .map(|c| cov[(n + c, n + c)].max(0.0).sqrt())
        .collect();
    let bcov: Vec<f64> = (0..b * b).map(|e| cov[(n + e / b, n + e % b)]).collect();
    let mut arm = model.clone();
    arm.beta = beta;
    arm.sigma = Some(bsig);
    arm.rsd_percent = arm.sigma.as_ref().map(|s| {
        s.iter()
            .zip(&arm.beta)
            .map(|(s, b)| (*b != 0.0).then(|| 100.0 * s / b.abs()))
            .collect()
    });
    arm.covariance = Some(bcov);
    arm.cond = Some(fit.cond.max(1.0)).filter(|c| c.is_finite());
    arm.method = "drive-gains".into();
    arm.settings = json!({
        "estimator": if instrumented { "instrumental variables (IDIM-IV)" } else { "least squares" },
        "iterations": settings.iterations,
        "payload_mass_kg": mass,
        "payload_link": l,
        "refit_friction": settings.refit_friction,
        "max_relative_sigma": settings.max_relative_sigma,
        "samples": {"unloaded": nu, "loaded": nl},
        "joint_residual_variances": var,
        "correlation_time_samples": kap,
    });
    arm.standard = None;
    arm.payload = None;
    arm.drive_gains = Some(DriveGains {
        values: gains.clone(),
        sigma: gsig,
        identifiable,
        identification: json!({
            "method": if instrumented { "iv" } else { "ls" },
            "naive_least_squares": naive,
            "payload_mass_kg": mass,
            "undetermined": undetermined,
        }),
    });
    let torque_data = to_torques(unloaded, &coupling, &gains)?;
    arm.residual_rms = residual_rms(&arm, &torque_data)?;
    arm.validate()?;
    arm.actuators = arm.actuator_estimates();

    let mut pi = [0.0; 10];
    pi[0] = mass;
    for c in 0..9 {
        pi[1 + c] = x[n + b + nf + c];
    }
    let off = n + b + nf;
    let pcov = payload_block(1, 9, |r, c| cov[(off + r, off + c)]);
    let info_inv = cov.view((off, off), (9, 9)).into_owned();
    let metric = match info_inv.clone().try_inverse() {
        Some(info) => payload_block(1, 9, |r, c| info[(r, c)]),
        None => payload_block(1, 9, |r, c| if r == c { 1.0 } else { 0.0 }),
    };
    let projected = !crate::models::payload::is_physical(&pi);
    let pi = project_physical(&pi, &metric, true)?;
    let mut payload = Payload::from_parameters(&link_name(&chain, l), l, pi, Some(pcov))?;
    payload.mass_given = true;
    payload.classify(&settings.thresholds);
    let mut undetermined = [false; LINK_PARAMS];
    for c in 0..9 {
        undetermined[1 + c] = fit.undetermined(off + c);
    }
    flag_undetermined(&mut payload, &undetermined);
    payload.identification = json!({
        "method": "with the drive gains (instrumental variables)",
        "projected": projected,
    });
    Ok(DriveGainsFit {
        model: arm,
        payload,
        naive_gains: naive,
    })
}

/// A 10×10 matrix over a payload's inertial parameters (row-major), zero but for the
/// m×m block from parameter `first` on, whose entry (r, c) is `f(r, c)`.
fn payload_block(first: usize, m: usize, f: impl Fn(usize, usize) -> f64) -> Vec<f64> {
    let mut out = vec![0.0; LINK_PARAMS * LINK_PARAMS];
    for r in 0..m {
        for c in 0..m {
            out[(first + r) * LINK_PARAMS + first + c] = f(r, c);
        }
    }
    out
}

/// The name of link `l` (0-based) of `chain`, or `link{l+1}` for a chain without one.
fn link_name(chain: &DynChain, l: usize) -> String {
    chain
        .meta()
        .links
        .get(l)
        .cloned()
        .unwrap_or_else(|| format!("link{}", l + 1))
}

/// A copy of `data` whose currents (A) are joint torques Cᵀ·(K∘i).
fn to_torques(data: &DynDataset, coupling: &[f64], gains: &[f64]) -> Result<DynDataset> {
    let n = data.dof();
    let mut tau = vec![0.0; data.tau().len()];
    for (s, cur) in data.tau().chunks_exact(n).enumerate() {
        for i in 0..n {
            tau[s * n + i] = (0..n)
                .map(|m| coupling[m * n + i] * gains[m] * cur[m])
                .sum();
        }
    }
    data.with_tau(tau)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identification::{identify, LsSettings, Method};
    use crate::test_support::{puma, random_data};
    use crate::BaseOptions;

    #[test]
    fn drive_gain_iterations_beyond_the_bound_are_refused() {
        let chain = puma(false);
        let data = random_data(200, 7, |_| 2.0);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let ls = Method::Ls(LsSettings::default());
        let model = identify(&chain, &base, &data, &ls, serde_json::Value::Null).unwrap();
        let settings = DriveGainSettings {
            iterations: MAX_DRIVE_GAIN_ITERATIONS + 1,
            ..DriveGainSettings::new(1.0)
        };
        let got = identify_drive_gains(&model, &data, &data, &settings);
        assert!(
            matches!(&got, Err(PrrrpError::InvalidParameter { field, .. }) if field == "iterations"),
            "{got:?}"
        );
    }
}
