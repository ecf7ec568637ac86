//! The independent-decoder test: the real controller process talks MAVLink to a pymavlink
//! peer that plays a PX4 autopilot, answers its commands and decodes everything the
//! controller sends, once speaking MAVLink 2 and once only MAVLink 1 (pymavlink's default
//! framing, which the controller once never heard). The test plays the hub, publishing valid
//! and hostile bound setpoints over iceoryx2; none of the hostile ones may reach the wire.

use aeris_runtime::FlightBus;
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::{ActionMode, BoundSetpoint, VehicleTelemetry, topics};
use aeris_tests::{ChildGuard, TempDir, aeris_bin, python, unique_flight};
use serde_json::{Value, json};
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const BOUND: Duration = Duration::from_secs(150);
const SETPOINTS_TO_COLLECT: u64 = 150;

const V_MAX: f64 = 5.0;
const H_MIN: f64 = 0.0;
const H_MAX: f64 = 25.0;
const FENCE_MIN: [f64; 3] = [-50.0, -50.0, 0.0];
const FENCE_MAX: [f64; 3] = [50.0, 50.0, 25.0];

// MAVLink ids, written out so the expectations do not come from the code under test.
const MAV_CMD_COMPONENT_ARM_DISARM: u64 = 400;
const MAV_CMD_DO_SET_MODE: u64 = 176;
const MAV_TYPE_ONBOARD_CONTROLLER: u64 = 18;
const MAV_AUTOPILOT_INVALID: u64 = 8;
const MAV_FRAME_LOCAL_NED: u64 = 1;
const MAV_COMP_ID_ONBOARD_COMPUTER: u64 = 191;

