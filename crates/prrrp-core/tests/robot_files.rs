//! Robot files: URDF import, TOML DH tables and URDF export, checked against independent
//! computations (hand-composed 4×4 transforms and the parallel-axis theorem written out
//! here, closed-form dynamics, a Pinocchio reference) rather than the loader's own output.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3};
use prrrp_core::{
    is_physically_consistent, DhConvention, DhRow, DynChain, FrictionModel, Joint, JointKind,
    JointType, PrrrpError, SerialChain, UrdfOptions,
};

mod files_support;
use files_support::{data, three_joint_text, tip};

// ---------------------------------------------------------------------------------------
// Independent kinematics and inertia: explicit matrices, no nalgebra rotation helpers.

fn rx(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn ry(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn rz(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Homogeneous transform of a URDF `<origin xyz rpy>` (fixed-axis roll, pitch, yaw).
fn hom(xyz: [f64; 3], rpy: [f64; 3]) -> Matrix4<f64> {
    let r = rz(rpy[2]) * ry(rpy[1]) * rx(rpy[0]);
    let mut t = Matrix4::identity();
    t.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    t[(0, 3)] = xyz[0];
    t[(1, 3)] = xyz[1];
    t[(2, 3)] = xyz[2];
    t
}

fn to_iso(t: &Matrix4<f64>) -> Isometry3<f64> {
    let r = Rotation3::from_matrix_unchecked(t.fixed_view::<3, 3>(0, 0).into_owned());
    Isometry3::from_parts(
        Translation3::new(t[(0, 3)], t[(1, 3)], t[(2, 3)]),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// A URDF `<inertial>`: pose of the inertial frame in its link, mass, inertia about the
/// centre of mass as URDF lists it (ixx, ixy, ixz, iyy, iyz, izz).
struct Body {
    xyz: [f64; 3],
    rpy: [f64; 3],
    m: f64,
    i: [f64; 6],
}

/// Standard parameters [m, mc, I about the owner's origin] of a body whose link sits at
/// `owner_t_link` in the owner frame: COM = T·origin, I_O = R·I_C·Rᵀ + m(|c|²·1 − c·cᵀ).
fn params_in_owner(owner_t_link: &Matrix4<f64>, b: &Body) -> [f64; 10] {
    let t = owner_t_link * hom(b.xyz, b.rpy);
    let r = t.fixed_view::<3, 3>(0, 0).into_owned();
    let c = Vector3::new(t[(0, 3)], t[(1, 3)], t[(2, 3)]);
    let [ixx, ixy, ixz, iyy, iyz, izz] = b.i;
    let ic = Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
    let io = r * ic * r.transpose() + (Matrix3::identity() * c.dot(&c) - c * c.transpose()) * b.m;
    [
        b.m,
        b.m * c.x,
        b.m * c.y,
        b.m * c.z,
        io[(0, 0)],
        io[(0, 1)],
        io[(1, 1)],
        io[(0, 2)],
        io[(1, 2)],
        io[(2, 2)],
    ]
}

fn sum(parts: &[[f64; 10]]) -> [f64; 10] {
    let mut out = [0.0; 10];
    for p in parts {
        for (o, v) in out.iter_mut().zip(p) {
            *o += v;
        }
    }
    out
}

/// The fixture's chain (tip `link3`, fingers locked), assembled by hand from its numbers.
fn three_joint_by_hand() -> DynChain {
    let id = Matrix4::identity();
    let adapter_mount = hom([0.0, 0.03, 0.25], [0.1, 0.2, -0.3]);
    let joints = vec![
        Joint::new(
            JointType::Revolute,
            to_iso(&hom([0.1, -0.05, 0.3], [0.3, -0.2, 0.5])),
            Vector3::z(),
        ),
        Joint::new(
            JointType::Continuous,
            to_iso(&(adapter_mount * hom([0.02, -0.01, 0.05], [-0.6, 0.4, 0.15]))),
            Vector3::new(0.6, 0.0, 0.8),
        ),
        Joint::new(
            JointType::Prismatic,
            to_iso(&hom([0.4, 0.02, -0.01], [0.2, 0.3, -0.5])),
            Vector3::y(),
        ),
    ];
    let link1 = Body {
        xyz: [0.05, -0.02, 0.12],
        rpy: [0.2, -0.1, 0.4],
        m: 2.5,
        i: [0.031, 0.002, -0.001, 0.027, 0.0015, 0.012],
    };
    let sensor = Body {
        xyz: [0.01, 0.02, 0.0],
        rpy: [0.5, 0.1, -0.3],
        m: 0.4,
        i: [0.0004, 0.00001, 0.0, 0.0005, 0.00002, 0.0006],
    };
    let adapter = Body {
        xyz: [0.0, 0.0, 0.02],
        rpy: [0.0; 3],
        m: 0.3,
        i: [0.0002, 0.0, 0.0, 0.0002, 0.0, 0.0001],
    };
    let link2 = Body {
        xyz: [0.2, 0.01, -0.03],
        rpy: [-0.3, 0.25, 0.1],
        m: 1.8,
        i: [0.004, -0.0005, 0.0008, 0.035, 0.0003, 0.033],
    };
    let link3 = Body {
        xyz: [0.0, 0.1, 0.02],
        rpy: [0.0, 0.0, 0.7],
        m: 0.9,
        i: [0.006, 0.0002, 0.0, 0.001, -0.0001, 0.0062],
    };
    let finger = |y: f64, m: f64| Body {
        xyz: [0.0, y, 0.03],
        rpy: [0.0; 3],
        m,
        i: [0.00002, 0.0, 0.0, 0.00002, 0.0, 0.00001],
    };
    let tool = Body {
        xyz: [0.01, 0.0, 0.01],
        rpy: [0.3, 0.0, 0.0],
        m: 0.2,
        i: [0.0001, 0.0, 0.0, 0.00012, 0.0, 0.00008],
    };
    let inertial = vec![
        sum(&[
            params_in_owner(&id, &link1),
            params_in_owner(&hom([0.04, 0.06, 0.1], [-0.4, 0.3, 0.2]), &sensor),
            params_in_owner(&adapter_mount, &adapter),
        ]),
        params_in_owner(&id, &link2),
        sum(&[
            params_in_owner(&id, &link3),
            params_in_owner(
                &hom([0.0, 0.15, 0.04], [0.0, 0.1, 0.0]),
                &finger(0.01, 0.05),
            ),
            params_in_owner(
                &hom([0.0, 0.15, -0.04], [0.0, -0.1, 0.0]),
                &finger(-0.01, 0.06),
            ),
            params_in_owner(&hom([0.0, 0.2, 0.0], [0.0, 0.0, 1.0]), &tool),
        ]),
    ];
    DynChain::from_joints(joints)
        .unwrap()
        .with_inertial(inertial)
        .unwrap()
}

// ---------------------------------------------------------------------------------------
// Comparison helpers.

/// Deterministic pseudo-random numbers in [−1, 1) (no rand dependency needed here).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
    fn vec(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.next()).collect()
    }
}

fn assert_close(a: &[f64], b: &[f64], rel: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let scale = b.iter().fold(1.0_f64, |m, x| m.max(x.abs()));
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= rel * scale,
            "{what}[{k}]: {x} vs {y} (diff {:e}, scale {scale})",
            (x - y).abs()
        );
    }
}

/// Same inverse dynamics and mass matrix on random states, to `rel` of the largest entry.
fn assert_same_dynamics(a: &DynChain, b: &DynChain, rel: f64, what: &str) {
    assert_eq!(a.dof(), b.dof(), "{what}: dof");
    let n = a.dof();
    let mut rng = Lcg(7);
    for s in 0..20 {
        let q = rng.vec(n, 2.0);
        let qd = rng.vec(n, 2.0);
        let qdd = rng.vec(n, 5.0);
        let ta = a.inverse_dynamics(&q, &qd, &qdd).unwrap();
        let tb = b.inverse_dynamics(&q, &qd, &qdd).unwrap();
        assert_close(&ta, &tb, rel, &format!("{what}: tau sample {s}"));
        let ma = a.mass_matrix(&q).unwrap();
        let mb = b.mass_matrix(&q).unwrap();
        assert_close(
            ma.as_slice(),
            mb.as_slice(),
            rel,
            &format!("{what}: M sample {s}"),
        );
    }
}

fn robot_file_error(r: Result<DynChain, PrrrpError>) -> (String, String, String) {
    match r {
        Err(PrrrpError::RobotFile {
            file,
            element,
            message,
        }) => (file, element, message),
        Err(e) => panic!("expected a RobotFile error, got {e:?}"),
        Ok(_) => panic!("expected a RobotFile error, got a chain"),
    }
}

/// The error's Display contains every `needle`.
fn assert_error_names(r: Result<DynChain, PrrrpError>, needles: &[&str]) {
    let (file, element, message) = robot_file_error(r);
    let shown = PrrrpError::RobotFile {
        file,
        element,
        message,
    }
    .to_string();
    for n in needles {
        assert!(shown.contains(n), "`{n}` not in: {shown}");
    }
}

// ---------------------------------------------------------------------------------------
// URDF import.

#[test]
fn urdf_matches_hand_assembled_chain() {
    let chain = DynChain::from_urdf_file(data("three_joint.urdf"), &tip("link3")).unwrap();
    let hand = three_joint_by_hand();
    assert_eq!(chain.dof(), 3);
    for (k, (a, b)) in chain.inertial().iter().zip(hand.inertial()).enumerate() {
        assert_close(a, b, 1e-13, &format!("inertial[{k}]"));
    }
    for (k, (a, b)) in chain.joints().iter().zip(hand.joints()).enumerate() {
        assert_eq!(a.kind, b.kind, "joint {k} kind");
        assert!((a.axis - b.axis).norm() < 1e-15, "joint {k} axis");
        let ta = a.placement.to_homogeneous();
        let tb = b.placement.to_homogeneous();
        assert!((ta - tb).norm() < 1e-14, "joint {k} placement");
    }
    assert_same_dynamics(&chain, &hand, 1e-12, "three_joint vs hand");
    assert_eq!(chain.gravity(), [0.0, 0.0, -9.81]);
}

#[test]
fn urdf_matches_pinocchio_reduced_model() {
    // scripts/robot_files_reference.py: Pinocchio's buildReducedModel with the fingers
    // locked at zero, RNEA and CRBA on random states.
    let chain = DynChain::from_urdf_file(data("three_joint.urdf"), &tip("link3")).unwrap();
    let text = std::fs::read_to_string(data("three_joint_pinocchio.txt")).unwrap();
    let mut rows = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        assert_eq!(v.len(), 21);
        let tau = chain
            .inverse_dynamics(&v[0..3], &v[3..6], &v[6..9])
            .unwrap();
        assert_close(&tau, &v[9..12], 1e-10, "tau vs Pinocchio");
        let m = chain.mass_matrix(&v[0..3]).unwrap();
        // nalgebra is column-major, the file row-major; M is symmetric.
        assert_close(m.as_slice(), &v[12..21], 1e-10, "M vs Pinocchio");
        rows += 1;
    }
    assert_eq!(rows, 12);
}

