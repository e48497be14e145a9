//! The result of an identification, for any robot: an [`IdentifiedModel`] holds the robot
//! description, the base-parameter analysis, the estimate β̂ with its uncertainty, the fit
//! statistics and how the data were prepared. It predicts joint torques on its own and
//! round-trips through JSON (schema version [`MODEL_SCHEMA_VERSION`], documented in
//! `docs/model-schema.md`), so a saved model needs neither the robot file nor the data.

use serde::{Deserialize, Serialize};

use crate::error::{check_joints, PrrrpError, Result};
use crate::models::chain::{BaseParameters, ChainDescription, DynChain, DynWorkspace};
use crate::models::payload::Payload;

mod ekf_defaults;
mod methods;
pub(crate) use methods::Rows;
mod payload;
pub use payload::{
    identify_drive_gains, identify_payload, DriveGainSettings, DriveGainsFit, PayloadSettings,
    MAX_DRIVE_GAIN_ITERATIONS,
};

pub use methods::{
    identify, identify_cached, identify_robot, identify_robot_cached, EkfSettings, EkfStart,
    FitCache, GradientSettings, LsSettings, Method, PhysicalSettings, RlsSettings, METHOD_NAMES,
};

/// Version of the [`IdentifiedModel`] JSON layout; bumped on any incompatible change.
/// Version 2: the robot may carry actuators (coupling, armature; chain schema 2) and the
/// model lists its actuator estimates ([`IdentifiedModel::actuators`]). Version 3: an
/// optional payload ([`IdentifiedModel::payload`]) whose torques predictions add, and
/// identified drive gains ([`IdentifiedModel::drive_gains`]); a model with neither is
/// still written as version 2. Versions 1 and 2 still load.
pub const MODEL_SCHEMA_VERSION: u32 = 3;

/// The base-parameter analysis a model was identified in: which standard parameters are
/// the base columns and how the others fold into them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaseDescription {
    /// Indices of the standard parameters kept as base columns (τ = Y[:, independent]·β).
    pub independent: Vec<usize>,
    /// Names of the standard parameters, e.g. `m1, mx1, …, fv1, …`.
    pub standard_names: Vec<String>,
    /// Each base parameter as a readable combination of standard ones.
    pub combinations: Vec<String>,
    /// β = map·π, row-major (count × standard parameters).
    pub map: Vec<f64>,
    /// Rank tolerance of the analysis.
    pub rank_tolerance: f64,
}

impl From<&BaseParameters> for BaseDescription {
    fn from(b: &BaseParameters) -> Self {
        Self {
            independent: b.independent.clone(),
            standard_names: b.names.clone(),
            combinations: b.combinations.clone(),
            map: b.map_row_major(),
            rank_tolerance: b.rank_tolerance,
        }
    }
}

