//! Generic serial chains: dynamics checked against physics computed independently
//! (geometric Jacobians and the Lagrange equations), against the PRRRP closed form, and
//! between the two DH conventions.

use proptest::prelude::*;
use prrrp_core::nalgebra::{
    DMatrix, Isometry3, Matrix3, SMatrix, SVector, Translation3, UnitQuaternion, Vector3,
};
use prrrp_core::{
    com_and_inertia, inertial_parameters, transform_inertial_parameters, DhConvention, DhRow,
    DynChain, FrictionModel, JointKind, PrrrpError, Robot, SerialChain, Vec5,
};

// ---------------------------------------------------------------------------------------
// Independent reference: forward kinematics from elementary transforms, link Jacobians,
// M(q) = Σ m·Jvᵀ·Jv + Jwᵀ·(R·I_c·Rᵀ)·Jw, and τ from the Lagrange equations with the
// q-derivatives of M taken by central differences.
// ---------------------------------------------------------------------------------------

struct Reference {
    dh: Vec<DhRow>,
    conv: DhConvention,
    /// (mass, centre of mass in link frame, inertia about the centre of mass).
    links: Vec<(f64, Vector3<f64>, Matrix3<f64>)>,
    gravity: Vector3<f64>,
}

fn rot(axis: Vector3<f64>, angle: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_scaled_axis(axis * angle),
    )
}
fn tr(v: Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(v), UnitQuaternion::identity())
}

impl Reference {
    fn new(dh: &[DhRow], conv: DhConvention, inertial: &[[f64; 10]], gravity: [f64; 3]) -> Self {
        let links = inertial
            .iter()
            .map(|p| match com_and_inertia(p) {
                Some((m, c, i)) => (
                    m,
                    Vector3::from(c),
                    Matrix3::new(i[0], i[1], i[3], i[1], i[2], i[4], i[3], i[4], i[5]),
                ),
                // A massless link: its inertia is about the frame origin.
                None => (
                    0.0,
                    Vector3::zeros(),
                    Matrix3::new(p[4], p[5], p[7], p[5], p[6], p[8], p[7], p[8], p[9]),
                ),
            })
            .collect();
        Self {
            dh: dh.to_vec(),
            conv,
            links,
            gravity: Vector3::from(gravity),
        }
    }

    /// World poses of frames 0..n and, per joint, (axis, point on axis) in world.
    fn kinematics(&self, q: &[f64]) -> (Vec<Isometry3<f64>>, Vec<Axis>) {
        let mut frames = vec![Isometry3::identity()];
        let mut axes = Vec::new();
        for (i, r) in self.dh.iter().enumerate() {
            let (theta, d) = match r.kind {
                JointKind::Revolute => (r.theta + q[i], r.d),
                JointKind::Prismatic => (r.theta, r.d + q[i]),
            };
            let prev = frames[i];
            let x = Vector3::x();
            let z = Vector3::z();
            let t = match self.conv {
                DhConvention::Standard => {
                    axes.push((prev.rotation * z, prev.translation.vector));
                    rot(z, theta) * tr(z * d) * tr(x * r.a) * rot(x, r.alpha)
                }
                DhConvention::Modified => rot(x, r.alpha) * tr(x * r.a) * rot(z, theta) * tr(z * d),
            };
            let next = prev * t;
            if self.conv == DhConvention::Modified {
                axes.push((next.rotation * z, next.translation.vector));
            }
            frames.push(next);
        }
        (frames, axes)
    }

