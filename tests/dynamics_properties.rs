//! Physics checks of the closed-form PRRRP model over wide random states (proptest).

mod est_support;

use est_support::paper;
use nalgebra::SMatrix;
use proptest::prelude::*;
use prrrp_core::{Lambda, Mat5, PrrrpError, PrrrpModel, Robot, Vec5};

/// A state with angles over several turns, and velocities/accelerations from realistic
/// (≈1 rad/s) up to large (≈30 rad/s, 300 rad/s²) magnitudes.
fn state() -> impl Strategy<Value = (Vec5, Vec5, Vec5)> {
    let q = prop::array::uniform5(-20.0..20.0f64).prop_map(Vec5::from);
    let scale = prop_oneof![Just(1.0), Just(30.0)];
    let v = prop::array::uniform5(-1.0..1.0f64);
    let a = prop::array::uniform5(-10.0..10.0f64);
    (q, scale, v, a).prop_map(|(q, s, v, a)| (q, Vec5::from(v) * s, Vec5::from(a) * s))
}

/// A physical robot: every parameter positive, drawn over a wide range around Table 2.
fn robot() -> impl Strategy<Value = Robot> {
    (
        prop::array::uniform5(0.05..10.0f64),
        prop::array::uniform5(0.05..1.0f64),
        prop::array::uniform3(0.0..1.0f64),
        prop::array::uniform3(1e-5..0.1f64),
        0.0..20.0f64,
    )
        .prop_map(|(m, l, c, i, g)| {
            // centre of mass somewhere along the link
            let com = [c[0] * l[1], c[1] * l[2], c[2] * l[3]];
            Robot::new(m, l, com, i, g).unwrap()
        })
}

fn rel_close(a: &[f64], b: &[f64], tol: f64) -> bool {
    let scale = b.iter().chain(a).fold(1.0f64, |s, x| s.max(x.abs()));
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * scale)
}

proptest! {
    #[test]
    fn mass_matrix_symmetric_positive_definite(r in robot(), (q, _, _) in state()) {
        let lambda = r.base_parameters();
        let m = r.model().mass_matrix(&q, &lambda);
        prop_assert_eq!(m, m.transpose());
        let eig = m.symmetric_eigenvalues();
        prop_assert!(eig.iter().all(|&e| e > 0.0), "eigenvalues {}", eig);
    }

    #[test]
    fn regressor_times_lambda_is_inverse_dynamics(r in robot(), (q, qd, qdd) in state()) {
        let lambda = r.base_parameters();
        let model = r.model();
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
        let from_parts = model.mass_matrix(&q, &lambda) * qdd
            + model.coriolis(&q, &qd, &lambda)
            + model.gravity_vector(&lambda);
        prop_assert!(rel_close(tau.as_slice(), from_parts.as_slice(), 1e-12));
        let phi = model.regressor(&q, &qd, &qdd) * lambda;
        prop_assert!(rel_close(phi.as_slice(), tau.as_slice(), 1e-12));
    }

    #[test]
    fn forward_dynamics_inverts_inverse_dynamics(r in robot(), (q, qd, qdd) in state()) {
        let lambda = r.base_parameters();
        let model = r.model();
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
        let back = model.forward_dynamics(&q, &qd, &tau, &lambda).unwrap();
        // M can be ill-conditioned for extreme random robots: compare in torque space,
        // where the error is bounded by round-off times the torque scale.
        let tau_back = model.inverse_dynamics(&q, &qd, &back, &lambda);
        prop_assert!(rel_close(tau_back.as_slice(), tau.as_slice(), 1e-10));
    }

    /// Skew symmetry of Ṁ − 2C along q̇, i.e. q̇ᵀ·Ṁ·q̇ = 2·q̇ᵀ·(C·q̇): the Coriolis terms do
    /// no work. Ṁ = dM/dt along q̇ by a central difference.
    #[test]
    fn coriolis_does_no_work(r in robot(), (q, qd, _) in state()) {
        let lambda = r.base_parameters();
        let model = r.model();
        let h = 1e-6 / (1.0 + qd.amax());
        let mdot = (model.mass_matrix(&(q + qd * h), &lambda)
            - model.mass_matrix(&(q - qd * h), &lambda)) / (2.0 * h);
        let lhs = qd.dot(&(mdot * qd));
        let rhs = 2.0 * qd.dot(&model.coriolis(&q, &qd, &lambda));
        let scale = 1.0 + qd.norm_squared() * lambda.amax();
        prop_assert!((lhs - rhs).abs() <= 1e-6 * scale, "{} vs {}", lhs, rhs);
    }

    #[test]
    fn inverse_derivatives_match_finite_differences((q, qd, qdd) in state()) {
        let (model, lambda) = paper();
        let d = model.inverse_derivatives(&q, &qd, &qdd, &lambda);
        let fd_q = central_diff(|x| model.inverse_dynamics(&x, &qd, &qdd, &lambda), q, 1e-6);
        let fd_qd = central_diff(|x| model.inverse_dynamics(&q, &x, &qdd, &lambda), qd, 1e-6);
        prop_assert!(rel_close(d.dtau_dq.as_slice(), fd_q.as_slice(), 1e-6), "{} vs {}", d.dtau_dq, fd_q);
        prop_assert!(rel_close(d.dtau_dqd.as_slice(), fd_qd.as_slice(), 1e-6), "{} vs {}", d.dtau_dqd, fd_qd);
    }

    #[test]
    fn forward_derivatives_match_finite_differences((q, qd, qdd) in state()) {
        let (model, lambda) = paper();
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
        let d = model.forward_derivatives(&q, &qd, &tau, &lambda).unwrap();
        let fdyn = |q: &Vec5, qd: &Vec5, l: &Lambda| model.forward_dynamics(q, qd, &tau, l).unwrap();
        let fd_q = central_diff(|x| fdyn(&x, &qd, &lambda), q, 1e-6);
        let fd_qd = central_diff(|x| fdyn(&q, &x, &lambda), qd, 1e-6);
        let fd_l = central_diff(|x| fdyn(&q, &qd, &x), lambda, 1e-7);
        prop_assert!(rel_close(d.qdd.as_slice(), qdd.as_slice(), 1e-8));
        prop_assert!(rel_close(d.dqdd_dq.as_slice(), fd_q.as_slice(), 1e-5), "{} vs {}", d.dqdd_dq, fd_q);
        prop_assert!(rel_close(d.dqdd_dqd.as_slice(), fd_qd.as_slice(), 1e-5), "{} vs {}", d.dqdd_dqd, fd_qd);
        prop_assert!(rel_close(d.dqdd_dlambda.as_slice(), fd_l.as_slice(), 1e-5), "{} vs {}", d.dqdd_dlambda, fd_l);
    }

    /// The grouped model reproduces the paper's Annex A, written in physical parameters
    /// (typos corrected: inertias about the centre of mass), for random physical robots.
    #[test]
    fn annex_a_entries((q, _, _) in state(), r in robot()) {
        let lambda = r.base_parameters();
        let m = r.model().mass_matrix(&q, &lambda);
        let annex = annex_a_mass_matrix(&r, &q);
        prop_assert!(rel_close(m.as_slice(), annex.as_slice(), 1e-12), "{} vs {}", m, annex);
        let g = r.model().gravity_vector(&lambda);
        let ms: f64 = r.mass.iter().sum();
        let annex_g = Vec5::new(ms * r.gravity, 0.0, 0.0, 0.0, -r.mass[4] * r.gravity);
        prop_assert!(rel_close(g.as_slice(), annex_g.as_slice(), 1e-12));
    }
}

