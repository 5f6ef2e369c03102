//! What each key carries: JSON objects cut from the console's snapshot, with the field
//! names the console's page reads (docs/operating.md#the-key-space has the schema).

use serde_json::{json, Value};

use super::keys::Formation;

/// The samples published every period: the formation, and each robot's pose, state and link.
pub fn per_period(f: &Formation, snapshot: &Value) -> Vec<(String, Value)> {
    let t = &snapshot["t_s"];
    let mut samples = vec![(f.key("formation"), formation(snapshot))];
    for robot in snapshot["robots"].as_array().into_iter().flatten() {
        let Some(id) = robot["id"].as_u64().and_then(|i| u16::try_from(i).ok()) else {
            continue;
        };
        let pose = &robot["pose"];
        if pose.is_array() {
            samples.push((
                f.robot_key(id, "pose"),
                json!({ "t_s": t, "x": pose[0], "y": pose[1], "heading": pose[2] }),
            ));
        }
        samples.push((
            f.robot_key(id, "state"),
            json!({
                "t_s": t,
                "role": robot["role"],
                "mode": robot["mode"],
                "faults": robot["faults"],
                "v": robot["v"],
                "tracking_error_m": robot["tracking_error_m"],
            }),
        ));
        samples.push((
            f.robot_key(id, "link"),
            json!({
                "t_s": t,
                "linked": robot["linked"],
                "seen_ms_ago": robot["seen_ms_ago"],
                "lost_after_ms": snapshot["lost_after_ms"],
            }),
        ));
    }
    samples
}

/// The formation as a whole.
fn formation(s: &Value) -> Value {
    json!({
        "t_s": s["t_s"],
        "gate": s["gate"],
        "shape": s["shape"],
        "blend": s["blend"],
        "hold": s["hold"],
        "arrived": s["arrived"],
        "progress": s["progress"],
        "slots": s["slots"],
        "footprint_m": s["footprint_m"],
        "robots": s["robots"].as_array().map(|r| r.iter().map(|r| r["id"].clone()).collect::<Vec<_>>()),
        "finished": s.get("finished"),
    })
}

/// The route's points.
pub fn route(s: &Value) -> Value {
    json!({ "t_s": s["t_s"], "points": s["route"] })
}

/// The events the snapshot has that were not published yet (`published` counts them all).
pub fn new_events(s: &Value, published: &mut u64) -> Vec<Value> {
    let total = s["events_total"].as_u64().unwrap_or(0);
    let shown = s["events"].as_array().map_or(&[][..], Vec::as_slice);
    let fresh = total.saturating_sub(*published).min(shown.len() as u64) as usize;
    *published = total;
    shown[shown.len() - fresh..].to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_are_published_once_each() {
        let snapshot = |total: u64, shown: &[u64]| json!({ "events_total": total, "events": shown.iter().map(|i| json!({"n": i})).collect::<Vec<_>>() });
        let mut published = 0;
        assert_eq!(new_events(&snapshot(2, &[0, 1]), &mut published).len(), 2);
        assert!(new_events(&snapshot(2, &[0, 1]), &mut published).is_empty());
        let fresh = new_events(&snapshot(4, &[0, 1, 2, 3]), &mut published);
        assert_eq!(fresh, vec![json!({"n": 2}), json!({"n": 3})]);
        // More than the snapshot shows came at once: those it shows.
        assert_eq!(
            new_events(&snapshot(100, &[97, 98, 99]), &mut published).len(),
            3
        );
    }

    #[test]
    fn a_robot_without_a_pose_has_no_pose_sample() {
        let f = Formation::new("s", "f").expect("names");
        let s = json!({ "t_s": 1.0, "robots": [
            { "id": 1, "pose": [1.0, 2.0, 0.5], "linked": true },
            { "id": 2, "pose": null, "linked": false },
        ]});
        let keys: Vec<String> = per_period(&f, &s).into_iter().map(|(k, _)| k).collect();
        assert!(keys.contains(&"sweeper/s/f/robot/1/pose".to_string()));
        assert!(!keys.contains(&"sweeper/s/f/robot/2/pose".to_string()));
        assert!(keys.contains(&"sweeper/s/f/robot/2/link".to_string()));
    }
}
