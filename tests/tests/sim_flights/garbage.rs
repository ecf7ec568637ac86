//! A reasoner that publishes garbage (NaN, infinities, out-of-range fields, unknown actions,
//! stale cycles, replayed sequence numbers): the hub rejects it, and no setpoint outside the
//! flight's bounds ever reaches the autopilot's MAVLink input.
//!
//! The check is made where the MAVLink stream lands: the simulated vehicle decodes every
//! SET_POSITION_TARGET_LOCAL_NED and counts those outside the mission's geofence and altitude
//! band (heartbeat counters[1]); the pymavlink test checks the same stream independently.
//! Its subject is the gate, not timing: it flies on simulated time (`--clock sim`).

use aeris_runtime::bus::FlightBus;
use aeris_schemas::{PlannerCounters, VehicleCounters, topics};
use aeris_tests::*;
use std::time::Duration;

#[test]
fn garbage_decisions_never_reach_the_autopilot() {
    let dir = TempDir::new("garbage");
    let flight = unique_flight("garbage");
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let heartbeats = observer.subscriber::<topics::Heartbeat>().unwrap();
    let mut workflow = default_workflow();
    // the subject is the gate, not the mission: a short hop
    short_hop(&mut workflow);
    set_variant(&mut workflow, "reasoning", "garbage");
    let path = write_workflow(&dir.0, "garbage", &workflow);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap(), "--clock", "sim"]);

    let mut vehicle_counters = [0u64; 8];
    let mut garbage_counters = [0u64; 8];
    let finished = poll_until(Duration::from_secs(900), || {
        let _ = heartbeats.drain(|hb| match hb.role.as_str() {
            Some("vehicle") => vehicle_counters = hb.counters,
            Some("reasoning") => garbage_counters = hb.counters,
            _ => {}
        });
        run.0.try_wait().ok().flatten()
    })
    .expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(
        finished.success(),
        "aeris run failed: {finished}\n{stderr}\n{}",
        run_logs_tail(&dir.0, 20)
    );
    let summary = last_json_line(&stdout);

    assert!(
        PlannerCounters::from_heartbeat(&garbage_counters).corrupted > 0,
        "the garbage reasoner corrupted decisions: {garbage_counters:?}"
    );
    assert!(
        summary["decisions_rejected"].as_u64().unwrap() > 0,
        "{summary}"
    );
    assert!(
        VehicleCounters::from_heartbeat(&vehicle_counters).setpoints > 0,
        "the vehicle received setpoints: {vehicle_counters:?}"
    );
    assert_eq!(
        VehicleCounters::from_heartbeat(&vehicle_counters).outside_fence,
        0,
        "setpoints outside the bounds reached MAVLink: {vehicle_counters:?}"
    );
    assert_eq!(
        summary["reached_goal"], true,
        "valid decisions in between still fly the mission: {summary}"
    );
}
