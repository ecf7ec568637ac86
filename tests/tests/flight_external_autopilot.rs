//! `aeris run --autopilot URL` flies an autopilot that is not the built-in vehicle of the
//! flight: here a simulated vehicle started by hand in another namespace, reached only over
//! MAVLink/UDP. The flight's own vehicle role is not started.

use aeris_runtime::bus::FlightBus;
use aeris_tests::*;
use std::process::Command;
use std::time::Duration;

#[test]
fn run_flies_an_external_autopilot_over_mavlink() {
    let dir = TempDir::new("external");
    let port = free_udp_port();
    // The "external autopilot": a vehicle process in a flight of its own.
    let autopilot_flight = unique_flight("ext-autopilot");
    let spec = role_spec(
        &autopilot_flight,
        "px4",
        "vehicle",
        "sim-multirotor",
        serde_json::json!({ "listen": format!("udpin:127.0.0.1:{port}") }),
    );
    let spec_path = write_spec(&dir.0, &spec);
    let _autopilot = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&spec_path),
    )
    .unwrap();

    let flight = unique_flight("external");
    let url = format!("udpout:127.0.0.1:{port}");
    let mut run = spawn_run(&dir.0, &flight, &["--autopilot", &url]);

    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let board = poll_until(Duration::from_secs(120), || {
        observer
            .read_status_board()
            .ok()
            .filter(|b| b.role_count > 0 && b.roles().iter().all(|r| r.heartbeats > 0))
    })
    .unwrap_or_else(|| panic!("flight never came up: {:?}", run_output(&dir.0)));
    let names: Vec<&str> = board
        .roles()
        .iter()
        .map(|r| r.name.as_str_lossy())
        .collect();
    assert!(
        !names.contains(&"vehicle"),
        "the built-in vehicle must not start: {names:?}"
    );
    assert!(names.contains(&"controller"));

    let status = wait_bounded(&mut run.0, Duration::from_secs(900)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
}
