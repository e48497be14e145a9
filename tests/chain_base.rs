//! Base parameters of generic chains: the count and meaning for the PRRRP arm (paper
//! section 4.1), a 6R arm (PUMA 560), the base-parameter model the estimators use, and
//! end-to-end identification of the PUMA 560 by least squares.

mod seeded_support;

use prrrp_core::faer::linalg::solvers::SolveLstsq;
use prrrp_core::faer::Mat;
use prrrp_core::nalgebra::{SMatrix, SVector};
use prrrp_core::{
    observation_matrix, BaseOptions, BaseParameters, FrictionModel, LinearDynamics, PrrrpError,
    SerialChain,
};

fn numerical_rank(w: &Mat<f64>, rel: f64) -> usize {
    let s = w.singular_values().expect("SVD converges");
    let max = s.iter().fold(0.0f64, |a, &b| a.max(b));
    s.iter().filter(|&&x| x > rel * max).count()
}

fn mat_from_rows(rows: &[Vec<f64>]) -> Mat<f64> {
    Mat::from_fn(rows.len(), rows[0].len(), |i, j| rows[i][j])
}

/// Random states from a small seeded LCG, independent of the library's sampler.
fn states<const N: usize>(seed: u64, count: usize) -> Vec<[SVector<f64, N>; 3]> {
    let mut u = seeded_support::lcg(seed);
    let mut next = move || u() * 6.0 - 3.0;
    (0..count)
        .map(|_| {
            let mut v = || SVector::<f64, N>::from_fn(|_, _| next());
            [v(), v(), v()]
        })
        .collect()
}

/// The states of [`states`] as columns (q, q̇, q̈).
type Columns<const N: usize> = [Vec<SVector<f64, N>>; 3];

fn state_columns<const N: usize>(seed: u64, count: usize) -> Columns<N> {
    let s = states::<N>(seed, count);
    [0, 1, 2].map(|c| s.iter().map(|x| x[c]).collect())
}

/// The chain's base parameters under the default analysis.
fn base_of<const N: usize>(chain: &SerialChain<N>) -> BaseParameters {
    chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis")
}

/// [`base_of`], listed on stdout as `name`'s and checked to number `count`.
fn listed_base<const N: usize>(name: &str, chain: &SerialChain<N>, count: usize) -> BaseParameters {
    let base = base_of(chain);
    for c in &base.combinations {
        println!("{name} base parameter: {c}");
    }
    assert_eq!(base.count(), count, "{name}");
    base
}

/// `samples` samples every 20 ms of [`fourier`] with amplitude `amp` and the chain's exact
/// torques: the columns (q, q̇, q̈) and τ.
fn fourier_record<const N: usize>(
    chain: &SerialChain<N>,
    samples: usize,
    amp: f64,
) -> (Columns<N>, Vec<SVector<f64, N>>) {
    let (mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![]);
    for k in 0..samples {
        let [a, b, c] = fourier::<N>(0.02 * k as f64, amp);
        tau.push(chain.inverse_dynamics(&a, &b, &c));
        q.push(a);
        qd.push(b);
        qdd.push(c);
    }
    ([q, qd, qdd], tau)
}

/// W·π and W_b·β agree on states the analysis never saw.
fn check_reproduces<const N: usize>(chain: &SerialChain<N>, base: &BaseParameters) {
    let [q, qd, qdd] = state_columns::<N>(42, 30);
    let w = chain
        .observation_matrix(&q, &qd, &qdd)
        .expect("finite states");
    let wb = chain
        .base_observation_matrix(base, &q, &qd, &qdd)
        .expect("same chain");
    let pi = chain.parameters();
    let beta = base.base_values(&pi).expect("length p");
    for i in 0..w.nrows() {
        let full: f64 = (0..w.ncols()).map(|j| w[(i, j)] * pi[j]).sum();
        let red: f64 = (0..wb.ncols()).map(|j| wb[(i, j)] * beta[j]).sum();
        // The rows are also the inverse dynamics.
        let tau = chain.inverse_dynamics(&q[i / N], &qd[i / N], &qdd[i / N])[i % N];
        assert!(
            (full - tau).abs() < 1e-10 * (1.0 + tau.abs()),
            "row {i}: {full} vs {tau}"
        );
        assert!(
            (red - tau).abs() < 1e-9 * (1.0 + tau.abs()),
            "row {i}: {red} vs {tau}"
        );
    }
    // K has the identity on the independent columns.
    for (r, &j) in base.independent.iter().enumerate() {
        for (r2, _) in base.independent.iter().enumerate() {
            let want = if r == r2 { 1.0 } else { 0.0 };
            assert_eq!(base.map[(r2, j)], want);
        }
    }
}

