//! URDF → [`DynChain`]: the movable joints from a base link to a tip link, with everything
//! rigidly attached to a chain link (fixed joints, locked joints) merged into it.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use urdf_rs::JointType as UrdfJointType;

use super::{file_error, UrdfOptions};
use crate::error::Result;
use crate::models::chain::{
    transform_inertial_parameters, ChainMeta, DynChain, Joint, JointInfo, JointLimit, JointType,
    AXIS_UNIT_TOLERANCE, MAX_DOF,
};
use crate::models::prrrp::robot::STANDARD_GRAVITY;

/// Index structure of the URDF's kinematic tree.
struct Tree<'r> {
    robot: &'r urdf_rs::Robot,
    link_index: HashMap<&'r str, usize>,
    /// Joint whose child each link is.
    parent_joint: Vec<Option<usize>>,
    /// Joints whose parent each link is, in file order.
    child_joints: Vec<Vec<usize>>,
    /// Link index of each joint's parent and child.
    joint_parent: Vec<usize>,
    joint_child: Vec<usize>,
}

/// Any joint that is not fixed. The default tip follows these, so that a floating or planar
/// joint at the end of the only path is reported by name rather than as "no joint".
fn is_articulated(t: &UrdfJointType) -> bool {
    !matches!(t, UrdfJointType::Fixed)
}

fn type_name(t: &UrdfJointType) -> &'static str {
    match t {
        UrdfJointType::Revolute => "revolute",
        UrdfJointType::Continuous => "continuous",
        UrdfJointType::Prismatic => "prismatic",
        UrdfJointType::Fixed => "fixed",
        UrdfJointType::Floating => "floating",
        UrdfJointType::Planar => "planar",
        UrdfJointType::Spherical => "spherical",
    }
}

fn joint_el(name: &str, part: &str) -> String {
    if part.is_empty() {
        format!("joint[{name}]")
    } else {
        format!("joint[{name}]/{part}")
    }
}

fn link_el(name: &str, part: &str) -> String {
    if part.is_empty() {
        format!("link[{name}]")
    } else {
        format!("link[{name}]/{part}")
    }
}

/// Records element `i` of kind `kind` ("link" or "joint") under its `name`; a name
/// already recorded is an error at the element `el(name, "")`.
fn insert_unique<'r>(
    names: &mut HashMap<&'r str, usize>,
    name: &'r str,
    i: usize,
    file: &str,
    kind: &str,
    el: fn(&str, &str) -> String,
) -> Result<()> {
    if names.insert(name, i).is_some() {
        return Err(file_error(
            file,
            el(name, ""),
            format!("two {kind}s have this name; {kind} names must be unique"),
        ));
    }
    Ok(())
}

impl<'r> Tree<'r> {
    fn new(robot: &'r urdf_rs::Robot, file: &str) -> Result<Self> {
        let mut link_index = HashMap::with_capacity(robot.links.len());
        for (i, l) in robot.links.iter().enumerate() {
            insert_unique(&mut link_index, &l.name, i, file, "link", link_el)?;
        }
        let nl = robot.links.len();
        let mut parent_joint = vec![None; nl];
        let mut child_joints = vec![Vec::new(); nl];
        let mut joint_parent = Vec::with_capacity(robot.joints.len());
        let mut joint_child = Vec::with_capacity(robot.joints.len());
        let mut joint_names = HashMap::with_capacity(robot.joints.len());
        for (j, joint) in robot.joints.iter().enumerate() {
            insert_unique(&mut joint_names, &joint.name, j, file, "joint", joint_el)?;
            let find = |name: &str, part: &str| {
                link_index.get(name).copied().ok_or_else(|| {
                    file_error(
                        file,
                        joint_el(&joint.name, part),
                        format!("link `{name}` does not exist; add a <link name=\"{name}\"/>"),
                    )
                })
            };
            let p = find(&joint.parent.link, "parent")?;
            let c = find(&joint.child.link, "child")?;
            if parent_joint[c].is_some() {
                return Err(file_error(
                    file,
                    joint_el(&joint.name, "child"),
                    format!(
                        "link `{}` is the child of two joints; a URDF must be a tree",
                        joint.child.link
                    ),
                ));
            }
            parent_joint[c] = Some(j);
            child_joints[p].push(j);
            joint_parent.push(p);
            joint_child.push(c);
        }
        Ok(Self {
            robot,
            link_index,
            parent_joint,
            child_joints,
            joint_parent,
            joint_child,
        })
    }