#[test]
fn urdf_meta_names_limits_and_locked_joints() {
    let chain = DynChain::from_urdf_file(data("three_joint.urdf"), &tip("link3")).unwrap();
    let meta = chain.meta();
    assert_eq!(meta.name, "three_joint");
    assert_eq!(meta.base_link, "base_link");
    assert_eq!(meta.links, ["link1", "link2", "link3"]);
    assert_eq!(chain.joint_names(), ["shoulder", "elbow", "slide"]);
    assert_eq!(
        meta.locked_joints,
        ["finger_left_joint", "finger_right_joint"]
    );
    let s = &meta.joints[0];
    assert_eq!(
        (
            s.limit.lower,
            s.limit.upper,
            s.limit.effort,
            s.limit.velocity
        ),
        (-2.5, 2.5, 80.0, 2.0)
    );
    assert!(s.limit.acceleration.is_nan());
    assert_eq!((s.damping, s.friction), (0.5, 1.2));
    let e = &meta.joints[1];
    assert!(e.limit.lower.is_nan() && e.limit.upper.is_nan() && e.limit.velocity.is_nan());
    assert!(e.damping.is_nan() && e.friction.is_nan());
    let p = &meta.joints[2];
    assert_eq!((p.limit.lower, p.limit.upper), (-0.1, 0.3));
    assert_eq!(chain.joints()[1].kind, JointType::Continuous);
    assert_eq!(chain.joints()[2].kind, JointType::Prismatic);
}

#[test]
fn single_revolute_point_mass_closed_form() {
    // Axis y through the origin, point mass m at x = r: z = −r·sin q, so
    // τ = m·r²·q̈ − m·g·r·cos q (no velocity term for one joint).
    let (m, r, g) = (1.7, 0.35, 9.81);
    let xml = format!(
        r#"<robot name="pendulum">
             <link name="world"/>
             <link name="arm">
               <inertial><origin xyz="{r} 0 0"/><mass value="{m}"/>
                 <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
             </link>
             <joint name="hinge" type="continuous">
               <parent link="world"/><child link="arm"/><axis xyz="0 1 0"/>
             </joint>
           </robot>"#
    );
    let chain = DynChain::from_urdf_str(&xml, &UrdfOptions::default()).unwrap();
    for (q, qd, qdd) in [(0.0, 0.0, 0.0), (0.7, -1.3, 2.1), (-2.2, 3.0, -0.4)] {
        let tau = chain.inverse_dynamics(&[q], &[qd], &[qdd]).unwrap()[0];
        let want = m * r * r * qdd - m * g * r * f64::cos(q);
        assert!((tau - want).abs() < 1e-12, "{tau} vs {want}");
    }
    // Gravity from the options, in the base frame: along +x now, so τ = m·r²·q̈ + m·g·r·sin q
    // (the force m·g·x̂ at (r cos q, 0, −r sin q) has moment −m·g·r·sin q about y).
    let opts = UrdfOptions {
        gravity: Some([g, 0.0, 0.0]),
        ..UrdfOptions::default()
    };
    let chain = DynChain::from_urdf_str(&xml, &opts).unwrap();
    let q = 0.9;
    let tau = chain.inverse_dynamics(&[q], &[0.0], &[0.0]).unwrap()[0];
    assert!((tau - m * g * r * f64::sin(q)).abs() < 1e-12);
}

/// Two-joint arm; `payload` is either a body on a fixed joint or the same body written by
/// hand into link1's own inertial.
fn two_joint_xml(link1_inertial: &str, payload: &str) -> String {
    format!(
        r#"<robot name="two">
             <link name="base"/>
             <link name="link1">{link1_inertial}</link>
             <link name="link2">
               <inertial><origin xyz="0.2 0 0.01" rpy="0.1 0 0"/><mass value="1.1"/>
                 <inertia ixx="0.002" ixy="0" ixz="0.0001" iyy="0.01" iyz="0" izz="0.011"/>
               </inertial>
             </link>
             <joint name="j1" type="revolute">
               <parent link="base"/><child link="link1"/><origin xyz="0 0 0.3"/>
               <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="50" velocity="2"/>
             </joint>
             <joint name="j2" type="revolute">
               <parent link="link1"/><child link="link2"/>
               <origin xyz="0.4 0 0" rpy="1.5707963267948966 0 0"/>
               <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="50" velocity="2"/>
             </joint>
             {payload}
           </robot>"#
    )
}

