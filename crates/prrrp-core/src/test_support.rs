//! Fixtures shared by the unit tests of several modules.

use crate::models::chain::Actuators;
use crate::{DynChain, DynDataset, FrictionModel, SerialChain};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// The PUMA 560 with viscous, Coulomb and offset friction; `coupled`: its sixth motor
/// turns with q̇5 + q̇6 and every motor has an armature.
pub(crate) fn puma(coupled: bool) -> DynChain {
    let chain = SerialChain::puma560()
        .to_dyn()
        .with_friction(FrictionModel::all(), vec![[0.5, 0.3, 0.02]; 6])
        .unwrap();
    if !coupled {
        return chain;
    }
    let mut c = vec![vec![0.0; 6]; 6];
    for (i, row) in c.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    c[5][4] = 1.0;
    chain
        .with_actuators(Actuators {
            coupling: Some(c),
            armature: true,
            armature_values: Some(vec![0.5, 0.8, 0.3, 0.02, 0.02, 0.01]),
            gear_ratios: None,
        })
        .unwrap()
}

/// `samples` random states and torques of a 6-joint arm (seeded): nothing a fit would
/// favour. q within ±3, q̇ within ±`qd_scale(i)` for its i-th value, q̈ within ±5, τ
/// within ±10 (SI units).
pub(crate) fn random_data(samples: usize, seed: u64, qd_scale: fn(usize) -> f64) -> DynDataset {
    let n = 6;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut u = |scale: f64| scale * (2.0 * rng.random::<f64>() - 1.0);
    let t: Vec<f64> = (0..samples).map(|k| k as f64 * 0.01).collect();
    let q: Vec<f64> = (0..samples * n).map(|_| u(3.0)).collect();
    let qd: Vec<f64> = (0..samples * n).map(|i| u(qd_scale(i))).collect();
    let qdd: Vec<f64> = (0..samples * n).map(|_| u(5.0)).collect();
    let tau: Vec<f64> = (0..samples * n).map(|_| u(10.0)).collect();
    DynDataset::new(n, t, q, qd, qdd, tau).unwrap()
}
