//! The actuator model (issue 26): coupled actuators with rotor inertias and friction on the
//! actuator velocities, τ = M·q̈ + C·q̇ + G + Cᵀ·(diag(Ia)·C·q̈ + f(C·q̇)), checked against
//! physics written out here: the power balance of the energy (finite differences in time),
//! the kinetic energy of the rotors, columns built by hand from the rigid regressor, and
//! the base-parameter rank of that hand-built matrix.

mod dyn_support;
mod seeded_support;

use dyn_support::{coupling, with_smoothed_friction};
use nalgebra::{DMatrix, DVector};
use prrrp_core::{Actuators, BaseOptions, DynChain, PrrrpError, SerialChain};

/// C of a six-axis arm whose sixth motor turns with q̇5 + q̇6 and whose fifth turns with
/// q̇5 − 0.3·q̇4 (a second, asymmetric coupling so that Cᵀ ≠ C matters).
fn wrist_coupling() -> Vec<Vec<f64>> {
    coupling(6, &[(5, 4, 1.0), (4, 3, -0.3)])
}

/// Reflected rotor inertias of an industrial six-axis arm (kg·m², joint side).
const ARMATURE: [f64; 6] = [1.2, 1.5, 0.6, 0.08, 0.06, 0.04];
const FRICTION: [[f64; 3]; 6] = [
    [8.0, 6.0, 0.5],
    [9.0, 7.0, -0.4],
    [4.0, 3.0, 0.2],
    [0.8, 0.9, 0.05],
    [0.7, 0.6, -0.03],
    [0.5, 0.5, 0.02],
];
const SMOOTHING: f64 = 0.02;

fn coupled_puma(coupling: Option<Vec<Vec<f64>>>) -> DynChain {
    let puma = SerialChain::puma560().to_dyn();
    with_smoothed_friction(puma, SMOOTHING, FRICTION.to_vec())
        .with_actuators(Actuators {
            coupling,
            armature: true,
            armature_values: Some(ARMATURE.to_vec()),
            gear_ratios: None,
        })
        .unwrap()
}

/// A smooth trajectory q(t) with its exact derivatives.
fn trajectory(t: f64) -> [Vec<f64>; 3] {
    let (mut q, mut qd, mut qdd) = (vec![], vec![], vec![]);
    for j in 0..6 {
        let (w1, w2, p) = (0.9 + 0.37 * j as f64, 2.3 - 0.21 * j as f64, 0.4 * j as f64);
        q.push(0.8 * (w1 * t + p).sin() + 0.3 * (w2 * t).cos());
        qd.push(0.8 * w1 * (w1 * t + p).cos() - 0.3 * w2 * (w2 * t).sin());
        qdd.push(-0.8 * w1 * w1 * (w1 * t + p).sin() - 0.3 * w2 * w2 * (w2 * t).cos());
    }
    [q, qd, qdd]
}

