//! Excitation trajectory optimisation (paper eqs. 37–38): choose the reference trajectory
//! that minimises the condition number of the observation matrix W, under joint limits,
//! starting and ending at rest.
//!
//! Revolute joints 2–4 follow piecewise quintics, the prismatic joints 1 and 5 the paper's
//! sinusoids. Every candidate is scaled into the limits by construction, so the optimiser
//! (seeded Nelder–Mead: cond(W) is not smooth where singular values cross) searches shapes
//! only and never returns an infeasible trajectory; the result is re-checked on a finer
//! grid ([`PrrrpError::Infeasible`] otherwise).
//!
//! Design: docs/design/excitation.md.

use std::cell::RefCell;
use std::f64::consts::PI;

use argmin::core::{CostFunction, Error as ArgminError, Executor};
use argmin::solver::neldermead::NelderMead;
use argmin_math::{ArgminAdd, ArgminMul, ArgminSub};
use nalgebra::{SMatrix, SymmetricEigen};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use crate::error::{invalid, PrrrpError, Result};
use crate::models::prrrp::dynamics::PrrrpModel;
use crate::models::prrrp::regressor::{condition_number, observation_matrix};
use crate::models::prrrp::types::NPARAM;
use crate::motion::limits::{limit_usage, JointLimits, LimitUsage};
use crate::motion::trajectory::{
    sample_trajectory, ExcitationTrajectory, JointTrajectory, PiecewiseQuintic, Sinusoid,
};

/// Settings of [`optimise_excitation`]. Every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationConfig {
    /// Horizon T, s (default 10).
    pub duration: f64,
    /// Sampling period of W, s (default 0.02, the paper's).
    pub dt: f64,
    /// Joint limits (default [`JointLimits::default`]).
    pub limits: JointLimits,
    /// Whole periods of the sinusoids of joints 1 and 5 over the horizon (default [2, 3];
    /// different counts keep d̈1 and d̈5 from being proportional). Each must be at least 1
    /// and below half the number of sampling intervals, duration/(2·dt) (Nyquist: W's
    /// samples must resolve the sinusoid).
    pub prismatic_periods: [u32; 2],
    /// Maximum number of cost evaluations over all restarts (default 6000).
    pub max_evaluations: usize,
    /// Maximum number of Nelder–Mead runs, each restarted from the best point so far
    /// (default 6).
    pub restarts: usize,
    /// Initial simplex edge in the normalised decision space (default 0.5; knot
    /// positions lie in about [−1, 1] before scaling).
    pub simplex_step: f64,
    /// Fraction of each limit kept free as a safety margin (default 0.01).
    pub margin: f64,
    /// Seed of the initial guess (default 0).
    pub seed: u64,
    /// The progress callback is called every this many evaluations, and once at the end
    /// (default 100).
    pub progress_every: usize,
}

impl Default for ExcitationConfig {
    fn default() -> Self {
        Self {
            duration: 10.0,
            dt: 0.02,
            limits: JointLimits::default(),
            prismatic_periods: [2, 3],
            max_evaluations: 6000,
            restarts: 6,
            simplex_step: 0.5,
            margin: 0.01,
            seed: 0,
            progress_every: 100,
        }
    }
}

/// Progress report passed to the callback of [`optimise_excitation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationProgress {
    /// Cost evaluations so far.
    pub evaluations: usize,
    /// Evaluation budget ([`ExcitationConfig::max_evaluations`]).
    pub max_evaluations: usize,
    /// cond(W) of the initial guess.
    pub initial_cond: f64,
    /// Lowest cond(W) found so far.
    pub best_cond: f64,
    /// Index of the current Nelder–Mead run (0-based).
    pub run: usize,
}

/// Outcome of [`optimise_excitation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationResult<const K: usize> {
    /// The optimised reference trajectory on [0, duration].
    pub trajectory: ExcitationTrajectory<K>,
    /// cond(W) of the initial guess (SVD of W over the sampled trajectory).
    pub cond_initial: f64,
    /// cond(W) of the result (SVD of W over the sampled trajectory).
    pub cond_final: f64,
    /// Whether every limit holds on the fine verification grid (always true for a
    /// returned result: a violation is an error).
    pub limits_satisfied: bool,
    /// Fraction of each limit the result uses, on the verification grid.
    pub limit_usage: LimitUsage,
    /// Cost evaluations spent.
    pub evaluations: usize,
    /// Number of samples in W (duration/dt + 1).
    pub samples: usize,
}

