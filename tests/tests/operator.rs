//! The operator's commands (the console's buttons) through the real station, radio and
//! robots: an emergency stop latches every robot within a second, even on the scenario's
//! lossy radio, until Resume; a Stop halts the formation; the mission then goes on.

mod common;

use base_station::station::OperatorCommand;
use common::shipped;
use hil_sim::run::report_of;
use hil_sim::world::{SimOptions, World};

/// Runs the paper's passage, giving `command` at `at_s` and Resume at `resume_s`; returns
/// the world and the time of the last robot still moving (> 0.01 m/s) in between.
fn hold(command: OperatorCommand, at_s: f64, resume_s: f64) -> (World, f64) {
    let mut world = World::new(shipped("paper-passage"), SimOptions::new(1)).unwrap();
    let (at, resume) = ((at_s * 1e6) as u64, (resume_s * 1e6) as u64);
    let mut last_moving = 0.0f64;
    world
        .run_with(|w| {
            let now_ms = w.base_ms();
            if w.t_us == at {
                w.station.operator(command, now_ms);
            }
            if w.t_us == resume {
                w.station.operator(OperatorCommand::Resume, now_ms);
            }
            if (at..resume).contains(&w.t_us)
                && w.robots.iter().any(|r| r.body.twist().0.abs() > 0.01)
            {
                last_moving = w.t_us as f64 / 1e6;
            }
        })
        .unwrap();
    (world, last_moving)
}

#[test]
fn an_emergency_stop_latches_every_robot_within_a_second_until_resume() {
    let (world, last_moving) = hold(OperatorCommand::EmergencyStop, 30.0, 40.0);
    let r = report_of(&world, 0.0);
    println!("emergency stop at 30.0 s: last robot moving at {last_moving:.2} s");
    assert!(last_moving <= 31.0, "a robot moved until {last_moving} s");
    assert!(r.goal_reached, "the mission did not go on after Resume");
    assert_eq!(r.collisions, 0);
    let events: Vec<_> = r.station_events.iter().map(|e| e.event.as_str()).collect();
    assert!(events.contains(&"operator_emergency_stop") && events.contains(&"operator_resume"));
}

#[test]
fn a_stop_halts_the_formation_and_resume_goes_on() {
    let (world, last_moving) = hold(OperatorCommand::Stop, 30.0, 40.0);
    let r = report_of(&world, 0.0);
    println!("stop at 30.0 s: last robot moving at {last_moving:.2} s");
    assert!(last_moving <= 32.0, "a robot moved until {last_moving} s");
    assert!(r.goal_reached);
    assert_eq!(r.collisions, 0);
}
