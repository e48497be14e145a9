//! TOML DH table → [`DynChain`].
//!
//! The document is walked key by key rather than deserialised into a struct so that every
//! error names its full key path (`joint[3].inertial`), which serde's messages do not.

use toml::{Table, Value};

use super::{file_error, UrdfOptions};
use crate::error::Result;
use crate::models::chain::{
    ChainMeta, DhConvention, DynChain, FrictionModel, JointInfo, JointLimit, MAX_DOF,
};
use crate::models::prrrp::robot::{DhRow, JointKind, STANDARD_GRAVITY};

const TOP_KEYS: [&str; 9] = [
    "name",
    "convention",
    "gravity",
    "base_link",
    "joint",
    "urdf",
    "base",
    "tip",
    "actuators",
];
const JOINT_KEYS: [&str; 14] = [
    "type",
    "a",
    "alpha",
    "d",
    "theta",
    "name",
    "link",
    "lower",
    "upper",
    "velocity",
    "acceleration",
    "effort",
    "inertial",
    "friction",
];

pub(super) struct Ctx<'a> {
    pub(super) file: &'a str,
}

impl Ctx<'_> {
    pub(super) fn err(&self, key: impl Into<String>, msg: impl Into<String>) -> crate::PrrrpError {
        file_error(self.file, key, msg)
    }

    pub(super) fn check_keys(&self, table: &Table, allowed: &[&str], prefix: &str) -> Result<()> {
        for k in table.keys() {
            if !allowed.contains(&k.as_str()) {
                return Err(self.err(
                    format!("{prefix}{k}"),
                    format!("unknown key `{k}`; allowed here: {}", allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }

    pub(super) fn number(&self, v: &Value, key: &str) -> Result<f64> {
        let x = match v {
            Value::Float(x) => *x,
            // Integers are common in hand-written tables (`d = 0`).
            Value::Integer(i) => *i as f64,
            other => {
                return Err(self.err(
                    key,
                    format!("expected a number, found type `{}`", other.type_str()),
                ))
            }
        };
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(key, format!("{x} is not finite; give a finite number")))
        }
    }

    fn opt_number(&self, t: &Table, key: &str, path: &str) -> Result<Option<f64>> {
        t.get(key)
            .map(|v| self.number(v, &format!("{path}{key}")))
            .transpose()
    }

    fn req_number(&self, t: &Table, key: &str, path: &str) -> Result<f64> {
        self.opt_number(t, key, path)?
            .ok_or_else(|| self.err(format!("{path}{key}"), "missing; give a number (SI units)"))
    }

    pub(super) fn string<'v>(&self, v: &'v Value, key: &str) -> Result<&'v str> {
        v.as_str().ok_or_else(|| {
            self.err(
                key,
                format!("expected a string, found type `{}`", v.type_str()),
            )
        })
    }

    pub(super) fn array<const N: usize>(&self, v: &Value, key: &str) -> Result<[f64; N]> {
        let items = self.numbers(v, key, N, "", "")?;
        Ok(std::array::from_fn(|i| items[i]))
    }

    /// The array of exactly `n` numbers at `key`; the errors say what it is (`kind`, after
    /// "array of n numbers") and why n (`why`, after "expected n numbers"), each "" or a
    /// parenthesis with its leading space.
    pub(super) fn numbers(
        &self,
        v: &Value,
        key: &str,
        n: usize,
        kind: &str,
        why: &str,
    ) -> Result<Vec<f64>> {
        let Some(items) = v.as_array() else {
            return Err(self.err(
                key,
                format!(
                    "expected an array of {n} numbers{kind}, found type `{}`",
                    v.type_str()
                ),
            ));
        };
        if items.len() != n {
            return Err(self.err(
                key,
                format!("expected {n} numbers{why}, found {}", items.len()),
            ));
        }
        items
            .iter()
            .enumerate()
            .map(|(i, x)| self.number(x, &format!("{key}[{i}]")))
            .collect()
    }
}

