//! Extended Kalman filter: one step against a dense textbook implementation with a
//! finite-difference Jacobian, accuracy on a simulated closed-loop run, NaN handling,
//! symmetry, and bad input.

mod est_support;

use est_support::{closed_loop, line, paper, rel_errors, DT};
use prrrp_core::nalgebra::{SMatrix, SVector};
use prrrp_core::{
    Discretisation, EkfConfig, EkfMeasurement, Estimator, Lambda, PrrrpEkf, PrrrpError, Sample,
    Vec5,
};

type M18 = SMatrix<f64, 18, 18>;
type V18 = SVector<f64, 18>;

/// The Euler map x⁺ = f(x, τ) written out from the forward dynamics.
fn euler(x: &V18, tau: &Vec5, h: f64, second_order: bool) -> V18 {
    let (model, _) = paper();
    let q = x.fixed_rows::<5>(0).into_owned();
    let v = x.fixed_rows::<5>(5).into_owned();
    let l = x.fixed_rows::<8>(10).into_owned();
    let qdd = model.forward_dynamics(&q, &v, tau, &l).unwrap();
    let mut out = *x;
    let c = if second_order { 0.5 * h * h } else { 0.0 };
    out.fixed_rows_mut::<5>(0).copy_from(&(q + h * v + c * qdd));
    out.fixed_rows_mut::<5>(5).copy_from(&(v + h * qdd));
    out
}

/// One dense EKF step: Joseph update with a selection H, then F·P·Fᵀ + Q with F from
/// central differences of the Euler map.
fn dense_step(
    x: &V18,
    p: &M18,
    z: &[(usize, f64, f64)],
    tau: &Vec5,
    h: f64,
    q_diag: &V18,
    second_order: bool,
) -> (V18, M18) {
    let m = z.len();
    let mut hm = SMatrix::<f64, 10, 18>::zeros();
    let mut r = SMatrix::<f64, 10, 10>::zeros();
    let mut zv = SVector::<f64, 10>::zeros();
    for (row, &(idx, val, var)) in z.iter().enumerate() {
        hm[(row, idx)] = 1.0;
        r[(row, row)] = var;
        zv[row] = val;
    }
    let hm = hm.rows(0, m).into_owned();
    let r = r.view((0, 0), (m, m)).into_owned();
    let zv = zv.rows(0, m).into_owned();
    let s = &hm * p * hm.transpose() + &r;
    let k = p * hm.transpose() * s.try_inverse().unwrap();
    let x_post = x + &k * (zv - &hm * x);
    let ikh = M18::identity() - &k * &hm;
    let p_post = ikh * p * ikh.transpose() + &k * r * k.transpose();

    let mut f = M18::zeros();
    for j in 0..18 {
        let step = 1e-6 * (1.0 + x_post[j].abs());
        let mut xp = x_post;
        let mut xm = x_post;
        xp[j] += step;
        xm[j] -= step;
        let col =
            (euler(&xp, tau, h, second_order) - euler(&xm, tau, h, second_order)) / (2.0 * step);
        f.set_column(j, &col);
    }
    let x_next = euler(&x_post, tau, h, second_order);
    let p_next = f * p_post * f.transpose() + M18::from_diagonal(q_diag);
    (x_next, p_next)
}

fn lambda0() -> Lambda {
    let (_, lambda) = paper();
    // Inertias up 30 %, couplings and masses down 30 %: wrong but physical.
    let signs = [1.0, 1.0, 1.0, -1.0, 1.0, -1.0, -1.0, -1.0];
    Lambda::from_fn(|i, _| lambda[i] * (1.0 + 0.3 * signs[i]))
}

