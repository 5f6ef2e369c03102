//! README's first command, as a user runs it: `basestation sim` writes a report with the
//! public keys and a figure.

use std::process::Command;

#[test]
fn basestation_sim_writes_report_and_figure() {
    let dir = std::env::temp_dir().join(format!("e2e-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let report = dir.join("r.json");
    let plot = dir.join("f.svg");
    let status = Command::new(env!("CARGO_BIN_EXE_basestation"))
        .args(["sim", "paper-passage", "--seed", "3"])
        .arg("--report")
        .arg(&report)
        .arg("--plot")
        .arg(&plot)
        .status()
        .unwrap();
    assert!(status.success());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in [
        "schema_version",
        "scenario",
        "seed",
        "firmware",
        "sim_time_s",
        "wall_time_s",
        "goal_reached",
        "time_to_goal_s",
        "collisions",
        "min_obstacle_clearance_m",
        "min_robot_separation_m",
        "convergence_time_s",
        "robots",
        "transformations",
        "link",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(r["schema_version"], 2);
    assert_eq!(r["seed"], 3);
    assert_eq!(r["firmware"], "native");
    for key in ["frames_sent", "frames_delivered", "frames_rejected"] {
        assert!(r["link"][key].is_u64(), "link.{key}");
    }
    let robot = &r["robots"][1];
    for key in [
        "id",
        "role",
        "avg_speed_mps",
        "avg_abs_omega_radps",
        "max_tracking_error_m",
        "stable_max_tracking_error_m",
    ] {
        assert!(robot.get(key).is_some(), "robots[1] lacks {key}");
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("tracking error"));
}

#[test]
fn sim_takes_faults_on_the_command_line() {
    let dir = std::env::temp_dir().join(format!("e2e-fault-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let report = dir.join("r.json");
    let out = Command::new(env!("CARGO_BIN_EXE_basestation"))
        .args(["sim", "paper-passage", "--plot", "/dev/null", "--fault"])
        .arg(r#"{ at_s = 30, kind = "leader_dies" }"#)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["goal_reached"], false);
    assert!(r["station_events"]
        .as_array()
        .unwrap()
        .iter()
        .any(|e| e["event"] == "leader_lost"));
    let bad = Command::new(env!("CARGO_BIN_EXE_basestation"))
        .args(["sim", "--fault", r#"{ at_s = 1, kind = "melt" }"#])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown variant `melt`"));
}
