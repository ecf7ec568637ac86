//! A short hop (take off, 30 m, land) flown through a real MAVLink router, as many real set-ups are:
//! MAVProxy (PyPI, non-interactive) has the built-in vehicle as its master and serves the
//! controller on an output; the router's own ground-station heartbeats share the link and
//! must not be taken for the autopilot.

use aeris_tests::*;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

fn mavproxy() -> PathBuf {
    let python = PathBuf::from(python());
    python.with_file_name("mavproxy.py")
}

#[test]
fn a_short_hop_reaches_its_goal_through_mavproxy() {
    let dir = TempDir::new("mavproxy");
    let vehicle_port = free_udp_port();
    let router_port = free_udp_port();
    // the vehicle, in a flight of its own: reached only through the router
    let autopilot_flight = unique_flight("mavproxy-vehicle");
    let spec = role_spec(
        &autopilot_flight,
        "px4",
        aeris_schemas::RoleKind::Vehicle,
        "sim-multirotor",
        serde_json::json!({ "listen": format!("udpin:127.0.0.1:{vehicle_port}") }),
    );
    let spec_path = write_spec(&dir.0, &spec);
    let _vehicle = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&spec_path),
    )
    .unwrap();
    let router_dir = dir.0.join("mavproxy");
    std::fs::create_dir_all(&router_dir).unwrap();
    let _router = ChildGuard::spawn(
        Command::new(python())
            .arg(mavproxy())
            .arg(format!("--master=udpout:127.0.0.1:{vehicle_port}"))
            .arg(format!("--out=udpin:127.0.0.1:{router_port}"))
            .args(["--daemon", "--non-interactive", "--default-modules="])
            .arg(format!("--state-basedir={}", router_dir.display()))
            .current_dir(&router_dir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit()),
    )
    .expect("start MAVProxy (scripts/setup-test-deps.sh installs it beside AERIS_PYTHON)");

    let flight = unique_flight("mavproxy");
    let url = format!("udpout:127.0.0.1:{router_port}");
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(
        &dir.0,
        &flight,
        &[hop.to_str().unwrap(), "--autopilot", &url],
    );
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(
        status.success(),
        "aeris run failed: {status}\n{stdout}\n{stderr}"
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");
    assert_eq!(
        summary["autopilot"], "PX4 (system 1, component 1, MAVLink 2 sent)",
        "{summary}"
    );
}
