//! Hardening of the estimators: bounded and interruptible training, defined relative
//! standard deviations for zero estimates, non-finite estimates as typed errors. A single
//! test, because raising the process-wide stop flag would stop other tests of this binary.

mod est_support;

use est_support::{excitation, paper};
use prrrp_core::{
    clear_stop, least_squares, request_stop, Adaline, AdalineConfig, Hopfield, HopfieldConfig,
    Lambda, LeastSquaresConfig, PrrrpError, Vec5,
};

#[test]
fn hardening() {
    let (model, lambda) = paper();
    let data = excitation(200, 2);
    // Absurd epoch counts are refused before anything is allocated.
    let mut ad = Adaline::new(model, Lambda::zeros(), AdalineConfig::default()).unwrap();
    for epochs in [10_000_001, 1_000_000_000_000, usize::MAX] {
        assert!(matches!(
            ad.train(&data.dataset(), epochs),
            Err(PrrrpError::InvalidParameter { .. })
        ));
    }
    let mut hop = Hopfield::new(model, lambda, HopfieldConfig::default()).unwrap();
    assert!(matches!(
        hop.train(&data.dataset(), usize::MAX),
        Err(PrrrpError::InvalidParameter { .. })
    ));
    // A raised stop flag ends training.
    request_stop();
    let r = ad.train(&data.dataset(), 10_000_000);
    clear_stop();
    assert!(matches!(r, Err(PrrrpError::Interrupted { .. })), "{r:?}");
    // A zero estimate has an infinite (not NaN) relative standard deviation.
    let mut zero = excitation(200, 2);
    zero.tau = vec![Vec5::zeros(); zero.tau.len()];
    let rep = least_squares(&model, &zero.dataset(), &LeastSquaresConfig::default()).unwrap();
    assert!(rep.rel_std_dev.iter().all(|x| *x == f64::INFINITY));
    // Overflowing data: a typed error, not a non-finite λ.
    let mut huge = excitation(200, 2);
    for k in 50..60 {
        huge.tau[k][0] = 1e308;
    }
    let r = least_squares(&model, &huge.dataset(), &LeastSquaresConfig::default());
    assert!(matches!(r, Err(PrrrpError::NonFinite { .. })), "{r:?}");
}