/// Cost given to candidates whose W is singular or non-finite (ln cond ≈ 100, far above
/// any useful trajectory).
const BAD_COST: f64 = 100.0;
/// Scan points per sampling interval for the limit scaling during the search, for the
/// final trajectory, and for its verification.
const SCAN_SEARCH: usize = 2;
const SCAN_FINAL: usize = 20;
const SCAN_VERIFY: usize = 50;

/// Knots per revolute joint used by default (5 segments of 2 s over the default 10 s
/// horizon): in the measurements of the project notes it reaches cond(W) ≈ 4.5 in about
/// 2 s, where K = 5 stops near 5.5 and K = 4 near 7.
pub const DEFAULT_EXCITATION_KNOTS: usize = 6;

/// Number of decision variables for K knots.
pub const fn excitation_variables(k: usize) -> usize {
    3 * (2 + 3 * (k - 2)) + 2
}

/// Finds the excitation trajectory with the smallest cond(W) (eqs. 37–38) within the
/// joint limits, rest to rest; see the module docs for the method.
///
/// `K` is the number of knots of each revolute joint's piecewise quintic (≥ 3; use
/// [`DEFAULT_EXCITATION_KNOTS`]). K = 2, the paper's single rest-to-rest quintic per
/// joint, is refused: scaled to the limits its shape is fixed (only the direction of each
/// move is free), so there is nothing to optimise — its cond(W) is about 150 for the
/// default limits. `progress` is called every
/// [`ExcitationConfig::progress_every`] evaluations and once at the end.
///
/// ```no_run
/// use prrrp_core::{optimise_excitation, ExcitationConfig, Robot, DEFAULT_EXCITATION_KNOTS};
/// let model = Robot::paper().model();
/// let res = optimise_excitation::<DEFAULT_EXCITATION_KNOTS>(&model, &ExcitationConfig::default(), |p| {
///     eprintln!("{}/{}: cond = {:.1}", p.evaluations, p.max_evaluations, p.best_cond);
/// })?;
/// assert!(res.cond_final < res.cond_initial);
/// # Ok::<(), prrrp_core::PrrrpError>(())
/// ```
///
/// # Errors
/// - [`PrrrpError::InvalidParameter`] for a non-positive or non-finite duration, dt,
///   margin outside [0, 0.5), zero periods or periods at or above the Nyquist limit
///   duration/(2·dt), K < 3, or a duration shorter than 8 samples;
/// - [`PrrrpError::Infeasible`] if a joint's limits leave it no room to move, if no
///   candidate with finite cond(W) is found, or if the result violates a limit on the
///   verification grid.
pub fn optimise_excitation<const K: usize>(
    model: &PrrrpModel,
    config: &ExcitationConfig,
    mut progress: impl FnMut(&ExcitationProgress),
) -> Result<ExcitationResult<K>> {
    let shaper = Shaper::<K>::new(config)?;
    let n = excitation_variables(K);
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    let mut x0 = vec![0.0; n];
    for v in x0.iter_mut().take(n - 2) {
        *v = rng.random_range(-1.0..1.0);
    }
    let (_, cond_initial) = shaper.final_shape(model, &x0, "the initial guess")?;

    let problem = Problem {
        shaper: &shaper,
        model: *model,
        state: RefCell::new(SearchState {
            evaluations: 0,
            budget: config.max_evaluations,
            best_x: x0.clone(),
            best_cost: f64::INFINITY,
            run: 0,
            initial_cond: cond_initial,
            progress_every: config.progress_every.max(1),
            progress: &mut progress,
        }),
    };
    for run in 0..config.restarts.max(1) {
        crate::interrupt::check("excitation optimisation")?;
        let start = {
            let mut s = problem.state.borrow_mut();
            // Nelder–Mead evaluates its whole initial simplex before the first iteration
            // and cannot be interrupted there.
            if s.budget.saturating_sub(s.evaluations) < n + 2 {
                break;
            }
            s.run = run;
            s.best_x.clone()
        };
        nelder_mead_run(&problem, &start, config.simplex_step, 1e-9)?;
    }
    crate::interrupt::check("excitation optimisation")?;
    let SearchState {
        evaluations,
        best_x,
        best_cost,
        run,
        ..
    } = problem.state.into_inner();
    if !best_cost.is_finite() || best_cost >= BAD_COST {
        return Err(PrrrpError::Infeasible {
            what: "no trajectory with a finite cond(W) was found within the limits".into(),
        });
    }
    let (trajectory, cond_final) = shaper.final_shape(model, &best_x, "the optimised shape")?;
    let usage = limit_usage(
        &trajectory,
        &config.limits,
        0.0,
        config.duration,
        SCAN_VERIFY * (shaper.samples - 1) + 1,
    )?;
    if !usage.within(1e-9) {
        return Err(PrrrpError::Infeasible {
            what: format!(
                "the optimised trajectory uses {:.4} of a limit on the verification grid",
                usage.max()
            ),
        });
    }
    progress(&ExcitationProgress {
        evaluations,
        max_evaluations: config.max_evaluations,
        initial_cond: cond_initial,
        best_cond: cond_final,
        run,
    });
    Ok(ExcitationResult {
        trajectory,
        cond_initial,
        cond_final,
        limits_satisfied: true,
        limit_usage: usage,
        evaluations,
        samples: shaper.samples,
    })
}

