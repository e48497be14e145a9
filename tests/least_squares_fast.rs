//! The normal-equations path of batch least squares against the Householder QR path
//! (forced through the rank tolerance: a tolerance τ with τ·cond < 1 < 2·τ·cond keeps the
//! rank full but denies the fast path its margin), and the QR fallback of an
//! ill-conditioned, full-rank W against an SVD solve of W built here.

#[path = "dyn_support/mod.rs"]
mod dyn_support;
#[path = "est_support/mod.rs"]
mod est_support;

use dyn_support::{base_model, exact_record, panda_like, DynFourier};
use est_support::{add_noise, excitation, paper, Noise};
use prrrp_core::nalgebra::allocator::Allocator;
use prrrp_core::nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, SVector, U5, U8};
use prrrp_core::{
    JointNoise, LeastSquares, LeastSquaresConfig, LeastSquaresReportOf, LinearModel, PrrrpError,
    ScaledModel,
};

type PResult<T> = Result<T, PrrrpError>;

const EPS: f64 = f64::EPSILON;

fn rel(a: &[f64], b: &[f64]) -> f64 {
    let d: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt();
    d / b.iter().map(|y| y * y).sum::<f64>().sqrt()
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs())
        .fold(0.0, f64::max)
}

/// A configuration whose rank tolerance sends a problem of condition number `cond` to
/// the QR path while keeping it full rank there.
fn qr_config(cond: f64) -> LeastSquaresConfig {
    LeastSquaresConfig {
        rank_tolerance: 0.75 / cond,
    }
}

/// Runs `solve` with the default configuration, which must take the normal equations,
/// then with a fresh solver forced onto the QR path at the first solve's cond. Returns the
/// default solver, both reports and the bound 10·cond²·ε on their difference.
fn fast_and_qr<N: Dim, P: Dim>(
    solve: impl Fn(&mut LeastSquares) -> PResult<LeastSquaresReportOf<N, P>>,
) -> (
    LeastSquares,
    LeastSquaresReportOf<N, P>,
    LeastSquaresReportOf<N, P>,
    f64,
)
where
    DefaultAllocator: Allocator<N> + Allocator<P>,
{
    let mut fast = LeastSquares::new(LeastSquaresConfig::default()).unwrap();
    let f = solve(&mut fast).unwrap();
    assert!(fast.used_normal_equations());
    let mut qr = LeastSquares::new(qr_config(f.cond)).unwrap();
    let q = solve(&mut qr).unwrap();
    assert!(!qr.used_normal_equations());
    let bound = 10.0 * f.cond * f.cond * EPS;
    (fast, f, q, bound)
}

#[test]
fn fast_path_agrees_with_qr_on_noisy_prrrp_data() {
    let (model, _) = paper();
    let (data, _) = add_noise(&excitation(5000, 2), Noise::realistic(), 3);
    let ds = data.dataset();
    let (_, f, q, bound) = fast_and_qr(|s| s.solve(&model, &ds));
    println!("cond {:.1}, bound {bound:.1e}", f.cond);
    let d = rel(f.lambda.as_slice(), q.lambda.as_slice());
    println!("λ: {d:.1e}");
    assert!(d <= bound, "{d}");
    let d = max_rel(f.singular_values.as_slice(), q.singular_values.as_slice());
    println!("singular values: {d:.1e}");
    assert!(d <= bound, "{d}");
    assert!((f.cond / q.cond - 1.0).abs() <= bound);
    // Noise dominates the residual: σ², σ_i and the per-joint variances agree closely.
    for (name, a, b) in [
        ("sigma2", vec![f.sigma2], vec![q.sigma2]),
        (
            "std_dev",
            f.std_dev.as_slice().to_vec(),
            q.std_dev.as_slice().to_vec(),
        ),
        (
            "joint_variances",
            f.joint_variances.as_slice().to_vec(),
            q.joint_variances.as_slice().to_vec(),
        ),
    ] {
        let d = max_rel(&a, &b);
        println!("{name}: {d:.1e}");
        assert!(d <= bound, "{name}: {d}");
    }
}

