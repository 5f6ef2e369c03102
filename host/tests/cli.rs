//! The operator's program as a user runs it: bad scenario files, decode on garbage.

mod common;

use std::io::Write;
use std::os::unix::fs::PermissionsExt;
use std::process::Stdio;

fn basestation(args: &[&str], stdin: Option<&[u8]>) -> (i32, String, String) {
    let mut child = common::basestation()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = child.stdin.take().unwrap();
    if let Some(bytes) = stdin {
        // A command that refuses its arguments exits without reading: a broken pipe.
        if let Err(e) = input.write_all(bytes) {
            assert_eq!(e.kind(), std::io::ErrorKind::BrokenPipe, "{e}");
        }
    }
    drop(input);
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

const GOOD: &str = include_str!("../../scenarios/paper-obstacles.toml");

fn check_text(name: &str, text: &str) -> (i32, String) {
    let (code, _, err) = check_file(name, text);
    (code, err)
}

/// `check` on `text` written to a file called `name`: exit code, stdout, stderr.
fn check_file(name: &str, text: &str) -> (i32, String, String) {
    let dir = std::env::temp_dir().join(format!("basestation-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    basestation(&["check", path.to_str().unwrap()], None)
}

#[test]
fn shipped_scenarios_check_clean() {
    for name in [
        "paper-obstacles",
        "paper-passage",
        "street-crossing",
        "plaza-crowd",
        "plaza-sweep",
        "street-block-sweep",
    ] {
        let (code, out, err) = basestation(&["check", name], None);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains("ok"));
    }
    // What moves in a scenario is listed: each mover, each crowd.
    let (_, out, _) = basestation(&["check", "street-crossing"], None);
    assert!(
        out.contains("mover 2     oblivious pedestrian, 1.1 m/s from 62.5 s"),
        "{out}"
    );
    let (_, out, _) = basestation(&["check", "plaza-crowd"], None);
    assert!(
        out.contains("crowd 0     social at 0.10 persons/m²"),
        "{out}"
    );
    // A sweep's plan, before anything moves.
    let (_, out, _) = basestation(&["check", "plaza-sweep"], None);
    assert!(
        out.contains("sweep       swath 2.00 m (3 robots' brushes of 0.70 m)"),
        "{out}"
    );
    assert!(out.contains("area 0      plaza: 1200 m²"), "{out}");
    assert!(out.contains("% of 1186 m² to sweep"), "{out}");
}

/// An area to sweep that is bad, or that nothing can reach, is refused with its line and
/// field.
#[test]
fn bad_areas_to_sweep_are_refused_with_their_field() {
    let area = |polygon: &str, more: &str| {
        GOOD.replacen(
            "[route]",
            &format!("[[sweep]]\npolygon = {polygon}\n{more}\n[route]"),
            1,
        )
    };
    let cases = [
        (
            "two.toml",
            area("[[0.0, 0.0], [5.0, 0.0]]", ""),
            "field `sweep[0].polygon`: give at least three points",
        ),
        (
            "bow.toml",
            area("[[0.0, 0.0], [5.0, 5.0], [5.0, 0.0], [0.0, 5.0]]", ""),
            "field `sweep[0].polygon`: the outline crosses itself",
        ),
        (
            "overlap.toml",
            area(
                "[[0.0, 0.0], [5.0, 0.0], [5.0, 5.0], [0.0, 5.0]]",
                "overlap = 5.0",
            ),
            "field `sweep[0].overlap`: must be under half the swath",
        ),
        (
            "walled.toml",
            area("[[3.9, 4.4], [5.1, 4.4], [5.1, 5.6], [3.9, 5.6]]", ""),
            "field `sweep[0].polygon`: no pass fits: the area has no room for the leader",
        ),
    ];
    for (name, text, expected) in cases {
        let (code, err) = check_text(name, &text);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(expected),
            "{name}:\n  got: {err}\n  expected: {expected}"
        );
    }
}

/// A shared radio: `check` says what one frame costs on its air and the station's
/// schedule, or that the radio cannot carry the fleet; a bad radio is refused with its
/// field.
#[test]
fn check_prints_the_channel_and_refuses_a_bad_radio() {
    let with = |link: &str| format!("{GOOD}\n[link]\n{link}\n");
    let (code, out, err) = check_file(
        "sik.toml",
        &with("radio = \"sik-64k\"\naccess = \"scheduled\""),
    );
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("channel     sik-64k"), "{out}");
    assert!(out.contains("each follower every 2 period(s)"), "{out}");
    let (_, out, _) = check_file(
        "lora.toml",
        &with("radio = \"lora-sf7-125\"\naccess = \"scheduled\""),
    );
    assert!(out.contains("this radio cannot carry the fleet"), "{out}");
    let cases = [
        (
            "wifi.toml",
            "radio = \"wifi\"",
            "field `link.radio`: unknown radio \"wifi\"",
        ),
        ("fec.toml", "fec = 2.0", "field `link.fec`: needs `radio`"),
        (
            "sf.toml",
            "radio = \"lora-sf7-125\"\nspreading_factor = 13",
            "field `link.spreading_factor`: must be 7 to 12",
        ),
    ];
    for (name, link, expected) in cases {
        let (code, err) = check_text(name, &with(link));
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(expected),
            "{name}:\n  got: {err}\n  expected: {expected}"
        );
    }
}

