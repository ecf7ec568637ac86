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
