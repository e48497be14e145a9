//! An identified model predicts like the robot it describes, on its own after a JSON round
//! trip, and refuses inconsistent parts.

use prrrp_core::{BaseOptions, DynChain, FrictionModel, IdentifiedModel, PrrrpError, SerialChain};

fn puma() -> DynChain {
    SerialChain::puma560()
        .to_dyn()
        .with_friction(FrictionModel::all(), vec![[0.3, 0.8, -0.1]; 6])
        .unwrap()
}

fn exact_model(chain: &DynChain) -> IdentifiedModel {
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let beta = base.base_values(&chain.parameters()).unwrap();
    let b = beta.len();
    IdentifiedModel::new(
        chain,
        &base,
        beta,
        Some(vec![1e-3; b]),
        None,
        Some(12.5),
        vec![0.0; chain.dof()],
        "ls",
        serde_json::json!({"weighted": false}),
        serde_json::json!({"rate_hz": 100.0}),
    )
    .unwrap()
}

fn states(n: usize, samples: usize) -> [Vec<f64>; 3] {
    std::array::from_fn(|s| {
        (0..n * samples)
            .map(|i| (0.37 * i as f64 + 1.3 * s as f64).sin() * (1.0 + s as f64))
            .collect()
    })
}

#[test]
fn predicts_the_inverse_dynamics_also_after_json() {
    let chain = puma();
    let model = exact_model(&chain);
    let [q, qd, qdd] = states(6, 25);
    let tau = model.predict(&q, &qd, &qdd).unwrap();
    for k in 0..25 {
        let r = 6 * k..6 * k + 6;
        let want = chain
            .inverse_dynamics(&q[r.clone()], &qd[r.clone()], &qdd[r.clone()])
            .unwrap();
        for (a, b) in tau[r].iter().zip(&want) {
            assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()), "{a} vs {b}");
        }
    }
    let text = model.to_json().unwrap();
    let back = IdentifiedModel::from_json(&text).unwrap();
    assert_eq!(back.predict(&q, &qd, &qdd).unwrap(), tau);
    assert_eq!(back.beta, model.beta);
    assert_eq!(back.settings["weighted"], false);
    assert!(back.rsd_percent.is_some());
}

#[test]
fn inconsistent_parts_are_typed_errors() {
    let chain = puma();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let make = |beta: Vec<f64>, rms: Vec<f64>| {
        IdentifiedModel::new(
            &chain,
            &base,
            beta,
            None,
            None,
            None,
            rms,
            "ls",
            serde_json::Value::Null,
            serde_json::Value::Null,
        )
    };
    let b = base.count();
    assert!(matches!(
        make(vec![1.0; b - 1], vec![0.0; 6]),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        make(vec![1.0; b], vec![0.0; 5]),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let mut nan = vec![1.0; b];
    nan[3] = f64::NAN;
    assert!(matches!(
        make(nan, vec![0.0; 6]),
        Err(PrrrpError::NonFinite { .. })
    ));
    assert!(IdentifiedModel::from_json("{}").is_err());
    let model = exact_model(&chain);
    let mut v: serde_json::Value = serde_json::from_str(&model.to_json().unwrap()).unwrap();
    v["schema_version"] = 7.into();
    assert!(IdentifiedModel::from_json(&v.to_string()).is_err());
    // A finite negative σ read as "has a NaN or infinite value".
    let mut v: serde_json::Value = serde_json::from_str(&model.to_json().unwrap()).unwrap();
    v["sigma"][2] = (-1.0).into();
    let e = IdentifiedModel::from_json(&v.to_string()).unwrap_err();
    assert!(
        matches!(&e, PrrrpError::InvalidParameter { field, .. } if field == "sigma[2]"),
        "{e}"
    );
    let [q, qd, qdd] = states(6, 2);
    assert!(model.predict(&q[..7], &qd[..7], &qdd[..7]).is_err());
}

#[test]
fn a_model_with_thousands_of_joints_is_refused_when_read() {
    // An 8000-joint model.json aborted `prrrp predict` (allocations of p² values); it must
    // be a typed error when read, before anything of its size is built. The per-joint
    // lists are grown consistently, so only the joint count is wrong.
    let model = exact_model(&puma());
    let mut v: serde_json::Value = serde_json::from_str(&model.to_json().unwrap()).unwrap();
    let grow = |v: &mut serde_json::Value, n: usize| {
        let first = v.as_array().unwrap()[0].clone();
        *v = serde_json::Value::Array(vec![first; n]);
    };
    let n = 8000;
    for key in ["joints", "inertial", "friction_params"] {
        grow(&mut v["robot"][key], n);
    }
    v["robot"]["dh"] = serde_json::Value::Null;
    grow(&mut v["residual_rms"], n);
    match IdentifiedModel::from_json(&v.to_string()) {
        Err(PrrrpError::ShapeMismatch { what, expected, .. }) => {
            assert!(what.contains("joints"), "{what}");
            assert!(expected.contains("MAX_DOF"), "{expected}");
        }
        other => panic!("expected a joint-count error, got {other:?}"),
    }
}
