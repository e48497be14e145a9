//! Validation of `Dataset`: every kind of bad input gets a typed error naming the column
//! and the first bad row.

use prrrp_core::{Dataset, DynDataset, PrrrpError, Vec5};

/// (t, q, qd, qdd, tau).
type Columns = (Vec<f64>, Vec<Vec5>, Vec<Vec5>, Vec<Vec5>, Vec<Vec5>);

fn columns(n: usize) -> Columns {
    let t: Vec<f64> = (0..n).map(|k| 0.02 * k as f64).collect();
    let col = |s: f64| -> Vec<Vec5> {
        (0..n)
            .map(|k| Vec5::from_fn(|j, _| s * (k * 5 + j) as f64))
            .collect()
    };
    (t, col(1.0), col(2.0), col(3.0), col(4.0))
}

#[test]
fn valid_dataset_keeps_its_columns() {
    let (t, q, qd, qdd, tau) = columns(12);
    let d = Dataset::new(t.clone(), q.clone(), qd.clone(), qdd.clone(), tau.clone()).unwrap();
    assert_eq!(d.len(), 12);
    assert!(!d.is_empty());
    assert_eq!(d.t(), &t[..]);
    let s = d.samples();
    assert_eq!(s.q(), &q[..]);
    assert_eq!(s.qd(), &qd[..]);
    assert_eq!(s.qdd(), &qdd[..]);
    assert_eq!(s.tau(), &tau[..]);
    // The flat columns are the same values, row-major.
    assert_eq!(d.tau()[5 * 7 + 3], tau[7][3]);
    assert_eq!(d.qd_row(4), qd[4].as_slice());
    assert!((d.duration() - 0.22).abs() < 1e-12);
    let p = d.into_parts();
    assert_eq!(p.dof, 5);
    assert_eq!(p.tau, tau.iter().flatten().copied().collect::<Vec<_>>());
}

#[test]
fn length_mismatch_names_the_column() {
    for bad in ["q", "qd", "qdd", "tau"] {
        let (t, mut q, mut qd, mut qdd, mut tau) = columns(10);
        match bad {
            "q" => drop(q.pop()),
            "qd" => drop(qd.pop()),
            "qdd" => qdd.push(Vec5::zeros()),
            _ => drop(tau.pop()),
        }
        match Dataset::new(t, q, qd, qdd, tau) {
            Err(PrrrpError::ShapeMismatch { what, .. }) => assert_eq!(what, bad),
            other => panic!("expected ShapeMismatch for {bad}, got {other:?}"),
        }
    }
}

#[test]
fn too_few_samples() {
    let (t, q, qd, qdd, tau) = columns(Dataset::MIN_SAMPLES - 1);
    assert_eq!(
        Dataset::new(t, q, qd, qdd, tau),
        Err(PrrrpError::TooFewSamples { needed: 8, got: 7 })
    );
    let (t, q, qd, qdd, tau) = columns(Dataset::MIN_SAMPLES);
    assert!(Dataset::new(t, q, qd, qdd, tau).is_ok());
}

#[test]
fn non_finite_values_name_column_joint_and_first_row() {
    let (t, q, qd, mut qdd, tau) = columns(20);
    qdd[7][2] = f64::NAN;
    qdd[9][0] = f64::INFINITY;
    assert_eq!(
        Dataset::new(t, q, qd, qdd, tau),
        Err(PrrrpError::NonFinite {
            what: "qdd[2] (joint 3)".into(),
            row: Some(7)
        })
    );

    let (mut t, q, qd, qdd, mut tau) = columns(20);
    tau[3][4] = f64::NEG_INFINITY;
    t[11] = f64::NAN;
    // Time is checked first.
    assert_eq!(
        Dataset::new(t, q, qd, qdd, tau),
        Err(PrrrpError::NonFinite {
            what: "t".into(),
            row: Some(11)
        })
    );
}

