//! The independent-decoder test: the real controller process talks MAVLink to a pymavlink
//! peer that plays an autopilot, answers its commands and decodes everything the controller
//! sends: PX4 speaking MAVLink 2 at system 7 with a ground station on the same link, PX4
//! speaking only MAVLink 1 (pymavlink's default framing, which the controller once never
//! heard), ArduPilot Copter (guided, take-off command), and a PX4 that refuses to arm. The
//! test plays the hub, publishing valid and hostile bound setpoints over iceoryx2; none of
//! the hostile ones may reach the wire.

use aeris_runtime::FlightBus;
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::{ActionMode, AutopilotLinkStatus, BoundSetpoint, VehicleTelemetry, topics};
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

/// The autopilot's ids come from its HEARTBEAT (system 7 here), and a ground station on
/// the same link (its heartbeats, a denied ACK of its own) is ignored.
#[test]
fn controller_output_decodes_in_pymavlink_and_hostile_setpoints_never_reach_the_wire() {
    let (report, link) =
        fly_against_pymavlink_peer("mavpy-sys7", 2, &["--system-id", "7", "--gcs-noise"], true);
    assert_eq!(
        report["mavlink1"],
        json!(0),
        "everything is MAVLink 2: {report}"
    );
    assert_eq!(
        report["command_targets"],
        json!([[7, 1]]),
        "commands go to the autopilot its heartbeat named: {report}"
    );
    assert_eq!((link.system_id, link.component_id), (7, 1), "{link:?}");
    assert!(
        link.other_frames > 0 && link.foreign_heartbeats > 0,
        "{link:?}"
    );
    assert_eq!(
        link.commands_refused, 0,
        "the ground station's denied ACK is not the autopilot's: {link:?}"
    );
}

/// ArduPilot Copter: guided (custom mode 4), armed, then MAV_CMD_NAV_TAKEOFF to the
/// setpoint's height before its position targets are flown.
#[test]
fn an_ardupilot_copter_is_flown_in_guided_after_a_takeoff_command() {
    let (report, link) =
        fly_against_pymavlink_peer("mavpy-ardu", 2, &["--flavour", "ardupilot"], true);
    let takeoffs = report["takeoffs"].as_array().unwrap();
    assert!(!takeoffs.is_empty(), "no take-off command: {report}");
    for t in takeoffs {
        let h = num(t);
        assert!(
            (h - 10.0).abs() < 0.5,
            "take-off to the setpoint's 10 m: {h}"
        );
    }
    assert!(
        num(&report["max_up"]) > 2.0,
        "the copter never left the ground: {report}"
    );
    assert_eq!(
        link.autopilot,
        aeris_schemas::AutopilotKind::ArduPilot as u8
    );
}

/// MAVLink 2 signing on both ends (the key a passphrase, hashed the same way by both):
/// every frame the autopilot decodes was signed, none of its frames was refused, and it
/// flew.
#[test]
fn a_signed_link_flies_with_signed_frames_both_ways() {
    let dir = TempDir::new("mavpy-signed-key");
    let key = dir.0.join("key");
    std::fs::write(&key, "correct horse battery staple\n").unwrap();
    let key = key.to_str().unwrap();
    let (report, link) = fly_against_pymavlink_peer_with(
        "mavpy-signed",
        2,
        &["--signing-key-file", key],
        true,
        json!({ "signing_key_file": key }),
    );
    assert!(num(&report["signed_in"]) > 100.0, "{report}");
    assert_eq!(report["unsigned_in"], json!(0), "{report}");
    assert_eq!(link.signing, 1, "{link:?}");
    assert_eq!(
        (link.unsigned_refused, link.bad_signature_refused),
        (0, 0),
        "{link:?}"
    );
}

/// An autopilot that refuses to arm: the refusal is reported with its MAV_RESULT.
#[test]
fn a_refused_arm_is_reported_with_its_result() {
    let (report, link) = fly_against_pymavlink_peer(
        "mavpy-refuse",
        2,
        &["--refuse-arm", "--max-count", "200"],
        false,
    );
    assert!(
        report["arm_params"]
            .as_array()
            .is_some_and(|a| !a.is_empty()),
        "{report}"
    );
    assert!(link.commands_refused > 0, "{link:?}");
    assert_eq!(
        link.last_refusal.as_str(),
        Some("MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_DENIED"),
        "{link:?}"
    );
}

/// An autopilot that speaks only MAVLink 1: the controller hears it (it arms it and asks
/// for offboard, which it only does on the autopilot's heartbeat) and answers in MAVLink 1.
#[test]
fn a_mavlink_1_autopilot_is_heard_and_answered_in_mavlink_1() {
    let (report, _) = fly_against_pymavlink_peer("mavpy-v1", 1, &[], true);
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

/// Fly the controller process against the pymavlink peer speaking MAVLink `mavlink` (with
/// the peer's `extra` arguments), check everything every peer shares (and, when
/// `expect_flight`, that the vehicle flew the valid setpoints), and return the peer's
/// report and the controller's last `controller/link` status.
fn fly_against_pymavlink_peer(
    tag: &str,
    mavlink: u8,
    extra: &[&str],
    expect_flight: bool,
) -> (Value, AutopilotLinkStatus) {
    fly_against_pymavlink_peer_with(tag, mavlink, extra, expect_flight, json!({}))
}

/// [`fly_against_pymavlink_peer`] with `params` added to the controller's.
fn fly_against_pymavlink_peer_with(
    tag: &str,
    mavlink: u8,
    extra: &[&str],
    expect_flight: bool,
    params: Value,
) -> (Value, AutopilotLinkStatus) {
    let port = free_udp_port();
    let flight = unique_flight(tag);
    let dir = TempDir::new(tag);
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
            .args(extra)
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
    let mut spec = spec;
    for (k, v) in params.as_object().unwrap() {
        spec["params"][k] = v.clone();
    }
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
    let hub = bus.publisher::<topics::HubSetpoint>().unwrap();
    let telemetry = bus.subscriber::<topics::VehicleTelemetry>().unwrap();
    let link_status = bus.subscriber::<topics::ControllerLink>().unwrap();
    let mut last_link: Option<AutopilotLinkStatus> = None;

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
        link_status.drain(|l| last_link = Some(*l)).unwrap();
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
    let ardupilot = extra.contains(&"ardupilot");
    for mp in report["mode_params"].as_array().unwrap() {
        assert_eq!(mp[0].as_f64(), Some(1.0), "custom mode enabled: {mp}");
        if ardupilot {
            assert_eq!(mp[1].as_f64(), Some(4.0), "ArduPilot guided: {mp}");
        } else {
            assert_eq!(mp[1].as_f64(), Some(6.0), "PX4 offboard: {mp}");
        }
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
    if expect_flight {
        // The valid setpoints were flown: it climbed and headed north-east.
        assert!(max_up > 1.0, "never climbed: max up {max_up}");
        assert!(
            max_north >= 3.0,
            "never headed to the goto target: {max_north}"
        );
    }

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
    let link = last_link.expect("the controller never published its link status");
    (report, link)
}
