//! Per-sample trajectory evaluation, the controller and the RK4 step never allocate.

mod alloc_support;

use prrrp_core::{
    rk4_step, ComputedTorque, ExcitationTrajectory, FourierSeries, JointTrajectory,
    PiecewiseQuintic, Quintic, Robot, Sinusoid, Vec5,
};

/// Allocations made by the calling thread in a second run of `f` (the first warms up).
fn allocations(f: impl Fn()) -> usize {
    f(); // warm-up
    let before = alloc_support::allocations();
    f();
    alloc_support::allocations() - before
}

#[test]
fn per_sample_functions_do_not_allocate() {
    let pq = PiecewiseQuintic::new(
        [0.0, 1.0, 2.5, 4.0],
        [0.0, 1.0, -0.5, 0.2],
        [0.0, 1.0, 0.5, 0.0],
        [0.0; 4],
    )
    .unwrap();
    let sin = Sinusoid {
        offset: 0.1,
        amplitude: 0.05,
        omega: 2.0,
        phase: 0.0,
    };
    let exc = ExcitationTrajectory {
        prismatic: [sin, sin],
        revolute: [pq; 3],
    };
    let fourier = [FourierSeries {
        omega: 1.0,
        offset: 0.0,
        a: [0.1, 0.2, -0.3],
        b: [0.0, 0.1, 0.0],
    }; 5];
    let quintics = [Quintic::new([0.0, 1.0, 0.5, 0.1, 0.0, 0.01]); 5];
    let robot = Robot::paper();
    let (model, lambda) = (robot.model(), robot.base_parameters());
    let ctrl = ComputedTorque {
        model,
        lambda,
        kp: Vec5::repeat(400.0),
        kd: Vec5::repeat(40.0),
    };

    let n = allocations(|| {
        let mut acc = Vec5::zeros();
        for k in 0..200 {
            let t = 0.02 * k as f64;
            let r = exc.eval(t);
            acc += r.q + fourier.eval(t).qd + quintics.eval(t).qdd;
            let tau = ctrl.torque(&r, &(r.q * 0.99), &r.qd);
            let (q, qd) = rk4_step(&model, &lambda, &r.q, &r.qd, &tau, 1e-3).unwrap();
            acc += q + qd;
        }
        std::hint::black_box(acc);
    });
    assert_eq!(n, 0, "{n} heap allocations in per-sample code");
}
