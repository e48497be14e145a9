//! The parts of a TOML robot file about drives: links taken from a URDF (`urdf`, `base`,
//! `tip`) and the `[actuators]` table (coupling, armature, gear ratios, per-actuator
//! friction), for either kind of TOML file.
//!
//! ```toml
//! name = "tx40"
//! urdf = "tx40.urdf"     # links, joints, limits, inertials (path relative to this file)
//! base = "base_link"     # optional, as UrdfOptions::base / ::tip
//! tip = "tool0"
//! [actuators]
//! armature = true        # one rotor inertia per actuator (default false)
//! coupling = [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],
//!             [0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,1,1]]
//! armature_values = [...]   # optional, kg·m² (joint side), one per actuator
//! gear_ratios = [...]       # optional, motor angle per joint-side angle
//! friction = [[fv, fc, fo], ...]   # optional, per actuator (N·m·s/rad, N·m, N·m)
//! coulomb_smoothing = 0.02  # optional, v_s of fc·tanh(q̇ₘ/v_s), rad/s (0 = sign)
//! ```
//!
//! [`DynChain::to_toml_with_urdf`] writes such a file for a chain whose URDF is written
//! next to it.

use std::path::{Path, PathBuf};

use toml::{Table, Value};

use super::toml_file::Ctx;
use super::{UrdfOptions, STRING_SOURCE};
use crate::error::Result;
use crate::models::chain::{DynChain, FrictionModel};
use crate::models::prrrp::robot::STANDARD_GRAVITY;

const URDF_KEYS: [&str; 6] = ["name", "urdf", "base", "tip", "gravity", "actuators"];
const ACTUATOR_KEYS: [&str; 6] = [
    "armature",
    "coupling",
    "armature_values",
    "gear_ratios",
    "friction",
    "coulomb_smoothing",
];

/// `base` and `tip` name URDF links: without `urdf` they are a mistake.
pub(super) fn refuse_urdf_keys(ctx: &Ctx<'_>, doc: &Table) -> Result<()> {
    for k in ["base", "tip"] {
        if doc.contains_key(k) {
            return Err(ctx.err(
                k,
                format!(
                    "`{k}` picks a link of a URDF and needs `urdf = \"file.urdf\"`; a DH \
                     table's chain is its [[joint]] tables (use base_link to name the base)"
                ),
            ));
        }
    }
    Ok(())
}

fn opt_string(ctx: &Ctx<'_>, doc: &Table, key: &str) -> Result<Option<String>> {
    doc.get(key)
        .map(|v| ctx.string(v, key).map(str::to_string))
        .transpose()
}

/// A TOML file whose links come from a URDF: `urdf` (a path relative to the TOML file),
/// optional `name`, `base`, `tip` (overridden by `opts`), `gravity` and `[actuators]`.
pub(super) fn chain_from_urdf_toml(
    ctx: &Ctx<'_>,
    doc: &Table,
    opts: &UrdfOptions,
) -> Result<DynChain> {
    for k in ["joint", "convention", "base_link"] {
        if doc.contains_key(k) {
            return Err(ctx.err(
                k,
                format!(
                    "`{k}` describes a DH table, but this file takes its links from `urdf`: \
                     `urdf` and [[joint]] tables are exclusive (remove one)"
                ),
            ));
        }
    }
    ctx.check_keys(doc, &URDF_KEYS, "")?;
    let urdf = opt_string(ctx, doc, "urdf")?.unwrap_or_default();
    if urdf.trim().is_empty() {
        return Err(ctx.err("urdf", "is empty; give the URDF's path"));
    }
    let path = relative_to(ctx.file, &urdf);
    if !path.is_file() {
        return Err(ctx.err(
            "urdf",
            format!(
                "`{}` is not a file (paths are relative to the TOML file's folder)",
                path.display()
            ),
        ));
    }
    let gravity = match doc.get("gravity") {
        Some(v) => Some(ctx.array::<3>(v, "gravity")?),
        None => opts.gravity,
    };
    let urdf_opts = UrdfOptions {
        base: opts.base.clone().or(opt_string(ctx, doc, "base")?),
        tip: opts.tip.clone().or(opt_string(ctx, doc, "tip")?),
        gravity: Some(gravity.unwrap_or([0.0, 0.0, -STANDARD_GRAVITY])),
    };
    let mut chain = DynChain::from_urdf_file(&path, &urdf_opts)?;
    if let Some(name) = opt_string(ctx, doc, "name")? {
        let mut meta = chain.meta().clone();
        meta.name = name;
        chain = chain.with_meta(meta)?;
    }
    apply_actuators(ctx, doc, chain, false)
}