    fn mass_matrix(&self, q: &[f64]) -> DMatrix<f64> {
        let n = self.dh.len();
        let (frames, axes) = self.kinematics(q);
        let mut m = DMatrix::zeros(n, n);
        for (i, (mass, c, ic)) in self.links.iter().enumerate() {
            let pose = frames[i + 1];
            let cw = pose * prrrp_core::nalgebra::Point3::from(*c);
            let r = pose.rotation.to_rotation_matrix().into_inner();
            let iw = r * ic * r.transpose();
            let mut jv = DMatrix::zeros(3, n);
            let mut jw = DMatrix::zeros(3, n);
            for (j, (u, o)) in axes.iter().enumerate().take(i + 1) {
                match self.dh[j].kind {
                    JointKind::Revolute => {
                        jv.fixed_view_mut::<3, 1>(0, j)
                            .copy_from(&u.cross(&(cw.coords - o)));
                        jw.fixed_view_mut::<3, 1>(0, j).copy_from(u);
                    }
                    JointKind::Prismatic => jv.fixed_view_mut::<3, 1>(0, j).copy_from(u),
                }
            }
            m += jv.transpose() * &jv * *mass + jw.transpose() * iw * &jw;
        }
        m
    }

    fn potential(&self, q: &[f64]) -> f64 {
        let (frames, _) = self.kinematics(q);
        self.links
            .iter()
            .enumerate()
            .map(|(i, (mass, c, _))| {
                let cw = frames[i + 1] * prrrp_core::nalgebra::Point3::from(*c);
                -mass * self.gravity.dot(&cw.coords)
            })
            .sum()
    }

    /// τ = M·q̈ + Ṁ·q̇ − ½·∂(q̇ᵀMq̇)/∂q + ∂V/∂q.
    fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        let n = q.len();
        let h = 1e-6;
        let shift = |dir: &[f64], s: f64| -> Vec<f64> {
            q.iter().zip(dir).map(|(a, b)| a + s * b).collect()
        };
        let qd_v = SVectorD::from_column_slice(qd);
        let m = self.mass_matrix(q);
        let mdot = (self.mass_matrix(&shift(qd, h)) - self.mass_matrix(&shift(qd, -h))) / (2.0 * h);
        let mut tau = &m * SVectorD::from_column_slice(qdd) + &mdot * &qd_v;
        for k in 0..n {
            let mut e = vec![0.0; n];
            e[k] = 1.0;
            let (qp, qm) = (shift(&e, h), shift(&e, -h));
            let dk = (self.mass_matrix(&qp) - self.mass_matrix(&qm)) / (2.0 * h);
            let dv = (self.potential(&qp) - self.potential(&qm)) / (2.0 * h);
            tau[k] += -0.5 * qd_v.dot(&(&dk * &qd_v)) + dv;
        }
        tau.iter().copied().collect()
    }
}

type SVectorD = prrrp_core::nalgebra::DVector<f64>;
/// A joint axis in world coordinates: (unit direction, a point on it).
type Axis = (Vector3<f64>, Vector3<f64>);

fn close(a: &[f64], b: &[f64], tol: f64) -> Result<(), String> {
    let scale = 1.0 + b.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        if (x - y).abs() > tol * scale {
            return Err(format!(
                "entry {k}: {x} vs {y} (tol {tol}·{scale})\n{a:?}\n{b:?}"
            ));
        }
    }
    Ok(())
}

/// The PUMA 560 of the standard-DH chain re-described in modified DH: modified frame i
/// is standard frame i−1 moved by joint i, so row i takes (α, a) of standard row i−1, and
/// each link's parameters move by the constant transform Tx(aᵢ)·Rx(αᵢ).
fn to_modified<const N: usize>(c: &SerialChain<N>) -> SerialChain<N> {
    let std = c.dh().expect("a DH chain");
    let dh: [DhRow; N] = std::array::from_fn(|i| DhRow {
        kind: std[i].kind,
        theta: std[i].theta,
        d: std[i].d,
        a: if i == 0 { 0.0 } else { std[i - 1].a },
        alpha: if i == 0 { 0.0 } else { std[i - 1].alpha },
    });
    let inertial: [[f64; 10]; N] = std::array::from_fn(|i| {
        let r = prrrp_core::nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std[i].alpha);
        transform_inertial_parameters(
            &c.inertial()[i],
            r.matrix(),
            &Vector3::new(std[i].a, 0.0, 0.0),
        )
    });
    SerialChain::new(dh, DhConvention::Modified)
        .and_then(|s| s.with_inertial(inertial))
        .and_then(|s| s.with_gravity(c.gravity()))
        .expect("valid chain")
}

