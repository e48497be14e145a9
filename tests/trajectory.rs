//! Trajectory generators: boundary conditions, C² continuity, and analytic derivatives
//! checked against finite differences of the positions (an independent computation).

use std::f64::consts::PI;

use proptest::prelude::*;
use prrrp_core::{
    sample_trajectory, ExcitationTrajectory, FourierSeries, JointTrajectory, PiecewiseQuintic,
    PrrrpError, Quintic, Reflected, ScalarTrajectory, Sinusoid,
};

/// Fourth-order central differences of q: errors ~ h⁴·q⁽⁵⁾/30 plus rounding ~ ε·|q|/h.
fn fd<S: ScalarTrajectory>(s: &S, t: f64) -> (f64, f64) {
    let h = 1e-3;
    let q = |dt: f64| s.eval(t + dt).0;
    let d1 = (q(-2.0 * h) - 8.0 * q(-h) + 8.0 * q(h) - q(2.0 * h)) / (12.0 * h);
    let d2 =
        (-q(-2.0 * h) + 16.0 * q(-h) - 30.0 * q(0.0) + 16.0 * q(h) - q(2.0 * h)) / (12.0 * h * h);
    (d1, d2)
}

/// Checks q̇ and q̈ against finite differences at `t`, relative to `scale`.
/// h = 1e-3 gives truncation ≈ 3e-14·q⁽⁵⁾ and rounding ≈ 1e-13·|q|/h² ≈ 1e-7·|q| for q̈,
/// so 1e-6 of the signal's scale is a safe bound.
fn check_derivatives<S: ScalarTrajectory>(s: &S, t: f64, scale: f64) {
    let (_, qd, qdd) = s.eval(t);
    let (d1, d2) = fd(s, t);
    assert!(
        (qd - d1).abs() <= 1e-6 * scale,
        "q̇ {qd} vs FD {d1} at t = {t}"
    );
    assert!(
        (qdd - d2).abs() <= 1e-6 * scale,
        "q̈ {qdd} vs FD {d2} at t = {t}"
    );
}

fn b3() -> impl Strategy<Value = (f64, f64, f64)> {
    (-2.0..2.0f64, -3.0..3.0f64, -10.0..10.0f64)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn quintic_meets_its_boundary_conditions(t0 in -1.0..1.0f64, h in 0.2..5.0f64, a in b3(), b in b3()) {
        let p = Quintic::from_boundary(t0, t0 + h, a, b).unwrap();
        let (s, e) = (p.eval(t0), p.eval(t0 + h));
        for (x, y) in [(s.0, a.0), (s.1, a.1), (s.2, a.2), (e.0, b.0), (e.1, b.1), (e.2, b.2)] {
            prop_assert!((x - y).abs() < 1e-9 * (1.0 + y.abs()), "{x} vs {y}");
        }
        for k in 0..=10 {
            check_derivatives(&p, t0 + h * k as f64 / 10.0, 100.0);
        }
    }

    #[test]
    fn piecewise_quintic_is_c2_and_interpolates(
        q in prop::array::uniform4(-2.0..2.0f64),
        qd in prop::array::uniform4(-3.0..3.0f64),
        qdd in prop::array::uniform4(-10.0..10.0f64),
        gaps in prop::array::uniform3(0.3..3.0f64),
    ) {
        let times = [0.0, gaps[0], gaps[0] + gaps[1], gaps[0] + gaps[1] + gaps[2]];
        let p = PiecewiseQuintic::new(times, q, qd, qdd).unwrap();
        let (kt, kq, kqd, kqdd) = p.knots();
        prop_assert_eq!(kt, times);
        let rebuilt = PiecewiseQuintic::new(kt, kq, kqd, kqdd).unwrap();
        for k in 0..=12 {
            let t = times[3] * k as f64 / 12.0;
            let (a, b) = (p.eval(t), rebuilt.eval(t));
            prop_assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-8 && (a.2 - b.2).abs() < 1e-7);
        }
        for k in 0..4 {
            let (a, b, c) = p.eval(times[k]);
            prop_assert!((a - q[k]).abs() < 1e-9 && (b - qd[k]).abs() < 1e-8 && (c - qdd[k]).abs() < 1e-7);
            // Continuity across the knot: limits from both sides agree to O(ε).
            if k > 0 && k < 3 {
                let eps = 1e-9;
                let (l, r) = (p.eval(times[k] - eps), p.eval(times[k] + eps));
                prop_assert!((l.0 - r.0).abs() < 1e-7 && (l.1 - r.1).abs() < 1e-6 && (l.2 - r.2).abs() < 1e-5);
            }
        }
        for k in 0..=30 {
            let t = times[3] * k as f64 / 30.0;
            // Skip points within the FD stencil of a knot, where q⁽³⁾ jumps.
            if times.iter().all(|&tk| (t - tk).abs() > 3e-3) {
                check_derivatives(&p, t, 1e3);
            }
        }
    }
}

