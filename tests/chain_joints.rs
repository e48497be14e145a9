//! Chains of general joints (arbitrary placements, unit axes off the coordinate axes, link
//! frames off the joint axes, revolute and prismatic), checked against physics computed
//! here from the joints' composed definition ([`Joint::transform`]) rather than from the
//! chain's own recursions:
//! - the mass matrix equals Σ (Jᵥᵀ·m·Jᵥ + J_ωᵀ·I_c·J_ω) of the links' geometric Jacobians,
//!   themselves taken by finite differences of the composed link poses;
//! - power balance along a trajectory: d(T + V)/dt = q̇ᵀ·τ with T and V computed from the
//!   composed poses;
//! - Y·π = τ, forward ∘ inverse = identity, fixed- and run-time-size chains agree.

use prrrp_core::nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3,
};
use prrrp_core::{inertial_parameters, DynChain, Joint, JointType, SerialChain};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

const N: usize = 5;

fn random_iso(rng: &mut StdRng) -> Isometry3<f64> {
    let t = Vector3::new(
        rng.random_range(-0.4..0.4),
        rng.random_range(-0.4..0.4),
        rng.random_range(-0.4..0.4),
    );
    let r = Vector3::new(
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
    );
    Isometry3::new(t, r)
}

fn random_unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n: f64 = v.norm();
        if n > 0.2 && n <= 1.0 {
            return v / n;
        }
    }
}

/// A physical link: mass, centre of mass and a principal inertia rotated arbitrarily.
fn random_link(rng: &mut StdRng) -> [f64; 10] {
    let m = rng.random_range(0.5..4.0);
    let com = [
        rng.random_range(-0.2..0.2),
        rng.random_range(-0.2..0.2),
        rng.random_range(-0.2..0.2),
    ];
    // Principal moments of a box: always satisfy the triangle inequality.
    let (a, b, c): (f64, f64, f64) = (
        rng.random_range(0.05..0.3),
        rng.random_range(0.05..0.3),
        rng.random_range(0.05..0.3),
    );
    let d = Matrix3::from_diagonal(&Vector3::new(
        m * (b * b + c * c) / 12.0,
        m * (a * a + c * c) / 12.0,
        m * (a * a + b * b) / 12.0,
    ));
    let r = UnitQuaternion::from_scaled_axis(Vector3::new(
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
        rng.random_range(-3.0..3.0),
    ))
    .to_rotation_matrix()
    .into_inner();
    let i = r * d * r.transpose();
    let upper = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)].map(|rc| i[rc]);
    inertial_parameters(m, com, upper)
}

fn random_chain(seed: u64) -> SerialChain<N> {
    let mut rng = StdRng::seed_from_u64(seed);
    let joints: [Joint; N] = std::array::from_fn(|i| {
        let kind = if i == 2 {
            JointType::Prismatic
        } else if i == 4 {
            JointType::Continuous
        } else {
            JointType::Revolute
        };
        Joint {
            kind,
            placement: random_iso(&mut rng),
            axis: random_unit(&mut rng),
            // Odd links carry a frame off the joint axis, as standard DH does.
            link_frame: if i % 2 == 1 {
                random_iso(&mut rng)
            } else {
                Isometry3::identity()
            },
        }
    });
    let inertial: [[f64; 10]; N] = std::array::from_fn(|_| random_link(&mut rng));
    SerialChain::from_joints(joints)
        .unwrap()
        .with_inertial(inertial)
        .unwrap()
        .with_gravity([0.3, -1.2, -9.7])
        .unwrap()
}

fn random_state(rng: &mut StdRng) -> [SVector<f64, N>; 3] {
    std::array::from_fn(|_| SVector::from_fn(|_, _| rng.random_range(-1.5..1.5)))
}

/// For seed in 0..`count`: the chain `random_chain(first + seed)` and a random state, the
/// states drawn in turn from one generator seeded with `state_seed`.
type Case = (u64, SerialChain<N>, [SVector<f64, N>; 3]);

