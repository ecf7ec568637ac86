//! The hub role over real iceoryx2 services (two nodes in this process): decisions, states
//! and telemetry in; setpoints and reports out.

use aeris_hub::HubRole;
use aeris_hub::role::core_from_spec;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::spec::{CameraSpec, SubgoalSpec, TimingSpec};
use aeris_runtime::{
    CycleOutcome, CycleReport, FlightBus, MissionSpec, Role, RoleContext, RoleError, RoleSpec,
};
use aeris_schemas::{
    ActionMode, Decision, DecisionLimits, PerceptionState, VehicleTelemetry, topics,
};

fn spec(flight: &str) -> RoleSpec {
    let subgoal = |text: &str, action: &str, waypoint: [f32; 3]| SubgoalSpec {
        text: text.into(),
        action: action.into(),
        waypoint: Some(waypoint),
        reading: None,
    };
    RoleSpec {
        flight: flight.into(),
        name: "hub".into(),
        kind: aeris_schemas::RoleKind::Hub,
        variant: "gate".into(),
        cpus: String::new(),
        // a deadline of an hour: the test does not depend on how fast it runs
        timing: TimingSpec {
            heartbeat_period_ms: 3_600_000,
            decision_deadline_ms: 3_600_000,
            ..TimingSpec::default()
        },
        camera: CameraSpec::default(),
        mission: MissionSpec {
            instruction: "take off, fly to the red tower, then land".into(),
            subgoals: vec![
                subgoal("take off", "takeoff", [0.0, 0.0, 10.0]),
                subgoal("fly to the red tower", "goto", [40.0, 0.0, 10.0]),
                subgoal("land", "land", [40.0, 0.0, 0.0]),
            ],
            world: "village".into(),
            start: [0.0; 3],
            cruise_speed: 5.0,
            acceptance_radius_m: 2.0,
            max_duration_s: 60.0,
            limits: DecisionLimits::default(),
        },
        params: Default::default(),
        instance: 0,
        remote: None,
        heartbeat_pid: None,
        flight_clock_offset_ns: 0,
        clock: Default::default(),
        accelerator: None,
        vehicle: None,
    }
}

fn flight(tag: &str) -> String {
    format!("t-hub-{tag}-{}", std::process::id())
}

fn goto(seq: u64, start_ns: u64) -> Decision {
    Decision {
        seq,
        cycle: seq,
        cycle_start_ns: start_ns,
        state_stamp_ns: start_ns,
        reasoning_start_ns: start_ns,
        publish_ns: start_ns,
        target: [40.0, 0.0, 10.0],
        yaw: 0.0,
        speed: 5.0,
        altitude: 10.0,
        acceptance_radius: 2.0,
        confidence: 1.0,
        step: 2,
        action: ActionMode::Goto as u8,
        reserved: 0,
        source: 0,
    }
}

#[test]
fn decisions_in_setpoints_and_reports_out() {
    let f = flight("io");
    let bus = FlightBus::builder(&f).node_name("hub").create().unwrap();
    let mut ctx = RoleContext::new(spec(&f), bus).unwrap();
    let mut role = HubRole::new(&mut ctx).unwrap();
    assert_eq!(role.period().as_millis(), 20);

    let peer = FlightBus::builder(&f).node_name("peer").create().unwrap();
    let decisions = peer.publisher::<topics::ReasoningDecision>().unwrap();
    let states = peer.publisher::<topics::PerceptionState>().unwrap();
    let telemetry = peer.publisher::<topics::VehicleTelemetry>().unwrap();
    let setpoints = peer.subscriber::<topics::HubSetpoint>().unwrap();
    let reports = peer.subscriber::<topics::HubReport>().unwrap();

    // nothing in: nothing out
    let mut report = CycleReport::default();
    assert_eq!(
        role.cycle(&mut ctx, &mut report).unwrap(),
        CycleOutcome::Idle
    );
    assert_eq!(setpoints.next().unwrap(), None);

    telemetry
        .publish(&VehicleTelemetry {
            position: [0.0, 0.0, 10.0],
            ..VehicleTelemetry::default()
        })
        .unwrap();
    let mut s = PerceptionState::default();
    s.summary.set("a red tower ahead");
    // a present grid, nothing observed in it: the way is not blocked
    s.occupancy = aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0);
    states.publish(&s).unwrap();
    let first = goto(1, monotonic_ns());
    decisions.publish(&first).unwrap();
    assert_eq!(
        role.cycle(&mut ctx, &mut report).unwrap(),
        CycleOutcome::Worked
    );
    let sp = setpoints.latest().unwrap().expect("a setpoint");
    assert_eq!(
        sp.validate(&ctx.spec.mission.decision_limits()),
        Ok(ActionMode::Goto)
    );
    assert_eq!(
        (sp.decision_seq, sp.position, sp.reused),
        (1, [40.0, 0.0, 10.0], 0)
    );
    assert_eq!(sp.active_step, 2, "ATT saw the red tower");
    let r = reports.latest().unwrap().expect("a report");
    assert_eq!(
        (r.committed, r.reused, r.cycle, r.active_step),
        (1, 0, 1, 2)
    );
    assert_eq!(
        r.occupancy_status(),
        Some(aeris_schemas::OccupancyStatus::Present)
    );
    assert_eq!(r.validate(), Ok(()));

    // garbage: rejected, the last valid decision is reused
    let mut bad = goto(2, monotonic_ns());
    bad.altitude = f32::NAN;
    decisions.publish(&bad).unwrap();
    role.cycle(&mut ctx, &mut report).unwrap();
    let sp = setpoints.latest().unwrap().expect("a setpoint");
    assert_eq!(
        (sp.decision_seq, sp.position, sp.reused),
        (1, [40.0, 0.0, 10.0], 1)
    );
    let r = reports.latest().unwrap().expect("a reuse report");
    assert_eq!(
        (r.committed, r.reused, r.counts.decisions_rejected),
        (0, 1, 1)
    );
    // [received, rejected, late, reused, gaps, reorders, states, 0]
    assert_eq!(report.counters, [2, 1, 0, 1, 0, 0, 1, 0]);

    // a replayed decision is a reorder
    decisions.publish(&first).unwrap();
    role.cycle(&mut ctx, &mut report).unwrap();
    assert_eq!(report.counters, [3, 2, 0, 1, 0, 1, 1, 0]);
    // the setpoint keeps being published every tick
    assert!(setpoints.latest().unwrap().is_some());
    assert_eq!(role.core().counters().decisions_committed, 1);
}

#[test]
fn params_are_checked() {
    let f = flight("params");
    let mut s = spec(&f);
    assert!(core_from_spec(&s).is_ok());
    s.params.insert("no_att".into(), "yes".into());
    assert!(matches!(core_from_spec(&s), Err(RoleError::Config(_))));
    s.params.insert("no_att".into(), true.into());
    assert!(core_from_spec(&s).is_ok());
    s.params.insert("att_temperature".into(), (-1.0).into());
    assert!(matches!(core_from_spec(&s), Err(RoleError::Config(_))));
    s.params.insert("att_temperature".into(), 0.25.into());
    assert!(core_from_spec(&s).is_ok());
    s.mission.limits.obstacle_clearance_m = f32::NAN;
    assert!(matches!(core_from_spec(&s), Err(RoleError::Config(_))));
}