/// An identified dynamic model (see the module docs). Units: β in the SI units of its
/// combination (kg, kg·m, kg·m², N·m·s/rad, N·m); torques in N·m or N.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifiedModel {
    /// [`MODEL_SCHEMA_VERSION`] of the writer.
    pub schema_version: u32,
    /// The robot: joints, the inertials it was loaded with (a prior), friction model.
    pub robot: ChainDescription,
    /// The base-parameter analysis.
    pub base: BaseDescription,
    /// The estimate β̂, one value per base parameter.
    pub beta: Vec<f64>,
    /// Standard deviation of each β̂ where the method gives one.
    pub sigma: Option<Vec<f64>>,
    /// 100·σ/|β̂| (%), where σ is given; `None` in an entry whose β̂ is exactly 0 (the
    /// relative deviation is undefined there).
    pub rsd_percent: Option<Vec<Option<f64>>>,
    /// Covariance of β̂ (row-major b × b) where the method gives one (the EKF).
    pub covariance: Option<Vec<f64>>,
    /// Condition number of the base observation matrix W_b, where computed.
    pub cond: Option<f64>,
    /// RMS of the torque residual per joint on the identification data (N·m or N).
    pub residual_rms: Vec<f64>,
    /// The method: `"ls"`, `"wls"`, `"rls"`, `"adaline"`, `"hopfield"`, `"ekf"`, ….
    pub method: String,
    /// The method's settings, as given (free-form JSON object).
    pub settings: serde_json::Value,
    /// What the preprocessing did (free-form JSON object: rows dropped, rate, cut-off …).
    pub preprocessing: serde_json::Value,
    /// Physically consistent standard parameters π (the robot's layout: 10 inertial per
    /// link, then the actuator terms) with K·π = β̂, where the method gives them (`"physical"`);
    /// they make [`IdentifiedModel::to_urdf`] possible. Optional in the JSON (schema v1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub standard: Option<Vec<f64>>,
    /// Whether the method met its stopping rule. The gradient methods (Adaline, Hopfield)
    /// train until the relative changes of the estimate and of the equation error per
    /// epoch fall below their tolerances ([`GradientSettings`]); `false` means they hit
    /// `max_epochs` first and β̂ is not at the method's optimum. The one-pass and closed-
    /// form methods (LS, WLS, RLS, EKF, physical) are `true` when they finished normally
    /// (a failure is an error, never a model). Optional in the JSON (default `true`).
    #[serde(default = "converged_default")]
    pub converged: bool,
    /// Epochs (passes over the data) the gradient methods trained; `None` for the others.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epochs: Option<usize>,
    /// Each actuator's identified terms (friction, armature) with σ, read off β̂ and σ by
    /// [`IdentifiedModel::actuator_estimates`] (schema 2; empty without actuator terms).
    /// Written for the reader of the JSON; recomputed on load.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub actuators: Vec<ActuatorEstimate>,
    /// A payload carried by the arm (schema 3): its torques Y[:, carrying link]·π are added
    /// to every prediction. `None` for the bare arm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Payload>,
    /// Drive gains identified with the model (schema 3; N·m/A or N/A per actuator,
    /// joint side), with σ and whether the data determine each.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_gains: Option<DriveGains>,
}

/// Drive gains K (τ = Cᵀ·(K∘i)) identified from motor currents
/// ([`identify_drive_gains`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DriveGains {
    /// One gain per actuator (N·m/A, or N/A for a prismatic joint).
    pub values: Vec<f64>,
    /// σ of each gain (same units).
    pub sigma: Vec<f64>,
    /// Whether the data determine each gain (σ at most `max_relative_sigma` of it); a gain
    /// the data do not determine is the estimate's value, not to be trusted.
    pub identifiable: Vec<bool>,
    /// How they were identified (method, settings, the naive least-squares values beside).
    #[serde(default)]
    pub identification: serde_json::Value,
}

fn converged_default() -> bool {
    true
}

/// One actuator term (`fv3`, `Ia6`, …) of an identified model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TermEstimate {
    /// The standard parameter's name, e.g. `Ia6` (units: fv N·m·s/rad or N·s/m, fc and fo
    /// N·m or N, Ia kg·m² or kg, joint side).
    pub name: String,
    /// Index of the base parameter the term is identified in; `None` when the data
    /// cannot see it (an unidentifiable term).
    pub base_index: Option<usize>,
    /// That base parameter's combination: the term's own name when it is identified on
    /// its own, else e.g. `Izz1 + Ia1` (an armature that turns with one link only is
    /// inseparable from the link's inertia).
    pub combination: Option<String>,
    /// Whether the term is a base parameter on its own, so that `value` is the term.
    pub alone: bool,
    /// β̂ of that base parameter.
    pub value: Option<f64>,
    /// Its standard deviation, where the method gives one.
    pub sigma: Option<f64>,
    /// The term's physically consistent standard value, where the method gives standard
    /// parameters (`"physical"`).
    pub standard: Option<f64>,
}

/// The identified terms of one actuator ([`IdentifiedModel::actuators`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActuatorEstimate {
    /// Actuator number, 1-based.
    pub actuator: usize,
    /// The joints it moves (those with a non-zero coupling coefficient).
    pub joints: Vec<String>,
    /// Its terms among viscous, Coulomb, offset friction and armature, in that order.
    pub terms: Vec<TermEstimate>,
}

