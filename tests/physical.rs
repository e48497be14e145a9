//! Physically consistent identification and the feasibility report, checked against
//! physics rather than against the estimator's own output:
//! - on exact inverse-dynamics data of physical robots (PUMA 560, a Panda-like 7R arm with
//!   friction) the estimate reproduces the true base parameters;
//! - on few noisy samples, where least squares gives base values no rigid bodies have
//!   (shown by the base-feasibility solve and by the standard vector nearest to the
//!   prior), the estimate is consistent and predicts torques on another trajectory about
//!   as well;
//! - the report's numbers for bodies whose moments are known in closed form (point mass,
//!   thin rod, a body breaking the triangle inequality);
//! - typed errors for bad input.

mod dyn_support;

use dyn_support::{exact_record, panda_like, DynFourier, DynRecord};
use prrrp_core::faer::Mat;
use prrrp_core::{
    base_feasibility, identify_physical, inertial_parameters, standard_from_base, BaseParameters,
    DynChain, FeasibilityReport, FrictionModel, LinkFeasibility, PhysicalConfig, PhysicalEstimate,
    PhysicalProblem, PrrrpError, SerialChain,
};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Flat row-major (samples × n) columns of a record.
struct Flat {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    tau: Vec<f64>,
}

impl Flat {
    /// The physical-identification problem of these samples.
    fn problem(&self, chain: &DynChain, cfg: &PhysicalConfig) -> PhysicalProblem {
        PhysicalProblem::new(chain, &self.q, &self.qd, &self.qdd, &self.tau, cfg).unwrap()
    }

    /// [`identify_physical`] on these samples.
    fn identify(
        &self,
        chain: &DynChain,
        cfg: &PhysicalConfig,
    ) -> Result<PhysicalEstimate, PrrrpError> {
        identify_physical(chain, &self.q, &self.qd, &self.qdd, &self.tau, cfg)
    }
}

fn flat(rec: &DynRecord) -> Flat {
    let cat = |v: &[prrrp_core::nalgebra::DVector<f64>]| {
        v.iter()
            .flat_map(|x| x.iter().copied())
            .collect::<Vec<f64>>()
    };
    Flat {
        q: cat(&rec.q),
        qd: cat(&rec.qd),
        qdd: cat(&rec.qdd),
        tau: cat(&rec.tau),
    }
}

fn data(chain: &DynChain, seed: u64, samples: usize, dt: f64) -> Flat {
    let reference = DynFourier::seeded(seed, chain.dof(), 1.0);
    flat(&exact_record(chain, &reference, samples, dt))
}

/// `d` with seeded Gaussian noise of standard deviation `sigma` (N·m) on every torque.
fn with_noise(mut d: Flat, sigma: f64, seed: u64) -> Flat {
    let mut rng = StdRng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma).unwrap();
    for t in &mut d.tau {
        *t += normal.sample(&mut rng);
    }
    d
}

/// max_r |a_r − b_r| / max(|b_r|, 1e-4·max|b|): entries that vanish for the true robot (e.g.
/// products of inertia of the PUMA) are compared at 1e-4 of the largest.
fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    let bmax = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / y.abs().max(1e-4 * bmax))
        .fold(0.0, f64::max)
}

/// The chain's standard parameters with every link's ten inertial entries times `inertial`
/// and every friction coefficient times `friction`: another robot, consistent when both
/// factors are positive.
fn scaled_parameters(chain: &DynChain, inertial: f64, friction: f64) -> Vec<f64> {
    let links = 10 * chain.dof();
    chain
        .parameters()
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if k < links {
                inertial * v
            } else {
                friction * v
            }
        })
        .collect()
}

/// The standard vector identified on `d` with `prior` at `prior_weight`, and its largest
/// relative distance ([`max_rel`]) to `expected`.
fn prior_estimate_error(
    chain: &DynChain,
    d: &Flat,
    prior: Vec<f64>,
    prior_weight: f64,
    expected: &[f64],
) -> f64 {
    let cfg = PhysicalConfig {
        prior: Some(prior),
        prior_weight,
        ..PhysicalConfig::default()
    };
    let est = d.identify(chain, &cfg).unwrap();
    max_rel(&est.parameters, expected)
}