#[test]
fn quintic_coefficients_follow_eq_39() {
    let p = Quintic::new([1.0, -2.0, 0.5, 0.25, -0.1, 0.02]);
    let t: f64 = 1.7;
    let want =
        1.0 - 2.0 * t + 0.5 * t.powi(2) + 0.25 * t.powi(3) - 0.1 * t.powi(4) + 0.02 * t.powi(5);
    assert!((p.eval(t).0 - want).abs() < 1e-12);
    check_derivatives(&p, t, 10.0);
}

#[test]
fn piecewise_rejects_bad_knots() {
    assert_eq!(
        PiecewiseQuintic::new([0.0, 1.0, 1.0], [0.0; 3], [0.0; 3], [0.0; 3]),
        Err(PrrrpError::NonIncreasingTime { row: 2 })
    );
    assert!(matches!(
        PiecewiseQuintic::new([0.0, 1.0, 2.0], [0.0, f64::NAN, 0.0], [0.0; 3], [0.0; 3]),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(matches!(
        PiecewiseQuintic::<1>::new([0.0], [0.0], [0.0], [0.0]),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(Quintic::from_boundary(1.0, 1.0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)).is_err());
}

#[test]
fn sinusoid_derivatives() {
    let s = Sinusoid {
        offset: 0.1,
        amplitude: 0.05,
        omega: 2.3,
        phase: 0.4,
    };
    for k in 0..20 {
        check_derivatives(&s, 0.37 * k as f64, 1.0);
    }
    // The rest-start form used for the prismatic joints.
    let r = Sinusoid {
        phase: -0.5 * PI,
        ..s
    };
    let (q, qd, qdd) = r.eval(0.0);
    assert!((q - 0.05).abs() < 1e-15 && qd.abs() < 1e-15 && (qdd - 0.05 * 2.3 * 2.3).abs() < 1e-12);
}

#[test]
fn fourier_series_derivatives_and_rest_conditions() {
    // Σa = 0 and Σ l·b_l = 0: starts (and, after a period, ends) at rest.
    let f = FourierSeries {
        omega: 2.0 * PI / 5.0,
        offset: 0.3,
        a: [0.4, -0.1, -0.3],
        b: [0.2, 0.2, -0.2],
    };
    for t in [0.0, 5.0] {
        let (_, qd, qdd) = f.eval(t);
        assert!(
            qd.abs() < 1e-12 && qdd.abs() < 1e-12,
            "t = {t}: {qd}, {qdd}"
        );
    }
    // Periodic.
    let (a, b) = (f.eval(1.234), f.eval(6.234));
    assert!((a.0 - b.0).abs() < 1e-12);
    for k in 0..25 {
        check_derivatives(&f, 0.2 * k as f64, 1.0);
    }
    // q(t) − q0 is the integral of q̇: check against the closed form at t = 0.
    let q0 = 0.3 - (0.2 / (f.omega * 1.0) + 0.2 / (f.omega * 2.0) - 0.2 / (f.omega * 3.0));
    assert!((f.eval(0.0).0 - q0).abs() < 1e-12);
}

#[test]
fn joint_trajectories_route_each_joint() {
    let s = |o: f64| Sinusoid {
        offset: o,
        amplitude: 0.01,
        omega: 1.0,
        phase: 0.0,
    };
    let rq = |v: f64| PiecewiseQuintic::new([0.0, 2.0], [v, -v], [0.0; 2], [0.0; 2]).unwrap();
    let traj = ExcitationTrajectory {
        prismatic: [s(0.1), s(0.05)],
        revolute: [rq(1.0), rq(2.0), rq(3.0)],
    };
    let p = traj.eval(0.0);
    assert_eq!(p.q.as_slice(), &[0.1, 1.0, 2.0, 3.0, 0.05]);
    assert!((traj.duration() - 2.0).abs() < 1e-15);

    let arr = [s(1.0), s(2.0), s(3.0), s(4.0), s(5.0)];
    let p = arr.eval(0.0);
    assert_eq!(p.q.as_slice(), &[1.0, 2.0, 3.0, 4.0, 5.0]);

    let sampled = sample_trajectory(&traj, 0.0, 0.5, 5).unwrap();
    assert_eq!(sampled.t, vec![0.0, 0.5, 1.0, 1.5, 2.0]);
    assert_eq!(sampled.q[4], traj.eval(2.0).q);
    assert!(sample_trajectory(&traj, 0.0, 0.0, 5).is_err());
}

/// A rest-to-rest 5-joint trajectory on [0, 2] s: sinusoids with q̇ = 0 at both ends and
/// piecewise quintics through a moving via-point.
fn rest_to_rest(end_speed: f64) -> ExcitationTrajectory<3> {
    let s = |o: f64, a: f64| Sinusoid {
        offset: o,
        amplitude: a,
        omega: PI,
        phase: PI / 2.0,
    };
    let rq = |v: f64| {
        PiecewiseQuintic::new(
            [0.0, 1.1, 2.0],
            [v, 0.3 - v, -v],
            [0.0, 0.7 * v, end_speed],
            [0.0, -0.5, 0.0],
        )
        .unwrap()
    };
    ExcitationTrajectory {
        prismatic: [s(0.1, 0.02), s(0.05, 0.01)],
        revolute: [rq(1.0), rq(-0.6), rq(0.4)],
    }
}

/// The reflected trajectory equals the inner one on [0, D], is the time mirror on
/// [D, 2D], is periodic with 2D, and is C² across every turn.
#[test]
fn reflected_trajectory_is_c2_across_turns() {
    let inner = rest_to_rest(0.0);
    let r = Reflected::new(inner).unwrap();
    assert_eq!(r.half_period(), 2.0);
    assert_eq!(r.end_time(), None);
    for t in [0.0, 0.3, 1.1, 1.999] {
        assert_eq!(r.eval(t), inner.eval(t));
        let (a, b) = (r.eval(4.0 - t), inner.eval(t));
        assert!((a.q - b.q).amax() < 1e-12 && (a.qd + b.qd).amax() < 1e-12);
        assert!((a.qdd - b.qdd).amax() < 1e-12);
        assert!((r.eval(t + 8.0).q - b.q).amax() < 1e-12);
    }
    // C²: q, q̇, q̈ have the same limits from both sides of every turn (ε·jerk apart);
    // the jerk changes sign there, so C³ is not claimed.
    let eps = 1e-7;
    for turn in [2.0, 4.0, 6.0, 10.0] {
        let (a, b) = (r.eval(turn - eps), r.eval(turn + eps));
        assert!((a.q - b.q).amax() < 1e-9, "q at {turn}");
        assert!(
            (a.qd - b.qd).amax() < 1e-6,
            "q̇ at {turn}: {} vs {}",
            a.qd,
            b.qd
        );
        assert!(
            (a.qdd - b.qdd).amax() < 1e-5,
            "q̈ at {turn}: {} vs {}",
            a.qdd,
            b.qdd
        );
        // and q̇ is the derivative of q across the turn (central difference, O(h²)).
        let h = 1e-5;
        let d1 = (r.eval(turn + h).q - r.eval(turn - h).q) / (2.0 * h);
        assert!((r.eval(turn).qd - d1).amax() < 1e-8, "q̇ at {turn}");
    }
}

/// Only a trajectory with an end, at rest at both ends, is reflected.
#[test]
fn reflected_refuses_trajectories_not_at_rest() {
    let moving = rest_to_rest(0.2);
    assert!(matches!(
        Reflected::new(moving),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let endless = [Sinusoid {
        offset: 0.0,
        amplitude: 0.1,
        omega: 1.0,
        phase: PI / 2.0,
    }; 5];
    assert!(matches!(
        Reflected::new(endless),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}