fn state<const N: usize>() -> impl Strategy<Value = [SVector<f64, N>; 3]> {
    (
        prop::array::uniform::<_, N>(-3.0..3.0f64),
        prop::array::uniform::<_, N>(-2.0..2.0f64),
        prop::array::uniform::<_, N>(-4.0..4.0f64),
    )
        .prop_map(|(a, b, c)| [a.into(), b.into(), c.into()])
}

/// A random chain with mixed joints, both conventions, random gravity and consistent
/// random inertia (SPD inertia about the centre of mass, positive mass).
fn random_chain() -> impl Strategy<Value = SerialChain<4>> {
    let row = (
        any::<bool>(),
        -1.0..1.0f64,
        -0.5..0.5f64,
        -0.5..0.5f64,
        -3.2..3.2f64,
    )
        .prop_map(|(p, theta, d, a, alpha)| DhRow {
            kind: if p {
                JointKind::Prismatic
            } else {
                JointKind::Revolute
            },
            theta,
            d,
            a,
            alpha,
        });
    let link = (
        0.1..5.0f64,
        prop::array::uniform3(-0.3..0.3f64),
        prop::array::uniform6(-0.2..0.2f64),
    )
        .prop_map(|(m, c, l)| {
            let lm = Matrix3::new(l[0], 0.0, 0.0, l[1], l[2], 0.0, l[3], l[4], l[5]);
            // A rigid body's inertia is tr(Σ)·1 − Σ for its second moment Σ = ∫ r·rᵀ dm ⪰ 0;
            // any PSD Σ gives one (an arbitrary PD matrix may break the triangle
            // inequality, which forward dynamics refuses).
            let sigma = lm * lm.transpose() + Matrix3::identity() * 0.005;
            let i = Matrix3::identity() * sigma.trace() - sigma;
            let upper = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)].map(|rc| i[rc]);
            inertial_parameters(m, c, upper)
        });
    (
        prop::array::uniform4(row),
        prop::array::uniform4(link),
        any::<bool>(),
        prop::array::uniform3(-10.0..10.0f64),
    )
        .prop_map(|(dh, inertial, modified, g)| {
            let conv = if modified {
                DhConvention::Modified
            } else {
                DhConvention::Standard
            };
            SerialChain::new(dh, conv)
                .and_then(|c| c.with_inertial(inertial))
                .and_then(|c| c.with_gravity(g))
                .expect("valid random chain")
        })
}

