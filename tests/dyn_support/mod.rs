//! Run-time-size test data: a Panda-like 7R chain with viscous, Coulomb and offset
//! friction built with `DynChain::new`, an analytic Fourier excitation, exact records
//! (τ = inverse dynamics of the chain's true parameters, no noise) and conversions of
//! compile-time records to run-time vectors. Shared by tests and benchmarks.
#![allow(dead_code)]

// Each support module is included on its own by tests and benches, so a test that takes
// two of them holds two copies of these free functions.
#[allow(clippy::duplicate_mod)]
#[path = "../seeded_support/mod.rs"]
mod seeded_support;

use prrrp_core::nalgebra::{DVector, SVector};
use prrrp_core::{
    inertial_parameters, BaseOptions, BaseParameters, DhConvention, DhRow, DynChain,
    DynChainBaseModel, DynDataset, DynSamples, FourierTrajectory, FrictionModel, GradientSettings,
    IdentifiedModel, JointKind, Method, UrdfOptions,
};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Velocity scale of the smoothed Coulomb sign tanh(q̇/v_s), rad/s.
pub const COULOMB_SMOOTHING: f64 = 0.02;

/// A 7R arm with the Franka Panda's modified-DH kinematics, plausible (physically
/// consistent) link inertials and friction on every joint (viscous, smoothed Coulomb,
/// offset).
pub fn panda_like() -> DynChain {
    use std::f64::consts::FRAC_PI_2;
    let a = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088];
    let d = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0];
    let alpha = [
        0.0, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2,
    ];
    let dh = (0..7)
        .map(|i| DhRow {
            kind: JointKind::Revolute,
            theta: 0.0,
            d: d[i],
            a: a[i],
            alpha: alpha[i],
        })
        .collect();
    // Mass (kg), centre of mass in the link frame (m), principal inertia about it
    // (kg·m², each satisfying the triangle inequality).
    let links: [(f64, [f64; 3], [f64; 3]); 7] = [
        (4.97, [0.0039, 0.0021, -0.0476], [0.70, 0.70, 0.009]),
        (0.65, [-0.0031, -0.0287, 0.0035], [0.008, 0.028, 0.026]),
        (3.23, [0.0275, 0.0393, -0.0665], [0.037, 0.036, 0.011]),
        (3.59, [-0.0532, 0.1047, 0.0274], [0.026, 0.019, 0.029]),
        (1.23, [-0.0120, 0.0411, -0.0384], [0.036, 0.029, 0.009]),
        (1.67, [0.0601, -0.0141, -0.0105], [0.002, 0.004, 0.005]),
        (0.74, [0.0105, -0.0043, 0.0617], [0.013, 0.010, 0.008]),
    ];
    let inertial = links
        .iter()
        .map(|&(m, c, i)| inertial_parameters(m, c, [i[0], 0.0, i[1], 0.0, 0.0, i[2]]))
        .collect();
    // fv (N·m·s/rad), fc (N·m), fo (N·m) per joint.
    let friction = (0..7)
        .map(|j| {
            let s = if j < 4 { 1.0 } else { 0.4 };
            [0.5 * s, 0.8 * s, if j % 2 == 0 { 0.1 } else { -0.05 } * s]
        })
        .collect();
    let chain = DynChain::new(dh, DhConvention::Modified)
        .expect("DH table")
        .with_inertial(inertial)
        .expect("inertials");
    with_smoothed_friction(chain, COULOMB_SMOOTHING, friction)
}

/// `chain` with viscous (N·m·s/rad), Coulomb (N·m, sign smoothed as tanh(q̇/v_s) with
/// v_s = `smoothing` rad/s) and offset (N·m) friction, one `[fv, fc, fo]` per joint.
pub fn with_smoothed_friction(
    chain: DynChain,
    smoothing: f64,
    per_joint: Vec<[f64; 3]>,
) -> DynChain {
    let model = FrictionModel {
        coulomb_smoothing: smoothing,
        ..FrictionModel::all()
    };
    chain.with_friction(model, per_joint).expect("friction")
}