#[test]
fn fixed_body_equals_mass_moved_into_parent() {
    // Payload: fixed joint at xyz (0.1, 0.05, 0.02), yaw a; its inertial at xyz
    // (0.03, −0.01, 0.04), yaw b. In link1: yaw a + b, xyz = Rz(a)·(0.03, −0.01, 0.04) +
    // (0.1, 0.05, 0.02).
    let (a, b) = (0.4, -0.9);
    let inertia = r#"<mass value="0.8"/>
        <inertia ixx="0.003" ixy="0.0002" ixz="0" iyy="0.001" iyz="0" izz="0.0025"/>"#;
    let on_fixed = format!(
        r#"<link name="payload"><inertial><origin xyz="0.03 -0.01 0.04" rpy="0 0 {b}"/>
             {inertia}</inertial></link>
           <joint name="mount" type="fixed"><parent link="link1"/><child link="payload"/>
             <origin xyz="0.1 0.05 0.02" rpy="0 0 {a}"/></joint>"#
    );
    let p = rz(a) * Vector3::new(0.03, -0.01, 0.04) + Vector3::new(0.1, 0.05, 0.02);
    let moved = format!(
        r#"<inertial><origin xyz="{:?} {:?} {:?}" rpy="0 0 {:?}"/>{inertia}</inertial>"#,
        p.x,
        p.y,
        p.z,
        a + b
    );
    let c1 =
        DynChain::from_urdf_str(&two_joint_xml("", &on_fixed), &UrdfOptions::default()).unwrap();
    let c2 = DynChain::from_urdf_str(&two_joint_xml(&moved, ""), &UrdfOptions::default()).unwrap();
    for (x, y) in c1.inertial().iter().zip(c2.inertial()) {
        assert_close(x, y, 1e-14, "inertial");
    }
    assert_same_dynamics(&c1, &c2, 1e-13, "fixed payload vs moved");
    assert!(c1.inertial()[0][0] == 0.8 && c1.meta().locked_joints.is_empty());
}

#[test]
fn bodies_on_the_base_are_ignored() {
    let base_body = r#"<link name="stand"><inertial><mass value="50"/>
        <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
        <joint name="stand_mount" type="fixed"><parent link="base"/><child link="stand"/>
        <origin xyz="1 2 3"/></joint>"#;
    let a =
        DynChain::from_urdf_str(&two_joint_xml("", base_body), &UrdfOptions::default()).unwrap();
    let b = DynChain::from_urdf_str(&two_joint_xml("", ""), &UrdfOptions::default()).unwrap();
    assert_eq!(a.inertial(), b.inertial());
}

#[test]
fn geometry_urdf_rs_would_refuse_does_not_stop_a_robot() {
    // As in iCub's and Romeo's files (example-robot-data), which urdfdom and Pinocchio
    // read: a `<texture />` without a file name, in the robot's material list and in a
    // visual; also a mesh without one in a collision and an unknown geometry type.
    let link1 = r#"<visual><geometry><box size="0.1 0.1 0.1"/></geometry>
          <material name="metal"><texture /></material></visual>
        <collision><geometry><mesh /></geometry></collision>
        <collision><geometry><capsule radius="0.1" length="0.2"/></geometry></collision>
        <inertial><origin xyz="0.1 0 0"/><mass value="2.0"/>
          <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/></inertial>"#;
    let plain = r#"<inertial><origin xyz="0.1 0 0"/><mass value="2.0"/>
          <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/></inertial>"#;
    let materials = r#"<material name="metal"><texture /></material><material name="x"/>"#;
    let a =
        DynChain::from_urdf_str(&two_joint_xml(link1, materials), &UrdfOptions::default()).unwrap();
    let b = DynChain::from_urdf_str(&two_joint_xml(plain, ""), &UrdfOptions::default()).unwrap();
    assert_eq!(a.inertial(), b.inertial());
    assert_same_dynamics(&a, &b, 0.0, "with and without geometry");
    // What matters is still read and checked: a broken inertial is an error.
    let broken = two_joint_xml(&link1.replace(r#"value="2.0""#, r#"value="two""#), "");
    assert!(DynChain::from_urdf_str(&broken, &UrdfOptions::default()).is_err());
}

#[test]
fn base_option_and_default_tip_below_it() {
    // From link1 down: elbow and slide, fingers still branch below link3.
    let opts = UrdfOptions {
        base: Some("adapter".into()),
        tip: Some("link3".into()),
        gravity: None,
    };
    let chain = DynChain::from_urdf_str(&three_joint_text(), &opts).unwrap();
    assert_eq!(chain.joint_names(), ["elbow", "slide"]);
    assert_eq!(chain.meta().base_link, "adapter");
    // The elbow now hangs from the base frame `adapter` directly.
    let want = to_iso(&hom([0.02, -0.01, 0.05], [-0.6, 0.4, 0.15])).to_homogeneous();
    assert!((chain.joints()[0].placement.to_homogeneous() - want).norm() < 1e-14);
}

#[test]
fn non_physical_inertias_load() {
    // Ixx > Iyy + Izz violates the triangle inequality; the file still loads.
    let bad = r#"<inertial><mass value="1"/>
        <inertia ixx="1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;
    let chain = DynChain::from_urdf_str(&two_joint_xml(bad, ""), &UrdfOptions::default()).unwrap();
    assert!(!is_physically_consistent(&chain.inertial()[0], 1e-12));
    assert!(is_physically_consistent(&chain.inertial()[1], 1e-12));
}

#[test]
fn negative_masses_load() {
    let neg = r#"<inertial><mass value="-1"/>
        <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;
    let chain = DynChain::from_urdf_str(&two_joint_xml(neg, ""), &UrdfOptions::default()).unwrap();
    assert!(!is_physically_consistent(&chain.inertial()[0], 1e-12));
}

// ---------------------------------------------------------------------------------------
// URDF errors.

#[test]
fn urdf_errors_name_file_and_element() {
    let text = three_joint_text();
    let default = UrdfOptions::default();
    // The fixture with `from` replaced by `to`, loaded up to link3, names every needle.
    let edited = |from: &str, to: &str, needles: &[&str]| {
        let bad = text.replace(from, to);
        assert_ne!(bad, text, "`{from}` not in the fixture");
        assert_error_names(DynChain::from_urdf_str(&bad, &tip("link3")), needles);
    };
    // Several candidate tips: both finger links listed.
    assert_error_names(
        DynChain::from_urdf_str(&text, &default),
        &[
            "<string>",
            "--tip LINK (Python: tip=)",
            "Candidates, best first: `link3` (the arm's end, where they branch), `finger_left`",
            "finger_right",
        ],
    );
    // Malformed XML.
    assert_error_names(
        DynChain::from_urdf_str("<robot name=\"x\"><link name=\"a\">", &default),
        &["<string>", "robot"],
    );
    assert_error_names(
        DynChain::from_urdf_str("not xml at all", &default),
        &["<string>"],
    );
    // Missing links: in options and in a joint.
    assert_error_names(
        DynChain::from_urdf_str(&text, &tip("no_such_link")),
        &["no_such_link", "tip"],
    );
    let opts = UrdfOptions {
        base: Some("ghost_base".into()),
        ..tip("link3")
    };
    assert_error_names(DynChain::from_urdf_str(&text, &opts), &["ghost_base"]);
    edited(
        "<parent link=\"link2\"/>",
        "<parent link=\"ghost\"/>",
        &["joint[slide]/parent", "ghost"],
    );
    // Tip not below base.
    let opts = UrdfOptions {
        base: Some("link2".into()),
        ..tip("link1")
    };
    assert_error_names(DynChain::from_urdf_str(&text, &opts), &["link1", "link2"]);
    // Zero and non-unit axes.
    for axis in ["0 0 0", "0 2 0", "0 0.9 0"] {
        edited(
            "<axis xyz=\"0 1 0\"/>",
            &format!("<axis xyz=\"{axis}\"/>"),
            &["joint[slide]/axis"],
        );
    }
    // Floating and planar joints on the path.
    for ty in ["floating", "planar"] {
        edited(
            "name=\"slide\" type=\"prismatic\"",
            &format!("name=\"slide\" type=\"{ty}\""),
            &["joint[slide]", ty],
        );
    }
    // A floating joint off the path below a moving link.
    edited(
        "name=\"tool_mount\" type=\"fixed\"",
        "name=\"tool_mount\" type=\"floating\"",
        &["joint[tool_mount]", "floating"],
    );
    // A mimic joint on the path.
    assert_error_names(
        DynChain::from_urdf_str(&text, &tip("finger_right")),
        &["joint[finger_right_joint]/mimic"],
    );
    // NaN values.
    edited(
        "<mass value=\"1.8\"/>",
        "<mass value=\"nan\"/>",
        &["link[link2]/inertial/mass"],
    );
    edited(
        "<origin xyz=\"0.4 0.02 -0.01\"",
        "<origin xyz=\"0.4 NaN -0.01\"",
        &["joint[slide]/origin/xyz"],
    );
    edited(
        "ixx=\"0.004\"",
        "ixx=\"inf\"",
        &["link[link2]/inertial/inertia"],
    );
    // Swapped or negative limits (a TOML file's are refused alike); 0 is URDF 1.0's
    // "not given" and reads.
    edited(
        "lower=\"-0.1\" upper=\"0.3\"",
        "lower=\"0.3\" upper=\"-0.1\"",
        &["joint[slide]/limit/lower", "swap them"],
    );
    for (from, to, at) in [
        ("velocity=\"0.5\"", "velocity=\"-0.5\"", "limit/velocity"),
        ("effort=\"200\"", "effort=\"-200\"", "limit/effort"),
    ] {
        edited(from, to, &["joint[slide]", at, "not positive"]);
    }
    let unlimited = text.replace("velocity=\"0.5\"", "velocity=\"0\"");
    assert!(DynChain::from_urdf_str(&unlimited, &tip("link3")).is_ok());
    // An empty <robot> (example-robot-data's ur3.urdf): it said "the joints form a cycle".
    assert_error_names(
        DynChain::from_urdf_str("<robot name=\"ur3\"><!-- nothing --></robot>", &default),
        &["<string>", "robot", "has no links"],
    );
    // A root other than <robot>: urdf-rs would read it as a robot without links.
    let sdf = text
        .replacen("<robot", "<sdf", 1)
        .replace("</robot>", "</sdf>");
    assert_error_names(
        DynChain::from_urdf_str(&sdf, &tip("link3")),
        &["<string>", "robot", "root element is <sdf>"],
    );
    // Tip equal to base, duplicate names.
    assert_error_names(DynChain::from_urdf_str(&text, &tip("base_link")), &["tip"]);
    edited(
        "<link name=\"tool\">",
        "<link name=\"link2\">",
        &[
            "link[link2]",
            "two links have this name; link names must be unique",
        ],
    );
    edited(
        "name=\"tool_mount\" type=\"fixed\"",
        "name=\"slide\" type=\"fixed\"",
        &[
            "joint[slide]",
            "two joints have this name; joint names must be unique",
        ],
    );
}

#[test]
fn urdf_file_errors_name_the_path() {
    let missing = data("does_not_exist.urdf");
    let (file, _, message) =
        robot_file_error(DynChain::from_urdf_file(&missing, &UrdfOptions::default()));
    assert_eq!(file, missing);
    assert!(message.contains("cannot read"), "{message}");
    let (file, element, _) = robot_file_error(DynChain::from_urdf_file(
        data("three_joint.urdf"),
        &UrdfOptions::default(),
    ));
    assert_eq!(
        (file.as_str(), element.as_str()),
        (data("three_joint.urdf").as_str(), "tip")
    );
}

#[test]
fn truncated_urdf_never_panics() {
    let text = three_joint_text();
    let mut cut = 0;
    while cut < text.len() {
        if text.is_char_boundary(cut) {
            match DynChain::from_urdf_str(&text[..cut], &tip("link3")) {
                Ok(_) | Err(PrrrpError::RobotFile { .. }) => {}
                Err(e) => panic!("cut at {cut}: unexpected error type {e:?}"),
            }
        }
        cut += 97;
    }
}

// ---------------------------------------------------------------------------------------
// TOML DH tables.

const PANDA_A: [f64; 7] = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088];
const PANDA_D: [f64; 7] = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0];
const PANDA_ALPHA: [f64; 7] = [
    0.0, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2,
];

