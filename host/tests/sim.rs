//! README's first command, as a user runs it: `basestation sim` writes a report with the
//! public keys, a figure and an MCAP recording (read back here with the `mcap` crate).

mod common;

use std::collections::BTreeMap;

#[test]
fn basestation_sim_writes_report_and_figure() {
    let dir = common::scratch("e2e-sim");
    let (out, report) = common::sim_into(&dir, "paper-passage", &["--seed", "3"]);
    let (plot, recording) = (dir.join("figure.svg"), dir.join("run.mcap"));
    assert!(out.status.success());
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
        "movers",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}");
    }
    assert_eq!(r["schema_version"], 6);
    assert_eq!(r["link"]["channel"]["radio"], "own_air");
    assert!(
        r.get("coverage").is_none(),
        "no areas to sweep, no coverage"
    );
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

    // The recording: every channel with its schema, and as many messages as the run has
    // samples (the report's sim time at 10 Hz), robots and station events.
    let bytes = std::fs::read(&recording).unwrap();
    let mut count: BTreeMap<String, (String, u64)> = BTreeMap::new();
    let mut schemas: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    let mut last_ns = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .map(|s| s.name.clone())
            .unwrap_or_default();
        if let Some(s) = &m.channel.schema {
            schemas
                .entry(m.channel.topic.clone())
                .or_insert_with(|| s.data.to_vec());
        }
        count
            .entry(m.channel.topic.clone())
            .or_insert((schema, 0))
            .1 += 1;
        last_ns = last_ns.max(m.log_time);
    }
    let samples = (r["sim_time_s"].as_f64().unwrap() * 10.0).round() as u64;
    let events = r["station_events"].as_array().unwrap().len() as u64;
    assert_eq!(count["/map"], ("foxglove.SceneUpdate".to_string(), 1));
    assert_eq!(
        count["/robots"],
        ("foxglove.SceneUpdate".to_string(), samples)
    );
    // Every robot's frame moves with one transform message per sample.
    assert_eq!(
        count["/tf"],
        ("foxglove.FrameTransforms".to_string(), samples)
    );
    for id in 0..3 {
        assert_eq!(
            count[&format!("/robot_{id}/pose")],
            ("foxglove.PoseInFrame".to_string(), samples)
        );
        assert_eq!(count[&format!("/robot_{id}/state")].1, samples);
    }
    assert_eq!(count["/events"], ("foxglove.Log".to_string(), events));
    // The route as planned (at least once), the shape at the start and at each change's
    // two ends (to the line, line, back to the wide shape, wide).
    assert!(count["/route"].1 >= 1, "{:?}", count["/route"]);
    // Each robot's link health once a second.
    for id in 0..3 {
        let links = count[&format!("/robot_{id}/link")].1;
        assert!(
            links + 1 >= r["sim_time_s"].as_f64().unwrap() as u64,
            "{links}"
        );
    }
    let changes = r["transformations"].as_array().unwrap().len() as u64;
    assert_eq!(
        count["/formation"].1,
        1 + 2 * changes,
        "{:?}",
        count["/formation"]
    );
    assert!(events > 0);
    // Stamped with the simulated clock.
    let end_ns = (r["sim_time_s"].as_f64().unwrap() * 1e9) as u64;
    assert!(
        last_ns <= end_ns && last_ns + 200_000_000 >= end_ns,
        "{last_ns} vs {end_ns}"
    );

    // `decode` reads the recording's radio channel: the run's frames, verified with the
    // simulation's key (from its seed), each with its time and sender.
    let lines = common::decode(&recording, &hex::encode(hil_sim::world::sim_key_bytes(3)));
    let verified = lines.iter().filter(|l| l["verified"] == true).count();
    let of = |message: &str, sender: &str| {
        lines
            .iter()
            .filter(|l| l["message"] == message && l["sender"] == sender)
            .count()
    };
    println!("decode: {} frames, {verified} verified", lines.len());
    // `decode --seed 3` derives the same key as the simulation: the same frames verify;
    // another seed's key verifies none, and says why; without a seed, the recording's own
    // (its metadata) is taken. The closing line counts the verified frames.
    let by_seed = |seed: Option<&str>| {
        let mut args = vec!["decode", recording.to_str().unwrap()];
        args.extend(seed.map(|s| ["--seed", s]).into_iter().flatten());
        let out = common::basestation()
            .args(args)
            .env_remove("SWEEPER_KEY_FILE")
            .env_remove("SWEEPER_FLEET_KEY")
            .output()
            .unwrap();
        assert!(out.status.success());
        let n = String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter(|l| l.contains("\"verified\":true"))
            .count();
        (n, String::from_utf8_lossy(&out.stderr).to_string())
    };
    let (n, err) = by_seed(Some("3"));
    assert_eq!(n, verified);
    assert!(err.contains(&format!("{verified} verified")), "{err}");
    let (n, err) = by_seed(Some("4"));
    assert_eq!(n, 0);
    assert!(err.contains("made with --seed 3, not 4"), "{err}");
    assert!(err.contains("no frame verified"), "{err}");
    let (n, err) = by_seed(None);
    assert_eq!(n, verified, "{err}");
    assert!(err.contains("from the recording's metadata"), "{err}");
    assert_eq!(count["/radio"].0, "RadioBytes");
    assert!(
        lines.len() as u64 >= count["/radio"].1,
        "every transmission holds a frame"
    );
    assert!(
        verified * 100 >= lines.len() * 95,
        "{verified} of {}",
        lines.len()
    );
    assert!(of("LeaderState", "base") > 500 && of("Telemetry", "robot:1") > 500);
    assert!(lines.iter().all(|l| l["t_s"].as_f64().is_some()));

    // A run without movers records none.
    common::assert_layout_fits(&schemas, &["/movers", "/tracks", "/sensed", "/coverage"]);
}

