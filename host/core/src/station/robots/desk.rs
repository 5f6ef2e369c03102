//! One desk for follower orders. Several rooms may want a follower somewhere other than
//! its slot this period: held short of a robot its ring cannot see, stepping aside for a
//! held one, backing off the leader it stands in front of, stepping aside for someone
//! coming down a narrow way, sent round what the map shows. Each proposes; the desk keeps
//! one order per follower, the highest by [`Kind`]'s written rank, and says which orders
//! are new. The radio only sends what it returns.

use std::collections::BTreeMap;

use glam::DVec2;

/// What a follower is told, highest rank first: safety between robots before making way
/// for the leader, before courtesy to people, before a way round the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// Stop where it can: its way runs into a robot its ring cannot see.
    Hold,
    /// Step aside: it stands in the way of a follower held for it.
    MakeRoom,
    /// Back off the leader it stands in front of.
    BackOff,
    /// Step aside for someone coming down a narrow way.
    StepAside,
    /// Go round what holds it on its way to its slot.
    Detour,
}

/// One room's wish for a follower: the point its control point makes for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proposal {
    pub robot: u16,
    pub kind: Kind,
    pub point: DVec2,
}

/// The order a follower gets this period, and whether it is new (it had none, or
/// another kind, last period).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Order {
    pub robot: u16,
    pub kind: Kind,
    pub point: DVec2,
    pub began: bool,
}

/// The orders given last period.
#[derive(Debug, Default)]
pub struct Desk {
    last: BTreeMap<u16, Kind>,
}

/// The highest-ranked of `proposals` for each follower.
pub fn best(proposals: &[Proposal]) -> BTreeMap<u16, Proposal> {
    let mut out: BTreeMap<u16, Proposal> = BTreeMap::new();
    for p in proposals {
        match out.get(&p.robot) {
            Some(kept) if kept.kind <= p.kind => {}
            _ => {
                out.insert(p.robot, *p);
            }
        }
    }
    out
}

impl Desk {
    /// This period's orders from every room's `proposals`, by follower.
    pub fn decide(&mut self, proposals: &[Proposal]) -> Vec<Order> {
        let orders: Vec<Order> = best(proposals)
            .into_values()
            .map(|p| Order {
                robot: p.robot,
                kind: p.kind,
                point: p.point,
                began: self.last.get(&p.robot) != Some(&p.kind),
            })
            .collect();
        self.last = orders.iter().map(|o| (o.robot, o.kind)).collect();
        orders
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(robot: u16, kind: Kind, x: f64) -> Proposal {
        Proposal {
            robot,
            kind,
            point: DVec2::new(x, 0.0),
        }
    }

    #[test]
    fn one_order_per_follower_by_rank_whatever_the_order_of_proposals() {
        let mut desk = Desk::default();
        let props = [
            p(1, Kind::Detour, 1.0),
            p(2, Kind::StepAside, 2.0),
            p(1, Kind::Hold, 3.0),
            p(2, Kind::BackOff, 4.0),
        ];
        let mut reversed = props;
        reversed.reverse();
        let a = desk.decide(&props);
        let b = Desk::default().decide(&reversed);
        assert_eq!(a, b);
        assert_eq!(a.len(), 2);
        assert_eq!(
            (a[0].kind, a[0].point.x, a[0].began),
            (Kind::Hold, 3.0, true)
        );
        assert_eq!((a[1].kind, a[1].point.x), (Kind::BackOff, 4.0));
        // The same again: not new. Another kind: new.
        let again = desk.decide(&[p(1, Kind::Hold, 3.1), p(2, Kind::Detour, 0.0)]);
        assert!(!again[0].began && again[1].began);
    }
}