fn panda_inertials() -> Vec<[f64; 10]> {
    (0..7)
        .map(|i| {
            let k = i as f64;
            // Integer-valued masses so that the TOML can write them as integers.
            [
                (7 - i) as f64,
                0.01 * k,
                -0.02 * k,
                0.03,
                0.1 + 0.01 * k,
                0.001,
                0.09,
                -0.002,
                0.0005 * k,
                0.05,
            ]
        })
        .collect()
}

fn panda_toml() -> String {
    // α as decimal text (TOML has no π); integers for masses and zero offsets.
    let mut s = String::from(
        "name = \"panda\"\nconvention = \"modified\"\ngravity = [0, 0, -9.80665]\n\
         base_link = \"panda_link0\"\n",
    );
    for (i, p) in panda_inertials().iter().enumerate() {
        s += &format!(
            "\n[[joint]]\nname = \"panda_joint{}\"\nlink = \"panda_link{}\"\ntype = \"revolute\"\n\
             a = {:?}\nalpha = {:?}\nd = {:?}\ntheta = 0\nlower = -2.8973\nupper = 2.8973\n\
             velocity = 2\neffort = 87\ninertial = [{}, {:?}, {:?}, {:?}, {:?}, {:?}, {:?}, \
             {:?}, {:?}, {:?}]\n",
            i + 1,
            i + 1,
            PANDA_A[i],
            PANDA_ALPHA[i],
            PANDA_D[i],
            7 - i,
            p[1],
            p[2],
            p[3],
            p[4],
            p[5],
            p[6],
            p[7],
            p[8],
            p[9]
        );
    }
    s
}

#[test]
fn toml_panda_equals_dh_chain() {
    let chain = DynChain::from_toml_str(&panda_toml()).unwrap();
    let rows: Vec<DhRow> = (0..7)
        .map(|i| DhRow {
            kind: JointKind::Revolute,
            theta: 0.0,
            d: PANDA_D[i],
            a: PANDA_A[i],
            alpha: PANDA_ALPHA[i],
        })
        .collect();
    let want = DynChain::new(rows, DhConvention::Modified)
        .unwrap()
        .with_inertial(panda_inertials())
        .unwrap()
        .with_gravity([0.0, 0.0, -9.80665])
        .unwrap();
    assert_eq!(chain.inertial(), want.inertial());
    assert_eq!(chain.convention(), Some(DhConvention::Modified));
    assert_eq!(chain.gravity(), [0.0, 0.0, -9.80665]);
    assert_same_dynamics(&chain, &want, 1e-15, "TOML panda vs DynChain::new");
    let meta = chain.meta();
    assert_eq!(meta.name, "panda");
    assert_eq!(meta.base_link, "panda_link0");
    assert_eq!(meta.links[6], "panda_link7");
    assert_eq!(meta.joints[2].name, "panda_joint3");
    let l = meta.joints[0].limit;
    assert_eq!(
        (l.lower, l.upper, l.velocity, l.effort),
        (-2.8973, 2.8973, 2.0, 87.0)
    );
    assert!(l.acceleration.is_nan());
    assert_eq!(chain.friction(), FrictionModel::default());
    // Modified DH through URDF: the same dynamics and names.
    let xml = chain.to_urdf(None).unwrap();
    let back = DynChain::from_urdf_str(&xml, &UrdfOptions::default()).unwrap();
    assert_eq!(back.gravity(), [0.0, 0.0, -9.81], "URDF carries no gravity");
    let opts = UrdfOptions {
        gravity: Some(chain.gravity()),
        ..UrdfOptions::default()
    };
    let back = DynChain::from_urdf_str(&xml, &opts).unwrap();
    assert_same_dynamics(&chain, &back, 1e-12, "TOML panda via URDF");
    assert_eq!(back.meta().links, meta.links);
}

#[test]
fn toml_defaults_friction_and_standard_convention() {
    let text = r#"
        convention = "standard"
        [[joint]]
        type = "prismatic"
        a = 0
        alpha = 1
        d = 0.5
        theta = 0.25
        friction = [0.1, 0.2, 3]
        [[joint]]
        type = "continuous"
        a = 0.3
        alpha = 0
        d = 0
        theta = 0
        acceleration = 10
    "#;
    let chain = DynChain::from_toml_str(text).unwrap();
    assert_eq!(chain.convention(), Some(DhConvention::Standard));
    assert_eq!(chain.gravity(), [0.0, 0.0, -9.81]);
    assert_eq!(chain.meta().name, "robot");
    assert_eq!(chain.joint_names(), ["joint1", "joint2"]);
    assert_eq!(chain.friction(), FrictionModel::all());
    assert_eq!(chain.friction_params(), [[0.1, 0.2, 3.0], [0.0; 3]]);
    assert_eq!(chain.inertial(), [[0.0; 10]; 2]);
    assert_eq!(chain.dh().unwrap()[0].kind, JointKind::Prismatic);
    assert_eq!(chain.meta().joints[1].limit.acceleration, 10.0);
}

