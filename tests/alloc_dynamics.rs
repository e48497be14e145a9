//! Proves that every per-sample function of the core model is allocation-free: a counting
//! global allocator records heap allocations made by the calling thread.

mod alloc_support;

use std::hint::black_box;

use prrrp_core::{LinearDynamics, MassCholesky, Robot, Vec5};

/// Allocations made by the calling thread while `f` runs.
fn allocations(f: impl FnOnce()) -> usize {
    let before = alloc_support::allocations();
    f();
    alloc_support::allocations() - before
}

#[test]
fn counter_sees_allocations() {
    // The test must be able to fail: a Vec does allocate.
    assert!(allocations(|| drop(black_box(vec![1.0f64; 8]))) >= 1);
}

#[test]
fn per_sample_model_functions_do_not_allocate() {
    let robot = Robot::paper();
    let model = robot.model();
    let lambda = robot.base_parameters();
    let q = Vec5::new(0.1, 0.3, -0.5, 1.2, 0.02);
    let qd = Vec5::new(0.2, -1.0, 0.5, 2.0, -0.1);
    let qdd = Vec5::new(1.0, 3.0, -2.0, 0.5, 0.3);
    let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
    let m = model.mass_matrix(&q, &lambda);
    type Check<'a> = (&'static str, Box<dyn Fn() + 'a>);
    let checks: Vec<Check> = vec![
        (
            "base_parameters",
            Box::new(|| {
                black_box(robot.base_parameters());
            }),
        ),
        (
            "mass_matrix",
            Box::new(|| {
                black_box(model.mass_matrix(&q, &lambda));
            }),
        ),
        (
            "coriolis",
            Box::new(|| {
                black_box(model.coriolis(&q, &qd, &lambda));
            }),
        ),
        (
            "gravity_vector",
            Box::new(|| {
                black_box(model.gravity_vector(&lambda));
            }),
        ),
        (
            "nonlinear_effects",
            Box::new(|| {
                black_box(model.nonlinear_effects(&q, &qd, &lambda));
            }),
        ),
        (
            "inverse_dynamics",
            Box::new(|| {
                black_box(model.inverse_dynamics(&q, &qd, &qdd, &lambda));
            }),
        ),
        (
            "regressor",
            Box::new(|| {
                black_box(model.regressor(&q, &qd, &qdd));
            }),
        ),
        (
            "forward_dynamics",
            Box::new(|| {
                let _ = black_box(model.forward_dynamics(&q, &qd, &tau, &lambda));
            }),
        ),
        (
            "mass_cholesky",
            Box::new(|| {
                let _ = black_box(MassCholesky::new(&m).map(|c| c.solve(&tau)));
            }),
        ),
        (
            "inverse_derivatives",
            Box::new(|| {
                black_box(model.inverse_derivatives(&q, &qd, &qdd, &lambda));
            }),
        ),
        (
            "forward_derivatives",
            Box::new(|| {
                let _ = black_box(model.forward_derivatives(&q, &qd, &tau, &lambda));
            }),
        ),
        (
            "LinearDynamics::forward_derivatives",
            Box::new(|| {
                let _ = black_box(LinearDynamics::forward_derivatives(
                    &model, &q, &qd, &tau, &lambda,
                ));
            }),
        ),
        (
            "kinetic_energy",
            Box::new(|| {
                black_box(model.kinetic_energy(&q, &qd, &lambda));
            }),
        ),
    ];
    for (name, f) in &checks {
        f(); // warm-up
        let n = allocations(|| {
            for _ in 0..100 {
                f()
            }
        });
        assert_eq!(n, 0, "{name} allocated {n} times in 100 calls");
    }
}