/// A shape the robots cannot hold (a slot on the leader) is refused, with its line.
#[test]
fn check_refuses_a_shape_whose_robots_would_touch() {
    let text = GOOD;
    let tight = text.replacen("distance = 3.0", "distance = 0.5", 1);
    assert_ne!(tight, text, "the shipped file's slot distance");
    let (code, err) = check_text("tight.toml", &tight);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("field `formation.distance`: slot 0 is 0.50 m from the leader"),
        "{err}"
    );
}

#[test]
fn bad_files_name_file_line_and_field() {
    let cases: &[(&str, String, &str)] = &[
        (
            "type.toml",
            GOOD.replacen("radius = 0.5", "radius = \"big\"", 1),
            "type.toml:9:54: field `map.obstacles[0].radius`: invalid type: string \"big\", expected f64",
        ),
        (
            "negative.toml",
            GOOD.replacen("radius = 0.5", "radius = -1.0", 1),
            "negative.toml:9:54: field `map.obstacles[0].radius`: must be a finite number > 0",
        ),
        (
            "path.toml",
            GOOD.replacen("name = \"", "name = \"../", 1),
            "field `name`: must be a plain file name",
        ),
        (
            "unknown.toml",
            GOOD.replace("k2 = 0.3", "k2 = 0.3\nkp = 3"),
            "field `follower.kp`: unknown field `kp`",
        ),
        (
            "role.toml",
            GOOD.replacen("role = \"follower\"", "role = \"folower\"", 1),
            "role.toml:23:8: field `robots[1].role`: unknown variant `folower`",
        ),
        (
            "two-leaders.toml",
            GOOD.replacen("role = \"follower\"", "role = \"leader\"", 1),
            "field `robots`: exactly one robot must have role = \"leader\", found 2",
        ),
        (
            "goal.toml",
            GOOD.replace("goal = [20.0, 20.0]", "goal = [4.5, 5.0]"),
            "goal.toml:38:8: field `route.goal`: the point is inside or too close to an obstacle",
        ),
        (
            "missing.toml",
            GOOD.replace("shape = \"triangle\"\n", ""),
            "field `formation`: missing field `shape`",
        ),
        ("syntax.toml", "name = \"x\"\n[map\n".to_string(), "syntax.toml:2:5: unclosed table"),
        (
            "nan.toml",
            GOOD.replace("k_a = 1.0", "k_a = nan"),
            "field `planner.k_a`: must be a finite number > 0",
        ),
        (
            "fast.toml",
            format!("{GOOD}\n[robot]\nmax_speed = 3.0\n"),
            "field `robot.max_speed`: 3: at most 2.047 (the leader-state frame's range)",
        ),
        (
            "mover-kind.toml",
            format!("{GOOD}\n[[movers]]\nkind = \"dog\"\npath = [[1.0, 1.0]]\nspeed = 1.0\n"),
            "field `movers[0].kind`: unknown variant `dog`",
        ),
        (
            "mover-pause.toml",
            format!("{GOOD}\n[[movers]]\nkind = \"pedestrian\"\npath = [[1.0, 1.0], [1.0, 9.0]]\nspeed = 1.0\npauses = [{{ at = 2, for_s = 20.0 }}]\n"),
            "field `movers[0].pauses[0].at`: point 2 of a 2-point path",
        ),
        (
            "mover-shape.toml",
            format!("{GOOD}\n[[movers]]\nkind = \"vehicle\"\nlength = 4.5\npath = [[1.0, 1.0]]\nspeed = 1.0\n"),
            "field `movers[0]`: a footprint is `radius` (a circle) or `length` and `width` (a rectangle)",
        ),
        (
            "crowd.toml",
            format!("{GOOD}\n[[crowds]]\narea = {{ min = [9.0, 0.0], max = [0.0, 9.0] }}\ndensity = 0.1\n"),
            "field `crowds[0].area`: `min` must lie below and left of `max`",
        ),
        (
            "passing.toml",
            format!("{GOOD}\n[yielding]\npassing_share = 1.5\n"),
            "passing.toml:50:17: field `yielding.passing_share`: must be at most 1 (the leader's full pace), got 1.5",
        ),
    ];
    for (name, text, expected) in cases {
        let (code, err) = check_text(name, text);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(
            err.contains(expected),
            "{name}:\n  got: {err}\n  expected: {expected}"
        );
    }
    let (code, _, err) = basestation(&["check", "no-such-file.toml"], None);
    assert_eq!(code, 1);
    assert!(err.contains("no-such-file.toml: no such file"));
}

