//! Runs the paper's study with defaults and prints λ per method against the truth.
//!
//! `cargo run --release --example study -- [SEED] [OUT.json]`

use prrrp_core::{run_study, Robot, StudyConfig};

fn main() -> Result<(), prrrp_core::PrrrpError> {
    let mut args = std::env::args().skip(1);
    let seed = args.next().and_then(|s| s.parse().ok()).unwrap_or(0);
    let out = args.next();
    let mut config = StudyConfig {
        seed,
        ..StudyConfig::default()
    };
    // Tuning knobs for experiments, e.g. EKF_POS_NOISE=3e-3 EKF_REL_STD=0.3.
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<f64>().ok());
    if let Some(v) = env("EKF_POS_NOISE") {
        config.ekf.position_noise = v;
    }
    if let Some(v) = env("EKF_REL_STD") {
        config.ekf.initial_parameter_rel_std = v;
    }
    if let Some(v) = env("EKF_PARAM_NOISE") {
        config.ekf.process_parameter_noise = v;
    }
    if let Some(v) = env("ADALINE_MU") {
        config.adaline.step_size = v;
    }
    if let Some(v) = env("HOPFIELD_BETA") {
        config.hopfield.beta = v;
    }
    let r = run_study(&Robot::paper(), &config, &|_, _, _| {})?;
    println!(
        "cond(W): {:.2} -> {:.2}",
        r.excitation.cond_initial, r.excitation.cond_final
    );
    print!("{:>14}", "truth");
    for x in r.truth {
        print!(" {x:9.5}");
    }
    println!();
    for e in &r.estimates {
        print!("{:>14}", e.method);
        for x in e.lambda {
            print!(" {x:9.5}");
        }
        let worst = e
            .relative_error_percent
            .iter()
            .fold(0.0f64, |a, &b| a.max(b));
        println!("   worst {worst:.2} %  ({:.2} s) {:?}", e.seconds, e.error);
    }
    for m in &r.validation.methods {
        println!(
            "{:>14} torque RMS {:?}  rel% {:?}",
            m.method, m.torque_rms, m.torque_relative_percent
        );
    }
    println!("timings {:?}", r.timings_s);
    if let Some(path) = out {
        std::fs::write(&path, r.to_json()?).expect("write");
    }
    Ok(())
}
