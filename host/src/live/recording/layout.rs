//! A Foxglove / Lichtblick layout for one fleet: the shipped one
//! (`docs/foxglove-layout.json`) with its plots rewritten for the scenario's robots (the
//! leader's and every follower's speeds and turn rates, every follower's tracking error),
//! so the same file serves a `sim` and a `run` recording of any fleet size
//! (`--layout FILE`).

use base_station::scenario::{Role, Scenario};
use serde_json::{json, Value};

/// The shipped layout, as written by hand after Foxglove's format.
const SHIPPED: &str = include_str!("../../../../docs/foxglove-layout.json");

/// The layout for `scenario`'s fleet.
pub fn for_fleet(scenario: &Scenario) -> anyhow::Result<Value> {
    let mut layout: Value = serde_json::from_str(SHIPPED)?;
    let plot = |value: String| json!({ "value": value, "enabled": true, "timestampMethod": "receiveTime" });
    let followers: Vec<u16> = scenario
        .robots
        .iter()
        .filter(|r| r.role == Role::Follower)
        .map(|r| r.id)
        .collect();
    let errors: Vec<Value> = followers
        .iter()
        .map(|id| plot(format!("/robot_{id}/state.tracking_error")))
        .collect();
    let speeds: Vec<Value> = scenario
        .robots
        .iter()
        .flat_map(|r| ["v", "omega"].map(|field| plot(format!("/robot_{}/state.{field}", r.id))))
        .collect();
    let panels = layout["configById"]
        .as_object_mut()
        .ok_or_else(|| anyhow::anyhow!("the shipped layout has no panels"))?;
    for (panel, paths) in [("Plot!errors", errors), ("Plot!speeds", speeds)] {
        if let Some(config) = panels.get_mut(panel) {
            config["paths"] = Value::Array(paths);
        }
    }
    Ok(layout)
}

/// Writes the layout for `scenario`'s fleet to `path`.
pub fn write(scenario: &Scenario, path: &std::path::Path) -> anyhow::Result<()> {
    use anyhow::Context;
    let text = serde_json::to_string_pretty(&for_fleet(scenario)?)? + "\n";
    crate::commands::replace(path, |partial| {
        std::fs::write(partial, &text)
            .with_context(|| format!("cannot write {}", partial.display()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plots_follow_the_fleet() {
        let text = include_str!("../../../../scenarios/paper-obstacles.toml");
        let mut s = Scenario::parse(text, "paper").unwrap();
        let layout = for_fleet(&s).unwrap();
        let errors = layout["configById"]["Plot!errors"]["paths"].to_string();
        assert!(errors.contains("/robot_2/state.tracking_error"));
        assert!(!errors.contains("/robot_3/"), "{errors}");
        let mut extra = s.robots[2].clone();
        extra.id = 11;
        s.robots.push(extra);
        let layout = for_fleet(&s).unwrap();
        let errors = layout["configById"]["Plot!errors"]["paths"].to_string();
        assert!(
            errors.contains("/robot_11/state.tracking_error"),
            "{errors}"
        );
        let speeds = layout["configById"]["Plot!speeds"]["paths"].to_string();
        assert!(speeds.contains("/robot_0/state.v") && speeds.contains("/robot_11/state.omega"));
    }
}