/// RMS of W·π − τ on a record.
fn rms_error(w: &Mat<f64>, pi: &[f64], tau: &[f64]) -> f64 {
    let mut s = 0.0;
    for i in 0..w.nrows() {
        let pred: f64 = (0..w.ncols()).map(|j| w[(i, j)] * pi[j]).sum();
        s += (pred - tau[i]).powi(2);
    }
    (s / w.nrows() as f64).sqrt()
}

/// RMS torque errors on a held-out trajectory (seed 77, exact torques) of the standard
/// vector `pi` and of the base values `beta`.
fn held_out_rms(
    chain: &DynChain,
    base: &BaseParameters,
    pi: &[f64],
    beta: &[f64],
    samples: usize,
    dt: f64,
) -> (f64, f64) {
    let test = data(chain, 77, samples, dt);
    let w = chain
        .observation_matrix(&test.q, &test.qd, &test.qdd)
        .unwrap();
    let wb = base.select_columns(&w).unwrap();
    (
        rms_error(&w, pi, &test.tau),
        rms_error(&wb, beta, &test.tau),
    )
}

fn exact_recovery(chain: &DynChain, samples: usize) {
    let d = data(chain, 11, samples, 0.02);
    let est = d.identify(chain, &PhysicalConfig::default()).unwrap();
    let truth = est
        .base_parameters
        .base_values(&chain.parameters())
        .unwrap();
    let err = max_rel(&est.base, &truth);
    let worst = (0..truth.len())
        .max_by(|&i, &j| {
            let e = |k: usize| (est.base[k] - truth[k]).abs() / truth[k].abs().max(1e-12);
            e(i).total_cmp(&e(j))
        })
        .unwrap();
    assert!(
        err < 1e-6,
        "base parameters off by {err:e} (relative); worst {} = {} vs {}",
        est.base_parameters.combinations[worst],
        est.base[worst],
        truth[worst]
    );
    assert!(est.feasibility.is_feasible(), "{:?}", est.feasibility);
    assert!(est.residual < 1e-6 * d.tau.iter().map(|t| t * t).sum::<f64>().sqrt());
    // The least-squares estimate on exact data is the truth as well.
    assert!(max_rel(&est.ls_base, &truth) < 1e-6);
}

#[test]
fn exact_data_recover_true_base_parameters_puma() {
    exact_recovery(&SerialChain::puma560().to_dyn(), 400);
}

#[test]
fn exact_data_recover_true_base_parameters_7r_with_friction() {
    exact_recovery(&panda_like(), 400);
}

/// With the true parameters as prior, exact data fix the base directions and the prior
/// the others: the whole standard vector is recovered, not only its base values.
#[test]
fn prior_fixes_unidentifiable_directions() {
    let chain = panda_like();
    let d = data(&chain, 5, 200, 0.05);
    let truth = chain.parameters();
    let weight = PhysicalConfig::default().prior_weight;
    let err = prior_estimate_error(&chain, &d, truth.clone(), weight, &truth);
    assert!(err < 1e-6, "standard parameters off by {err:e}");
}

