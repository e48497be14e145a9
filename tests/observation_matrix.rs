//! The stacked observation matrix W and its condition number (eqs. 35–38).

use faer::Mat;
use nalgebra::DMatrix;
use prrrp_core::{condition_number, observation_matrix, PrrrpError, Robot, Vec5};

fn samples(n: usize) -> (Vec<Vec5>, Vec<Vec5>, Vec<Vec5>) {
    // A deterministic multi-sine motion that excites every joint.
    let (mut q, mut qd, mut qdd) = (vec![], vec![], vec![]);
    for k in 0..n {
        let t = k as f64 * 0.02;
        let f = [0.3, 0.5, 0.7, 1.1, 0.4];
        let amp = [0.1, 1.5, 2.0, 2.5, 0.05];
        let w = |j: usize| 2.0 * std::f64::consts::PI * f[j];
        q.push(Vec5::from_fn(|j, _| amp[j] * (w(j) * t).sin()));
        qd.push(Vec5::from_fn(|j, _| amp[j] * w(j) * (w(j) * t).cos()));
        qdd.push(Vec5::from_fn(|j, _| {
            -amp[j] * w(j) * w(j) * (w(j) * t).sin()
        }));
    }
    (q, qd, qdd)
}

#[test]
fn w_stacks_regressors_and_its_condition_number_matches_nalgebra_svd() {
    let model = Robot::paper().model();
    let (q, qd, qdd) = samples(200);
    let w = observation_matrix(&model, &q, &qd, &qdd).unwrap();
    assert_eq!((w.nrows(), w.ncols()), (1000, 8));
    let phi = model.regressor(&q[17], &qd[17], &qdd[17]);
    for i in 0..5 {
        for j in 0..8 {
            assert_eq!(w[(5 * 17 + i, j)], phi[(i, j)]);
        }
    }
    // Independent SVD (nalgebra's) of the same matrix.
    let dm = DMatrix::from_fn(w.nrows(), w.ncols(), |i, j| w[(i, j)]);
    let s = dm.singular_values();
    let want = s.max() / s.min();
    let got = condition_number(&w).unwrap();
    assert!((got - want).abs() <= 1e-8 * want, "{got} vs {want}");
    assert!(got.is_finite() && got > 1.0);
}

#[test]
fn condition_number_of_known_matrices() {
    let d = Mat::<f64>::from_fn(4, 3, |i, j| if i == j { [2.0, 8.0, 0.5][i] } else { 0.0 });
    assert!((condition_number(&d).unwrap() - 16.0).abs() < 1e-12);
    // Rank deficient: two equal columns.
    let r = Mat::<f64>::from_fn(5, 2, |i, _| i as f64 + 1.0);
    assert_eq!(condition_number(&r).unwrap(), f64::INFINITY);
    let wide = Mat::<f64>::zeros(2, 3);
    assert!(matches!(
        condition_number(&wide),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
}

#[test]
fn observation_matrix_rejects_bad_input() {
    let model = Robot::paper().model();
    let (q, qd, mut qdd) = samples(10);
    assert!(matches!(
        observation_matrix(&model, &q, &qd[..9], &qdd),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    qdd[4][2] = f64::NAN;
    match observation_matrix(&model, &q, &qd, &qdd) {
        Err(PrrrpError::NonFinite { what, row }) => {
            assert_eq!((what.as_str(), row), ("qdd", Some(4)))
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn static_data_cannot_identify_inertia() {
    // At rest only gravity acts: W has rank 2 (λ1 + λ8 and λ8), cond = ∞.
    let model = Robot::paper().model();
    let q = vec![Vec5::new(0.1, 0.2, 0.3, 0.4, 0.05); 20];
    let z = vec![Vec5::zeros(); 20];
    let w = observation_matrix(&model, &q, &z, &z).unwrap();
    assert_eq!(condition_number(&w).unwrap(), f64::INFINITY);
}
