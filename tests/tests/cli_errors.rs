//! Bad input to the CLI gives clear errors and a non-zero exit, never a panic.

use aeris_tests::*;
use std::process::Command;

fn run(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(aeris_bin())
        .args(args)
        .output()
        .expect("run aeris");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn bad_workflows_are_refused_with_the_reason() {
    let dir = TempDir::new("cli-errors");
    type Edit = Box<dyn Fn(&mut toml::Table)>;
    let cases: Vec<(&str, Edit, &str)> = vec![
        (
            "unknown-variant",
            Box::new(|w| set_variant(w, "reasoning", "gpt-9")),
            "gpt-9",
        ),
        (
            "missing-hub",
            Box::new(|w| {
                let roles = w["roles"].as_array_mut().unwrap();
                roles.retain(|r| r["name"].as_str() != Some("hub"));
            }),
            "hub",
        ),
        (
            "bad-cpus",
            Box::new(|w| {
                w["executors"]["control"]["cpus"] = toml::Value::String("0-x".into());
            }),
            "0-x",
        ),
    ];
    for (name, edit, needle) in cases {
        let mut w = default_workflow();
        edit(&mut w);
        let path = write_workflow(&dir.0, name, &w);
        for cmd in ["validate", "run"] {
            let (code, stderr) = run(&[cmd, path.to_str().unwrap()]);
            assert_eq!(code, Some(1), "{cmd} {name}: {stderr}");
            assert!(
                stderr.contains("error") && stderr.contains(needle),
                "{cmd} {name}: {stderr}"
            );
            assert!(!stderr.contains("panicked"), "{stderr}");
        }
    }
    let (code, stderr) = run(&["run", "/nonexistent/flight.toml"]);
    assert_eq!(code, Some(1));
    assert!(stderr.contains("/nonexistent/flight.toml"), "{stderr}");
}

#[test]
fn inspecting_a_flight_that_does_not_exist_is_a_clear_error() {
    let (code, stderr) = run(&["status", "--flight", "no-such-flight-x"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("no-such-flight-x"), "{stderr}");
    let (code, stderr) = run(&[
        "topic",
        "echo",
        "no/such/topic",
        "--flight",
        "no-such-flight-y",
        "--seconds",
        "0.1",
    ]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("unknown topic"), "{stderr}");
}

#[test]
fn every_shipped_workflow_validates_and_its_json_is_the_same_check() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let validate = |json: bool| {
            let mut cmd = Command::new(aeris_bin());
            cmd.arg("validate").arg(&path);
            if json {
                cmd.arg("--json");
            }
            let out = cmd.output().expect("run aeris");
            let text = String::from_utf8_lossy(&out.stdout).into_owned();
            let err = String::from_utf8_lossy(&out.stderr).into_owned();
            assert!(out.status.success(), "{}: {text}{err}", path.display());
            text
        };
        let text = validate(false);
        let json: serde_json::Value = serde_json::from_str(&validate(true)).unwrap();
        let roles = json["roles"].as_array().expect("roles");
        assert!(
            text.contains(&format!("ok — {} roles", roles.len())),
            "{text}"
        );
        for r in roles {
            assert!(text.contains(r["name"].as_str().unwrap()), "{r} in {text}");
        }
        checked += 1;
    }
    // the default flight, the models', the FPV camera's and the formation's
    assert!(checked >= 4, "{checked} workflows in {}", dir.display());
}

#[test]
fn validate_lists_the_executor_registry_with_what_onnx_runtime_offers() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/models.toml");
    let out = Command::new(aeris_bin())
        .args(["validate", path.to_str().unwrap()])
        .output()
        .expect("run aeris");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    // the declared CPU-set executors, resolved
    let executors = stdout
        .split("executors:")
        .nth(1)
        .expect("an executors section");
    for name in ["control", "perception", "reasoning"] {
        assert!(
            executors
                .lines()
                .any(|l| l.trim_start().starts_with(name) && l.contains("declared")),
            "{name}: {stdout}"
        );
    }
    // the provisioned runtime was asked: its CPU provider is always compiled in
    let line = stdout
        .lines()
        .find(|l| l.starts_with("accelerators:"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        line.contains("ONNX Runtime providers:") && line.contains("CPU"),
        "{line}"
    );
}

/// The model flight with role `role` on an accelerator executor `accelerator`.
fn role_on(dir: &std::path::Path, name: &str, accelerator: &str, role: &str) -> String {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/models.toml"),
    )
    .unwrap();
    let mut w: toml::Table = text.parse().unwrap();
    add_gpu_executor(&mut w, accelerator);
    for r in w["roles"].as_array_mut().unwrap() {
        if r["name"].as_str() == Some(role) {
            r.as_table_mut()
                .unwrap()
                .insert("executor".into(), "gpu".into());
        }
    }
    write_workflow(dir, name, &w).display().to_string()
}

