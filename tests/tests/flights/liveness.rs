//! A flight whose reasoner never decides within the deadline does not hover until its time
//! limit: every decision of the real planner here arrives after a 1 ms deadline (its cycle is
//! measured from the frame's capture, and perception alone takes longer), so the hub commits
//! none and reports no cycle. The flight fails after its first-decision heartbeats
//! (`aeris_flight::first_decision`), and says why: the decisions came late.

use aeris_tests::*;
use std::time::Duration;

/// Startup, 15 heartbeats of 1 s, the shutdown, with room for a loaded machine.
const FLIGHT_BOUND: Duration = Duration::from_secs(300);

#[test]
fn a_flight_whose_every_decision_is_late_fails_with_the_reason_instead_of_hovering() {
    let dir = TempDir::new("late-reasoner");
    let flight = unique_flight("late");
    let mut w = default_workflow();
    short_hop(&mut w);
    let timing = w["flight"].as_table_mut().unwrap();
    // 1 s heartbeats: the 15 without a decision take 15 s
    timing.insert("heartbeat_period_ms".into(), toml::Value::Integer(1000));
    timing.insert("decision_deadline_ms".into(), toml::Value::Integer(1));
    let path = write_workflow(&dir.0, "late", &w);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND);
    let (out, err) = run_output(&dir.0);
    assert!(
        status.is_some_and(|s| !s.success()),
        "the flight did not fail ({status:?}): {err}"
    );
    // `aeris run` prints the reason under the flight's result
    let reason = out
        .lines()
        .find(|l| l.trim_start().starts_with("reason:"))
        .unwrap_or_default();
    assert!(
        reason.contains("no decision was committed in 15 s of flight")
            && reason.contains("came after the 1 ms deadline")
            && reason.contains("does not decide within the heartbeat"),
        "{out}\n{err}\n{}",
        run_logs_tail(&dir.0, 10)
    );
    // the summary counts the late decisions (from the hub's heartbeats: it reported no cycle)
    let summary = last_json_line(&out);
    let late = summary["decisions_late"].as_u64().unwrap();
    assert!(late > 0, "{summary}");
    assert_eq!(
        summary["decisions_received"].as_u64(),
        Some(late),
        "{summary}"
    );
}
