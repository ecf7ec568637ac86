//! `aeris formation plan`: an instruction parsed, flown in simulation and repaired by the
//! real binary; exit status and output as a user sees them.

use aeris_tests::*;
use std::process::Command;

/// `aeris formation plan TEXT [extra..] --json`: (exit ok, its JSON, stderr).
fn plan(text: &str, extra: &[&str]) -> (bool, serde_json::Value, String) {
    let out = Command::new(aeris_bin())
        .args(["formation", "plan", text, "--json"])
        .args(extra)
        .output()
        .expect("run aeris formation plan");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    (
        out.status.success(),
        last_json_line(&stdout),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

#[test]
fn instructions_are_accepted_repaired_or_refused_with_the_reason() {
    // the instruction: accepted as asked, every phase, clear of the minimum
    let (ok, out, err) = plan(
        "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
         hold 10 s, then a circle of radius 6 m, and land",
        &[],
    );
    assert!(ok, "{out}\n{err}");
    assert_eq!(out["outcome"], "accepted", "{out}");
    let kinds: Vec<&str> = out["phases"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["kind"].as_str().unwrap())
        .collect();
    assert_eq!(
        kinds,
        ["take_off", "assume", "assume", "hold", "assume", "land"]
    );
    assert!(out["min_separation_m"].as_f64().unwrap() >= 2.0, "{out}");

    // eight vehicles on a circle of radius 2 m: too tight, widened, then flown clear
    let (ok, out, err) = plan(
        "eight drones take off, a circle of radius 2 m, land",
        &["--vehicles", "8"],
    );
    assert!(ok, "{out}\n{err}");
    assert_eq!(out["outcome"], "repaired", "{out}");
    let problem = out["repaired"][0].as_str().unwrap();
    assert!(
        problem.contains("come within") && problem.contains("during the change to a circle"),
        "{problem}"
    );
    assert!(
        out["phases"][1]["spacing_m"].as_f64().unwrap() > 2.0,
        "{out}"
    );
    assert!(out["min_separation_m"].as_f64().unwrap() >= 2.0, "{out}");

    // more vehicles than the flight has: refused, never flown, exit status 1
    let (ok, out, err) = plan("six drones take off, a circle, land", &[]);
    assert!(!ok);
    assert_eq!(out["outcome"], "refused", "{out}");
    assert!(out["duration_s"].is_null(), "{out}");
    assert!(
        err.contains("refused: invalid: 6 vehicles: the flight has 4"),
        "{err}"
    );

    // a clause the parser cannot read is quoted
    let out = Command::new(aeris_bin())
        .args(["formation", "plan", "take off, do a barrel roll, land"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("`do a barrel roll`: not a take-off"), "{err}");

    // a variant that does not exist is named, with those that do
    let out = Command::new(aeris_bin())
        .args(["formation", "plan", "take off, land", "--variant", "gpt5"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--variant gpt5: the formation variants are parser, qwen-coder"),
        "{err}"
    );
}
