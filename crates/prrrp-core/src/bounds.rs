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

/// Largest magnitude of a robot description's lengths (m: joint placements, DH `a` and
/// `d`): 1e6, beyond any arm, and a thousand times a file written in millimetres (a DH
/// length of 1e300 m overflowed the base parameters' derivation into an empty basis).
pub const MAX_ROBOT_SIZE: f64 = 1e6;

/// Largest magnitude of a robot description's inertial parameters (kg, kg·m, kg·m²):
/// 1e12. Far beyond any arm (a 1e299 kg link simulated torques of 1e299 N·m), yet a file
/// written in grams and millimetres still reads (a 5 kg link 0.2 m out is 2e8 g·mm²):
/// its inertials are only a prior, and identification needs its kinematics.
pub const MAX_INERTIAL: f64 = 1e12;

/// Largest initial covariance δ of an RLS on equilibrated columns (P₀ = δ·I; the online
/// identifier's [`crate::OnlineConfig::initial_covariance`] and the batch RLS's
/// [`crate::RlsSettings::initial_covariance`] with `scale_columns`): 1e9, a prior σ of
/// 3·10⁴ N·m on the torque each parameter explains, already no prior for any arm. Larger
/// values leave the first updates' P − P·φ·φᵀ·P/(1 + φᵀ·P·φ) without a correct digit.
/// Measured: online, on 100 Hz UR3, UR5 and UR10 stand-in logs (1e-4 rad noise, no
/// prior), the RLS diverged in its first 60 rows from 3e10–3e11 on; batch, on a 500 Hz
/// UR5 stand-in (30 s), the fit moved at 1e12 and diverged at 1e14.
pub const MAX_INITIAL_COVARIANCE: f64 = 1e9;

/// Smallest initial covariance δ on equilibrated columns: [`MIN_FACTOR`]², 1e-12 (δ is a
/// variance, the square of a width). It already holds the estimate at λ₀ (a prior σ of
/// 1e-6 N·m on the torque each parameter explains); 1e-300 reported λ₀ with σ ≈ 1e-150 as
/// "converged", a certainty no data gave.
pub const MIN_INITIAL_COVARIANCE: f64 = MIN_FACTOR * MIN_FACTOR;

/// Refuses an initial covariance `delta` (field `initial_covariance`) outside
/// [[`MIN_INITIAL_COVARIANCE`], [`MAX_INITIAL_COVARIANCE`]]; NaN is the callers' own check.
pub(crate) fn check_initial_covariance(delta: f64) -> crate::error::Result<()> {
    if delta < MIN_INITIAL_COVARIANCE {
        return Err(crate::error::invalid(
            "initial_covariance",
            delta,
            "must be at least MIN_INITIAL_COVARIANCE (1e-12 on equilibrated columns, a prior \
             σ of 1e-6 N·m on the torque each parameter explains, already a prior the data \
             cannot move): smaller values claim a certainty no data gave",
        ));
    }
    if delta > MAX_INITIAL_COVARIANCE {
        return Err(crate::error::invalid(
            "initial_covariance",
            delta,
            "must be at most MAX_INITIAL_COVARIANCE (1e9 on equilibrated columns: a prior \
             σ of 3·10⁴ N·m on the torque each parameter explains, already no prior for any \
             arm): larger values leave the first updates' covariance without a correct \
             digit, and the estimate diverges",
        ));
    }
    Ok(())
}

/// Refuses a per-sample input `v` (named `what`, e.g. `"qd"`) with an entry that is NaN or
/// infinite ([`crate::PrrrpError::NonFinite`]) or at or above [`MAX_MAGNITUDE`] in
/// magnitude ([`crate::PrrrpError::InvalidParameter`]): such inputs made the dynamics
/// return `Ok` with NaN (1e200² overflows). One comparison per entry; allocates only on
/// the error.
pub(crate) fn check_sample(what: &str, v: &[f64]) -> crate::error::Result<()> {
    if let Some(j) = v
        .iter()
        .position(|x| x.abs() >= MAX_MAGNITUDE || x.is_nan())
    {
        let x = v[j];
        if !x.is_finite() {
            return Err(crate::PrrrpError::NonFinite {
                what: format!("{what}[{j}]"),
                row: None,
            });
        }
        return Err(crate::error::invalid(
            format!("{what}[{j}]"),
            x,
            "is at or above MAX_MAGNITUDE (1e100) in magnitude: no joint turns, moves or \
             pushes that much, and the dynamics overflow; check the units (rad, m, N·m, N)",
        ));
    }
    Ok(())
}

/// Whether `v` lies in [[`MIN_FACTOR`], [`MAX_FACTOR`]] (false for NaN and infinities).
/// The Python package checks its factor options with the same function
/// (`prrrp.is_factor`).
pub fn is_factor(v: f64) -> bool {
    (MIN_FACTOR..=MAX_FACTOR).contains(&v)
}

/// Refuses a factor `v` (named `field`) outside [[`MIN_FACTOR`], [`MAX_FACTOR`]] (and NaN).
pub(crate) fn check_factor(field: &str, v: f64) -> crate::error::Result<()> {
    if !is_factor(v) {
        return Err(crate::error::invalid(
            field,
            v,
            "must be between MIN_FACTOR (1e-6) and MAX_FACTOR (1e6): it is squared into a \
             covariance",
        ));
    }
    Ok(())
}