impl IdentifiedModel {
    /// A model from its parts, checked for consistency.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] when β, σ, the covariance, the residuals or the base
    /// analysis do not fit the robot (among them a `base` analysed for another chain, as
    /// [`identify`] refuses it); [`PrrrpError::NonFinite`] for a NaN/∞ in β or σ.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        chain: &DynChain,
        base: &BaseParameters,
        beta: Vec<f64>,
        sigma: Option<Vec<f64>>,
        covariance: Option<Vec<f64>>,
        cond: Option<f64>,
        residual_rms: Vec<f64>,
        method: &str,
        settings: serde_json::Value,
        preprocessing: serde_json::Value,
    ) -> Result<Self> {
        // Identify's own check: another chain's analysis was accepted here, saved and read
        // back, and failed only at `predict`.
        base.check_layout(chain.dof(), &chain.layout())?;
        let rsd_percent = sigma.as_ref().map(|s| {
            s.iter()
                .zip(&beta)
                .map(|(s, b)| (*b != 0.0).then(|| 100.0 * s / b.abs()))
                .collect()
        });
        let model = Self {
            schema_version: MODEL_SCHEMA_VERSION,
            robot: chain.description(),
            base: BaseDescription::from(base),
            beta,
            sigma,
            rsd_percent,
            covariance,
            cond,
            residual_rms,
            method: method.into(),
            settings,
            preprocessing,
            standard: None,
            converged: true,
            epochs: None,
            actuators: Vec::new(),
            payload: None,
            drive_gains: None,
        };
        model.validate()?;
        let mut model = model;
        model.actuators = model.actuator_estimates();
        Ok(model)
    }

    /// Each actuator's terms (friction and armature, the parameters after the 10·n
    /// inertial ones) with the base parameter they are identified in, its β̂ and σ (see
    /// [`TermEstimate`]). Empty when the robot has no actuator terms.
    pub fn actuator_estimates(&self) -> Vec<ActuatorEstimate> {
        let n = self.robot.joints.len();
        let names = &self.base.standard_names;
        let p = names.len();
        let b = self.base.independent.len();
        if n == 0 || p <= 10 * n || (p - 10 * n) % n != 0 || self.base.map.len() != b * p {
            return Vec::new();
        }
        let per = (p - 10 * n) / n;
        let coupling = self
            .robot
            .actuators
            .as_ref()
            .map(|a| a.coupling_row_major(n))
            .unwrap_or_else(|| crate::Actuators::default().coupling_row_major(n));
        let map = |r: usize, j: usize| self.base.map[r * p + j];
        (0..n)
            .map(|m| {
                let terms = (0..per)
                    .map(|s| {
                        let j = 10 * n + per * m + s;
                        let rows: Vec<usize> = (0..b).filter(|&r| map(r, j) != 0.0).collect();
                        let own = self.base.independent.iter().position(|&i| i == j);
                        let r = own.or_else(|| (rows.len() == 1).then(|| rows[0]));
                        let alone = r.is_some_and(|r| (0..p).all(|k| k == j || map(r, k) == 0.0));
                        TermEstimate {
                            name: names[j].clone(),
                            base_index: r,
                            combination: r.map(|r| self.base.combinations[r].clone()),
                            alone,
                            value: r.and_then(|r| self.beta.get(r).copied()),
                            sigma: r.and_then(|r| self.sigma.as_ref()?.get(r).copied()),
                            standard: self.standard.as_ref().and_then(|s| s.get(j).copied()),
                        }
                    })
                    .collect();
                ActuatorEstimate {
                    actuator: m + 1,
                    joints: (0..n)
                        .filter(|&j| coupling[m * n + j] != 0.0)
                        .map(|j| self.robot.joints[j].name.clone())
                        .collect(),
                    terms,
                }
            })
            .collect()
    }

    /// A URDF of the robot with the identified inertials: the standard parameters π of a
    /// physically consistent method written into the robot's links (friction is not a
    /// URDF quantity and stays in the model).
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] if the model carries no standard parameters (only
    /// `"physical"` gives them: base parameters alone do not determine the links), and as
    /// [`DynChain::to_urdf`].
    pub fn to_urdf(&self) -> Result<String> {
        let Some(pi) = &self.standard else {
            return Err(PrrrpError::InvalidParameter {
                field: format!("model of method {:?}", self.method),
                value: f64::NAN,
                reason: "carries base parameters only, which do not determine each link's \
                         inertials: identify with method \"physical\" for a URDF",
            });
        };
        self.chain()?.to_urdf(Some(pi))
    }

    fn validate(&self) -> Result<()> {
        if !(1..=MODEL_SCHEMA_VERSION).contains(&self.schema_version) {
            return Err(PrrrpError::InvalidParameter {
                field: "schema_version".into(),
                value: self.schema_version as f64,
                reason: "unknown model version (this prrrp reads versions 1 to 3)",
            });
        }
        let n = self.robot.joints.len();
        let b = self.base.independent.len();
        let p = self.base.standard_names.len();
        // Sizes first, before any product of them is formed or allocated (an 8000-joint
        // file would otherwise ask for a p × p covariance of 10¹⁰ values).
        crate::models::chain::check_dof("robot.joints", n)?;
        // Per joint: 10 inertial parameters and the actuator terms (fv, fc, fo, Ia).
        let most = n * (crate::LINK_PARAMS + crate::models::chain::ACTUATOR_PARAMETER_NAMES.len());
        if p > most || b > p {
            return Err(PrrrpError::ShapeMismatch {
                what: "base (standard_names, independent)".into(),
                expected: format!("at most {most} standard and as many base parameters"),
                got: format!("{p} standard, {b} base parameters"),
            });
        }
        let shape = |what: &str, want: usize, got: usize| -> Result<()> {
            if want == got {
                Ok(())
            } else {
                Err(PrrrpError::ShapeMismatch {
                    what: what.into(),
                    expected: format!("{want} values"),
                    got: format!("{got} values"),
                })
            }
        };
        shape("beta (one per base parameter)", b, self.beta.len())?;
        shape("base.combinations", b, self.base.combinations.len())?;
        shape("base.map (base × standard)", b * p, self.base.map.len())?;
        shape("residual_rms (one per joint)", n, self.residual_rms.len())?;
        if let Some(s) = &self.sigma {
            shape("sigma (one per base parameter)", b, s.len())?;
            if let Some(row) = s.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: "sigma (must be finite and >= 0)".into(),
                    row: Some(row),
                });
            }
            // A finite negative σ read as "has a NaN or infinite value".
            if let Some(row) = s.iter().position(|x| *x < 0.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("sigma[{row}]"),
                    value: s[row],
                    reason: "a standard deviation must be >= 0",
                });
            }
        }
        if let Some(c) = &self.covariance {
            shape("covariance (base × base)", b * b, c.len())?;
            if let Some(row) = c.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: "covariance".into(),
                    row: Some(row),
                });
            }
        }
        if let Some(c) = self.cond {
            if !(c.is_finite() && c >= 1.0) {
                return Err(PrrrpError::InvalidParameter {
                    field: "cond".into(),
                    value: c,
                    reason: "a condition number is finite and >= 1 (rank-deficient data \
                             give no model)",
                });
            }
        }
        if let Some(&j) = self.base.independent.iter().find(|&&j| j >= p) {
            return Err(PrrrpError::ShapeMismatch {
                what: "base.independent".into(),
                expected: format!("indices below {p} (standard parameters)"),
                got: format!("index {j}"),
            });
        }
        if let Some(pl) = &self.payload {
            pl.validate()?;
            if pl.link_index >= n {
                return Err(PrrrpError::ShapeMismatch {
                    what: "payload.link_index".into(),
                    expected: format!("a link of the robot (below {n})"),
                    got: format!("{}", pl.link_index),
                });
            }
        }
        if let Some(g) = &self.drive_gains {
            shape("drive_gains.values (one per actuator)", n, g.values.len())?;
            shape("drive_gains.sigma (one per actuator)", n, g.sigma.len())?;
            shape("drive_gains.identifiable", n, g.identifiable.len())?;
            if let Some(row) = g.values.iter().chain(&g.sigma).position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: "drive_gains".into(),
                    row: Some(row),
                });
            }
        }
        for (name, v) in [("beta", &self.beta), ("residual_rms", &self.residual_rms)] {
            if let Some(row) = v.iter().position(|x| !x.is_finite()) {
                return Err(PrrrpError::NonFinite {
                    what: name.into(),
                    row: Some(row),
                });
            }
        }
        // A β of 1e299 predicted torques whose squares overflowed: errors printed as inf.
        if let Some((row, &v)) = self
            .beta
            .iter()
            .enumerate()
            .find(|(_, v)| v.abs() >= crate::MAX_MAGNITUDE)
        {
            return Err(PrrrpError::InvalidParameter {
                field: format!("beta[{row}]"),
                value: v,
                reason: "no base parameter reaches MAX_MAGNITUDE (1e100); the file is damaged",
            });
        }
        // A repeated index read one standard parameter twice and predicted wrong torques.
        let mut seen = vec![false; p];
        if let Some(&j) = self
            .base
            .independent
            .iter()
            .find(|&&j| std::mem::replace(&mut seen[j], true))
        {
            return Err(PrrrpError::ShapeMismatch {
                what: "base.independent".into(),
                expected: "distinct standard-parameter indices".into(),
                got: format!("index {j} twice"),
            });
        }
        Ok(())
    }

    /// The robot as a chain (with the inertials it was loaded with).
    ///
    /// # Errors
    /// As [`DynChain::from_description`].
    pub fn chain(&self) -> Result<DynChain> {
        DynChain::from_description(&self.robot)
    }

    /// A predictor: the chain and a workspace, built once for many [`Predictor::predict_into`]
    /// calls.
    ///
    /// # Errors
    /// As [`IdentifiedModel::chain`], and [`PrrrpError::ShapeMismatch`] if the robot's
    /// parameter count does not match the base analysis.
    pub fn predictor(&self) -> Result<Predictor<'_>> {
        let chain = self.chain()?;
        self.check_base_fits(&chain)?;
        let ws = chain.workspace();
        let y = vec![0.0; chain.dof() * chain.num_params()];
        if let Some(pl) = &self.payload {
            if pl.link_index >= chain.dof() {
                return Err(PrrrpError::ShapeMismatch {
                    what: "payload.link_index".into(),
                    expected: format!("a link of the robot (below {})", chain.dof()),
                    got: format!("{}", pl.link_index),
                });
            }
        }
        Ok(Predictor {
            model: self,
            chain,
            ws,
            y,
        })
    }

    /// Refuses a base analysis whose standard parameters are not the robot's (another
    /// chain's analysis, or one with other actuator terms).
    fn check_base_fits(&self, chain: &DynChain) -> Result<()> {
        if chain.num_params() != self.base.standard_names.len() {
            return Err(PrrrpError::ShapeMismatch {
                what: "base.standard_names".into(),
                expected: format!("{} (the robot's standard parameters)", chain.num_params()),
                got: format!("{}", self.base.standard_names.len()),
            });
        }
        Ok(())
    }

    /// Joint torques τ = Y_b(q, q̇, q̈)·β̂ for many samples: flat row-major (samples × n)
    /// inputs and output.
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for lengths that are not multiples of n or differ,
    /// [`PrrrpError::NonFinite`] naming the first bad sample (a NaN/∞ input, or a torque
    /// the inputs overflow), [`PrrrpError::InvalidParameter`] naming the sample of an
    /// input at or above [`crate::MAX_MAGNITUDE`].
    pub fn predict(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Vec<f64>> {
        let mut p = self.predictor()?;
        let n = p.chain.dof();
        let samples = crate::models::chain::flat_samples(n, q, qd, qdd)?;
        let mut tau = vec![0.0; n * samples];
        for k in 0..samples {
            let r = n * k..n * k + n;
            p.predict_into(&q[r.clone()], &qd[r.clone()], &qdd[r.clone()], &mut tau[r])
                .map_err(|e| match e {
                    PrrrpError::NonFinite { what, .. } => {
                        PrrrpError::NonFinite { what, row: Some(k) }
                    }
                    PrrrpError::InvalidParameter {
                        field,
                        value,
                        reason,
                    } => PrrrpError::InvalidParameter {
                        field: format!("{field} at sample {k}"),
                        value,
                        reason,
                    },
                    other => other,
                })?;
        }
        Ok(tau)
    }

    /// The model as JSON (see the module docs).
    ///
    /// # Errors
    /// [`PrrrpError::NonFinite`] if a value is not finite (JSON has no NaN).
    pub fn to_json(&self) -> Result<String> {
        let mut out = self.clone();
        // Version 3 only where its fields are used: a reader of version 2 would ignore a
        // payload and predict the bare arm, so it must refuse such a file, but it reads a
        // plain model as well as ever.
        out.schema_version = if out.payload.is_some() || out.drive_gains.is_some() {
            MODEL_SCHEMA_VERSION
        } else {
            2
        };
        out.actuators = self.actuator_estimates();
        if let Some(p) = out.payload.as_mut() {
            p.derive();
        }
        crate::json::to_pretty(&out, "identified model")
    }

    /// A model from the JSON of [`IdentifiedModel::to_json`], checked.
    ///
    /// # Errors
    /// [`PrrrpError::InvalidParameter`] naming the JSON problem, and the errors of
    /// [`IdentifiedModel::new`].
    pub fn from_json(text: &str) -> Result<Self> {
        let mut m: Self = crate::json::parse(
            text,
            "model",
            "not a prrrp model file; write it with IdentifiedModel::to_json",
        )?;
        m.validate()?;
        // A file cannot carry a `BaseParameters`, so `new`'s check is the analysis's size
        // against the robot's: a mismatch read fine and failed only at `predict`.
        m.check_base_fits(&m.chain()?)?;
        // A file of any version this prrrp reads is held in this version's layout (as a
        // model built here is); `to_json` decides the version it writes.
        m.schema_version = MODEL_SCHEMA_VERSION;
        m.actuators = m.actuator_estimates();
        if let Some(p) = m.payload.as_mut() {
            p.derive();
        }
        Ok(m)
    }
}

