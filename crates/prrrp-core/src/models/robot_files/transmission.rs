//! URDF `<transmission>` elements ↔ the chain's [`Actuators`].
//!
//! urdf-rs does not read transmissions, so the document is read a second time with
//! quick-xml into a small element tree. ROS 1 and ros2_control simple, differential and
//! four-bar transmissions and Drake's rotor inertia and gear ratio are understood; their
//! motor-velocity map G is split as G = diag(r)·C into gear ratios and a joint-side
//! coupling, and rotor inertias become joint-side armatures J·r². Placeholder reductions of
//! 1 leave the default actuators; transmissions off the chain, or of other types, are
//! ignored.
//!
//! The elements and formulas understood: docs/design/actuators.md.

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use super::file_error;
use crate::error::Result;
use crate::models::chain::{Actuators, DynChain};

/// A reduction of 0 says the motor does not move its joint: no transmission.
const ZERO_REDUCTION: &str = "a mechanical reduction of 0 (the motor would not move the joint): \
     give the gear ratio, motor turns per joint turn, e.g. \
     <mechanicalReduction>100</mechanicalReduction>, or leave it out for 1";

/// An XML element: name as written (with its prefix), attributes, text, children.
#[derive(Debug, Default)]
struct Element {
    name: String,
    attrs: Vec<(String, String)>,
    text: String,
    children: Vec<Element>,
}

impl Element {
    fn attr(&self, key: &str) -> Option<&str> {
        self.attrs
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    fn child(&self, names: &[&str]) -> Option<&Element> {
        self.children
            .iter()
            .find(|c| names.contains(&c.name.as_str()))
    }

    fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// Text of the first child among `names`, trimmed.
    fn child_text(&self, names: &[&str]) -> Option<&str> {
        self.child(names).map(|c| c.text.trim())
    }
}

/// Deepest element nesting read (URDFs nest a handful of levels).
const MAX_DEPTH: usize = 256;

fn start(e: &BytesStart<'_>, file: &str) -> Result<Element> {
    let bad = |m: String| file_error(file, "robot", format!("not readable XML ({m})"));
    let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let mut attrs = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|x| bad(x.to_string()))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a.unescape_value().map_err(|x| bad(x.to_string()))?;
        attrs.push((key, value.into_owned()));
    }
    Ok(Element {
        name,
        attrs,
        ..Element::default()
    })
}

/// The document's element tree (a virtual root holds the top-level elements).
fn parse(xml: &str, file: &str) -> Result<Element> {
    let bad = |m: String| file_error(file, "robot", format!("not readable XML ({m})"));
    let mut reader = Reader::from_str(xml);
    let mut stack = vec![Element::default()];
    loop {
        match reader.read_event().map_err(|e| bad(e.to_string()))? {
            Event::Start(e) => {
                if stack.len() > MAX_DEPTH {
                    return Err(bad(format!("elements nested deeper than {MAX_DEPTH}")));
                }
                stack.push(start(&e, file)?);
            }
            Event::Empty(e) => {
                let el = start(&e, file)?;
                if let Some(top) = stack.last_mut() {
                    top.children.push(el);
                }
            }
            Event::End(_) if stack.len() > 1 => {
                if let (Some(done), Some(parent)) = (stack.pop(), stack.last_mut()) {
                    parent.children.push(done);
                }
            }
            Event::Text(t) => {
                if let Some(top) = stack.last_mut() {
                    top.text
                        .push_str(&t.xml10_content().map_err(|e| bad(e.to_string()))?);
                }
            }
            Event::CData(t) => {
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&String::from_utf8_lossy(&t));
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    while stack.len() > 1 {
        if let (Some(done), Some(parent)) = (stack.pop(), stack.last_mut()) {
            parent.children.push(done);
        }
    }
    Ok(stack.pop().unwrap_or_default())
}

fn collect<'a>(e: &'a Element, out: &mut Vec<&'a Element>) {
    let mut todo = vec![e];
    while let Some(el) = todo.pop() {
        for c in el.children.iter().rev() {
            if c.name == "transmission" {
                out.push(c);
            } else {
                todo.push(c);
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Simple,
    Differential,
    FourBar,
}

/// One `<joint>` or `<actuator>` of a transmission.
#[derive(Debug)]
struct End<'a> {
    name: &'a str,
    role: Option<&'a str>,
    reduction: Option<f64>,
    rotor_inertia: Option<f64>,
    gear_ratio: Option<f64>,
}

const REDUCTION: [&str; 2] = ["mechanicalReduction", "mechanical_reduction"];

fn number(text: &str, file: &str, element: &str) -> Result<f64> {
    let x: f64 = text
        .trim()
        .parse()
        .map_err(|_| file_error(file, element, format!("`{}` is not a number", text.trim())))?;
    if !x.is_finite() {
        return Err(file_error(file, element, format!("{x} is not finite")));
    }
    Ok(x)
}

fn end<'a>(e: &'a Element, file: &str, at: &str) -> Result<End<'a>> {
    let name = e.attr("name").unwrap_or("");
    let el = format!("{at}/{}[{name}]", e.name);
    let reduction = e
        .child_text(&REDUCTION)
        .map(|t| number(t, file, &format!("{el}/mechanicalReduction")))
        .transpose()?;
    let value = |tag: &str| -> Result<Option<f64>> {
        e.child(&[tag])
            .and_then(|c| c.attr("value").or(Some(c.text.trim())))
            .filter(|t| !t.is_empty())
            .map(|t| number(t, file, &format!("{el}/{tag}")))
            .transpose()
    };
    Ok(End {
        name,
        role: e.attr("role").or_else(|| e.child_text(&["role"])),
        reduction,
        rotor_inertia: value("drake:rotor_inertia")?,
        gear_ratio: value("drake:gear_ratio")?,
    })
}

/// Sorts the two ends of a two-by-two transmission by role (`…1`, `…2`), else keeps the
/// file order.
fn by_role<'a>(mut v: Vec<End<'a>>) -> Vec<End<'a>> {
    if v.iter().all(|e| e.role.is_some()) {
        v.sort_by_key(|e| e.role.map(|r| r.ends_with('2')));
    }
    v
}

