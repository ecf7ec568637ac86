//! The benchmarks run end to end through the CLI and print their JSON on the last line
//! (figures are not asserted: speed belongs to the benchmark's output, not to tests).

use aeris_tests::*;
use std::process::Command;

fn bench(args: &[&str]) -> serde_json::Value {
    let out = Command::new(aeris_bin())
        .arg("bench")
        .args(args)
        .output()
        .expect("run aeris bench");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "bench {args:?} failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    last_json_line(&stdout)
}

#[test]
fn ipc_bench_measures_every_transport_and_wake_mode() {
    let report = bench(&[
        "ipc",
        "--iterations",
        "20",
        "--warmup",
        "5",
        "--payloads",
        "64,4096",
        "--json",
    ]);
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2 * 2 * 2, "{report}");
    for transport in ["iceoryx2", "uds"] {
        for wake in ["busy", "event"] {
            for bytes in [64, 4096] {
                let row = rows
                    .iter()
                    .find(|r| {
                        r["transport"] == transport
                            && r["wake"] == wake
                            && r["payload_bytes"] == bytes
                    })
                    .unwrap_or_else(|| panic!("no row {transport}/{wake}/{bytes}: {report}"));
                let (p50, p99, max) = (
                    row["p50_us"].as_f64().unwrap(),
                    row["p99_us"].as_f64().unwrap(),
                    row["max_us"].as_f64().unwrap(),
                );
                assert!(p50 > 0.0 && p50 <= p99 && p99 <= max, "{row}");
            }
        }
    }
}

#[test]
fn gate_and_control_benches_report_their_rows() {
    let gate = bench(&["gate", "--calls", "1000", "--json"]);
    let mixes: Vec<&str> = gate["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["mix"].as_str().unwrap())
        .collect();
    assert_eq!(mixes, ["valid", "occupancy", "invalid"]);
    let control = bench(&["control", "--seconds", "0.2", "--json"]);
    let rows = control["rows"].as_array().unwrap();
    assert!(
        rows.iter().any(|r| r["scenario"] == "alone")
            && rows.iter().any(|r| r["scenario"] == "hog"),
        "{control}"
    );
    for r in rows {
        assert!(r["ticks"].as_u64().unwrap() > 0, "{r}");
    }
    // each report names the machine that measured it, and the debug build says so
    for report in [&gate, &control] {
        let m = &report["machine"];
        assert!(!m["cpu_model"].as_str().unwrap().is_empty(), "{m}");
        assert!(m["cores"].as_u64().unwrap() >= 1, "{m}");
        assert_eq!(m["build_profile"], "debug", "{m}");
        assert!(m["calibration_gflops"].as_f64().unwrap() > 0.0, "{m}");
        assert!(m["run_s"].as_f64().unwrap() > 0.0, "{m}");
    }
}