#[test]
fn weighted_fast_path_agrees_with_qr() {
    let (model, _) = paper();
    let (data, sigma) = add_noise(&excitation(3000, 4), Noise::realistic(), 5);
    let ds = data.dataset();
    let var = JointNoise::<5>::Variances(sigma.map(|s| s * s));
    let (mut fast, f, q, bound) = fast_and_qr(|s| s.solve_weighted(&model, &ds, var));
    let d = rel(f.lambda.as_slice(), q.lambda.as_slice());
    println!("WLS cond {:.1}: λ {d:.1e}", f.cond);
    assert!(d <= bound, "{d}");
    let d = max_rel(f.std_dev.as_slice(), q.std_dev.as_slice());
    assert!(d <= bound, "{d}");
    assert!((f.sigma2 / q.sigma2 - 1.0).abs() <= bound);
    // Estimated variances: the same fixed point through either path.
    let fe = fast
        .solve_weighted(&model, &ds, JointNoise::<5>::Estimated)
        .unwrap();
    let mut qr = LeastSquares::new(qr_config(fe.cond)).unwrap();
    let qe = qr
        .solve_weighted(&model, &ds, JointNoise::<5>::Estimated)
        .unwrap();
    assert!(!qr.used_normal_equations());
    let d = max_rel(fe.joint_variances.as_slice(), qe.joint_variances.as_slice());
    println!("estimated variances: {d:.1e}");
    assert!(d <= 1e-9, "{d}");
    assert!(rel(fe.lambda.as_slice(), qe.lambda.as_slice()) <= bound);
}

/// The 7-joint chain (64 base parameters, cond ≈ 1.6e3): exact data, so compare λ and
/// the spectrum (the residual is rounding).
#[test]
fn fast_path_agrees_with_qr_on_the_panda_like_chain() {
    let chain = panda_like();
    let model = base_model(&chain);
    let rec = exact_record(&chain, &DynFourier::seeded(11, 7, 1.0), 2000, 0.01);
    let (_, f, q, bound) = fast_and_qr(|s| s.solve(&model, &rec.samples()));
    let d = rel(f.lambda.as_slice(), q.lambda.as_slice());
    println!("chain cond {:.1}, bound {bound:.1e}: λ {d:.1e}", f.cond);
    assert!(d <= bound, "{d}");
    let d = max_rel(f.singular_values.as_slice(), q.singular_values.as_slice());
    println!("singular values: {d:.1e}");
    assert!(d <= bound, "{d}");
}

/// One parameter column scaled by 1e-6: full rank, cond(W) ≈ 1e8, so the normal equations
/// (error ≈ cond²·ε ≫ 1) must not be used; the QR result matches a nalgebra SVD solve of
/// the same W, and its singular values match the SVD's.
#[test]
fn ill_conditioned_full_rank_falls_back_to_qr() {
    let (inner, _) = paper();
    let mut scale = SVector::<f64, 8>::repeat(1.0);
    scale[3] = 1e-6;
    let model = ScaledModel::new(inner, scale).unwrap();
    let (data, _) = add_noise(&excitation(2000, 6), Noise::realistic(), 7);
    let ds = data.dataset();
    let mut solver = LeastSquares::new(LeastSquaresConfig::default()).unwrap();
    let r = solver.solve(&model, &ds).unwrap();
    assert!(!solver.used_normal_equations());
    assert!(r.cond > 1e6, "{}", r.cond);

    // Reference: W and τ stacked here, solved by SVD.
    let n = ds.len();
    let mut w = DMatrix::<f64>::zeros(5 * n, 8);
    let mut y = DVector::<f64>::zeros(5 * n);
    let mut phi = prrrp_core::nalgebra::OMatrix::<f64, U5, U8>::zeros();
    for (k, s) in ds.iter().enumerate() {
        model
            .regressor_into(&mut model.workspace(), s.q, s.qd, s.qdd, &mut phi)
            .unwrap();
        for i in 0..5 {
            y[5 * k + i] = s.tau[i];
            for j in 0..8 {
                w[(5 * k + i, j)] = phi[(i, j)];
            }
        }
    }
    let svd = w.svd(true, true);
    let reference = svd.solve(&y, 0.0).unwrap();
    // Both are backward stable: they agree to ≈ cond·ε (the normal equations would be off
    // by cond²·ε ≫ 1).
    let bound = r.cond * EPS;
    let d = max_rel(r.lambda.as_slice(), reference.as_slice());
    println!("cond {:.1e}: λ vs SVD {d:.1e}, bound {bound:.1e}", r.cond);
    assert!(d <= bound, "{d}");
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    let ds = max_rel(r.singular_values.as_slice(), &sv);
    println!("singular values vs SVD {ds:.1e}");
    assert!(ds <= bound, "{ds}");
}