/// `rel` relative to the folder of the TOML file `file` (the working directory for text
/// given directly).
fn relative_to(file: &str, rel: &str) -> PathBuf {
    let p = Path::new(rel);
    if p.is_absolute() || file == STRING_SOURCE {
        return p.to_path_buf();
    }
    match Path::new(file).parent() {
        Some(dir) => dir.join(p),
        None => p.to_path_buf(),
    }
}

fn numbers(ctx: &Ctx<'_>, v: &Value, key: &str, n: usize) -> Result<Vec<f64>> {
    let why = format!(" (one per actuator: the chain has {n} joints)");
    ctx.numbers(v, key, n, " (one per actuator)", &why)
}

/// Applies the `[actuators]` table, if any, to a chain read from the rest of the file
/// (`joint_friction`: the [[joint]] tables gave friction, which `[actuators].friction`
/// would contradict).
pub(super) fn apply_actuators(
    ctx: &Ctx<'_>,
    doc: &Table,
    chain: DynChain,
    joint_friction: bool,
) -> Result<DynChain> {
    let Some(v) = doc.get("actuators") else {
        return Ok(chain);
    };
    let Some(t) = v.as_table() else {
        return Err(ctx.err(
            "actuators",
            format!(
                "expected an [actuators] table, found type `{}`",
                v.type_str()
            ),
        ));
    };
    ctx.check_keys(t, &ACTUATOR_KEYS, "actuators.")?;
    let n = chain.dof();
    let mut act = chain.actuators().clone();
    if let Some(v) = t.get("armature") {
        act.armature = v.as_bool().ok_or_else(|| {
            ctx.err(
                "actuators.armature",
                format!("expected true or false, found type `{}`", v.type_str()),
            )
        })?;
    }
    if let Some(v) = t.get("coupling") {
        let key = "actuators.coupling";
        let rows = v.as_array().ok_or_else(|| {
            ctx.err(
                key,
                format!(
                    "expected {n} rows of {n} numbers (C, q̇ₘ = C·q̇), found type `{}`",
                    v.type_str()
                ),
            )
        })?;
        if rows.len() != n {
            return Err(ctx.err(
                key,
                format!(
                    "expected {n} rows (one per actuator: the chain has {n} joints, C is \
                     square), found {}",
                    rows.len()
                ),
            ));
        }
        act.coupling = Some(
            rows.iter()
                .enumerate()
                .map(|(m, r)| numbers(ctx, r, &format!("{key}[{m}]"), n))
                .collect::<Result<_>>()?,
        );
    }
    if let Some(v) = t.get("armature_values") {
        if !act.armature {
            return Err(ctx.err(
                "actuators.armature_values",
                "given without `armature = true`: the values are the armature term's, turn \
                 it on (or remove the values)",
            ));
        }
        act.armature_values = Some(numbers(ctx, v, "actuators.armature_values", n)?);
    }
    if let Some(v) = t.get("gear_ratios") {
        act.gear_ratios = Some(numbers(ctx, v, "actuators.gear_ratios", n)?);
    }
    let mut chain = chain;
    if let Some(v) = t.get("friction") {
        let key = "actuators.friction";
        if joint_friction {
            return Err(ctx.err(
                key,
                "friction is given both in [[joint]] tables and under [actuators]; give it in \
                 one place (per actuator: [actuators].friction)",
            ));
        }
        let rows = v.as_array().filter(|r| r.len() == n).ok_or_else(|| {
            ctx.err(
                key,
                format!("expected {n} rows [fv, fc, fo], one per actuator"),
            )
        })?;
        let params = rows
            .iter()
            .enumerate()
            .map(|(m, r)| ctx.array::<3>(r, &format!("{key}[{m}]")))
            .collect::<Result<Vec<_>>>()?;
        chain = chain.with_friction(FrictionModel::all(), params)?;
    }
    if let Some(v) = t.get("coulomb_smoothing") {
        let key = "actuators.coulomb_smoothing";
        let vs = ctx.number(v, key)?;
        if vs < 0.0 {
            return Err(ctx.err(key, format!("{vs} is negative; give v_s >= 0 rad/s")));
        }
        let model = FrictionModel {
            coulomb_smoothing: vs,
            ..chain.friction()
        };
        let params = chain.friction_params().to_vec();
        chain = chain.with_friction(model, params)?;
    }
    chain.with_actuators(act).map_err(|e| {
        ctx.err(
            "actuators",
            format!("{e} (the coupling must be square, finite and invertible)"),
        )
    })
}

