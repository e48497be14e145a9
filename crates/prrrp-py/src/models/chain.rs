//! `prrrp.SerialChain` (any serial arm of revolute and prismatic joints from a DH table)
//! and `prrrp.BaseParameters` (its numerical base-parameter analysis). The chain's size is
//! known at run time, so arrays are read with `DynSamples` and every batch loop reuses one
//! `DynWorkspace` with the GIL released.

use std::sync::OnceLock;

use numpy::PyArray1;
use prrrp_core::{
    Actuators, BaseOptions, BaseParameters, DhConvention, DhRow, DynChain, FrictionModel,
    JointKind, SerialChain, UrdfOptions,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple};

use crate::arrays::{
    check_len, dyn_samples_of, fixed_vector, map_samples, map_samples_with, matrix_rows, to_array,
    vector_of_len, DynSamples, Out, UInt,
};
use crate::errors::{shape_error, Exc, ToPyResult};
use crate::interrupt::interruptible;

/// The `#[pymethods]` of `SerialChain`: its getters (as `pymethods_with_getters!` takes
/// them), its methods of array arguments (its `arrays` section), the robot-file loaders
/// `fn name(source: Type) = chain;` (static methods taking `source` and the keywords
/// `base`, `tip`, `gravity`, `friction`, `coulomb_smoothing`, with `chain` read at the
/// `UrdfOptions` `opts` and the GIL token named in `arrays`), its own items, then one
/// method per dynamics quantity `fn name(args) -> [shape] = fill;`, taking (n,) or (N, n)
/// arguments, with `fill` writing sample `k` into `out` through chain `c` and its
/// workspace `ws` (one per batch, the GIL released).
macro_rules! chain_pymethods {
    (getters ($($getters:tt)*)
     arrays($this:ident, $py:ident) { $($arrays:tt)* }
     loaders |$opts:ident| {
         $($(#[$ldoc:meta])* fn $loader:ident($source:ident: $sty:ty) = $load:expr;)*
     }
     |$c:ident, $ws:ident, $k:ident, $out:ident| { $($extra:tt)* }
     $($(#[$doc:meta])* fn $name:ident($($arg:ident),+) -> [$($dim:expr),+] = $fill:expr;)*) => {
        pymethods_with_getters!(PySerialChain $($getters)* arrays($this, $py) {
            $($arrays)*
            $(
            $(#[$doc])*
            fn $name($($arg),+) {
                let ([$($arg),+], n) = $this.joints($py, [$($arg),+], [$(stringify!($arg)),+])?;
                let $c = &$this.inner;
                let shape = [$($dim),+];
                let [y] = map_samples_with($py, n, [&shape], $c.workspace(), |$ws, $k, [$out]| {
                    $fill
                })?;
                Ok(y)
            }
            )*
        } {
            $(
            $(#[$ldoc])*
            #[staticmethod]
            #[pyo3(signature = ($source, *, base=None, tip=None, gravity=None, friction=None,
                coulomb_smoothing=0.0))]
            fn $loader(
                $py: Python<'_>,
                $source: $sty,
                base: Option<String>,
                tip: Option<String>,
                gravity: Option<&Bound<'_, PyAny>>,
                friction: Option<&Bound<'_, PyAny>>,
                coulomb_smoothing: f64,
            ) -> PyResult<Self> {
                let $opts = urdf_options(base, tip, gravity)?;
                Self::finish_loaded($py, $load, friction, coulomb_smoothing)
            }
            )*
            $($extra)*
        });
    };
}

/// Default rank tolerance and seed of `BaseOptions`, for the Python signature.
const DEFAULT_SEED: u64 = 0x5EED_BA5E;
const DEFAULT_RANK_TOLERANCE: f64 = 1e-8;

/// An `InvalidParameterError` for a non-numeric setting: `field` names it, `value` is
/// what the caller gave (as text).
fn invalid(py: Python<'_>, field: &str, value: &str, reason: &'static str) -> PyErr {
    let attrs = || -> PyResult<Vec<(&str, Bound<'_, PyAny>)>> {
        Ok(vec![
            ("field", field.into_pyobject(py)?.into_any()),
            ("value", value.into_pyobject(py)?.into_any()),
            ("reason", reason.into_pyobject(py)?.into_any()),
        ])
    };
    match attrs() {
        Ok(a) => Exc::InvalidParameter.new_err(py, format!("`{field}` is {value}: {reason}"), &a),
        Err(e) => e,
    }
}

/// Joint kinds from "RRP" or ["R", "revolute", "P", ...] (case-insensitive).
fn joint_kinds(obj: &Bound<'_, PyAny>) -> PyResult<Vec<JointKind>> {
    let py = obj.py();
    let not_names = || {
        let reason = "must be a string such as 'RRP' or a list of 'R'/'P'";
        invalid(
            py,
            "joint_types",
            "not a string or a list of strings",
            reason,
        )
    };
    let items: Vec<String> = if let Ok(s) = obj.cast::<PyString>() {
        s.to_str()?.chars().map(String::from).collect()
    } else {
        obj.try_iter()
            .map_err(|_| not_names())?
            .map(|x| x.and_then(|x| x.extract::<String>()))
            .collect::<PyResult<_>>()
            .map_err(|_| not_names())?
    };
    items
        .iter()
        .enumerate()
        .map(|(i, t)| match t.to_ascii_lowercase().as_str() {
            "r" | "revolute" => Ok(JointKind::Revolute),
            "p" | "prismatic" => Ok(JointKind::Prismatic),
            _ => Err(invalid(
                py,
                &format!("joint_types[{i}]"),
                &format!("{t:?}"),
                "unknown joint type: use 'R' (revolute) or 'P' (prismatic)",
            )),
        })
        .collect()
}

fn convention_from(py: Python<'_>, s: &str) -> PyResult<DhConvention> {
    match s.to_ascii_lowercase().as_str() {
        "standard" => Ok(DhConvention::Standard),
        "modified" => Ok(DhConvention::Modified),
        _ => Err(invalid(
            py,
            "convention",
            &format!("{s:?}"),
            "must be 'standard' (distal DH) or 'modified' (proximal, Craig)",
        )),
    }
}

fn convention_name(c: DhConvention) -> &'static str {
    match c {
        DhConvention::Standard => "standard",
        DhConvention::Modified => "modified",
    }
}

/// Friction terms from None, "viscous+coulomb", or ["viscous", "coulomb", "offset"].
fn friction_from(obj: Option<&Bound<'_, PyAny>>, smoothing: f64) -> PyResult<FrictionModel> {
    let mut model = FrictionModel {
        coulomb_smoothing: smoothing,
        ..FrictionModel::default()
    };
    let Some(obj) = obj else {
        return Ok(model);
    };
    let py = obj.py();
    let reason = "must be None or terms among 'viscous', 'coulomb', 'offset' (a list, or one \
                  string joined with '+')";
    let terms: Vec<String> = if let Ok(s) = obj.cast::<PyString>() {
        let s = s.to_str()?;
        if s.trim().is_empty() {
            Vec::new()
        } else {
            // An empty term ('viscous+') is a typo, not "no more terms".
            s.split(['+', ',']).map(|t| t.trim().to_string()).collect()
        }
    } else {
        obj.try_iter()
            .map_err(|_| invalid(py, "friction", "not a string or a list of strings", reason))?
            .map(|x| x.and_then(|x| x.extract::<String>()))
            .collect::<PyResult<_>>()
            .map_err(|_| invalid(py, "friction", "not a string or a list of strings", reason))?
    };
    for t in terms {
        match t.to_ascii_lowercase().as_str() {
            "viscous" => model.viscous = true,
            "coulomb" => model.coulomb = true,
            "offset" => model.offset = true,
            _ => return Err(invalid(py, "friction", &format!("{t:?}"), reason)),
        }
    }
    Ok(model)
}

fn friction_names(f: &FrictionModel) -> Vec<&'static str> {
    [
        (f.viscous, "viscous"),
        (f.coulomb, "coulomb"),
        (f.offset, "offset"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect()
}

/// A serial manipulator of revolute and prismatic joints from a Denavit–Hartenberg table,
/// with the 10 standard inertial parameters per link and optional joint friction.
#[pyclass(module = "prrrp", name = "SerialChain", frozen)]
pub(crate) struct PySerialChain {
    inner: DynChain,
    /// The default base-parameter analysis, computed on first use.
    base: OnceLock<BaseParameters>,
}

impl PySerialChain {
    /// The chain.
    pub(crate) fn chain(&self) -> &DynChain {
        &self.inner
    }

    pub(crate) fn wrap(inner: DynChain) -> Self {
        Self {
            inner,
            base: OnceLock::new(),
        }
    }

    /// K joint-space arguments, (n,) or (N, n) each, and their batch length.
    fn joints<const K: usize>(
        &self,
        py: Python<'_>,
        args: [&Bound<'_, PyAny>; K],
        names: [&'static str; K],
    ) -> PyResult<([DynSamples; K], Option<usize>)> {
        dyn_samples_of(py, args, names, self.inner.dof())
    }

    /// Applies the Python-side friction choice to a chain read from a file: the file's own
    /// friction (a TOML `friction` row) stays unless `friction` is given.
    fn finish_loaded(
        py: Python<'_>,
        chain: DynChain,
        friction: Option<&Bound<'_, PyAny>>,
        smoothing: f64,
    ) -> PyResult<Self> {
        let chain = if friction.is_some() || smoothing != 0.0 {
            let mut model = friction_from(friction, smoothing)?;
            if friction.is_none() {
                let f = chain.friction();
                (model.viscous, model.coulomb, model.offset) = (f.viscous, f.coulomb, f.offset);
            }
            let params = chain.friction_params().to_vec();
            chain.with_friction(model, params).to_py(py)?
        } else {
            chain
        };
        Ok(Self::wrap(chain))
    }

    /// Applies a per-sample actuator map to an (n,) or (N, n) array.
    fn joint_map<'py>(
        &self,
        py: Python<'py>,
        obj: &Bound<'py, PyAny>,
        name: &'static str,
        f: impl FnOnce(&Actuators, usize, &[f64]) -> prrrp_core::Result<Vec<f64>>,
    ) -> Out<'py> {
        let n = self.inner.dof();
        let (shape, data) = crate::arrays::any_array(obj, name, &format!("({n},) or (N, {n})"))?;
        let batch = match *shape {
            [d] if d == n => None,
            [s, d] if d == n => Some(s),
            _ => {
                return Err(shape_error(
                    py,
                    name,
                    format!("({n},) or (N, {n})"),
                    crate::arrays::fmt_shape(&shape),
                ))
            }
        };
        if let Some(k) = data.iter().position(|x| !x.is_finite()) {
            return Err(prrrp_core::PrrrpError::NonFinite {
                what: name.into(),
                row: Some(k / n),
            })
            .to_py(py);
        }
        let out = f(self.inner.actuators(), n, &data).to_py(py)?;
        to_array(py, out, batch, &[n])
    }

    pub(crate) fn default_base(&self, py: Python<'_>) -> PyResult<&BaseParameters> {
        if let Some(b) = self.base.get() {
            return Ok(b);
        }
        let b = py
            .detach(|| self.inner.base_parameters(&BaseOptions::default()))
            .to_py(py)?;
        Ok(self.base.get_or_init(|| b))
    }
}

chain_pymethods! {
getters ({} inner {
    /// Number of joints n.
    dof: usize = { dof() }
    /// Number of standard parameters P = 10·n + (friction terms per joint)·n.
    num_params: usize = { num_params() }
    /// Names of the standard parameters, e.g. ['m1', 'mx1', ..., 'Izz6', 'fv1', ...].
    parameter_names: Vec<String> = { parameter_names() }
    /// The robot's name (from its file; 'robot' otherwise).
    name: String = { meta().name.clone() }
    /// Movable joints of the source file held at zero and merged into the links.
    locked_joints: Vec<String> = { meta().locked_joints.clone() }
    /// Velocity scale of the smoothed Coulomb sign (0 = exact sign).
    coulomb_smoothing: f64 = { friction().coulomb_smoothing }
})
arrays(this, py) {
    /// Observation matrix W: the regressors of the samples stacked, shape (N·n, P); rows
    /// n·k..n·k+n hold sample k.
    fn observation_matrix(q, qd, qdd) {
        let y = this.regressor(py, q, qd, qdd)?;
        y.call_method1("reshape", ((-1i64, this.inner.num_params()),))
    }

    /// Joint torques τ = Cᵀ·(K∘i) (N·m, N) from motor currents i (A), (n,) or (N, n), with
    /// joint-side drive gains K (N·m/A), (n,).
    fn joint_torques_from_currents(current, gains) {
        let k = crate::arrays::vector(gains, "gains")?;
        this.joint_map(py, current, "current", |a, n, x| {
            a.joint_torques_from_currents(n, x, &k)
        })
    }

    /// Joint positions q = C⁻¹·(θ/r) (rad, m) from motor angles θ (rad, motor side), (n,)
    /// or (N, n); needs the gear ratios. The same map takes motor velocities and
    /// accelerations to the joint side.
    fn joint_positions_from_motor(theta) {
        this.joint_map(py, theta, "theta", |a, n, x| a.joint_positions_from_motor(n, x))
    }

    /// Joint torques τ = Cᵀ·(r∘τ_motor) (N·m, N) from motor-side torques (N·m), (n,) or
    /// (N, n); needs the gear ratios.
    fn joint_torques_from_motor(tau_motor) {
        this.joint_map(py, tau_motor, "tau_motor", |a, n, x| a.joint_torques_from_motor(n, x))
    }
}
loaders |opts| {
    /// A chain from a URDF file or string: the movable joints from `base` to `tip`, with
    /// fixed bodies and off-path joints (held at zero) merged into the links.
    fn from_urdf(source: &Bound<'_, PyAny>) = match source_text(source)? {
        Source::Text(xml) => py.detach(|| DynChain::from_urdf_str(&xml, &opts)),
        Source::Path(path) => py.detach(|| DynChain::from_urdf_file(&path, &opts)),
    }
    .to_py(py)?;

    /// A chain from a robot file: `.urdf` (see `from_urdf`) or `.toml` (a DH table).
    fn from_file(path: std::path::PathBuf) = {
        let chain = py.detach(|| DynChain::from_file(&path, &opts)).to_py(py)?;
        match opts.gravity {
            // The argument overrides a TOML file's `gravity` too.
            Some(g) => chain.with_gravity(g).to_py(py)?,
            None => chain,
        }
    };
}
|c, ws, k, out| {
    /// See the class documentation in `_prrrp.pyi`.
    #[new]
    #[pyo3(signature = (dh, joint_types, *, convention="standard", inertial=None, gravity=None,
        friction=None, friction_params=None, coulomb_smoothing=0.0))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        dh: &Bound<'_, PyAny>,
        joint_types: &Bound<'_, PyAny>,
        convention: &str,
        inertial: Option<&Bound<'_, PyAny>>,
        gravity: Option<&Bound<'_, PyAny>>,
        friction: Option<&Bound<'_, PyAny>>,
        friction_params: Option<&Bound<'_, PyAny>>,
        coulomb_smoothing: f64,
    ) -> PyResult<Self> {
        let (n, table) = matrix_rows(dh, "dh", None, 4)?;
        let kinds = joint_kinds(joint_types)?;
        check_len(py, "joint_types", kinds.len(), n, " (one type per DH row)")?;
        let conv = convention_from(py, convention)?;
        let rows: Vec<DhRow> = table
            .chunks_exact(4)
            .zip(&kinds)
            .map(|(r, &kind)| DhRow {
                kind,
                a: r[0],
                alpha: r[1],
                d: r[2],
                theta: r[3],
            })
            .collect();
        let mut chain = DynChain::new(rows, conv).to_py(py)?;
        if let Some(obj) = inertial {
            let (_, flat) = matrix_rows(obj, "inertial", Some(n), 10)?;
            let links = flat
                .chunks_exact(10)
                .map(|c| <[f64; 10]>::try_from(c).unwrap_or([f64::NAN; 10]))
                .collect();
            chain = chain.with_inertial(links).to_py(py)?;
        }
        if let Some(obj) = gravity {
            chain = chain
                .with_gravity(fixed_vector::<3>(obj, "gravity")?)
                .to_py(py)?;
        }
        let model = friction_from(friction, coulomb_smoothing)?;
        let params = match friction_params {
            Some(obj) => {
                if model.columns_per_joint() == 0 {
                    return Err(invalid(
                        py,
                        "friction_params",
                        "given without friction terms",
                        "pass friction=['viscous', ...] to say which terms the columns hold",
                    ));
                }
                let (_, flat) = matrix_rows(obj, "friction_params", Some(n), 3)?;
                flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            None => vec![[0.0; 3]; n],
        };
        chain = chain.with_friction(model, params).to_py(py)?;
        Ok(Self::wrap(chain))
    }

    /// A URDF of this chain with the given standard parameters (default: its own).
    #[pyo3(signature = (parameters=None))]
    fn to_urdf(&self, py: Python<'_>, parameters: Option<&Bound<'_, PyAny>>) -> PyResult<String> {
        let p = self.inner.num_params();
        let params = parameters
            .map(|obj| vector_of_len(obj, "parameters", p, ""))
            .transpose()?;
        self.inner.to_urdf(params.as_deref()).to_py(py)
    }

    /// The same chain with another friction model: terms among 'viscous', 'coulomb',
    /// 'offset', per-joint [fv, fc, fo] (n, 3) (default zeros) and the smooth-sign scale.
    #[pyo3(signature = (friction, friction_params=None, *, coulomb_smoothing=0.0))]
    fn with_friction(
        &self,
        py: Python<'_>,
        friction: Option<&Bound<'_, PyAny>>,
        friction_params: Option<&Bound<'_, PyAny>>,
        coulomb_smoothing: f64,
    ) -> PyResult<Self> {
        let n = self.inner.dof();
        let model = friction_from(friction, coulomb_smoothing)?;
        let params = match friction_params {
            Some(obj) => {
                let (_, flat) = matrix_rows(obj, "friction_params", Some(n), 3)?;
                flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            None => vec![[0.0; 3]; n],
        };
        let chain = self.inner.clone().with_friction(model, params).to_py(py)?;
        Ok(Self::wrap(chain))
    }

    /// The same chain with other actuators (see `_prrrp.pyi`): arguments left None keep
    /// the chain's own.
    #[pyo3(signature = (*, coupling=None, armature=None, armature_values=None, gear_ratios=None))]
    fn with_actuators(
        &self,
        py: Python<'_>,
        coupling: Option<&Bound<'_, PyAny>>,
        armature: Option<bool>,
        armature_values: Option<&Bound<'_, PyAny>>,
        gear_ratios: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let n = self.inner.dof();
        let mut act = self.inner.actuators().clone();
        if let Some(obj) = coupling {
            let (_, flat) = matrix_rows(obj, "coupling", Some(n), n)?;
            act.coupling = Some(flat.chunks_exact(n).map(<[f64]>::to_vec).collect());
        }
        if let Some(on) = armature {
            act.armature = on;
        }
        if let Some(obj) = armature_values {
            act.armature_values = Some(crate::arrays::vector(obj, "armature_values")?);
        }
        if let Some(obj) = gear_ratios {
            act.gear_ratios = Some(crate::arrays::vector(obj, "gear_ratios")?);
        }
        let chain = self.inner.clone().with_actuators(act).to_py(py)?;
        Ok(Self::wrap(chain))
    }

    /// The actuators: a dict with 'coupling' ((n, n) array or None = identity),
    /// 'armature' (bool), 'armature_values' ((n,) kg·m² or None), 'gear_ratios' ((n,) or
    /// None).
    #[getter]
    fn actuators<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let a = self.inner.actuators();
        let n = self.inner.dof();
        let d = PyDict::new(py);
        let coupling = match &a.coupling {
            Some(rows) => Some(to_array(
                py,
                rows.iter().flatten().copied().collect(),
                Some(n),
                &[n],
            )?),
            None => None,
        };
        d.set_item("coupling", coupling)?;
        d.set_item("armature", a.armature)?;
        d.set_item(
            "armature_values",
            a.armature_values
                .as_ref()
                .map(|v| PyArray1::from_slice(py, v)),
        )?;
        d.set_item(
            "gear_ratios",
            a.gear_ratios.as_ref().map(|v| PyArray1::from_slice(py, v)),
        )?;
        Ok(d)
    }

    /// A TOML robot file for this chain whose links are in the URDF at `urdf` (relative to
    /// the TOML file), with the drives URDF cannot hold; `parameters` default to the
    /// chain's own.
    #[pyo3(signature = (urdf, parameters=None))]
    fn to_toml(
        &self,
        py: Python<'_>,
        urdf: &str,
        parameters: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<String> {
        let params = parameters
            .map(|p| crate::arrays::vector(p, "parameters"))
            .transpose()?;
        self.inner
            .to_toml_with_urdf(urdf, params.as_deref())
            .to_py(py)
    }

    /// Joint names, base to tip.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner
            .meta()
            .joints
            .iter()
            .map(|j| j.name.clone())
            .collect()
    }

    /// Names of the fixed base link and of the link each joint moves.
    #[getter]
    fn link_names(&self) -> Vec<String> {
        let m = self.inner.meta();
        std::iter::once(m.base_link.clone())
            .chain(m.links.iter().cloned())
            .collect()
    }

    /// Joint limits from the robot file: a dict of arrays of shape (n,) 'lower', 'upper'
    /// (rad or m), 'velocity', 'acceleration', 'effort' (SI); NaN where the file gives none.
    #[getter]
    fn limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let joints = &self.inner.meta().joints;
        let d = PyDict::new(py);
        let column = |get: &dyn Fn(&prrrp_core::JointLimit) -> f64| {
            PyArray1::from_vec(py, joints.iter().map(|j| get(&j.limit)).collect())
        };
        d.set_item("lower", column(&|l| l.lower))?;
        d.set_item("upper", column(&|l| l.upper))?;
        d.set_item("velocity", column(&|l| l.velocity))?;
        d.set_item("acceleration", column(&|l| l.acceleration))?;
        d.set_item("effort", column(&|l| l.effort))?;
        Ok(d)
    }

    /// Names of the links whose inertial parameters no rigid body has (a pseudo-inertia
    /// that is not positive semidefinite: negative mass, triangle inequality broken).
    #[getter]
    fn non_physical_links(&self) -> Vec<String> {
        let m = self.inner.meta();
        self.inner
            .non_physical_links()
            .into_iter()
            .map(|i| m.links[i].clone())
            .collect()
    }

    /// True when every link's inertial parameters describe a rigid body.
    fn is_physically_consistent(&self) -> bool {
        self.inner.is_physically_consistent()
    }

    /// Whether the chain is evaluated in closed form (the paper's arm: same values as the
    /// recursive algorithms, a fraction of the time); any change of its inertial
    /// parameters, gravity or actuators turns it off.
    #[getter]
    fn is_closed_form(&self) -> bool {
        self.inner.is_closed_form()
    }

    /// The paper's PRRRP arm (Tables 1–2, g = 9.81 m/s²) as a chain, with the joint
    /// limits of its excitation.
    #[staticmethod]
    fn paper() -> Self {
        Self::wrap(DynChain::paper())
    }

    /// The PUMA 560 (6R; Corke & Armstrong-Hélouvry 1994, links only) as a chain.
    #[staticmethod]
    fn puma560() -> Self {
        Self::wrap(SerialChain::puma560().to_dyn())
    }

    /// The standard parameter vector π, shape (P,).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.parameters())
    }

    /// The DH table, shape (n, 4), columns [a, alpha, d, theta] (m, rad); None for a
    /// chain not built from a DH table (e.g. from a URDF).
    #[getter]
    fn dh<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(table) = self.inner.dh() else {
            return Ok(None);
        };
        let flat: Vec<f64> = table
            .iter()
            .flat_map(|r| [r.a, r.alpha, r.d, r.theta])
            .collect();
        to_array(py, flat, Some(self.inner.dof()), &[4]).map(Some)
    }

    /// Joint types as a string of 'R'/'P', e.g. 'RRRRRR'.
    #[getter]
    fn joint_types(&self) -> String {
        self.inner
            .joints()
            .iter()
            .map(|j| if j.kind.is_rotational() { 'R' } else { 'P' })
            .collect()
    }

    /// 'standard' or 'modified'; None for a chain not built from a DH table.
    #[getter]
    fn convention(&self) -> Option<&'static str> {
        self.inner.convention().map(convention_name)
    }

    /// Inertial parameters, shape (n, 10), per link [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz,
    /// Iyz, Izz] about the link-frame origin.
    #[getter]
    fn inertial<'py>(&self, py: Python<'py>) -> Out<'py> {
        let flat: Vec<f64> = self.inner.inertial().iter().flatten().copied().collect();
        to_array(py, flat, Some(self.inner.dof()), &[10])
    }

    /// Gravity in world coordinates, m/s², shape (3,).
    #[getter]
    fn gravity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.gravity())
    }

    /// The enabled friction terms, a tuple among ('viscous', 'coulomb', 'offset').
    #[getter]
    fn friction<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        PyTuple::new(py, friction_names(&self.inner.friction()))
    }

    /// Friction parameters, shape (n, 3), per joint [fv, fc, fo] (disabled terms kept).
    #[getter]
    fn friction_params<'py>(&self, py: Python<'py>) -> Out<'py> {
        let flat: Vec<f64> = self
            .inner
            .friction_params()
            .iter()
            .flatten()
            .copied()
            .collect();
        to_array(py, flat, Some(self.inner.dof()), &[3])
    }

    /// Numerical base parameters (QR with column pivoting on the regressor stacked over
    /// `samples` random states drawn with `seed`; `rank_tolerance` on unit-norm columns).
    #[pyo3(signature = (*, samples=UInt(0), seed=UInt(DEFAULT_SEED), rank_tolerance=DEFAULT_RANK_TOLERANCE))]
    fn base_parameters(
        &self,
        py: Python<'_>,
        samples: UInt<usize>,
        seed: UInt<u64>,
        rank_tolerance: f64,
    ) -> PyResult<PyBaseParameters> {
        let samples = samples.0;
        let seed = seed.0;
        let opts = BaseOptions {
            samples,
            seed,
            rank_tolerance,
        };
        if opts == BaseOptions::default() {
            return Ok(PyBaseParameters {
                inner: self.default_base(py)?.clone(),
            });
        }
        let inner = interruptible(py, || self.inner.base_parameters(&opts))?.to_py(py)?;
        Ok(PyBaseParameters { inner })
    }

    /// Physical feasibility of standard parameters (default this chain's own); see
    /// `_prrrp.pyi`.
    #[pyo3(signature = (parameters=None))]
    fn feasibility<'py>(
        &self,
        py: Python<'py>,
        parameters: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.inner;
        let pi = match parameters {
            Some(p) => crate::arrays::vector(p, "parameters")?,
            None => c.parameters(),
        };
        let report = prrrp_core::FeasibilityReport::with_armature(
            &pi,
            c.dof(),
            &c.friction(),
            c.actuators().armature,
        )
        .to_py(py)?;
        feasibility_dict(py, c, &report)
    }

    /// Whether rigid bodies reproduce base values `beta`; see `_prrrp.pyi`.
    #[pyo3(signature = (beta, *, prior=None))]
    fn base_feasibility<'py>(
        &self,
        py: Python<'py>,
        beta: &Bound<'py, PyAny>,
        prior: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let beta = crate::arrays::vector(beta, "beta")?;
        let config = prrrp_core::PhysicalConfig {
            prior: prior
                .map(|p| crate::arrays::vector(p, "prior"))
                .transpose()?,
            ..Default::default()
        };
        let base = self.default_base(py)?.clone();
        let r =
            interruptible(py, || prrrp_core::base_feasibility(&base, &beta, &config))?.to_py(py)?;
        let d = feasibility_dict(py, &self.inner, &r.report)?;
        d.set_item("feasible", r.feasible)?;
        d.set_item("max_relative_mismatch", r.max_relative_mismatch)?;
        d.set_item("converged", r.converged)?;
        d.set_item("iterations", r.iterations)?;
        d.set_item("parameters", PyArray1::from_vec(py, r.parameters))?;
        Ok(d)
    }

    /// The Coulomb speed scale v_s chosen from `data` by cross-validated least squares
    /// (see `_prrrp.pyi`); a dict (the core's `CoulombScaleReport`).
    #[pyo3(signature = (
        data, *, candidates=None, folds=UInt(4), refine=true,
        max_widenings=UInt(prrrp_core::COULOMB_SCALE_MAX_WIDENINGS)
    ))]
    fn coulomb_scale<'py>(
        &self,
        py: Python<'py>,
        data: &crate::data::dataset::PyDataset,
        candidates: Option<Vec<f64>>,
        folds: UInt<usize>,
        refine: bool,
        max_widenings: UInt<usize>,
    ) -> Out<'py> {
        let base = self.default_base(py)?.clone();
        let config = prrrp_core::CoulombScaleConfig {
            candidates,
            folds: folds.0,
            refine,
            max_widenings: max_widenings.0,
        };
        let report = interruptible(py, || {
            prrrp_core::select_coulomb_scale(&self.inner, &base, &data.inner, &config)
        })?
        .to_py(py)?;
        let text = serde_json::to_string(&report)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// Base regressor Y_b (the independent columns of Y) with τ = Y_b·β: (n, b) or
    /// (N, n, b). `base` defaults to `base_parameters()` with default options.
    #[pyo3(signature = (q, qd, qdd, *, base=None))]
    fn base_regressor<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        base: Option<PyRef<'py, PyBaseParameters>>,
    ) -> Out<'py> {
        let ([q, qd, qdd], n) = self.joints(py, [q, qd, qdd], ["q", "qd", "qdd"])?;
        let b = match &base {
            Some(b) => &b.inner,
            None => self.default_base(py)?,
        };
        let c = &self.inner;
        let shape = [c.dof(), b.count()];
        let [y] = map_samples_with(py, n, [&shape], c.workspace(), |ws, k, [out]| {
            c.base_regressor_row_major_into(ws, b, q.at(k), qd.at(k), qdd.at(k), out)
        })?;
        Ok(y)
    }

    fn __repr__(&self) -> String {
        let a = self.inner.actuators();
        format!(
            "SerialChain(dof={}, joint_types='{}', convention='{}', friction={:?}, \
             coupled={}, armature={}, num_params={})",
            self.inner.dof(),
            self.joint_types(),
            self.convention().unwrap_or("none"),
            friction_names(&self.inner.friction()),
            if a.is_default_coupling() {
                "False"
            } else {
                "True"
            },
            if a.armature { "True" } else { "False" },
            self.inner.num_params()
        )
    }

    /// The chain's complete description as JSON (joints, inertials, friction, gravity,
    /// names, limits; schema version 1): `SerialChain.from_json` rebuilds it exactly.
    fn to_json(&self, py: Python<'_>) -> PyResult<String> {
        self.inner.to_json().to_py(py)
    }

    /// A chain from the JSON of `to_json`.
    #[staticmethod]
    fn from_json(py: Python<'_>, text: &str) -> PyResult<Self> {
        let chain = py.detach(|| DynChain::from_json(text)).to_py(py)?;
        Ok(Self::wrap(chain))
    }

    /// Pickle and copy support, for any chain (DH or URDF): rebuilt from its JSON.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let rebuild = py.get_type::<PySerialChain>().getattr("from_json")?;
        let args = PyTuple::new(py, [self.to_json(py)?])?;
        PyTuple::new(py, [rebuild, args.into_any()])
    }
}

    /// Inverse dynamics τ = M·q̈ + C·q̇ + G + τ_friction (N, N·m): (n,) or (N, n).
    fn inverse_dynamics(q, qd, qdd) -> [c.dof()] =
        c.inverse_dynamics_into(ws, q.at(k), qd.at(k), qdd.at(k), out);

    /// Nonlinear effects C(q, q̇)·q̇ + G(q) + τ_friction(q̇) (N, N·m): (n,) or (N, n).
    fn nonlinear_effects(q, qd) -> [c.dof()] =
        c.nonlinear_effects_into(ws, q.at(k), qd.at(k), out);

    /// Gravity torques G(q) (N, N·m; no friction): (n,) or (N, n).
    fn gravity_torques(q) -> [c.dof()] = c.gravity_torques_into(ws, q.at(k), out);

    /// Mass matrix M(q): (n, n) or (N, n, n).
    fn mass_matrix(q) -> [c.dof(), c.dof()] = c.mass_matrix_into(ws, q.at(k), out);

    /// Forward dynamics q̈ = M⁻¹(τ − C·q̇ − G − τ_friction): (n,) or (N, n). Raises
    /// NotPositiveDefiniteError (with `.sample` for a batch) where M(q) is singular.
    fn forward_dynamics(q, qd, tau) -> [c.dof()] =
        c.forward_dynamics_into(ws, q.at(k), qd.at(k), tau.at(k), out);

    /// Full regressor Y (friction columns included) with τ = Y·parameters: (n, P) or
    /// (N, n, P).
    fn regressor(q, qd, qdd) -> [c.dof(), c.num_params()] =
        c.regressor_row_major_into(ws, q.at(k), qd.at(k), qdd.at(k), out);
}

