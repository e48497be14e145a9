//! Batch least squares: exactness on noise-free data, accuracy and honest standard
//! deviations on noisy data, weighted least squares, rank deficiency and bad input.

mod est_support;

use est_support::{add_noise, excitation, line, paper, rel_errors, Noise};
use prrrp_core::nalgebra::{SMatrix, SVector};
use prrrp_core::{
    least_squares, weighted_least_squares, JointNoise, LeastSquaresConfig, LinearDynamics,
    PrrrpError, Samples, Vec5,
};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const N_SAMPLES: usize = 1000;

#[test]
fn noise_free_recovers_lambda_to_1e_6() {
    let (model, lambda) = paper();
    let data = excitation(N_SAMPLES, 1);
    let rep = least_squares(&model, &data.dataset(), &LeastSquaresConfig::default()).unwrap();
    let (max, errs) = rel_errors(&rep.lambda, &lambda);
    eprintln!(
        "LS noise-free rel errors {}, cond {:.1}",
        line(&errs),
        rep.cond
    );
    assert!(max < 1e-6, "max relative error {max:e}");
    assert!(rep.sigma2 < 1e-20, "σ² {}", rep.sigma2);
    assert!(rep.cond.is_finite() && rep.cond > 1.0);
}

/// Statistics checked against an independent computation from the explicit W (in the test
/// only: the normal equations are fine for a check at this conditioning).
#[test]
fn statistics_match_an_independent_computation() {
    let (model, _) = paper();
    let clean = excitation(300, 2);
    let (data, _) = add_noise(&clean, Noise::realistic(), 7);
    let rep = least_squares(&model, &data.dataset(), &LeastSquaresConfig::default()).unwrap();

    let mut wtw = SMatrix::<f64, 8, 8>::zeros();
    let mut wty = SVector::<f64, 8>::zeros();
    let mut rows = Vec::new();
    for k in 0..data.len() {
        let phi = LinearDynamics::regressor(&model, &data.q[k], &data.qd[k], &data.qdd[k]);
        wtw += phi.transpose() * phi;
        wty += phi.transpose() * data.tau[k];
        rows.push((phi, data.tau[k]));
    }
    let inv = wtw.try_inverse().unwrap();
    let lambda = inv * wty;
    let rss: f64 = rows
        .iter()
        .map(|(phi, tau)| (tau - phi * lambda).norm_squared())
        .sum();
    let sigma2 = rss / (5 * data.len() - 8) as f64;
    assert!((rep.lambda - lambda).norm() / lambda.norm() < 1e-9);
    assert!((rep.sigma2 - sigma2).abs() / sigma2 < 1e-9);
    for i in 0..8 {
        let sd = (sigma2 * inv[(i, i)]).sqrt();
        assert!(
            (rep.std_dev[i] - sd).abs() / sd < 1e-6,
            "σ_{i}: {} vs {sd}",
            rep.std_dev[i]
        );
        let rel = 100.0 * sd / lambda[i].abs();
        assert!((rep.rel_std_dev[i] - rel).abs() / rel < 1e-6);
    }
    // cond(W)² = cond(WᵀW).
    let ev = wtw.symmetric_eigenvalues();
    let cond_n = ev.max() / ev.min();
    assert!((rep.cond * rep.cond - cond_n).abs() / cond_n < 1e-6);
    // Per-joint residual variances from the stacked residual.
    for j in 0..5 {
        let ss: f64 = rows
            .iter()
            .map(|(phi, tau)| (tau - phi * lambda)[j].powi(2))
            .sum();
        let v = ss / (data.len() as f64 - 8.0 / 5.0);
        assert!((rep.joint_variances[j] - v).abs() / v < 1e-6);
    }
}

#[test]
fn realistic_noise_stays_within_2_percent() {
    let (model, lambda) = paper();
    let clean = excitation(5000, 3);
    let (data, sigma_tau) = add_noise(&clean, Noise::realistic(), 11);
    let cfg = LeastSquaresConfig::default();
    let ols = least_squares(&model, &data.dataset(), &cfg).unwrap();
    let wls = weighted_least_squares(&model, &data.dataset(), JointNoise::Estimated, &cfg).unwrap();
    let (max_ols, e_ols) = rel_errors(&ols.lambda, &lambda);
    let (max_wls, e_wls) = rel_errors(&wls.lambda, &lambda);
    eprintln!("OLS noisy rel errors {}", line(&e_ols));
    eprintln!("  %σ {}", line(&ols.rel_std_dev));
    eprintln!("WLS noisy rel errors {}", line(&e_wls));
    eprintln!("  %σ {}", line(&wls.rel_std_dev));
    assert!(max_ols < 0.02, "OLS max relative error {max_ols}");
    assert!(max_wls < 0.02, "WLS max relative error {max_wls}");
    // The estimated joint variances are what the noise puts into each equation: the torque
    // noise plus the effect of the noise in q, q̇, q̈ on Φ·λ (computed here from the clean
    // and noisy regressors at the true λ).
    let mut expected = sigma_tau.map(|s| s * s);
    for k in 0..data.len() {
        let phi_noisy = model.regressor(&data.q[k], &data.qd[k], &data.qdd[k]);
        let phi_clean = model.regressor(&clean.q[k], &clean.qd[k], &clean.qdd[k]);
        let d = (phi_noisy - phi_clean) * lambda;
        expected += d.component_mul(&d) / data.len() as f64;
    }
    for j in 0..5 {
        let ratio = ols.joint_variances[j] / expected[j];
        assert!(
            (0.9..1.1).contains(&ratio),
            "joint {j}: variance ratio {ratio}"
        );
    }
    // Errors are consistent with the reported standard deviations.
    for i in 0..8 {
        assert!((ols.lambda[i] - lambda[i]).abs() < 4.0 * ols.std_dev[i]);
        assert!((wls.lambda[i] - lambda[i]).abs() < 4.0 * wls.std_dev[i]);
    }
}

