//! The main job end to end: `aeris run` flies the built-in default mission with every role
//! in its own process, while `aeris status` and `aeris topic` inspect it from outside and
//! two busy threads outside the flight share the machine (issue 21: the roles get priority
//! over them); no iceoryx2 resources of the flight remain afterwards.

use aeris_runtime::bus::{FlightBus, flight_node_census, list_flight_services};
use aeris_tests::*;
use std::collections::HashSet;
use std::process::Command;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

fn aeris(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(aeris_bin())
        .args(args)
        .output()
        .expect("run aeris");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn default_mission_reaches_the_goal_with_every_role_in_its_own_process() {
    let dir = TempDir::new("default");
    let flight = unique_flight("default");
    // a shared machine: two busy threads of this process, outside the flight, all along
    let load = OutsideLoad::start(2);
    let mut run = spawn_run(&dir.0, &flight, &[]);

    // While it flies: the status board lists every role with a live pid of its own.
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let board = poll_until(Duration::from_secs(120), || {
        let b = observer.read_status_board().ok()?;
        (b.role_count >= 6 && b.roles().iter().all(|r| r.pid != 0 && r.heartbeats > 0)).then_some(b)
    })
    .unwrap_or_else(|| panic!("roles never all reported: {:?}", run_output(&dir.0)));
    let pids: HashSet<u32> = board.roles().iter().map(|r| r.pid).collect();
    assert_eq!(
        pids.len(),
        board.roles().len(),
        "every role has its own process"
    );
    assert!(
        !pids.contains(&run.pid()),
        "no role runs inside the supervisor"
    );
    let names: HashSet<&str> = board
        .roles()
        .iter()
        .map(|r| r.name.as_str_lossy())
        .collect();
    for r in [
        "vehicle",
        "controller",
        "controller-standby",
        "camera",
        "perception",
        "hub",
        "reasoning",
    ] {
        assert!(names.contains(r), "{r} missing from {names:?}");
    }
    // where the flight has a CPU control group (named after the supervisor's pid), every
    // role and the supervisor are in it; the busy threads (this process) are not
    let group = format!("/aeris-{}-{flight}", run.pid());
    let cgroups = std::fs::read_to_string("/proc/self/cgroup").unwrap();
    assert!(!cgroups.contains(&group), "this process: {cgroups}");
    let in_group: Vec<bool> = pids
        .iter()
        .chain([&run.pid()])
        .map(|p| {
            std::fs::read_to_string(format!("/proc/{p}/cgroup"))
                .is_ok_and(|c| c.lines().any(|l| l.ends_with(&group)))
        })
        .collect();

    let (ok, out, err) = aeris(&["status", "--json", "--flight", &flight]);
    assert!(ok, "aeris status failed: {err}");
    let status = last_json_line(&out);
    let roles = status["roles"].as_array().expect("roles array");
    assert_eq!(roles.len(), board.roles().len());
    for r in roles {
        for key in [
            "name",
            "pid",
            "cpus",
            "variant",
            "latency_p50_ms",
            "latency_p95_ms",
            "restarts",
            "rss_mib",
        ] {
            assert!(!r[key].is_null(), "status role lacks {key}: {r}");
        }
    }
    assert!(
        status["memory"]["rss_total_mib"].as_f64().unwrap() > 0.0,
        "{status}"
    );

    let (ok, out, err) = aeris(&["topic", "list", "--flight", &flight]);
    assert!(ok, "topic list failed: {err}");
    for t in [
        "camera/rgb",
        "perception/state",
        "reasoning/decision",
        "hub/setpoint",
        "vehicle/telemetry",
    ] {
        assert!(out.contains(t), "topic list lacks {t}:\n{out}");
    }
    let (ok, out, err) = aeris(&[
        "topic",
        "echo",
        "vehicle/telemetry",
        "--flight",
        &flight,
        "-n",
        "1",
        "--seconds",
        "60",
    ]);
    assert!(
        ok && out.contains("VehicleTelemetry"),
        "echo failed: {out} {err}"
    );

    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    drop(load);
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    let priority = summary["priority"].as_str().unwrap();
    if priority.starts_with("cgroup") {
        assert!(in_group.iter().all(|&i| i), "{in_group:?} {summary}");
        // "cgroup v1 PATH cpu.shares N": the group is gone with the flight
        let detail = summary["priority_detail"].as_str().unwrap();
        let path = detail.split_whitespace().nth(2).unwrap();
        assert!(path.ends_with(&group), "{detail}");
        assert!(!std::path::Path::new(path).exists(), "{detail}");
    } else {
        assert!(in_group.iter().all(|&i| !i), "{in_group:?} {summary}");
    }
    // with CAP_SYS_NICE the roles always get priority (a nice value at least)
    let cap_sys_nice = std::fs::read_to_string("/proc/self/status")
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("CapEff:"))
        .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        .is_some_and(|caps| caps & (1 << 23) != 0);
    if cap_sys_nice {
        assert_ne!(priority, "none", "{summary}");
    }
    assert!(
        stderr.contains("roles' priority over outside work:"),
        "{stderr}"
    );
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert!(
        summary["final_distance_m"].as_f64().unwrap() <= 3.0,
        "{summary}"
    );
    for key in [
        "cycles",
        "ct_mean_s",
        "ct_p95_s",
        "eer",
        "decisions_rejected",
        "decisions_reused",
        "controller_ticks",
        "controller_missed_ticks",
        "role_restarts",
    ] {
        assert!(summary[key].is_number(), "summary lacks {key}: {summary}");
    }
    assert!(summary["controller_ticks"].as_u64().unwrap() > 0);
    // every role's memory, and the flight's at least the largest role's
    let memory = &summary["memory"];
    let roles = memory["roles"].as_array().unwrap();
    assert_eq!(roles.len(), board.roles().len(), "{memory}");
    let largest = roles
        .iter()
        .map(|r| r["rss_peak_mib"].as_f64().unwrap())
        .fold(0.0, f64::max);
    assert!(largest > 0.0, "{memory}");
    assert!(
        memory["total_rss_peak_mib"].as_f64().unwrap() >= largest,
        "{memory}"
    );
    assert!(summary["cycles"].as_u64().unwrap() > 0);
    assert_eq!(summary["role_restarts"], 0);
    assert_eq!(
        summary["max_active_step"], summary["subgoals_total"],
        "ATT reached the last step: {summary}"
    );

    drop(observer);
    aeris_runtime::bus::cleanup_dead_nodes();
    assert_eq!(
        flight_node_census(&flight),
        (0, 0),
        "no node of the flight remains"
    );
    assert!(
        list_flight_services(&flight).is_empty(),
        "{:?}",
        list_flight_services(&flight)
    );
}
