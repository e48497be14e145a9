//! Independent check of the closed-form PRRRP model against Pinocchio, a rigid-body library
//! no one here wrote. The reference file is produced by `scripts/pinocchio_reference.py`,
//! which builds the arm joint by joint (not from λ) and runs RNEA, CRBA and ABA.

use prrrp_core::{Mat5, Robot, Vec5};

struct Row {
    q: Vec5,
    qd: Vec5,
    qdd: Vec5,
    tau: Vec5,
    m: Mat5,
    nle: Vec5,
    tau_fd: Vec5,
    qdd_fd: Vec5,
}

fn load() -> Vec<Row> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/pinocchio_reference.txt"
    );
    let text = std::fs::read_to_string(path).expect("reference file is committed");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let x: Vec<f64> = l.split_whitespace().map(|s| s.parse().unwrap()).collect();
            assert_eq!(x.len(), 5 * 4 + 25 + 5 * 3);
            let v = |i: usize| Vec5::from_column_slice(&x[i..i + 5]);
            Row {
                q: v(0),
                qd: v(5),
                qdd: v(10),
                tau: v(15),
                m: Mat5::from_row_slice(&x[20..45]),
                nle: v(45),
                tau_fd: v(50),
                qdd_fd: v(55),
            }
        })
        .collect()
}

/// Relative error with a floor of 1 on the scale, so that entries near zero are compared
/// absolutely: Pinocchio and the closed form differ only by round-off (≈1e-15 relative),
/// so 1e-10 leaves ample room for accumulated round-off while catching any wrong term
/// (the smallest physical term, λ7-scale Coriolis at 1 rad/s, is ≈ 1e-2).
fn close(a: &[f64], b: &[f64]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| (x - y).abs() <= 1e-10 * (1.0 + y.abs()))
}

#[test]
fn closed_form_matches_pinocchio() {
    let robot = Robot::paper();
    let lambda = robot.base_parameters();
    let model = robot.model();
    let rows = load();
    assert_eq!(rows.len(), 64);
    for (k, r) in rows.iter().enumerate() {
        let tau = model.inverse_dynamics(&r.q, &r.qd, &r.qdd, &lambda);
        assert!(
            close(tau.as_slice(), r.tau.as_slice()),
            "row {k}: τ {tau} vs {}",
            r.tau
        );
        let phi_tau = model.regressor(&r.q, &r.qd, &r.qdd) * lambda;
        assert!(
            close(phi_tau.as_slice(), r.tau.as_slice()),
            "row {k}: Φλ {phi_tau} vs {}",
            r.tau
        );
        let m = model.mass_matrix(&r.q, &lambda);
        assert!(
            close(m.as_slice(), r.m.as_slice()),
            "row {k}: M {m} vs {}",
            r.m
        );
        let nle = model.nonlinear_effects(&r.q, &r.qd, &lambda);
        assert!(
            close(nle.as_slice(), r.nle.as_slice()),
            "row {k}: nle {nle} vs {}",
            r.nle
        );
        let g = model.gravity_vector(&lambda);
        let cor = model.coriolis(&r.q, &r.qd, &lambda);
        assert!(
            close((cor + g).as_slice(), r.nle.as_slice()),
            "row {k}: C·q̇ + G"
        );
        let qdd = model
            .forward_dynamics(&r.q, &r.qd, &r.tau_fd, &lambda)
            .unwrap();
        assert!(
            close(qdd.as_slice(), r.qdd_fd.as_slice()),
            "row {k}: q̈ {qdd} vs {}",
            r.qdd_fd
        );
    }
}