fn free_udp_port() -> u16 {
    let s = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

fn setpoint(seq: u64, mode: ActionMode, position: [f32; 3], speed: f32) -> BoundSetpoint {
    BoundSetpoint {
        seq,
        decision_seq: seq,
        publish_ns: monotonic_ns(),
        position,
        yaw: 0.3,
        speed,
        acceptance_radius: 2.0,
        active_step: 1,
        mode: mode as u8,
        ..BoundSetpoint::default()
    }
}

fn num(v: &Value) -> f64 {
    v.as_f64()
        .unwrap_or_else(|| panic!("not a finite number on the wire: {v}"))
}

#[test]
fn controller_output_decodes_in_pymavlink_and_hostile_setpoints_never_reach_the_wire() {
    let report = fly_against_pymavlink_peer(2);
    assert_eq!(
        report["mavlink1"],
        json!(0),
        "everything is MAVLink 2: {report}"
    );
}

/// An autopilot that speaks only MAVLink 1: the controller hears it (it arms it and asks
/// for offboard, which it only does on the autopilot's heartbeat) and answers in MAVLink 1.
#[test]
fn a_mavlink_1_autopilot_is_heard_and_answered_in_mavlink_1() {
    let report = fly_against_pymavlink_peer(1);
    assert!(
        report["setpoints_v1"].as_u64().unwrap_or(0) > 0,
        "no setpoint in MAVLink 1: {report}"
    );
    assert_eq!(
        report["last_setpoint_v1"],
        json!(true),
        "the controller went back to MAVLink 2: {report}"
    );
}

/// Fly the controller process against the pymavlink peer speaking MAVLink `mavlink`, check
/// everything both framings share, and return the peer's report.
fn fly_against_pymavlink_peer(mavlink: u8) -> Value {
    let port = free_udp_port();
    let flight = unique_flight(&format!("mavpy{mavlink}"));
    let dir = TempDir::new(&format!("mavpy{mavlink}"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("py/mav_peer.py");

    let mut peer = ChildGuard::spawn(
        Command::new(python())
            .arg(&script)
            .args(["--listen", &format!("udpin:127.0.0.1:{port}")])
            .args(["--count", &SETPOINTS_TO_COLLECT.to_string()])
            .args(["--timeout", "120"])
            .args(["--until-north", "3.0"])
            .args(["--max-count", "3000"])
            .args(["--mavlink", &mavlink.to_string()])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit()),
    )
    .expect("start the pymavlink peer");
    // Read the peer's (large) JSON line concurrently so a full pipe never blocks it.
    let mut peer_stdout = peer.0.stdout.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut out = String::new();
        peer_stdout.read_to_string(&mut out).map(|_| out)
    });

    let spec = json!({
        "flight": flight,
        "name": "controller",
        "kind": "controller",
        "variant": "mavlink",
        "mission": {
            "instruction": "take off and fly to the mast",
            "subgoals": [
                {"text": "take off", "action": "takeoff", "waypoint": [0.0, 0.0, 10.0]},
                {"text": "fly to the mast", "action": "goto", "waypoint": [20.0, 10.0, 15.0]}
            ],
            "start": [0.0, 0.0, 0.0],
            "cruise_speed": 4.0,
            "limits": {
                "v_max": V_MAX, "h_min": H_MIN, "h_max": H_MAX, "r_max": 5.0,
                "geofence_min": FENCE_MIN, "geofence_max": FENCE_MAX
            }
        },
        "params": {"autopilot": format!("udpout:127.0.0.1:{port}")}
    });
    let spec_path = dir.0.join("controller.json");
    std::fs::write(&spec_path, serde_json::to_vec_pretty(&spec).unwrap()).unwrap();
    let mut controller = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&spec_path)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit()),
    )
    .expect("start the controller role");

    let bus = FlightBus::builder(&flight)
        .node_name("test-hub")
        .create()
        .unwrap();
    let hub = bus
        .publisher::<BoundSetpoint>(topics::HUB_SETPOINT)
        .unwrap();
    let telemetry = bus
        .subscriber::<VehicleTelemetry>(topics::VEHICLE_TELEMETRY)
        .unwrap();

    let start = Instant::now();
    let mut seq = 0;
    let mut last_tel: Option<VehicleTelemetry> = None;
    let mut link_seen = false;
    let mut hostile_sent = 0u64;
    loop {
        if let Some(status) = peer.0.try_wait().unwrap() {
            assert!(status.success(), "pymavlink peer failed: {status}");
            break;
        }
        assert!(
            start.elapsed() < BOUND,
            "the pymavlink peer did not finish; last telemetry {last_tel:?}"
        );
        if let Some(status) = controller.0.try_wait().unwrap() {
            panic!("the controller exited early: {status}");
        }
        // One valid setpoint, then hostile ones after it (the newest sample the controller
        // drains is usually hostile: it must keep flying the last valid one).
        // Take off until the peer's vehicle climbed (so it is armed and in offboard), then go.
        let climbed = last_tel.is_some_and(|t| t.position[2] > 2.0);
        let valid = if !climbed {
            setpoint(seq, ActionMode::Takeoff, [0.0, 0.0, 10.0], 2.0)
        } else {
            setpoint(seq, ActionMode::Goto, [20.0, 10.0, 15.0], 4.0)
        };
        seq += 1;
        hub.publish(&valid).unwrap();
        let hostile = [
            setpoint(seq, ActionMode::Goto, [f32::NAN, 10.0, 15.0], 4.0),
            setpoint(seq + 1, ActionMode::Goto, [400.0, -300.0, 15.0], 4.0),
            setpoint(seq + 2, ActionMode::Goto, [20.0, 10.0, 15.0], 45.0),
            setpoint(seq + 3, ActionMode::Goto, [20.0, 10.0, 80.0], 4.0),
            setpoint(seq + 4, ActionMode::Land, [f32::INFINITY, 0.0, 0.0], 1.0),
        ];
        seq += hostile.len() as u64;
        for h in &hostile {
            hub.publish(h).unwrap();
            hostile_sent += 1;
        }
        telemetry
            .drain(|t| {
                link_seen |= t.link_up == 1;
                last_tel = Some(*t);
            })
            .unwrap();
        std::thread::sleep(Duration::from_millis(20)); // pacing of the fake hub
    }

    let out = reader.join().unwrap().unwrap();
    let report: Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("peer output is not one JSON line ({e}): {out}"));
    assert_eq!(report["timed_out"], json!(false), "{report}");
    assert_eq!(report["bad_data"], json!(0), "{report}");

    // Identity: every message from system 1, component 191.
    assert_eq!(
        report["sources"],
        json!([[1, MAV_COMP_ID_ONBOARD_COMPUTER]]),
        "{report}"
    );
    // HEARTBEAT decoded, onboard controller, no autopilot.
    assert!(
        report["counts"]["HEARTBEAT"].as_u64().unwrap_or(0) >= 1,
        "{report}"
    );
    for hb in report["heartbeats"].as_array().unwrap() {
        assert_eq!(hb[0].as_u64(), Some(MAV_TYPE_ONBOARD_CONTROLLER), "{hb}");
        assert_eq!(hb[1].as_u64(), Some(MAV_AUTOPILOT_INVALID), "{hb}");
    }
    // Arm and offboard were requested.
    let commands: Vec<u64> = report["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_u64)
        .collect();
    assert!(commands.contains(&MAV_CMD_COMPONENT_ARM_DISARM), "{report}");
    assert!(commands.contains(&MAV_CMD_DO_SET_MODE), "{report}");
    assert!(
        report["arm_params"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p.as_f64() == Some(1.0)),
        "only arm, never disarm: {report}"
    );
    for mp in report["mode_params"].as_array().unwrap() {
        assert_eq!(mp[0].as_f64(), Some(1.0), "custom mode enabled: {mp}");
        assert_eq!(mp[1].as_f64(), Some(6.0), "PX4 offboard: {mp}");
    }

    // Every setpoint: local NED, finite, inside the fence and the altitude band, speed
    // within v_max. So no hostile setpoint reached the wire.
    let sps = report["setpoints"].as_array().unwrap();
    assert!(sps.len() as u64 >= SETPOINTS_TO_COLLECT, "{}", sps.len());
    assert_eq!(
        report["counts"]["SET_POSITION_TARGET_LOCAL_NED"].as_u64(),
        Some(sps.len() as u64)
    );
    let mut max_north: f64 = 0.0;
    let mut max_up: f64 = 0.0;
    for s in sps {
        let [x, y, z, vx, vy, vz] = [0, 1, 2, 3, 4, 5].map(|i| num(&s[i]));
        assert_eq!(s[7].as_u64(), Some(MAV_FRAME_LOCAL_NED), "{s}");
        let mask = s[6].as_u64().unwrap();
        assert_eq!(mask & 0b111, 0, "position used: {s}");
        assert_eq!(mask & 0b111000, 0, "velocity used: {s}");
        let neu = [x, y, -z];
        for i in 0..3 {
            assert!(
                neu[i] >= FENCE_MIN[i] && neu[i] <= FENCE_MAX[i],
                "outside the geofence: {neu:?}"
            );
        }
        assert!(
            neu[2] >= H_MIN && neu[2] <= H_MAX,
            "outside the altitude band: {neu:?}"
        );
        let speed = (vx * vx + vy * vy + vz * vz).sqrt();
        assert!(
            speed <= V_MAX + 1e-4,
            "feed-forward {speed} above v_max: {s}"
        );
        max_north = max_north.max(neu[0]);
        max_up = max_up.max(neu[2]);
    }
    // The valid setpoints were flown: it climbed and headed north-east.
    assert!(max_up > 1.0, "never climbed: max up {max_up}");
    assert!(
        max_north >= 3.0,
        "never headed to the goto target: {max_north}"
    );

    // The controller's own account, over iceoryx2.
    assert!(link_seen, "telemetry never reported the link up");
    let t = last_tel.expect("no telemetry from the controller");
    assert!(
        t.setpoints_refused > 0 && t.setpoints_refused <= hostile_sent,
        "{t:?}"
    );
    assert!(t.controller_ticks > 0);
    assert!(t.validate().is_ok());

    // SIGTERM: the controller stops its receive thread and exits cleanly.
    // SAFETY: plain kill(2) on our own child's pid.
    unsafe { libc::kill(controller.pid() as libc::pid_t, libc::SIGTERM) };
    let stop = Instant::now();
    let status = loop {
        if let Some(s) = controller.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            stop.elapsed() < Duration::from_secs(30),
            "controller ignored SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "controller exit: {status}");
    report
}