#[test]
fn one_step_matches_a_dense_implementation() {
    let (model, _) = paper();
    let data = closed_loop(40, 3, 10, DT);
    let cases = [
        (EkfMeasurement::Positions, Discretisation::Euler),
        (EkfMeasurement::PositionsVelocities, Discretisation::Euler),
        (EkfMeasurement::Positions, Discretisation::SecondOrder),
        (
            EkfMeasurement::PositionsVelocities,
            Discretisation::SecondOrder,
        ),
    ];
    for (meas, disc) in cases {
        let cfg = EkfConfig {
            measurement: meas,
            discretisation: disc,
            process_parameter_noise: 1e-4,
            ..Default::default()
        };
        let mut ekf = PrrrpEkf::new(model, lambda0(), cfg).unwrap();
        let ds = data.dataset();
        // A few steps first, so that P is full and the state is off the measurements.
        for k in 0..30 {
            ekf.step(ds.sample(k)).unwrap();
        }
        let q_diag = {
            let mut d = V18::zeros();
            for i in 0..5 {
                d[i] = cfg.process_position_noise.powi(2);
                d[5 + i] = cfg.process_velocity_noise.powi(2);
            }
            for i in 0..8 {
                d[10 + i] = (cfg.process_parameter_noise * lambda0()[i]).powi(2);
            }
            d
        };
        for k in 30..40 {
            let x = *ekf.state();
            let p = *ekf.covariance();
            let s = ds.sample(k);
            let mut z = Vec::new();
            for i in 0..5 {
                z.push((i, s.q[i], cfg.position_noise.powi(2)));
            }
            if meas == EkfMeasurement::PositionsVelocities {
                for i in 0..5 {
                    z.push((5 + i, s.qd[i], cfg.velocity_noise.powi(2)));
                }
            }
            let (x_ref, p_ref) = dense_step(
                &x,
                &p,
                &z,
                s.tau,
                cfg.dt,
                &q_diag,
                disc == Discretisation::SecondOrder,
            );
            let lam = *ekf.step(s).unwrap();
            let x_new = *ekf.state();
            let p_new = *ekf.covariance();
            for i in 0..18 {
                let tol = 1e-7 * (1.0 + x_ref[i].abs());
                assert!(
                    (x_new[i] - x_ref[i]).abs() < tol,
                    "{meas:?} k {k} x[{i}]: {} vs {}",
                    x_new[i],
                    x_ref[i]
                );
            }
            for i in 0..18 {
                for j in 0..18 {
                    let scale = (p_ref[(i, i)] * p_ref[(j, j)]).sqrt();
                    assert!(
                        (p_new[(i, j)] - p_ref[(i, j)]).abs() < 1e-6 * scale,
                        "{meas:?} k {k} P[{i},{j}]: {:e} vs {:e}",
                        p_new[(i, j)],
                        p_ref[(i, j)]
                    );
                    assert_eq!(p_new[(i, j)], p_new[(j, i)], "P exactly symmetric");
                }
            }
            assert_eq!(lam, x_new.fixed_rows::<8>(10).into_owned());
        }
    }
}