/// Maps decision variables to feasible trajectories and scores them.
struct Shaper<const K: usize> {
    duration: f64,
    dt: f64,
    samples: usize,
    limits: JointLimits,
    omega: [f64; 2],
    margin: f64,
    times: [f64; K],
}

impl<const K: usize> Shaper<K> {
    fn new(c: &ExcitationConfig) -> Result<Self> {
        if K < 3 {
            return Err(invalid(
                "K",
                K as f64,
                "at least 3 knots are needed: a single rest-to-rest quintic scaled to the \
                 limits has no free shape",
            ));
        }
        if !(c.duration.is_finite() && c.duration > 0.0) {
            return Err(invalid("duration", c.duration, "must be finite and > 0 s"));
        }
        if !(c.dt.is_finite() && c.dt > 0.0) {
            return Err(invalid("dt", c.dt, "must be finite and > 0 s"));
        }
        if !(c.margin.is_finite() && (0.0..0.5).contains(&c.margin)) {
            return Err(invalid("margin", c.margin, "must be in [0, 0.5)"));
        }
        if !(c.simplex_step.is_finite() && c.simplex_step > 0.0) {
            return Err(invalid(
                "simplex_step",
                c.simplex_step,
                "must be finite and > 0",
            ));
        }
        for (i, &p) in c.prismatic_periods.iter().enumerate() {
            if p == 0 {
                return Err(invalid(
                    format!("prismatic_periods[{i}]"),
                    0.0,
                    "needs at least one whole period to start and end at rest",
                ));
            }
        }
        c.limits.validate()?;
        // A tiny tolerance so that e.g. 10 s / 0.02 s gives 501 samples despite rounding.
        let samples = crate::interrupt::check_count(
            "duration (in samples of dt)",
            (c.duration / c.dt + 1e-9).floor() + 1.0,
            "asks for more than MAX_SAMPLES (1e7) samples per evaluation: shorten the \
             duration or raise dt",
        )?;
        if samples < NPARAM {
            return Err(invalid(
                "duration",
                c.duration,
                "must span at least 8 samples of dt (one per parameter)",
            ));
        }
        // At or above Nyquist W sees an alias or nothing, and the limit scaling shrinks the
        // amplitude to ~1e-19 (u32::MAX periods gave ω ≈ 2.7e9 rad/s and an Ok).
        let intervals = (samples - 1) as u64;
        for (i, &p) in c.prismatic_periods.iter().enumerate() {
            if 2 * u64::from(p) >= intervals {
                return Err(invalid(
                    format!("prismatic_periods[{i}]"),
                    f64::from(p),
                    "must be below duration/(2·dt), the Nyquist limit of W's sampling: use \
                     fewer periods, a longer duration or a smaller dt",
                ));
            }
        }
        let mut times = [0.0; K];
        for (k, t) in times.iter_mut().enumerate() {
            *t = c.duration * k as f64 / (K - 1) as f64;
        }
        Ok(Self {
            duration: c.duration,
            dt: c.dt,
            samples,
            limits: c.limits,
            omega: c
                .prismatic_periods
                .map(|p| 2.0 * PI * f64::from(p) / c.duration),
            margin: c.margin,
            times,
        })
    }

