//! Excitation design for any robot: per-joint finite Fourier series (Swevers et al. 1997)
//! whose coefficients minimise cond(W_b), the condition number of the robot's base
//! observation matrix (friction columns included when the chain has friction), starting
//! and ending at rest and within the joint limits.
//!
//! As the paper's design ([`crate::optimise_excitation`]), every shape is scaled into the
//! limits by construction and the seeded Nelder–Mead search sees shapes only; a joint
//! without the limits its scaling needs is an error naming the joint.
//!
//! Design: docs/design/excitation.md.

use std::cell::RefCell;
use std::f64::consts::PI;

use argmin::core::{CostFunction, Error as ArgminError};
use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};

use crate::error::{invalid, PrrrpError, Result};
use crate::models::chain::{BaseParameters, DynChain, JointLimit};
use crate::motion::dyn_trajectory::FourierTrajectory;
use crate::motion::excitation::{nelder_mead_run, Params};
use crate::motion::trajectory::DynTrajectory;

/// Settings of [`optimise_chain_excitation`]; every field has a documented default.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainExcitationConfig {
    /// Harmonics H per joint, 2 to [`MAX_HARMONICS`] (default 5).
    pub harmonics: usize,
    /// Base frequency ω/2π, Hz (default 0.1: a 10 s period).
    pub base_frequency_hz: f64,
    /// Rate at which W_b is sampled during the search, Hz (default 10).
    pub sample_rate_hz: f64,
    /// Fraction of every limit kept free, in [0, 1) (default 0.05).
    pub margin: f64,
    /// Seed of the random initial shapes (default 0).
    pub seed: u64,
    /// Random shapes drawn before the local search, ≥ 1 (default 16).
    pub restarts: usize,
    /// Cost evaluations in all, random shapes included (default 2000).
    pub max_evaluations: usize,
}

impl Default for ChainExcitationConfig {
    fn default() -> Self {
        Self {
            harmonics: 5,
            base_frequency_hz: 0.1,
            sample_rate_hz: 10.0,
            margin: 0.05,
            seed: 0,
            restarts: 16,
            max_evaluations: 2000,
        }
    }
}

/// The designed excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainExcitation {
    /// The trajectory (periodic; one period is the excitation).
    pub trajectory: FourierTrajectory,
    /// Its period, s.
    pub period: f64,
    /// cond(W_b) of the first random shape, and of the result.
    pub cond_initial: f64,
    /// cond(W_b) of the result (sampled at `sample_rate_hz`).
    pub cond_final: f64,
    /// Cost evaluations used.
    pub evaluations: usize,
    /// Per joint, the fraction of the [position, speed, acceleration] limits used (NaN
    /// where the limit is not given).
    pub limit_usage: Vec<[f64; 3]>,
}

/// Most harmonics per joint of a design (100).
pub const MAX_HARMONICS: usize = 100;

/// Most cost evaluations one design may use.
pub const MAX_EXCITATION_EVALUATIONS: usize = 10_000_000;

