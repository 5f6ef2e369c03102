//! The localization watch: when `run` has a localization source, the station forwards each
//! robot's fixes (at most `forward_hz` each) and watches their age. A robot without fixes
//! drives on odometry; after `lost_after` it is reported lost, after `stop_after` the fleet
//! stops until every robot has fixes again.
//!
//! Within each forwarding interval the fix that agrees best with the robot's own estimate
//! (its odometry, as its telemetry reports it) goes out, not the first to arrive: a source
//! that floods cannot win the interval by speed. A fix the robot would take for an outlier
//! is held back while fixes it agrees with keep coming (for [`HOLD_OUTLIERS_MS`] after the
//! last of them): only a localization that has really moved for that long reaches the
//! robot, which then re-anchors after its own count of outliers. Only the fixes that go
//! out count as fixes for the watch: lines that arrive and are never forwarded do not keep
//! a robot "located".

use std::collections::BTreeMap;

/// The watch's limits, from the site file's `[localization]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixLimits {
    pub forward_interval_ms: u32,
    pub lost_after_ms: u32,
    pub stop_after_ms: u32,
}

impl FixLimits {
    pub fn from_spec(z: &crate::scenario::LocalizationSpec) -> Self {
        Self {
            forward_interval_ms: (1000.0 / z.forward_hz).round() as u32,
            lost_after_ms: (z.lost_after_s * 1000.0).round() as u32,
            stop_after_ms: (z.stop_after_s * 1000.0).round() as u32,
        }
    }
}

/// Outliers wait this long after the last fix the robot agreed with, ms: as long as the
/// robot's own odometry holds out against them (control-core's `RELOCALIZE_AFTER`).
pub const HOLD_OUTLIERS_MS: u32 = 5000;

/// A fix waiting for its robot's next forwarding slot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate<F> {
    pub fix: F,
    /// How far it is from what the robot believes (lower is better; see
    /// [`super::check`]).
    pub disagreement: f64,
    /// The robot would take it for an outlier.
    pub outlier: bool,
}

#[derive(Debug, Clone, Copy)]
struct RobotFixes<F> {
    /// Station clock of the last fix forwarded (or of the watch's start).
    last_fix_ms: u32,
    last_forward_ms: Option<u32>,
    /// Station clock of the last fix the robot agreed with that arrived.
    last_agreed_ms: Option<u32>,
    lost: bool,
    waiting: Option<Candidate<F>>,
}

/// A change the watch saw at a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixChange {
    Lost(u16),
    Back(u16),
    /// A robot has had no fix for `stop_after`: the fleet stops.
    Halt,
    /// Every robot has fixes again: the fleet may go on.
    Resume,
}

/// What became of a fix offered to the watch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offer {
    /// It waits for the robot's next slot (it replaced a worse one, if any).
    Waiting,
    /// A fix that agrees better with the robot already waits for the slot.
    Outdone,
    /// An outlier to the robot while fixes it agrees with still come.
    HeldOutlier,
    /// Not a robot of the fleet.
    Unknown,
}

#[derive(Debug, Clone)]
pub struct FixWatch<F> {
    limits: FixLimits,
    robots: BTreeMap<u16, RobotFixes<F>>,
    halted: bool,
}

impl<F: Copy> FixWatch<F> {
    pub fn new(limits: FixLimits, robots: impl IntoIterator<Item = u16>, now_ms: u32) -> Self {
        let state = RobotFixes {
            last_fix_ms: now_ms,
            last_forward_ms: None,
            last_agreed_ms: None,
            lost: false,
            waiting: None,
        };
        Self {
            limits,
            robots: robots.into_iter().map(|id| (id, state)).collect(),
            halted: false,
        }
    }

    pub fn halted(&self) -> bool {
        self.halted
    }

    /// A fix of `robot` came from the source at `now_ms`: it waits for the robot's next
    /// slot unless a fix that agrees better with the robot waits already, or it is an
    /// outlier while agreeing fixes still come.
    pub fn offer(&mut self, robot: u16, candidate: Candidate<F>, now_ms: u32) -> Offer {
        let Some(r) = self.robots.get_mut(&robot) else {
            return Offer::Unknown;
        };
        if !candidate.outlier {
            r.last_agreed_ms = Some(now_ms);
        } else if r
            .last_agreed_ms
            .is_some_and(|t| now_ms.wrapping_sub(t) < HOLD_OUTLIERS_MS)
        {
            return Offer::HeldOutlier;
        }
        match &r.waiting {
            Some(w) if w.disagreement <= candidate.disagreement => Offer::Outdone,
            _ => {
                r.waiting = Some(candidate);
                Offer::Waiting
            }
        }
    }

    /// The fixes whose robots' slots have come, to go out now; each counts as that
    /// robot's latest fix.
    pub fn due(&mut self, now_ms: u32) -> Vec<(u16, F)> {
        let interval = self.limits.forward_interval_ms;
        let mut out = Vec::new();
        for (id, r) in &mut self.robots {
            let slot = r
                .last_forward_ms
                .is_none_or(|t| now_ms.wrapping_sub(t) >= interval);
            if let (true, Some(c)) = (slot, r.waiting.take_if(|_| slot)) {
                r.last_forward_ms = Some(now_ms);
                r.last_fix_ms = now_ms;
                out.push((*id, c.fix));
            }
        }
        out
    }

