//! A short hop (take off, 30 m, land) flown end to end with the built-in vehicle playing an
//! ArduPilot Copter at system 3 that speaks only MAVLink 1: the controller learns the firmware, the
//! ids and the framing from its heartbeat, flies it in guided after a take-off command, and
//! lands it in its land mode.

use aeris_tests::*;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

#[test]
fn a_short_hop_flies_an_ardupilot_copter_speaking_mavlink_1() {
    let dir = TempDir::new("ardupilot");
    let mut wf = default_workflow();
    short_hop(&mut wf);
    for role in wf["roles"].as_array_mut().unwrap() {
        let t = role.as_table_mut().unwrap();
        if t["kind"].as_str() == Some("vehicle") {
            let params = t["params"].as_table_mut().unwrap();
            params.insert("autopilot".into(), toml::Value::String("ardupilot".into()));
            params.insert("mavlink".into(), toml::Value::Integer(1));
            params.insert("system_id".into(), toml::Value::Integer(3));
        }
    }
    let path = write_workflow(&dir.0, "ardupilot", &wf);
    let flight = unique_flight("ardupilot");
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(
        status.success(),
        "aeris run failed: {status}\n{stdout}\n{stderr}\n{}",
        run_logs_tail(&dir.0, 20)
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");
    assert_eq!(
        summary["autopilot"], "ArduPilot (system 3, component 1, MAVLink 1 sent)",
        "{summary}"
    );
    assert_eq!(
        summary["autopilot_commands_refused"], 0,
        "{summary}\n{stderr}"
    );
    assert!(
        stderr.contains("flying ArduPilot at system 3 component 1 (MAVLink 1)"),
        "{stderr}"
    );
}
