//! What the operator tells the fleet (the console's buttons), and how long the station
//! holds it: a Stop or an emergency stop is repeated every period until Resume; Resume is
//! repeated a few periods, so that one lost frame leaves no robot running or latched.

use protocol::messages::{EmergencyStop, Message, Resume, Stop};

/// What the operator tells the fleet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OperatorCommand {
    /// The formation halts: every robot brakes and holds; Resume goes on.
    Stop,
    /// Every robot latches stopped (its motors held at zero) until Resume.
    EmergencyStop,
    /// Clears a Stop or an emergency stop: the mission goes on.
    Resume,
}

/// The `reason` of the frames an operator's command sends.
const OPERATOR_REASON: u8 = 3;

/// A Resume is sent this many periods running.
const RESUME_REPEATS: u8 = 5;

impl OperatorCommand {
    pub fn name(self) -> &'static str {
        match self {
            OperatorCommand::Stop => "stop",
            OperatorCommand::EmergencyStop => "emergency_stop",
            OperatorCommand::Resume => "resume",
        }
    }

    /// The frame that carries it to every robot.
    pub fn message(self) -> Message {
        let reason = OPERATOR_REASON;
        match self {
            OperatorCommand::Stop => Message::Stop(Stop { reason }),
            OperatorCommand::EmergencyStop => Message::EmergencyStop(EmergencyStop { reason }),
            OperatorCommand::Resume => Message::Resume(Resume { reason }),
        }
    }
}

/// The operator's command in force, and the resumes still owed.
#[derive(Debug, Clone, Copy, Default)]
pub struct OperatorHold {
    held: Option<OperatorCommand>,
    resumes_left: u8,
}

impl OperatorHold {
    /// The operator said `command`.
    pub fn set(&mut self, command: OperatorCommand) {
        match command {
            OperatorCommand::Resume => {
                self.held = None;
                self.resumes_left = RESUME_REPEATS;
            }
            hold => {
                self.held = Some(hold);
                self.resumes_left = 0;
            }
        }
    }

    /// The Stop or emergency stop in force, if any.
    pub fn held(&self) -> Option<OperatorCommand> {
        self.held
    }

    /// What to broadcast this period for the operator: the hold (every period), or one of
    /// the resumes still owed.
    pub fn this_period(&mut self) -> Option<OperatorCommand> {
        if self.held.is_some() {
            return self.held;
        }
        (self.resumes_left > 0).then(|| {
            self.resumes_left -= 1;
            OperatorCommand::Resume
        })
    }
}