/// The chain's actuators as the URDF's transmissions describe them (the default when the
/// file has none for the chain's joints).
pub(super) fn actuators_from_urdf(xml: &str, file: &str, chain: &DynChain) -> Result<Actuators> {
    if !xml.contains("transmission") {
        return Ok(Actuators::default());
    }
    let root = parse(xml, file)?;
    let mut found = Vec::new();
    collect(&root, &mut found);
    let names = chain.joint_names();
    let index = |name: &str| names.iter().position(|&j| j == name);
    let n = chain.dof();
    // θ̇ = G·q̇ (motor units), rotor inertias J (motor side).
    let mut g = vec![0.0; n * n];
    for i in 0..n {
        g[i * n + i] = 1.0;
    }
    // Whether each joint's transmission states a reduction (not just the default 1).
    let mut covered = vec![false; n];
    let mut rotor: Vec<Option<f64>> = vec![None; n];
    let mut any = false;
    for t in found {
        let tname = t.attr("name").unwrap_or("");
        let at = format!("transmission[{tname}]");
        let ty = t
            .child_text(&["type", "plugin"])
            .or_else(|| t.attr("type"))
            .unwrap_or("");
        let kind = if ty.contains("SimpleTransmission") {
            Kind::Simple
        } else if ty.contains("DifferentialTransmission") {
            Kind::Differential
        } else if ty.contains("FourBarLinkageTransmission") {
            Kind::FourBar
        } else {
            continue;
        };
        let joints = t
            .children_named("joint")
            .map(|e| end(e, file, &at))
            .collect::<Result<Vec<_>>>()?;
        let actuators = t
            .children_named("actuator")
            .map(|e| end(e, file, &at))
            .collect::<Result<Vec<_>>>()?;
        // The oldest format puts the reduction on the transmission itself.
        let outer = t
            .child_text(&REDUCTION)
            .map(|x| number(x, file, &format!("{at}/mechanicalReduction")))
            .transpose()?;
        match kind {
            Kind::Simple => {
                let [j] = joints.as_slice() else {
                    return Err(file_error(
                        file,
                        at,
                        format!(
                            "a SimpleTransmission has one <joint>, found {}",
                            joints.len()
                        ),
                    ));
                };
                let Some(k) = index(j.name) else { continue };
                let a = actuators.first();
                let r = a.and_then(|a| a.reduction.or(a.gear_ratio)).unwrap_or(1.0)
                    * j.reduction.unwrap_or(1.0)
                    * outer.unwrap_or(1.0);
                if r == 0.0 {
                    return Err(file_error(file, at, ZERO_REDUCTION));
                }
                g[k * n + k] = r;
                covered[k] = a.is_some_and(|a| a.reduction.or(a.gear_ratio).is_some())
                    || j.reduction.is_some()
                    || outer.is_some();
                rotor[k] = a.and_then(|a| a.rotor_inertia);
                any = true;
            }
            Kind::Differential | Kind::FourBar => {
                if joints.len() != 2 || actuators.len() != 2 {
                    return Err(file_error(
                        file,
                        at,
                        format!(
                            "a {ty} has two <joint> and two <actuator> elements, found {} and {}",
                            joints.len(),
                            actuators.len()
                        ),
                    ));
                }
                let (joints, actuators) = (by_role(joints), by_role(actuators));
                let (Some(k1), Some(k2)) = (index(joints[0].name), index(joints[1].name)) else {
                    continue;
                };
                let nj = [0, 1].map(|i| joints[i].reduction.unwrap_or(1.0));
                let na = [0, 1].map(|i| {
                    actuators[i]
                        .reduction
                        .or(actuators[i].gear_ratio)
                        .unwrap_or(1.0)
                });
                if nj.contains(&0.0) || na.contains(&0.0) {
                    return Err(file_error(file, at, ZERO_REDUCTION));
                }
                let rows = if kind == Kind::Differential {
                    [
                        [na[0] * nj[0], na[0] * nj[1]],
                        [na[1] * nj[0], -na[1] * nj[1]],
                    ]
                } else {
                    [[nj[0] * na[0], 0.0], [na[1], na[1] * nj[1]]]
                };
                let stated = joints
                    .iter()
                    .chain(&actuators)
                    .any(|e| e.reduction.or(e.gear_ratio).is_some());
                for (row, k) in [k1, k2].into_iter().enumerate() {
                    g[k * n..k * n + n].fill(0.0);
                    g[k * n + k1] = rows[row][0];
                    g[k * n + k2] = rows[row][1];
                    covered[k] = stated;
                    rotor[k] = actuators[row].rotor_inertia;
                }
                any = true;
            }
        }
    }
    if !any {
        return Ok(Actuators::default());
    }
    // G = diag(r)·C, each row of C with its largest entry scaled to 1.
    let mut ratios = vec![1.0; n];
    let mut coupling = vec![vec![0.0; n]; n];
    for m in 0..n {
        let row = &g[m * n..m * n + n];
        let r = row
            .iter()
            .copied()
            .fold(0.0f64, |a, x| if x.abs() > a.abs() { x } else { a });
        ratios[m] = r;
        for j in 0..n {
            coupling[m][j] = row[j] / r;
        }
    }
    let identity = (0..n).all(|m| (0..n).all(|j| coupling[m][j] == if m == j { 1.0 } else { 0.0 }));
    let armature = rotor.iter().any(Option::is_some);
    // Many ROS descriptions (the UR5's among them) state a reduction of 1 for every joint
    // as a placeholder of a joint-side hardware interface: nothing to model.
    if identity && !armature && ratios.iter().all(|&r| r == 1.0) {
        return Ok(Actuators::default());
    }
    let act = Actuators {
        coupling: (!identity).then_some(coupling),
        armature,
        armature_values: armature.then(|| {
            rotor
                .iter()
                .zip(&ratios)
                .map(|(j, r)| j.unwrap_or(0.0) * r * r)
                .collect()
        }),
        gear_ratios: covered.iter().all(|&c| c).then_some(ratios),
    };
    act.validate(n).map_err(|e| {
        file_error(
            file,
            "transmission",
            format!("the transmissions do not describe the chain's actuators: {e}"),
        )
    })?;
    Ok(act)
}