/// The divergence prior does to the base parameters what a maximum a posteriori estimate
/// should, no more: with a prior off the truth (every link 1.2 times heavier and larger)
/// and noisy torques whose least-squares fit is itself physical (so that the constraints
/// move nothing), the estimate is the Gaussian MAP of the least-squares β (covariance
/// σ̂²·(W_bᵀW_b)⁻¹) and the prior (precision (γ/2)·∇²D at the prior, the objective being
/// χ² + γ·D), solved here by plain linear algebra — to a tenth of each base parameter's
/// σ. The data's blind spot (link 1's mass: the first axis is vertical) is the prior's.
#[test]
fn divergence_prior_is_the_maximum_a_posteriori_estimate() {
    use prrrp_core::nalgebra::{DMatrix, DVector, Matrix4};
    let chain = panda_like();
    let d = with_noise(data(&chain, 8, 2000, 0.01), 0.005, 3);
    let prior = scaled_parameters(&chain, 1.2, 1.0);
    let cfg = PhysicalConfig {
        prior: Some(prior.clone()),
        ..PhysicalConfig::default()
    };
    let problem = d.problem(&chain, &cfg);
    let est = problem.solve(&cfg).unwrap();
    let base = problem.base_parameters().clone();
    let bf = base_feasibility(&base, &est.ls_base, &PhysicalConfig::default()).unwrap();
    assert!(bf.feasible, "LS mismatch {:e}", bf.max_relative_mismatch);
    let (b, p) = (base.count(), base.num_standard());
    // Data: β ~ N(β_LS, σ̂²·(W_bᵀW_b)⁻¹), i.e. χ² = (Kπ − β_LS)ᵀ·G/σ̂²·(Kπ − β_LS).
    let w = chain.observation_matrix(&d.q, &d.qd, &d.qdd).unwrap();
    let wb = base.select_columns(&w).unwrap();
    let gram = DMatrix::from_fn(b, b, |i, j| {
        (0..wb.nrows())
            .map(|r| wb[(r, i)] * wb[(r, j)])
            .sum::<f64>()
    });
    let data_info = &gram / est.residual_variance;
    let k = DMatrix::from_fn(b, p, |r, j| base.map[(r, j)]);
    // Prior: (γ/2)·∇²D per link, ∇²D_kl = tr(J₀⁻¹A_k·J₀⁻¹A_l).
    let basis: Vec<Matrix4<f64>> = (0..10)
        .map(|c| {
            let mut e = [0.0; 10];
            e[c] = 1.0;
            prrrp_core::pseudo_inertia(&e)
        })
        .collect();
    let gamma = PhysicalConfig::default().divergence_weight;
    let mut prior_info = DMatrix::zeros(p, p);
    for i in 0..7 {
        let mut l = [0.0; 10];
        l.copy_from_slice(&prior[10 * i..10 * i + 10]);
        let j0inv = prrrp_core::pseudo_inertia(&l).try_inverse().unwrap();
        for a in 0..10 {
            for c in 0..10 {
                prior_info[(10 * i + a, 10 * i + c)] =
                    (j0inv * basis[a] * j0inv * basis[c]).trace() * gamma / 2.0;
            }
        }
    }
    // MAP: (Kᵀ·I_d·K + I_p)·π = Kᵀ·I_d·β_LS + I_p·π₀ (friction: no prior, but seen).
    let ls = DVector::from_column_slice(&est.ls_base);
    let pi0 = DVector::from_column_slice(&prior);
    let lhs = k.transpose() * &data_info * &k + &prior_info;
    let rhs = k.transpose() * &data_info * &ls + &prior_info * &pi0;
    let map = lhs.cholesky().expect("MAP system").solve(&rhs);
    let beta_map = &k * &map;
    let data_cov = gram.cholesky().unwrap().inverse() * est.residual_variance;
    // (Measured: within 0.025 σ; 0.09 σ with a prior 50 % off, where D is less quadratic.
    // The largest move from least squares was 0.31 σ, the MAP's 0.29 σ.)
    for r in 0..b {
        let s = data_cov[(r, r)].sqrt();
        let (got, want) = (est.base[r] - ls[r], beta_map[r] - ls[r]);
        assert!(
            (got - want).abs() <= 0.1 * s,
            "{}: moved {:.3} σ, the MAP {:.3} σ",
            base.combinations[r],
            got / s,
            want / s
        );
    }
    assert!(
        (est.parameters[0] / prior[0] - 1.0).abs() < 0.05,
        "m1 {} against the prior's {}",
        est.parameters[0],
        prior[0]
    );
}

