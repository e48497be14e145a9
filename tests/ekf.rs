//! Extended Kalman filter: one step against a dense textbook implementation with a
//! finite-difference Jacobian, accuracy on a simulated closed-loop run, NaN handling,
//! symmetry, and bad input.

mod est_support;

use est_support::{closed_loop, line, paper, rel_errors};
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
    let data = closed_loop(40, 3, 10);
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