/// One `[[joint]]` table.
struct JointSpec {
    row: DhRow,
    info: JointInfo,
    link: Option<String>,
    inertial: Option<[f64; 10]>,
    friction: Option<[f64; 3]>,
}

fn joint_spec(ctx: &Ctx<'_>, t: &Table, i: usize) -> Result<JointSpec> {
    let path = format!("joint[{i}].");
    ctx.check_keys(t, &JOINT_KEYS, &path)?;
    let ty_key = format!("{path}type");
    let ty = match t.get("type") {
        Some(v) => ctx.string(v, &ty_key)?,
        None => {
            return Err(ctx.err(
                ty_key,
                "missing; give \"revolute\", \"continuous\" or \"prismatic\"",
            ))
        }
    };
    let (kind, continuous) = match ty {
        "revolute" => (JointKind::Revolute, false),
        "continuous" => (JointKind::Revolute, true),
        "prismatic" => (JointKind::Prismatic, false),
        other => {
            return Err(ctx.err(
                ty_key,
                format!(
                    "unknown joint type \"{other}\"; use \"revolute\", \"continuous\" or \
                     \"prismatic\""
                ),
            ))
        }
    };
    let row = DhRow {
        kind,
        theta: ctx.req_number(t, "theta", &path)?,
        d: ctx.req_number(t, "d", &path)?,
        a: ctx.req_number(t, "a", &path)?,
        alpha: ctx.req_number(t, "alpha", &path)?,
    };
    let name = match t.get("name") {
        Some(v) => ctx.string(v, &format!("{path}name"))?.to_string(),
        None => format!("joint{}", i + 1),
    };
    let link = t
        .get("link")
        .map(|v| ctx.string(v, &format!("{path}link")).map(str::to_string))
        .transpose()?;
    let mut limit = JointLimit::default();
    for (key, slot) in [
        ("lower", &mut limit.lower),
        ("upper", &mut limit.upper),
        ("velocity", &mut limit.velocity),
        ("acceleration", &mut limit.acceleration),
        ("effort", &mut limit.effort),
    ] {
        if let Some(x) = ctx.opt_number(t, key, &path)? {
            *slot = x;
        }
    }
    if continuous && !(limit.lower.is_nan() && limit.upper.is_nan()) {
        return Err(ctx.err(
            format!("{path}lower"),
            "a continuous joint has no position limits; remove lower/upper or use \
             type = \"revolute\"",
        ));
    }
    let bounds = [
        ("velocity", limit.velocity),
        ("acceleration", limit.acceleration),
        ("effort", limit.effort),
    ];
    if let Some((key, message)) = super::limit_problem(limit.lower, limit.upper, bounds, false) {
        return Err(ctx.err(format!("{path}{key}"), message));
    }
    let inertial = t
        .get("inertial")
        .map(|v| ctx.array::<10>(v, &format!("{path}inertial")))
        .transpose()?;
    let friction = t
        .get("friction")
        .map(|v| ctx.array::<3>(v, &format!("{path}friction")))
        .transpose()?;
    Ok(JointSpec {
        row,
        info: JointInfo {
            name,
            limit,
            damping: f64::NAN,
            friction: f64::NAN,
        },
        link,
        inertial,
        friction,
    })
}

