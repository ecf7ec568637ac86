//! Fault tolerance end to end: SIGKILL each non-supervisor role in turn during one flight;
//! the supervisor restarts each, the flight still completes, and no iceoryx2 resources of
//! dead processes remain.

use aeris_runtime::bus::{FlightBus, flight_node_census, list_flight_services};
use aeris_tests::*;
use std::time::Duration;

#[test]
fn every_role_killed_in_turn_is_restarted_and_the_flight_completes() {
    let dir = TempDir::new("faults");
    let flight = unique_flight("faults");
    let mut run = spawn_run(&dir.0, &flight, &[]);
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let board_ok = |b: &aeris_schemas::SupervisorStatus| {
        b.role_count >= 6 && b.roles().iter().all(|r| r.pid != 0 && r.heartbeats > 0)
    };
    poll_flight(
        &mut run,
        &dir.0,
        "the flight came up",
        Duration::from_secs(120),
        || observer.read_status_board().ok().filter(board_ok),
    );

    for role in [
        "camera",
        "perception",
        "reasoning",
        "hub",
        "controller",
        "vehicle",
    ] {
        let before = observer.read_status_board().unwrap();
        let entry = *before
            .roles()
            .iter()
            .find(|r| r.name.as_str() == Some(role))
            .unwrap();
        // SAFETY: kill(2) with a pid the supervisor reports for a child it owns.
        assert_eq!(
            unsafe { libc::kill(entry.pid as i32, libc::SIGKILL) },
            0,
            "kill {role}"
        );
        // Restarted: a new pid, one more restart, and heartbeats from the new process.
        poll_until(Duration::from_secs(60), || {
            let b = observer.read_status_board().ok()?;
            let r = *b.roles().iter().find(|r| r.name.as_str() == Some(role))?;
            (r.pid != 0
                && r.pid != entry.pid
                && r.restarts == entry.restarts + 1
                && r.heartbeats > entry.heartbeats)
                .then_some(())
        })
        .unwrap_or_else(|| panic!("{role} was not restarted: {:?}", run_output(&dir.0)));
    }

    let status = wait_bounded(&mut run.0, Duration::from_secs(900)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert!(summary["role_restarts"].as_u64().unwrap() >= 6, "{summary}");

    drop(observer);
    aeris_runtime::bus::cleanup_dead_nodes();
    assert_eq!(
        flight_node_census(&flight),
        (0, 0),
        "dead processes left iceoryx2 nodes behind"
    );
    assert!(
        list_flight_services(&flight).is_empty(),
        "{:?}",
        list_flight_services(&flight)
    );
}
