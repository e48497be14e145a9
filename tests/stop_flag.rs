//! Per-call stop flags: raising one call's [`StopFlag`] stops that call, including the
//! worker threads it spawns, and no other computation of the process.

use std::sync::atomic::{AtomicUsize, Ordering};

use prrrp_core::{sensitivity, PrrrpError, Robot, SensitivityConfig, StopFlag};

fn sweep_config() -> SensitivityConfig {
    let mut cfg = SensitivityConfig {
        points: 5,
        threads: 2,
        ..SensitivityConfig::default()
    };
    cfg.validation.duration = 2.0;
    cfg
}

#[test]
fn a_raised_flag_stops_its_call_and_its_workers_only() {
    let robot = Robot::paper();
    let (model, nominal) = (robot.model(), robot.base_parameters());
    let cfg = sweep_config();
    let flag = StopFlag::new();
    std::thread::scope(|s| {
        // The sweep under the flag, raised by its first progress report (from a worker).
        let stopped = s.spawn(|| {
            let reports = AtomicUsize::new(0);
            let r = flag.run(|| {
                sensitivity(&model, &nominal, &cfg, &|_, _| {
                    reports.fetch_add(1, Ordering::Relaxed);
                    flag.raise();
                })
            });
            (r, reports.into_inner())
        });
        // Another sweep, in another thread, with no flag: it must run to its end.
        let other = s.spawn(|| sensitivity(&model, &nominal, &cfg, &|_, _| {}));
        let (r, reports) = stopped.join().unwrap();
        assert!(matches!(r, Err(PrrrpError::Interrupted { .. })), "{r:?}");
        assert!(reports >= 1);
        let full = other
            .join()
            .unwrap()
            .expect("the other call is not interrupted");
        let again = StopFlag::new().run(|| sensitivity(&model, &nominal, &cfg, &|_, _| {}));
        assert_eq!(full, again.unwrap());
    });
    // A raised flag is not the process's: a new call without it runs.
    assert!(!prrrp_core::stop_requested());
    assert!(flag.run(prrrp_core::stop_requested));
}
