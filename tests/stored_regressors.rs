//! Training on regressors built once (`train_stored`) against training on the samples
//! (`train`, which builds each regressor in every epoch: the online form of the paper's
//! Adaline delta rule and Hopfield network). The stored form exists only for speed, so it
//! must compute the same numbers to the last bit — the estimates, the per-epoch errors,
//! the sub-step counts and the errors — on random data, at run-time sizes (a 7-joint
//! chain's whitened base model, as `identify` runs them) and compile-time sizes (the
//! paper's arm).

#[path = "dyn_support/mod.rs"]
mod dyn_support;
#[path = "est_support/mod.rs"]
mod est_support;

use dyn_support::{base_model, panda_like, DynRecord};
use prrrp_core::nalgebra::{DVector, Dyn};
use prrrp_core::{
    Adaline, AdalineConfig, AdalineRule, DynAdaline, DynChainBaseModel, DynHopfield,
    DynScaledModel, Estimator, Hopfield, HopfieldConfig, LinearModel, PrrrpError, StoredRegressors,
};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Random states (rad, rad/s, rad/s²) and torques (N·m), nothing a fit would favour.
fn random_record(n: usize, samples: usize, seed: u64) -> DynRecord {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut v = |scale: f64| DVector::from_fn(n, |_, _| scale * (2.0 * rng.random::<f64>() - 1.0));
    let mut r = DynRecord::default();
    for _ in 0..samples {
        r.q.push(v(2.0));
        r.qd.push(v(2.0));
        r.qdd.push(v(5.0));
        r.tau.push(v(20.0));
    }
    r
}

fn whitened_panda(rec: &DynRecord) -> DynScaledModel<DynChainBaseModel> {
    let chain = panda_like();
    let model = base_model(&chain);
    DynScaledModel::whitened(model, &rec.samples()).unwrap()
}

/// A random 7-joint record and what the tests build on it.
struct Case {
    rec: DynRecord,
    /// The Panda-like chain's whitened base model on the record.
    sm: DynScaledModel<DynChainBaseModel>,
    /// [`peaks`] of `sm` on the record.
    row: f64,
    frob: f64,
    /// Number of (scaled) parameters.
    p: usize,
    /// `sm`'s regressors on the record, stored.
    st: StoredRegressors<Dyn, Dyn>,
}

fn case(samples: usize, seed: u64) -> Case {
    let rec = random_record(7, samples, seed);
    let sm = whitened_panda(&rec);
    let (row, frob) = peaks(&sm, &rec);
    let p = sm.dims().1 .0;
    let st = StoredRegressors::new(&sm, &rec.samples(), usize::MAX).unwrap();
    Case {
        rec,
        sm,
        row,
        frob,
        p,
        st,
    }
}

/// Largest ‖row‖² and ‖Φ‖_F² of the model's regressors on the data (the step bounds).
fn peaks<M: LinearModel<Dyn, Dyn>>(m: &M, rec: &DynRecord) -> (f64, f64) {
    let st = StoredRegressors::new(m, &rec.samples(), usize::MAX).unwrap();
    let (mut row, mut frob) = (0.0f64, 0.0f64);
    for k in 0..st.len() {
        let phi = st.regressor(k);
        for r in phi.row_iter() {
            row = row.max(r.norm_squared());
        }
        frob = frob.max(phi.norm_squared());
    }
    (row, frob)
}

