//! How a run ended, as the process's exit code: distinct, so that a script can tell a
//! reached goal from a stop, a missed goal, a fleet that never answered and bad input
//! (`README.md#exit-codes`). The same in `sim` and `run`.

use std::process::ExitCode;

use base_station::station::Ending;

/// How a `sim` or `run` ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The leader reached the goal: 0.
    GoalReached,
    /// The operator stopped the run (a Stop or emergency stop in force at the end, or the
    /// process interrupted): 4.
    Stopped,
    /// The run ended without reaching the goal: 3.
    GoalNotReached,
    /// No robot ever linked: 5.
    NeverLinked,
}

/// Bad input (a file, a scenario, a key) or a failure: 1. Clap's own usage errors: 2.
pub const BAD_INPUT: u8 = 1;

impl Outcome {
    pub fn code(self) -> u8 {
        match self {
            Outcome::GoalReached => 0,
            Outcome::GoalNotReached => 3,
            Outcome::Stopped => 4,
            Outcome::NeverLinked => 5,
        }
    }

    /// The exit code's class of how a run ended.
    pub fn of(ending: &Ending) -> Self {
        match ending {
            Ending::GoalReached { .. } => Outcome::GoalReached,
            Ending::NeverLinked => Outcome::NeverLinked,
            Ending::Stopped { .. } => Outcome::Stopped,
            _ => Outcome::GoalNotReached,
        }
    }

    /// The process's exit code.
    pub fn exit_code(self) -> ExitCode {
        ExitCode::from(self.code())
    }
}