/// A heavy prior weight pulls the estimate onto the prior, whatever the data.
#[test]
fn heavy_prior_weight_returns_the_prior() {
    let chain = panda_like();
    let d = data(&chain, 5, 100, 0.05);
    // A different consistent robot as prior: every mass doubled (with first and second
    // moments), friction halved.
    let prior = scaled_parameters(&chain, 2.0, 0.5);
    let err = prior_estimate_error(&chain, &d, prior.clone(), 1e8, &prior);
    assert!(err < 1e-3, "estimate {err:e} away from the prior");
}

/// Scaling every joint weight by the same factor changes nothing; the weights are used
/// (a zero weight on all but one joint changes the estimate).
#[test]
fn joint_weights() {
    let chain = panda_like();
    let d = with_noise(data(&chain, 3, 120, 0.05), 0.3, 9);
    let solve = |w: Option<Vec<f64>>| {
        let cfg = PhysicalConfig {
            joint_weights: w,
            ..PhysicalConfig::default()
        };
        d.identify(&chain, &cfg).unwrap()
    };
    let plain = solve(None);
    let scaled = solve(Some(vec![4.0; 7]));
    assert!(max_rel(&scaled.base, &plain.base) < 1e-5);
    assert!((scaled.residual - 2.0 * plain.residual).abs() < 1e-6 * plain.residual);
    let skewed = solve(Some(vec![1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 100.0]));
    assert!(max_rel(&skewed.base, &plain.base) > 1e-4);
}

/// Few noisy samples: least squares has no rigid-body realisation, the consistent
/// estimate has one and predicts another trajectory's torques about as well.
#[test]
fn few_noisy_samples() {
    let chain = panda_like();
    let train = with_noise(data(&chain, 21, 60, 0.15), 0.5, 1);
    let problem = train.problem(&chain, &PhysicalConfig::default());
    let base = problem.base_parameters().clone();
    let (ls_beta, ls_res) = problem.least_squares();

    // Least squares is infeasible: no consistent π has K·π = β_LS ...
    let bf = base_feasibility(&base, &ls_beta, &PhysicalConfig::default()).unwrap();
    assert!(
        !bf.feasible && bf.max_relative_mismatch > 1e-3,
        "LS base values reachable (mismatch {:e})",
        bf.max_relative_mismatch
    );
    // ... and the standard vector nearest the true robot with those base values has
    // links no rigid body has.
    let anchored = standard_from_base(&base, &ls_beta, &chain.parameters()).unwrap();
    let rep = FeasibilityReport::new(&anchored, 7, &chain.friction()).unwrap();
    assert!(!rep.is_feasible());

    let est = problem.solve(&PhysicalConfig::default()).unwrap();
    assert!(est.feasibility.is_feasible(), "{:?}", est.feasibility);
    for l in &est.feasibility.links {
        assert!(l.min_eigenvalue() >= -1e-9, "{l:?}");
    }
    for f in &est.feasibility.friction {
        assert!(f.viscous.unwrap() >= 0.0 && f.coulomb.unwrap() >= 0.0);
    }
    assert!(est.residual >= ls_res * (1.0 - 1e-9));
    assert!((est.ls_residual - ls_res).abs() <= 1e-12 * ls_res);
    // Physical consistency costs residual on these data (LS is infeasible).
    assert!(est.residual_increase_percent > 0.0);

    // Held-out trajectory, exact torques.
    let (e_phys, e_ls) = held_out_rms(&chain, &base, &est.parameters, &ls_beta, 400, 0.025);
    assert!(
        e_phys <= 1.1 * e_ls,
        "held-out RMS: consistent {e_phys:.4} vs least squares {e_ls:.4}"
    );
}