#[test]
fn sim_takes_faults_on_the_command_line() {
    let dir = common::scratch("e2e-fault");
    let fault = r#"{ at_s = 30, kind = "leader_dies" }"#;
    let (out, report) = common::sim_into(&dir, "paper-passage", &["--fault", fault]);
    // The goal not reached: exit code 3 (README.md#exit-codes).
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The progress bar draws on a terminal only: nothing of it in a pipe.
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains('\r') && !err.contains("simulating"), "{err}");
    // A halt is an ERROR, at the default level (issue 30: it was INFO).
    assert!(
        err.lines().any(|l| l.contains("ERROR")
            && l.contains("no fresh telemetry from the leader: fleet stops")),
        "{err}"
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["goal_reached"], false);
    assert!(r["station_events"]
        .as_array()
        .unwrap()
        .iter()
        .any(|e| e["event"] == "leader_lost"));
    let bad = common::basestation()
        .args(["sim", "--fault", r#"{ at_s = 1, kind = "melt" }"#])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown variant `melt`"));
}

/// The shipped street crossing: the report counts its movers and what the robots did
/// among them; the recording shows the movers (the truth) and the station's tracks, a
/// scene update per sample while there are any.
#[test]
fn street_crossing_reports_and_records_the_movers() {
    let dir = common::scratch("e2e-sim-movers");
    let layout = dir.join("layout.json");
    let (out, report) = common::sim_into(
        &dir,
        "street-crossing",
        &["--layout", layout.to_str().unwrap()],
    );
    // The goal reached: exit code 0.
    assert_eq!(out.status.code(), Some(0));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let m = &r["movers"];
    assert_eq!(m["count"], 5);
    assert_eq!(m["contacts_moving"], 0, "{m}");
    assert!(m["time_to_goal_empty_s"].as_f64().unwrap() > 0.0);
    assert!(
        m["tracking"]["detected_fraction"].as_f64().unwrap() > 0.5,
        "{m}"
    );
    let samples = (r["sim_time_s"].as_f64().unwrap() * 10.0).round() as u64;
    let bytes = std::fs::read(dir.join("run.mcap")).unwrap();
    let mut count: BTreeMap<String, (String, u64)> = BTreeMap::new();
    let mut schemas: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if let Some(s) = &m.channel.schema {
            schemas
                .entry(m.channel.topic.clone())
                .or_insert_with(|| s.data.to_vec());
        }
        let schema = m.channel.schema.as_ref().map(|s| s.name.clone());
        count
            .entry(m.channel.topic.clone())
            .or_insert((schema.unwrap_or_default(), 0))
            .1 += 1;
    }
    // A walker goes back and forth for ever: movers every sample once it appeared.
    let (schema, movers) = &count["/movers"];
    assert_eq!(schema, "foxglove.SceneUpdate");
    assert!(*movers + 10 >= samples, "{movers} of {samples}");
    let (schema, tracks) = &count["/tracks"];
    assert_eq!(schema, "foxglove.SceneUpdate");
    assert!(*tracks > samples / 2, "{tracks} of {samples}");
    // The person who stops in the street is marked, with the room they are owed.
    let (schema, sensed) = &count["/sensed"];
    assert_eq!(schema, "foxglove.SceneUpdate");
    assert!(*sensed >= 1, "{sensed}");
    // And the figure draws the marks, in the station's colour, with their legend.
    let figure = std::fs::read_to_string(dir.join("figure.svg")).unwrap();
    assert!(figure.contains("marks (station)"), "no marks' legend");
    assert!(
        figure.contains(r##"opacity="0.12" fill="#9650D2""##),
        "no mark drawn"
    );
    // The shipped layout shows them.
    common::assert_layout_fits(&schemas, &["/coverage"]);
    // `--layout`: every topic its plots name is a channel of this recording.
    let layout: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&layout).unwrap()).unwrap();
    let mut plotted = 0;
    for panel in layout["configById"].as_object().unwrap().values() {
        for p in panel["paths"].as_array().into_iter().flatten() {
            let (topic, field) = p["value"].as_str().unwrap().split_once('.').unwrap();
            let schema = schemas
                .get(topic)
                .unwrap_or_else(|| panic!("{topic} not recorded"));
            assert!(
                schema.windows(field.len()).any(|w| w == field.as_bytes()),
                "{topic}.{field}"
            );
            plotted += 1;
        }
    }
    assert_eq!(
        plotted,
        2 + 3 * 2,
        "two followers' errors, three robots' v and omega"
    );
    // A metadata record says what ran, which build, since when.
    let meta = mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .filter_map(|r| match r.unwrap() {
            mcap::records::Record::Metadata(m) => Some(m),
            _ => None,
        })
        .find(|m| m.name == "run")
        .expect("a metadata record");
    let get = |k: &str| meta.metadata.get(k).cloned().unwrap_or_default();
    assert_eq!(get("scenario"), "street-crossing");
    assert_eq!(get("seed"), "1");
    assert_eq!(get("firmware"), "native");
    assert_eq!(get("version"), env!("CARGO_PKG_VERSION"));
    assert!(!get("git_revision").is_empty());
    assert!(get("started_utc").starts_with("20"), "{meta:?}");
}