    fn link_name(&self, l: usize) -> &'r str {
        &self.robot.links[l].name
    }

    fn joint(&self, j: usize) -> &'r urdf_rs::Joint {
        &self.robot.joints[j]
    }

    fn find_link(&self, name: &str, file: &str, option: &str) -> Result<usize> {
        self.link_index.get(name).copied().ok_or_else(|| {
            file_error(
                file,
                option,
                format!("link `{name}` does not exist in the file; check the spelling"),
            )
        })
    }

    fn base(&self, opts: &UrdfOptions, file: &str) -> Result<usize> {
        if let Some(name) = &opts.base {
            return self.find_link(name, file, "base");
        }
        let roots: Vec<usize> = (0..self.parent_joint.len())
            .filter(|&l| self.parent_joint[l].is_none())
            .collect();
        match roots.as_slice() {
            [r] => Ok(*r),
            // An empty <robot> (example-robot-data's ur3.urdf) has no link at all.
            [] if self.parent_joint.is_empty() => Err(file_error(
                file,
                "robot",
                "the robot has no links: the file describes nothing (is it a stub, or the \
                 wrong file?)",
            )),
            [] => Err(file_error(
                file,
                "robot",
                "no root link (every link is a joint's child): the joints form a cycle",
            )),
            _ => Err(file_error(
                file,
                "robot",
                format!(
                    "several root links ({}); connect them or choose the chain's first link \
                     with --base LINK (Python: base=)",
                    names(roots.iter().map(|&l| self.link_name(l)))
                ),
            )),
        }
    }

    /// Links of the subtree below `base` (base first, parents before children).
    fn subtree(&self, base: usize, file: &str) -> Result<Vec<usize>> {
        let mut seen = vec![false; self.parent_joint.len()];
        let mut order = vec![base];
        seen[base] = true;
        let mut k = 0;
        while k < order.len() {
            let l = order[k];
            k += 1;
            for &j in &self.child_joints[l] {
                let c = self.joint_child[j];
                if seen[c] {
                    return Err(file_error(
                        file,
                        joint_el(&self.joint(j).name, ""),
                        "the joints form a cycle; a URDF must be a tree",
                    ));
                }
                seen[c] = true;
                order.push(c);
            }
        }
        Ok(order)
    }

    /// The tip when none is given: the child of the only movable joint below the base with
    /// no movable joint below it. When the movable joints branch, the error proposes the
    /// arm's end first — the link where they branch (a hand whose fingers are separate
    /// joints), if a movable joint lies above it — then the branch ends, the end of the
    /// longest movable chain first.
    fn default_tip(&self, base: usize, file: &str) -> Result<usize> {
        let order = self.subtree(base, file)?;
        let nl = self.parent_joint.len();
        // Movable joints strictly below each link, and on the path from the base to it.
        let mut movable_below = vec![false; nl];
        for &l in order.iter().rev() {
            movable_below[l] = self.child_joints[l].iter().any(|&j| {
                is_articulated(&self.joint(j).joint_type) || movable_below[self.joint_child[j]]
            });
        }
        let mut movable_above = vec![0usize; nl];
        for &l in &order {
            for &j in &self.child_joints[l] {
                movable_above[self.joint_child[j]] =
                    movable_above[l] + usize::from(is_articulated(&self.joint(j).joint_type));
            }
        }
        let mut tips: Vec<usize> = order
            .iter()
            .flat_map(|&l| self.child_joints[l].iter().copied())
            .filter(|&j| is_articulated(&self.joint(j).joint_type))
            .map(|j| self.joint_child[j])
            .filter(|&c| !movable_below[c])
            .collect();
        match tips.as_slice() {
            [t] => Ok(*t),
            [] => Err(file_error(
                file,
                "tip",
                format!(
                    "no revolute, continuous or prismatic joint below the base link `{}`",
                    self.link_name(base)
                ),
            )),
            _ => {
                // Stable: equal lengths keep file order.
                tips.sort_by_key(|&t| std::cmp::Reverse(movable_above[t]));
                // Walk down while a single child subtree holds movable joints.
                let mut branch = base;
                loop {
                    let mut moving = self.child_joints[branch].iter().filter(|&&j| {
                        is_articulated(&self.joint(j).joint_type)
                            || movable_below[self.joint_child[j]]
                    });
                    match (moving.next(), moving.next()) {
                        (Some(&j), None) => branch = self.joint_child[j],
                        _ => break,
                    }
                }
                let arm_end = (movable_above[branch] > 0).then(|| {
                    format!(
                        "`{}` (the arm's end, where they branch), ",
                        self.link_name(branch)
                    )
                });
                Err(file_error(
                    file,
                    "tip",
                    format!(
                        "the movable joints below `{}` branch: choose the chain's last link \
                         with --tip LINK (Python: tip=). Candidates, best first: {}{} \
                         (branch ends, the longest movable chain first); the joints off the \
                         chosen chain are locked at zero",
                        self.link_name(base),
                        arm_end.unwrap_or_default(),
                        names(tips.iter().map(|&l| self.link_name(l)))
                    ),
                ))
            }
        }
    }

    /// Joints from `base` down to `tip`, base first.
    fn path(&self, base: usize, tip: usize, file: &str) -> Result<Vec<usize>> {
        let mut path = Vec::new();
        let mut cur = tip;
        while cur != base {
            match self.parent_joint[cur] {
                Some(j) if path.len() < self.robot.joints.len() => {
                    path.push(j);
                    cur = self.joint_parent[j];
                }
                Some(_) => {
                    return Err(file_error(
                        file,
                        "tip",
                        "the joints above the tip form a cycle; a URDF must be a tree",
                    ))
                }
                None => {
                    return Err(file_error(
                        file,
                        "tip",
                        format!(
                            "link `{}` is not below the base link `{}`; choose a tip in the \
                             base's subtree or another base",
                            self.link_name(tip),
                            self.link_name(base)
                        ),
                    ))
                }
            }
        }
        path.reverse();
        Ok(path)
    }
}