/// Designs an exciting trajectory for `chain` (module docs). `limits` overrides the
/// chain's own (from its robot file) when given; `progress(done, total)` is called every
/// few evaluations.
///
/// # Errors
/// [`PrrrpError::InvalidParameter`] for a bad setting; [`PrrrpError::Infeasible`] for a
/// joint whose limits do not bound its motion (named, with what is missing) and when no
/// shape gives a finite cond(W_b); [`PrrrpError::ShapeMismatch`] for a limit list of
/// another length; an interrupt.
pub fn optimise_chain_excitation(
    chain: &DynChain,
    base: &BaseParameters,
    limits: Option<&[JointLimit]>,
    config: &ChainExcitationConfig,
    mut progress: impl FnMut(usize, usize),
) -> Result<ChainExcitation> {
    let n = chain.dof();
    let own: Vec<JointLimit> = chain.joint_info().iter().map(|j| j.limit).collect();
    let limits = limits.unwrap_or(&own);
    if limits.len() != n {
        return Err(PrrrpError::ShapeMismatch {
            what: "limits".into(),
            expected: format!("{n} entries (one per joint)"),
            got: format!("{} entries", limits.len()),
        });
    }
    let c = config;
    if !(2..=MAX_HARMONICS).contains(&c.harmonics) {
        return Err(invalid(
            "harmonics",
            c.harmonics as f64,
            "must be between 2 and MAX_HARMONICS (100)",
        ));
    }
    if !(c.base_frequency_hz.is_finite() && c.base_frequency_hz > 0.0) {
        return Err(invalid(
            "base_frequency_hz",
            c.base_frequency_hz,
            "must be finite and > 0 Hz",
        ));
    }
    let period = 1.0 / c.base_frequency_hz;
    if !(c.sample_rate_hz.is_finite() && c.sample_rate_hz > 0.0) {
        return Err(invalid(
            "sample_rate_hz",
            c.sample_rate_hz,
            "must be finite and > 0 Hz",
        ));
    }
    let samples = (period * c.sample_rate_hz).round() as usize;
    if samples > crate::interrupt::MAX_SAMPLES {
        return Err(invalid(
            "sample_rate_hz",
            c.sample_rate_hz,
            "gives more than MAX_SAMPLES (1e7) samples per period",
        ));
    }
    if !(0.0..1.0).contains(&c.margin) {
        return Err(invalid("margin", c.margin, "must be in [0, 1)"));
    }
    if c.restarts == 0 {
        return Err(invalid("restarts", 0.0, "must be at least 1"));
    }
    if c.max_evaluations > MAX_EXCITATION_EVALUATIONS {
        return Err(invalid(
            "max_evaluations",
            c.max_evaluations as f64,
            "exceeds MAX_EXCITATION_EVALUATIONS (1e7)",
        ));
    }
    let names: Vec<String> = chain.joint_names().iter().map(|s| s.to_string()).collect();
    let shaper = Shaper::new(limits, &names, c, period)?;
    let h = c.harmonics;
    let vars = n * 2 * (h - 1);
    if samples * n < base.count() + 1 {
        return Err(invalid(
            "sample_rate_hz",
            c.sample_rate_hz,
            "times the period 1/base_frequency_hz (the design's duration, s) gives fewer \
             equations (samples × joints) than base parameters: raise the rate or the duration",
        ));
    }
    let problem = Problem {
        chain,
        base,
        shaper: &shaper,
        samples,
        state: RefCell::new(State {
            evaluations: 0,
            budget: c.max_evaluations.max(c.restarts),
            best_x: vec![],
            best_cost: f64::INFINITY,
            progress: &mut progress,
        }),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(c.seed);
    let mut cond_initial = f64::NAN;
    for k in 0..c.restarts {
        crate::interrupt::check("excitation design")?;
        let x: Vec<f64> = (0..vars).map(|_| rng.random_range(-1.0..1.0)).collect();
        let cost = (&problem).cost(&Params(x)).unwrap_or(f64::INFINITY);
        if k == 0 {
            cond_initial = cost.exp();
        }
    }
    // Nelder–Mead from the best random shape while the budget lasts.
    loop {
        crate::interrupt::check("excitation design")?;
        let start = {
            let s = problem.state.borrow();
            if s.best_x.is_empty() || s.budget.saturating_sub(s.evaluations) < vars + 2 {
                break;
            }
            s.best_x.clone()
        };
        let before = problem.state.borrow().evaluations;
        nelder_mead_run(&problem, &start, 0.3, 1e-6)?;
        if problem.state.borrow().evaluations == before {
            break;
        }
    }
    crate::interrupt::check("excitation design")?;
    let state = problem.state.into_inner();
    if !state.best_cost.is_finite() {
        return Err(PrrrpError::Infeasible {
            what: "no trajectory within the limits gives a finite cond(W_b): the joints cannot \
                   excite every base parameter (check the limits and friction terms)"
                .into(),
        });
    }
    let (trajectory, usage) = shaper.build(&state.best_x)?;
    let cond_final = cond_of(chain, base, &trajectory, samples, period)?;
    Ok(ChainExcitation {
        trajectory,
        period,
        cond_initial,
        cond_final,
        evaluations: state.evaluations,
        limit_usage: usage,
    })
}

/// cond(W_b) of `traj` sampled `samples` times over one period.
fn cond_of(
    chain: &DynChain,
    base: &BaseParameters,
    traj: &FourierTrajectory,
    samples: usize,
    period: f64,
) -> Result<f64> {
    let n = chain.dof();
    let (mut q, mut qd, mut qdd) = (
        vec![0.0; n * samples],
        vec![0.0; n * samples],
        vec![0.0; n * samples],
    );
    for k in 0..samples {
        let t = period * k as f64 / samples as f64;
        let r = k * n..(k + 1) * n;
        let (a, b, c) = (&mut q[r.clone()], &mut qd[r.clone()], &mut qdd[r]);
        traj.eval_into(t, a, b, c);
    }
    let w = chain.base_observation_matrix(base, &q, &qd, &qdd)?;
    let s = w.singular_values().map_err(|_| PrrrpError::NonFinite {
        what: "singular values of W_b".into(),
        row: None,
    })?;
    let (hi, lo) = s
        .iter()
        .fold((0.0f64, f64::INFINITY), |(h, l), &x| (h.max(x), l.min(x)));
    Ok(if lo > 0.0 { hi / lo } else { f64::INFINITY })
}

struct Shaper {
    n: usize,
    h: usize,
    omega: f64,
    margin: f64,
    offsets: Vec<f64>,
    limits: Vec<JointLimit>,
    grid: Vec<f64>,
}

impl Shaper {
    fn new(
        limits: &[JointLimit],
        names: &[String],
        c: &ChainExcitationConfig,
        period: f64,
    ) -> Result<Self> {
        let mut offsets = Vec::with_capacity(limits.len());
        for (j, l) in limits.iter().enumerate() {
            let has_pos = l.lower.is_finite() && l.upper.is_finite();
            if has_pos && l.upper <= l.lower {
                return Err(PrrrpError::InvalidParameter {
                    field: format!("position limits of joint {}", names[j]),
                    value: l.upper - l.lower,
                    reason: "must have upper > lower",
                });
            }
            let vel = l.velocity.is_finite() && l.velocity > 0.0;
            let acc = l.acceleration.is_finite() && l.acceleration > 0.0;
            if !vel || !(has_pos || acc) {
                let missing = if vel {
                    "position or acceleration limit"
                } else if has_pos || acc {
                    "speed limit"
                } else {
                    "speed limit and no position or acceleration limit"
                };
                return Err(PrrrpError::Infeasible {
                    what: format!(
                        "joint {} has no {missing}, so nothing bounds its excitation; give \
                         them in the robot file (URDF <limit velocity=.. lower=.. upper=..>) \
                         or as an override (`--limits velocity=2,acceleration=8` of `prrrp excite` and \
                         `prrrp simulate`, `limits` in Python)",
                        names[j]
                    ),
                });
            }
            offsets.push(if has_pos {
                0.5 * (l.lower + l.upper)
            } else {
                0.0
            });
        }
        let points = (40 * c.harmonics).max(200);
        Ok(Self {
            n: limits.len(),
            h: c.harmonics,
            omega: 2.0 * PI / period,
            margin: c.margin,
            offsets,
            limits: limits.to_vec(),
            grid: (0..points)
                .map(|k| period * k as f64 / points as f64)
                .collect(),
        })
    }

    /// The feasible trajectory of the free coefficients `x`, and each joint's limit usage.
    fn build(&self, x: &[f64]) -> Result<(FourierTrajectory, Vec<[f64; 3]>)> {
        let (n, h) = (self.n, self.h);
        let free = h - 1;
        let mut a = vec![0.0; n * h];
        let mut b = vec![0.0; n * h];
        for j in 0..n {
            let xa = &x[j * 2 * free..j * 2 * free + free];
            let xb = &x[j * 2 * free + free..(j + 1) * 2 * free];
            let (mut sa, mut sb) = (0.0, 0.0);
            for l in 0..free {
                a[j * h + l] = xa[l];
                b[j * h + l] = xb[l];
                sa += xa[l];
                sb += (l + 1) as f64 * xb[l];
            }
            a[j * h + free] = -sa;
            b[j * h + free] = -sb / h as f64;
        }
        let unit = FourierTrajectory::new(self.omega, vec![0.0; n], a.clone(), b.clone())?;
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut peak = vec![[0.0f64; 3]; n];
        for &t in &self.grid {
            unit.eval_into(t, &mut q, &mut qd, &mut qdd);
            for j in 0..n {
                peak[j][0] = peak[j][0].max(q[j].abs());
                peak[j][1] = peak[j][1].max(qd[j].abs());
                peak[j][2] = peak[j][2].max(qdd[j].abs());
            }
        }
        let keep = 1.0 - self.margin;
        let mut usage = vec![[f64::NAN; 3]; n];
        for j in 0..n {
            let l = &self.limits[j];
            let room = [0.5 * (l.upper - l.lower), l.velocity, l.acceleration];
            let mut s = f64::INFINITY;
            for k in 0..3 {
                if room[k].is_finite() && room[k] > 0.0 && peak[j][k] > 0.0 {
                    s = s.min(keep * room[k] / peak[j][k]);
                }
            }
            if !s.is_finite() {
                s = 0.0;
            }
            for l in 0..h {
                a[j * h + l] *= s;
                b[j * h + l] *= s;
            }
            for k in 0..3 {
                if room[k].is_finite() && room[k] > 0.0 {
                    usage[j][k] = s * peak[j][k] / room[k];
                }
            }
        }
        Ok((
            FourierTrajectory::new(self.omega, self.offsets.clone(), a, b)?,
            usage,
        ))
    }
}

struct State<'p> {
    evaluations: usize,
    budget: usize,
    best_x: Vec<f64>,
    best_cost: f64,
    progress: &'p mut dyn FnMut(usize, usize),
}