    /// The ages at `now_ms`: who is lost, who is back, and whether the fleet must stop.
    pub fn check(&mut self, now_ms: u32, changes: &mut Vec<FixChange>) {
        let mut oldest = 0;
        for (id, r) in &mut self.robots {
            let age = now_ms.wrapping_sub(r.last_fix_ms);
            oldest = oldest.max(age);
            let lost = age > self.limits.lost_after_ms;
            if lost != r.lost {
                r.lost = lost;
                changes.push(if lost {
                    FixChange::Lost(*id)
                } else {
                    FixChange::Back(*id)
                });
            }
        }
        if !self.halted && oldest > self.limits.stop_after_ms {
            self.halted = true;
            changes.push(FixChange::Halt);
        } else if self.halted && oldest <= self.limits.lost_after_ms {
            self.halted = false;
            changes.push(FixChange::Resume);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: FixLimits = FixLimits {
        forward_interval_ms: 200,
        lost_after_ms: 2000,
        stop_after_ms: 10_000,
    };

    fn offer(watch: &mut FixWatch<u32>, robot: u16, fix: u32, disagreement: f64) -> Offer {
        let candidate = Candidate {
            fix,
            disagreement,
            outlier: false,
        };
        watch.offer(robot, candidate, fix)
    }

    #[test]
    fn outliers_wait_while_agreeing_fixes_come_then_go_out() {
        let mut watch = FixWatch::new(LIMITS, [1], 0);
        let outlier = |fix| Candidate {
            fix,
            disagreement: 1e4,
            outlier: true,
        };
        assert_eq!(offer(&mut watch, 1, 0, 0.2), Offer::Waiting);
        watch.due(0);
        // A flood of outliers beside the agreeing fixes: none goes out.
        for t in (200..3000).step_by(200) {
            assert_eq!(watch.offer(1, outlier(t), t), Offer::HeldOutlier);
            offer(&mut watch, 1, t, 0.2);
            assert_eq!(watch.due(t), [(1, t)]);
        }
        // The localization moved for good: 5 s after the last agreeing fix, the outliers
        // go out (the robot re-anchors on them after its own count).
        assert_eq!(watch.offer(1, outlier(7799), 7799), Offer::HeldOutlier);
        assert_eq!(watch.offer(1, outlier(7800), 7800), Offer::Waiting);
        assert_eq!(watch.due(7800), [(1, 7800)]);
    }

    #[test]
    fn each_slot_takes_the_fix_that_agrees_best_not_the_first() {
        let mut watch = FixWatch::new(LIMITS, [1, 2], 0);
        assert_eq!(offer(&mut watch, 1, 10, 0.5), Offer::Waiting);
        assert_eq!(watch.due(0), [(1, 10)]);
        // A flood of far-off fixes first, the genuine one last: the genuine one goes out.
        for k in 0..50 {
            offer(&mut watch, 1, 100 + k, 40.0);
        }
        assert_eq!(offer(&mut watch, 1, 20, 0.3), Offer::Waiting);
        assert_eq!(offer(&mut watch, 1, 21, 45.0), Offer::Outdone);
        assert_eq!(watch.due(100), [], "not before the slot");
        assert_eq!(watch.due(200), [(1, 20)]);
        assert_eq!(watch.due(400), [], "nothing waits");
        assert_eq!(offer(&mut watch, 9, 1, 0.0), Offer::Unknown);
    }

    #[test]
    fn only_forwarded_fixes_keep_a_robot_located() {
        let mut watch = FixWatch::new(LIMITS, [1], 0);
        let mut changes = Vec::new();
        // Fixes keep arriving but none is ever taken out (the station never sends them):
        // the robot is lost all the same.
        for t in (0..=3000).step_by(100) {
            offer(&mut watch, 1, t, 1.0);
            watch.check(t, &mut changes);
        }
        assert_eq!(changes, [FixChange::Lost(1)]);
        changes.clear();
        watch.due(3100);
        watch.check(3100, &mut changes);
        assert_eq!(changes, [FixChange::Back(1)]);
    }

    #[test]
    fn a_silent_source_is_lost_then_stops_the_fleet_until_it_is_back() {
        let mut watch = FixWatch::new(LIMITS, [1, 2], 0);
        let mut changes = Vec::new();
        for t in (0..=12_000).step_by(100) {
            offer(&mut watch, 2, t, 0.0);
            watch.due(t);
            watch.check(t, &mut changes);
        }
        assert_eq!(changes, [FixChange::Lost(1), FixChange::Halt]);
        assert!(watch.halted());
        changes.clear();
        offer(&mut watch, 1, 0, 0.0);
        watch.due(12_100);
        watch.check(12_100, &mut changes);
        assert_eq!(changes, [FixChange::Back(1), FixChange::Resume]);
    }
}
