//! `aeris run --autopilot URL` flies an autopilot that is not the built-in vehicle of the
//! flight: here a simulated vehicle started by hand in another namespace, reached only over
//! MAVLink/UDP, with MAVLink 2 signing on both ends (one key file). The flight's own vehicle
//! role is not started. In flight the autopilot falls silent (its process stopped) for
//! longer than the link timeout: the loss and the return are events, the summary counts the
//! loss, and the flight goes on to its goal.

use aeris_runtime::bus::FlightBus;
use aeris_tests::*;
use std::process::Command;
use std::time::Duration;

#[test]
fn run_flies_an_external_autopilot_over_mavlink() {
    let dir = TempDir::new("external");
    let port = free_udp_port();
    let key_path = dir.0.join("signing.key");
    std::fs::write(
        &key_path,
        "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n",
    )
    .unwrap();
    let key = key_path.to_str().unwrap();
    let mut wf = default_workflow();
    short_hop(&mut wf);
    for role in wf["roles"].as_array_mut().unwrap() {
        let t = role.as_table_mut().unwrap();
        if t["kind"].as_str() == Some("controller") {
            t["params"]
                .as_table_mut()
                .unwrap()
                .insert("signing_key_file".into(), toml::Value::String(key.into()));
        }
    }
    let workflow = write_workflow(&dir.0, "signed", &wf);
    // The "external autopilot": a vehicle process in a flight of its own.
    let autopilot_flight = unique_flight("ext-autopilot");
    let spec = role_spec(
        &autopilot_flight,
        "px4",
        aeris_schemas::RoleKind::Vehicle,
        "sim-multirotor",
        serde_json::json!({
            "listen": format!("udpin:127.0.0.1:{port}"),
            "signing_key_file": key,
            "signing_link_id": 1,
        }),
    );
    let spec_path = write_spec(&dir.0, &spec);
    let autopilot = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&spec_path),
    )
    .unwrap();

    let flight = unique_flight("external");
    let url = format!("udpout:127.0.0.1:{port}");
    let mut run = spawn_run(
        &dir.0,
        &flight,
        &[workflow.to_str().unwrap(), "--autopilot", &url],
    );

    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let board = poll_flight(
        &mut run,
        &dir.0,
        "the flight came up",
        Duration::from_secs(120),
        || {
            observer
                .read_status_board()
                .ok()
                .filter(|b| b.role_count > 0 && b.roles().iter().all(|r| r.heartbeats > 0))
        },
    );
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

    // airborne: silence the autopilot until the flight reports the link lost, then resume it
    let telemetry = observer
        .subscriber::<aeris_schemas::topics::VehicleTelemetry>()
        .unwrap();
    poll_until(Duration::from_secs(300), || {
        telemetry
            .latest()
            .ok()
            .flatten()
            .filter(|t| t.position[2] > 3.0)
    })
    .unwrap_or_else(|| panic!("never took off: {:?}", run_output(&dir.0)));
    // SAFETY: plain kill(2) on our own child's pid.
    unsafe { libc::kill(autopilot.pid() as libc::pid_t, libc::SIGSTOP) };
    let lost = poll_until(Duration::from_secs(120), || {
        run_output(&dir.0)
            .1
            .contains("autopilot link lost")
            .then_some(())
    });
    // SAFETY: as above.
    unsafe { libc::kill(autopilot.pid() as libc::pid_t, libc::SIGCONT) };
    assert!(
        lost.is_some(),
        "no link-lost event: {:?}",
        run_output(&dir.0)
    );

    let status = wait_bounded(&mut run.0, Duration::from_secs(900)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert_eq!(summary["autopilot_link_losses"], 1, "{summary}\n{stderr}");
    assert!(stderr.contains("autopilot link back"), "{stderr}");
}