    /// The feasible trajectory for decision vector `x`, with limits measured on `scan`
    /// points per sampling interval; `None` if a joint's shape does not move or is not
    /// finite.
    fn build(&self, x: &[f64], scan: usize) -> Option<ExcitationTrajectory<K>> {
        let h = self.duration / (K - 1) as f64;
        let per_joint = 2 + 3 * (K - 2);
        let points = scan * (self.samples - 1) + 1;
        let keep = 1.0 - self.margin;
        let (center, half) = (self.limits.q_center(), self.limits.q_half_range());
        let mut revolute =
            [PiecewiseQuintic::<K>::new(self.times, [0.0; K], [0.0; K], [0.0; K]).ok()?; 3];
        for (i, rev) in revolute.iter_mut().enumerate() {
            let j = i + 1;
            let v = &x[i * per_joint..(i + 1) * per_joint];
            let (mut p, mut pd, mut pdd) = ([0.0; K], [0.0; K], [0.0; K]);
            p[0] = v[0];
            p[K - 1] = v[1];
            for k in 1..K - 1 {
                let o = 2 + 3 * (k - 1);
                p[k] = v[o];
                pd[k] = v[o + 1] / h;
                pdd[k] = v[o + 2] / (h * h);
            }
            let shape = PiecewiseQuintic::new(self.times, p, pd, pdd).ok()?;
            let (mut lo, mut hi, mut vmax, mut amax) = (f64::INFINITY, -f64::INFINITY, 0.0, 0.0);
            let step = self.duration / (points - 1) as f64;
            for s in 0..points {
                use crate::motion::trajectory::ScalarTrajectory;
                let (q, qd, qdd) = shape.eval(step * s as f64);
                lo = f64::min(lo, q);
                hi = f64::max(hi, q);
                vmax = f64::max(vmax, qd.abs());
                amax = f64::max(amax, qdd.abs());
            }
            let mid = 0.5 * (lo + hi);
            let scale = keep
                * (half[j] / (0.5 * (hi - lo)))
                    .min(self.limits.qd_max[j] / vmax)
                    .min(self.limits.qdd_max[j] / amax);
            if !(scale.is_finite() && scale > 0.0) {
                return None;
            }
            *rev = PiecewiseQuintic::new(
                self.times,
                p.map(|pk| center[j] + scale * (pk - mid)),
                pd.map(|d| scale * d),
                pdd.map(|a| scale * a),
            )
            .ok()?;
        }
        let mut prismatic = [Sinusoid {
            offset: 0.0,
            amplitude: 0.0,
            omega: 1.0,
            phase: -0.5 * PI,
        }; 2];
        for (i, (sin, j)) in prismatic.iter_mut().zip([0, 4]).enumerate() {
            let w = self.omega[i];
            let a_max = keep
                * half[j]
                    .min(self.limits.qd_max[j] / w)
                    .min(self.limits.qdd_max[j] / (w * w));
            let frac = 1.0 / (1.0 + (-x[3 * per_joint + i]).exp());
            *sin = Sinusoid {
                offset: center[j],
                amplitude: frac * a_max,
                omega: w,
                phase: -0.5 * PI,
            };
        }
        Some(ExcitationTrajectory {
            prismatic,
            revolute,
        })
    }

    /// ½·ln(λmax/λmin) of WᵀW = ln cond(W), accumulated without heap allocation.
    fn log_cond(&self, model: &PrrrpModel, traj: &ExcitationTrajectory<K>) -> f64 {
        let mut wtw = SMatrix::<f64, NPARAM, NPARAM>::zeros();
        for k in 0..self.samples {
            let p = traj.eval(self.dt * k as f64);
            let phi = model.regressor(&p.q, &p.qd, &p.qdd);
            wtw += phi.tr_mul(&phi);
        }
        let eig = SymmetricEigen::new(wtw).eigenvalues;
        let (min, max) = (eig.min(), eig.max());
        let c = 0.5 * (max / min).ln();
        if min > 0.0 && c.is_finite() {
            c.min(BAD_COST)
        } else {
            BAD_COST
        }
    }

    /// The trajectory of `x` on the final scan grid and its reported cond(W);
    /// [`PrrrpError::Infeasible`] naming `what` (the shape) if it cannot be scaled into the
    /// limits.
    fn final_shape(
        &self,
        model: &PrrrpModel,
        x: &[f64],
        what: &str,
    ) -> Result<(ExcitationTrajectory<K>, f64)> {
        let traj = self
            .build(x, SCAN_FINAL)
            .ok_or_else(|| PrrrpError::Infeasible {
                what: format!("{what} cannot be scaled into the limits"),
            })?;
        let cond = self.reported_cond(model, &traj)?;
        Ok((traj, cond))
    }

    /// cond(W) from the SVD of the stacked observation matrix.
    fn reported_cond(&self, model: &PrrrpModel, traj: &ExcitationTrajectory<K>) -> Result<f64> {
        let s = sample_trajectory(traj, 0.0, self.dt, self.samples)?;
        condition_number(&observation_matrix(model, &s.q, &s.qd, &s.qdd)?)
    }
}

struct SearchState<'p> {
    evaluations: usize,
    budget: usize,
    best_x: Vec<f64>,
    best_cost: f64,
    run: usize,
    initial_cond: f64,
    progress_every: usize,
    progress: &'p mut dyn FnMut(&ExcitationProgress),
}