enum Source {
    Text(String),
    Path(std::path::PathBuf),
}

/// A URDF given as XML text (it contains '<') or as a path (str or os.PathLike).
fn source_text(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
    if let Ok(s) = obj.cast::<PyString>() {
        let s = s.to_str()?;
        return Ok(if s.contains('<') {
            Source::Text(s.to_owned())
        } else {
            Source::Path(s.into())
        });
    }
    obj.extract::<std::path::PathBuf>()
        .map(Source::Path)
        .map_err(|_| {
            invalid(
                obj.py(),
                "source",
                "neither a string nor a path",
                "give the URDF's path or its XML text",
            )
        })
}

fn urdf_options(
    base: Option<String>,
    tip: Option<String>,
    gravity: Option<&Bound<'_, PyAny>>,
) -> PyResult<UrdfOptions> {
    Ok(UrdfOptions {
        base,
        tip,
        gravity: gravity
            .map(|g| fixed_vector::<3>(g, "gravity"))
            .transpose()?,
    })
}

/// The base parameters of a chain: β = map · parameters, τ = Y_b·β.
#[pyclass(module = "prrrp", name = "BaseParameters", frozen)]
pub(crate) struct PyBaseParameters {
    pub(crate) inner: BaseParameters,
}

fn index_array<'py>(py: Python<'py>, v: &[usize]) -> Bound<'py, PyArray1<i64>> {
    PyArray1::from_vec(py, v.iter().map(|&i| i as i64).collect())
}