fn mat(rows: &[Vec<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(rows.len(), rows.len(), |i, j| rows[i][j])
}

/// The PUMA with the wrist coupling, the rigid PUMA alone (no actuators), and the
/// coupling matrix C.
fn coupled_and_rigid() -> (DynChain, DynChain, DMatrix<f64>) {
    let c = wrist_coupling();
    let chain = coupled_puma(Some(c.clone()));
    (chain, SerialChain::puma560().to_dyn(), mat(&c))
}

#[test]
fn regressor_is_the_power_balance_of_the_energy() {
    // Lagrange: q̇ᵀτ = dE/dt + q̇ᵀ·Cᵀ·f(C·q̇) with E = T_links + T_rotors + V. The links'
    // kinetic energy comes from the rigid chain (M checked against Pinocchio elsewhere),
    // the rotors' from ½·Σ Iaₘ·(C·q̇)ₘ² written out here; the potential's rate is q̇ᵀ·G.
    let (chain, rigid, cm) = coupled_and_rigid();
    let energy = |t: f64| {
        let [q, qd, _] = trajectory(t);
        let m = rigid.mass_matrix(&q).unwrap();
        let v = DVector::from_vec(qd.clone());
        let vm = &cm * &v;
        let rotors: f64 = (0..6).map(|k| 0.5 * ARMATURE[k] * vm[k] * vm[k]).sum();
        0.5 * v.dot(&(m * &v)) + rotors
    };
    let pi = DVector::from_vec(chain.parameters());
    let h = 1e-4;
    for &t in &[0.1, 0.77, 1.9, 3.3] {
        let [q, qd, qdd] = trajectory(t);
        let tau = chain.regressor(&q, &qd, &qdd).unwrap() * &pi;
        let v = DVector::from_vec(qd.clone());
        let vm = &cm * &v;
        let friction_power: f64 = (0..6)
            .map(|m| {
                let [fv, fc, fo] = FRICTION[m];
                vm[m] * (fv * vm[m] + fc * (vm[m] / SMOOTHING).tanh() + fo)
            })
            .sum();
        let g = DVector::from_vec(rigid.gravity_torques(&q).unwrap());
        let de_dt = (energy(t + h) - energy(t - h)) / (2.0 * h) + v.dot(&g);
        let power = v.dot(&tau);
        let scale = power.abs().max(1.0);
        assert!(
            (power - de_dt - friction_power).abs() < 1e-6 * scale,
            "t = {t}: q̇ᵀτ = {power}, dE/dt + friction = {}",
            de_dt + friction_power
        );
        // Inverse dynamics (Newton–Euler plus the actuator terms) is the same τ.
        let rnea = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
        for j in 0..6 {
            assert!((rnea[j] - tau[j]).abs() < 1e-9 * scale);
        }
    }
}

#[test]
fn mass_matrix_gains_the_reflected_rotor_inertia_and_forward_inverts_inverse() {
    let (chain, rigid, cm) = coupled_and_rigid();
    let ia = DMatrix::from_diagonal(&DVector::from_row_slice(&ARMATURE));
    let want_extra = cm.transpose() * ia * &cm;
    for &t in &[0.3, 1.4] {
        let [q, qd, qdd] = trajectory(t);
        let m = chain.mass_matrix(&q).unwrap();
        let extra = m.clone() - rigid.mass_matrix(&q).unwrap();
        assert!((extra - &want_extra).amax() < 1e-12);
        assert!(m.clone().cholesky().is_some(), "M + CᵀIaC is SPD");
        let tau = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
        let back = chain.forward_dynamics(&q, &qd, &tau).unwrap();
        for j in 0..6 {
            assert!((back[j] - qdd[j]).abs() < 1e-9, "{back:?} vs {qdd:?}");
        }
        // The compile-time chain runs the same kernels.
        let fixed = chain.to_fixed::<6>().unwrap();
        let sv = |v: &[f64]| nalgebra::SVector::<f64, 6>::from_column_slice(v);
        let tau6 = fixed.inverse_dynamics(&sv(&q), &sv(&qd), &sv(&qdd));
        for j in 0..6 {
            assert!((tau6[j] - tau[j]).abs() < 1e-10 * tau[j].abs().max(1.0));
        }
        assert_eq!(fixed.actuators(), chain.actuators().clone());
    }
}

/// The full observation matrix built by hand: the rigid chain's 10·n columns, then per
/// actuator m the columns Cᵀeₘ·[vₘ, tanh(vₘ/v_s), 1, aₘ] with v = C·q̇, a = C·q̈.
fn hand_built(c: &DMatrix<f64>, states: &[[Vec<f64>; 3]]) -> DMatrix<f64> {
    let rigid = SerialChain::puma560().to_dyn();
    let n = 6;
    let p = 10 * n + 4 * n;
    let mut w = DMatrix::zeros(n * states.len(), p);
    for (k, [q, qd, qdd]) in states.iter().enumerate() {
        let y = rigid.regressor(q, qd, qdd).unwrap();
        w.view_mut((n * k, 0), (n, 10 * n)).copy_from(&y);
        let v = c * DVector::from_column_slice(qd);
        let a = c * DVector::from_column_slice(qdd);
        for m in 0..n {
            let feat = [v[m], (v[m] / SMOOTHING).tanh(), 1.0, a[m]];
            for (s, f) in feat.iter().enumerate() {
                for j in 0..n {
                    w[(n * k + j, 10 * n + 4 * m + s)] = c[(m, j)] * f;
                }
            }
        }
    }
    w
}

fn random_states(seed: u64, count: usize) -> Vec<[Vec<f64>; 3]> {
    let mut u = seeded_support::lcg(seed);
    let mut next = || u() * 2.0 - 1.0;
    (0..count)
        .map(|_| {
            let mut s = || (0..6).map(|_| 2.0 * next()).collect::<Vec<_>>();
            [s(), s(), s()]
        })
        .collect()
}

/// Numerical rank of a matrix with unit-norm columns (zero columns dropped).
fn rank(w: &DMatrix<f64>) -> usize {
    let cols: Vec<usize> = (0..w.ncols())
        .filter(|&j| w.column(j).norm() > 1e-12)
        .collect();
    let s = DMatrix::from_fn(w.nrows(), cols.len(), |i, c| {
        w[(i, cols[c])] / w.column(cols[c]).norm()
    });
    let sv = s.singular_values();
    let top = sv.max();
    sv.iter().filter(|&&x| x > 1e-9 * top).count()
}

#[test]
fn base_parameters_with_coupling_match_a_hand_built_regressor() {
    for coupling in [None, Some(wrist_coupling())] {
        let chain = coupled_puma(coupling.clone());
        let c = mat(&coupling.clone().unwrap_or_else(|| {
            (0..6)
                .map(|i| (0..6).map(|j| f64::from(u8::from(i == j))).collect())
                .collect()
        }));
        let states = random_states(7, 60);
        let w_hand = hand_built(&c, &states);
        let (q, qd, qdd): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            states.iter().flat_map(|s| s[0].clone()).collect(),
            states.iter().flat_map(|s| s[1].clone()).collect(),
            states.iter().flat_map(|s| s[2].clone()).collect(),
        );
        let w = chain.observation_matrix(&q, &qd, &qdd).unwrap();
        let w = DMatrix::from_fn(w.nrows(), w.ncols(), |i, j| w[(i, j)]);
        assert_eq!(w.shape(), w_hand.shape());
        assert!((&w - &w_hand).amax() < 1e-10 * w_hand.amax());

        let base = chain.base_parameters(&BaseOptions::default()).unwrap();
        assert_eq!(base.count(), rank(&w_hand), "coupling {coupling:?}");
        // τ = W_b·β on states the analysis never saw.
        let beta = DVector::from_vec(base.base_values(&chain.parameters()).unwrap());
        let wb = chain.base_observation_matrix(&base, &q, &qd, &qdd).unwrap();
        let wb = DMatrix::from_fn(wb.nrows(), wb.ncols(), |i, j| wb[(i, j)]);
        let tau = &w_hand * DVector::from_vec(chain.parameters());
        assert!((wb * beta - &tau).amax() < 1e-8 * tau.amax());

        // Joint 1 turns about the fixed vertical axis: its rotor is inseparable from link
        // 1's moment about that axis (Iyy1 in the PUMA's DH frame 1). Joint 2's axis is
        // perpendicular to it, so link 2's moment about axis 2 (Izz2) only ever appears as
        // Izz2·q̈2 in joint 2's torque, like the rotor: Khalil's rule, Ia2 joins Izz2. The
        // other rotors are identifiable.
        let names = &base.names;
        for (k, link) in [(1, "Iyy1"), (2, "Izz2")] {
            let ia = names.iter().position(|s| *s == format!("Ia{k}")).unwrap();
            assert!(!base.independent.contains(&ia));
            let with: Vec<&String> = base
                .combinations
                .iter()
                .filter(|s| s.contains(&format!("Ia{k}")))
                .collect();
            assert_eq!(with.len(), 1);
            assert!(with[0].contains(link), "{with:?}");
        }
        for k in 3..=6 {
            let j = names.iter().position(|s| *s == format!("Ia{k}")).unwrap();
            assert!(
                base.independent.contains(&j),
                "Ia{k}: {:?}",
                base.combinations
            );
        }
    }
}