/// The paper's 8 λ plus the lateral first moments, as functionals of the chain's 50
/// link-frame parameters, span exactly the chain's 9 base parameters.
///
/// Physics: joints 2–4 turn about vertical axes, so only the inertia of each link about
/// its joint axis (Izz + 2·l·mx + l²·m in the distal link frame, where the joint lies at
/// x = −l), the horizontal first moments (mx, my), and masses carried at the link ends
/// act; link 5 moves with link 4 horizontally (frame 5 = frame 4 shifted along z4), so
/// links 4 and 5 act as one body "45" for joints 2–4; joint 1 (vertical) sees the total
/// mass, joint 5 the mass m5.
#[test]
fn prrrp_has_nine_base_parameters_spanning_the_papers() {
    let chain = SerialChain::paper();
    let base = listed_base("PRRRP", &chain, 9);
    let l = chain.dh().expect("a DH chain").map(|r| r.a);
    let idx = |link: usize, k: usize| 10 * (link - 1) + k;
    let (m, mx, my, izz) = (0, 1, 2, 9);
    let functional = |terms: &[(f64, usize)]| {
        let mut v = vec![0.0; 50];
        for &(c, j) in terms {
            v[j] += c;
        }
        v
    };
    // Body 45 = links 4 and 5.
    let m45 = |c: f64| vec![(c, idx(4, m)), (c, idx(5, m))];
    let cat = |parts: Vec<Vec<(f64, usize)>>| parts.concat();
    let rows = vec![
        // λ1 + λ8: total mass (joint 1).
        functional(&(1..=5).map(|i| (1.0, idx(i, m))).collect::<Vec<_>>()),
        // λ8 = m5 (joint 5).
        functional(&[(1.0, idx(5, m))]),
        // λ2: link 2 and everything beyond about joint 2.
        functional(&cat(vec![
            vec![(1.0, idx(2, izz)), (2.0 * l[1], idx(2, mx))],
            vec![(l[1] * l[1], idx(2, m)), (l[1] * l[1], idx(3, m))],
            m45(l[1] * l[1]),
        ])),
        // λ3.
        functional(&cat(vec![
            vec![
                (1.0, idx(3, izz)),
                (2.0 * l[2], idx(3, mx)),
                (l[2] * l[2], idx(3, m)),
            ],
            m45(l[2] * l[2]),
        ])),
        // λ4 / l2 = mx3 + l3·(m3 + m45).
        functional(&cat(vec![
            vec![(1.0, idx(3, mx)), (l[2], idx(3, m))],
            m45(l[2]),
        ])),
        // λ5 for body 45.
        functional(&cat(vec![
            vec![(1.0, idx(4, izz)), (1.0, idx(5, izz))],
            vec![(2.0 * l[3], idx(4, mx)), (2.0 * l[3], idx(5, mx))],
            m45(l[3] * l[3]),
        ])),
        // MX4R = λ6 / l2 = λ7 / l3 for body 45.
        functional(&cat(vec![
            vec![(1.0, idx(4, mx)), (1.0, idx(5, mx))],
            m45(l[3]),
        ])),
        // The two lateral first moments.
        functional(&[(1.0, idx(3, my))]),
        functional(&[(1.0, idx(4, my)), (1.0, idx(5, my))]),
    ];
    let lmat = mat_from_rows(&rows);
    assert_eq!(numerical_rank(&lmat, 1e-10), 9);
    let both = Mat::from_fn(18, 50, |i, j| {
        if i < 9 {
            lmat[(i, j)]
        } else {
            base.map[(i - 9, j)]
        }
    });
    assert_eq!(numerical_rank(&both, 1e-10), 9, "the spans differ");
    // The physically obvious unidentifiable parameters are reported as such.
    let unid: Vec<&str> = base
        .unidentifiable
        .iter()
        .map(|&j| base.names[j].as_str())
        .collect();
    for name in ["Izz1", "mx1", "Ixx2", "Iyz3", "mz4", "Ixy4"] {
        assert!(
            unid.contains(&name),
            "{name} should be unidentifiable: {unid:?}"
        );
    }
    for name in ["m5", "my3"] {
        assert!(!unid.contains(&name));
    }
    check_reproduces(&chain, &base);
}