pymethods_with_getters!(PyBaseParameters {} inner {
    /// Number of base parameters b.
    count: usize = { count() }
    /// Number of standard parameters P.
    num_params: usize = { num_standard() }
    /// Names of the standard parameters (length P).
    names: Vec<String> = { names.clone() }
    /// Each base parameter as a readable combination, e.g. 'Izz2 + 0.4318*mx2 + ...'.
    combinations: Vec<String> = { combinations.clone() }
    /// The rank tolerance used.
    rank_tolerance: f64 = { rank_tolerance }
} {
    /// Indices of the standard parameters kept as base parameters, increasing, (b,).
    #[getter]
    fn independent<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        index_array(py, &self.inner.independent)
    }

    /// Names of the independent standard parameters (length b).
    #[getter]
    fn independent_names(&self) -> Vec<String> {
        self.inner
            .independent
            .iter()
            .map(|&j| self.inner.names[j].clone())
            .collect()
    }

    /// Indices of the standard parameters regrouped or unidentifiable, (P − b,).
    #[getter]
    fn dependent<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        index_array(py, &self.inner.dependent)
    }

    /// Indices of the standard parameters that affect no joint force (a subset of
    /// `dependent`).
    #[getter]
    fn unidentifiable<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        index_array(py, &self.inner.unidentifiable)
    }

    /// The standard → base map K, shape (b, P): β = K @ parameters.
    #[getter]
    fn map<'py>(&self, py: Python<'py>) -> Out<'py> {
        let (b, p) = (self.inner.count(), self.inner.num_standard());
        to_array(py, self.inner.map_row_major(), Some(b), &[p])
    }

    /// Pivots |R_kk| of the scaled pivoted QR (the rank gap diagnostic).
    #[getter]
    fn pivots<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.pivots)
    }

    /// β = K·π for standard parameters π of shape (P,) or (N, P): (b,) or (N, b).
    fn base_values<'py>(&self, py: Python<'py>, parameters: &Bound<'py, PyAny>) -> Out<'py> {
        let p = self.inner.num_standard();
        let ([pi], n) = dyn_samples_of(py, [parameters], ["parameters"], p)?;
        let b = &self.inner;
        let [beta] = map_samples(py, n, [&[b.count()]], |k, [out]| {
            out.copy_from_slice(&b.base_values(pi.at(k))?);
            Ok(())
        })?;
        Ok(beta)
    }

    fn __len__(&self) -> usize {
        self.inner.count()
    }

    fn __repr__(&self) -> String {
        format!(
            "BaseParameters(count={}, num_params={}, independent={:?})",
            self.inner.count(),
            self.inner.num_standard(),
            self.independent_names()
        )
    }
});

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySerialChain>()?;
    m.add_class::<PyBaseParameters>()?;
    Ok(())
}