#[test]
fn values_beyond_any_log_name_column_joint_and_row() {
    // Finite but past MAX_MAGNITUDE: W overflowed and the fit read "'QR factor of W' has
    // a NaN". The value just below the bound is taken.
    let (t, mut q, qd, qdd, tau) = columns(20);
    q[4][1] = -1e300;
    match Dataset::new(t, q, qd, qdd, tau) {
        Err(PrrrpError::InvalidParameter { field, value, .. }) => {
            assert_eq!(field, "q[1] (joint 2) at row 4");
            assert_eq!(value, -1e300);
        }
        other => panic!("expected InvalidParameter, got {other:?}"),
    }
    let (mut t, q, qd, qdd, tau) = columns(20);
    t[19] = 1e100;
    assert!(
        matches!(Dataset::new(t, q, qd, qdd, tau), Err(PrrrpError::InvalidParameter { field, .. }) if field == "t at row 19")
    );
    let (t, q, qd, qdd, mut tau) = columns(20);
    tau[0][0] = 9.9e99;
    assert!(Dataset::new(t, q, qd, qdd, tau).is_ok());
}

#[test]
fn time_must_strictly_increase() {
    let (mut t, q, qd, qdd, tau) = columns(20);
    t[5] = t[4];
    t[15] = 0.0;
    assert_eq!(
        Dataset::new(t, q.clone(), qd.clone(), qdd.clone(), tau.clone()),
        Err(PrrrpError::NonIncreasingTime { row: 5 })
    );
    let (mut t, ..) = columns(20);
    t[19] = t[17];
    assert_eq!(
        Dataset::new(t, q, qd, qdd, tau),
        Err(PrrrpError::NonIncreasingTime { row: 19 })
    );
}

#[test]
fn row_major_constructor_matches_per_sample_one() {
    let (t, q, qd, qdd, tau) = columns(9);
    let flat = |c: &[Vec5]| -> Vec<f64> { c.iter().flat_map(|v| v.iter().copied()).collect() };
    let a = Dataset::from_row_major(&t, &flat(&q), &flat(&qd), &flat(&qdd), &flat(&tau)).unwrap();
    let b = Dataset::new(t.clone(), q.clone(), qd.clone(), qdd.clone(), tau.clone()).unwrap();
    assert_eq!(a, b);
    // Row-major: sample 3, joint 4 is flat entry 5·3 + 4.
    assert_eq!(a.q_row(3)[4], flat(&q)[19]);
    assert_eq!(a.samples().q()[3][4], flat(&q)[19]);

    let mut short = flat(&qd);
    short.pop();
    match Dataset::from_row_major(&t, &flat(&q), &short, &flat(&qdd), &flat(&tau)) {
        Err(PrrrpError::ShapeMismatch { what, .. }) => assert_eq!(what, "qd"),
        other => panic!("expected ShapeMismatch, got {other:?}"),
    }
    let mut bad = flat(&tau);
    bad[5 * 6 + 1] = f64::NAN;
    assert_eq!(
        Dataset::from_row_major(&t, &flat(&q), &flat(&qd), &flat(&qdd), &bad),
        Err(PrrrpError::NonFinite {
            what: "tau[1] (joint 2)".into(),
            row: Some(6)
        })
    );
}

#[test]
fn slice_is_validated() {
    let (t, q, qd, qdd, tau) = columns(30);
    let d = Dataset::new(t, q, qd, qdd, tau).unwrap();
    let s = d.slice(10..20).unwrap();
    assert_eq!(s.len(), 10);
    assert_eq!(s.t()[0], d.t()[10]);
    assert_eq!(s.tau_row(9), d.tau_row(19));
    assert!(matches!(
        d.slice(25..31),
        Err(PrrrpError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        d.slice(0..3),
        Err(PrrrpError::TooFewSamples { .. })
    ));
}

/// One validation serves both dimensions; the wording of a wrong column length stays
/// what each path said before they were one type (the Python tests match it).
#[test]
fn column_length_messages_of_both_dimensions() {
    let (t, q, ..) = columns(9);
    let full: Vec<f64> = q.iter().flatten().copied().collect();
    let mut short = full.clone();
    short.pop();
    assert_eq!(
        Dataset::from_row_major(&t, &full, &short, &full, &full),
        Err(PrrrpError::ShapeMismatch {
            what: "qd".into(),
            expected: "45 values (row-major, 5 joints per sample, 9 samples as t)".into(),
            got: "44 values".into(),
        })
    );
    assert_eq!(
        DynDataset::with_min_samples(5, 1, t, full.clone(), short, full.clone(), full),
        Err(PrrrpError::ShapeMismatch {
            what: "qd".into(),
            expected: "5·9 values (row-major, 5 joints per sample, 9 samples as t)".into(),
            got: "44 values".into(),
        })
    );
}
