//! The run's story for the operator: how far the fleet has to go ([`Progress`]), and how
//! the run ended, in one line read the same everywhere ([`Ending`]: `sim`'s and `run`'s
//! summaries, the report, the figure's title, the console's banner).

use serde::Serialize;

use super::{BaseStation, Gate, StationEvent};

/// Where the fleet stands on its way.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Progress {
    /// Driven, and still to go along the route, m.
    pub done_m: f64,
    pub left_m: f64,
    /// The share of the way done, 0–1.
    pub share: f64,
    /// The waypoint it makes for (1-based), of how many (the goal is the last).
    pub waypoint: usize,
    pub waypoints: usize,
    /// At its average speed so far, when it arrives, s from now (null: too early to say).
    pub eta_s: Option<f64>,
    /// With areas to sweep: their share swept so far, as the station estimates its
    /// robots' brushes, 0–1.
    pub swept: Option<f64>,
}

/// The average speed is not told before the leader has driven this far, m.
const ETA_AFTER_M: f64 = 2.0;

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    GoalReached {
        at_s: f64,
    },
    /// The operator's Stop or emergency stop in force at the end (`interrupted`: the
    /// process was asked to stop).
    Stopped {
        how: &'static str,
        at_s: Option<f64>,
    },
    /// A robot fault halted the fleet for good.
    Halted {
        robot: u16,
        fault: String,
        at_s: f64,
    },
    /// The localization watch halted the fleet.
    LocalizationLost {
        at_s: f64,
    },
    /// The leader's telemetry stopped and never came back.
    LeaderLost {
        at_s: f64,
    },
    /// No way to the goal on the map as sensed.
    NoRoute {
        why: String,
        at_s: f64,
    },
    /// The run's time was up (its `duration_s`, or `--duration`) short of the goal.
    TimeUp {
        progress: Option<Progress>,
    },
    NeverLinked,
}

impl Ending {
    /// Its name in the report (`ending`).
    pub fn kind(&self) -> &'static str {
        match self {
            Ending::GoalReached { .. } => "goal_reached",
            Ending::Stopped { .. } => "stopped",
            Ending::Halted { .. } => "halted",
            Ending::LocalizationLost { .. } => "localization_lost",
            Ending::LeaderLost { .. } => "leader_lost",
            Ending::NoRoute { .. } => "no_route",
            Ending::TimeUp { .. } => "time_up",
            Ending::NeverLinked => "never_linked",
        }
    }

    /// The one line that says why it ended as it did.
    pub fn why(&self) -> String {
        match self {
            Ending::GoalReached { at_s } => format!("goal reached at {at_s:.1} s"),
            Ending::Stopped { how, at_s } => match at_s {
                Some(t) => format!("stopped by the operator ({how}) at {t:.1} s"),
                None => format!("stopped by the operator ({how})"),
            },
            Ending::Halted { robot, fault, at_s } => {
                format!("halted at {at_s:.1} s: robot {robot} reported {fault}")
            }
            Ending::LocalizationLost { at_s } => {
                format!("halted at {at_s:.1} s: the robots lost their localization")
            }
            Ending::LeaderLost { at_s } => {
                format!("the leader was lost at {at_s:.1} s and never came back")
            }
            Ending::NoRoute { why, at_s } => format!("no route to the goal at {at_s:.1} s: {why}"),
            Ending::TimeUp { progress: Some(p) } => format!(
                "time up {:.1} m short of the goal (waypoint {} of {}, {:.0} % of the way)",
                p.left_m,
                p.waypoint,
                p.waypoints,
                100.0 * p.share
            ),
            Ending::TimeUp { progress: None } => "time up before the leader set off".into(),
            Ending::NeverLinked => "no robot ever linked".into(),
        }
    }
}

impl BaseStation {
    /// Where the fleet stands on its way at `now_ms`, once the leader is known.
    pub fn progress(&self, now_ms: u32) -> Option<Progress> {
        let leader = self.leader_estimate(now_ms)?.pose.position;
        let (left_m, waypoint, waypoints) = self.guidance().planner().still_to_go(leader)?;
        let done_m = self.guidance().driven_m();
        let total = done_m + left_m;
        let running_s = self
            .running_since_ms
            .map(|t| now_ms.wrapping_sub(t) as f64 / 1000.0);
        let speed = running_s.filter(|s| *s > 0.0).map(|s| done_m / s);
        Some(Progress {
            done_m,
            left_m,
            share: if total > 0.0 { done_m / total } else { 1.0 },
            waypoint,
            waypoints,
            eta_s: speed
                .filter(|v| done_m >= ETA_AFTER_M && *v > 0.0)
                .map(|v| left_m / v),
            swept: self.sweeping().map(|w| w.swept_fraction()),
        })
    }

