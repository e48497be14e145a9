//! Optimises the default excitation trajectory for the paper's robot and prints cond(W)
//! before and after, the evaluations and the wall time.
//!
//! `cargo run --release -p prrrp-core --example excitation [seed] [max_evaluations]`

use prrrp_core::{optimise_excitation, ExcitationConfig, Robot, DEFAULT_EXCITATION_KNOTS};

fn main() -> Result<(), prrrp_core::PrrrpError> {
    let mut args = std::env::args().skip(1);
    let mut config = ExcitationConfig::default();
    if let Some(seed) = args.next().and_then(|s| s.parse().ok()) {
        config.seed = seed;
    }
    if let Some(n) = args.next().and_then(|s| s.parse().ok()) {
        config.max_evaluations = n;
    }
    let model = Robot::paper().model();
    let start = std::time::Instant::now();
    let res = optimise_excitation::<DEFAULT_EXCITATION_KNOTS>(&model, &config, |p| {
        if p.evaluations % 500 == 0 {
            eprintln!(
                "{:>6} evals, run {}: cond {:.2}",
                p.evaluations, p.run, p.best_cond
            );
        }
    })?;
    println!(
        "cond(W): initial {:.2}, final {:.2}; {} evaluations; {:.2} s; max limit usage {:.4}",
        res.cond_initial,
        res.cond_final,
        res.evaluations,
        start.elapsed().as_secs_f64(),
        res.limit_usage.max()
    );
    Ok(())
}
