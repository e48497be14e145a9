//! The per-sample methods of a fixed-size chain and of its base-parameter model allocate
//! nothing (a counting global allocator; the count is per thread, so parallel tests do
//! not interfere).

mod alloc_support;
mod dyn_support;

use alloc_support::allocations;
use dyn_support::{coupling, three_joint_urdf, with_smoothed_friction};
use prrrp_core::nalgebra::{SMatrix, SVector};
use prrrp_core::{Actuators, BaseOptions, FrictionModel, LinearDynamics, LinearModel, SerialChain};

/// Runs `f` once to warm up, then 20 times, and returns the allocations of the 20.
fn count(mut f: impl FnMut(usize)) -> usize {
    f(0);
    let before = allocations();
    for k in 1..=20 {
        f(k);
    }
    allocations() - before
}

fn state<const N: usize>(k: usize) -> [SVector<f64, N>; 3] {
    let v = |s: f64| SVector::<f64, N>::from_fn(|i, _| (s * (i + 1) as f64 + 0.1 * k as f64).sin());
    [v(0.7), v(1.3), v(2.1)]
}

#[test]
fn the_counter_sees_allocations() {
    assert!(count(|k| drop(std::hint::black_box(vec![k; 4]))) >= 20);
}

#[test]
fn fixed_size_chain_does_not_allocate() {
    let chain = SerialChain::puma560()
        .with_friction(FrictionModel::all(), [[0.5, 0.2, 0.01]; 6])
        .expect("valid");
    let mut out = vec![0.0; 6 * chain.num_params()];
    let mut sink = 0.0;
    let n = count(|k| {
        let [q, qd, qdd] = state::<6>(k);
        let tau = chain.inverse_dynamics(&q, &qd, &qdd);
        let m = chain.mass_matrix(&q);
        let y: SMatrix<f64, 6, 60> = chain.regressor(&q, &qd, &qdd);
        let qdd2 = chain.forward_dynamics(&q, &qd, &tau).expect("PD");
        let g = chain.gravity_torques(&q);
        chain
            .regressor_full_into(&q, &qd, &qdd, &mut out)
            .expect("size");
        sink += tau[0] + m[(1, 1)] + y[(0, 5)] + qdd2[2] + g[1] + out[7];
    });
    std::hint::black_box(sink);
    assert_eq!(n, 0);
}

#[test]
fn base_model_does_not_allocate() {
    let chain = SerialChain::paper();
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    let model = chain.base_model::<9>(&base).expect("9");
    let beta = model.chain_base_values();
    let mut sink = 0.0;
    let n = count(|k| {
        let [q, qd, qdd] = state::<5>(k);
        let phi = model.regressor(&q, &qd, &qdd);
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &beta);
        let fd = model.forward_dynamics(&q, &qd, &tau, &beta).expect("PD");
        let d = model.forward_derivatives(&q, &qd, &tau, &beta).expect("PD");
        sink += phi[(1, 2)] + fd[0] + d.dqdd_dq[(1, 1)];
    });
    std::hint::black_box(sink);
    assert_eq!(n, 0);
}

/// A chain loaded from a URDF (tilted axes, a prismatic joint, merged fixed bodies and
/// locked fingers): the fixed-size methods and the run-time `*_into` methods with a
/// workspace allocate nothing either.
#[test]
fn urdf_chain_does_not_allocate() {
    let chain = three_joint_urdf()
        .with_friction(FrictionModel::all(), vec![[0.5, 0.2, 0.01]; 3])
        .expect("valid");
    let fixed = chain.to_fixed::<3>().expect("3 joints");
    let mut ws = chain.workspace();
    let (mut tau, mut back) = ([0.0; 3], [0.0; 3]);
    let mut m = [0.0; 9];
    let mut y = vec![0.0; 3 * chain.num_params()];
    let mut sink = 0.0;
    let n = count(|k| {
        let [q, qd, qdd] = state::<3>(k);
        let t = fixed.inverse_dynamics(&q, &qd, &qdd);
        let yf: SMatrix<f64, 3, 30> = fixed.regressor(&q, &qd, &qdd);
        let fd = fixed.forward_dynamics(&q, &qd, &t).expect("PD");
        let (q, qd, qdd) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
        chain
            .inverse_dynamics_into(&mut ws, q, qd, qdd, &mut tau)
            .expect("sizes");
        chain.mass_matrix_into(&mut ws, q, &mut m).expect("sizes");
        chain
            .forward_dynamics_into(&mut ws, q, qd, &tau, &mut back)
            .expect("PD");
        chain
            .regressor_row_major_into(&mut ws, q, qd, qdd, &mut y)
            .expect("sizes");
        sink += t[0] + yf[(0, 3)] + fd[1] + tau[2] + m[4] + back[0] + y[5];
    });
    std::hint::black_box(sink);
    assert_eq!(n, 0);
}