fn check_against_reference<const N: usize, const P: usize>(
    chain: &SerialChain<N>,
    [q, qd, qdd]: &[SVector<f64, N>; 3],
) -> Result<(), String> {
    let r = Reference::new(
        chain.dh().expect("a DH chain"),
        chain.convention().expect("a DH chain"),
        chain.inertial(),
        chain.gravity(),
    );
    let m = chain.mass_matrix(q);
    let m_ref = r.mass_matrix(q.as_slice());
    close(m.as_slice(), m_ref.as_slice(), 1e-12)?;
    let tau = chain.inverse_dynamics(q, qd, qdd);
    close(
        tau.as_slice(),
        &r.inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice()),
        1e-7,
    )?;
    // The regressor reproduces the recursion.
    let y: SMatrix<f64, N, P> = chain.regressor(q, qd, qdd);
    close(
        (y * chain.inertial_vector::<P>()).as_slice(),
        tau.as_slice(),
        1e-12,
    )?;
    // Forward dynamics inverts inverse dynamics.
    let back = chain
        .forward_dynamics(q, qd, &tau)
        .map_err(|e| e.to_string())?;
    let sv = DMatrix::from_column_slice(N, N, m.as_slice()).singular_values();
    let cond = sv.max() / sv.min();
    close(back.as_slice(), qdd.as_slice(), 1e-13 * cond.max(1.0))?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Table 1 + Table 2 as a chain equal the paper's closed form (corrected) to round-off.
    #[test]
    fn prrrp_chain_matches_closed_form(s in state::<5>()) {
        let [q, qd, qdd] = s;
        let robot = Robot::paper();
        let (model, lambda) = (robot.model(), robot.base_parameters());
        let chain = SerialChain::paper();
        let (q, qd, qdd) = (Vec5::from(q), Vec5::from(qd), Vec5::from(qdd));
        let tau = model.inverse_dynamics(&q, &qd, &qdd, &lambda);
        close(chain.inverse_dynamics(&q, &qd, &qdd).as_slice(), tau.as_slice(), 1e-13)
            .map_err(TestCaseError::fail)?;
        close(chain.mass_matrix(&q).as_slice(), model.mass_matrix(&q, &lambda).as_slice(), 1e-14)
            .map_err(TestCaseError::fail)?;
        close(chain.gravity_torques(&q).as_slice(), model.gravity_vector(&lambda).as_slice(), 1e-14)
            .map_err(TestCaseError::fail)?;
        let fd = chain.forward_dynamics(&q, &qd, &tau).map_err(|e| TestCaseError::fail(e.to_string()))?;
        close(fd.as_slice(), qdd.as_slice(), 1e-10).map_err(TestCaseError::fail)?;
    }

    /// A robot with other Table-2 values still matches (the conversion is not tuned to
    /// the paper's numbers).
    #[test]
    fn prrrp_chain_matches_closed_form_for_other_robots(
        mass in prop::array::uniform5(0.2..3.0f64),
        length in prop::array::uniform5(0.05..0.6f64),
        com in prop::array::uniform3(0.0..0.3f64),
        izz in prop::array::uniform3(0.0..0.05f64),
        s in state::<5>(),
    ) {
        let robot = Robot::new(mass, length, com, izz, 9.81).expect("valid robot");
        let chain = SerialChain::from_robot(&robot).expect("valid chain");
        let (model, lambda) = (robot.model(), robot.base_parameters());
        let [q, qd, qdd] = s;
        close(chain.inverse_dynamics(&q, &qd, &qdd).as_slice(),
              model.inverse_dynamics(&q, &qd, &qdd, &lambda).as_slice(), 1e-13)
            .map_err(TestCaseError::fail)?;
        close(chain.mass_matrix(&q).as_slice(), model.mass_matrix(&q, &lambda).as_slice(), 1e-14)
            .map_err(TestCaseError::fail)?;
    }

    #[test]
    fn puma_matches_lagrange_reference(s in state::<6>()) {
        check_against_reference::<6, 60>(&SerialChain::puma560(), &s).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn modified_dh_puma_matches_reference_and_standard(s in state::<6>()) {
        let std = SerialChain::puma560();
        let modi = to_modified(&std);
        check_against_reference::<6, 60>(&modi, &s).map_err(TestCaseError::fail)?;
        let [q, qd, qdd] = s;
        close(modi.inverse_dynamics(&q, &qd, &qdd).as_slice(),
              std.inverse_dynamics(&q, &qd, &qdd).as_slice(), 1e-12)
            .map_err(TestCaseError::fail)?;
        close(modi.mass_matrix(&q).as_slice(), std.mass_matrix(&q).as_slice(), 1e-12)
            .map_err(TestCaseError::fail)?;
    }

    #[test]
    fn random_chains_match_lagrange_reference(chain in random_chain(), s in state::<4>()) {
        check_against_reference::<4, 40>(&chain, &s).map_err(TestCaseError::fail)?;
    }

    /// Friction adds its terms to τ, and the full regressor (with its friction columns)
    /// reproduces τ with the full parameter vector.
    #[test]
    fn friction_columns_reproduce_friction(s in state::<6>(), smooth in prop::bool::ANY) {
        let [q, qd, qdd] = s;
        let fp = [[4.9, 0.8, 0.1], [8.4, 1.2, -0.2], [4.0, 0.6, 0.05], [0.5, 0.2, 0.0], [0.5, 0.1, 0.01], [0.4, 0.1, -0.02]];
        let model = FrictionModel { coulomb_smoothing: if smooth { 0.05 } else { 0.0 }, ..FrictionModel::all() };
        let rigid = SerialChain::puma560();
        let chain = rigid.with_friction(model, fp).expect("valid friction");
        let want: Vec<f64> = (0..6).map(|j| {
            let sgn = if smooth { (qd[j] / 0.05).tanh() } else { qd[j].signum() };
            fp[j][0] * qd[j] + fp[j][1] * sgn + fp[j][2]
        }).collect();
        let diff = chain.inverse_dynamics(&q, &qd, &qdd) - rigid.inverse_dynamics(&q, &qd, &qdd);
        close(diff.as_slice(), &want, 1e-12).map_err(TestCaseError::fail)?;
        prop_assert_eq!(chain.num_params(), 78);
        let mut y = vec![0.0; 6 * 78];
        chain.regressor_full_into(&q, &qd, &qdd, &mut y).expect("right size");
        let pi = chain.parameters();
        let tau: Vec<f64> = (0..6).map(|i| (0..78).map(|j| y[i + 6 * j] * pi[j]).sum()).collect();
        close(&tau, chain.inverse_dynamics(&q, &qd, &qdd).as_slice(), 1e-12).map_err(TestCaseError::fail)?;
        // The run-time chain agrees.
        let d = chain.to_dyn();
        let yd = d.regressor(q.as_slice(), qd.as_slice(), qdd.as_slice()).expect("sizes");
        close(yd.as_slice(), &y, 0.0).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn dyn_chain_equals_fixed_chain(chain in random_chain(), s in state::<4>()) {
        let [q, qd, qdd] = s;
        let d = DynChain::from(&chain);
        let tau = d.inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice()).expect("sizes");
        close(&tau, chain.inverse_dynamics(&q, &qd, &qdd).as_slice(), 0.0).map_err(TestCaseError::fail)?;
        let m = d.mass_matrix(q.as_slice()).expect("sizes");
        close(m.as_slice(), chain.mass_matrix(&q).as_slice(), 0.0).map_err(TestCaseError::fail)?;
        let fd = d.forward_dynamics(q.as_slice(), qd.as_slice(), &tau).expect("PD");
        close(&fd, qdd.as_slice(), 1e-8).map_err(TestCaseError::fail)?;
        let y: SMatrix<f64, 4, 40> = chain.regressor(&q, &qd, &qdd);
        let yd = d.regressor(q.as_slice(), qd.as_slice(), qdd.as_slice()).expect("sizes");
        close(yd.as_slice(), y.as_slice(), 0.0).map_err(TestCaseError::fail)?;
        prop_assert_eq!(d.to_fixed::<4>().expect("4 joints"), chain);
    }
}