/// A bad command line exits 2, as README.md's table says, the flags `sim` checks itself
/// included.
#[test]
fn a_bad_command_line_exits_2() {
    let (code, _, err) = basestation(&["sim", "--console"], None);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--console and --live need --realtime"),
        "{err}"
    );
    let (code, _, err) = basestation(&["sim", "--zenoh", "station.json5"], None);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--zenoh needs --realtime"), "{err}");
    let (code, _, _) = basestation(&["sim", "--no-such-flag"], None);
    assert_eq!(code, 2);
}

/// A bad bus configuration or name is refused before anything runs, the file named.
#[test]
fn a_bad_bus_configuration_is_refused_with_its_file() {
    let dir = common::scratch("cli-bus");
    let bad = dir.join("bad.json5");
    std::fs::write(&bad, "{ mode: \"client\", connect: { endpoints: [ }").unwrap();
    let path = bad.to_str().unwrap();
    let (code, _, err) = basestation(&["sim", "--realtime", "--zenoh", path], None);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("--zenoh") && err.contains("bad.json5"),
        "{err}"
    );
    let (code, _, err) = basestation(&["sim", "--realtime", "--zenoh", "nowhere.json5"], None);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("nowhere.json5: no such file"), "{err}");
    let good = dir.join("good.json5");
    std::fs::write(&good, "{ mode: \"client\" }").unwrap();
    let good = good.to_str().unwrap();
    let args = ["sim", "--realtime", "--zenoh", good, "--formation", "a/b"];
    let (code, _, err) = basestation(&args, None);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("formation name \"a/b\""), "{err}");
    let (code, _, err) = basestation(&["ops", "--zenoh", path], None);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("bad.json5"), "{err}");
}

#[test]
fn check_lists_every_problem_in_a_file() {
    let text = GOOD
        .replacen("radius = 0.5", "radius = -1.0", 1)
        .replace("k_a = 1.0", "k_a = nan");
    let (code, err) = check_text("two.toml", &text);
    assert_eq!(code, 1, "{err}");
    for expected in [
        "two.toml:9:54: field `map.obstacles[0].radius`: must be a finite number > 0",
        "field `planner.k_a`: must be a finite number > 0",
    ] {
        assert!(err.contains(expected), "got: {err}\nexpected: {expected}");
    }
}