/// Trains `$online` on `$samples` and `$stored` on the stored regressors `$st` with each
/// of `$epochs` in turn, each call continuing from the last, and asserts the same
/// per-epoch errors and estimates to the bit; `$case` names the case in failures. (A macro:
/// `train` and `train_stored` are inherent methods of each estimator, no shared trait.)
macro_rules! assert_same_training {
    ($case:expr, $epochs:expr, $online:ident, $samples:expr, $stored:ident, $st:expr) => {
        for e in $epochs {
            let a = $online.train($samples, e).unwrap();
            let b = $stored.train_stored($st, e).unwrap();
            assert_eq!(bits(&a.rms_error), bits(&b.rms_error), "{}", $case);
            assert_eq!(
                bits($online.estimate().as_slice()),
                bits($stored.estimate().as_slice()),
                "{}",
                $case
            );
        }
    };
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn adaline_on_stored_regressors_equals_adaline_on_samples_to_the_bit() {
    for seed in [1, 2] {
        let Case {
            rec,
            sm,
            row,
            p,
            st,
            ..
        } = case(600, seed);
        assert_eq!((st.len(), st.shape()), (600, (7, p)));
        for (rule, mu) in [(AdalineRule::Delta, 0.5), (AdalineRule::Normalised, 0.7)] {
            let cfg = AdalineConfig {
                rule,
                learning_rate: mu / row,
                step_size: mu,
                ..AdalineConfig::default()
            };
            let start = DVector::from_fn(p, |i, _| 0.1 * i as f64);
            let mut online = DynAdaline::new(sm.clone(), start.clone(), cfg).unwrap();
            let mut stored = DynAdaline::new(sm.clone(), start.clone(), cfg).unwrap();
            // Two calls: the second continues from the weights of the first.
            assert_same_training!(
                format!("{rule:?}"),
                [3, 2],
                online,
                &rec.samples(),
                stored,
                &st
            );
            assert_eq!(online.samples(), stored.samples());
            // The estimate moved: the comparison is not of two untouched starts.
            assert!((online.estimate() - &start).amax() > 1e-2);
        }
    }
}

#[test]
fn hopfield_on_stored_regressors_equals_hopfield_on_samples_to_the_bit() {
    let Case {
        rec,
        sm,
        frob,
        p,
        st,
        ..
    } = case(500, 3);
    // μ = 0.5 per sample as `identify` starts, and μ = 4 (several sub-steps per sample),
    // with a tight bound so that the box and its clamp act.
    for (mu, bound) in [(0.5, 1e3), (4.0, 30.0)] {
        let cfg = HopfieldConfig {
            bound,
            beta: bound * frob / mu,
            dt: 1.0,
            stability_limit: 1.0,
            max_substeps: 64,
        };
        let mut online = DynHopfield::new(sm.clone(), DVector::zeros(p), cfg).unwrap();
        let mut stored = DynHopfield::new(sm.clone(), DVector::zeros(p), cfg).unwrap();
        assert_same_training!(
            format!("μ = {mu}"),
            [2, 3],
            online,
            &rec.samples(),
            stored,
            &st
        );
        assert_eq!(online.substeps(), stored.substeps());
        assert_eq!(online.samples(), stored.samples());
        assert!(online.estimate().amax() > 1e-2);
        if mu > 1.0 {
            assert!(online.substeps() > online.samples() as u64);
        }
    }
}

/// The paper's arm at compile-time sizes (5 joints, 8 parameters).
#[test]
fn compile_time_sizes_agree_to_the_bit() {
    let (model, _) = est_support::paper();
    let data = est_support::excitation(400, 5);
    let samples = data.dataset();
    let st = StoredRegressors::new(&model, &samples, usize::MAX).unwrap();
    let cfg = AdalineConfig::default();
    let mut a: Adaline<_, 5, 8> = Adaline::new(model, Default::default(), cfg).unwrap();
    let mut b = a.clone();
    assert_same_training!("Adaline", [3], a, &samples, b, &st);

    let cfg = HopfieldConfig::default();
    let mut a: Hopfield<_, 5, 8> = Hopfield::new(model, Default::default(), cfg).unwrap();
    let mut b = a.clone();
    assert_same_training!("Hopfield", [2], a, &samples, b, &st);
    assert_eq!(a.substeps(), b.substeps());
    assert!(a.estimate().amax() > 0.0);
}

/// The same errors, at the same sample: a divergence of the delta rule, and a NaN.
#[test]
fn errors_are_the_same_and_name_the_sample() {
    let Case {
        rec,
        sm,
        row,
        p,
        st,
        ..
    } = case(300, 4);
    // γ·‖x‖² = 50 > 2 on the largest row: the delta rule diverges.
    let cfg = AdalineConfig {
        rule: AdalineRule::Delta,
        learning_rate: 50.0 / row,
        ..AdalineConfig::default()
    };
    let mut online = DynAdaline::new(sm.clone(), DVector::zeros(p), cfg).unwrap();
    let mut stored = DynAdaline::new(sm.clone(), DVector::zeros(p), cfg).unwrap();
    let a = online.train(&rec.samples(), 50).unwrap_err();
    let b = stored.train_stored(&st, 50).unwrap_err();
    assert!(matches!(a, PrrrpError::Diverged { .. }), "{a:?}");
    assert_eq!(format!("{a:?}"), format!("{b:?}"));

    // A NaN torque in sample 7: the store refuses it, naming the sample, as `train` does.
    let mut bad = rec.clone();
    bad.tau[7][2] = f64::NAN;
    let e = StoredRegressors::new(&sm, &bad.samples(), usize::MAX).unwrap_err();
    assert!(
        matches!(e, PrrrpError::NonFinite { row: Some(7), .. }),
        "{e:?}"
    );
    let mut online = DynAdaline::new(sm.clone(), DVector::zeros(p), Default::default()).unwrap();
    let a = online.train(&bad.samples(), 1).unwrap_err();
    assert_eq!(format!("{a:?}"), format!("{e:?}"));
}

#[test]
fn the_memory_bound_and_the_shapes_are_checked() {
    let rec = random_record(7, 100, 5);
    let sm = whitened_panda(&rec);
    let p = sm.dims().1 .0;
    let need = StoredRegressors::<Dyn, Dyn>::bytes(7, p, 100).unwrap();
    assert_eq!(need, 7 * (p + 1) * 100 * 8);
    assert!(StoredRegressors::new(&sm, &rec.samples(), need).is_ok());
    let e = StoredRegressors::new(&sm, &rec.samples(), need - 1).unwrap_err();
    assert!(
        matches!(&e, PrrrpError::InvalidParameter { field, value, .. }
            if field == "max_bytes" && *value == need as f64),
        "{e:?}"
    );
    // 10⁷ samples (the library's MAX_SAMPLES) of a large model: refused before any
    // allocation, and sizes that overflow usize are None.
    assert!(StoredRegressors::<Dyn, Dyn>::bytes(7, p, 10_000_000).unwrap() > 1 << 30);
    assert_eq!(
        StoredRegressors::<Dyn, Dyn>::bytes(usize::MAX / 2, 3, 10),
        None
    );

    // Regressors of another model (the PRRRP arm's 5×8 at run-time sizes).
    let (paper, _) = est_support::paper();
    let d = est_support::excitation(50, 1);
    let fixed = StoredRegressors::new(&paper, &d.dataset(), usize::MAX).unwrap();
    assert_eq!(fixed.shape(), (5, 8));
    let other = random_record(5, 50, 6);
    let chain5 = five_joint_model(&other);
    let st5 = StoredRegressors::new(&chain5, &other.samples(), usize::MAX).unwrap();
    let mut est = DynAdaline::new(sm.clone(), DVector::zeros(p), Default::default()).unwrap();
    let e = est.train_stored(&st5, 1).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e:?}");
    let mut est = DynHopfield::new(sm, DVector::zeros(p), Default::default()).unwrap();
    let e = est.train_stored(&st5, 1).unwrap_err();
    assert!(matches!(e, PrrrpError::ShapeMismatch { .. }), "{e:?}");
}

/// A 5-joint run-time model (the first five joints' worth of a Panda-like chain would
/// need a new DH table; the PRRRP arm's chain is one).
fn five_joint_model(rec: &DynRecord) -> DynScaledModel<DynChainBaseModel> {
    let chain = prrrp_core::SerialChain::from_robot(&prrrp_core::Robot::paper())
        .unwrap()
        .to_dyn();
    let model = base_model(&chain);
    DynScaledModel::equilibrated(model, &rec.samples()).unwrap()
}