/// PUMA 560: 36 base inertial parameters — Khalil's count for this geometry: 7 per link
/// (YY, MZ and M of each link regroup into the links before it) except link 1, whose
/// vertical, fixed axis leaves only its inertia about that axis (7·6 − 6 = 36) — and the
/// rank of the stacked regressor from an SVD agrees.
#[test]
fn puma_base_parameters() {
    let chain = SerialChain::puma560();
    let base = listed_base("PUMA 560", &chain, 36);
    let [q, qd, qdd] = state_columns::<6>(7, 40);
    let w = chain.observation_matrix(&q, &qd, &qdd).expect("finite");
    // Scale columns (units differ) before the SVD rank; columns that are zero up to
    // round-off (≤ 1e-12 of the largest) stay zero instead of being blown up to unit norm.
    let norms: Vec<f64> = (0..60).map(|j| w.col(j).norm_l2()).collect();
    let big = norms.iter().fold(0.0f64, |a, &b| a.max(b));
    let ws = Mat::from_fn(w.nrows(), 60, |i, j| {
        if norms[j] > 1e-12 * big {
            w[(i, j)] / norms[j]
        } else {
            0.0
        }
    });
    assert_eq!(numerical_rank(&ws, 1e-9), 36);
    // The gap in the pivots is wide: the rank does not hinge on the tolerance.
    assert!(
        base.pivots[35] > 1e-3 && base.pivots[36] < 1e-12,
        "{:?}",
        &base.pivots[30..]
    );
    check_reproduces(&chain, &base);

    // Friction columns are independent of everything else: +3 per joint.
    let fr = chain
        .with_friction(FrictionModel::all(), [[1.0, 0.5, 0.1]; 6])
        .expect("valid");
    let bf = base_of(&fr);
    assert_eq!(bf.count(), 36 + 18);
    check_reproduces(&fr, &bf);
    // The same through the run-time-size chain.
    let bd = fr
        .to_dyn()
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    assert_eq!(bd, bf);
}