/// Torque prediction of an [`IdentifiedModel`] with preallocated buffers
/// ([`IdentifiedModel::predictor`]); `predict_into` allocates nothing.
#[derive(Debug, Clone)]
pub struct Predictor<'m> {
    model: &'m IdentifiedModel,
    chain: DynChain,
    ws: DynWorkspace,
    y: Vec<f64>,
}

impl Predictor<'_> {
    /// The robot as a chain.
    pub fn chain(&self) -> &DynChain {
        &self.chain
    }

    /// τ = Y_b·β̂ of one sample into `tau` (n entries, N·m or N).
    ///
    /// # Errors
    /// [`PrrrpError::ShapeMismatch`] for slices that do not have n entries,
    /// [`PrrrpError::NonFinite`] for NaN/∞ inputs or a predicted torque that is not finite
    /// (the inputs overflow the model), [`PrrrpError::InvalidParameter`] for an input at
    /// or above [`crate::MAX_MAGNITUDE`].
    pub fn predict_into(
        &mut self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        tau: &mut [f64],
    ) -> Result<()> {
        // Finite was not enough: q̇ = 1e160 squared overflows, and `Ok([NaN; n])` came back.
        for (name, v) in [("q", q), ("qd", qd), ("qdd", qdd)] {
            crate::bounds::check_sample(name, v)?;
        }
        self.chain
            .regressor_row_major_into(&mut self.ws, q, qd, qdd, &mut self.y)?;
        let (n, p) = (self.chain.dof(), self.chain.num_params());
        check_joints("tau", tau.len(), n)?;
        let base = &self.model.base.independent;
        let payload = self.model.payload.as_ref();
        for (i, t) in tau.iter_mut().enumerate() {
            let row = &self.y[i * p..(i + 1) * p];
            *t = base
                .iter()
                .zip(&self.model.beta)
                .map(|(&j, b)| row[j] * b)
                .sum();
            if let Some(pl) = payload {
                // The link index was checked against the chain when the predictor was built.
                *t += pl.torque_from_regressor_row(row).unwrap_or(0.0);
            }
        }
        // A backstop for inputs below MAX_MAGNITUDE whose products with β̂ still overflow.
        if let Some(j) = tau.iter().position(|t| !t.is_finite()) {
            return Err(PrrrpError::NonFinite {
                what: format!(
                    "predicted torque tau[{j}] (the inputs q, qd, qdd overflow the model: \
                     check their units, rad, m, per s)"
                ),
                row: None,
            });
        }
        Ok(())
    }
}

