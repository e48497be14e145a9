use prrrp_core::{Robot, Vec5};

#[test]
fn paper_base_parameters() {
    let l = Robot::paper().base_parameters();
    let want = [
        4.297000, 0.108632, 0.067712, 0.066061, 0.026792, 0.025141, 0.025141, 0.511400,
    ];
    for i in 0..8 {
        assert!(
            (l[i] - want[i]).abs() < 5e-7,
            "λ{} = {} vs {}",
            i + 1,
            l[i],
            want[i]
        );
    }
    let m = Robot::paper().model();
    let q = Vec5::new(0.1, 0.2, 0.3, 0.4, 0.5);
    let _ = m.mass_matrix(&q, &l);
}
