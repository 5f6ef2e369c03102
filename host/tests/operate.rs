//! `basestation run` against `basestation robots`, two real processes in real time over
//! real transports (UDP, a pseudo-terminal), with the fleet key from a file: the path an
//! operator takes with real robots. Each test runs for real-time seconds (the longest, the
//! paper's passage, ~75 s); they run side by side.

mod common;

use std::time::{Duration, Instant};

use common::fleet::*;

/// `run` drives `robots` over `transport` ("udp" or "pty") through the paper's passage:
/// the goal, no contact, and each follower's max tracking error after its join within
/// [`REAL_TIME_MARGIN_M`] of `sim`'s.
fn paper_passage_over(transport: &str) {
    let site = Site::new(transport);
    // Before the real-time processes start: a simulation beside them takes CPU they need.
    let sim = sim_report(&site, "paper-passage");
    let report = site.path("robots.json");
    let report_arg = report.to_str().unwrap();
    let mut args = vec!["robots", "paper-passage", "--report", report_arg];
    args.extend(match transport {
        "udp" => ["--udp", "127.0.0.1:0"].as_slice(),
        _ => ["--pty"].as_slice(),
    });
    let mut robots = Process::start(&site, &args);
    let at = robots.address();
    let transport_args: Vec<&str> = match transport {
        "udp" => vec!["--udp", &at, "--bind", "127.0.0.1:0"],
        _ => vec!["--port", &at],
    };
    let run_report = site.path("run.json");
    let recording = site.path("run.mcap");
    let mut args = vec![
        "run",
        "paper-passage",
        "--report",
        run_report.to_str().unwrap(),
        "--mcap",
        recording.to_str().unwrap(),
    ];
    args.extend(&transport_args);
    let run = Process::start(&site, &args);
    run.finish(Duration::from_secs(110));
    let err = robots.finish(Duration::from_secs(30));
    println!("{transport}: {}", err.trim());
    // The real run's recording has the scene a simulation's has: the shipped layout
    // shows it (issue 30).
    let channels = common::channels(&recording);
    for topic in [
        "/map",
        "/tf",
        "/robots",
        "/route",
        "/formation",
        "/robot_1/state",
    ] {
        assert!(channels.contains_key(topic), "{topic} not recorded");
    }
    assert!(channels["/tf"].2 > 100, "{:?}", channels["/tf"]);
    let schemas = channels
        .iter()
        .map(|(t, (_, data, _))| (t.clone(), data.clone()))
        .collect();
    common::assert_layout_fits(&schemas, &["/movers", "/tracks", "/sensed", "/coverage"]);

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    assert_eq!(json(&run_report)["goal_reached"], true);
    // One clock for both processes' reports: the robots started first, within seconds.
    let (robots_t0, run_t0) = (
        r["started_unix_ms"].as_u64().expect("robots' start"),
        json(&run_report)["started_unix_ms"]
            .as_u64()
            .expect("run's start"),
    );
    assert!(
        robots_t0 <= run_t0 && run_t0 - robots_t0 < 30_000,
        "{robots_t0} {run_t0}"
    );
    for ((id, real), (_, simulated)) in follower_errors(&r).into_iter().zip(follower_errors(&sim)) {
        println!("{transport}: follower {id}: max tracking error after join {real:.3} m (sim {simulated:.3} m)");
        assert!(
            real <= simulated + REAL_TIME_MARGIN_M,
            "follower {id}: {real:.3} m over {transport}, {simulated:.3} m in sim"
        );
    }
}

#[test]
fn run_drives_robots_over_udp_through_the_passage_as_sim_does() {
    paper_passage_over("udp");
}

#[test]
fn run_drives_robots_over_a_pty_through_the_passage_as_sim_does() {
    paper_passage_over("pty");
}

