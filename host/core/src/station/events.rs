//! What the station tells the operator and the run's report: its events, and the robots'
//! fault flags it reports.

use protocol::messages::faults;

use super::{FixChange, OperatorCommand};
use crate::formation::Target;

/// Something the operator (and the run's report) should know.
#[derive(Debug, Clone, PartialEq)]
pub enum StationEvent {
    Linked {
        robot: u16,
        at_ms: u32,
    },
    Transformation {
        to: Target,
        at_ms: u32,
    },
    LeaderLost {
        at_ms: u32,
    },
    LeaderBack {
        at_ms: u32,
    },
    Escape {
        at_ms: u32,
    },
    /// The way ahead was blocked: the route was planned again.
    Replanned {
        at_ms: u32,
    },
    /// No route to the next waypoint: the leader holds.
    NoRoute {
        at_ms: u32,
        why: String,
    },
    Arrived {
        at_ms: u32,
    },
    /// Every robot linked and reporting, followers holding slots: the leader may go.
    FleetReady {
        at_ms: u32,
    },
    /// The localization watch saw a robot's fixes stop or come back, or stopped or
    /// resumed the fleet for it.
    Localization {
        change: FixChange,
        at_ms: u32,
    },
    /// The operator (the console) told the fleet something.
    Operator {
        command: OperatorCommand,
        at_ms: u32,
    },
    /// A joined follower has been more than a metre from its reference for 5 s: the
    /// formation goes on without it (its ring holds it behind an obstacle, say).
    FollowerBehind {
        robot: u16,
        at_ms: u32,
    },
    /// A follower held on its way was sent round the obstacle (a `Detour`).
    FollowerDetour {
        robot: u16,
        at_ms: u32,
    },
    /// A follower whose way ran into another robot was held short of it (`spacing`).
    FollowerGivesWay {
        robot: u16,
        at_ms: u32,
    },
    /// The line's followers stood out of order: its slots were handed out anew in the
    /// order they stand (`order`).
    LineReordered {
        at_ms: u32,
    },
    /// A follower stepped aside for someone coming along a narrow way (`passing`).
    FollowerStepsAside {
        robot: u16,
        at_ms: u32,
    },
    /// A follower left behind is within 0.3 m of its reference again.
    FollowerCaughtUp {
        robot: u16,
        at_ms: u32,
    },
    /// Movers hold the leader: it waits for them to pass (`movers::Manner::Waiting`).
    Yielding {
        at_ms: u32,
    },
    /// The leader began to back out of the way of someone who may not see it.
    SteppingBack {
        at_ms: u32,
    },
    /// The leader began to go on, hurrying if need be, out of the way of someone who
    /// would walk into it standing.
    ClearingWay {
        at_ms: u32,
    },
    /// The leader began to step aside, out of the lane of someone coming along it.
    SteppingAside {
        at_ms: u32,
    },
    /// The leader is back at its route's pace after one of the four above.
    PaceResumed {
        at_ms: u32,
    },
    /// A feed (localization or scans) refused records in bulk: `refused` in the last
    /// second (unsealed, another key, replayed, off the clock, from outside the site).
    FeedRefused {
        input: String,
        refused: u64,
        at_ms: u32,
    },
    /// The sweep of `area` missed `patches` strips (people, a detour, the line's narrow
    /// swath): the leader goes back for them before leaving the area.
    SweepTouchUp {
        area: String,
        patches: usize,
        at_ms: u32,
    },
    /// A touch-up the leader made no way on for a minute was given up: what it was for
    /// stays unswept (the report's missed patches).
    SweepGivenUp {
        at_ms: u32,
    },
    /// A robot reported a fault; `halts` when the fleet was stopped for it.
    RobotFault {
        robot: u16,
        fault: &'static str,
        at_ms: u32,
        halts: bool,
    },
}