#[test]
fn base_model_of_prrrp_is_a_linear_dynamics_model() {
    let chain = SerialChain::paper();
    let base = base_of(&chain);
    let model = chain.base_model::<9>(&base).expect("9 base parameters");
    let beta = model.chain_base_values();
    let want = base.base_values(&chain.parameters()).expect("p");
    assert_eq!(beta.as_slice(), &want[..]);
    for [q, qd, qdd] in states::<5>(3, 20) {
        let phi = model.regressor(&q, &qd, &qdd);
        let y: SMatrix<f64, 5, 50> = chain.regressor(&q, &qd, &qdd);
        for (c, &j) in base.independent.iter().enumerate() {
            assert_eq!(phi.column(c), y.column(j));
        }
        let tau = chain.inverse_dynamics(&q, &qd, &qdd);
        assert!((phi * beta - tau).norm() < 1e-12 * (1.0 + tau.norm()));
        assert!(
            (model.inverse_dynamics(&q, &qd, &qdd, &beta) - tau).norm()
                < 1e-12 * (1.0 + tau.norm())
        );
        let fd = model
            .forward_dynamics(&q, &qd, &tau, &beta)
            .expect("physical β");
        assert!((fd - qdd).norm() < 1e-9 * (1.0 + qdd.norm()));
        assert!((model.mass_matrix(&q, &beta) - chain.mass_matrix(&q)).norm() < 1e-13);

        // Derivatives against central differences of the forward dynamics.
        let d = model
            .forward_derivatives(&q, &qd, &tau, &beta)
            .expect("physical β");
        assert!((d.qdd - qdd).norm() < 1e-9 * (1.0 + qdd.norm()));
        let h = 1e-5;
        let fdiff = |dq: SVector<f64, 5>, dqd: SVector<f64, 5>, db: SVector<f64, 9>| {
            let p = model
                .forward_dynamics(&(q + dq * h), &(qd + dqd * h), &tau, &(beta + db * h))
                .expect("PD");
            let m = model
                .forward_dynamics(&(q - dq * h), &(qd - dqd * h), &tau, &(beta - db * h))
                .expect("PD");
            (p - m) / (2.0 * h)
        };
        let (z5, z9) = (SVector::<f64, 5>::zeros(), SVector::<f64, 9>::zeros());
        for k in 0..5 {
            let e = SVector::<f64, 5>::from_fn(|i, _| if i == k { 1.0 } else { 0.0 });
            let a = fdiff(e, z5, z9);
            assert!(
                (d.dqdd_dq.column(k) - a).norm() < 1e-5 * (1.0 + a.norm()),
                "dq {k}"
            );
            let a = fdiff(z5, e, z9);
            assert!(
                (d.dqdd_dqd.column(k) - a).norm() < 1e-5 * (1.0 + a.norm()),
                "dqd {k}"
            );
        }
        for k in 0..9 {
            let e = SVector::<f64, 9>::from_fn(|i, _| if i == k { 1.0 } else { 0.0 });
            let a = fdiff(z5, z5, e);
            assert!(
                (d.dqdd_dlambda.column(k) - a).norm() < 1e-5 * (1.0 + a.norm()),
                "dβ {k}"
            );
        }
    }
    assert!(matches!(
        chain.base_model::<8>(&base),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let puma = base_of(&SerialChain::puma560());
    assert!(matches!(
        chain.base_model::<36>(&puma),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}

/// A smooth excitation: a 5-harmonic Fourier series per joint (Swevers et al. 1997)
/// with analytic derivatives; coefficients from a fixed formula.
fn fourier<const N: usize>(t: f64, amp: f64) -> [SVector<f64, N>; 3] {
    let w = 2.0 * std::f64::consts::PI * 0.1;
    let mut out = [SVector::<f64, N>::zeros(); 3];
    #[allow(clippy::needless_range_loop)] // i also seeds the coefficients
    for i in 0..N {
        for k in 1..=5 {
            let kf = k as f64;
            let a = amp * (1.7 * (5 * i + k) as f64 + 0.3).sin();
            let b = amp * (2.3 * (5 * i + k) as f64 + 1.1).cos();
            let (s, c) = (w * kf * t).sin_cos();
            out[0][i] += (a * s - b * c) / (w * kf);
            out[1][i] += a * c + b * s;
            out[2][i] += w * kf * (b * c - a * s);
        }
    }
    out
}

/// Simulate (noise-free torques from the recursive Newton–Euler algorithm along smooth
/// trajectories), stack the base regressor, solve by QR least squares: the PUMA 560's
/// 36 inertial + 12 friction base parameters come back to round-off.
#[test]
fn puma560_identification_end_to_end() {
    let fp = [
        [4.9, 0.8, 0.0],
        [8.5, 1.3, 0.0],
        [4.0, 0.7, 0.0],
        [0.5, 0.3, 0.0],
        [0.5, 0.2, 0.0],
        [0.4, 0.1, 0.0],
    ];
    let chain = SerialChain::puma560()
        .with_friction(FrictionModel::viscous_coulomb(), fp)
        .expect("valid friction");
    let base = base_of(&chain);
    assert_eq!(base.count(), 48);
    let ([q, qd, qdd], tau) = fourier_record(&chain, 500, 0.4);
    let wb = chain
        .base_observation_matrix(&base, &q, &qd, &qdd)
        .expect("finite");
    let y = Mat::from_fn(wb.nrows(), 1, |i, _| tau[i / 6][i % 6]);
    let beta_hat = wb.qr().solve_lstsq(&y);
    let beta = base.base_values(&chain.parameters()).expect("p");
    let scale = beta.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    let cond = prrrp_core::condition_number(&wb).expect("shape");
    println!("cond(W_b) = {cond:.3e}");
    for (r, want) in beta.iter().enumerate() {
        let err = (beta_hat[(r, 0)] - want).abs();
        assert!(
            err < 1e-10 * scale,
            "{}: {} vs {want}",
            base.combinations[r],
            beta_hat[(r, 0)]
        );
    }
}

/// The PRRRP chain's base model plugs into the generic observation matrix the estimators
/// use, and least squares recovers the chain's base parameters.
#[test]
fn prrrp_chain_identification_through_linear_dynamics() {
    let chain = SerialChain::paper();
    let base = base_of(&chain);
    let model = chain.base_model::<9>(&base).expect("9");
    let ([q, qd, qdd], tau) = fourier_record(&chain, 300, 0.5);
    let w = observation_matrix(&model, &q, &qd, &qdd).expect("finite");
    let y = Mat::from_fn(w.nrows(), 1, |i, _| tau[i / 5][i % 5]);
    let beta_hat = w.qr().solve_lstsq(&y);
    let beta = model.chain_base_values();
    for r in 0..9 {
        assert!(
            (beta_hat[(r, 0)] - beta[r]).abs() < 1e-10 * beta.amax(),
            "{}",
            base.combinations[r]
        );
    }
}

#[test]
fn bad_options_are_typed_errors() {
    let chain = SerialChain::paper();
    let bad = BaseOptions {
        rank_tolerance: 0.0,
        ..BaseOptions::default()
    };
    assert!(matches!(
        chain.base_parameters(&bad),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let few = BaseOptions {
        samples: 3,
        ..BaseOptions::default()
    };
    assert!(matches!(
        chain.base_parameters(&few),
        Err(PrrrpError::TooFewSamples { .. })
    ));
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("analysis");
    assert!(matches!(
        base.base_values(&[1.0; 3]),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let fr = chain
        .with_friction(FrictionModel::viscous_coulomb(), [[0.0; 3]; 5])
        .expect("valid");
    let q = [SVector::<f64, 5>::zeros()];
    assert!(matches!(
        fr.base_observation_matrix(&base, &q, &q, &q),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}