/// Central differences of f at x, column j = (f(x + h·e_j) − f(x − h·e_j)) / 2h, with the
/// step scaled by |x_j| so that large angles keep relative precision.
fn central_diff<const C: usize>(
    f: impl Fn(SMatrix<f64, C, 1>) -> Vec5,
    x: SMatrix<f64, C, 1>,
    h0: f64,
) -> SMatrix<f64, 5, C> {
    let mut out = SMatrix::<f64, 5, C>::zeros();
    for j in 0..C {
        let h = h0 * (1.0 + x[j].abs());
        let (mut xp, mut xm) = (x, x);
        xp[j] += h;
        xm[j] -= h;
        out.set_column(j, &((f(xp) - f(xm)) / (2.0 * h)));
    }
    out
}

/// Annex A (A.1)–(A.10) transcribed in physical parameters.
fn annex_a_mass_matrix(r: &Robot, q: &Vec5) -> Mat5 {
    let [m1, m2, m3, m4, m5] = r.mass;
    let [_, l2, l3, l4, _] = r.length;
    let [lc2, lc3, lc4] = r.com;
    let [i2, i3, i4] = r.inertia_zz;
    let (c3, c4, c34) = (q[2].cos(), q[3].cos(), (q[2] + q[3]).cos());
    let m22 = lc2 * lc2 * m2
        + (l2 * l2 + lc3 * lc3 + 2.0 * l2 * lc3 * c3) * m3
        + (l2 * l2 + l3 * l3 + lc4 * lc4 + 2.0 * l2 * l3 * c3) * m4
        + 2.0 * (l3 * lc4 * c4 + l2 * lc4 * c34) * m4
        + (l2 * l2 + l3 * l3 + l4 * l4 + 2.0 * l2 * l3 * c3) * m5
        + 2.0 * (l3 * l4 * c4 + l2 * l4 * c34) * m5
        + i2
        + i3
        + i4;
    let m23 = (lc3 * lc3 + l2 * lc3 * c3) * m3
        + (l3 * l3 + lc4 * lc4 + l2 * l3 * c3 + 2.0 * l3 * lc4 * c4) * m4
        + l2 * lc4 * c34 * m4
        + l2 * l4 * c34 * m5
        + (l3 * l3 + l4 * l4 + l2 * l3 * c3 + 2.0 * l3 * l4 * c4) * m5
        + i3
        + i4;
    let m24 = (lc4 * lc4 + l3 * lc4 * c4 + l2 * lc4 * c34) * m4
        + (l4 * l4 + l3 * l4 * c4 + l2 * l4 * c34) * m5
        + i4;
    let m33 = lc3 * lc3 * m3
        + (l3 * l3 + lc4 * lc4 + 2.0 * l3 * lc4 * c4) * m4
        + (l3 * l3 + l4 * l4 + 2.0 * l3 * l4 * c4) * m5
        + i3
        + i4;
    let m34 = (lc4 * lc4 + l3 * lc4 * c4) * m4 + (l4 * l4 + l3 * l4 * c4) * m5 + i4;
    let m44 = lc4 * lc4 * m4 + l4 * l4 * m5 + i4;
    let m11 = m1 + m2 + m3 + m4 + m5;
    Mat5::new(
        m11, 0.0, 0.0, 0.0, -m5, //
        0.0, m22, m23, m24, 0.0, //
        0.0, m23, m33, m34, 0.0, //
        0.0, m24, m34, m44, 0.0, //
        -m5, 0.0, 0.0, 0.0, m5,
    )
}

