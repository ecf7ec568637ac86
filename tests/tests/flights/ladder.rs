//! The role-adaptive model stack end to end. The default flight (on a short hop) starts its reasoner on
//! SmolLM2 (a real language model, from the provisioned cache) with the ladder
//! `["smollm2", "planner"]` and a 1 ms latency budget, which no language model meets. The
//! supervisor must step the reasoner down its ladder by itself: a make-before-break swap to
//! the planner, shown on the status board and counted in the run summary, after which the
//! flight reaches its goal on the lighter rung and never climbs back (SmolLM2's measured
//! latency stays far over the budget).

use aeris_runtime::bus::FlightBus;
use aeris_schemas::SupervisorStatus;
use aeris_tests::*;
use std::time::Duration;

fn reasoning(board: &SupervisorStatus) -> Option<(String, u32)> {
    board
        .roles()
        .iter()
        .find(|r| r.name.as_str() == Some("reasoning"))
        .and_then(|r| Some((r.variant.as_str()?.to_string(), r.pid)))
}

#[test]
fn a_reasoner_over_its_budget_steps_down_its_ladder_and_the_flight_completes() {
    let dir = TempDir::new("ladder");
    let flight = unique_flight("ladder");
    // the ladder is the subject, not the route: a short hop
    let mut w = default_workflow();
    short_hop(&mut w);
    let roles = w["roles"].as_array_mut().unwrap();
    let r = roles
        .iter_mut()
        .find(|r| r["name"].as_str() == Some("reasoning"))
        .unwrap()
        .as_table_mut()
        .unwrap();
    r.insert("variant".into(), "smollm2".into());
    r.insert(
        "variants".into(),
        toml::Value::Array(vec!["smollm2".into(), "planner".into()]),
    );
    r.insert(
        "ladder".into(),
        toml::Value::Array(vec!["smollm2".into(), "planner".into()]),
    );
    r.insert("budget_ms".into(), toml::Value::Float(1.0));
    let path = write_workflow(&dir.0, "ladder", &w);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();

    let (first, first_pid) = poll_until(Duration::from_secs(300), || {
        observer
            .read_status_board()
            .ok()
            .and_then(|b| reasoning(&b))
            .filter(|(_, pid)| *pid != 0)
    })
    .unwrap_or_else(|| panic!("the reasoner never came up: {:?}", run_output(&dir.0)));
    assert_eq!(first, "smollm2");
    // the ladder's step: a new process running the planner
    let (now, pid) = poll_until(Duration::from_secs(300), || {
        observer
            .read_status_board()
            .ok()
            .and_then(|b| reasoning(&b))
            .filter(|(v, _)| v == "planner")
    })
    .unwrap_or_else(|| {
        panic!(
            "the reasoner never stepped down: {}",
            run_logs_tail(&dir.0, 40)
        )
    });
    assert_eq!(now, "planner");
    assert_ne!(pid, first_pid, "a swap starts a new process");

    let status = wait_bounded(&mut run.0, Duration::from_secs(900)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert_eq!(
        summary["variant_steps"], 1,
        "one step down, none back up: {summary}"
    );
    assert_eq!(summary["swaps_done"], 1, "{summary}");
    assert!(
        stderr.contains("variant ladder steps down from `smollm2` to `planner`"),
        "{stderr}"
    );
    // the planner committed decisions after the step: the flight was flown, not held
    assert!(
        summary["cycles_committed"].as_u64().unwrap() > 0,
        "{summary}"
    );
}