/// Over independent noise draws, the spread of λ̂ matches the reported σ_i: for ordinary
/// least squares when every joint has the same noise (its σ² pools the joints), for
/// weighted least squares also when the joints' noise differs.
#[test]
fn reported_std_dev_matches_monte_carlo_spread() {
    let (model, _) = paper();
    let clean = excitation(400, 4);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let runs = 60;
    let cfg = LeastSquaresConfig::default();
    // Equal noise (0.05 N or N·m) on every joint, then noise of 5 % of each joint's RMS.
    for weighted in [false, true] {
        let mut ests = Vec::new();
        let mut reported = SVector::<f64, 8>::zeros();
        for seed in 0..runs {
            let data = if weighted {
                let noise = Noise::torque_only(0.05);
                add_noise(&clean, noise, 1000 + seed).0
            } else {
                let mut rng = StdRng::seed_from_u64(2000 + seed);
                let mut d = clean.clone();
                for t in &mut d.tau {
                    *t += Vec5::from_fn(|_, _| 0.05 * unit.sample(&mut rng));
                }
                d
            };
            let rep = if weighted {
                weighted_least_squares(&model, &data.dataset(), JointNoise::Estimated, &cfg)
            } else {
                least_squares(&model, &data.dataset(), &cfg)
            }
            .unwrap();
            reported += rep.std_dev / runs as f64;
            ests.push(rep.lambda);
        }
        let mean = ests.iter().sum::<SVector<f64, 8>>() / runs as f64;
        for i in 0..8 {
            let var =
                ests.iter().map(|e| (e[i] - mean[i]).powi(2)).sum::<f64>() / (runs - 1) as f64;
            let ratio = var.sqrt() / reported[i];
            // 60 draws: the sample standard deviation is within ±30 % with high probability.
            assert!(
                (0.7..1.3).contains(&ratio),
                "weighted {weighted}, λ{}: spread/σ = {ratio}",
                i + 1
            );
        }
    }
}

#[test]
fn weighted_with_given_variances_downweights_the_noisy_joint() {
    let (model, lambda) = paper();
    let clean = excitation(1000, 5);
    let (mut data, _) = add_noise(&clean, Noise::torque_only(0.01), 21);
    // Joint 3 gets a hundred times more torque noise.
    let (noisy3, sigma3) = add_noise(&clean, Noise::torque_only(1.0), 22);
    for k in 0..data.len() {
        data.tau[k][2] = noisy3.tau[k][2];
    }
    let mut var = Vec5::zeros();
    let (_, sigma_others) = add_noise(&clean, Noise::torque_only(0.01), 0);
    for j in 0..5 {
        var[j] = if j == 2 {
            sigma3[j].powi(2)
        } else {
            sigma_others[j].powi(2)
        };
    }
    let cfg = LeastSquaresConfig::default();
    let ols = least_squares(&model, &data.dataset(), &cfg).unwrap();
    let wls =
        weighted_least_squares(&model, &data.dataset(), JointNoise::Variances(var), &cfg).unwrap();
    let est = weighted_least_squares(&model, &data.dataset(), JointNoise::Estimated, &cfg).unwrap();
    let err = |l: &SVector<f64, 8>| rel_errors(l, &lambda).1.norm();
    eprintln!(
        "OLS {:.3e}  WLS(given) {:.3e}  WLS(estimated) {:.3e}",
        err(&ols.lambda),
        err(&wls.lambda),
        err(&est.lambda)
    );
    assert!(err(&wls.lambda) < 0.5 * err(&ols.lambda));
    assert!(err(&est.lambda) < 0.5 * err(&ols.lambda));
    // The weighted residual variance is ≈ 1 when the given variances are right.
    assert!((0.8..1.25).contains(&wls.sigma2), "σ²_w = {}", wls.sigma2);
    // Wider σ where it is honest: the weighted σ_i are smaller than the OLS ones for the
    // planar parameters joint 3 informs.
    assert!(wls.std_dev[2] < ols.std_dev[2]);
}