fn names<'a>(it: impl Iterator<Item = &'a str>) -> String {
    it.map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
}

/// Numbers as a URDF attribute writes them: `"0 nan 1.5"`.
fn xml_numbers(values: &[f64]) -> String {
    // Exponent form far from 1: `to_string` spelt 1e308 with all its 309 digits.
    let v: Vec<String> = values
        .iter()
        .map(|&v| {
            if v != 0.0 && v.is_finite() && !(1e-4..1e15).contains(&v.abs()) {
                format!("{v:e}")
            } else {
                v.to_string().to_lowercase()
            }
        })
        .collect();
    format!("\"{}\"", v.join(" "))
}

fn check_finite(values: &[f64], file: &str, element: impl FnOnce() -> String) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(file_error(
            file,
            element(),
            format!(
                "{} has a NaN or infinite value; give finite numbers (SI units)",
                xml_numbers(values)
            ),
        ))
    }
}

/// The pose of a URDF `<origin xyz rpy>`; rpy are fixed-axis roll, pitch, yaw:
/// R = Rz(y)·Ry(p)·Rx(r).
pub(super) fn pose(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rpy[2])
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), rpy[1])
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), rpy[0]);
    Isometry3::from_parts(Translation3::from(Vector3::from(xyz)), r)
}

fn origin(p: &urdf_rs::Pose, file: &str, element: impl Fn() -> String) -> Result<Isometry3<f64>> {
    check_finite(&p.xyz.0, file, || format!("{}/origin/xyz", element()))?;
    check_finite(&p.rpy.0, file, || format!("{}/origin/rpy", element()))?;
    Ok(pose(p.xyz.0, p.rpy.0))
}