#[test]
fn paper_base_parameters_match_table_3() {
    // Table 3 (corrected) evaluated by hand from Table 2, to 6 decimals (notes/paper.md).
    let want = [
        4.297000, 0.108632, 0.067712, 0.066061, 0.026792, 0.025141, 0.025141, 0.511400,
    ];
    let l = Robot::paper().base_parameters();
    for i in 0..8 {
        assert!(
            (l[i] - want[i]).abs() < 5e-7,
            "λ{} = {} vs {}",
            i + 1,
            l[i],
            want[i]
        );
    }
}

#[test]
fn non_physical_robot_is_rejected_naming_the_field() {
    let p = Robot::paper();
    let cases: [(Robot, &str); 5] = [
        (
            Robot {
                mass: [1.0, 1.0, -1.0, 1.0, 1.0],
                ..p
            },
            "mass[2]",
        ),
        (
            Robot {
                length: [0.5, 0.2, 0.0, 0.2, 0.1],
                ..p
            },
            "length[2]",
        ),
        (
            Robot {
                inertia_zz: [0.1, -1e-3, 0.1],
                ..p
            },
            "inertia_zz[1]",
        ),
        (
            Robot {
                com: [f64::NAN, 0.0, 0.0],
                ..p
            },
            "com[0]",
        ),
        (
            Robot {
                gravity: f64::INFINITY,
                ..p
            },
            "gravity",
        ),
    ];
    for (r, field) in cases {
        let err = Robot::new(r.mass, r.length, r.com, r.inertia_zz, r.gravity).unwrap_err();
        match &err {
            PrrrpError::InvalidParameter { field: f, .. } => assert!(f.starts_with(field), "{f}"),
            other => panic!("unexpected error {other:?}"),
        }
        assert!(err.to_string().contains(field));
    }
}

#[test]
fn non_physical_lambda_gives_typed_error() {
    let model = PrrrpModel::default();
    let q = Vec5::new(0.0, 0.1, 0.2, 0.3, 0.0);
    let mut lambda = Robot::paper().base_parameters();
    lambda[7] = -0.1; // negative tool mass
    let err = model.forward_dynamics(&q, &Vec5::zeros(), &Vec5::zeros(), &lambda);
    assert!(matches!(err, Err(PrrrpError::NotPositiveDefinite { .. })));
    // λ = ones(8), the paper's EKF initial guess, makes the planar block indefinite at
    // θ3 = θ4 = 0: M22 − M23²/M33 … fails.
    let ones = Lambda::from_element(1.0);
    let q0 = Vec5::zeros();
    assert!(model.mass_cholesky(&q0, &ones).is_err());
}

#[test]
fn potential_energy_gradient_is_gravity() {
    let (model, lambda) = paper();
    let q = Vec5::new(0.3, 1.0, -2.0, 0.5, 0.05);
    let grad = central_diff(
        |x| Vec5::from_element(model.potential_energy(&x, &lambda)),
        q,
        1e-6,
    );
    let g = model.gravity_vector(&lambda);
    for j in 0..5 {
        assert!(
            (grad[(0, j)] - g[j]).abs() < 1e-6,
            "∂U/∂q{} = {} vs G = {}",
            j + 1,
            grad[(0, j)],
            g[j]
        );
    }
}