#[test]
fn unexcited_parameters_are_reported_with_their_directions() {
    let (model, _) = paper();
    // Only the prismatic joints move: λ2..λ7 never enter τ.
    let mut data = excitation(200, 6);
    for k in 0..data.len() {
        for j in 1..4 {
            data.q[k][j] = 0.3;
            data.qd[k][j] = 0.0;
            data.qdd[k][j] = 0.0;
        }
        data.tau[k] = model.inverse_dynamics(&data.q[k], &data.qd[k], &data.qdd[k], &paper().1);
    }
    let err = least_squares(&model, &data.dataset(), &LeastSquaresConfig::default()).unwrap_err();
    match err {
        PrrrpError::RankDeficient {
            rank,
            params,
            directions,
            ..
        } => {
            assert_eq!((rank, params), (2, 8));
            assert_eq!(directions.len(), 6);
            for d in &directions {
                let v = SVector::<f64, 8>::from_column_slice(d);
                assert!((v.norm() - 1.0).abs() < 1e-9);
                // Every unidentifiable direction lies in the span of λ2..λ7 …
                assert!(v[0].abs() < 1e-9 && v[7].abs() < 1e-9, "{v}");
                // … and is a null vector of every regressor.
                for k in (0..data.len()).step_by(17) {
                    let phi = model.regressor(&data.q[k], &data.qd[k], &data.qdd[k]);
                    assert!((phi * v).norm() < 1e-9);
                }
            }
        }
        other => panic!("expected RankDeficient, got {other:?}"),
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let (model, _) = paper();
    let mut data = excitation(50, 7);
    let cfg = LeastSquaresConfig::default();
    data.qd[13][2] = f64::NAN;
    match least_squares(&model, &data.dataset(), &cfg) {
        Err(PrrrpError::NonFinite { what, row }) => {
            assert_eq!(what, "qd");
            assert_eq!(row, Some(13));
        }
        other => panic!("{other:?}"),
    }
    let short = excitation(1, 7);
    assert!(matches!(
        least_squares(&model, &short.dataset(), &cfg),
        Err(PrrrpError::TooFewSamples { needed: 2, got: 1 })
    ));
    let d = excitation(10, 7);
    assert!(matches!(
        Samples::new(&d.q, &d.qd[..9], &d.qdd, &d.tau),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    let bad_cfg = LeastSquaresConfig {
        rank_tolerance: f64::NAN,
    };
    assert!(matches!(
        least_squares(&model, &d.dataset(), &bad_cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let mut var = Vec5::repeat(1.0);
    var[4] = 0.0;
    assert!(matches!(
        weighted_least_squares(&model, &d.dataset(), JointNoise::Variances(var), &cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
}

/// A model whose regressor couples every joint with every parameter: W is one block, the
/// solver factorises it without copying. Checked against an explicit solve.
#[test]
fn fully_coupled_model_is_solved_as_one_block() {
    use prrrp_core::nalgebra::{SMatrix, Vector2};
    use prrrp_core::{ForwardDerivatives, Result as PResult};
    struct Toy;
    impl LinearDynamics<2, 3> for Toy {
        fn regressor(
            &self,
            q: &Vector2<f64>,
            qd: &Vector2<f64>,
            qdd: &Vector2<f64>,
        ) -> SMatrix<f64, 2, 3> {
            SMatrix::<f64, 2, 3>::new(
                qdd[0],
                q[1].cos(),
                qd[0] * qd[1],
                qdd[1] + q[0],
                q[0].sin(),
                qd[1],
            )
        }
        fn forward_dynamics(
            &self,
            _: &Vector2<f64>,
            _: &Vector2<f64>,
            _: &Vector2<f64>,
            _: &SVector<f64, 3>,
        ) -> PResult<Vector2<f64>> {
            Ok(Vector2::zeros())
        }
        fn forward_derivatives(
            &self,
            _: &Vector2<f64>,
            _: &Vector2<f64>,
            _: &Vector2<f64>,
            _: &SVector<f64, 3>,
        ) -> PResult<ForwardDerivatives<2, 3>> {
            unimplemented!("not needed by least squares")
        }
    }
    let truth = SVector::<f64, 3>::new(1.5, -0.7, 0.3);
    let mut rng = StdRng::seed_from_u64(5);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut v = || Vector2::from_fn(|_, _| unit.sample(&mut rng));
    let (mut q, mut qd, mut qdd, mut tau) = (vec![], vec![], vec![], vec![]);
    let mut wtw = SMatrix::<f64, 3, 3>::zeros();
    let mut wty = SVector::<f64, 3>::zeros();
    for _ in 0..200 {
        let (a, b, c) = (v(), v(), v());
        let phi = Toy.regressor(&a, &b, &c);
        let t = phi * truth + 0.01 * v();
        wtw += phi.transpose() * phi;
        wty += phi.transpose() * t;
        q.push(a);
        qd.push(b);
        qdd.push(c);
        tau.push(t);
    }
    let data = Samples::new(&q, &qd, &qdd, &tau).unwrap();
    let rep = least_squares(&Toy, &data, &LeastSquaresConfig::default()).unwrap();
    let explicit = wtw.try_inverse().unwrap() * wty;
    assert!(
        (rep.lambda - explicit).norm() < 1e-10,
        "{} vs {}",
        rep.lambda,
        explicit
    );
    assert!((rep.lambda - truth).amax() < 0.01);
}
