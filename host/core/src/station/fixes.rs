//! The localization watch: when `run` has a localization source, the station forwards each
//! robot's fixes (at most `forward_hz` each) and watches their age. A robot without fixes
//! drives on odometry; after `lost_after` it is reported lost, after `stop_after` the fleet
//! stops until every robot has fixes again.

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

#[derive(Debug, Clone, Copy)]
struct RobotFixes {
    /// Station clock of the last fix received (or of the watch's start).
    last_fix_ms: u32,
    last_forward_ms: Option<u32>,
    lost: bool,
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

#[derive(Debug, Clone)]
pub struct FixWatch {
    limits: FixLimits,
    robots: BTreeMap<u16, RobotFixes>,
    halted: bool,
}

impl FixWatch {
    pub fn new(limits: FixLimits, robots: impl IntoIterator<Item = u16>, now_ms: u32) -> Self {
        let state = RobotFixes {
            last_fix_ms: now_ms,
            last_forward_ms: None,
            lost: false,
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

    /// A fix of `robot` came from the source: whether it may go out now (`None`: not a
    /// robot of the fleet).
    pub fn admit(&mut self, robot: u16, now_ms: u32) -> Option<bool> {
        let r = self.robots.get_mut(&robot)?;
        r.last_fix_ms = now_ms;
        let due = r
            .last_forward_ms
            .is_none_or(|t| now_ms.wrapping_sub(t) >= self.limits.forward_interval_ms);
        if due {
            r.last_forward_ms = Some(now_ms);
        }
        Some(due)
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

    #[test]
    fn fixes_are_rate_limited_per_robot() {
        let mut watch = FixWatch::new(LIMITS, [1, 2], 0);
        let sent: Vec<bool> = [0, 100, 200, 250, 400]
            .iter()
            .map(|t| watch.admit(1, *t).unwrap())
            .collect();
        assert_eq!(sent, [true, false, true, false, true]);
        assert_eq!(watch.admit(2, 250), Some(true));
        assert_eq!(watch.admit(9, 250), None);
    }

    #[test]
    fn a_silent_source_is_lost_then_stops_the_fleet_until_it_is_back() {
        let mut watch = FixWatch::new(LIMITS, [1, 2], 0);
        let mut changes = Vec::new();
        for t in (0..=12_000).step_by(100) {
            watch.admit(2, t);
            watch.check(t, &mut changes);
        }
        assert_eq!(changes, [FixChange::Lost(1), FixChange::Halt]);
        assert!(watch.halted());
        changes.clear();
        watch.admit(1, 12_100);
        watch.check(12_100, &mut changes);
        assert_eq!(changes, [FixChange::Back(1), FixChange::Resume]);
    }
}