fn random_cases(state_seed: u64, first: u64, count: u64) -> Vec<Case> {
    let mut rng = StdRng::seed_from_u64(state_seed);
    (0..count)
        .map(|seed| (seed, random_chain(first + seed), random_state(&mut rng)))
        .collect()
}

/// Link poses in the world frame, composed from the joints' definitions.
fn poses(chain: &SerialChain<N>, q: &SVector<f64, N>) -> [Isometry3<f64>; N] {
    let mut t = Isometry3::identity();
    std::array::from_fn(|i| {
        t *= chain.joints()[i].transform(q[i]);
        t
    })
}

/// Mass, centre of mass (link frame) and inertia about it (link axes) of one link.
fn body(p: &[f64; 10]) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let (m, c, i) = prrrp_core::com_and_inertia(p).unwrap();
    let ic = Matrix3::new(i[0], i[1], i[3], i[1], i[2], i[4], i[3], i[4], i[5]);
    (m, Vector3::from(c), ic)
}

/// World-frame centre of mass and orientation of every link.
fn com_world(chain: &SerialChain<N>, q: &SVector<f64, N>) -> [(Vector3<f64>, Matrix3<f64>); N] {
    let ps = poses(chain, q);
    std::array::from_fn(|i| {
        let (_, c, _) = body(&chain.inertial()[i]);
        (
            ps[i].transform_point(&c.into()).coords,
            ps[i].rotation.to_rotation_matrix().into_inner(),
        )
    })
}

/// Geometric Jacobians (linear velocity of the centre of mass, angular velocity, both in
/// the world frame) of every link, by central differences of the composed poses.
fn jacobians(
    chain: &SerialChain<N>,
    q: &SVector<f64, N>,
) -> Vec<(SMatrix<f64, 3, N>, SMatrix<f64, 3, N>)> {
    let h = 1e-6;
    let mut jv = vec![SMatrix::<f64, 3, N>::zeros(); N];
    let mut jw = vec![SMatrix::<f64, 3, N>::zeros(); N];
    for k in 0..N {
        let mut qp = *q;
        let mut qm = *q;
        qp[k] += h;
        qm[k] -= h;
        let (a, b) = (com_world(chain, &qp), com_world(chain, &qm));
        for i in 0..N {
            jv[i].set_column(k, &((a[i].0 - b[i].0) / (2.0 * h)));
            let (_, r) = com_world(chain, q)[i];
            // [ω]× = Ṙ·Rᵀ.
            let w = (a[i].1 - b[i].1) / (2.0 * h) * r.transpose();
            jw[i].set_column(k, &Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]));
        }
    }
    jv.into_iter().zip(jw).collect()
}

fn energy(chain: &SerialChain<N>, q: &SVector<f64, N>, qd: &SVector<f64, N>) -> (f64, f64) {
    let g = Vector3::from(chain.gravity());
    let cw = com_world(chain, q);
    let mut t = 0.0;
    let mut v = 0.0;
    for (i, (jv, jw)) in jacobians(chain, q).into_iter().enumerate() {
        let (m, _, ic) = body(&chain.inertial()[i]);
        let r = cw[i].1;
        let vel = jv * qd;
        let w = jw * qd;
        t += 0.5 * m * vel.norm_squared() + 0.5 * w.dot(&(r * ic * r.transpose() * w));
        v -= m * g.dot(&cw[i].0);
    }
    (t, v)
}

#[test]
fn mass_matrix_equals_the_jacobian_sum_of_the_composed_poses() {
    for (seed, chain, [q, _, _]) in random_cases(11, 0, 6) {
        let cw = com_world(&chain, &q);
        let mut want = SMatrix::<f64, N, N>::zeros();
        for (i, (jv, jw)) in jacobians(&chain, &q).into_iter().enumerate() {
            let (m, _, ic) = body(&chain.inertial()[i]);
            let r = cw[i].1;
            want += jv.transpose() * jv * m + jw.transpose() * (r * ic * r.transpose()) * jw;
        }
        let got = chain.mass_matrix(&q);
        let err = (got - want).norm() / want.norm();
        assert!(err < 1e-7, "seed {seed}: relative error {err:e}");
        assert!((got - got.transpose()).norm() < 1e-12 * got.norm());
        assert!(got.cholesky().is_some(), "M not positive definite");
    }
}