/// The three-joint URDF fixture of prrrp-core's tests (tilted axes, a prismatic joint,
/// merged fixed bodies, locked fingers), ended at `link3`.
pub fn three_joint_urdf() -> DynChain {
    let opts = UrdfOptions {
        tip: Some("link3".into()),
        ..UrdfOptions::default()
    };
    let xml = include_str!("../../crates/prrrp-core/tests/data/three_joint.urdf");
    DynChain::from_urdf_str(xml, &opts).expect("fixture loads")
}

/// An n×n motor-to-joint coupling C (motor velocities = C·q̇): the identity plus the
/// off-diagonal `entries` (row, column, value).
pub fn coupling(n: usize, entries: &[(usize, usize, f64)]) -> Vec<Vec<f64>> {
    let mut c = vec![vec![0.0; n]; n];
    for (i, r) in c.iter_mut().enumerate() {
        r[i] = 1.0;
    }
    for &(i, j, v) in entries {
        c[i][j] = v;
    }
    c
}

/// The chain's base model under the default base-parameter analysis (the model an
/// identification fits); its true β is `chain_base_values()`.
pub fn base_model(chain: &DynChain) -> DynChainBaseModel {
    let base = chain
        .base_parameters(&BaseOptions::default())
        .expect("base-parameter analysis");
    chain.base_model(&base).expect("base model")
}

/// The chain's true base parameters as a prior model: σ of 5 % of each value (at least
/// 1e-4), independent, residual RMS `residual` (N·m or N) per joint.
pub fn truth_prior(chain: &DynChain, base: &BaseParameters, residual: f64) -> IdentifiedModel {
    let truth = chain
        .base_model(base)
        .unwrap()
        .chain_base_values()
        .as_slice()
        .to_vec();
    let b = truth.len();
    let mut cov = vec![0.0; b * b];
    for i in 0..b {
        cov[i * (b + 1)] = (0.05 * truth[i].abs()).max(1e-4).powi(2);
    }
    IdentifiedModel::new(
        chain,
        base,
        truth,
        None,
        Some(cov),
        None,
        vec![residual; chain.dof()],
        "manual",
        serde_json::json!({}),
        serde_json::json!({}),
    )
    .unwrap()
}

/// Owned run-time columns of a record.
#[derive(Debug, Clone, Default)]
pub struct DynRecord {
    pub q: Vec<DVector<f64>>,
    pub qd: Vec<DVector<f64>>,
    pub qdd: Vec<DVector<f64>>,
    pub tau: Vec<DVector<f64>>,
}

impl DynRecord {
    pub fn samples(&self) -> DynSamples<'_> {
        DynSamples::new(&self.q, &self.qd, &self.qdd, &self.tau).expect("equal lengths")
    }

    pub fn len(&self) -> usize {
        self.q.len()
    }

    /// The record as a data set of rows `dt` s apart, with seeded Gaussian noise of σ
    /// `noise` (N·m or N) added to τ (none for `noise` = 0).
    pub fn dataset(&self, dt: f64, noise: f64, seed: u64) -> DynDataset {
        let flat =
            |v: &[DVector<f64>]| -> Vec<f64> { v.iter().flat_map(|x| x.iter().copied()).collect() };
        let mut tau = flat(&self.tau);
        if noise > 0.0 {
            let mut rng = StdRng::seed_from_u64(seed);
            let d = Normal::new(0.0, noise).unwrap();
            for t in &mut tau {
                *t += d.sample(&mut rng);
            }
        }
        let t = (0..self.len()).map(|k| k as f64 * dt).collect();
        DynDataset::new(
            self.q[0].len(),
            t,
            flat(&self.q),
            flat(&self.qd),
            flat(&self.qdd),
            tau,
        )
        .unwrap()
    }

    /// The same record from compile-time vectors.
    pub fn from_fixed<const N: usize>(
        q: &[SVector<f64, N>],
        qd: &[SVector<f64, N>],
        qdd: &[SVector<f64, N>],
        tau: &[SVector<f64, N>],
    ) -> Self {
        let conv = |v: &[SVector<f64, N>]| {
            v.iter()
                .map(|x| DVector::from_column_slice(x.as_slice()))
                .collect()
        };
        Self {
            q: conv(q),
            qd: conv(qd),
            qdd: conv(qdd),
            tau: conv(tau),
        }
    }
}