#[test]
fn decode_prints_rejects_for_garbage_and_exits_cleanly() {
    let mut garbage: Vec<u8> = (0..5000u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    garbage.extend([0u8; 3]);
    let (code, out, err) = basestation(&["decode"], Some(&garbage));
    assert_eq!(code, 0, "{err}");
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(!lines.is_empty());
    assert!(lines
        .iter()
        .all(|l| l["ok"] == false && l["reject"].is_string()));
    assert!(err.contains("rejected"));
}

#[test]
fn decode_reads_genuine_frames_and_verifies_with_the_key() {
    use protocol::link::{Link, Timing};
    use protocol::messages::*;
    use protocol::{Address, MasterKey, MAX_WIRE};
    let hex = "11".repeat(32);
    let master = MasterKey::from_hex(&hex).unwrap();
    let mut base: Link<2> = Link::new(Address::Base, master.broadcast(), 7, 1, Timing::default());
    base.add_peer(Address::Robot(1), master.robot(1));
    let mut capture = Vec::new();
    let mut buf = [0u8; MAX_WIRE];
    let n = base.answer(Address::Robot(1), 99, 0, &mut buf).unwrap();
    capture.extend_from_slice(&buf[..n]);
    capture.extend_from_slice(b"\x05junk\x00");
    let state = Message::LeaderState(LeaderState {
        pose: WirePose::from_si(1.0, 2.0, 0.5).unwrap(),
        twist: WireTwist::new(400, 0),
        blend: 0,
    });
    let n = base
        .send(Address::Broadcast, 100, &state, &mut buf)
        .unwrap();
    capture.extend_from_slice(&buf[..n]);

    let (code, out, _) = basestation(&["decode", "-"], Some(&capture));
    assert_eq!(code, 0);
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0]["message"], "Welcome");
    assert_eq!(lines[0]["verified"], false);
    assert_eq!(lines[1]["ok"], false);
    assert_eq!(lines[2]["message"], "LeaderState");
    assert_eq!(lines[2]["fields"]["LeaderState"]["twist"]["v_mm_s"], 400);

    let dir = std::env::temp_dir().join(format!("basestation-key-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let key_file = dir.join("fleet.key");
    std::fs::write(&key_file, &hex).unwrap();
    // As ssh does: a key others can read is refused, saying how to fix it.
    let (code, _, err) = basestation(
        &["decode", "--key-file", key_file.to_str().unwrap()],
        Some(&capture),
    );
    assert_eq!(code, 1);
    assert!(
        err.contains("can be read by others") && err.contains("chmod 600"),
        "{err}"
    );
    std::fs::set_permissions(&key_file, std::fs::Permissions::from_mode(0o600)).unwrap();
    let (code, out, _) = basestation(
        &["decode", "--key-file", key_file.to_str().unwrap()],
        Some(&capture),
    );
    assert_eq!(code, 0);
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines[0]["verified"], true);
    assert_eq!(
        lines[2]["verified"], true,
        "session learnt from the Welcome"
    );

    std::fs::write(&key_file, "22".repeat(32)).unwrap();
    let (_, out, _) = basestation(
        &["decode", "--key-file", key_file.to_str().unwrap()],
        Some(&capture),
    );
    let first: serde_json::Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
    assert_eq!(first["reject"], "bad_tag");
}

#[test]
fn run_refuses_to_start_without_a_key() {
    let (code, _, err) = basestation(&["run", "paper-obstacles", "--udp", "127.0.0.1:9"], None);
    assert_eq!(code, 1);
    assert!(err.contains("no fleet key"), "{err}");
}