/// The 10 standard parameters of a link's `<inertial>` about the link frame's origin.
fn link_parameters(link: &urdf_rs::Link, file: &str) -> Result<[f64; 10]> {
    let i = &link.inertial;
    let frame = origin(&i.origin, file, || link_el(&link.name, "inertial"))?;
    check_finite(&[i.mass.value], file, || {
        link_el(&link.name, "inertial/mass")
    })?;
    let t = &i.inertia;
    check_finite(&[t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz], file, || {
        link_el(&link.name, "inertial/inertia")
    })?;
    // About the centre of mass in the inertial frame, the first moment is zero.
    let about_com = [
        i.mass.value,
        0.0,
        0.0,
        0.0,
        t.ixx,
        t.ixy,
        t.iyy,
        t.ixz,
        t.iyz,
        t.izz,
    ];
    Ok(in_frame(&about_com, &frame))
}

/// Parameters given in frame B expressed in frame A, with `b_in_a` the pose of B in A.
fn in_frame(params: &[f64; 10], b_in_a: &Isometry3<f64>) -> [f64; 10] {
    transform_inertial_parameters(
        params,
        &b_in_a.rotation.to_rotation_matrix().into_inner(),
        &b_in_a.translation.vector,
    )
}

fn joint_info(joint: &urdf_rs::Joint, file: &str) -> Result<JointInfo> {
    let l = &joint.limit;
    for (name, v) in [
        ("lower", l.lower),
        ("upper", l.upper),
        ("velocity", l.velocity),
        ("effort", l.effort),
        ("acceleration", l.acceleration),
    ] {
        if v.is_nan() {
            return Err(file_error(
                file,
                joint_el(&joint.name, &format!("limit/{name}")),
                "NaN limit; give a number or leave the attribute out",
            ));
        }
    }
    // Infinite limits are URDF 1.2's "no limit"; URDF 1.0 writes absent ones as 0.
    let given = |v: f64| {
        if v.is_finite() && v != 0.0 {
            v
        } else {
            f64::NAN
        }
    };
    let finite = |v: f64| if v.is_finite() { v } else { f64::NAN };
    let no_position =
        matches!(joint.joint_type, UrdfJointType::Continuous) || (l.lower == 0.0 && l.upper == 0.0);
    let (lower, upper) = if no_position {
        (f64::NAN, f64::NAN)
    } else {
        (finite(l.lower), finite(l.upper))
    };
    // As a TOML file's: a swapped pair or a negative bound on |q̇|, |q̈|, |τ| is a typo
    // that would make every excitation infeasible (0 stays URDF 1.0's "not given").
    let bounds = [
        ("velocity", l.velocity),
        ("acceleration", l.acceleration),
        ("effort", l.effort),
    ];
    if let Some((key, message)) = super::limit_problem(lower, upper, bounds, true) {
        return Err(file_error(
            file,
            joint_el(&joint.name, &format!("limit/{key}")),
            message,
        ));
    }
    let (damping, friction) = match &joint.dynamics {
        Some(d) => {
            check_finite(&[d.damping, d.friction], file, || {
                joint_el(&joint.name, "dynamics")
            })?;
            (d.damping, d.friction)
        }
        None => (f64::NAN, f64::NAN),
    };
    Ok(JointInfo {
        name: joint.name.clone(),
        limit: JointLimit {
            lower,
            upper,
            velocity: given(l.velocity),
            acceleration: finite(l.acceleration),
            effort: given(l.effort),
        },
        damping,
        friction,
    })
}