/// λ₀ patterns: inertias up and couplings down, all up, all down (30 %), all physical.
fn starts() -> [(&'static str, Lambda); 3] {
    let (_, lambda) = paper();
    let f = |signs: [f64; 8]| Lambda::from_fn(|i, _| lambda[i] * (1.0 + 0.3 * signs[i]));
    [
        ("mixed", f([1.0, 1.0, 1.0, -1.0, 1.0, -1.0, -1.0, -1.0])),
        ("up", f([1.0; 8])),
        ("down", f([-1.0; 8])),
    ]
}

/// Runs the filter over a closed-loop record and returns the relative errors.
fn run(cfg: EkfConfig, lambda0: Lambda, n: usize, seed: u64, dt: f64) -> Lambda {
    let (model, lambda) = paper();
    let data = closed_loop(n, seed, 10, dt);
    let mut ekf = PrrrpEkf::new(model, lambda0, cfg).unwrap();
    ekf.run(&data.dataset()).unwrap();
    rel_errors(ekf.estimate(), &lambda).1
}

/// Second-order discretisation at the paper's 50 Hz: every λ within 1 % after 3000
/// samples (60 s), from starts 30 % off, on two trajectories.
#[test]
fn second_order_recovers_lambda_to_1_percent() {
    let cfg = EkfConfig {
        discretisation: Discretisation::SecondOrder,
        ..Default::default()
    };
    for seed in [1, 2] {
        for (name, l0) in starts() {
            let e = run(cfg, l0, 3000, seed, DT);
            eprintln!("EKF second order seed {seed} {name}: {}", line(&e));
            assert!(e.max() < 0.01, "seed {seed} {name}: {}", line(&e));
        }
    }
}

/// The paper's Euler step: its bias is O(h) (the second difference of q is h²·q̈_k instead
/// of h²·(q̈_k + q̈_k+1)/2), so at 100 Hz it is within 1 % after 6000 samples (60 s); at 50
/// Hz it stays near 1 % (measured and reported, see the notes).
#[test]
fn euler_recovers_lambda_to_1_percent_at_100_hz() {
    let cfg = EkfConfig {
        dt: 0.01,
        ..Default::default()
    };
    let mut worst_50 = 0.0f64;
    for seed in [1, 2] {
        for (name, l0) in starts() {
            let e = run(cfg, l0, 6000, seed, 0.01);
            eprintln!("EKF Euler 100 Hz seed {seed} {name}: {}", line(&e));
            assert!(e.max() < 0.01, "seed {seed} {name}: {}", line(&e));
            let e50 = run(EkfConfig::default(), l0, 3000, seed, DT);
            eprintln!("EKF Euler  50 Hz seed {seed} {name}: {}", line(&e50));
            worst_50 = worst_50.max(e50.max());
        }
    }
    // The 50 Hz bias is real but bounded: it does not keep the filter from converging.
    assert!(worst_50 < 0.03, "Euler at 50 Hz: {worst_50}");
}

#[test]
fn nan_measurement_skips_the_update_only() {
    let (model, lambda) = paper();
    let data = closed_loop(400, 1, 10, DT);
    let mut holes = data.clone();
    for k in (50..400).step_by(7) {
        holes.q[k][k % 5] = f64::NAN;
    }
    let cfg = EkfConfig::default();
    let mut a = PrrrpEkf::new(model, lambda * 1.1, cfg).unwrap();
    let mut b = PrrrpEkf::new(model, lambda * 1.1, cfg).unwrap();
    for k in 0..400 {
        a.step(data.dataset().sample(k)).unwrap();
        b.step(holes.dataset().sample(k)).unwrap();
        assert!(b.state().iter().all(|v| v.is_finite()));
    }
    assert_eq!(b.skipped_updates(), 50);
    assert_eq!(a.skipped_updates(), 0);
    // Losing one in seven position samples barely changes the estimate.
    let d = (a.estimate() - b.estimate()).component_div(&lambda).amax();
    assert!(d < 0.01, "{d}");
    // A NaN torque cannot be skipped: it is an error naming τ.
    let mut bad = data.clone();
    bad.tau[3][1] = f64::NAN;
    let mut e = PrrrpEkf::new(model, lambda, cfg).unwrap();
    match e.run(&bad.dataset()) {
        Err(PrrrpError::NonFinite { what, row }) => {
            assert_eq!(what, "tau");
            assert_eq!(row, Some(3));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_pure_prediction_matches_the_model() {
    // With every measurement missing, one step is exactly the Euler map of the model.
    let (model, lambda) = paper();
    let q = Vec5::new(0.1, 0.2, -0.3, 0.4, 0.05);
    let qd = Vec5::new(0.3, -0.2, 0.5, 0.1, -0.1);
    let tau = Vec5::new(50.0, 0.1, -0.05, 0.02, -4.0);
    let nan = Vec5::repeat(f64::NAN);
    let zero = Vec5::zeros();
    // A filter that measures q̇ too, so that one update pins both q and q̇.
    let cfg = EkfConfig {
        measurement: EkfMeasurement::PositionsVelocities,
        ..Default::default()
    };
    let mut ekf2 = PrrrpEkf::new(model, lambda, cfg).unwrap();
    ekf2.step(Sample::new(&q, &qd, &zero, &tau)).unwrap();
    let x1 = *ekf2.state();
    ekf2.step(Sample::new(&nan, &nan, &zero, &tau)).unwrap();
    let x2 = *ekf2.state();
    let q1 = x1.fixed_rows::<5>(0).into_owned();
    let v1 = x1.fixed_rows::<5>(5).into_owned();
    let a = model.forward_dynamics(&q1, &v1, &tau, &lambda).unwrap();
    let h = cfg.dt;
    assert!((x2.fixed_rows::<5>(0) - (q1 + h * v1)).amax() < 1e-15);
    assert!((x2.fixed_rows::<5>(5) - (v1 + h * a)).amax() < 1e-13);
    assert_eq!(ekf2.skipped_updates(), 2);
}

#[test]
fn bad_configuration_and_non_physical_start_are_typed_errors() {
    let (model, lambda) = paper();
    let cfg = EkfConfig {
        dt: 0.0,
        ..Default::default()
    };
    assert!(matches!(
        PrrrpEkf::new(model, lambda, cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    let cfg = EkfConfig {
        position_noise: f64::NAN,
        ..Default::default()
    };
    assert!(matches!(
        PrrrpEkf::new(model, lambda, cfg),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // Finite, but squared into a variance of 0 or inf.
    for cfg in [
        EkfConfig {
            position_noise: 1e-300,
            ..Default::default()
        },
        EkfConfig {
            initial_velocity_std: 1e300,
            ..Default::default()
        },
    ] {
        assert!(matches!(
            PrrrpEkf::new(model, lambda, cfg),
            Err(PrrrpError::InvalidParameter { .. })
        ));
    }
    let mut l = lambda;
    l[0] = f64::INFINITY;
    assert!(matches!(
        PrrrpEkf::new(model, l, EkfConfig::default()),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // λ₀ = ones (the paper's eq. 44) makes the planar mass matrix indefinite at some
    // configurations: the filter reports it instead of producing NaN.
    let mut ekf = PrrrpEkf::new(model, Lambda::repeat(1.0), EkfConfig::default()).unwrap();
    let q = Vec5::new(0.0, 0.0, std::f64::consts::PI, 0.0, 0.0);
    let z = Vec5::zeros();
    let tau = Vec5::zeros();
    match ekf.step(Sample::new(&q, &z, &z, &tau)) {
        Err(PrrrpError::Diverged { .. }) => {}
        other => panic!("{other:?}"),
    }
    // The filter is left at its prior, finite.
    assert!(ekf.state().iter().all(|v| v.is_finite()));
    // Covariance setters validate.
    let mut p0 = SMatrix::<f64, 18, 18>::identity();
    p0[(0, 1)] = 0.5;
    assert!(ekf.set_initial_covariance(&p0).is_err());
    p0[(1, 0)] = 0.5;
    assert!(ekf.set_initial_covariance(&p0).is_ok());
    p0[(0, 1)] = 2.0;
    p0[(1, 0)] = 2.0;
    assert!(matches!(
        ekf.set_initial_covariance(&p0),
        Err(PrrrpError::NotPositiveDefinite { .. })
    ));
    let mut r = Vec5::repeat(1e-6);
    assert!(ekf.set_measurement_noise(&r, &r).is_ok());
    r[2] = 0.0;
    assert!(ekf.set_measurement_noise(&r, &r).is_err());
    assert!(ekf.set_process_noise(&SVector::<f64, 18>::zeros()).is_ok());
    assert!(ekf
        .set_process_noise(&SVector::<f64, 18>::repeat(-1.0))
        .is_err());
}
