//! Excitation design for any robot: the PUMA 560 with friction, limits given at run time.
//! The designed trajectory is checked on a grid 50× finer than the search's: it starts and
//! ends at rest, stays within every limit, and is better conditioned than the random
//! shapes it started from; a robot without limits is refused naming the joint.

use prrrp_core::{
    optimise_chain_excitation, BaseOptions, ChainExcitationConfig, DynTrajectory, FrictionModel,
    JointLimit, PrrrpError, SerialChain,
};

fn limits() -> Vec<JointLimit> {
    (0..6)
        .map(|j| JointLimit {
            lower: -1.5 + 0.1 * j as f64,
            upper: 1.2 + 0.05 * j as f64,
            velocity: 1.5,
            acceleration: 4.0,
            effort: f64::NAN,
        })
        .collect()
}

#[test]
fn designed_excitation_is_at_rest_within_limits_and_better_conditioned() {
    let chain = SerialChain::puma560()
        .to_dyn()
        .with_friction(FrictionModel::viscous_coulomb(), vec![[0.0; 3]; 6])
        .unwrap();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let config = ChainExcitationConfig {
        max_evaluations: 600,
        ..Default::default()
    };
    let lim = limits();
    let mut calls = 0;
    let e =
        optimise_chain_excitation(&chain, &base, Some(&lim), &config, |_, _| calls += 1).unwrap();
    assert!(calls > 0);
    assert!(
        e.cond_final.is_finite() && e.cond_final < e.cond_initial,
        "{e:?}"
    );
    let (mut q, mut qd, mut qdd) = ([0.0; 6], [0.0; 6], [0.0; 6]);
    for t in [0.0, e.period] {
        e.trajectory.eval_into(t, &mut q, &mut qd, &mut qdd);
        for j in 0..6 {
            assert!(
                qd[j].abs() < 1e-9 && qdd[j].abs() < 1e-9,
                "not at rest at {t}"
            );
        }
    }
    let points = 50 * 40 * config.harmonics;
    for k in 0..=points {
        let t = e.period * k as f64 / points as f64;
        e.trajectory.eval_into(t, &mut q, &mut qd, &mut qdd);
        for j in 0..6 {
            let l = &lim[j];
            // The search keeps a 5 % margin on its grid; between its points the motion may
            // reach a little further, never past the limit.
            assert!(
                q[j] >= l.lower && q[j] <= l.upper,
                "joint {j} at {t}: {}",
                q[j]
            );
            assert!(qd[j].abs() <= l.velocity, "joint {j} speed {}", qd[j]);
            assert!(
                qdd[j].abs() <= l.acceleration,
                "joint {j} acceleration {}",
                qdd[j]
            );
        }
    }
    // Every joint uses most of its tightest limit (the shapes are scaled to it).
    for u in &e.limit_usage {
        let top = u
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max);
        assert!((0.9..=1.0).contains(&top), "{u:?}");
    }
    // A seed fixes the result.
    let again = optimise_chain_excitation(&chain, &base, Some(&lim), &config, |_, _| {}).unwrap();
    assert_eq!(again.trajectory, e.trajectory);
}

#[test]
fn a_robot_without_limits_is_refused_naming_the_joint() {
    let chain = SerialChain::puma560().to_dyn();
    let base = chain.base_parameters(&BaseOptions::default()).unwrap();
    let err = optimise_chain_excitation(
        &chain,
        &base,
        None,
        &ChainExcitationConfig::default(),
        |_, _| {},
    )
    .unwrap_err();
    match err {
        PrrrpError::Infeasible { what } => {
            assert!(what.contains("joint joint1 has no speed limit"), "{what}")
        }
        other => panic!("{other:?}"),
    }
    let bad = ChainExcitationConfig {
        harmonics: 1,
        ..Default::default()
    };
    assert!(optimise_chain_excitation(&chain, &base, Some(&limits()), &bad, |_, _| {}).is_err());
}
