//! The model-backed roles as real processes: the perception pipeline (PP-OCRv4, YOLO, MiniLM,
//! depth occupancy, compose) flies the default mission end to end, and a role whose model
//! is missing or corrupt, or whose slot has no weights, stops with an error that says what
//! to do. Needs the provisioned model cache (`scripts/provision-models.sh`, part of the
//! test command).

use aeris_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);
const ROLE_BOUND: Duration = Duration::from_secs(120);

fn models_workflow() -> toml::Table {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/models.toml");
    std::fs::read_to_string(&path)
        .expect("workflows/models.toml")
        .parse()
        .expect("models workflow parses")
}

/// Start one role by hand and wait for it to stop; returns (success, stderr).
fn run_role(dir: &Path, spec: &aeris_runtime::RoleSpec) -> (bool, String) {
    let path = write_spec(dir, spec);
    let err_path = dir.join(format!("{}.stderr", spec.name));
    let err = std::fs::File::create(&err_path).unwrap();
    let mut cmd = Command::new(aeris_bin());
    cmd.args(["role", "--spec"])
        .arg(&path)
        .stdin(std::process::Stdio::null())
        .stderr(err);
    let mut child = ChildGuard::spawn(&mut cmd).expect("spawn role");
    let status = wait_bounded(&mut child.0, ROLE_BOUND).expect("the role stops by itself");
    (
        status.success(),
        std::fs::read_to_string(&err_path).unwrap_or_default(),
    )
}

#[test]
fn the_model_pipeline_flies_the_default_mission() {
    let dir = TempDir::new("models-flight");
    let flight = unique_flight("models");
    let mut w = models_workflow();
    // the deterministic planner decides: this test is about the perception processes.
    // The planner fires on its own 2 s clock, not on new states, so the newest S_t can be up
    // to one perception interval (2 s) plus the pipeline's latency (debug build) old: give
    // the deadline room for that instead of measuring the build's speed.
    set_variant(&mut w, "reasoning", "planner");
    w["flight"]
        .as_table_mut()
        .unwrap()
        .insert("decision_deadline_ms".into(), toml::Value::Integer(8000));
    let path = write_workflow(&dir.0, "models.toml", &w);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("the flight ends");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "flight failed: {stdout}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");
    assert_eq!(summary["role_restarts"], 0, "{summary}");
    assert_eq!(summary["decisions_rejected"], 0, "{summary}");
    // S_t reached the hub: ATT followed the instruction past its first step
    assert!(
        summary["max_active_step"].as_u64().unwrap_or(0) >= 2,
        "{summary}"
    );
    // perception is the composed pipeline, and it was measured
    assert!(
        summary["stages_mean_s"]["perception"]
            .as_f64()
            .unwrap_or(0.0)
            > 0.0,
        "{summary}"
    );
}

/// A model cache with the real manifest and ONNX Runtime, and `file` replaced by garbage.
fn corrupt_cache(dir: &Path, file: &str) -> PathBuf {
    let real = aeris_models::ModelStore::open(None).expect("provisioned model cache");
    let root = dir.join("cache");
    std::fs::create_dir_all(root.join(Path::new(file).parent().unwrap())).unwrap();
    std::fs::copy(
        real.root().join("MANIFEST.sha256"),
        root.join("MANIFEST.sha256"),
    )
    .unwrap();
    // the runtime itself is intact
    let ort = "onnxruntime/libonnxruntime.so";
    std::fs::create_dir_all(root.join("onnxruntime")).unwrap();
    std::fs::copy(real.root().join(ort), root.join(ort)).unwrap();
    std::fs::write(root.join(file), b"not a model").unwrap();
    root
}

#[test]
fn missing_corrupt_or_absent_models_stop_the_role_with_a_clear_error() {
    let dir = TempDir::new("model-errors");
    let flight = unique_flight("modelerr");
    let cache = corrupt_cache(&dir.0, "detect/yolov3-tiny.onnx");
    let cases: Vec<(aeris_runtime::RoleSpec, &[&str])> = vec![
        (
            role_spec(
                &flight,
                "missing",
                "detector",
                "yolo",
                serde_json::json!({ "model": "detect/nope.onnx" }),
            ),
            &["detect/nope.onnx", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "corrupt",
                "detector",
                "yolo",
                serde_json::json!({ "models_dir": cache.to_str().unwrap() }),
            ),
            &["yolov3-tiny.onnx", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "lm-corrupt",
                "reasoning",
                "smollm2",
                serde_json::json!({ "models_dir": cache.to_str().unwrap() }),
            ),
            &["smollm2", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "vlm",
                "image-to-text",
                "vlm",
                serde_json::json!({}),
            ),
            &["no captioning", "compose"],
        ),
        (
            role_spec(
                &flight,
                "learned",
                "occupancy",
                "onnx",
                serde_json::json!({}),
            ),
            &["no occupancy-model weights", "params.model"],
        ),
    ];
    for (spec, needles) in cases {
        let (ok, stderr) = run_role(&dir.0, &spec);
        assert!(!ok, "{} started without its model", spec.name);
        for n in needles {
            assert!(stderr.contains(n), "{}: {n:?} not in {stderr}", spec.name);
        }
        assert!(!stderr.contains("panicked"), "{}: {stderr}", spec.name);
    }
}