/// Logs piped to a file carry no colour codes; the shipped plaza's crowd is crossed
/// (docs/results.md#movers) and the exit code says whether the goal was reached.
#[test]
fn piped_logs_are_plain_and_the_plaza_is_crossed() {
    let dir = common::scratch("e2e-sim-plain");
    let (out, _) = common::sim_into(&dir, "paper-obstacles", &["-v"]);
    assert_eq!(out.status.code(), Some(0));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("INFO"), "{err}");
    assert!(!err.contains('\u{1b}'), "colour codes in a pipe: {err}");
    let (out, report) = common::sim_into(&dir, "plaza-crowd", &[]);
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(r["goal_reached"].as_bool(), Some(true), "{r}");
    assert_eq!(r["movers"]["contacts_moving"].as_u64(), Some(0), "{r}");
    assert_eq!(out.status.code(), Some(0));
}

/// Ctrl-C on `sim --realtime`: the report, the figure and a whole recording of the run so
/// far, written in place of the last run's only at the end (the old recording stays whole
/// while the run goes on); exit code 4 (stopped by the operator). Issue 30.
#[test]
fn an_interrupted_realtime_sim_writes_whole_files() {
    let dir = common::scratch("e2e-sim-interrupted");
    let (out, _) = common::sim_into(&dir, "paper-passage", &[]);
    assert_eq!(out.status.code(), Some(0));
    let recording = dir.join("run.mcap");
    let before = std::fs::read(&recording).unwrap();
    let sim = common::Killed(
        common::basestation()
            .args(["sim", "paper-passage", "--realtime", "--report"])
            .arg(dir.join("report.json"))
            .arg("--plot")
            .arg(dir.join("figure.svg"))
            .arg("--mcap")
            .arg(&recording)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    std::thread::sleep(std::time::Duration::from_secs(3));
    assert_eq!(
        std::fs::read(&recording).unwrap(),
        before,
        "the last run's recording is untouched while this one goes on"
    );
    let pid = sim.0.id().to_string();
    let kill = std::process::Command::new("kill")
        .args(["-INT", &pid])
        .status()
        .unwrap();
    assert!(kill.success());
    let mut sim = sim;
    let status = sim.0.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(sim.0.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(4), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    let t = r["sim_time_s"].as_f64().unwrap();
    assert!(
        (1.0..10.0).contains(&t),
        "{t} s simulated before the interrupt"
    );
    assert!(std::fs::read_to_string(dir.join("figure.svg"))
        .unwrap()
        .starts_with("<svg"));
    let bytes = std::fs::read(&recording).unwrap();
    let mut messages = 0;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        m.expect("a whole recording");
        messages += 1;
    }
    assert!(messages > 100, "{messages}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// Every way a run can end says why, in one line read the same in the summary, the
/// report and the figure's title (issue 53): the goal, the time up short of it with the
/// distance left, the leader lost, a fault that halted the fleet. Each figure pins what
/// happened (numbered, listed with its time) and explains its plots' marks.
#[test]
fn every_ending_says_why() {
    let dir = common::scratch("e2e-why");
    let passage = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/paper-passage.toml"
    ))
    .unwrap();
    let short = dir.join("short.toml");
    std::fs::write(&short, passage + "\n[sim]\nduration_s = 20.0\n").unwrap();
    let cases: [(&str, &str, Vec<&str>, &str); 4] = [
        ("goal", "paper-passage", vec![], "goal reached at "),
        ("time", short.to_str().unwrap(), vec![], "time up "),
        (
            "leader",
            "paper-passage",
            vec!["--fault", r#"{ at_s = 30, kind = "leader_dies" }"#],
            "the leader was lost at 30.",
        ),
        (
            "fault",
            "paper-passage",
            vec![
                "--fault",
                r#"{ at_s = 20, kind = "stuck_wheel", robot = 1 }"#,
            ],
            "robot 1 reported wheel stall left",
        ),
    ];
    for (name, scenario, args, expected) in cases {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        let (out, report) = common::sim_into(&sub, scenario, &args);
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let why = r["why"].as_str().unwrap().to_string();
        assert!(why.contains(expected), "{name}: {why}");
        let summary = String::from_utf8_lossy(&out.stdout);
        assert!(summary.lines().any(|l| l == why), "{name}: {summary}");
        let svg = std::fs::read_to_string(sub.join("figure.svg")).unwrap();
        assert!(svg.contains(&why), "{name}: the figure's title");
        assert!(svg.contains("a shape change under way") || name == "time");
        assert!(svg.contains("leader 0: v solid, ω dashed"), "{name}");
        if name == "time" {
            assert!(
                why.contains("m short of the goal (waypoint 1 of 1"),
                "{why}"
            );
            assert_eq!(r["ending"], "time_up");
        }
        if name == "goal" {
            // The paper's own scenario: its figures beside the paper's, its shape changes
            // pinned on the figure and listed with their times.
            assert!(summary.contains("paper (L / F1 / F2)"), "{summary}");
            assert!(svg.contains("into the line") && svg.contains("goal reached"));
        }
    }
    // Elsewhere the paper's columns are left out.
    let (out, _) = common::sim_into(&dir, "street-crossing", &[]);
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(!summary.contains("paper"), "{summary}");
}

/// A sweep: the report's coverage, the figure's swept ground, and the recording's coverage
/// layer filling in (a Foxglove grid every 30 s and at the end), in the layout's 3D panel.
#[test]
fn a_sweep_reports_draws_and_records_its_coverage() {
    let dir = common::scratch("sweep");
    let (out, report) = common::sim_into(&dir, "street-block-sweep", &[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report).unwrap()).unwrap();
    assert_eq!(r["schema_version"], 6);
    let c = &r["coverage"];
    let swept = c["swept_fraction"].as_f64().unwrap();
    assert!(swept > 0.5 && swept <= 1.0, "{c}");
    assert!(c["missed_patches"].as_u64().unwrap() >= c["missed"].as_array().unwrap().len() as u64);
    let svg = std::fs::read_to_string(dir.join("figure.svg")).unwrap();
    for label in ["swept twice or more", "missed"] {
        assert!(svg.contains(label), "the figure's legend lacks {label}");
    }
    let count = common::channels(&dir.join("run.mcap"));
    let (schema, _, n) = &count["/coverage"];
    assert_eq!(schema, "foxglove.Grid");
    let minutes = r["sim_time_s"].as_f64().unwrap() / 60.0;
    assert!(
        *n as f64 >= minutes,
        "{n} coverage snapshots over {minutes:.0} min"
    );
    let schemas: std::collections::BTreeMap<String, Vec<u8>> = count
        .iter()
        .map(|(t, (_, s, _))| (t.clone(), s.clone()))
        .collect();
    common::assert_layout_fits(&schemas, &["/movers", "/tracks", "/sensed"]);
}