struct Problem<'s, 'p, const K: usize> {
    shaper: &'s Shaper<K>,
    model: PrrrpModel,
    state: RefCell<SearchState<'p>>,
}

impl<const K: usize> CostFunction for &Problem<'_, '_, K> {
    type Param = Params;
    type Output = f64;

    fn cost(&self, x: &Params) -> std::result::Result<f64, ArgminError> {
        let mut s = self.state.borrow_mut();
        if s.evaluations >= s.budget {
            return Err(ArgminError::msg("evaluation budget spent"));
        }
        // An error stops the executor; the caller then sees the interruption.
        if crate::interrupt::stop_requested() {
            return Err(ArgminError::msg("interrupted"));
        }
        s.evaluations += 1;
        let c = match self.shaper.build(&x.0, SCAN_SEARCH) {
            Some(traj) => self.shaper.log_cond(&self.model, &traj),
            None => BAD_COST,
        };
        if c < s.best_cost {
            s.best_cost = c;
            s.best_x.clone_from(&x.0);
        }
        if s.evaluations % s.progress_every == 0 {
            let report = ExcitationProgress {
                evaluations: s.evaluations,
                max_evaluations: s.budget,
                initial_cond: s.initial_cond,
                best_cond: s.best_cost.exp(),
                run: s.run,
            };
            (s.progress)(&report);
        }
        Ok(c)
    }
}

/// Decision vector for argmin (a local type, so the vector arithmetic the solver needs
/// can be given here instead of enabling argmin-math's `vec` backend and its second
/// `rand` version).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Params(pub(crate) Vec<f64>);

impl ArgminAdd<Params, Params> for Params {
    fn add(&self, other: &Params) -> Params {
        Params(self.0.iter().zip(&other.0).map(|(a, b)| a + b).collect())
    }
}

impl ArgminSub<Params, Params> for Params {
    fn sub(&self, other: &Params) -> Params {
        Params(self.0.iter().zip(&other.0).map(|(a, b)| a - b).collect())
    }
}

impl ArgminMul<f64, Params> for Params {
    fn mul(&self, other: &f64) -> Params {
        Params(self.0.iter().map(|a| a * other).collect())
    }
}

/// One Nelder–Mead run of `problem` from `start`, the initial simplex stepping each
/// coordinate by `step` (units of the decision vector), until the simplex's spread of
/// costs falls below `sd_tolerance` or the cost function returns an error (both designs'
/// costs do once their evaluation budget is spent, which stops the executor). The best
/// point is tracked by the problem itself, so the run's own result is dropped.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] if the solver rejects `sd_tolerance`.
pub(crate) fn nelder_mead_run<O>(
    problem: O,
    start: &[f64],
    step: f64,
    sd_tolerance: f64,
) -> Result<()>
where
    O: CostFunction<Param = Params, Output = f64>,
{
    let simplex: Vec<Params> = std::iter::once(Params(start.to_vec()))
        .chain((0..start.len()).map(|i| {
            let mut v = start.to_vec();
            v[i] += step;
            Params(v)
        }))
        .collect();
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(sd_tolerance)
        .map_err(|_| PrrrpError::InvalidParameter {
            field: "sd_tolerance".into(),
            value: sd_tolerance,
            reason: "rejected by the Nelder-Mead solver",
        })?;
    let _ = Executor::new(problem, solver)
        .configure(|st| st.max_iters(u64::MAX))
        .run();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn periods(p: [u32; 2]) -> ExcitationConfig {
        ExcitationConfig {
            prismatic_periods: p,
            ..ExcitationConfig::default()
        }
    }

    #[test]
    fn periods_at_or_above_nyquist_are_refused() {
        // The default 10 s at 0.02 s: 500 intervals, so at most 249 periods.
        assert!(Shaper::<6>::new(&periods([249, 3])).is_ok());
        for (p, field) in [
            ([250, 3], "prismatic_periods[0]"),
            ([2, u32::MAX], "prismatic_periods[1]"),
        ] {
            let got = Shaper::<6>::new(&periods(p)).map(|_| ());
            assert!(
                matches!(&got, Err(PrrrpError::InvalidParameter { field: f, .. }) if f == field),
                "{p:?}: {got:?}"
            );
        }
        let got = optimise_excitation::<6>(
            &crate::Robot::paper().model(),
            &periods([u32::MAX; 2]),
            |_| {},
        );
        assert!(matches!(got, Err(PrrrpError::InvalidParameter { .. })));
    }
}
