//! The per-step simulation of a run-time chain allocates nothing: reference evaluation,
//! computed-torque control and RK4 with buffers sized once; and a whole simulation
//! allocates the same number of times whatever its length (its record is reserved up
//! front). A counting global allocator, per thread, so parallel tests do not interfere.

mod alloc_support;
mod dyn_support;

use alloc_support::allocations;
use dyn_support::with_smoothed_friction;
use prrrp_core::{
    simulate_dyn_closed_loop, DynChain, DynComputedTorque, DynSimulationConfig, DynTrajectory,
    FourierTrajectory, Rk4Integrator, SerialChain,
};

fn chain() -> prrrp_core::DynChain {
    with_smoothed_friction(
        SerialChain::puma560().to_dyn(),
        0.1,
        vec![[0.01, 0.005, 0.001]; 6],
    )
}

fn reference() -> FourierTrajectory {
    FourierTrajectory::new(
        1.2,
        vec![0.1; 6],
        (0..12).map(|i| 0.2 * ((i % 2) as f64 - 0.5)).collect(),
        vec![0.05; 12],
    )
    .unwrap()
}

/// Allocations made by `steps` 1 ms steps of [`reference`] tracked on `chain` (computed
/// torque, Kp = 400, Kd = 40, then RK4), the state started on the reference; `each` sees
/// the joint velocities before and after every step. Also returns the final q and q_r.
fn tracking_allocations(
    chain: &DynChain,
    steps: usize,
    mut each: impl FnMut(&[f64; 6], &[f64]),
) -> (usize, Vec<f64>, Vec<f64>) {
    let reference = reference();
    let mut ctrl = DynComputedTorque::new(chain, &[400.0; 6], &[40.0; 6]).unwrap();
    let mut rk = Rk4Integrator::new(chain);
    let (mut q_r, mut qd_r, mut qdd_r) = (vec![0.0; 6], vec![0.0; 6], vec![0.0; 6]);
    reference.eval_into(0.0, &mut q_r, &mut qd_r, &mut qdd_r);
    let (mut q, mut qd) = (q_r.clone(), qd_r.clone());
    let (mut tau, mut qdd) = (vec![0.0; 6], vec![0.0; 6]);
    let h = 1e-3;
    let before = allocations();
    for k in 0..steps {
        let t = h * k as f64;
        reference.eval_into(t, &mut q_r, &mut qd_r, &mut qdd_r);
        ctrl.torque_into((&q_r, &qd_r, &qdd_r), &q, &qd, &mut tau)
            .unwrap();
        rk.acceleration_into(&q, &qd, &tau, &mut qdd).unwrap();
        let was: [f64; 6] = std::array::from_fn(|j| qd[j]);
        rk.step(&mut q, &mut qd, &tau, h).unwrap();
        each(&was, &qd);
    }
    (allocations() - before, q, q_r)
}

#[test]
fn closed_loop_step_of_a_dyn_chain_does_not_allocate() {
    let (n, q, q_r) = tracking_allocations(&chain(), 2000, |_, _| {});
    assert_eq!(n, 0, "{n} allocations in 2000 control + RK4 steps");
    // The loop did track the reference (the work was not optimised away).
    assert!(
        q.iter().zip(&q_r).all(|(a, b)| (a - b).abs() < 1e-2),
        "{q:?} vs {q_r:?}"
    );
}

#[test]
fn stick_slip_steps_do_not_allocate() {
    // Coulomb friction with the exact sign: mode tests, hold torques and event cuts.
    let chain = prrrp_core::DynChain::from_toml_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/ur5_like_friction.toml"
    ))
    .unwrap();
    let (mut stuck, mut cuts) = (0, 0);
    let (n, _, _) = tracking_allocations(&chain, 6000, |was, qd| {
        stuck += qd.iter().filter(|&&v| v == 0.0).count();
        cuts += (0..6)
            .filter(|&j| was[j] * qd[j] < 0.0 || (was[j] != 0.0 && qd[j] == 0.0))
            .count();
    });
    assert_eq!(
        n, 0,
        "{n} allocations in 6000 stick-slip control + RK4 steps"
    );
    // The run did reverse joints and hold some at rest (the event code ran).
    assert!(
        cuts > 0 && stuck > 0,
        "{cuts} reversals, {stuck} stuck steps"
    );
}

#[test]
fn whole_simulation_allocations_do_not_grow_with_length() {
    let chain = chain();
    let reference = reference();
    let cfg = DynSimulationConfig::new(6);
    let count = |duration: f64| {
        let before = allocations();
        let rec = simulate_dyn_closed_loop(&chain, &chain, &reference, duration, &cfg).unwrap();
        let n = allocations() - before;
        std::hint::black_box(rec);
        n
    };
    let (short, long) = (count(0.5), count(5.0));
    assert_eq!(
        short, long,
        "allocations grow with the run: {short} vs {long}"
    );
}