struct Problem<'a, 'p> {
    chain: &'a DynChain,
    base: &'a BaseParameters,
    shaper: &'a Shaper,
    samples: usize,
    state: RefCell<State<'p>>,
}

impl CostFunction for &Problem<'_, '_> {
    type Param = Params;
    type Output = f64;

    fn cost(&self, x: &Params) -> std::result::Result<f64, ArgminError> {
        {
            let s = self.state.borrow();
            if s.evaluations >= s.budget {
                return Err(ArgminError::msg("evaluation budget spent"));
            }
        }
        if crate::interrupt::stop_requested() {
            return Err(ArgminError::msg("interrupted"));
        }
        let period = 2.0 * PI / self.shaper.omega;
        let c = match self.shaper.build(&x.0) {
            Ok((traj, _)) => cond_of(self.chain, self.base, &traj, self.samples, period)
                .map(f64::ln)
                .unwrap_or(f64::INFINITY),
            Err(_) => f64::INFINITY,
        };
        // Nelder–Mead needs a finite value to order its simplex.
        let c = if c.is_finite() { c } else { 1e3 };
        let mut s = self.state.borrow_mut();
        s.evaluations += 1;
        if c < s.best_cost && c < 1e3 {
            s.best_cost = c;
            s.best_x.clone_from(&x.0);
        }
        let (e, b) = (s.evaluations, s.budget);
        if e % 20 == 0 || e == b {
            (s.progress)(e, b);
        }
        Ok(c)
    }
}
