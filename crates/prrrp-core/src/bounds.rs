//! Bounds on inputs that are finite but beyond any use: values past them overflow or
//! underflow the squares the estimators form, and are refused with a typed error that
//! names them. The Python package reads the same constants (`prrrp.MAX_MAGNITUDE`, …).

/// Magnitude from which a logged value is refused (s, rad, m, N·m, N, A, per s): far
/// beyond any arm or clock, far below where the squares that least squares and the online
/// estimators form overflow a double (a torque of 1e300 N·m read as rank deficiency).
/// [`crate::OnlineIdentifier::update`] refuses it, and so do the Python readers of CSV
/// files and bags (`prrrp.MAX_MAGNITUDE`).
pub const MAX_MAGNITUDE: f64 = 1e100;

/// Smallest dimensionless width or noise factor that is squared into a covariance
/// ([`crate::OnlineConfig::prior_width`], its `ekf_noise`, the EKF's least-squares prior
/// width; also the payload's mass σ in kg and size in m): 1e-6. Far below any use; its
/// square and products stay normal doubles (1e-300 underflowed to a zero variance).
pub const MIN_FACTOR: f64 = 1e-6;

/// Largest such factor, 1e6 (1e300 made the covariance infinite and the prior was dropped
/// without a word). Also the largest factor on simulated noise.
pub const MAX_FACTOR: f64 = 1e6;

/// Whether `v` lies in [[`MIN_FACTOR`], [`MAX_FACTOR`]] (false for NaN).
pub(crate) fn is_factor(v: f64) -> bool {
    (MIN_FACTOR..=MAX_FACTOR).contains(&v)
}