/// Identifies the base parameters of `chain` (in the analysis `base`) from `data` by
/// ordinary (`weighted = false`, method `"ls"`) or weighted least squares with per-joint
/// noise variances estimated from the residuals (`"wls"`): [`identify`] with
/// [`Method::Ls`] or [`Method::Wls`].
///
/// # Errors
/// As [`identify`].
pub fn identify_least_squares(
    chain: &DynChain,
    base: &BaseParameters,
    data: &crate::DynDataset,
    weighted: bool,
    config: &crate::LeastSquaresConfig,
    preprocessing: serde_json::Value,
) -> Result<IdentifiedModel> {
    let s = LsSettings {
        rank_tolerance: config.rank_tolerance,
    };
    let method = if weighted {
        Method::Wls(s)
    } else {
        Method::Ls(s)
    };
    identify(chain, base, data, &method, preprocessing)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BaseOptions;

    fn model(chain: &DynChain, base: &BaseParameters) -> Result<IdentifiedModel> {
        let beta = base.base_values(&chain.parameters())?;
        let n = chain.dof();
        IdentifiedModel::new(
            chain,
            base,
            beta,
            None,
            None,
            None,
            vec![0.0; n],
            "ls",
            serde_json::Value::Null,
            serde_json::Value::Null,
        )
    }

    /// q̇ = 1e160 returned `Ok([NaN; n])` (finite inputs whose products overflow): inputs
    /// at or above MAX_MAGNITUDE are refused with their sample, and a torque that still
    /// overflows is refused as such.
    #[test]
    fn predict_refuses_inputs_that_overflow_the_model() {
        let chain = crate::test_support::puma(false);
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let mut m = model(&chain, &base).unwrap();
        let ok = vec![0.1; 12];
        let mut huge = ok.clone();
        huge[7] = 1e160;
        let err = m.predict(&ok, &huge, &ok).unwrap_err();
        let named = matches!(&err, PrrrpError::InvalidParameter { field, .. }
            if field == "qd[1] at sample 1");
        assert!(named, "{err}");
        assert!(m
            .predict(&ok, &ok, &ok)
            .unwrap()
            .iter()
            .all(|t| t.is_finite()));
        // The backstop: inputs below the bound, but a β̂ (not checked by `predict`) that
        // takes the products past f64::MAX.
        m.beta.iter_mut().for_each(|b| *b = 1e300);
        let mut big = ok.clone();
        big[8] = 1e50;
        let err = m.predict(&ok, &big, &ok).unwrap_err();
        assert!(
            matches!(&err, PrrrpError::NonFinite { what, row: Some(1) }
                if what.starts_with("predicted torque") && what.contains("overflow")),
            "{err}"
        );
    }

    /// Another chain's base analysis is refused when the model is made, as `identify`
    /// refuses it, and when a file carrying one is read (it failed only at `predict`).
    #[test]
    fn a_base_analysis_of_another_chain_is_refused() {
        let chain = crate::test_support::puma(false);
        let paper = DynChain::paper();
        let other = paper.base_parameters(&BaseOptions::default()).unwrap();
        let err = IdentifiedModel::new(
            &chain,
            &other,
            vec![1.0; other.count()],
            None,
            None,
            None,
            vec![0.0; 6],
            "ls",
            serde_json::Value::Null,
            serde_json::Value::Null,
        )
        .unwrap_err();
        assert!(matches!(err, PrrrpError::ShapeMismatch { .. }), "{err}");
        // A file with the paper arm's analysis on the PUMA's robot.
        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        let mut m = model(&chain, &base).unwrap();
        m.base = BaseDescription::from(&other);
        m.beta = vec![1.0; other.count()];
        m.residual_rms = vec![0.0; 6];
        let text = crate::json::to_pretty(&m, "identified model").unwrap();
        let err = IdentifiedModel::from_json(&text).unwrap_err();
        assert!(
            matches!(&err, PrrrpError::ShapeMismatch { what, .. } if what == "base.standard_names"),
            "{err}"
        );
    }
}