/// The paper's λ, written as linear functionals of the chain's link-frame parameters
/// (link i's frame at its distal end: the joint lies at x = −lᵢ), recover
/// `Robot::base_parameters` — the Table 2 conversion is right.
#[test]
fn paper_lambda_from_link_frame_parameters() {
    let robot = Robot::paper();
    let chain = SerialChain::paper();
    let p = chain.inertial();
    let l = robot.length;
    let m: Vec<f64> = p.iter().map(|x| x[0]).collect();
    let mx = |i: usize| p[i - 1][1];
    let izz = |i: usize| p[i - 1][9];
    // Inertia about joint i's axis of link i and everything beyond it as point masses at l.
    let lambda = [
        m[0] + m[1] + m[2] + m[3],
        izz(2) + 2.0 * l[1] * mx(2) + l[1] * l[1] * (m[1] + m[2] + m[3] + m[4]),
        izz(3) + 2.0 * l[2] * mx(3) + l[2] * l[2] * (m[2] + m[3] + m[4]),
        l[1] * (mx(3) + l[2] * (m[2] + m[3] + m[4])),
        izz(4) + 2.0 * l[3] * mx(4) + l[3] * l[3] * (m[3] + m[4]),
        l[1] * (mx(4) + l[3] * (m[3] + m[4])),
        l[2] * (mx(4) + l[3] * (m[3] + m[4])),
        m[4],
    ];
    let want = robot.base_parameters();
    close(&lambda, want.as_slice(), 1e-15).unwrap();
}

