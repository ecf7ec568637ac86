//! `aeris distill` flies `train` episodes with the planner as teacher (on simulated time)
//! and writes the aligned reasoner's training pairs: every decision the planner made, with
//! what an aligned model reads at that heartbeat (never the plan) and the decision as the
//! grammar writes it; held-out splits and episodes are refused before anything flies.

use aeris_tests::*;
use std::process::Command;

/// The keys of a decision, in the order the decision grammar writes them.
const DECISION_KEYS: [&str; 9] = [
    "step",
    "action",
    "north",
    "east",
    "altitude",
    "yaw_deg",
    "speed",
    "radius",
    "confidence",
];

#[test]
fn the_planner_teaches_one_train_episode_into_training_pairs() {
    let dir = TempDir::new("distill");
    let out = Command::new(aeris_bin())
        .args(["distill", "--episodes", "1", "--airspace", "open"])
        .args(["--perception", "geometric", "--json", "--out"])
        .arg(&dir.0)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris distill");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "distill failed: {stderr}\n{stdout}");
    let summary = last_json_line(&stdout);
    let episode: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(dir.0.join("episodes.jsonl"))
            .expect("episodes.jsonl")
            .lines()
            .next()
            .expect("one episode"),
    )
    .expect("an episode line");
    assert_eq!(episode["split"], "train", "{episode}");
    assert_eq!(episode["agent"], "aeris-planner-geometric");
    let text = std::fs::read_to_string(dir.0.join("pairs.jsonl")).expect("pairs.jsonl");
    let pairs: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON pair"))
        .collect();
    assert_eq!(summary["pairs"], pairs.len(), "{summary}");
    assert!(pairs.len() >= 10, "{} pairs", pairs.len());
    let success = episode["sr"].as_f64().expect("sr") > 0.5;
    let mut last_step = 0;
    for (i, pair) in pairs.iter().enumerate() {
        assert_eq!(pair["episode_id"], episode["episode_id"]);
        assert_eq!(pair["agent"], "aeris-planner-geometric");
        assert_eq!(
            pair["success"], success,
            "the episode's outcome on each pair"
        );
        assert_eq!(pair["dagger"], false, "the planner flew");
        let user = pair["user"].as_str().expect("user");
        // a segmented mission is read from its steps, its whole text not repeated
        assert!(user.starts_with("1. "), "{user}");
        assert!(!user.contains("Mission:"), "{user}");
        assert!(user.ends_with("Decision:"), "{user}");
        assert!(!user.contains("Plan"), "pair {i} shows a plan: {user}");
        assert!(pair["system"].as_str().is_some_and(|s| s.contains("JSON")));
        // the target is a decision as the grammar writes it: its keys in order
        let target = pair["target"].as_str().expect("target");
        let mut keys: Vec<String> = serde_json::from_str::<serde_json::Map<_, _>>(target)
            .expect("a JSON decision")
            .keys()
            .cloned()
            .collect();
        keys.sort();
        let mut expected = DECISION_KEYS;
        expected.sort();
        assert_eq!(keys, expected, "{target}");
        let quoted: Vec<usize> = DECISION_KEYS
            .iter()
            .map(|k| target.find(&format!("\"{k}\":")).expect("the key"))
            .collect();
        assert!(quoted.is_sorted(), "keys out of order in {target}");
        let decision: serde_json::Value = serde_json::from_str(target).unwrap();
        let step = decision["step"].as_u64().expect("a step");
        assert!(step >= last_step, "pair {i}: step {step} after {last_step}");
        last_step = step;
        // the memory line is the decision before
        if i == 0 {
            assert!(user.contains("\nLast: none.\n"), "{user}");
        } else {
            let before: serde_json::Value =
                serde_json::from_str(pairs[i - 1]["target"].as_str().unwrap()).unwrap();
            // ... and how far the drone is from its waypoint
            let memory = format!(
                "\nLast: {} {} at {} {} {}, ",
                before["step"],
                before["action"].as_str().unwrap(),
                before["north"],
                before["east"],
                before["altitude"]
            );
            let at = user
                .find(&memory)
                .unwrap_or_else(|| panic!("pair {i}: {memory:?} not in {user}"));
            let rest = &user[at + memory.len()..];
            let away = rest.split_once(" m away.\n").map(|(d, _)| d);
            assert!(
                away.is_some_and(|d| d.parse::<u32>().is_ok()),
                "pair {i}: no distance in {user}"
            );
        }
    }
    assert!(last_step >= 2, "the planner never left the first step");
}

#[test]
fn a_held_out_split_is_refused_before_anything_flies() {
    let dir = TempDir::new("distill-held-out");
    for split in ["val_unseen", "test_unseen"] {
        let out = Command::new(aeris_bin())
            .args(["distill", "--split", split, "--out"])
            .arg(&dir.0)
            .stdin(std::process::Stdio::null())
            .output()
            .expect("run aeris distill");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(
            stderr.contains(&format!("split `{split}` is held out")),
            "{stderr}"
        );
        assert!(!dir.0.join("episodes.jsonl").exists());
    }
    // nor can a file of held-out episodes bring them in
    let file = dir.0.join("test_unseen.json");
    let out = Command::new(aeris_bin())
        .args([
            "episodes",
            "generate",
            "--split",
            "test_unseen",
            "--episodes",
            "1",
        ])
        .arg("--out")
        .arg(&file)
        .output()
        .expect("run aeris episodes generate");
    assert!(out.status.success());
    let out = Command::new(aeris_bin())
        .args(["distill", "--episodes-file"])
        .arg(&file)
        .arg("--out")
        .arg(&dir.0)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris distill");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("is on scene open-3000, not a train scene"),
        "{stderr}"
    );
    assert!(!dir.0.join("episodes.jsonl").exists());
}