#[test]
fn coupled_friction_moves_two_joints() {
    // Motor 6's viscous friction (q̇5 + q̇6) loads joints 5 and 6 equally; with C = I it
    // loads joint 6 only.
    let chain = coupled_puma(Some(wrist_coupling()));
    let names = chain.parameter_names();
    let fv6 = names.iter().position(|s| s == "fv6").unwrap();
    let q = [0.1; 6];
    let qd = [0.0, 0.0, 0.0, 0.0, 0.4, 0.7];
    let y = chain.regressor(&q, &qd, &[0.0; 6]).unwrap();
    assert!((y[(4, fv6)] - 1.1).abs() < 1e-15 && (y[(5, fv6)] - 1.1).abs() < 1e-15);
    let plain = coupled_puma(None);
    let y = plain.regressor(&q, &qd, &[0.0; 6]).unwrap();
    assert!(y[(4, fv6)] == 0.0 && (y[(5, fv6)] - 0.7).abs() < 1e-15);
}

#[test]
fn bad_couplings_are_clear_errors() {
    let chain = || SerialChain::puma560().to_dyn();
    let with = |c: Vec<Vec<f64>>| {
        chain().with_actuators(Actuators {
            coupling: Some(c),
            ..Actuators::default()
        })
    };
    // Not square.
    let mut c = wrist_coupling();
    c[2].pop();
    let e = with(c).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    assert!(e.to_string().contains("actuators.coupling"), "{e}");
    // Wrong size for the chain.
    assert!(with(vec![vec![1.0]]).is_err());
    // Not finite.
    let mut c = wrist_coupling();
    c[3][1] = f64::INFINITY;
    assert!(with(c).unwrap_err().to_string().contains("coupling[3][1]"));
    // Singular: motor 6 repeats motor 5.
    let mut c = wrist_coupling();
    c[5] = c[4].clone();
    let e = with(c).unwrap_err().to_string();
    assert!(e.contains("singular"), "{e}");
    // The same errors from a TOML robot file, naming the key.
    let toml = |coupling: &str| {
        format!(
            "convention = \"standard\"\n\
             [[joint]]\ntype = \"revolute\"\na = 0.5\nalpha = 0\nd = 0\ntheta = 0\n\
             inertial = [1, 0.2, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1]\n\
             [[joint]]\ntype = \"revolute\"\na = 0.4\nalpha = 0\nd = 0\ntheta = 0\n\
             inertial = [1, 0.2, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1]\n\
             [actuators]\ncoupling = {coupling}\n"
        )
    };
    assert!(DynChain::from_toml_str(&toml("[[1, 0], [1, 1]]")).is_ok());
    for (bad, want) in [
        ("[[1, 0], [1, 1], [0, 1]]", "actuators.coupling"),
        ("[[1, 0], [1]]", "actuators.coupling[1]"),
        ("[[1, 2], [0.5, 1]]", "singular"),
        ("[[1, 0], [0, \"x\"]]", "actuators.coupling[1][1]"),
    ] {
        let e = DynChain::from_toml_str(&toml(bad)).unwrap_err().to_string();
        assert!(e.contains(want), "{bad}: {e}");
    }
    // Armatures and gear ratios beyond any drive: an armature of 1e200 kg·m² was taken,
    // and `prrrp simulate` wrote torques of 1e201 N·m.
    let act = |armature: Option<Vec<f64>>, ratios: Option<Vec<f64>>| {
        chain().with_actuators(Actuators {
            armature: armature.is_some(),
            armature_values: armature,
            gear_ratios: ratios,
            ..Actuators::default()
        })
    };
    let mut ok = vec![0.0, 0.1, 0.1, 0.01, 0.01, 1e6];
    assert!(act(Some(ok.clone()), None).is_ok());
    ok[0] = 1e200;
    let e = act(Some(ok), None).unwrap_err().to_string();
    assert!(
        e.contains("armature_values[0]") && e.contains("MAX_INERTIAL"),
        "{e}"
    );
    assert!(act(None, Some(vec![100.0, -50.0, 1e-6, 1e6, 1.0, 2.0])).is_ok());
    for bad in [1e300, 1e-300, 0.0, f64::NAN] {
        let e = act(None, Some(vec![100.0, 50.0, 20.0, bad, 1.0, 1.0]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("gear_ratios[3]") && e.contains("MAX_FACTOR"),
            "{bad}: {e}"
        );
    }
}

#[test]
fn identified_models_carry_the_actuators_and_version_1_files_load() {
    use prrrp_core::IdentifiedModel;
    let chain = coupled_puma(Some(wrist_coupling()));
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let beta = base.base_values(&chain.parameters()).unwrap();
    let b = beta.len();
    let model = IdentifiedModel::new(
        &chain,
        &base,
        beta.clone(),
        Some(vec![1e-3; b]),
        None,
        Some(10.0),
        vec![0.0; 6],
        "ls",
        serde_json::Value::Null,
        serde_json::Value::Null,
    )
    .unwrap();
    // Motor 6 moves joints 5 and 6; its Ia6 is a base parameter on its own with its σ.
    let a6 = &model.actuators[5];
    assert_eq!(a6.joints, ["joint5", "joint6"]);
    let ia6 = a6.terms.iter().find(|t| t.name == "Ia6").unwrap();
    assert!(ia6.alone);
    assert_eq!((ia6.value, ia6.sigma), (Some(ARMATURE[5]), Some(1e-3)));
    let ia1 = &model.actuators[0].terms[3];
    assert!(!ia1.alone && ia1.combination.as_deref().unwrap().contains("Ia1"));
    let text = model.to_json().unwrap();
    let back = IdentifiedModel::from_json(&text).unwrap();
    let [q, qd, qdd] = trajectory(0.4);
    assert_eq!(
        back.predict(&q, &qd, &qdd).unwrap(),
        model.predict(&q, &qd, &qdd).unwrap()
    );
    let want = chain.inverse_dynamics(&q, &qd, &qdd).unwrap();
    let got = back.predict(&q, &qd, &qdd).unwrap();
    for j in 0..6 {
        assert!((got[j] - want[j]).abs() < 1e-9 * want[j].abs().max(1.0));
    }
    // A version-1 file (no actuators anywhere) still loads and predicts.
    let plain = SerialChain::puma560().to_dyn();
    let base = plain.base_parameters(&BaseOptions::default()).unwrap();
    let beta = base.base_values(&plain.parameters()).unwrap();
    let v2 = IdentifiedModel::new(
        &plain,
        &base,
        beta,
        None,
        None,
        None,
        vec![0.0; 6],
        "ls",
        serde_json::Value::Null,
        serde_json::Value::Null,
    )
    .unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&v2.to_json().unwrap()).unwrap();
    v["schema_version"] = 1.into();
    v["robot"]["schema_version"] = 1.into();
    assert!(v.get("actuators").is_none() && v["robot"].get("actuators").is_none());
    let old = IdentifiedModel::from_json(&v.to_string()).unwrap();
    assert_eq!(
        old.predict(&q, &qd, &qdd).unwrap(),
        v2.predict(&q, &qd, &qdd).unwrap()
    );
}