/// The leader's scans reach `run` as the scan feed (here from `robots --publish-scan`, on a
/// real site from whatever processes its lidar): the station senses the van the map does
/// not hold, plans round it, and the fleet reaches the goal without touching it.
#[test]
fn run_routes_round_an_unmapped_van_from_the_scan_feed() {
    let site = Site::new("scan");
    let scenario = site.path("van.toml");
    std::fs::write(&scenario, VAN_ON_THE_WAY).unwrap();
    let scenario = scenario.to_str().unwrap();
    let feed = format!("127.0.0.1:{}", free_udp_port());
    let report = site.path("robots.json");
    let mut robots = Process::start(
        &site,
        &[
            "robots",
            scenario,
            "--udp",
            "127.0.0.1:0",
            "--publish-scan",
            &feed,
            "--report",
            report.to_str().unwrap(),
        ],
    );
    let at = robots.address();
    let run_report = site.path("run.json");
    let recording = site.path("run.mcap");
    run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--scan-feed",
            &feed,
            "--report",
            run_report.to_str().unwrap(),
            "--mcap",
            recording.to_str().unwrap(),
        ],
    )
    .finish(Duration::from_secs(110));
    robots.finish(Duration::from_secs(30));

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    let run = json(&run_report);
    println!(
        "scan feed: {}, sensed {}",
        run["scan_feed"], run["sensed_obstacles"]
    );
    assert!(
        run["scan_feed"]["scans"].as_u64().unwrap() > 50,
        "{}",
        run["scan_feed"]
    );
    assert_eq!(run["scan_feed"]["malformed"], 0);
    assert!(run["sensed_obstacles"].as_u64().unwrap() > 10);
    let replans = run["station_events"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["event"] == "replanned")
        .count();
    assert!(replans > 0, "never planned round the van");
    // The operator sees what the route keeps out of: the van's marks.
    let channels = common::channels(&recording);
    let (schema, _, sensed) = &channels["/sensed"];
    assert_eq!(schema, "foxglove.SceneUpdate");
    assert!(*sensed >= 1, "{sensed}");
}

/// The station is killed mid-way (no goodbye): robots stop on their own within the stop
/// bound; a new station relinks them and finishes the mission.
#[test]
fn a_killed_run_stops_the_fleet_and_a_restarted_run_finishes_the_mission() {
    let site = Site::new("restart");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let (mut robots, report, trace_csv) = robots_over_udp(&site, scenario, &[]);
    let at = robots.address();
    let started = Instant::now();
    let run = |name: &str| {
        let path = site.path(name);
        let args = [
            "run",
            scenario,
            "--udp",
            &at,
            "--bind",
            "127.0.0.1:0",
            "--report",
        ];
        (
            Process::start(&site, &[&args[..], &[path.to_str().unwrap()]].concat()),
            path,
        )
    };
    let (first, _) = run("run-1.json");
    std::thread::sleep(Duration::from_secs(12));
    // SIGKILL: the station leaves without a Stop.
    drop(first);
    let killed_at = started.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_secs(4));
    let (second, second_report) = run("run-2.json");
    second.finish(Duration::from_secs(90));
    robots.finish(Duration::from_secs(30));

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    // `started` is a little after the robots' clock began: measuring from it counts a
    // little driving from before the kill too.
    let bound = 1.2; // RobotConfig::stop_distance_bound(), docs/control.md
    for (id, path, v) in driven(&trace(&trace_csv), killed_at, killed_at + 3.5) {
        println!("robot {id}: {path:.2} m driven after the station died, then {v:.3} m/s");
        assert!(path <= bound, "robot {id} drove {path:.2} m");
        assert!(v.abs() < 0.02, "robot {id} still at {v:.3} m/s");
    }
    let second = json(&second_report);
    for id in 0..3 {
        assert!(
            events(&second)
                .iter()
                .any(|e| e.1 == "linked" && e.2 == Some(id)),
            "robot {id} not relinked: {second}"
        );
    }
    assert_eq!(second["goal_reached"], true);
}