/// The feasibility report as a dict: per link and per joint, named.
fn feasibility_dict<'py>(
    py: Python<'py>,
    c: &DynChain,
    r: &prrrp_core::FeasibilityReport,
) -> PyResult<Bound<'py, PyDict>> {
    let links = pyo3::types::PyList::empty(py);
    for (i, l) in r.links.iter().enumerate() {
        let d = PyDict::new(py);
        d.set_item("link", &c.meta().links[i])?;
        d.set_item("mass", l.mass)?;
        d.set_item("min_eigenvalue", l.min_eigenvalue())?;
        d.set_item(
            "pseudo_inertia_eigenvalues",
            l.pseudo_inertia_eigenvalues.to_vec(),
        )?;
        d.set_item("com", l.com.map(|v| v.to_vec()))?;
        d.set_item("principal_moments", l.principal_moments.map(|v| v.to_vec()))?;
        d.set_item("triangle_margins", l.triangle_margins.map(|v| v.to_vec()))?;
        d.set_item("consistent", l.consistent)?;
        links.append(d)?;
    }
    let joints = pyo3::types::PyList::empty(py);
    for (j, f) in r.friction.iter().enumerate() {
        let d = PyDict::new(py);
        d.set_item("joint", &c.meta().joints[j].name)?;
        d.set_item("viscous", f.viscous)?;
        d.set_item("coulomb", f.coulomb)?;
        d.set_item("armature", f.armature)?;
        d.set_item("consistent", f.consistent)?;
        joints.append(d)?;
    }
    let out = PyDict::new(py);
    let bad: Vec<&String> = r
        .links
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.consistent)
        .map(|(i, _)| &c.meta().links[i])
        .collect();
    out.set_item(
        "consistent",
        bad.is_empty() && r.friction.iter().all(|f| f.consistent),
    )?;
    out.set_item("non_physical_links", bad)?;
    out.set_item("links", links)?;
    out.set_item("friction", joints)?;
    Ok(out)
}