#[test]
fn bad_input_is_a_typed_error() {
    let row = DhRow {
        kind: JointKind::Revolute,
        theta: 0.0,
        d: 0.0,
        a: 0.3,
        alpha: 0.0,
    };
    let nan = DhRow { a: f64::NAN, ..row };
    assert!(matches!(
        SerialChain::new([row, nan], DhConvention::Standard),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(matches!(
        DynChain::new(vec![], DhConvention::Standard),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let c = SerialChain::new([row, row], DhConvention::Standard).unwrap();
    // Non-physical inertials load (a file's are only a prior) and are reported; NaN does
    // not load.
    let mut neg = [[0.0; 10]; 2];
    neg[1][0] = -1.0;
    let bad = c.with_inertial(neg).unwrap();
    assert_eq!(bad.non_physical_links(), vec![1]);
    // ... but forward dynamics, which needs a rigid body, refuses them naming the link.
    let z = SVector::<f64, 2>::zeros();
    match bad.forward_dynamics(&z, &z, &z) {
        Err(PrrrpError::InvalidParameter { field, .. }) => {
            assert!(field.contains("link 2"), "{field}")
        }
        other => panic!("expected a typed error, got {other:?}"),
    }
    match bad
        .to_dyn()
        .forward_dynamics(&[0.0; 2], &[0.0; 2], &[0.0; 2])
    {
        Err(PrrrpError::InvalidParameter { field, .. }) => {
            assert!(field.contains("'link2' (link 2)"), "{field}")
        }
        other => panic!("expected a typed error, got {other:?}"),
    }
    // The built-in robots are rigid bodies (the PUMA's published link 1 and 3 inertias
    // are corrected to the nearest physical ones, see `SerialChain::puma560`).
    assert!(SerialChain::puma560().is_physically_consistent());
    assert!(SerialChain::paper().is_physically_consistent());
    neg[0][3] = f64::NAN;
    assert!(matches!(
        c.with_inertial(neg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    assert!(matches!(
        c.with_gravity([0.0, f64::INFINITY, 0.0]),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // Negative; past the factor range the term vanishes or its slope at rest overflows.
    for v in [-1.0, 1e300, 1e-300, f64::NAN] {
        let smooth = FrictionModel {
            coulomb_smoothing: v,
            ..FrictionModel::all()
        };
        assert!(
            matches!(
                c.with_friction(smooth, [[0.0; 3]; 2]),
                Err(PrrrpError::InvalidParameter { .. })
            ),
            "{v}"
        );
    }
    for v in [0.0, 1e-6, 0.02, 1e6] {
        let smooth = FrictionModel {
            coulomb_smoothing: v,
            ..FrictionModel::all()
        };
        assert!(c.with_friction(smooth, [[0.0; 3]; 2]).is_ok(), "{v}");
    }
    // Massless links: M(q) is singular, forward dynamics says so.
    let q = SVector::<f64, 2>::zeros();
    assert!(matches!(
        c.forward_dynamics(&q, &q, &q),
        Err(PrrrpError::NotPositiveDefinite { .. })
    ));
    let d = c.to_dyn();
    assert!(matches!(
        d.inverse_dynamics(&[0.0], &[0.0, 0.0], &[0.0, 0.0]),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        d.to_fixed::<3>(),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        d.observation_matrix(&[0.0, 1.0, f64::NAN, 0.0], &[0.0; 4], &[0.0; 4]),
        Err(PrrrpError::NonFinite { row: Some(1), .. })
    ));
    let mut out = vec![0.0; 3];
    assert!(matches!(
        c.regressor_full_into(&q, &q, &q, &mut out),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}