#[test]
fn an_accelerator_this_onnx_runtime_lacks_is_refused_before_any_role_starts() {
    let dir = TempDir::new("cli-accel");
    let cuda = role_on(&dir.0, "cuda.toml", "cuda:0", "text");
    // validate names the provider and what the runtime offers instead
    let (code, err) = run(&["validate", &cuda]);
    assert_eq!(code, Some(1), "{err}");
    for needle in [
        "[executors.gpu]",
        "CUDAExecutionProvider",
        "it offers: ",
        "CPUExecutionProvider",
    ] {
        assert!(err.contains(needle), "{needle:?} not in {err}");
    }
    // a flight of it stops before starting a role (no run folder with role logs)
    let run_dir = dir.0.join("run");
    let (code, run_err) = run(&["run", &cuda, "--run-dir", run_dir.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{run_err}");
    assert!(run_err.contains("CUDAExecutionProvider"), "{run_err}");
    assert!(
        !run_dir.join("logs").exists(),
        "roles were started: {run_err}"
    );
    // a role that runs no model cannot be bound to one at all
    let camera = role_on(&dir.0, "camera.toml", "cuda:0", "camera");
    let (code, err) = run(&["validate", &camera]);
    assert_eq!(code, Some(1));
    assert!(err.contains("only model roles can use one"), "{err}");
    // nor can an accelerator no ONNX Runtime provider drives
    let npu = role_on(&dir.0, "npu.toml", "npu:0", "text");
    let (code, err) = run(&["validate", &npu]);
    assert_eq!(code, Some(1));
    assert!(err.contains("unknown accelerator `npu:0`"), "{err}");
}

#[test]
fn a_language_model_on_an_accelerator_needs_cuda_and_a_build_that_offloads() {
    let dir = TempDir::new("cli-llm-accel");
    // the reasoning role alone on the accelerator: its pool and ladder hold only smollm2
    let on = |name: &str, accelerator: &str| {
        let path = role_on(&dir.0, name, accelerator, "reasoning");
        let mut w: toml::Table = std::fs::read_to_string(&path).unwrap().parse().unwrap();
        for r in w["roles"].as_array_mut().unwrap() {
            if r["name"].as_str() == Some("reasoning") {
                let r = r.as_table_mut().unwrap();
                r.remove("variants");
                r.remove("ladder");
            }
        }
        std::fs::write(&path, toml::to_string(&w).unwrap()).unwrap();
        path
    };
    // llama.cpp offloads to CUDA only: TensorRT is an ONNX Runtime provider
    let trt = on("llm-trt", "tensorrt:0");
    let (code, err) = run(&["validate", &trt]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("reasoning / smollm2") && err.contains("reasoning/smollm2 (cuda only)"),
        "{err}"
    );
    // on CUDA, a build without llama.cpp's GPU offload (the default, CI's) says how to get
    // one, before any role starts
    let cuda = on("llm-cuda", "cuda:0");
    let (code, err) = run(&["validate", &cuda]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("[executors.gpu]")
            && err.contains("has no GPU offload")
            && err.contains("--features cuda"),
        "{err}"
    );
    let run_dir = dir.0.join("run");
    let (code, run_err) = run(&["run", &cuda, "--run-dir", run_dir.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{run_err}");
    assert!(run_err.contains("has no GPU offload"), "{run_err}");
    assert!(
        !run_dir.join("logs").exists(),
        "roles were started: {run_err}"
    );
    // the role itself refuses too (a role started by hand, or moved there by `aeris migrate`)
    let (code, err) = run(&[
        "bench",
        "models",
        "--only",
        "smollm2",
        "--runs",
        "1",
        "--accelerator",
        "cuda:0",
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("smollm2: accelerator `cuda:0`: this build's llama.cpp has no GPU offload"),
        "{err}"
    );
}

#[test]
fn an_own_onnx_runtime_that_is_missing_or_too_old_is_refused_clearly() {
    let dir = TempDir::new("cli-own-ort");
    let cuda = role_on(&dir.0, "cuda.toml", "cuda:0", "text");
    let validate = |lib: &str| {
        let out = Command::new(aeris_bin())
            .args(["validate", &cuda])
            .env("AERIS_ONNXRUNTIME", lib)
            .output()
            .expect("run aeris");
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (code, err) = validate("/nonexistent/libonnxruntime.so");
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("AERIS_ONNXRUNTIME names: /nonexistent/libonnxruntime.so does not exist"),
        "{err}"
    );
    // a real ONNX Runtime one minor version too old for `ort` (scripts/setup-test-deps.sh)
    if std::env::consts::ARCH != "x86_64" {
        eprintln!("skipped the too-old runtime: its wheel is pinned for x86_64 only");
        return;
    }
    let old = std::env::var_os("AERIS_TEST_DOWNLOADS")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(std::env::var_os("HOME").unwrap())
                .join(".cache/aeris/test-downloads")
        })
        .join("libonnxruntime.so.1.21.1");
    assert!(
        old.is_file(),
        "{} is missing: run scripts/setup-test-deps.sh",
        old.display()
    );
    let (code, err) = validate(old.to_str().unwrap());
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("expected version >= '1.22") && err.contains("got '1.21.1'"),
        "{err}"
    );
}

/// A command that only prints, whose reader is gone (`aeris roles | head -1` once head
/// exits), ends as other Unix tools do, by SIGPIPE, not with a panic in println!.
#[test]
fn a_printing_command_whose_reader_is_gone_ends_without_a_panic() {
    use std::os::unix::process::ExitStatusExt;
    let (reader, writer) = std::io::pipe().expect("a pipe");
    // every write to the pipe fails: its only reader is closed before the command starts
    drop(reader);
    let out = Command::new(aeris_bin())
        .arg("roles")
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("run aeris roles");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        out.status.signal(),
        Some(libc::SIGPIPE),
        "{:?}: {stderr}",
        out.status
    );
}
