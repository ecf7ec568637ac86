//! The model-backed roles as real processes: a role whose model is missing or corrupt, whose
//! accelerator the ONNX Runtime cannot run, or whose slot has no weights, stops with an
//! error that says what to do (the whole model flight, with its swaps, is `hot_swap.rs`).
//! Needs the provisioned model cache (`scripts/provision-models.sh`, part of the test
//! command).

use aeris_tests::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const ROLE_BOUND: Duration = Duration::from_secs(120);

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
    // a detector told to run on CUDA, which the provisioned ONNX Runtime lacks
    let mut on_cuda = role_spec(
        &flight,
        "on-cuda",
        aeris_schemas::RoleKind::Detector,
        "yolo",
        serde_json::json!({}),
    );
    on_cuda.accelerator = Some("cuda:0".into());
    let cases: Vec<(aeris_runtime::RoleSpec, &[&str])> = vec![
        (
            on_cuda,
            &[
                "cuda:0",
                "CUDAExecutionProvider",
                "it offers: ",
                "CPUExecutionProvider",
            ],
        ),
        (
            role_spec(
                &flight,
                "missing",
                aeris_schemas::RoleKind::Detector,
                "yolo",
                serde_json::json!({ "model": "detect/nope.onnx" }),
            ),
            &["detect/nope.onnx", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "corrupt",
                aeris_schemas::RoleKind::Detector,
                "yolo",
                serde_json::json!({ "models_dir": cache.to_str().unwrap() }),
            ),
            &["yolov3-tiny.onnx", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "lm-corrupt",
                aeris_schemas::RoleKind::Reasoning,
                "smollm2",
                serde_json::json!({ "models_dir": cache.to_str().unwrap() }),
            ),
            &["smollm2", "provision-models.sh"],
        ),
        (
            role_spec(
                &flight,
                "vlm",
                aeris_schemas::RoleKind::ImageToText,
                "vlm",
                serde_json::json!({}),
            ),
            &["no captioning", "compose"],
        ),
        (
            role_spec(
                &flight,
                "learned",
                aeris_schemas::RoleKind::Occupancy,
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
