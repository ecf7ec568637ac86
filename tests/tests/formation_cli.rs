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

#[test]
fn an_accepted_program_is_flown_by_the_vehicle_model_and_its_tracks_are_plotted() {
    let dir = TempDir::new("formation-plot");
    let run = dir.0.join("run");
    let (ok, out, err) = plan(
        "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
         hold 10 s, then a circle of radius 6 m, and land",
        &["--run", run.to_str().unwrap()],
    );
    assert!(ok, "{out}\n{err}");
    // flown by the multirotor: every phase settled, apart as flown
    let flown = &out["flown"];
    assert_eq!(
        flown["settled_after_s"].as_array().unwrap().len(),
        6,
        "{out}"
    );
    assert!(flown["min_separation_m"].as_f64().unwrap() >= 2.0, "{out}");
    let tracks: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("formation.json")).unwrap())
            .unwrap();
    assert_eq!(tracks["vehicles"], 4);
    assert_eq!(
        tracks["phases"][2], "the change to a wedge",
        "{}",
        tracks["phases"]
    );
    let points = tracks["points"].as_array().unwrap();
    assert!(points.len() > 100, "{} points", points.len());
    assert_eq!(points[0]["positions"].as_array().unwrap().len(), 4);

    let png = dir.0.join("formation.png");
    let plot = |run: &std::path::Path| {
        Command::new(aeris_bin())
            .args(["plot", "formation", "--run"])
            .arg(run)
            .arg("--out")
            .arg(&png)
            .output()
            .unwrap()
    };
    let done = plot(&run);
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    let stdout = String::from_utf8_lossy(&done.stdout);
    assert!(stdout.contains("4 vehicles, 6 phases"), "{stdout}");
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG"), "not a PNG");

    // a folder without a formation flight: the file is named
    let empty = dir.0.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let failed = plot(&empty);
    let err = String::from_utf8_lossy(&failed.stderr);
    assert!(!failed.status.success());
    assert!(err.contains("empty/formation.json"), "{err}");
}
