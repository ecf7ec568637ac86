//! The re-binding policy and an accelerator executor on a machine without one. The default
//! flight gets a YOLO detector with a 1 ms budget, which no CPU meets, and an executor
//! `gpu` on `cuda:0` that no role starts on. With no measured plan that restores the budget,
//! the policy probes the accelerator (a make-before-break move there); this host's ONNX
//! Runtime has no CUDA provider, so the move is refused with the providers it offers, the
//! detector keeps running where it ran, and the policy does not try the accelerator again.

use aeris_tests::*;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

#[test]
fn a_model_role_over_budget_is_probed_on_the_accelerator_once_and_stays_when_it_cannot_run_there() {
    let dir = TempDir::new("accel-probe");
    let flight = unique_flight("accel-probe");
    // the policy's probe is the subject, not the route: a short hop
    let mut w = default_workflow();
    short_hop(&mut w);
    add_gpu_executor(&mut w, "cuda:0");
    let mut detector = toml::Table::new();
    detector.insert("name".into(), "detector".into());
    detector.insert("kind".into(), "detector".into());
    detector.insert("variant".into(), "yolo".into());
    detector.insert("executor".into(), "perception".into());
    detector.insert("budget_ms".into(), toml::Value::Float(1.0));
    w["roles"]
        .as_array_mut()
        .unwrap()
        .push(toml::Value::Table(detector));
    let path = write_workflow(&dir.0, "accel-probe", &w);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    // the probe, refused before a process started, naming the providers there are
    let refusals: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("role `detector` could not be moved: re-binding to gpu"))
        .collect();
    assert_eq!(refusals.len(), 1, "probed once, not again: {stderr}");
    for needle in ["CUDAExecutionProvider", "CPUExecutionProvider", "stays"] {
        assert!(
            refusals[0].contains(needle),
            "{needle:?} not in {}",
            refusals[0]
        );
    }
    assert!(
        !stderr.contains("moves `detector` to gpu"),
        "a move there was made: {stderr}"
    );
    // refused before a process started: no swap began, no role was restarted
    for counter in ["swaps_done", "swaps_failed", "role_restarts"] {
        assert_eq!(summary[counter], 0, "{counter}: {summary}");
    }
}