impl StationEvent {
    /// When (station clock, ms), what (a snake_case name, as in reports and recordings)
    /// and which robot; `leader`: the leader's id, for the events about it.
    pub fn describe(&self, leader: u16) -> (u32, String, Option<u16>) {
        use StationEvent as E;
        match self {
            E::Linked { robot, at_ms } => (*at_ms, "linked".into(), Some(*robot)),
            E::Transformation { to, at_ms } => {
                (*at_ms, format!("formation_to_{to:?}").to_lowercase(), None)
            }
            E::LeaderLost { at_ms } => (*at_ms, "leader_lost".into(), Some(leader)),
            E::LeaderBack { at_ms } => (*at_ms, "leader_back".into(), Some(leader)),
            E::Escape { at_ms } => (*at_ms, "local_minimum_escape".into(), None),
            E::Replanned { at_ms } => (*at_ms, "replanned".into(), None),
            E::NoRoute { at_ms, .. } => (*at_ms, "no_route".into(), None),
            E::Arrived { at_ms } => (*at_ms, "goal_reached".into(), None),
            E::FollowerBehind { robot, at_ms } => (*at_ms, "follower_behind".into(), Some(*robot)),
            E::FollowerDetour { robot, at_ms } => (*at_ms, "follower_detour".into(), Some(*robot)),
            E::FollowerGivesWay { robot, at_ms } => {
                (*at_ms, "follower_gives_way".into(), Some(*robot))
            }
            E::LineReordered { at_ms } => (*at_ms, "line_reordered".into(), None),
            E::FollowerStepsAside { robot, at_ms } => {
                (*at_ms, "follower_steps_aside".into(), Some(*robot))
            }
            E::FollowerCaughtUp { robot, at_ms } => {
                (*at_ms, "follower_caught_up".into(), Some(*robot))
            }
            E::FleetReady { at_ms } => (*at_ms, "fleet_ready".into(), None),
            E::Yielding { at_ms } => (*at_ms, "yielding".into(), Some(leader)),
            E::SteppingBack { at_ms } => (*at_ms, "stepping_back".into(), Some(leader)),
            E::ClearingWay { at_ms } => (*at_ms, "clearing_way".into(), Some(leader)),
            E::PaceResumed { at_ms } => (*at_ms, "pace_resumed".into(), Some(leader)),
            E::SteppingAside { at_ms } => (*at_ms, "stepping_aside".into(), Some(leader)),
            E::FeedRefused { input, at_ms, .. } => (*at_ms, format!("feed_refused:{input}"), None),
            E::SweepTouchUp { area, at_ms, .. } => (*at_ms, format!("sweep_touch_up:{area}"), None),
            E::SweepGivenUp { at_ms } => (*at_ms, "sweep_touch_up_given_up".into(), None),
            E::Operator { command, at_ms } => {
                (*at_ms, format!("operator_{}", command.name()), None)
            }
            E::Localization { change, at_ms } => match change {
                FixChange::Lost(robot) => (*at_ms, "localization_lost".into(), Some(*robot)),
                FixChange::Back(robot) => (*at_ms, "localization_back".into(), Some(*robot)),
                FixChange::Halt => (*at_ms, "localization_lost:fleet_halted".into(), None),
                FixChange::Resume => (*at_ms, "localization_back:fleet_resumed".into(), None),
            },
            E::RobotFault {
                robot,
                fault,
                at_ms,
                halts,
            } => (
                *at_ms,
                format!(
                    "robot_fault:{fault}{}",
                    if *halts { ":fleet_halted" } else { "" }
                ),
                Some(*robot),
            ),
        }
    }
}

/// How much an event matters to whoever watches the run: what stopped a robot or the
/// fleet for good is an error, what stopped it for a while or lost sight of something a
/// warning, the rest information.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    Info,
    Warning,
    Error,
}

impl Severity {
    /// An event's severity from its name (as in reports and recordings).
    pub fn of(event: &str) -> Severity {
        let halts = event.ends_with(":fleet_halted");
        match event {
            _ if halts => Severity::Error,
            "leader_lost" | "no_route" | "operator_emergency_stop" => Severity::Error,
            _ if event.starts_with("robot_fault:") || event.starts_with("feed_refused:") => {
                Severity::Warning
            }
            "localization_lost"
            | "follower_behind"
            | "operator_stop"
            | "local_minimum_escape"
            | "sweep_touch_up_given_up" => Severity::Warning,
            _ => Severity::Info,
        }
    }

    /// Its lower-case name, as the console and the logs give it.
    pub fn name(self) -> &'static str {
        match self {
            Severity::Info => "info",
            Severity::Warning => "warning",
            Severity::Error => "error",
        }
    }
}

/// Every fault flag a robot reports (`protocol::messages::faults`), by its name in
/// events, reports and the console.
pub const FAULT_NAMES: [(u16, &str); 10] = [
    (faults::LEADER_STATE_STALE, "leader_state_stale"),
    (faults::COMMAND_STALE, "command_stale"),
    (faults::NON_FINITE_INPUT, "non_finite_input"),
    (faults::WHEEL_STALL_LEFT, "wheel_stall_left"),
    (faults::WHEEL_STALL_RIGHT, "wheel_stall_right"),
    (faults::POSE_FIX_STALE, "pose_fix_stale"),
    (faults::POSE_FIX_REJECTED, "pose_fix_rejected"),
    (faults::EMERGENCY_STOP, "emergency_stop"),
    (faults::NOT_LINKED, "not_linked"),
    (faults::NOT_LOCALIZED, "not_localized"),
];

/// A fault flag's name (`?` for a bit [`FAULT_NAMES`] does not hold).
pub fn fault_name(bit: u16) -> &'static str {
    FAULT_NAMES
        .iter()
        .find(|(b, _)| *b == bit)
        .map_or("?", |(_, name)| name)
}

/// Fault flags the station reports as events, and whether they halt the fleet.
pub(super) const REPORTED_FAULTS: [(u16, bool); 3] = [
    (faults::WHEEL_STALL_LEFT, true),
    (faults::WHEEL_STALL_RIGHT, true),
    (faults::POSE_FIX_REJECTED, false),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn what_stops_the_fleet_is_an_error_and_a_wait_is_not() {
        assert_eq!(Severity::of("leader_lost"), Severity::Error);
        assert_eq!(Severity::of("operator_emergency_stop"), Severity::Error);
        assert_eq!(
            Severity::of("robot_fault:wheel_stall_left:fleet_halted"),
            Severity::Error
        );
        assert_eq!(
            Severity::of("localization_lost:fleet_halted"),
            Severity::Error
        );
        assert_eq!(
            Severity::of("robot_fault:pose_fix_rejected"),
            Severity::Warning
        );
        assert_eq!(Severity::of("localization_lost"), Severity::Warning);
        assert_eq!(Severity::of("yielding"), Severity::Info);
        assert_eq!(Severity::of("goal_reached"), Severity::Info);
    }
}