pub(super) fn chain_from_toml(text: &str, file: &str, opts: &UrdfOptions) -> Result<DynChain> {
    let ctx = Ctx { file };
    let doc: Table = text.parse().map_err(|e: toml::de::Error| {
        let at = e
            .span()
            .map(|s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!(" at line {line}")
            })
            .unwrap_or_default();
        ctx.err(
            "file",
            format!("not valid TOML{at}: {}", e.message().trim_end()),
        )
    })?;
    ctx.check_keys(&doc, &TOP_KEYS, "")?;
    if doc.contains_key("urdf") {
        return super::actuators::chain_from_urdf_toml(&ctx, &doc, opts);
    }
    super::actuators::refuse_urdf_keys(&ctx, &doc)?;
    let name = match doc.get("name") {
        Some(v) => ctx.string(v, "name")?.to_string(),
        None => "robot".to_string(),
    };
    let base_link = match doc.get("base_link") {
        Some(v) => ctx.string(v, "base_link")?.to_string(),
        None => "base_link".to_string(),
    };
    let convention = match doc.get("convention") {
        Some(v) => match ctx.string(v, "convention")? {
            "modified" => DhConvention::Modified,
            "standard" => DhConvention::Standard,
            other => {
                return Err(ctx.err(
                    "convention",
                    format!("unknown convention \"{other}\"; use \"modified\" or \"standard\""),
                ))
            }
        },
        None => {
            return Err(ctx.err(
                "convention",
                "missing; give \"modified\" (Craig) or \"standard\" (DH)",
            ))
        }
    };
    let gravity = match doc.get("gravity") {
        Some(v) => ctx.array::<3>(v, "gravity")?,
        None => [0.0, 0.0, -STANDARD_GRAVITY],
    };
    let tables = match doc.get("joint") {
        Some(Value::Array(items)) if !items.is_empty() => items,
        Some(Value::Array(_)) | None => {
            return Err(ctx.err(
                "joint",
                "no joints; add one [[joint]] table per joint, base to tip",
            ))
        }
        Some(other) => {
            return Err(ctx.err(
                "joint",
                format!(
                    "expected [[joint]] tables, found type `{}`",
                    other.type_str()
                ),
            ))
        }
    };
    if tables.len() > MAX_DOF {
        return Err(ctx.err(
            "joint",
            format!(
                "{} [[joint]] tables, more than MAX_DOF = {MAX_DOF}; a serial chain has a few \
                 dozen joints at most",
                tables.len()
            ),
        ));
    }
    let mut specs = Vec::with_capacity(tables.len());
    for (i, v) in tables.iter().enumerate() {
        let Some(t) = v.as_table() else {
            return Err(ctx.err(
                format!("joint[{i}]"),
                format!("expected a [[joint]] table, found type `{}`", v.type_str()),
            ));
        };
        specs.push(joint_spec(&ctx, t, i)?);
    }

    let n = specs.len();
    let has_friction = specs.iter().any(|s| s.friction.is_some());
    let mut meta = ChainMeta::numbered(n);
    meta.name = name;
    meta.base_link = base_link;
    for (i, s) in specs.iter().enumerate() {
        if let Some(l) = &s.link {
            meta.links[i] = l.clone();
        }
    }
    // Unique names keep the chain writable as URDF, where names identify links and joints.
    let mut seen = std::collections::HashSet::new();
    seen.insert(meta.base_link.as_str());
    for (i, l) in meta.links.iter().enumerate() {
        if !seen.insert(l.as_str()) {
            return Err(ctx.err(
                format!("joint[{i}].link"),
                format!(
                    "link name `{l}` is used twice (or is the base link); names must be unique"
                ),
            ));
        }
    }
    let mut seen = std::collections::HashSet::new();
    for (i, s) in specs.iter().enumerate() {
        if !seen.insert(s.info.name.as_str()) {
            return Err(ctx.err(
                format!("joint[{i}].name"),
                format!(
                    "joint name `{}` is used twice; names must be unique",
                    s.info.name
                ),
            ));
        }
    }
    let rows: Vec<DhRow> = specs.iter().map(|s| s.row).collect();
    let inertial: Vec<[f64; 10]> = specs
        .iter()
        .map(|s| s.inertial.unwrap_or([0.0; 10]))
        .collect();
    let friction: Vec<[f64; 3]> = specs
        .iter()
        .map(|s| s.friction.unwrap_or([0.0; 3]))
        .collect();
    meta.joints = specs.into_iter().map(|s| s.info).collect();
    let mut chain = DynChain::new(rows, convention)?
        .with_inertial(inertial)?
        .with_gravity(gravity)?
        .with_meta(meta)?;
    if has_friction {
        chain = chain.with_friction(FrictionModel::all(), friction)?;
    }
    super::actuators::apply_actuators(&ctx, &doc, chain, has_friction)
}