/// β of a physical robot is reachable by consistent parameters.
#[test]
fn base_feasibility_of_true_values() {
    let chain = panda_like();
    let base = chain
        .base_parameters(&prrrp_core::BaseOptions::default())
        .unwrap();
    let beta = base.base_values(&chain.parameters()).unwrap();
    let bf = base_feasibility(&base, &beta, &PhysicalConfig::default()).unwrap();
    assert!(bf.feasible, "mismatch {:e}", bf.max_relative_mismatch);
    assert!(bf.report.is_feasible());
    // Scaling all masses by −1 gives base values of a robot with negative masses: not
    // reachable.
    let neg = scaled_parameters(&chain, -1.0, 1.0);
    let beta_neg = base.base_values(&neg).unwrap();
    let bf = base_feasibility(&base, &beta_neg, &PhysicalConfig::default()).unwrap();
    assert!(!bf.feasible && bf.max_relative_mismatch > 1e-2);
}

/// Real robots' own base values are reachable, also where the truth sits on the boundary
/// of consistency (PUMA 560: a massless link 1, a rod-like link 3, base values that are
/// exactly zero) and the mismatch has to be driven to round-off there.
#[test]
fn base_feasibility_of_boundary_robots() {
    for (name, chain) in [
        ("PUMA 560", prrrp_core::SerialChain::puma560().to_dyn()),
        ("PRRRP", prrrp_core::SerialChain::paper().to_dyn()),
    ] {
        let base = chain
            .base_parameters(&prrrp_core::BaseOptions::default())
            .unwrap();
        let beta = base.base_values(&chain.parameters()).unwrap();
        let bf = base_feasibility(&base, &beta, &PhysicalConfig::default()).unwrap();
        assert!(
            bf.feasible && bf.converged,
            "{name}: mismatch {:e} after {} steps (converged {})",
            bf.max_relative_mismatch,
            bf.iterations,
            bf.converged
        );
        assert!(bf.report.is_feasible(), "{name}");
    }
}

