//! Keeping the line in order. The followers take the line's slots in the order the
//! scenario lists them, and a follower's ring does not let it pass the one ahead of it.
//! Where the line comes out of a hold or a detour in the other order, the one left behind
//! follows the other at its ring's distance, 2 m off its slot, for good, and the leader
//! waits for it at its floor pace until its time is up. So the station hands the line's
//! slots out in the order the followers
//! stand along the leader's trail: where a follower held [`STUCK_M`] off its slot stands
//! farther back along the trail than one with a later slot, by [`MARGIN_M`], for
//! [`SETTLE_MS`], the slots are handed out again in the order they stand. Only where one
//! is held off its slot: followers that keep their slots, though one may stand a little
//! behind another for a moment where the leader's way turns back on itself, keep them
//! (handed out anew there, they would drive off their slots to swap).

use glam::DVec2;

use crate::formation::FollowerStatus;

/// A follower farther back than one with a later slot by more than this is out of order,
/// m: less is the jostle of two robots side by side.
const MARGIN_M: f64 = 0.5;
/// Out of order this long before the slots are handed out again, ms.
const SETTLE_MS: u32 = 3000;
/// A follower out of order this far or farther off its slot (by its telemetry) is held
/// there, m.
const STUCK_M: f64 = 1.0;
/// A follower this far or farther from the trail is not in the line yet, m.
const OFF_TRAIL_M: f64 = 1.5;

/// Watches the line's order.
#[derive(Debug, Default)]
pub struct LineOrder {
    /// Since when the line has been out of order.
    since_ms: Option<u32>,
}

impl LineOrder {
    /// One period. `in_line`: the formation is (mostly) the line; `order`: the followers'
    /// ids by slot; `followers`: what is known of each of them, in the same order;
    /// `trail`: the path the leader drove, from where it is back. The followers by slot
    /// anew, where they have stood out of order for [`SETTLE_MS`].
    pub fn step(
        &mut self,
        now_ms: u32,
        in_line: bool,
        order: &[u16],
        followers: &[Option<FollowerStatus>],
        trail: &[DVec2],
    ) -> Option<Vec<u16>> {
        let sorted = in_line
            .then(|| in_trail_order(order, followers, trail))
            .flatten();
        let Some(sorted) = sorted else {
            self.since_ms = None;
            return None;
        };
        let since = *self.since_ms.get_or_insert(now_ms);
        if now_ms.wrapping_sub(since) < SETTLE_MS {
            return None;
        }
        self.since_ms = None;
        Some(sorted)
    }
}

/// The followers in the order they stand back along `trail`, if one held off its slot
/// stands behind one with a later slot by more than [`MARGIN_M`] (and every one of them
/// stands on the trail).
fn in_trail_order(
    order: &[u16],
    followers: &[Option<FollowerStatus>],
    trail: &[DVec2],
) -> Option<Vec<u16>> {
    let back: Vec<f64> = followers
        .iter()
        .map(|f| along(trail, (*f)?.position))
        .collect::<Option<_>>()?;
    let stuck = |i: usize| followers[i].is_some_and(|f| f.error >= STUCK_M);
    let out_of_order = back
        .iter()
        .enumerate()
        .any(|(i, a)| stuck(i) && back[i + 1..].iter().any(|b| *a > b + MARGIN_M));
    if !out_of_order {
        return None;
    }
    let mut ranked: Vec<(f64, u16)> = back.into_iter().zip(order.iter().copied()).collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    Some(ranked.into_iter().map(|(_, id)| id).collect())
}

/// How far back along `trail` (from its first point) the point nearest `p` is, if `p` is
/// within [`OFF_TRAIL_M`] of it.
fn along(trail: &[DVec2], p: DVec2) -> Option<f64> {
    let mut best: Option<(f64, f64)> = None;
    let mut arc = 0.0;
    for w in trail.windows(2) {
        let (a, b) = (w[0], w[1]);
        let seg = b - a;
        let len = seg.length();
        let f = if len > 1e-9 {
            ((p - a).dot(seg) / (len * len)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d = p.distance(a + seg * f);
        if best.is_none_or(|(bd, _)| d < bd) {
            best = Some((d, arc + f * len));
        }
        arc += len;
    }
    best.filter(|(d, _)| *d < OFF_TRAIL_M).map(|(_, s)| s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The leader at the origin, having driven along +x: its trail runs back along -x.
    fn trail() -> Vec<DVec2> {
        (0..40).map(|k| DVec2::new(-0.25 * k as f64, 0.0)).collect()
    }

    /// A follower at (`x`, `y`), `error` off its slot.
    fn at(x: f64, y: f64, error: f64) -> Option<FollowerStatus> {
        Some(FollowerStatus {
            position: DVec2::new(x, y),
            error,
            joined: true,
            detouring: false,
        })
    }

    #[test]
    fn followers_out_of_order_on_the_trail_get_the_slots_in_the_order_they_stand() {
        let mut o = LineOrder::default();
        // Follower 1 (first slot) stands 2 m behind follower 2, held 2.8 m off its slot.
        let positions = [at(-4.0, 0.2, 2.8), at(-2.0, -0.1, 0.1)];
        assert_eq!(o.step(0, true, &[1, 2], &positions, &trail()), None);
        assert_eq!(o.step(2900, true, &[1, 2], &positions, &trail()), None);
        assert_eq!(
            o.step(3000, true, &[1, 2], &positions, &trail()),
            Some(vec![2, 1])
        );
        // Not in the line (the wide shape), no matter.
        let mut o = LineOrder::default();
        for now in [0, 3000, 6000] {
            assert_eq!(o.step(now, false, &[1, 2], &positions, &trail()), None);
        }
    }

    #[test]
    fn the_order_stands_where_followers_keep_it_or_jostle_or_are_off_the_trail() {
        let mut o = LineOrder::default();
        let in_order = [at(-1.2, 0.0, 0.0), at(-2.4, 0.0, 0.0)];
        let side_by_side = [at(-2.0, 0.3, 1.0), at(-1.8, -0.3, 0.6)];
        let off = [at(-4.0, 2.0, 3.0), at(-2.0, 0.0, 0.0)];
        let unknown = [None, at(-2.0, 0.0, 0.0)];
        // Behind, but keeping its slot: the slots cross where the trail turns back.
        let keeping = [at(-4.0, 0.0, 0.3), at(-2.0, 0.0, 0.2)];
        let cases = [in_order, side_by_side, off, unknown, keeping];
        for (t, p) in cases.iter().enumerate() {
            for k in 0..3 {
                let now = (t * 9000 + k * 2000) as u32;
                assert_eq!(o.step(now, true, &[1, 2], p, &trail()), None, "case {t}");
            }
        }
    }

    #[test]
    fn an_order_mended_before_it_settles_stands() {
        let mut o = LineOrder::default();
        let swapped = [at(-4.0, 0.0, 2.8), at(-2.0, 0.0, 0.0)];
        let mended = [at(-1.2, 0.0, 0.0), at(-2.4, 0.0, 0.0)];
        assert_eq!(o.step(0, true, &[1, 2], &swapped, &trail()), None);
        assert_eq!(o.step(2000, true, &[1, 2], &mended, &trail()), None);
        assert_eq!(o.step(2100, true, &[1, 2], &swapped, &trail()), None);
        assert_eq!(o.step(5000, true, &[1, 2], &swapped, &trail()), None);
        assert_eq!(
            o.step(5100, true, &[1, 2], &swapped, &trail()),
            Some(vec![2, 1])
        );
    }
}
