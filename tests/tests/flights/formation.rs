//! Formation flights end to end (`aeris formation fly`): four built-in vehicles, each its own
//! vehicle and controller process on its own MAVLink link, services in its own scope
//! (`FLIGHT/v1` .. `FLIGHT/v4`), flown by the formation role from [`INSTRUCTION`] (take off,
//! a line, a V, a circle of radius 6 m, land: the built-in instruction without its 10 s hold,
//! which the suite's time cannot spare) written by the deterministic parser. One flight flies
//! it whole, recorded (every vehicle's topics under its scope). The other flies a line and a
//! long hold, is given a circle instead during the hold (`aeris formation say`), and loses
//! vehicle 3's process in the change to the circle: the three that remain must re-form and
//! land.

/// What the first flight flies.
const INSTRUCTION: &str = "four drones take off to 5 m in a line 3 m apart, then form a V \
                           heading north, then a circle of radius 6 m, and land";

use aeris_runtime::bus::FlightBus;
use aeris_schemas::{FormationCounters, RoleHeartbeat, topics};
use aeris_tests::*;
use serde_json::Value;
use std::time::Duration;

/// The program's minimum separation (`FormationLimits::default`, the role's default).
const MIN_SEPARATION_M: f64 = 2.0;

/// The fleet part of the flight's summary, after checks every formation flight must pass:
/// exit status 0 (every linked vehicle landed), no collision, no setpoint refused, never
/// two vehicles closer than the program's minimum.
fn landed_fleet(dir: &std::path::Path, status: std::process::ExitStatus) -> Value {
    let (stdout, stderr) = run_output(dir);
    let logs = run_logs_tail(dir, 30);
    assert!(
        status.success(),
        "formation fly failed: {status}\n{stderr}\n{logs}"
    );
    let summary = last_json_line(&stdout);
    let fleet = summary["fleet"].clone();
    assert!(fleet["collision"].is_null(), "{fleet}");
    let closest = fleet["min_separation_m"]
        .as_f64()
        .expect("separation measured");
    assert!(
        closest >= MIN_SEPARATION_M,
        "closest {closest} m\n{fleet}\n{logs}"
    );
    for v in fleet["vehicles"].as_array().expect("vehicles") {
        assert_eq!(v["setpoints_refused"], 0, "{v}");
        assert!(v["controller_ticks"].as_u64().unwrap() > 0, "{v}");
    }
    eprintln!("{stderr}");
    fleet
}

/// Horizontal `[N, E]` of a vehicle's last position.
fn ground_position(v: &Value) -> [f64; 2] {
    let p = &v["final_position"];
    [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]
}

#[test]
fn four_vehicles_fly_line_v_circle_and_land_from_the_parsers_program() {
    let dir = TempDir::new("formation");
    let flight = unique_flight("formation");
    let recording = dir.0.join("formation.mcap");
    let mut run = spawn_formation_fly(
        &dir.0,
        &flight,
        &[INSTRUCTION, "--record", recording.to_str().unwrap()],
    );
    let status = wait_bounded(&mut run.0, Duration::from_secs(600)).expect("flight finished");
    let fleet = landed_fleet(&dir.0, status);
    // the executor moves to a phase only once every vehicle is within 0.5 m of its slot
    // at the end of the one before: reaching the fifth (landing) with no replan means every
    // vehicle reached every slot
    let formation = &fleet["formation"];
    assert_eq!(formation["phase"], 5, "{formation}");
    assert_eq!(formation["refused_slots"], 0, "{formation}");
    assert_eq!(formation["replans"], 0, "{formation}");
    assert_eq!(formation["in_formation"], 4, "{formation}");
    assert_ne!(formation["state"], "stuck", "{formation}");
    // ... and they landed on the circle: radius 6 m around the row's centre
    for v in fleet["vehicles"].as_array().unwrap() {
        assert_eq!(v["landed_after_flight"], true, "{v}");
        let [n, e] = ground_position(v);
        let r = n.hypot(e);
        assert!(
            (r - 6.0).abs() <= 0.5,
            "vehicle {} landed {r:.2} m out: {v}",
            v["vehicle"]
        );
    }
    // the recording, read by the independent MCAP reader: whole, and every vehicle's
    // telemetry and setpoints in it under its own scope (none unscoped: no such services)
    let read = crate::record::read_back(&recording);
    assert_eq!(read["complete"], true, "{read}");
    crate::record::assert_well_formed(&read, "the formation's recording");
    for k in 1..=4 {
        for topic in [topics::VEHICLE_TELEMETRY, topics::HUB_SETPOINT] {
            let scoped = topics::in_vehicle(k, topic);
            assert!(crate::record::count(&read, &scoped) > 0, "{scoped}: {read}");
        }
    }
    assert_eq!(
        crate::record::count(&read, topics::VEHICLE_TELEMETRY),
        0,
        "{read}"
    );
    assert!(crate::record::count(&read, topics::HEARTBEAT) > 0, "{read}");
    // a replay replays one vehicle's flight: refused, saying why, before anything starts
    let (status, _, stderr) = crate::record::replay_run(&dir.0, &flight, &recording, &[]);
    assert!(
        !status.success() && stderr.contains("is a flight of 4 vehicles"),
        "{status}: {stderr}"
    );
    // the formation role left the vehicles' tracks in the run folder, and they draw
    let run_dir = dir.0.join("run");
    let text = std::fs::read_to_string(run_dir.join("formation.json")).expect("tracks written");
    let tracks: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(tracks["vehicles"], 4);
    assert_eq!(
        tracks["phases"].as_array().map(Vec::len),
        Some(5),
        "{}",
        tracks["phases"]
    );
    let points = tracks["points"].as_array().unwrap();
    assert!(points.len() > 10, "{} track points", points.len());
    let png = dir.0.join("formation.png");
    let plotted = std::process::Command::new(aeris_bin())
        .args(["plot", "formation", "--run"])
        .arg(&run_dir)
        .arg("--out")
        .arg(&png)
        .output()
        .expect("run aeris plot formation");
    assert!(
        plotted.status.success() && png.exists(),
        "{}",
        String::from_utf8_lossy(&plotted.stderr)
    );
}