/// Hand-computed feasibility numbers.
#[test]
fn report_of_known_bodies() {
    // Point mass m at c: J = m·[c;1]·[c;1]ᵀ, eigenvalues {0, 0, 0, m·(1 + ‖c‖²)}; all
    // moments about the centre of mass vanish.
    let (m, c) = (2.0, [0.1, 0.2, 0.3]);
    let point = LinkFeasibility::of(&inertial_parameters(m, c, [0.0; 6]));
    let e = point.pseudo_inertia_eigenvalues;
    assert!(e[0].abs() < 1e-15 && e[2].abs() < 1e-15, "{e:?}");
    assert!((e[3] - m * (1.0 + 0.01 + 0.04 + 0.09)).abs() < 1e-14);
    assert_eq!(point.mass, 2.0);
    let com = point.com.unwrap();
    assert!((com[2] - 0.3).abs() < 1e-15);
    assert!(point
        .principal_moments
        .unwrap()
        .iter()
        .all(|x| x.abs() < 1e-14));
    assert!(point.consistent);

    // Thin rod of mass m, length L along x, about its centre: moments (0, mL²/12, mL²/12),
    // margins (mL²/6, 0, 0); J = diag(mL²/12, 0, 0, m).
    let (m, l) = (3.0, 0.6);
    let k = m * l * l / 12.0;
    let rod = LinkFeasibility::of(&inertial_parameters(
        m,
        [0.0; 3],
        [0.0, 0.0, k, 0.0, 0.0, k],
    ));
    let pm = rod.principal_moments.unwrap();
    assert!(pm[0].abs() < 1e-15 && (pm[1] - k).abs() < 1e-15 && (pm[2] - k).abs() < 1e-15);
    let tm = rod.triangle_margins.unwrap();
    assert!((tm[0] - 2.0 * k).abs() < 1e-15 && tm[1].abs() < 1e-15 && tm[2].abs() < 1e-15);
    let e = rod.pseudo_inertia_eigenvalues;
    assert!(e[0].abs() < 1e-15 && e[1].abs() < 1e-15);
    assert!((e[2] - k).abs() < 1e-15 && (e[3] - m).abs() < 1e-15);
    assert!(rod.consistent);

    // Izz = 0.05 > Ixx + Iyy = 0.02: margins (0.05, 0.05, −0.03); at the centre of mass
    // J = diag(Σ, m) with Σ = ½·tr(I)·1 − I = diag(0.025, 0.025, −0.015).
    let bad = LinkFeasibility::of(&inertial_parameters(
        1.0,
        [0.0; 3],
        [0.01, 0.0, 0.01, 0.0, 0.0, 0.05],
    ));
    let tm = bad.triangle_margins.unwrap();
    assert!((tm[2] + 0.03).abs() < 1e-15 && (tm[0] - 0.05).abs() < 1e-15);
    assert!((bad.min_eigenvalue() + 0.015).abs() < 1e-15);
    assert!(!bad.consistent);
    // Moved off the origin it is still no rigid body.
    let moved = LinkFeasibility::of(&inertial_parameters(
        1.0,
        [0.2, -0.1, 0.3],
        [0.01, 0.0, 0.01, 0.0, 0.0, 0.05],
    ));
    assert!(!moved.consistent && moved.min_eigenvalue() < 0.0);

    // Negative mass: no centre of mass, inconsistent.
    let neg = LinkFeasibility::of(&inertial_parameters(-1.0, [0.0; 3], [0.0; 6]));
    assert!(neg.com.is_none() && neg.principal_moments.is_none());
    assert!((neg.min_eigenvalue() + 1.0).abs() < 1e-15 && !neg.consistent);

    // Friction signs, and the layout (fv, fc, fo per joint after the inertials).
    let mut pi: Vec<f64> = inertial_parameters(1.0, [0.0; 3], [0.01, 0.0, 0.01, 0.0, 0.0, 0.01])
        .into_iter()
        .chain(inertial_parameters(
            1.0,
            [0.0; 3],
            [0.0, 0.0, k, 0.0, 0.0, k],
        ))
        .collect();
    pi.extend([0.5, 0.2, -3.0, 0.4, -0.1, 2.0]);
    let rep = FeasibilityReport::new(&pi, 2, &FrictionModel::all()).unwrap();
    assert_eq!(rep.friction[0].viscous, Some(0.5));
    assert!(rep.friction[0].consistent, "a negative offset is allowed");
    assert_eq!(rep.friction[1].coulomb, Some(-0.1));
    assert_eq!(rep.infeasible_joints(), vec![1]);
    assert!(rep.infeasible_links().is_empty());
    assert!(!rep.is_feasible());
    // The chains' own check agrees with the report.
    let puma = SerialChain::puma560();
    assert!(puma.feasibility_report().is_feasible());
    assert_eq!(
        panda_like().feasibility_report().infeasible_links(),
        panda_like().non_physical_links()
    );
}