#[test]
fn power_balance_along_a_trajectory() {
    for (seed, chain, [q0, qd0, qdd]) in random_cases(5, 100, 4) {
        // q(t) = q0 + q̇0·t + ½·q̈·t²: d(T+V)/dt at t = 0 by central differences.
        let at = |t: f64| (q0 + qd0 * t + qdd * (0.5 * t * t), qd0 + qdd * t);
        let h = 1e-4;
        let (qa, qda) = at(h);
        let (qb, qdb) = at(-h);
        let (ta, va) = energy(&chain, &qa, &qda);
        let (tb, vb) = energy(&chain, &qb, &qdb);
        let de = (ta + va - tb - vb) / (2.0 * h);
        let tau = chain.inverse_dynamics(&q0, &qd0, &qdd);
        let power = qd0.dot(&tau);
        let scale = qd0.abs().dot(&tau.abs()).max(1.0);
        assert!(
            (de - power).abs() < 1e-5 * scale,
            "seed {seed}: d(T+V)/dt = {de}, q̇ᵀτ = {power}"
        );
    }
}

#[test]
fn regressor_forward_dynamics_and_dynamic_size_agree() {
    for (_, chain, [q, qd, qdd]) in random_cases(9, 200, 6) {
        let tau = chain.inverse_dynamics(&q, &qd, &qdd);
        let y: SMatrix<f64, N, 50> = chain.regressor(&q, &qd, &qdd);
        let pi = chain.inertial_vector::<50>();
        assert!((y * pi - tau).norm() < 1e-10 * tau.norm().max(1.0));
        let back = chain.forward_dynamics(&q, &qd, &tau).unwrap();
        assert!((back - qdd).norm() < 1e-8 * qdd.norm().max(1.0));

        let d: DynChain = chain.to_dyn();
        let tau_d = d
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .unwrap();
        assert!(
            (DVector::from_vec(tau_d) - DVector::from_column_slice(tau.as_slice())).norm()
                < 1e-12 * tau.norm().max(1.0)
        );
        let m: DMatrix<f64> = d.mass_matrix(q.as_slice()).unwrap();
        let mf = chain.mass_matrix(&q);
        assert!((m - DMatrix::from_column_slice(N, N, mf.as_slice())).norm() < 1e-12);
        let back_fixed = d.to_fixed::<N>().unwrap();
        assert_eq!(back_fixed.joints(), chain.joints());
    }
}

/// A single revolute joint about a tilted axis carrying a point mass: τ = m·r²·q̈ plus the
/// gravity moment, written out by hand.
#[test]
fn point_mass_on_a_tilted_axis() {
    let axis = Vector3::new(0.0, 0.6, 0.8);
    let placement =
        Isometry3::from_parts(Translation3::new(0.1, 0.2, 0.3), UnitQuaternion::identity());
    let m = 2.0;
    let c = Vector3::new(0.5, 0.0, 0.0); // ⟂ axis, distance r = 0.5
    let chain = SerialChain::from_joints([Joint::new(JointType::Revolute, placement, axis)])
        .unwrap()
        .with_inertial([inertial_parameters(m, c.into(), [0.0; 6])])
        .unwrap();
    let g = Vector3::from(chain.gravity());
    for (q, qd, qdd) in [(0.3, 1.0, 2.0), (-1.2, -0.5, 0.7), (2.5, 0.0, -1.0)] {
        let rot =
            UnitQuaternion::from_axis_angle(&prrrp_core::nalgebra::Unit::new_unchecked(axis), q);
        let cw = rot * c;
        // Moment about the axis of the weight: (c × m·g)·u.
        let tau = m * 0.25 * qdd - cw.cross(&(g * m)).dot(&axis);
        let got = chain.inverse_dynamics(
            &SVector::from([q]),
            &SVector::from([qd]),
            &SVector::from([qdd]),
        )[0];
        assert!((got - tau).abs() < 1e-12, "{got} vs {tau}");
    }
}
