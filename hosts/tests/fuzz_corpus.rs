//! The `spawn_admission` fuzz target's corpus (`fuzz/corpus/spawn_admission/`) and crash
//! inputs (`fuzz/regressions/spawn_admission/`) replayed on stable Rust with the target's
//! check (`aeris_hosts::testing::fuzz_check_spawn_on_disk`), and the seed requests built
//! here with this build's schema stamp, so the admitted path is exercised whatever schema
//! the checked-in seeds were written with.
//!
//! The seeds are written by the ignored test `write_seed_corpus`:
//! `cargo test -p aeris-hosts --test fuzz_corpus -- --ignored write_seed_corpus`.

use aeris_hosts::protocol::SchemaStamp;
use aeris_hosts::testing::{fuzz_check_spawn, fuzz_check_spawn_on_disk};
use serde_json::json;
use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

/// Every input of the target: its corpus and its crash regressions.
fn inputs() -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(fuzz_dir().join(dir).join("spawn_admission")) else {
            continue;
        };
        for e in entries.flatten() {
            if let Ok(bytes) = std::fs::read(e.path()) {
                out.push((e.path(), bytes));
            }
        }
    }
    out.sort();
    out
}

/// A spawn request for `spec` fields over a planner reasoner, stamped with this build.
fn request(fields: serde_json::Value) -> Vec<u8> {
    let mut spec = json!({
        "flight": "f1", "name": "reasoning", "kind": "reasoning", "variant": "planner",
        "mission": {"instruction": "take off, then land",
                    "subgoals": [{"text": "take off", "action": "takeoff"},
                                 {"text": "land", "action": "land"}]},
    });
    for (k, v) in fields.as_object().into_iter().flatten() {
        spec[k] = v.clone();
    }
    json!({"schema": SchemaStamp::current(), "spec": spec, "handle_pid": 4242})
        .to_string()
        .into_bytes()
}

/// The seeds: admitted requests (a planner, a language model with its threads, a bridge,
/// a detector on CPUs) and refused ones (traversal names, a camera pipeline, file
/// parameters, a bridge's own link).
fn seeds() -> Vec<(&'static str, Vec<u8>, bool)> {
    vec![
        ("planner", request(json!({})), true),
        (
            "smollm2-threads",
            request(json!({"variant": "smollm2", "params": {"threads": 2, "plan": false}})),
            true,
        ),
        (
            "bridge",
            request(
                json!({"name": "bridge-on-ground", "kind": "bridge", "variant": "zenoh",
                "params": {"import": ["perception/state"], "export": ["reasoning/decision"],
                           "peer": "the flight's host", "on_host": "ground"}}),
            ),
            true,
        ),
        (
            "detector-cpus",
            request(
                json!({"name": "detector", "kind": "detector", "variant": "yolo",
                "cpus": "0", "instance": 7, "params": {"interval_ms": 500}}),
            ),
            true,
        ),
        (
            "traversal-name",
            request(json!({"name": "../../../../tmp/x"})),
            false,
        ),
        (
            "traversal-flight",
            request(json!({"flight": "../run"})),
            false,
        ),
        (
            "camera-pipeline",
            request(
                json!({"name": "camera", "kind": "camera", "variant": "gstreamer",
                "params": {"pipeline": "videotestsrc ! filesink location=/etc/x"}}),
            ),
            false,
        ),
        (
            "model-file",
            request(json!({"variant": "smollm2", "params": {"model": "/etc/shadow"}})),
            false,
        ),
        (
            "bridge-connect",
            request(
                json!({"name": "bridge-on-ground", "kind": "bridge", "variant": "zenoh",
                "params": {"connect": "tcp/192.0.2.1:7447", "keys": "/tmp/k"}}),
            ),
            false,
        ),
    ]
}

fn private_run_dir() -> (tempfile::TempDir, PathBuf) {
    let t = tempfile::tempdir().expect("a temp dir");
    let dir = aeris_hosts::private_dir::ensure_private_dir(&t.path().join("run"))
        .expect("a private run directory");
    (t, dir)
}

#[test]
fn the_seeds_are_admitted_or_refused_as_named_and_written_under_the_run_directory() {
    let (_t, run_dir) = private_run_dir();
    for (name, bytes, admitted) in seeds() {
        assert_eq!(fuzz_check_spawn(&bytes).is_some(), admitted, "seed {name}");
        fuzz_check_spawn_on_disk(&bytes, &run_dir);
    }
}

#[test]
fn every_corpus_and_regression_input_passes_the_check() {
    let (_t, run_dir) = private_run_dir();
    let inputs = inputs();
    assert!(!inputs.is_empty(), "no corpus in {}", fuzz_dir().display());
    for (path, bytes) in inputs {
        let r = std::panic::catch_unwind(|| fuzz_check_spawn_on_disk(&bytes, &run_dir));
        assert!(r.is_ok(), "{}", path.display());
    }
}

#[test]
#[ignore = "writes the seed corpus into fuzz/corpus/spawn_admission"]
fn write_seed_corpus() {
    let dir = fuzz_dir().join("corpus").join("spawn_admission");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, bytes, _) in seeds() {
        std::fs::write(dir.join(format!("seed-{name}.json")), bytes).unwrap();
    }
}