#[test]
fn bad_input_is_a_typed_error() {
    let chain = panda_like();
    let d = data(&chain, 2, 30, 0.1);
    let run = |cfg: &PhysicalConfig| d.identify(&chain, cfg);
    let err = |cfg: PhysicalConfig| run(&cfg).unwrap_err();

    assert!(matches!(
        err(PhysicalConfig {
            prior: Some(vec![1.0; 5]),
            ..PhysicalConfig::default()
        }),
        PrrrpError::ShapeMismatch { .. }
    ));
    let mut nan_prior = chain.parameters();
    nan_prior[3] = f64::NAN;
    assert!(matches!(
        err(PhysicalConfig {
            prior: Some(nan_prior),
            ..PhysicalConfig::default()
        }),
        PrrrpError::NonFinite { .. }
    ));
    for cfg in [
        PhysicalConfig {
            prior_weight: -1.0,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            regularisation: f64::NAN,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            tolerance: 0.0,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            max_iterations: 0,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            divergence_weight: -1.0,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            regularisation: 0.0,
            divergence_weight: 0.0,
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            joint_weights: Some(vec![1.0, 1.0, -1.0, 1.0, 1.0, 1.0, 1.0]),
            ..PhysicalConfig::default()
        },
        PhysicalConfig {
            joint_weights: Some(vec![0.0; 7]),
            ..PhysicalConfig::default()
        },
    ] {
        let e = err(cfg.clone());
        assert!(
            matches!(e, PrrrpError::InvalidParameter { .. }),
            "{cfg:?}: {e}"
        );
    }
    assert!(matches!(
        err(PhysicalConfig {
            joint_weights: Some(vec![1.0; 6]),
            ..PhysicalConfig::default()
        }),
        PrrrpError::ShapeMismatch { .. }
    ));
    // One iteration is not enough from the default start.
    let e = err(PhysicalConfig {
        max_iterations: 1,
        ..PhysicalConfig::default()
    });
    assert!(matches!(e, PrrrpError::Diverged { .. }), "{e}");
    assert!(e.to_string().contains("max_iterations"));

    let cfg = PhysicalConfig::default();
    let mut tau = d.tau.clone();
    tau[20] = f64::NAN;
    let e = identify_physical(&chain, &d.q, &d.qd, &d.qdd, &tau, &cfg).unwrap_err();
    assert!(
        matches!(e, PrrrpError::NonFinite { row: Some(2), .. }),
        "{e}"
    );
    let mut q = d.q.clone();
    q[8] = f64::INFINITY;
    let e = identify_physical(&chain, &q, &d.qd, &d.qdd, &d.tau, &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::NonFinite { .. }), "{e}");
    let e = identify_physical(&chain, &d.q, &d.qd, &d.qdd, &d.tau[..14], &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    let e = identify_physical(&chain, &d.q[..13], &d.qd, &d.qdd, &d.tau, &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    let e = identify_physical(&chain, &[], &[], &[], &[], &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::TooFewSamples { .. }), "{e}");

    let base = chain
        .base_parameters(&prrrp_core::BaseOptions::default())
        .unwrap();
    let e = base_feasibility(&base, &[1.0; 3], &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
    let mut beta = vec![1.0; base.count()];
    beta[0] = f64::NAN;
    let e = base_feasibility(&base, &beta, &cfg).unwrap_err();
    assert!(matches!(e, PrrrpError::NonFinite { .. }), "{e}");
    let e = FeasibilityReport::new(&[0.0; 11], 1, &FrictionModel::viscous_coulomb()).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e}");
}

/// The measurement on the 7-joint arm with 2000 noisy samples (run with
/// `cargo test --release --test physical -- --ignored --nocapture`).
#[test]
#[ignore]
fn measure_chain7_2000() {
    let chain = panda_like();
    let train = with_noise(data(&chain, 21, 2000, 0.01), 0.5, 1);
    let t0 = std::time::Instant::now();
    let est = train.identify(&chain, &PhysicalConfig::default()).unwrap();
    let dt = t0.elapsed();
    let base = &est.base_parameters;
    let bf = base_feasibility(base, &est.ls_base, &PhysicalConfig::default()).unwrap();
    let anchored = standard_from_base(base, &est.ls_base, &chain.parameters()).unwrap();
    let rep = FeasibilityReport::new(&anchored, 7, &chain.friction()).unwrap();
    let (e_phys, e_ls) = held_out_rms(&chain, base, &est.parameters, &est.ls_base, 1000, 0.01);
    println!("solve time {dt:?}, iterations {}", est.iterations);
    println!(
        "LS: base feasible {} (mismatch {:.3e}); anchored standard vector: infeasible links {:?}, joints {:?}",
        bf.feasible,
        bf.max_relative_mismatch,
        rep.infeasible_links(),
        rep.infeasible_joints()
    );
    println!(
        "residual {:.4} vs LS {:.4}: +{:.4} %",
        est.residual, est.ls_residual, est.residual_increase_percent
    );
    println!("held-out RMS: consistent {e_phys:.5}, LS {e_ls:.5}");
}
