//! Closed loop in one process: the controller role and the vehicle role, driven through the
//! `Role` trait, talk MAVLink over UDP loopback; the test plays the hub (bound setpoints on
//! `hub/setpoint` over iceoryx2) and reads `vehicle/telemetry` back.
#![allow(
    clippy::disallowed_methods,
    reason = "a test drives roles and measures them on the wall clock"
)]

use aeris_roles::controller::ControllerRole;
use aeris_runtime::{CycleReport, FlightBus, Role, RoleContext, RoleSpec};
use aeris_schemas::{ActionMode, BoundSetpoint, ControllerCounters, VehicleTelemetry, topics};
use aeris_sim_roles::vehicle::VehicleRole;
use std::time::{Duration, Instant};

const BOUND: Duration = Duration::from_secs(120);

fn free_udp_port() -> u16 {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

fn spec(
    flight: &str,
    name: &str,
    kind: &str,
    variant: &str,
    params: serde_json::Value,
) -> RoleSpec {
    serde_json::from_value(serde_json::json!({
        "flight": flight,
        "name": name,
        "kind": kind,
        "variant": variant,
        "mission": {
            "instruction": "take off, fly to the tower, land",
            "subgoals": [
                {"text": "take off", "action": "takeoff", "waypoint": [0.0, 0.0, 8.0]},
                {"text": "fly to the tower", "action": "goto", "waypoint": [15.0, 10.0, 8.0]},
                {"text": "land", "action": "land", "waypoint": [15.0, 10.0, 0.0]}
            ],
            "start": [0.0, 0.0, 0.0],
            "limits": {
                "v_max": 5.0, "h_min": 2.0, "h_max": 20.0, "r_max": 5.0,
                "geofence_min": [-30.0, -30.0, 0.0], "geofence_max": [30.0, 30.0, 20.0]
            }
        },
        "params": params
    }))
    .unwrap()
}

struct Loop {
    vehicle: VehicleRole,
    vctx: RoleContext<aeris_schemas::kinds::Vehicle>,
    controller: ControllerRole,
    cctx: RoleContext<aeris_schemas::kinds::Controller>,
    report: CycleReport,
    publisher: aeris_runtime::bus::TypedPublisher<BoundSetpoint>,
    telemetry: aeris_runtime::bus::TypedSubscriber<VehicleTelemetry>,
    last: Option<VehicleTelemetry>,
    seq: u64,
}

impl Loop {
    fn publish(&mut self, mode: ActionMode, position: [f32; 3], speed: f32) {
        self.seq += 1;
        self.publisher
            .publish(&BoundSetpoint {
                seq: self.seq,
                decision_seq: 1,
                publish_ns: aeris_runtime::clock::monotonic_ns(),
                position,
                speed,
                acceptance_radius: 1.0,
                mode: mode as u8,
                ..BoundSetpoint::default()
            })
            .unwrap();
    }

    /// One 10 ms step of both roles (the controller runs every other step: 50 Hz).
    fn step(&mut self, i: u64) {
        self.vehicle
            .cycle(&mut self.vctx, &mut self.report)
            .unwrap();
        self.vctx.cycles += 1;
        if i.is_multiple_of(2) {
            self.report = CycleReport::default();
            self.controller
                .cycle(&mut self.cctx, &mut self.report)
                .unwrap();
            self.cctx.cycles += 1;
        }
        self.telemetry
            .drain(|t| {
                assert!(t.validate().is_ok());
                self.last = Some(*t);
            })
            .unwrap();
        std::thread::sleep(Duration::from_millis(10)); // pacing: the roles measure real time
    }

    /// Step (publishing `setpoint` when given) until `done` holds on the telemetry.
    fn run_until(
        &mut self,
        setpoint: Option<(ActionMode, [f32; 3], f32)>,
        what: &str,
        mut done: impl FnMut(&VehicleTelemetry) -> bool,
    ) {
        let start = Instant::now();
        let mut i = 0u64;
        loop {
            if let Some((mode, p, v)) = setpoint
                && i.is_multiple_of(2)
            {
                self.publish(mode, p, v);
            }
            self.step(i);
            i += 1;
            if self.last.as_ref().is_some_and(&mut done) {
                return;
            }
            assert!(
                start.elapsed() < BOUND,
                "timed out waiting for {what}: {:?} vehicle {:?}",
                self.last,
                self.vehicle.sim().status()
            );
        }
    }
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn controller_flies_the_simulated_vehicle_holds_and_lands() {
    let flight = format!("ctl-loop-{}", std::process::id());
    let port = free_udp_port();
    let vspec = spec(
        &flight,
        "vehicle",
        "vehicle",
        "sim-multirotor",
        serde_json::json!({"listen": format!("udpin:127.0.0.1:{port}")}),
    );
    let cspec = spec(
        &flight,
        "controller",
        "controller",
        "mavlink",
        serde_json::json!({"autopilot": format!("udpout:127.0.0.1:{port}"), "realtime": false}),
    );
    let mut vctx = RoleContext::new(
        vspec,
        FlightBus::builder(&flight)
            .node_name("vehicle")
            .create()
            .unwrap(),
    )
    .unwrap();
    let mut cctx = RoleContext::new(
        cspec,
        FlightBus::builder(&flight)
            .node_name("controller")
            .create()
            .unwrap(),
    )
    .unwrap();
    let hub = FlightBus::builder(&flight)
        .node_name("hub")
        .create()
        .unwrap();
    let vehicle = VehicleRole::new(&mut vctx).unwrap();
    let controller = ControllerRole::new(&mut cctx).unwrap();
    // the role polls the autopilot lease several times per 20 ms control period
    assert_eq!(
        controller.period() * aeris_roles::controller::POLLS_PER_TICK,
        Duration::from_millis(20)
    );
    let mut l = Loop {
        vehicle,
        vctx,
        controller,
        cctx,
        report: CycleReport::default(),
        publisher: hub.publisher::<topics::HubSetpoint>().unwrap(),
        telemetry: hub.subscriber::<topics::VehicleTelemetry>().unwrap(),
        last: None,
        seq: 0,
    };

    // Before any setpoint: link up, holding, not armed (nothing asked for flight).
    l.run_until(None, "link up", |t| t.link_up == 1 && t.hold_ticks > 50);
    let t = l.last.unwrap();
    assert_eq!((t.armed, t.offboard, t.landed), (0, 0, 1));
    assert_eq!(
        l.vehicle.sim().stats().commands,
        0,
        "no arm before a setpoint"
    );

    // Take off: the controller switches to offboard and arms by itself.
    l.run_until(
        Some((ActionMode::Takeoff, [0.0, 0.0, 8.0], 2.0)),
        "takeoff to 8 m",
        |t| t.armed == 1 && t.offboard == 1 && t.position[2] > 7.8,
    );
    let t = l.last.unwrap();
    assert!(
        t.position[0].abs() < 0.2 && t.position[1].abs() < 0.2,
        "{t:?}"
    );

    // Goto, with hostile setpoints mixed in that must be refused.
    let goal = [15.0, 10.0, 8.0];
    let mut k = 0;
    let mut peak_speed: f32 = 0.0;
    l.run_until(Some((ActionMode::Goto, goal, 4.0)), "goto", |t| {
        peak_speed = peak_speed.max(t.speed());
        dist(t.position, goal) < 0.3
    });
    for bad in [[f32::NAN, 0.0, 8.0], [500.0, 0.0, 8.0], [0.0, 0.0, 100.0]] {
        l.publish(ActionMode::Goto, bad, 4.0);
        k += 1;
    }
    l.publish(ActionMode::Goto, goal, 40.0); // speed above v_max
    k += 1;
    l.run_until(None, "refusals counted", |t| t.setpoints_refused >= k);
    assert!(peak_speed <= 4.0 * 1.1, "peak speed {peak_speed}");
    let counters = ControllerCounters::from_heartbeat(&l.report.counters);
    assert_eq!(
        counters.refused_setpoints,
        l.last.unwrap().setpoints_refused
    );
    assert!(counters.sent > 0, "setpoints sent: {counters:?}");

    // The hub goes quiet: the controller holds where the vehicle is.
    let holds = l.last.unwrap().hold_ticks;
    l.run_until(None, "holding", |t| t.hold_ticks > holds + 100);
    let t = l.last.unwrap();
    assert!(dist(t.position, goal) < 0.5, "{t:?}");
    assert_eq!(
        (t.armed, t.offboard),
        (1, 1),
        "the stream of hold setpoints keeps offboard"
    );

    // Land at the goal's north/east; the vehicle disarms after touchdown and the controller
    // does not re-arm while the land setpoint keeps coming.
    l.run_until(
        Some((ActionMode::Land, [15.0, 10.0, 0.0], 2.0)),
        "landing",
        |t| t.landed == 1 && t.armed == 0,
    );
    let commands = l.vehicle.sim().stats().commands;
    let landed_at = l.last.unwrap().position;
    assert!(dist(landed_at, [15.0, 10.0, 0.0]) < 0.5, "{landed_at:?}");
    let ticks = l.last.unwrap().controller_ticks;
    l.run_until(
        Some((ActionMode::Land, [15.0, 10.0, 0.0], 2.0)),
        "quiet after landing",
        |t| t.controller_ticks > ticks + 60,
    );
    assert_eq!(l.last.unwrap().armed, 0);
    assert_eq!(
        l.vehicle.sim().stats().commands,
        commands,
        "no re-arm after landing"
    );

    let Loop {
        mut vehicle,
        mut vctx,
        mut controller,
        mut cctx,
        ..
    } = l;
    controller.shutdown(&mut cctx);
    vehicle.shutdown(&mut vctx);
}