/// `run`'s transport and NMEA flags, as a new user meets them: without a transport both
/// ways are named (usage, exit 2); `--udp` takes a host name; `--nmea` for a robot the
/// site does not have is refused up front (exit 1). Issue 30.
#[test]
fn run_names_its_transports_takes_host_names_and_checks_nmea_ids() {
    let key = "SWEEPER_FLEET_KEY";
    let run = |args: &[&str]| {
        let out = common::basestation()
            .arg("run")
            .args(args)
            .env(key, "33".repeat(32))
            .env_remove("SWEEPER_KEY_FILE")
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    let (code, err) = run(&["paper-obstacles"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--port <PORT>|--udp <UDP>"), "{err}");
    let (code, err) = run(&[
        "paper-obstacles",
        "--udp",
        "localhost:9",
        "--bind",
        "127.0.0.1:0",
        "--duration",
        "1",
    ]);
    assert_eq!(code, Some(5), "a host name is an address: {err}");
    let (code, err) = run(&[
        "paper-obstacles",
        "--udp",
        "127.0.0.1:9",
        "--nmea",
        "7=udp:127.0.0.1:0",
    ]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("the site has no robot 7 (its robots: 0, 1, 2)"),
        "{err}"
    );
}

/// `robots` with no station: within seconds it says so, and where `run` should point.
#[test]
fn robots_without_a_station_say_so() {
    let out = common::basestation()
        .args([
            "robots",
            "paper-passage",
            "--udp",
            "127.0.0.1:0",
            "--duration",
            "6",
        ])
        .env("SWEEPER_FLEET_KEY", "33".repeat(32))
        .env_remove("SWEEPER_KEY_FILE")
        .arg("--report")
        .arg(std::env::temp_dir().join(format!("robots-alone-{}.json", std::process::id())))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("no station heard for 5 s: point `basestation run --udp`"),
        "{err}"
    );
    assert!(err.contains("udp 127.0.0.1:"), "{err}");
}

#[test]
fn run_over_udp_challenges_every_robot() {
    use protocol::{frame, FrameDecoder, Message};
    let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    sock.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let addr = sock.local_addr().unwrap().to_string();
    let dir = std::env::temp_dir().join(format!("basestation-run-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let recording = dir.join("run.mcap");
    let mut child = common::basestation()
        .args([
            "run",
            "paper-obstacles",
            "--udp",
            &addr,
            "--bind",
            "127.0.0.1:0",
            "--duration",
            "1",
            "--mcap",
            recording.to_str().unwrap(),
        ])
        .env("SWEEPER_FLEET_KEY", "33".repeat(32))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut dec = FrameDecoder::new();
    let mut hellos = std::collections::BTreeSet::new();
    let mut buf = [0u8; 2048];
    while hellos.len() < 3 {
        let n = sock
            .recv(&mut buf)
            .expect("datagrams from the base station");
        for &b in &buf[..n] {
            if let Some(Ok(raw)) = dec.push(b) {
                if let Ok((h, Message::Hello(_))) = frame::parse_unverified(raw) {
                    hellos.insert(format!("{:?}", h.to));
                }
            }
        }
    }
    // Nobody answered: exit code 5, and the run says so.
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert_eq!(status.code(), Some(5), "{err}");
    assert!(err.contains("no robot ever linked"), "{err}");
    assert_eq!(hellos.len(), 3);

    // The run's recording: `decode` finds the challenges to every robot in its radio
    // channel, sent by the base station, verified with the key.
    let recorded: std::collections::BTreeSet<String> = common::decode(&recording, &"33".repeat(32))
        .into_iter()
        .filter(|l| l["message"] == "Hello" && l["sender"] == "base" && l["verified"] == true)
        .map(|l| l["to"].to_string())
        .collect();
    assert_eq!(recorded.len(), 3, "{recorded:?}");

    // Each robot's link health, once a second: none linked (nobody answered).
    let bytes = std::fs::read(&recording).unwrap();
    let links: Vec<_> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .filter(|m| m.channel.topic.ends_with("/link"))
        .map(|m| m.channel.topic.clone())
        .collect();
    for id in 0..3 {
        assert!(
            links.contains(&format!("/robot_{id}/link")),
            "no link health of robot {id}: {links:?}"
        );
    }
}

#[test]
fn robot_config_writes_a_page_the_firmware_accepts() {
    let dir = std::env::temp_dir().join(format!("basestation-cfg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let page = dir.join("robot.cfg");
    let out = common::basestation()
        .args(["robot-config", "--id", "3", "--role", "leader", "-o"])
        .arg(&page)
        .env("SWEEPER_FLEET_KEY", "ab".repeat(32))
        .env_remove("SWEEPER_KEY_FILE")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&page).unwrap();
    let c = protocol::config_page::ConfigPage::decode(&bytes).expect("valid page");
    let master = protocol::MasterKey::from_bytes(&[0xab; 32]);
    assert_eq!((c.id, c.leader), (3, true));
    assert_eq!(c.broadcast_key, master.broadcast_bytes());
    assert_eq!(
        c.robot_key,
        master.robot_bytes(3),
        "its own key, not the master key"
    );
    let mode = std::fs::metadata(&page).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600, "the page holds the key");

    // Provisioning a replacement board: its boot counter continues above the old one's.
    let log = dir.join("robot.boot");
    let out = common::basestation()
        .args(["robot-config", "--id", "3", "--role", "leader", "-o"])
        .arg(&page)
        .arg("--boot-log")
        .arg(&log)
        .args(["--last-boot-count", "41"])
        .env("SWEEPER_FLEET_KEY", "ab".repeat(32))
        .env_remove("SWEEPER_KEY_FILE")
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(std::fs::read(&log).unwrap(), 41u32.to_le_bytes());

    // An oversized "key file" is refused before it is read.
    let big = dir.join("big.key");
    std::fs::write(&big, vec![b'a'; 4096]).unwrap();
    std::fs::set_permissions(&big, std::fs::Permissions::from_mode(0o600)).unwrap();
    let refused = |extra: &[&str]| {
        let mut args = vec![
            "robot-config",
            "--id",
            "3",
            "--role",
            "leader",
            "-o",
            "/dev/null",
        ];
        args.extend_from_slice(extra);
        let (code, _, err) = basestation(&args, None);
        assert_eq!(code, 1);
        err
    };
    let err = refused(&["--key-file", big.to_str().unwrap()]);
    assert!(err.contains("is not a key file"), "{err}");
    let err = refused(&[]);
    assert!(err.contains("no fleet key"), "{err}");
}

/// Every documentation link in `--help` (the program's and each command's) names a page
/// that exists and a heading (or `<a id>`) on it, as GitHub makes anchors; every command
/// the program has is in README's table. Issue 30.
#[test]
fn help_links_and_readme_agree_with_the_program() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let help = |args: &[&str]| {
        let out = common::basestation().args(args).output().unwrap();
        assert!(out.status.success(), "{args:?}");
        String::from_utf8(out.stdout).unwrap()
    };
    let top = help(&["--help"]);
    let commands: Vec<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    assert!(commands.len() >= 8, "{commands:?}");
    let readme = std::fs::read_to_string(format!("{root}/README.md")).unwrap();
    let mut texts = vec![top.clone()];
    for c in &commands {
        assert!(
            readme.contains(&format!("| `{c}")),
            "README's table lacks `{c}`"
        );
        texts.push(help(&[c, "--help"]));
    }
    let slug = |heading: &str| -> String {
        heading
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect()
    };
    let mut checked = 0;
    for text in &texts {
        for word in text.split(|c: char| c.is_whitespace() || "(),;".contains(c)) {
            let Some((page, anchor)) = word.split_once(".md#") else {
                continue;
            };
            let anchor = anchor.trim_end_matches(['.', ':', ')']);
            let page = format!("{root}/{page}.md");
            let doc =
                std::fs::read_to_string(&page).unwrap_or_else(|_| panic!("{page}: no such page"));
            let found = doc.lines().any(|l| {
                l.starts_with('#') && slug(l.trim_start_matches('#')) == anchor
                    || l.contains(&format!("id=\"{anchor}\""))
            });
            assert!(found, "{word}: no such anchor in {page}");
            checked += 1;
        }
    }
    assert!(checked >= 5, "{checked} links checked");
}

/// Rows wider than eight abreast are refused, naming the field.
#[test]
fn check_refuses_rows_too_wide() {
    let text = GOOD;
    let wide = text.replacen("shape = \"triangle\"", "shape = \"rows\"\nper_row = 9", 1);
    assert_ne!(wide, text, "the shipped file's shape");
    let (code, err) = check_text("wide.toml", &wide);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("field `formation.per_row`: must be 1 to 8 followers abreast"),
        "{err}"
    );
    let ok = text.replacen("shape = \"triangle\"", "shape = \"rows\"\nper_row = 2", 1);
    let (code, err) = check_text("rows.toml", &ok);
    assert_eq!(code, 0, "{err}");
}