#[test]
fn toml_errors_name_the_key() {
    let good = panda_toml();
    // The file with the first `from` replaced by `to` names every needle.
    let edited = |from: &str, to: &str, needles: &[&str]| {
        let bad = good.replacen(from, to, 1);
        assert_ne!(bad, good, "`{from}` not in the file");
        assert_error_names(DynChain::from_toml_str(&bad), needles);
    };
    // Unknown keys, top level and in a joint.
    assert_error_names(
        DynChain::from_toml_str(&format!("colour = 1\n{good}")),
        &["<string>", "colour"],
    );
    let bad = good.replacen("theta = 0\n", "theta = 0\nmass = 3\n", 3);
    assert_error_names(DynChain::from_toml_str(&bad), &["joint[0].mass"]);
    // Wrong types and lengths.
    edited("a = 0.0825", "a = \"0.0825\"", &["joint[3].a", "string"]);
    edited(
        "inertial = [7, ",
        "inertial = [",
        &["joint[0].inertial", "10"],
    );
    edited(
        "inertial = [6, ",
        "inertial = [true, ",
        &["joint[1].inertial[0]"],
    );
    edited(
        "convention = \"modified\"",
        "convention = \"craig\"",
        &["convention", "craig"],
    );
    edited(
        "type = \"revolute\"",
        "type = \"ball\"",
        &["joint[0].type", "ball"],
    );
    // Missing keys.
    edited("d = 0.316\n", "", &["joint[2].d", "missing"]);
    assert_error_names(
        DynChain::from_toml_str(&good.replacen("convention = \"modified\"\n", "", 1)),
        &["convention"],
    );
    assert_error_names(
        DynChain::from_toml_str("convention = \"standard\""),
        &["joint"],
    );
    // Non-finite numbers, bad limits.
    edited("d = 0.333", "d = nan", &["joint[0].d"]);
    edited(
        "gravity = [0, 0, -9.80665]",
        "gravity = [0, inf, 0]",
        &["gravity[1]"],
    );
    // A negative mass loads (a file's inertials are only a prior) and is reported.
    let neg = good.replacen("inertial = [7, ", "inertial = [-7, ", 1);
    let chain = DynChain::from_toml_str(&neg).unwrap();
    assert!(chain.non_physical_links().contains(&0));
    let ok = DynChain::from_toml_str(&good).unwrap();
    assert!(!ok.non_physical_links().contains(&0));
    edited("lower = -2.8973", "lower = 3", &["joint[0].lower"]);
    // Repeated names.
    edited(
        "link = \"panda_link2\"",
        "link = \"panda_link1\"",
        &["joint[1].link", "panda_link1"],
    );
    edited(
        "name = \"panda_joint3\"",
        "name = \"panda_joint1\"",
        &["joint[2].name", "panda_joint1"],
    );
    // Syntax errors.
    assert_error_names(
        DynChain::from_toml_str("name = \"x\"\n[[joint]\n"),
        &["file", "line 2"],
    );
}

// ---------------------------------------------------------------------------------------
// Files by extension.

