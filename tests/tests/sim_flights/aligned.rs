//! The task-aligned reasoner flies from the instruction and S_t alone: `smollm2-aligned`
//! (SmolLM2 with its committed LoRA adapter, `adapters/smollm2-aligned/`) flies a short
//! `train` episode through the full pipeline on simulated time and lands at its goal, and
//! every prompt it decided on (the student's pairs `aeris distill` writes are its prompts,
//! byte for byte) holds no plan.

use aeris_tests::*;
use std::process::Command;

/// The episode: open airspace, three steps, the teacher lands 4 m from its goal in 56 s.
const EPISODE: &str = "train-open-1002-0";

#[test]
fn the_aligned_model_lands_a_short_episode_without_a_plan() {
    let dir = TempDir::new("aligned");
    let generated = dir.0.join("train-open.json");
    let out = Command::new(aeris_bin())
        .args([
            "episodes",
            "generate",
            "--split",
            "train",
            "--airspace",
            "open",
        ])
        .args(["--episodes", "3", "--out"])
        .arg(&generated)
        .output()
        .expect("run aeris episodes generate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let split: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&generated).unwrap()).unwrap();
    let episode = split["episodes"]
        .as_array()
        .expect("episodes")
        .iter()
        .find(|e| e["episode_id"] == EPISODE)
        .unwrap_or_else(|| panic!("{EPISODE} is not among the first train episodes"))
        .clone();
    let file = dir.0.join("one.json");
    std::fs::write(
        &file,
        serde_json::json!({ "episodes": [episode] }).to_string(),
    )
    .unwrap();
    let out = Command::new(aeris_bin())
        .args(["distill", "--student", "smollm2-aligned", "--episodes-file"])
        .arg(&file)
        .args(["--json", "--out"])
        .arg(dir.0.join("out"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris distill");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "distill failed: {stderr}\n{stdout}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["agent"], "aeris-smollm2-aligned", "{summary}");
    let prompts = std::fs::read_to_string(dir.0.join("out/pairs.jsonl")).expect("pairs.jsonl");
    let mut n = 0;
    for line in prompts.lines() {
        let pair: serde_json::Value = serde_json::from_str(line).expect("a pair");
        let user = pair["user"].as_str().expect("the prompt");
        assert!(!user.contains("Plan"), "a prompt with a plan: {user}");
        n += 1;
    }
    assert!(n >= 5, "{n} decisions");
    assert_eq!(
        summary["sr"], 1.0,
        "the aligned model did not land at the goal: {stderr}\n{summary}"
    );
}