/// Fixes from the line feed reach the robots as PoseFix frames; malformed lines are counted
/// and dropped, and so are lines without the source's seal; when the feed stops, the
/// robots drive on odometry, each is reported `localization_lost`, and the fleet stops
/// after `stop_after_s`.
#[test]
fn a_localization_feed_that_stops_is_reported_and_stops_the_fleet() {
    let site = Site::new("feed");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let feed = format!("127.0.0.1:{}", free_udp_port());
    let publish = format!("feed:{feed}");
    let (mut robots, report, trace_csv) = robots_over_udp(
        &site,
        scenario,
        &[
            "--publish-fixes",
            &publish,
            "--fixes-stop-at",
            "10",
            "--duration",
            "19",
        ],
    );
    let at = robots.address();
    let run_report = site.path("run.json");
    let run = run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--fix-feed",
            &feed,
            "--duration",
            "18",
            "--report",
            run_report.to_str().unwrap(),
        ],
    );
    // Garbage beside the good lines: counted, never forwarded, nothing breaks. Sealed by
    // the source, it is the source's malformed lines; unsealed, nobody's.
    std::thread::sleep(Duration::from_secs(3));
    let noise = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    for (k, bad) in ["garbage\n", "1,2,3\n", "\u{fffe}\n", "9,1e12,0,0,0,0.1\n"]
        .into_iter()
        .enumerate()
    {
        noise.send_to(bad.as_bytes(), &feed).unwrap();
        // The source's counter is its clock (µs since 1970): the same clock here.
        let sealed = seal("fixes", bad, unix_us() + k as u64);
        noise.send_to(sealed.as_bytes(), &feed).unwrap();
    }
    // The fleet stopped short of the goal: exit code 3.
    run.finish_with(Duration::from_secs(30), 3);
    robots.finish(Duration::from_secs(30));

    let r = json(&run_report);
    let counts = &r["localization"][format!("feed udp:{feed}")];
    println!("{counts}");
    assert!(counts["fixes"].as_u64().unwrap() > 150, "{counts}");
    assert_eq!(counts["unsealed"], 4, "{counts}");
    assert_eq!(counts["malformed"], 4, "{counts}");
    let events = events(&r);
    println!("{events:?}");
    let lost: Vec<_> = events
        .iter()
        .filter(|e| e.1 == "localization_lost")
        .collect();
    for id in 0..3 {
        assert!(
            lost.iter().any(|e| e.2 == Some(id)),
            "robot {id} not reported lost"
        );
    }
    let halted = events
        .iter()
        .find(|e| e.1 == "localization_lost:fleet_halted")
        .expect("the fleet was stopped");
    // The station's clock starts a little after the robots': its times are earlier.
    assert!(
        (13.5..15.0).contains(&(halted.0 + 0.5)),
        "halted at {} s",
        halted.0
    );
    assert_eq!(
        json(&report)["collisions"],
        0,
        "contacts on odometry or halting"
    );
    let trace = trace(&trace_csv);
    // On odometry between the feed's end (10 s) and the halt: the leader still drives.
    let leader_v = trace.iter().find(|s| s.1 == 0 && s.0 >= 12.0).unwrap().4;
    assert!(leader_v > 0.1, "leader at {leader_v} m/s on odometry");
    for (id, _, v) in driven(&trace, halted.0 + 0.5, 18.5) {
        assert!(v.abs() < 0.02, "robot {id} at {v:.3} m/s after the halt");
    }
}

