//! Flights on simulated time (`--clock sim`): every role takes its turns in lockstep, so
//! the default mission flown twice, once alone and once beside two busy threads, gives
//! byte-identical decisions and trajectories; a flight that cannot follow simulated time
//! (an external autopilot) is refused by name before anything starts.

use aeris_tests::*;
use std::process::Command;

/// `aeris run --clock sim --json` of the default mission in `dir`: its cycle trace and its
/// summary.
fn fly_on_simulated_time(dir: &std::path::Path, flight: &str) -> (String, serde_json::Value) {
    let out = Command::new(aeris_bin())
        .args([
            "run",
            "--clock",
            "sim",
            "--json",
            "--flight",
            flight,
            "--run-dir",
        ])
        .arg(dir.join("run"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "aeris run --clock sim failed: {}\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr),
        run_logs_tail(dir, 20)
    );
    let trace = std::fs::read_to_string(dir.join("run").join("cycles.jsonl")).expect("trace");
    (trace, last_json_line(&stdout))
}

#[test]
fn the_default_mission_on_simulated_time_flies_the_same_alone_and_beside_busy_threads() {
    let dir = TempDir::new("sim-time");
    let alone = dir.0.join("alone");
    let loaded = dir.0.join("loaded");
    for d in [&alone, &loaded] {
        std::fs::create_dir_all(d).unwrap();
    }
    let (trace_a, summary_a) = fly_on_simulated_time(&alone, &unique_flight("sim-alone"));
    let (trace_b, summary_b) = {
        let _load = OutsideLoad::start(2);
        fly_on_simulated_time(&loaded, &unique_flight("sim-loaded"))
    };
    assert_eq!(summary_a["reached_goal"], true, "{summary_a}");
    // every decision the hub committed, where the vehicle was and what it was sent, at
    // every cycle: the same bytes
    assert!(trace_a.lines().count() > 10, "{trace_a}");
    assert_eq!(trace_a, trace_b, "the two flights' cycle traces differ");
    for key in [
        "final_position",
        "duration_s",
        "cycles",
        "decisions_received",
        "decisions_committed",
        "states_received",
        "controller_ticks",
        "max_setpoint_gap_ms",
    ] {
        assert_eq!(
            summary_a[key], summary_b[key],
            "{key}: {summary_a} / {summary_b}"
        );
    }
    // simulated time never leaves the controller behind
    assert_eq!(summary_a["controller_missed_ticks"], 0, "{summary_a}");
    // work takes no simulated time: the hub's cycle time is 0, and what the work took on
    // this machine is measured apart (on the wall clock, so not compared between the runs)
    assert_eq!(summary_a["clock"], "sim", "{summary_a}");
    assert_eq!(summary_a["ct_mean_s"], 0.0, "{summary_a}");
    assert!(
        summary_a["ct_compute_mean_s"].as_f64().unwrap() > 0.0,
        "{summary_a}"
    );
    assert!(summary_a["eer_compute"].is_number(), "{summary_a}");
}

#[test]
fn an_external_autopilot_is_refused_on_simulated_time() {
    let port = free_udp_port();
    let url = format!("udpin:127.0.0.1:{port}");
    let out = Command::new(aeris_bin())
        .args(["run", "--clock", "sim", "--autopilot", &url])
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("cannot fly on simulated time") && stderr.contains(&url),
        "{stderr}"
    );
}
