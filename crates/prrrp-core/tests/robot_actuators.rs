//! Robot files with actuators (issue 26): TOML files that take their links from a URDF and
//! declare `[actuators]`, URDF `<transmission>` elements (ROS 1, ros2_control, Drake's
//! rotor inertia), and URDF export of the armature — the expected coupling matrices written
//! out by hand from the transmission formulas.

use prrrp_core::{Actuators, DynChain, UrdfOptions};

mod files_support;
use files_support::{three_joint_text, tip};

/// A fresh folder under the target directory (no temp-file crate needed).
fn folder(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "prrrp-robot-actuators-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The three-joint URDF with `extra` inserted before `</robot>`.
fn with_elements(extra: &str) -> String {
    three_joint_text().replace("</robot>", &format!("{extra}\n</robot>"))
}

/// The three-joint coupling whose last motor also turns with joint 2 (factor `c`): motor
/// velocities = C·q̇ with C the identity plus C[2][1] = c.
fn wrist_coupling(c: f64) -> Vec<Vec<f64>> {
    vec![vec![1.0, 0.0, 0.0], vec![0.0, 1.0, 0.0], vec![0.0, c, 1.0]]
}

/// Declares Drake's namespace on `<robot>`, as Drake's own URDFs do.
fn drake_namespace(xml: &str) -> String {
    xml.replacen("<robot ", "<robot xmlns:drake=\"http://drake.mit.edu\" ", 1)
}

#[test]
fn toml_takes_links_from_a_urdf_and_declares_actuators() {
    let dir = folder("toml");
    std::fs::write(dir.join("arm.urdf"), three_joint_text()).unwrap();
    let toml = r#"
        name = "geared"
        urdf = "arm.urdf"
        tip = "link3"
        [actuators]
        armature = true
        coupling = [[1, 0, 0], [0, 1, 0], [0, 1, 1]]
        armature_values = [0.5, 0.1, 0.02]
        gear_ratios = [100, 80, 50]
        friction = [[1.0, 2.0, 0.1], [0.5, 0.6, 0.0], [0.2, 0.3, -0.1]]
    "#;
    std::fs::write(dir.join("arm.toml"), toml).unwrap();
    let chain = DynChain::from_file(dir.join("arm.toml"), &UrdfOptions::default()).unwrap();
    let urdf = DynChain::from_urdf_file(dir.join("arm.urdf"), &tip("link3")).unwrap();
    assert_eq!(chain.meta().name, "geared");
    assert_eq!(chain.joints(), urdf.joints());
    assert_eq!(chain.inertial(), urdf.inertial());
    let act = chain.actuators();
    assert_eq!(
        act.coupling,
        Some(vec![
            vec![1.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0],
            vec![0.0, 1.0, 1.0]
        ])
    );
    assert!(act.armature);
    assert_eq!(act.armature_values, Some(vec![0.5, 0.1, 0.02]));
    assert_eq!(act.gear_ratios, Some(vec![100.0, 80.0, 50.0]));
    assert_eq!(chain.friction_params()[2], [0.2, 0.3, -0.1]);
    assert_eq!(chain.num_params(), 3 * (10 + 4));
    // The command line's --tip overrides the file's.
    let short = DynChain::from_file(dir.join("arm.toml"), &tip("link2"));
    assert!(
        short.is_err(),
        "a 3×3 coupling on a 2-joint chain is refused"
    );
    let e = short.unwrap_err().to_string();
    assert!(e.contains("actuators"), "{e}");
}

#[test]
fn toml_actuator_mistakes_are_clear_errors() {
    let dir = folder("toml-errors");
    std::fs::write(dir.join("arm.urdf"), three_joint_text()).unwrap();
    let cases = [
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\nconvention = \"standard\"\n",
            "exclusive",
        ),
        ("urdf = \"missing.urdf\"\ntip = \"link3\"\n", "not a file"),
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\n[actuators]\nrotor = true\n",
            "unknown key `rotor`",
        ),
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\n[actuators]\narmature_values = [1, 2, 3]\n",
            "armature = true",
        ),
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\n[actuators]\narmature = true\n\
             armature_values = [1, 2]\n",
            "actuators.armature_values",
        ),
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\n[actuators]\ngear_ratios = [1, 0, 2]\n",
            "gear_ratios[1]",
        ),
        (
            "urdf = \"arm.urdf\"\ntip = \"link3\"\nsurprise = 1\n",
            "unknown key `surprise`",
        ),
    ];
    for (k, (text, want)) in cases.iter().enumerate() {
        let path = dir.join(format!("case{k}.toml"));
        std::fs::write(&path, text).unwrap();
        let e = DynChain::from_file(&path, &UrdfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "case {k}: {e}");
        assert!(e.contains(&format!("case{k}.toml")), "names the file: {e}");
    }
    // `tip` without `urdf`, in a DH table.
    let e = DynChain::from_toml_str(
        "convention = \"standard\"\ntip = \"x\"\n[[joint]]\ntype = \"revolute\"\n\
         a = 1\nalpha = 0\nd = 0\ntheta = 0\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("needs `urdf"), "{e}");
}

#[test]
fn simple_transmissions_give_gear_ratios_and_rotor_inertias() {
    // ROS 1 transmissions with Drake's rotor inertia on the shoulder: Ia = J·r².
    let xml = drake_namespace(&with_elements(
        r#"
  <transmission name="t1">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>EffortJointInterface</hardwareInterface></joint>
    <actuator name="m1">
      <mechanicalReduction>100</mechanicalReduction>
      <drake:rotor_inertia value="2e-4"/>
    </actuator>
  </transmission>
  <transmission name="t2">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="elbow"/>
    <actuator name="m2"><mechanicalReduction>-50</mechanicalReduction></actuator>
  </transmission>
  <transmission name="t3">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="slide"/>
    <actuator name="m3"><mechanicalReduction>20</mechanicalReduction></actuator>
  </transmission>
  <transmission name="fingers">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="finger_left_joint"/>
    <actuator name="m4"><mechanicalReduction>7</mechanicalReduction></actuator>
  </transmission>"#,
    ));
    let chain = DynChain::from_urdf_str(&xml, &tip("link3")).unwrap();
    let act = chain.actuators();
    // A negative reduction flips the motor: C keeps +1 on the diagonal only up to sign.
    assert_eq!(
        act.coupling, None,
        "every row is a single reduction: C = I up to the ratio's sign"
    );
    assert_eq!(act.gear_ratios, Some(vec![100.0, -50.0, 20.0]));
    assert!(act.armature);
    let ia = act.armature_values.clone().unwrap();
    assert!((ia[0] - 2e-4 * 100.0 * 100.0).abs() < 1e-12 && ia[1] == 0.0 && ia[2] == 0.0);
    // Without transmissions nothing changes.
    let plain = DynChain::from_urdf_str(&three_joint_text(), &tip("link3")).unwrap();
    assert_eq!(plain.actuators(), &Actuators::default());
}

#[test]
fn differential_and_four_bar_transmissions_couple_the_joints() {
    // ros2_control format (inside <ros2_control>, <plugin>, roles, joint-side reductions):
    // θ̇1 = na1·(nj1·q̇1 + nj2·q̇2), θ̇2 = na2·(nj1·q̇1 − nj2·q̇2).
    let (na1, na2, nj1, nj2): (f64, f64, f64, f64) = (40.0, -30.0, 2.0, 1.5);
    let xml = with_elements(&format!(
        r#"
  <ros2_control name="arm" type="system">
    <transmission name="wrist">
      <plugin>transmission_interface/DifferentialTransmission</plugin>
      <actuator name="mb" role="actuator2"><mechanical_reduction>{na2}</mechanical_reduction></actuator>
      <actuator name="ma" role="actuator1"><mechanical_reduction>{na1}</mechanical_reduction></actuator>
      <joint name="elbow" role="joint1"><mechanical_reduction>{nj1}</mechanical_reduction></joint>
      <joint name="slide" role="joint2"><mechanical_reduction>{nj2}</mechanical_reduction></joint>
    </transmission>
  </ros2_control>"#
    ));
    let chain = DynChain::from_urdf_str(&xml, &tip("link3")).unwrap();
    let act = chain.actuators();
    let g = [[na1 * nj1, na1 * nj2], [na2 * nj1, -na2 * nj2]];
    let c = act.coupling.clone().expect("coupled");
    // Row m of G is rₘ times row m of C, each row of C with largest entry 1.
    for (m, row) in g.iter().enumerate() {
        let big = if row[0].abs() >= row[1].abs() {
            row[0]
        } else {
            row[1]
        };
        assert!((c[m + 1][1] - row[0] / big).abs() < 1e-15);
        assert!((c[m + 1][2] - row[1] / big).abs() < 1e-15);
        assert_eq!(c[m + 1][0], 0.0);
    }
    assert_eq!(c[0], vec![1.0, 0.0, 0.0]);
    // The shoulder has no transmission: no complete set of gear ratios.
    assert_eq!(act.gear_ratios, None);

    // Four-bar: θ̇1 = nj1·na1·q̇1, θ̇2 = na2·(q̇1 + nj2·q̇2); ROS 1 format with <role>.
    let xml = with_elements(
        r#"
  <transmission name="fb">
    <type>transmission_interface/FourBarLinkageTransmission</type>
    <actuator name="a1"><role>actuator1</role><mechanicalReduction>10</mechanicalReduction></actuator>
    <actuator name="a2"><role>actuator2</role><mechanicalReduction>5</mechanicalReduction></actuator>
    <joint name="shoulder"><role>joint1</role><mechanicalReduction>2</mechanicalReduction></joint>
    <joint name="elbow"><role>joint2</role><mechanicalReduction>4</mechanicalReduction></joint>
  </transmission>"#,
    );
    let c = DynChain::from_urdf_str(&xml, &tip("link3"))
        .unwrap()
        .actuators()
        .coupling
        .clone()
        .unwrap();
    assert_eq!(c[0], vec![1.0, 0.0, 0.0]);
    assert_eq!(c[1], vec![5.0 / 20.0, 1.0, 0.0]);
    assert_eq!(c[2], vec![0.0, 0.0, 1.0]);

    // A differential that makes the two motors equal is refused with the file named.
    let xml = with_elements(
        r#"
  <transmission name="bad">
    <type>transmission_interface/DifferentialTransmission</type>
    <actuator name="a1"><mechanicalReduction>1</mechanicalReduction></actuator>
    <actuator name="a2"><mechanicalReduction>1</mechanicalReduction></actuator>
    <joint name="elbow"><mechanicalReduction>1</mechanicalReduction></joint>
    <joint name="slide"><mechanicalReduction>0</mechanicalReduction></joint>
  </transmission>"#,
    );
    let e = DynChain::from_urdf_str(&xml, &tip("link3"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("transmission[bad]") && e.contains("reduction of 0"),
        "{e}"
    );
}

#[test]
fn urdf_export_writes_the_armature_and_reads_it_back() {
    let chain = DynChain::from_urdf_str(&three_joint_text(), &tip("link3"))
        .unwrap()
        .with_actuators(Actuators {
            armature: true,
            armature_values: Some(vec![0.9, 0.25, 0.04]),
            gear_ratios: Some(vec![120.0, 80.0, 30.0]),
            ..Actuators::default()
        })
        .unwrap();
    let xml = chain.to_urdf(None).unwrap();
    assert!(xml.contains("xmlns:drake"), "declares the namespace");
    let back = DynChain::from_urdf_str(&xml, &tip("link3")).unwrap();
    let (a, b) = (chain.actuators(), back.actuators());
    assert_eq!(a.gear_ratios, b.gear_ratios);
    assert!(b.armature);
    for (x, y) in a
        .armature_values
        .as_ref()
        .unwrap()
        .iter()
        .zip(b.armature_values.as_ref().unwrap())
    {
        assert!((x - y).abs() < 1e-12 * x, "{x} vs {y}");
    }
    // New standard parameters (e.g. identified ones) carry their own Ia.
    let mut pi = chain.parameters();
    let names = chain.parameter_names();
    let k = names.iter().position(|s| s == "Ia2").unwrap();
    pi[k] = 0.5;
    let back = DynChain::from_urdf_str(&chain.to_urdf(Some(&pi)).unwrap(), &tip("link3")).unwrap();
    assert!((back.armature_values()[1] - 0.5).abs() < 1e-12);
    // A coupled chain's URDF says where the coupling went.
    let coupled = chain
        .clone()
        .with_actuators(Actuators {
            coupling: Some(wrist_coupling(1.0)),
            ..chain.actuators().clone()
        })
        .unwrap();
    let xml = coupled.to_urdf(None).unwrap();
    assert!(xml.contains("TOML robot file keeps them"));
    assert!(DynChain::from_urdf_str(&xml, &tip("link3")).is_ok());
}

#[test]
fn toml_with_urdf_round_trips_a_coupled_chain() {
    let chain = DynChain::from_urdf_str(&three_joint_text(), &tip("link3"))
        .unwrap()
        .with_friction(
            prrrp_core::FrictionModel {
                coulomb_smoothing: 0.03,
                ..prrrp_core::FrictionModel::all()
            },
            vec![[1.0, 2.0, 0.1], [0.5, 0.6, 0.0], [0.2, 0.3, -0.1]],
        )
        .unwrap()
        .with_actuators(Actuators {
            coupling: Some(wrist_coupling(0.5)),
            armature: true,
            armature_values: Some(vec![0.7, 0.2, 0.05]),
            gear_ratios: Some(vec![100.0, 60.0, 30.0]),
        })
        .unwrap();
    let dir = folder("round-trip");
    std::fs::write(dir.join("robot.urdf"), chain.to_urdf(None).unwrap()).unwrap();
    let toml = chain.to_toml_with_urdf("robot.urdf", None).unwrap();
    std::fs::write(dir.join("robot.toml"), &toml).unwrap();
    let back = DynChain::from_file(dir.join("robot.toml"), &UrdfOptions::default()).unwrap();
    assert_eq!(back.actuators(), chain.actuators(), "{toml}");
    assert_eq!(back.friction(), chain.friction());
    assert_eq!(back.friction_params(), chain.friction_params());
    for k in 0..5 {
        let x = 0.3 * k as f64;
        let (q, qd, qdd) = ([x, -x, 0.1 * x], [0.4, -0.7 + x, 0.2], [1.0, x, -0.5]);
        let a = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
        let b = back.inverse_dynamics(&q, &qd, &qdd).unwrap();
        for j in 0..3 {
            assert!(
                (a[j] - b[j]).abs() < 1e-10 * a[j].abs().max(1.0),
                "{a:?} vs {b:?}"
            );
        }
    }
}