/// Each robot's GNSS receiver speaks NMEA (GGA + HDT) over UDP to the station, which
/// forwards fixes over a pseudo-terminal radio: the fleet reaches the goal as in `sim`.
#[test]
fn nmea_fixes_over_a_pty_bring_the_fleet_through_the_passage() {
    let site = Site::new("nmea");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let sim = sim_report(&site, scenario);
    let ports: Vec<String> = (0..3)
        .map(|_| format!("127.0.0.1:{}", free_udp_port()))
        .collect();
    let report = site.path("robots.json");
    let mut args = vec![
        "robots",
        scenario,
        "--pty",
        "--report",
        report.to_str().unwrap(),
    ];
    let publish: Vec<String> = ports
        .iter()
        .enumerate()
        .map(|(id, p)| format!("nmea:{id}={p}"))
        .collect();
    for p in &publish {
        args.extend(["--publish-fixes", p]);
    }
    let mut robots = Process::start(&site, &args);
    let at = robots.address();
    let run_report = site.path("run.json");
    let sources: Vec<String> = ports
        .iter()
        .enumerate()
        .map(|(id, p)| format!("{id}=udp:{p}"))
        .collect();
    let mut args = vec![
        "run",
        scenario,
        "--port",
        &at,
        "--report",
        run_report.to_str().unwrap(),
    ];
    for s in &sources {
        args.extend(["--nmea", s]);
    }
    Process::start(&site, &args).finish(Duration::from_secs(90));
    robots.finish(Duration::from_secs(30));

    let r = json(&report);
    assert_eq!(r["goal_reached"], true, "{r}");
    assert_eq!(r["collisions"], 0);
    let run = json(&run_report);
    for id in 0..3 {
        let c = &run["localization"][format!("nmea robot {id}")];
        println!("robot {id}: {c}");
        assert!(c["fixes"].as_u64().unwrap() > 200, "{c}");
        for dropped in ["malformed", "no_heading", "no_solution", "out_of_time"] {
            assert_eq!(c[dropped], 0, "{dropped}: {c}");
        }
    }
    for ((id, real), (_, simulated)) in follower_errors(&r).into_iter().zip(follower_errors(&sim)) {
        println!(
            "nmea: follower {id}: max tracking error after join {real:.3} m (sim {simulated:.3} m)"
        );
        assert!(
            real <= simulated + FORWARDED_FIX_MARGIN_M,
            "follower {id}: {real:.3} m, sim {simulated:.3} m"
        );
    }
}

/// NMEA over TCP, as from a receiver's network port: the station connects to each
/// receiver (here the test, relaying the simulated receivers' sentences), reads lines,
/// and forwards fixes; a broken line on the stream is counted, not forwarded.
#[test]
fn nmea_over_tcp_is_read_and_forwarded() {
    use std::io::Write;
    use std::net::{TcpListener, UdpSocket};
    let site = Site::new("nmea-tcp");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let mut publish = Vec::new();
    let mut sources = Vec::new();
    for id in 0..3 {
        let udp = UdpSocket::bind("127.0.0.1:0").unwrap();
        let tcp = TcpListener::bind("127.0.0.1:0").unwrap();
        publish.push(format!("nmea:{id}={}", udp.local_addr().unwrap()));
        sources.push(format!("{id}=tcp:{}", tcp.local_addr().unwrap()));
        // The receiver's network port: what arrives by UDP goes out on the TCP stream.
        let broken = seal(
            &format!("nmea-{id}"),
            "$GPGGA,this is not a sentence*00\r\n",
            unix_us(),
        );
        std::thread::spawn(move || {
            let (mut stream, _) = tcp.accept().unwrap();
            stream.write_all(broken.as_bytes()).unwrap();
            let mut buf = [0u8; 2048];
            while let Ok(n) = udp.recv(&mut buf) {
                if stream.write_all(&buf[..n]).is_err() {
                    return;
                }
            }
        });
    }
    let mut args = vec!["--duration", "20"];
    for p in &publish {
        args.extend(["--publish-fixes", p]);
    }
    let (mut robots, report, _) = robots_over_udp(&site, scenario, &args);
    let at = robots.address();
    let run_report = site.path("run.json");
    let mut args = vec![
        "run",
        scenario,
        "--udp",
        &at,
        "--bind",
        "127.0.0.1:0",
        "--duration",
        "18",
    ];
    args.extend(["--report", run_report.to_str().unwrap()]);
    for s in &sources {
        args.extend(["--nmea", s]);
    }
    // A run of fixed duration, over before the goal: exit code 3.
    Process::start(&site, &args).finish_with(Duration::from_secs(40), 3);
    robots.finish(Duration::from_secs(30));

    let run = json(&run_report);
    for id in 0..3 {
        let c = &run["localization"][format!("nmea robot {id}")];
        println!("robot {id} over TCP: {c}");
        assert!(c["fixes"].as_u64().unwrap() > 100, "{c}");
        assert_eq!(c["malformed"], 1, "{c}");
    }
    assert!(
        events(&run).iter().all(|e| e.1 != "localization_lost"),
        "{run}"
    );
    assert_eq!(json(&report)["collisions"], 0);
}