    /// How the run ended at `now_ms` (`interrupted`: the process was asked to stop).
    pub fn ending(&self, now_ms: u32, interrupted: bool) -> Ending {
        let s = |at_ms: u32| at_ms as f64 / 1000.0;
        let last =
            |f: &dyn Fn(&StationEvent) -> Option<Ending>| self.events().iter().rev().find_map(f);
        if self.arrived() {
            let at = last(&|e| match e {
                StationEvent::Arrived { at_ms } => Some(Ending::GoalReached { at_s: s(*at_ms) }),
                _ => None,
            });
            return at.unwrap_or(Ending::GoalReached { at_s: s(now_ms) });
        }
        let linked = self
            .events()
            .iter()
            .any(|e| matches!(e, StationEvent::Linked { .. }));
        if !linked {
            return Ending::NeverLinked;
        }
        if let Some(hold) = self.operator_hold() {
            let at_s = self.events().iter().rev().find_map(|e| match e {
                StationEvent::Operator { at_ms, .. } => Some(s(*at_ms)),
                _ => None,
            });
            return Ending::Stopped {
                how: hold.name(),
                at_s,
            };
        }
        if interrupted {
            return Ending::Stopped {
                how: "interrupted",
                at_s: Some(s(now_ms)),
            };
        }
        self.halted_ending().unwrap_or_else(|| Ending::TimeUp {
            progress: self.progress(now_ms),
        })
    }

    /// A fault, a lost localization, a lost leader or no route, if that is why the fleet
    /// stands at the end.
    fn halted_ending(&self) -> Option<Ending> {
        let s = |at_ms: u32| at_ms as f64 / 1000.0;
        let events = self.events();
        match self.gate {
            Gate::Halted => events.iter().rev().find_map(|e| match e {
                StationEvent::RobotFault {
                    robot,
                    fault,
                    at_ms,
                    halts: true,
                } => Some(Ending::Halted {
                    robot: *robot,
                    fault: fault.replace('_', " "),
                    at_s: s(*at_ms),
                }),
                _ => None,
            }),
            Gate::LeaderLost { .. } => events.iter().rev().find_map(|e| match e {
                StationEvent::LeaderLost { at_ms } => Some(Ending::LeaderLost { at_s: s(*at_ms) }),
                _ => None,
            }),
            _ if self.localization_halted() => events.iter().rev().find_map(|e| match e {
                StationEvent::Localization { at_ms, .. } => {
                    Some(Ending::LocalizationLost { at_s: s(*at_ms) })
                }
                _ => None,
            }),
            _ => {
                let why = self.guidance().planner().no_route()?.to_string();
                let at_s = events.iter().rev().find_map(|e| match e {
                    StationEvent::NoRoute { at_ms, .. } => Some(s(*at_ms)),
                    _ => None,
                })?;
                Some(Ending::NoRoute { why, at_s })
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every way a run ends has its one line, and its name in the report.
    #[test]
    fn every_ending_has_its_line() {
        let progress = Progress {
            done_m: 30.0,
            left_m: 12.5,
            share: 0.7,
            waypoint: 2,
            waypoints: 3,
            eta_s: Some(25.0),
            swept: None,
        };
        let cases = [
            (
                Ending::GoalReached { at_s: 71.5 },
                "goal_reached",
                "goal reached at 71.5 s",
            ),
            (
                Ending::Stopped {
                    how: "emergency_stop",
                    at_s: Some(12.0),
                },
                "stopped",
                "stopped by the operator (emergency_stop) at 12.0 s",
            ),
            (
                Ending::Halted {
                    robot: 2,
                    fault: "wheel stall left".into(),
                    at_s: 8.25,
                },
                "halted",
                "halted at 8.2 s: robot 2 reported wheel stall left",
            ),
            (
                Ending::LocalizationLost { at_s: 40.0 },
                "localization_lost",
                "halted at 40.0 s: the robots lost their localization",
            ),
            (
                Ending::LeaderLost { at_s: 30.1 },
                "leader_lost",
                "the leader was lost at 30.1 s and never came back",
            ),
            (
                Ending::NoRoute {
                    why: "the way is blocked".into(),
                    at_s: 5.0,
                },
                "no_route",
                "no route to the goal at 5.0 s: the way is blocked",
            ),
            (
                Ending::TimeUp {
                    progress: Some(progress),
                },
                "time_up",
                "time up 12.5 m short of the goal (waypoint 2 of 3, 70 % of the way)",
            ),
            (
                Ending::TimeUp { progress: None },
                "time_up",
                "time up before the leader set off",
            ),
            (Ending::NeverLinked, "never_linked", "no robot ever linked"),
        ];
        for (ending, kind, why) in cases {
            assert_eq!(ending.kind(), kind);
            assert_eq!(ending.why(), why);
        }
    }
}