/// The formation role's phase (heartbeat counter 0), newest first seen in `heartbeats`.
fn formation_phase(heartbeats: &aeris_runtime::bus::TypedSubscriber<RoleHeartbeat>) -> Option<u64> {
    let mut phase = None;
    heartbeats
        .drain(|h| {
            if h.role.as_str() == Some("formation") {
                phase = Some(FormationCounters::from_heartbeat(&h.counters).phase);
            }
        })
        .unwrap();
    phase
}

#[test]
fn a_formation_reshaped_in_flight_then_a_vehicle_killed_reforms_and_lands() {
    let dir = TempDir::new("formation-say");
    let flight = unique_flight("formation-say");
    let mut run = spawn_formation_fly(
        &dir.0,
        &flight,
        &["four drones take off to 5 m in a line 3 m apart, then hold 40 s, and land"],
    );
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let heartbeats = observer.subscriber::<topics::Heartbeat>().unwrap();
    // in the hold (phase 3), a new instruction: a circle instead, without landing first
    poll_flight(
        &mut run,
        &dir.0,
        "the formation began its hold",
        Duration::from_secs(180),
        || formation_phase(&heartbeats).filter(|p| *p == 3),
    );
    let said = std::process::Command::new(aeris_bin())
        .args(["formation", "say", "--flight", &flight])
        .arg("form a circle of radius 6 m, hold 4 s, and land")
        .output()
        .expect("run aeris formation say");
    let answer = String::from_utf8_lossy(&said.stdout);
    assert!(
        said.status.success() && answer.contains("accepted") && answer.contains("circle"),
        "{answer}{}",
        String::from_utf8_lossy(&said.stderr)
    );
    // the new program's change to the circle (its phase 2, after a take-off in place):
    // vehicle 3 is lost in the middle of it
    poll_flight(
        &mut run,
        &dir.0,
        "the change to the circle began",
        Duration::from_secs(60),
        || formation_phase(&heartbeats).filter(|p| *p == 2),
    );
    let board = observer.read_status_board().unwrap();
    let victim = board
        .roles()
        .iter()
        .find(|r| r.name.as_str() == Some("vehicle-v3"))
        .map(|r| r.pid)
        .filter(|p| *p != 0)
        .expect("vehicle-v3 runs");
    // SAFETY: kill(2) with a pid the supervisor reports for a child it owns.
    assert_eq!(unsafe { libc::kill(victim as i32, libc::SIGKILL) }, 0);
    let status = wait_bounded(&mut run.0, Duration::from_secs(600)).expect("flight finished");
    let fleet = landed_fleet(&dir.0, status);
    let formation = &fleet["formation"];
    assert_eq!(formation["replans"], 1, "{formation}");
    assert_eq!(formation["in_formation"], 3, "{formation}");
    let vehicles = fleet["vehicles"].as_array().unwrap();
    assert_eq!(vehicles[2]["link_lost"], true, "{}", vehicles[2]);
    // the three that remain took up the circle again (an equilateral triangle inscribed in
    // radius 6 m: 6·√3 m apart) and landed
    let remaining: Vec<&Value> = vehicles.iter().filter(|v| v["vehicle"] != 3).collect();
    for v in &remaining {
        assert_eq!(v["landed_after_flight"], true, "{v}");
    }
    for (i, a) in remaining.iter().enumerate() {
        for b in &remaining[i + 1..] {
            let ([an, ae], [bn, be]) = (ground_position(a), ground_position(b));
            let d = (an - bn).hypot(ae - be);
            assert!(
                (d - 6.0 * 3f64.sqrt()).abs() <= 1.0,
                "vehicles {} and {} landed {d:.2} m apart\n{fleet}",
                a["vehicle"],
                b["vehicle"]
            );
        }
    }
}