/// q_j(t) = Σ_k a_jk·sin(k·ω·t + φ_jk), five harmonics of a 10 s fundamental, amplitude
/// of harmonic k in `scale`·[0.3, 1]/k/2 rad, seeded; returns (q, q̇, q̈) exactly.
pub struct DynFourier {
    omega: f64,
    amp: Vec<[f64; 5]>,
    phase: Vec<[f64; 5]>,
}

impl DynFourier {
    pub fn seeded(seed: u64, n: usize, scale: f64) -> Self {
        let mut amp = vec![[0.0; 5]; n];
        let mut phase = vec![[0.0; 5]; n];
        seeded_support::draw(seed, &vec![scale; n], &mut amp, &mut phase);
        Self {
            omega: 2.0 * std::f64::consts::PI / 10.0,
            amp,
            phase,
        }
    }

    pub fn eval(&self, t: f64) -> [DVector<f64>; 3] {
        let n = self.amp.len();
        let (mut q, mut qd, mut qdd) = (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
        let (amp, phase) = (&self.amp, &self.phase);
        let (q_, qd_, qdd_) = (q.as_mut_slice(), qd.as_mut_slice(), qdd.as_mut_slice());
        seeded_support::add(self.omega, amp, phase, t, q_, qd_, qdd_);
        [q, qd, qdd]
    }
}

/// `samples` samples every `dt` s of the reference, with τ the chain's exact inverse
/// dynamics (true parameters, friction included): noise-free identification data.
pub fn exact_record(
    chain: &DynChain,
    reference: &DynFourier,
    samples: usize,
    dt: f64,
) -> DynRecord {
    let mut rec = DynRecord::default();
    for k in 0..samples {
        let [q, qd, qdd] = reference.eval(k as f64 * dt);
        let tau = chain
            .inverse_dynamics(q.as_slice(), qd.as_slice(), qdd.as_slice())
            .expect("sizes");
        rec.q.push(q);
        rec.qd.push(qd);
        rec.qdd.push(qdd);
        rec.tau.push(DVector::from_vec(tau));
    }
    rec
}

/// A Fourier excitation of n joints at 0.2 Hz, 3 harmonics, starting at rest
/// (Σ a = 0, Σ l·b = 0), amplitudes in proportion to `scale`; every joint reverses several
/// times in 10 s. The simulation tests' reference trajectory.
pub fn fourier(n: usize, scale: f64) -> FourierTrajectory {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for j in 0..n {
        let s = scale * (1.0 + 0.1 * j as f64);
        a.extend([0.6 * s, -0.2 * s, -0.4 * s]);
        b.extend([0.3 * s, 0.15 * s, -0.2 * s]);
    }
    let offsets = (0..n).map(|j| 0.1 * j as f64 - 0.2).collect();
    FourierTrajectory::new(2.0 * std::f64::consts::PI * 0.2, offsets, a, b).unwrap()
}

/// The `robots` folder of `example-robot-data` (`PRRRP_ROBOTS_DIR`, else the test venv's),
/// if installed.
pub fn robots_dir() -> Option<std::path::PathBuf> {
    let dir = std::env::var_os("PRRRP_ROBOTS_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(
                ".venv/lib/python3.11/site-packages/cmeel.prefix/share/example-robot-data/robots",
            )
        });
    dir.is_dir().then_some(dir)
}

/// The method `name` with its default settings, but at most `max_epochs` epochs for the
/// gradient methods (seconds instead of minutes per test).
pub fn method_with_epochs(name: &str, max_epochs: usize) -> Method {
    let fewer = |s| GradientSettings { max_epochs, ..s };
    match Method::parse(name).unwrap() {
        Method::Adaline(s) => Method::Adaline(fewer(s)),
        Method::Hopfield(s) => Method::Hopfield(fewer(s)),
        m => m,
    }
}