/// Appends one `SimpleTransmission` per joint for a chain whose actuators URDF can hold
/// (C = I) with a gear ratio or an armature: `<mechanicalReduction>` = the gear ratio (1
/// when unknown) and, with an armature, Drake's `<drake:rotor_inertia>` = Ia/r² (motor
/// side) and `<drake:gear_ratio>`, declaring the `drake` namespace on `<robot>`. A coupled
/// chain gets a comment: its coupling lives in the TOML robot file.
pub(super) fn write_transmissions(c: &DynChain, params: &[f64], out: &mut String) {
    use std::fmt::Write;
    let act = c.actuators();
    if act.is_default() {
        return;
    }
    if !act.is_default_coupling() {
        out.push_str(
            "  <!-- prrrp: the actuators are coupled (C is not the identity), which URDF \
             transmissions cannot say; the TOML robot file keeps them. -->\n",
        );
        return;
    }
    let n = c.dof();
    let layout = c.layout();
    let ia: Vec<f64> = (0..n)
        .map(|m| {
            if act.armature && params.len() == c.num_params() {
                params[10 * n + layout.per * m + layout.slots[3]]
            } else {
                c.armature_values()[m]
            }
        })
        .collect();
    let meta = c.meta();
    let num = super::urdf_export::num;
    for (m, info) in meta.joints.iter().enumerate() {
        let ratio = act.gear_ratios.as_ref().map(|g| g[m]);
        let r = ratio.unwrap_or(1.0);
        let name = super::urdf_export::attr(&info.name);
        let _ = write!(
            out,
            "  <transmission name=\"{name}_transmission\">\n    \
             <type>transmission_interface/SimpleTransmission</type>\n    \
             <joint name=\"{name}\">\n      \
             <hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface>\n    \
             </joint>\n    <actuator name=\"{name}_motor\">\n"
        );
        if let Some(r) = ratio {
            let _ = writeln!(
                out,
                "      <mechanicalReduction>{}</mechanicalReduction>",
                num(r)
            );
        }
        if act.armature {
            let _ = writeln!(
                out,
                "      <drake:rotor_inertia value=\"{}\"/>",
                num(ia[m] / (r * r))
            );
        }
        out.push_str("    </actuator>\n  </transmission>\n");
    }
    if act.armature {
        *out = out.replacen(
            "<robot name=",
            "<robot xmlns:drake=\"http://drake.mit.edu\" name=",
            1,
        );
    }
}