/// Coupled actuators with rotor inertias (issue 26): the actuator terms run inside the same
/// per-sample kernels, fixed-size and run-time, and the base models; still no allocation.
#[test]
fn coupled_actuators_do_not_allocate() {
    // The sixth motor turns with q̇5 + q̇6.
    let c = coupling(6, &[(5, 4, 1.0)]);
    let puma = SerialChain::puma560().to_dyn();
    let chain = with_smoothed_friction(puma, 0.02, vec![[0.5, 0.2, 0.01]; 6])
        .with_actuators(Actuators {
            coupling: Some(c),
            armature: true,
            armature_values: Some(vec![1.0, 1.2, 0.5, 0.05, 0.04, 0.03]),
            gear_ratios: None,
        })
        .expect("valid");
    let fixed = chain.to_fixed::<6>().expect("6 joints");
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    let model = chain.base_model(&base).expect("model");
    let beta = model.chain_base_values().clone();
    let mut mws = model.workspace();
    let (nd, bd) = model.dims();
    let mut phi = prrrp_core::nalgebra::DMatrix::zeros(nd.0, bd.0);
    let mut out = prrrp_core::nalgebra::DVector::zeros(6);
    let mut der = prrrp_core::ForwardDerivativesOf::zeros(nd, bd);
    let mut ws = chain.workspace();
    let (mut tau, mut back) = ([0.0; 6], [0.0; 6]);
    let mut full = vec![0.0; 6 * fixed.num_params()];
    let mut sink = 0.0;
    let states: Vec<[prrrp_core::nalgebra::DVector<f64>; 3]> = (0..21)
        .map(|k| {
            let [q, qd, qdd] = state::<6>(k);
            [q, qd, qdd].map(|v| prrrp_core::nalgebra::DVector::from_column_slice(v.as_slice()))
        })
        .collect();
    let n_fixed = count(|k| {
        let [q, qd, qdd] = state::<6>(k);
        let t = fixed.inverse_dynamics(&q, &qd, &qdd);
        let fd = fixed.forward_dynamics(&q, &qd, &t).expect("PD");
        fixed
            .regressor_full_into(&q, &qd, &qdd, &mut full)
            .expect("size");
        let (qs, qds, qdds) = (q.as_slice(), qd.as_slice(), qdd.as_slice());
        chain
            .inverse_dynamics_into(&mut ws, qs, qds, qdds, &mut tau)
            .expect("sizes");
        chain
            .forward_dynamics_into(&mut ws, qs, qds, &tau, &mut back)
            .expect("PD");
        sink += t[0] + fd[1] + full[3] + tau[2] + back[0];
    });
    let n_model = count(|k| {
        let [q, qd, qdd] = &states[k];
        model
            .regressor_into(&mut mws, q, qd, qdd, &mut phi)
            .expect("sizes");
        model
            .inverse_dynamics_into(&mut mws, q, qd, qdd, &beta, &mut out)
            .expect("sizes");
        model
            .forward_derivatives_into(&mut mws, q, qd, &out, &beta, &mut der)
            .expect("PD");
        sink += phi[(1, 2)] + out[0] + der.dqdd_dqd[(4, 5)];
    });
    std::hint::black_box(sink);
    assert_eq!((n_fixed, n_model), (0, 0));
}