/// Checks a chain joint's axis without normalising it: a wrong axis in a file is a typo to
/// report, not to paper over.
fn axis(joint: &urdf_rs::Joint, file: &str) -> Result<Vector3<f64>> {
    let a = Vector3::from(joint.axis.xyz.0);
    let norm = a.norm();
    if norm.is_finite() && (norm - 1.0).abs() <= AXIS_UNIT_TOLERANCE {
        Ok(a)
    } else {
        Err(file_error(
            file,
            joint_el(&joint.name, "axis"),
            format!(
                "axis xyz = {} has length {norm}; a joint axis must be a unit vector \
                 (within {AXIS_UNIT_TOLERANCE}), e.g. \"0 0 1\"",
                xml_numbers(&joint.axis.xyz.0)
            ),
        ))
    }
}

pub(super) fn chain_from_urdf(xml: &str, file: &str, opts: &UrdfOptions) -> Result<DynChain> {
    let filtered = super::xml_scan::prescan(xml, file)?;
    crate::interrupt::check("reading the URDF")?;
    let robot = urdf_rs::read_from_string(&filtered).map_err(|e| {
        file_error(
            file,
            "robot",
            format!("not a readable URDF document ({e}); fix the XML"),
        )
    })?;
    let tree = Tree::new(&robot, file)?;
    let base = tree.base(opts, file)?;
    let tip = match &opts.tip {
        Some(name) => tree.find_link(name, file, "tip")?,
        None => tree.default_tip(base, file)?,
    };
    if tip == base {
        return Err(file_error(
            file,
            "tip",
            format!(
                "the tip is the base link `{}`; choose a tip below it",
                tree.link_name(base)
            ),
        ));
    }
    // Everything below is walked from the base; a cycle through it (possible when --base
    // names a link that is some joint's child) is refused here, before any walk.
    tree.subtree(base, file)?;
    let path = tree.path(base, tip, file)?;

    // Chain index (1-based link number) of each movable path joint.
    let mut chain_index: HashMap<usize, usize> = HashMap::new();
    let mut on_path = vec![false; robot.joints.len()];
    for &j in &path {
        on_path[j] = true;
        let joint = tree.joint(j);
        match joint.joint_type {
            UrdfJointType::Revolute | UrdfJointType::Continuous | UrdfJointType::Prismatic => {
                if joint.mimic.is_some() {
                    return Err(file_error(
                        file,
                        joint_el(&joint.name, "mimic"),
                        "a mimic joint on the base→tip path is not an independent coordinate; \
                         choose a tip whose path has no mimic joint",
                    ));
                }
                chain_index.insert(j, chain_index.len() + 1);
            }
            UrdfJointType::Fixed => {}
            ref t => {
                return Err(file_error(
                    file,
                    joint_el(&joint.name, ""),
                    format!(
                        "a {} joint is on the base→tip path; only revolute, continuous, \
                         prismatic and fixed joints can form a serial chain",
                        type_name(t)
                    ),
                ))
            }
        }
    }
    let n = chain_index.len();
    if n > MAX_DOF {
        return Err(file_error(
            file,
            "tip",
            format!(
                "{n} movable joints between `{}` and `{}`, more than MAX_DOF = {MAX_DOF}; \
                 choose a shorter chain with --base/--tip (Python: base=, tip=)",
                tree.link_name(base),
                tree.link_name(tip)
            ),
        ));
    }
    if n == 0 {
        return Err(file_error(
            file,
            "tip",
            format!(
                "no revolute, continuous or prismatic joint between `{}` and `{}`",
                tree.link_name(base),
                tree.link_name(tip)
            ),
        ));
    }

    let mut joints: Vec<Option<Joint>> = vec![None; n];
    let mut infos: Vec<Option<JointInfo>> = vec![None; n];
    let mut links = vec![String::new(); n];
    let mut inertial = vec![[0.0; 10]; n];
    // Indices of the locked joints (sorted into file order at the end: linear time).
    let mut locked: Vec<usize> = Vec::new();
    let mut visited = vec![false; robot.links.len()];
    // (link, owner chain link (0 = base), pose of the link in the owner's frame)
    let mut stack = vec![(base, 0usize, Isometry3::identity())];
    let mut walked = 0usize;
    while let Some((l, owner, pose_in_owner)) = stack.pop() {
        // `subtree` refused cycles; a link seen twice would still mean one, so stop rather
        // than loop.
        if std::mem::replace(&mut visited[l], true) {
            return Err(file_error(
                file,
                link_el(tree.link_name(l), ""),
                "the joints form a cycle; a URDF must be a tree",
            ));
        }
        walked += 1;
        if walked % 4096 == 0 {
            crate::interrupt::check("reading the URDF")?;
        }
        if owner > 0 {
            let p = link_parameters(&robot.links[l], file)?;
            let p = in_frame(&p, &pose_in_owner);
            for (acc, v) in inertial[owner - 1].iter_mut().zip(p) {
                *acc += v;
            }
        }
        // Reverse so that the stack visits children in file order (locked_joints order).
        for &j in tree.child_joints[l].iter().rev() {
            let joint = tree.joint(j);
            let child = tree.joint_child[j];
            if !on_path[j] && owner == 0 {
                // Hangs from the fixed base: exerts no joint torque.
                continue;
            }
            let o = origin(&joint.origin, file, || joint_el(&joint.name, ""))?;
            if let Some(&k) = chain_index.get(&j) {
                let kind = match joint.joint_type {
                    UrdfJointType::Continuous => JointType::Continuous,
                    UrdfJointType::Prismatic => JointType::Prismatic,
                    _ => JointType::Revolute,
                };
                joints[k - 1] = Some(Joint::new(kind, pose_in_owner * o, axis(joint, file)?));
                infos[k - 1] = Some(joint_info(joint, file)?);
                links[k - 1] = tree.link_name(child).to_string();
                stack.push((child, k, Isometry3::identity()));
                continue;
            }
            match joint.joint_type {
                UrdfJointType::Fixed => {}
                UrdfJointType::Revolute | UrdfJointType::Continuous | UrdfJointType::Prismatic => {
                    // Held at q = 0, where the joint's motion is the identity.
                    locked.push(j);
                }
                ref t => {
                    return Err(file_error(
                        file,
                        joint_el(&joint.name, ""),
                        format!(
                            "a {} joint hangs from the moving link `{}`: its subtree has no \
                             fixed pose to merge; make it fixed or remove it",
                            type_name(t),
                            links[owner - 1]
                        ),
                    ))
                }
            }
            stack.push((child, owner, pose_in_owner * o));
        }
    }
    // Locked joints in file order, independent of the traversal.
    locked.sort_unstable();
    let locked: Vec<String> = locked
        .into_iter()
        .map(|j| tree.joint(j).name.clone())
        .collect();

    let joints: Vec<Joint> = joints.into_iter().flatten().collect();
    let infos: Vec<JointInfo> = infos.into_iter().flatten().collect();
    let meta = ChainMeta {
        name: robot.name.clone(),
        base_link: tree.link_name(base).to_string(),
        links,
        joints: infos,
        locked_joints: locked,
    };
    let chain = DynChain::from_joints(joints)?
        .with_inertial(inertial)?
        .with_gravity(opts.gravity.unwrap_or([0.0, 0.0, -STANDARD_GRAVITY]))?
        .with_meta(meta)?;
    let actuators = super::transmission::actuators_from_urdf(xml, file, &chain)?;
    if actuators.is_default() {
        return Ok(chain);
    }
    chain.with_actuators(actuators)
}