#[test]
fn from_file_chooses_by_extension() {
    let dir = std::env::temp_dir().join(format!("prrrp_robot_files_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let toml_path = dir.join("panda.TOML");
    std::fs::write(&toml_path, panda_toml()).unwrap();
    let chain = DynChain::from_file(&toml_path, &UrdfOptions::default()).unwrap();
    assert_eq!(chain.dof(), 7);
    let chain = DynChain::from_file(data("three_joint.urdf"), &tip("link3")).unwrap();
    assert_eq!(chain.dof(), 3);
    assert_error_names(
        DynChain::from_file(dir.join("robot.xml"), &UrdfOptions::default()),
        &[".xml", "robot.xml"],
    );
    assert_error_names(
        DynChain::from_file(dir.join("robot"), &UrdfOptions::default()),
        &["extension"],
    );
    let missing = dir.join("missing.toml");
    assert_error_names(
        DynChain::from_file(&missing, &UrdfOptions::default()),
        &["missing.toml", "cannot read"],
    );
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "convention = 1\n").unwrap();
    assert_error_names(DynChain::from_toml_file(&bad), &["bad.toml", "convention"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------
// URDF export round trips.

#[test]
fn urdf_round_trip_keeps_dynamics_inertials_and_names() {
    let chain = DynChain::from_urdf_file(data("three_joint.urdf"), &tip("link3")).unwrap();
    let xml = chain.to_urdf(None).unwrap();
    let back = DynChain::from_urdf_str(&xml, &UrdfOptions::default()).unwrap();
    assert_same_dynamics(&chain, &back, 1e-12, "URDF round trip");
    for (k, (a, b)) in chain.inertial().iter().zip(back.inertial()).enumerate() {
        assert_close(b, a, 1e-12, &format!("round-trip inertial[{k}]"));
    }
    let (m, mb) = (chain.meta(), back.meta());
    assert_eq!(mb.name, m.name);
    assert_eq!(mb.base_link, m.base_link);
    assert_eq!(mb.links, m.links);
    assert_eq!(back.joint_names(), chain.joint_names());
    for (a, b) in m.joints.iter().zip(&mb.joints) {
        for (x, y) in [
            (a.limit.lower, b.limit.lower),
            (a.limit.upper, b.limit.upper),
            (a.limit.velocity, b.limit.velocity),
            (a.limit.effort, b.limit.effort),
            (a.damping, b.damping),
            (a.friction, b.friction),
        ] {
            assert!(
                x == y || (x.is_nan() && y.is_nan()),
                "{}: {x} vs {y}",
                a.name
            );
        }
    }
    for (a, b) in chain.joints().iter().zip(back.joints()) {
        assert_eq!(a.kind, b.kind);
        assert_eq!(a.axis, b.axis);
    }
}

#[test]
fn standard_dh_puma_round_trips_through_urdf() {
    let puma = SerialChain::puma560().to_dyn();
    let back =
        DynChain::from_urdf_str(&puma.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
    assert_same_dynamics(&puma, &back, 1e-12, "PUMA via URDF");
    // Given parameters replace the chain's own.
    let mut p = puma.parameters();
    for (k, x) in p.iter_mut().enumerate() {
        *x *= 1.0 + 0.01 * (k % 7) as f64;
    }
    let xml = puma.to_urdf(Some(&p)).unwrap();
    let back = DynChain::from_urdf_str(&xml, &UrdfOptions::default()).unwrap();
    let want = puma
        .clone()
        .with_inertial(p.chunks(10).map(|c| c.try_into().unwrap()).collect())
        .unwrap();
    assert_same_dynamics(&want, &back, 1e-12, "PUMA with given parameters");
    assert!(puma.to_urdf(Some(&p[..11])).is_err());
}

#[test]
fn export_writes_friction_as_dynamics() {
    let text = r#"
        convention = "modified"
        [[joint]]
        type = "revolute"
        a = 0
        alpha = 0
        d = 0.3
        theta = 0
        inertial = [2, 0.2, 0, 0, 0.1, 0, 0.1, 0, 0, 0.05]
        friction = [0.25, 1.5, 0.1]
        [[joint]]
        type = "prismatic"
        a = 0.2
        alpha = 1.5707963267948966
        d = 0
        theta = 0
        inertial = [1, 0, 0, 0.1, 0.02, 0, 0.02, 0, 0, 0.01]
    "#;
    let chain = DynChain::from_toml_str(text).unwrap();
    let back =
        DynChain::from_urdf_str(&chain.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
    let infos = back.joint_info();
    assert_eq!((infos[0].damping, infos[0].friction), (0.25, 1.5));
    assert_eq!((infos[1].damping, infos[1].friction), (0.0, 0.0));
    // Friction entries after the inertials replace the chain's own.
    let mut p = chain.parameters();
    assert_eq!(p.len(), 26);
    p[20] = 0.75;
    p[21] = 2.5;
    let back = DynChain::from_urdf_str(&chain.to_urdf(Some(&p)).unwrap(), &UrdfOptions::default())
        .unwrap();
    assert_eq!(
        (back.joint_info()[0].damping, back.joint_info()[0].friction),
        (0.75, 2.5)
    );
    // Rigid-body dynamics are unchanged (friction is not part of the re-read model).
    let rigid = chain
        .clone()
        .with_friction(FrictionModel::default(), vec![[0.0; 3]; 2])
        .unwrap();
    assert_same_dynamics(&rigid, &back, 1e-12, "TOML → URDF");
}

#[test]
fn export_numbers_round_trip_exactly() {
    let x = 0.1 + 0.2;
    let text = format!(
        "convention = \"modified\"\n[[joint]]\ntype = \"revolute\"\na = 0\nalpha = 0\n\
         d = {x:?}\ntheta = 0\ninertial = [{x:?}, 0, 0, 0, 1e-7, 0, 3.3e-5, 0, 0, 1e-300]\n"
    );
    let chain = DynChain::from_toml_str(&text).unwrap();
    let back =
        DynChain::from_urdf_str(&chain.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
    assert_eq!(back.inertial()[0], chain.inertial()[0]);
    assert_eq!(
        back.joints()[0].placement.translation.vector,
        chain.joints()[0].placement.translation.vector
    );
}

// ---------------------------------------------------------------------------------------
// The example-robot-data URDFs (not in the repository).

#[test]
#[ignore = "reads example-robot-data from the Python venv; run with --ignored"]
fn example_robot_data_urdfs_load() {
    let root = std::env::var("PRRRP_EXAMPLE_ROBOT_DATA").unwrap_or_else(|_| {
        format!(
            "{}/../../.venv/lib/python3.11/site-packages/cmeel.prefix/share/example-robot-data/robots",
            env!("CARGO_MANIFEST_DIR")
        )
    });
    let panda_path = format!("{root}/panda_description/urdf/panda.urdf");
    assert_error_names(
        DynChain::from_urdf_file(&panda_path, &UrdfOptions::default()),
        &["panda_leftfinger", "panda_rightfinger"],
    );
    let panda = DynChain::from_urdf_file(&panda_path, &tip("panda_link8")).unwrap();
    assert_eq!(panda.dof(), 7);
    assert_eq!(
        panda.meta().locked_joints,
        ["panda_finger_joint1", "panda_finger_joint2"]
    );
    let ur5 = DynChain::from_urdf_file(
        format!("{root}/ur_description/urdf/ur5_robot.urdf"),
        &UrdfOptions::default(),
    )
    .unwrap();
    assert_eq!(ur5.dof(), 6);
    let kinova = DynChain::from_urdf_file(
        format!("{root}/kinova_description/robots/kinova.urdf"),
        &UrdfOptions::default(),
    )
    .unwrap();
    assert!(kinova.dof() >= 6);
    for c in [&panda, &ur5, &kinova] {
        let back =
            DynChain::from_urdf_str(&c.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
        assert_same_dynamics(c, &back, 1e-12, &c.meta().name);
    }
}

#[test]
fn export_is_accurate_near_pitch_half_pi() {
    // UR-style origins with pitch ≈ ±π/2, where asin-based rpy extraction loses ~8 digits.
    let xml = r#"<robot name="gimbal">
        <link name="base"/>
        <link name="l1"><inertial><origin xyz="0.1 0.02 0.3" rpy="0.3 1.570796325 -0.2"/>
          <mass value="3"/><inertia ixx="0.05" ixy="0.001" ixz="0" iyy="0.04" iyz="0" izz="0.02"/>
        </inertial></link>
        <link name="l2"><inertial><origin xyz="0.2 0 0.01"/><mass value="2"/>
          <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
        <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>
          <origin xyz="0 0 0.089" rpy="0.1 1.570796325 0.7"/><axis xyz="0 0 1"/></joint>
        <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
          <origin xyz="0 0.136 0" rpy="-0.4 -1.5707963267948966 0.2"/><axis xyz="0 1 0"/></joint>
      </robot>"#;
    let chain = DynChain::from_urdf_str(xml, &UrdfOptions::default()).unwrap();
    let back =
        DynChain::from_urdf_str(&chain.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
    for (a, b) in chain.joints().iter().zip(back.joints()) {
        let d = a.placement.to_homogeneous() - b.placement.to_homogeneous();
        assert!(d.norm() < 1e-15, "{d}");
    }
    assert_same_dynamics(&chain, &back, 1e-13, "gimbal round trip");
}

/// An endless or huge file is refused after a bounded read, not read into memory whole.
#[cfg(unix)]
#[test]
fn endless_file_is_refused() {
    let e = DynChain::from_urdf_file("/dev/zero", &UrdfOptions::default()).unwrap_err();
    assert!(e.to_string().contains("larger than"), "{e}");
}

/// A FIFO is refused without opening it: the open blocked until a writer came, and
/// neither Ctrl-C nor SIGTERM ended the wait.
#[cfg(unix)]
#[test]
fn fifo_is_refused_without_blocking() {
    let dir = std::env::temp_dir().join(format!("prrrp-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("robot.urdf");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("no mkfifo here: skipped");
        return;
    }
    let (tx, rx) = std::sync::mpsc::channel();
    let path = fifo.clone();
    // A thread, so that a regression fails the test instead of hanging it.
    std::thread::spawn(move || {
        let urdf = DynChain::from_urdf_file(&path, &UrdfOptions::default()).map(|_| ());
        let toml = DynChain::from_toml_file(&path).map(|_| ());
        let _ = tx.send((urdf, toml));
    });
    let got = rx.recv_timeout(std::time::Duration::from_secs(20));
    let _ = std::fs::remove_dir_all(&dir);
    let (urdf, toml) = got.expect("reading a FIFO blocked");
    for e in [urdf.unwrap_err(), toml.unwrap_err()] {
        assert!(e.to_string().contains("pipe or socket"), "{e}");
    }
}

// ---------------------------------------------------------------------------------------
// Hostile files (issue 25, item 6): each ends in a typed error or the right chain.

#[test]
fn joint_cycle_through_the_base_is_refused() {
    // a → b → a: no root; with --base inside the cycle the walk from it must stop.
    let xml = r#"<robot name="loop">
        <link name="a"/><link name="b"/>
        <joint name="ab" type="revolute"><parent link="a"/><child link="b"/>
          <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
        <joint name="ba" type="revolute"><parent link="b"/><child link="a"/>
          <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      </robot>"#;
    for (base, tip) in [("a", Some("b")), ("b", Some("a")), ("a", None)] {
        let opts = UrdfOptions {
            base: Some(base.into()),
            tip: tip.map(Into::into),
            gravity: None,
        };
        assert_error_names(DynChain::from_urdf_str(xml, &opts), &["cycle"]);
    }
}

#[test]
fn deeply_nested_xml_is_refused_before_urdf_rs_recurses() {
    // 30 000 levels overflowed urdf-rs's stack (SIGSEGV).
    let depth = 30_000;
    let xml = format!(
        "<robot name=\"deep\"><link name=\"a\"/>{}{}</robot>",
        "<x>".repeat(depth),
        "</x>".repeat(depth)
    );
    let (_, element, message) =
        robot_file_error(DynChain::from_urdf_str(&xml, &UrdfOptions::default()));
    assert_eq!(element, "robot");
    assert!(message.contains("MAX_URDF_DEPTH"), "{message}");
    // A URDF at the limit still reads.
    let ok = format!(
        "<robot name=\"deep\"><link name=\"a\"/><link name=\"b\">{}{}</link>\
         <joint name=\"j\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>\
         <axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>\
         </joint></robot>",
        "<x>".repeat(prrrp_core::MAX_URDF_DEPTH - 2),
        "</x>".repeat(prrrp_core::MAX_URDF_DEPTH - 2)
    );
    assert_eq!(
        DynChain::from_urdf_str(&ok, &UrdfOptions::default())
            .unwrap()
            .dof(),
        1
    );
}

#[test]
fn too_many_xml_elements_are_refused() {
    let xml = format!(
        "<robot name=\"many\"><link name=\"a\"/>{}</robot>",
        "<x/>".repeat(prrrp_core::MAX_URDF_ELEMENTS)
    );
    let (_, _, message) = robot_file_error(DynChain::from_urdf_str(&xml, &UrdfOptions::default()));
    assert!(message.contains("MAX_URDF_ELEMENTS"), "{message}");
}

/// A revolute joint `base → arm` with `locked` further revolute joints hanging from `arm`,
/// each with a 1 kg point mass at x = 0.1 m.
fn many_locked_xml(locked: usize) -> String {
    let mut xml = String::from(
        r#"<robot name="comb"><link name="base"/><link name="arm"/>
           <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
           <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>"#,
    );
    for i in 0..locked {
        xml.push_str(&format!(
            "<link name=\"t{i}\"><inertial><origin xyz=\"0.1 0 0\"/><mass value=\"1\"/>\
             <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial>\
             </link><joint name=\"l{i}\" type=\"revolute\"><parent link=\"arm\"/>\
             <child link=\"t{i}\"/><axis xyz=\"1 0 0\"/>\
             <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/></joint>"
        ));
    }
    xml.push_str("</robot>");
    xml
}

#[test]
fn many_locked_joints_merge_in_linear_time() {
    // 120 000 locked joints hung (quadratic sorting); 4 000 (40 000 elements, below
    // MAX_URDF_ELEMENTS) is a real test of the same code path, and the result is checked.
    let locked = 4_000;
    let chain = DynChain::from_urdf_str(&many_locked_xml(locked), &tip("arm")).unwrap();
    let meta = chain.meta();
    assert_eq!(meta.locked_joints.len(), locked);
    assert!(meta
        .locked_joints
        .iter()
        .enumerate()
        .all(|(i, name)| *name == format!("l{i}")));
    // All point masses merged into the arm: m = N kg, first moment N·0.1 kg·m along x.
    let p = chain.inertial()[0];
    assert_eq!(p[0], locked as f64);
    assert!((p[1] - 0.1 * locked as f64).abs() < 1e-9 * locked as f64);
    // The file of issue 25 (120 000 locked joints, 480 000 elements) is refused at once.
    let (_, _, message) = robot_file_error(DynChain::from_urdf_str(
        &many_locked_xml(120_000),
        &tip("arm"),
    ));
    assert!(message.contains("MAX_URDF_ELEMENTS"), "{message}");
}

fn dh_toml(joints: usize) -> String {
    let mut s = String::from("convention = \"modified\"\n");
    for _ in 0..joints {
        s.push_str(
            "[[joint]]\ntype = \"revolute\"\na = 0.1\nalpha = 0.3\nd = 0.1\ntheta = 0\n\
             inertial = [1, 0, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1]\n",
        );
    }
    s
}

#[test]
fn joint_counts_beyond_max_dof_are_refused_before_work() {
    let max = prrrp_core::MAX_DOF;
    assert_eq!(DynChain::from_toml_str(&dh_toml(max)).unwrap().dof(), max);
    // The 300-joint TOML of issue 25 hung in the base-parameter analysis.
    let (_, element, message) = robot_file_error(DynChain::from_toml_str(&dh_toml(300)));
    assert_eq!(element, "joint");
    assert!(message.contains("MAX_DOF"), "{message}");
    // A URDF chain of MAX_DOF + 1 movable joints.
    let mut xml = String::from("<robot name=\"snake\"><link name=\"l0\"/>");
    for i in 1..=max + 1 {
        xml.push_str(&format!(
            "<link name=\"l{i}\"/><joint name=\"j{i}\" type=\"continuous\">\
             <parent link=\"l{}\"/><child link=\"l{i}\"/><origin xyz=\"0.1 0 0\"/>\
             <axis xyz=\"0 0 1\"/></joint>",
            i - 1
        ));
    }
    xml.push_str("</robot>");
    let (_, _, message) = robot_file_error(DynChain::from_urdf_str(&xml, &UrdfOptions::default()));
    assert!(message.contains("MAX_DOF"), "{message}");
    // A description (saved model) with too many joints, before anything is built.
    let mut d = SerialChain::puma560().to_dyn().description();
    let j = d.joints[0].clone();
    d.joints = vec![j; 8000];
    d.dh = None;
    assert!(matches!(
        DynChain::from_description(&d),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}

#[test]
fn nan_or_zero_quaternions_are_refused() {
    let with_quat = |version: &str, quat: &str| {
        format!(
            r#"<robot name="q" version="{version}"><link name="a"/><link name="b"/>
               <joint name="j" type="revolute"><parent link="a"/><child link="b"/>
               <origin xyz="0 0 0.1" quat_xyzw="{quat}"/><axis xyz="0 0 1"/>
               <limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#
        )
    };
    for bad in ["nan nan nan nan", "0 0 0 0", "inf 0 0 1", "0 0 NaN 1"] {
        let (_, element, message) = robot_file_error(DynChain::from_urdf_str(
            &with_quat("1.1", bad),
            &UrdfOptions::default(),
        ));
        assert_eq!(element, "joint[j]/origin/quat_xyzw", "{bad}");
        assert!(message.contains("not a rotation"), "{bad}: {message}");
    }
    // A unit quaternion reads, as the rotation it is (90° about z).
    let chain = DynChain::from_urdf_str(
        &with_quat("1.1", "0 0 0.7071067811865476 0.7071067811865476"),
        &UrdfOptions::default(),
    )
    .unwrap();
    let r = chain.joints()[0].placement.rotation;
    assert!((r.angle() - FRAC_PI_2).abs() < 1e-12);
    // URDF 1.0 ignores quat_xyzw, as urdfdom does.
    assert!(DynChain::from_urdf_str(
        &with_quat("1.0", "nan nan nan nan"),
        &UrdfOptions::default()
    )
    .is_ok());
    // Non-finite xyz and rpy are named too.
    let inf_xyz = with_quat("1.1", "0 0 0 1").replace("xyz=\"0 0 0.1\"", "xyz=\"inf 0 0\"");
    assert_error_names(
        DynChain::from_urdf_str(&inf_xyz, &UrdfOptions::default()),
        &["joint[j]/origin/xyz", "\"inf 0 0\""],
    );
}

#[test]
fn to_urdf_refuses_what_it_cannot_write() {
    // A placement that would overflow when composed with the previous link frame is
    // refused when the chain is built (MAX_ROBOT_SIZE), before there is a file to write.
    let mut a = Joint::new(JointType::Revolute, Isometry3::identity(), Vector3::z());
    a.link_frame = Isometry3::translation(1.5e308, 0.0, 0.0);
    let b = Joint::new(
        JointType::Revolute,
        Isometry3::translation(1.5e308, 0.0, 0.0),
        Vector3::z(),
    );
    let err = DynChain::from_joints(vec![a, b]).unwrap_err();
    assert!(matches!(err, PrrrpError::InvalidParameter { .. }), "{err}");
    assert!(err.to_string().contains("MAX_ROBOT_SIZE"), "{err}");

    // A centre of mass at infinity: a subnormal mass with a first moment.
    let puma = SerialChain::puma560().to_dyn();
    let mut p = puma.inertial().to_vec();
    p[2] = [1e-310, 1.0, 0.0, 0.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.1];
    let err = puma.with_inertial(p).unwrap().to_urdf(None).unwrap_err();
    assert!(err.to_string().contains("link 3"), "{err}");
}

#[test]
fn to_urdf_names_round_trip_or_are_refused() {
    let puma = SerialChain::puma560().to_dyn();
    let mut meta = puma.meta().clone();
    let names = [
        "a&b",
        "<shoulder>",
        "quote\"d",
        "apos'trophe",
        "tab\there",
        "new\nline",
        "ünïcödé",
    ];
    for (i, name) in names.iter().take(6).enumerate() {
        meta.links[i] = format!("link {name}");
        meta.joints[i].name = format!("joint {name}");
    }
    meta.base_link = names[6].into();
    meta.name = "robot & <co>".into();
    let chain = puma.clone().with_meta(meta.clone()).unwrap();
    let back =
        DynChain::from_urdf_str(&chain.to_urdf(None).unwrap(), &UrdfOptions::default()).unwrap();
    assert_eq!(back.meta().links, meta.links);
    assert_eq!(back.joint_names(), chain.joint_names());
    assert_eq!(back.meta().base_link, meta.base_link);
    assert_eq!(back.meta().name, meta.name);
    // What XML cannot hold, or URDF cannot tell apart, is an error, not a broken file.
    let mut bad = meta.clone();
    bad.links[1] = "bell\u{7}".into();
    let err = puma
        .clone()
        .with_meta(bad)
        .unwrap()
        .to_urdf(None)
        .unwrap_err();
    assert!(err.to_string().contains("meta.links[1]"), "{err}");
    let mut dup = meta.clone();
    dup.links[4] = dup.links[2].clone();
    let err = puma
        .clone()
        .with_meta(dup)
        .unwrap()
        .to_urdf(None)
        .unwrap_err();
    assert!(err.to_string().contains("unique"), "{err}");
    let mut empty = meta;
    empty.joints[0].name = String::new();
    assert!(puma.with_meta(empty).unwrap().to_urdf(None).is_err());
}

#[test]
fn whole_file_errors_name_no_element() {
    let shown = DynChain::from_file("robot.xml", &UrdfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        shown.starts_with("robot file robot.xml: unknown"),
        "{shown}"
    );
    assert!(!shown.contains("`file`"), "{shown}");
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        /// Whatever the names and however far the links reach, `to_urdf` writes a file
        /// that reads back to the same names and placements, or refuses with a typed error.
        #[test]
        fn to_urdf_reads_back_or_refuses(
            link in ".{0,10}",
            joint in ".{0,10}",
            reach in prop_oneof![-1e3..1e3f64, Just(1e154), Just(-1.5e308), Just(1.5e308)],
            mass in prop_oneof![0.1..10.0f64, Just(0.0), Just(1e-310)],
        ) {
            let puma = SerialChain::puma560().to_dyn();
            let mut meta = puma.meta().clone();
            meta.links[3] = link.clone();
            meta.joints[1].name = joint.clone();
            let mut joints = puma.joints().to_vec();
            joints[4].placement.translation.vector.x = reach;
            let mut inertial = puma.inertial().to_vec();
            inertial[5] = [mass, 0.01, 0.0, 0.0, 0.1, 0.0, 0.1, 0.0, 0.0, 0.1];
            // Reaches past MAX_ROBOT_SIZE are refused when the chain is built.
            let built = DynChain::from_joints(joints);
            if reach.abs() > prrrp_core::bounds::MAX_ROBOT_SIZE {
                let e = built.expect_err("a 1e154 m reach is refused");
                prop_assert!(e.to_string().contains("MAX_ROBOT_SIZE"), "{e}");
                return Ok(());
            }
            let chain = built
                .unwrap()
                .with_inertial(inertial)
                .unwrap()
                .with_meta(meta)
                .unwrap();
            match chain.to_urdf(None) {
                Ok(xml) => {
                    let back = DynChain::from_urdf_str(&xml, &UrdfOptions::default()).unwrap();
                    prop_assert_eq!(&back.meta().links, &chain.meta().links);
                    prop_assert_eq!(back.joint_names(), chain.joint_names());
                    // Same dynamics (placements are re-expressed for standard DH).
                    let (q, qd, qdd) = ([0.3, -0.2, 0.5, 0.1, -0.4, 0.2], [0.5; 6], [-1.0; 6]);
                    let want = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
                    let got = back.inverse_dynamics(&q, &qd, &qdd).unwrap();
                    // (A 1e154 m reach overflows the dynamics themselves.)
                    prop_assume!(want.iter().all(|t| t.is_finite()));
                    let scale = want.iter().fold(1.0f64, |m, t| m.max(t.abs()));
                    for (g, w) in got.iter().zip(&want) {
                        prop_assert!((g - w).abs() <= 1e-9 * scale, "{got:?} vs {want:?}");
                    }
                }
                Err(e) => prop_assert!(matches!(e, PrrrpError::InvalidParameter { .. }), "{e}"),
            }
        }

        /// Any quaternion: a finite, non-zero one is read as its rotation, any other is a
        /// typed error naming it.
        #[test]
        fn urdf_quaternions(
            q in prop::array::uniform4(prop_oneof![
                -2.0..2.0f64, Just(0.0), Just(f64::NAN), Just(f64::INFINITY), Just(1e300)
            ]),
        ) {
            let text = format!("{} {} {} {}", q[0], q[1], q[2], q[3]);
            let xml = format!(
                r#"<robot name="q" version="1.1"><link name="a"/><link name="b"/>
                   <joint name="j" type="continuous"><parent link="a"/><child link="b"/>
                   <origin quat_xyzw="{text}"/><axis xyz="0 0 1"/></joint></robot>"#
            );
            let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            match DynChain::from_urdf_str(&xml, &UrdfOptions::default()) {
                Ok(chain) => {
                    prop_assert!(norm.is_finite() && norm > 1e-6, "{text} accepted");
                    let r = chain.joints()[0].placement.rotation;
                    let want = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                        q[3], q[0], q[1], q[2],
                    ));
                    prop_assert!(r.angle_to(&want) < 1e-9, "{text}: {r:?}");
                }
                Err(PrrrpError::RobotFile { element, .. }) => {
                    prop_assert!(!(norm.is_finite() && norm > 1e-6), "{text} refused");
                    prop_assert_eq!(element, "joint[j]/origin/quat_xyzw");
                }
                Err(e) => prop_assert!(false, "{e:?}"),
            }
        }
    }
}

/// Lengths and inertias beyond any arm (a damaged file) are refused with the value's
/// name, at MAX_ROBOT_SIZE (1e6 m) and MAX_INERTIAL (1e12 kg, kg·m²): a 1e299 kg link
/// simulated torques of 1e299 N·m, and a DH length of 1e300 m gave "'base parameters' has
/// shape 0". A file in grams and millimetres still reads.
#[test]
fn sizes_beyond_any_arm_are_refused() {
    let shown = |r: Result<DynChain, PrrrpError>| match r {
        Err(e) => e.to_string(),
        Ok(_) => panic!("expected an error, got a chain"),
    };
    let toml = panda_toml();
    for (from, to, needles) in [
        ("a = 0.0825", "a = 1e300", ["dh[3].a", "MAX_ROBOT_SIZE"]),
        ("d = 0.316", "d = -2e6", ["dh[2].d", "MAX_ROBOT_SIZE"]),
        (
            "inertial = [7, ",
            "inertial = [1e299, ",
            ["inertial[0][0]", "MAX_INERTIAL"],
        ),
    ] {
        let bad = toml.replacen(from, to, 1);
        assert_ne!(bad, toml, "`{from}` not in the file");
        let text = shown(DynChain::from_toml_str(&bad));
        for n in needles {
            assert!(text.contains(n), "`{n}` not in: {text}");
        }
    }
    let urdf = three_joint_text();
    for (from, to, bound) in [
        (
            "<mass value=\"1.8\"/>",
            "<mass value=\"1e299\"/>",
            "MAX_INERTIAL",
        ),
        (
            "<origin xyz=\"0.4 0.02 -0.01\"",
            "<origin xyz=\"0.4 0.02 -3e6\"",
            "MAX_ROBOT_SIZE",
        ),
    ] {
        let bad = urdf.replacen(from, to, 1);
        assert_ne!(bad, urdf, "`{from}` not in the fixture");
        let text = shown(DynChain::from_urdf_str(&bad, &tip("link3")));
        assert!(text.contains(bound), "{text}");
    }
    // A large but real arm (a 2 t gantry link 40 m out) still loads.
    let big = urdf
        .replacen("<mass value=\"1.8\"/>", "<mass value=\"2000\"/>", 1)
        .replacen(
            "<origin xyz=\"0.4 0.02 -0.01\"",
            "<origin xyz=\"40 0.02 -0.01\"",
            1,
        );
    assert!(DynChain::from_urdf_str(&big, &tip("link3")).is_ok());
    // So do its inertials in grams and millimetres (m ×1e3, m·c ×1e6, inertias ×1e9).
    let chain = DynChain::from_urdf_str(&urdf, &tip("link3")).unwrap();
    let grams: Vec<[f64; 10]> = chain
        .inertial()
        .iter()
        .map(|p| {
            let mut p = *p;
            p[0] *= 1e3;
            p[1..4].iter_mut().for_each(|v| *v *= 1e6);
            p[4..].iter_mut().for_each(|v| *v *= 1e9);
            p
        })
        .collect();
    assert!(chain.with_inertial(grams).is_ok());
}