/// A station whose fleet key differs from the robots': within seconds it names the robots
/// it does not hear and says that frames fail authentication, with what to check; it
/// exits 5 (never linked). Issue 30.
#[test]
fn a_station_with_another_key_says_so_and_exits_5() {
    use std::os::unix::fs::PermissionsExt;
    let site = Site::new("other-key");
    let other = site.path("other.key");
    std::fs::write(&other, format!("{}\n", "a7".repeat(32))).unwrap();
    std::fs::set_permissions(&other, std::fs::Permissions::from_mode(0o600)).unwrap();
    let mut robots = Process::start(
        &site,
        &[
            "robots",
            "paper-passage",
            "--udp",
            "127.0.0.1:0",
            "--duration",
            "12",
        ],
    );
    let at = robots.address();
    let run = Process::start_keyed(
        &other,
        &[
            "run",
            "paper-passage",
            "--udp",
            &at,
            "--bind",
            "127.0.0.1:0",
            "--duration",
            "7",
        ],
    );
    let err = run.finish_with(Duration::from_secs(30), 5);
    let robots_err = robots.finish(Duration::from_secs(30));
    assert!(
        robots_err.contains("frames rejected by the robots (bad_tag): frames fail authentication"),
        "robots did not say: {robots_err}"
    );
    for said in [
        "robot 0 not heard",
        "robot 2 not heard",
        "frames rejected (bad_tag): frames fail authentication",
        "share the fleet key",
        "no robot ever linked",
    ] {
        assert!(err.contains(said), "not said: {said}\n{err}");
    }
    // No colour codes in a pipe.
    assert!(!err.contains('\u{1b}'), "{err}");
}

/// Ctrl-C (SIGINT) on a linked `run`: the station stops the fleet, writes its report and
/// closes a whole recording, and exits 4 (stopped by the operator). Issue 30.
#[test]
fn an_interrupted_run_writes_its_report_and_recording_and_exits_4() {
    let site = Site::new("interrupted");
    let scenario = site.path("short-passage.toml");
    let scenario = scenario.to_str().unwrap();
    let (mut robots, _, _) = robots_over_udp(&site, scenario, &[]);
    let at = robots.address();
    let (report, recording) = (site.path("run.json"), site.path("run.mcap"));
    let run = run_over_udp(
        &site,
        scenario,
        &at,
        &[
            "--report",
            report.to_str().unwrap(),
            "--mcap",
            recording.to_str().unwrap(),
        ],
    );
    std::thread::sleep(Duration::from_secs(5));
    let kill = std::process::Command::new("kill")
        .args(["-INT", &run.0.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    run.finish_with(Duration::from_secs(20), 4);
    drop(robots);
    let r = json(&report);
    assert_eq!(r["goal_reached"], false);
    assert!(r["link"]["accepted"].as_u64().unwrap() > 50, "{r}");
    let channels = common::channels(&recording);
    assert!(channels["/tf"].2 > 20, "{:?}", channels.get("/tf"));
    assert!(!site.path("run.mcap.partial").exists());
}