impl DynChain {
    /// A TOML robot file for this chain whose links are in the URDF `urdf` (a path
    /// relative to the TOML file, e.g. the output of [`DynChain::to_urdf`] written next
    /// to it): name, `urdf`, `base`, `tip`, `gravity` and an `[actuators]` table with the
    /// coupling, armature, gear ratios and per-actuator friction (with its Coulomb speed
    /// scale) — what URDF cannot hold. `parameters` (`None` = the chain's own, else
    /// [`DynChain::num_params`] values) supplies the armature and friction values.
    ///
    /// # Errors
    /// [`crate::PrrrpError::ShapeMismatch`] for parameters of the wrong length;
    /// [`crate::PrrrpError::InvalidParameter`] for a non-finite value.
    pub fn to_toml_with_urdf(&self, urdf: &str, parameters: Option<&[f64]>) -> Result<String> {
        use std::fmt::Write;
        let num = super::urdf_export::num;
        let own = self.parameters();
        let p = parameters.unwrap_or(&own);
        if p.len() != self.num_params() {
            return Err(crate::PrrrpError::ShapeMismatch {
                what: "parameters".into(),
                expected: format!(
                    "{} values (the chain's standard parameters)",
                    self.num_params()
                ),
                got: format!("{} values", p.len()),
            });
        }
        if let Some(k) = p.iter().position(|x| !x.is_finite()) {
            return Err(crate::PrrrpError::InvalidParameter {
                field: format!("parameters[{k}]"),
                value: p[k],
                reason: "parameters written to a robot file must be finite",
            });
        }
        let quote = |s: &str| {
            let mut q = String::from('"');
            for ch in s.chars() {
                match ch {
                    '"' => q.push_str("\\\""),
                    '\\' => q.push_str("\\\\"),
                    c if (c as u32) < 0x20 || c == '\u{7f}' => {
                        let _ = write!(q, "\\u{:04X}", c as u32);
                    }
                    c => q.push(c),
                }
            }
            q.push('"');
            q
        };
        let list = |v: &[f64]| v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(", ");
        let meta = self.meta();
        let n = self.dof();
        let mut out = String::from(
            "# Written by prrrp: links, joints and inertials are in the URDF, the drives here.\n",
        );
        let _ = writeln!(out, "name = {}", quote(&meta.name));
        let _ = writeln!(out, "urdf = {}", quote(urdf));
        let _ = writeln!(out, "base = {}", quote(&meta.base_link));
        if let Some(tip) = meta.links.last() {
            let _ = writeln!(out, "tip = {}", quote(tip));
        }
        let _ = writeln!(out, "gravity = [{}]", list(&self.gravity()));
        out.push_str("\n[actuators]\n");
        let act = self.actuators();
        let layout = self.layout();
        let block = |m: usize, kind: usize| {
            let s = layout.slots[kind];
            (s != usize::MAX).then(|| p[10 * n + layout.per * m + s])
        };
        let _ = writeln!(out, "armature = {}", act.armature);
        if let Some(c) = &act.coupling {
            let rows: Vec<String> = c.iter().map(|r| format!("[{}]", list(r))).collect();
            let _ = writeln!(out, "coupling = [{}]", rows.join(", "));
        }
        if act.armature {
            let ia: Vec<f64> = (0..n).map(|m| block(m, 3).unwrap_or(0.0)).collect();
            let _ = writeln!(out, "armature_values = [{}]", list(&ia));
        }
        if let Some(r) = &act.gear_ratios {
            let _ = writeln!(out, "gear_ratios = [{}]", list(r));
        }
        let f = self.friction();
        if f.viscous || f.coulomb || f.offset {
            let rows: Vec<String> = (0..n)
                .map(|m| {
                    let v: Vec<f64> = (0..3).map(|k| block(m, k).unwrap_or(0.0)).collect();
                    format!("[{}]", list(&v))
                })
                .collect();
            let _ = writeln!(out, "friction = [{}]", rows.join(", "));
            let _ = writeln!(out, "coulomb_smoothing = {}", num(f.coulomb_smoothing));
        }
        Ok(out)
    }
}
