//! A bad radio: 30 % frame loss and 200 ms latency (± 20 ms). The formation still reaches
//! the goal of paper-obstacles without contact; the tracking error may grow.

mod common;

use common::{run, shipped};

#[test]
fn thirty_percent_loss_and_200_ms_latency() {
    let mut s = shipped("paper-obstacles");
    s.link.loss = 0.3;
    s.link.latency_ms = 200.0;
    s.link.jitter_ms = 20.0;
    let (r, _) = run(s, 1);
    println!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert!(r.goal_reached);
    assert_eq!(r.collisions, 0);
    assert!(r.min_obstacle_clearance_m >= 0.1);
    for f in r.robots.iter().filter(|x| x.role == "follower") {
        println!(
            "follower {}: max tracking error {:?}",
            f.id, f.max_tracking_error_m
        );
    }
}
