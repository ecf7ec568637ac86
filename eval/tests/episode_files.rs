//! AerialVLN-format episode files: real-format files load, malformed ones give errors that
//! name the bad field, generated episodes round-trip.

use aeris_eval::episode::{EpisodeError, load_episodes, parse_episodes, save_episodes};
use aeris_eval::generate::{AirspaceFilter, Split, generate_split};

/// An episode laid out as AerialVLN's files are: integer ids, 7-number poses
/// (position + quaternion), and fields we do not use.
const AERIALVLN: &str = r#"{"episodes": [{
  "episode_id": 7,
  "trajectory_id": 1093,
  "scene_id": 3,
  "start_position": [12.5, -3.0, 1.2],
  "start_rotation": [1.0, 0.0, 0.0, 0.0],
  "goals": [{"position": [80.0, 40.0, 10.0], "radius": 20.0}],
  "reference_path": [[12.5, -3.0, 1.2, 1.0, 0.0, 0.0, 0.0],
                     [17.5, -3.0, 1.2, 1.0, 0.0, 0.0, 0.0],
                     [80.0, 40.0, 10.0, 1.0, 0.0, 0.0, 0.0]],
  "actions": [1, 1, 0],
  "instruction": {"instruction_text": "fly forward past the tower and stop at the roof",
                  "instruction_tokens": [3, 9, 11]}
}]}"#;

fn episode_with(field: &str, value: &str) -> String {
    let mut v: serde_json::Value = serde_json::from_str(AERIALVLN).unwrap();
    let ep = &mut v["episodes"][0];
    let parsed: serde_json::Value = serde_json::from_str(value).unwrap();
    match field.split_once('.') {
        Some((a, b)) => ep[a][b] = parsed,
        None => ep[field] = parsed,
    }
    v.to_string()
}

fn without(field: &str) -> String {
    let mut v: serde_json::Value = serde_json::from_str(AERIALVLN).unwrap();
    v["episodes"][0].as_object_mut().unwrap().remove(field);
    v.to_string()
}

#[test]
fn an_aerialvln_file_loads_with_its_fields() {
    let eps = parse_episodes(AERIALVLN).unwrap();
    assert_eq!(eps.len(), 1);
    let e = &eps[0];
    assert_eq!(e.episode_id, "7");
    assert_eq!(e.scene_id, "3");
    assert_eq!(e.goal(), [80.0, 40.0, 10.0]);
    assert_eq!(
        e.reference_positions(),
        vec![[12.5, -3.0, 1.2], [17.5, -3.0, 1.2], [80.0, 40.0, 10.0]]
    );
    assert!(e.instruction.instruction_text.starts_with("fly forward"));
    assert!(e.subgoals.is_empty() && e.airspace.is_none());
    // a bare list of episodes loads too
    let v: serde_json::Value = serde_json::from_str(AERIALVLN).unwrap();
    let bare = v["episodes"].to_string();
    assert_eq!(parse_episodes(&bare).unwrap(), eps);
}

#[test]
fn malformed_files_name_the_bad_field() {
    let cases: Vec<(String, &str)> = vec![
        (without("goals"), "episodes[0]"),
        (
            episode_with("start_position", "[1.0, 2.0]"),
            "episodes[0].start_position",
        ),
        (
            episode_with("goals", "[{\"position\": [1, \"x\", 3]}]"),
            "episodes[0].goals[0].position[1]",
        ),
        (episode_with("goals", "[]"), "episodes[0].goals"),
        (
            episode_with("reference_path", "[[1.0, 2.0]]"),
            "episodes[0].reference_path[0]",
        ),
        (
            episode_with("reference_path", "[]"),
            "episodes[0].reference_path",
        ),
        (
            episode_with("instruction.instruction_text", "\"  \""),
            "episodes[0].instruction.instruction_text",
        ),
        (
            episode_with("instruction.instruction_text", "5"),
            "episodes[0].instruction.instruction_text",
        ),
        (
            episode_with("start_rotation", "[0.0, 0.0, 0.0, 0.0]"),
            "episodes[0].start_rotation",
        ),
        (episode_with("episode_id", "[1]"), "episodes[0].episode_id"),
        (
            episode_with("airspace", "\"underwater\""),
            "episodes[0].airspace",
        ),
        (
            episode_with(
                "subgoals",
                r#"[{"text": "a", "action": "goto", "waypoint": [0,0,0], "reference_range": [1, 3]}]"#,
            ),
            "episodes[0].subgoals[0].reference_range",
        ),
        (
            episode_with(
                "subgoals",
                r#"[{"text": "a", "action": "dance", "waypoint": [0,0,0], "reference_range": [0, 1]}]"#,
            ),
            "episodes[0].subgoals[0].action",
        ),
    ];
    for (text, field) in cases {
        let err = parse_episodes(&text).unwrap_err();
        assert_eq!(err.field(), Some(field), "{err}");
        let msg = err.to_string();
        assert!(msg.starts_with(field), "{msg}");
    }
    let missing = parse_episodes(&without("goals")).unwrap_err().to_string();
    assert!(missing.contains("missing field `goals`"), "{missing}");
    // not JSON at all
    let err = parse_episodes("{\"episodes\": [").unwrap_err();
    assert!(matches!(err, EpisodeError::Format { .. }), "{err}");
    // two episodes with one id
    let v: serde_json::Value = serde_json::from_str(AERIALVLN).unwrap();
    let twice = serde_json::json!({"episodes": [v["episodes"][0], v["episodes"][0]]});
    let err = parse_episodes(&twice.to_string()).unwrap_err();
    assert!(
        matches!(err, EpisodeError::DuplicateId { index: 1, .. }),
        "{err}"
    );
    // a missing file names the file
    let err = load_episodes(std::path::Path::new("/nonexistent/episodes.json")).unwrap_err();
    assert!(
        err.to_string().contains("/nonexistent/episodes.json"),
        "{err}"
    );
}

#[test]
fn generated_episodes_round_trip_through_a_file() {
    let eps = generate_split(Split::ValUnseen, AirspaceFilter::Full, 4, &mut |_, _| {}).unwrap();
    let dir = std::env::temp_dir().join(format!("aeris-episodes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("val.json");
    save_episodes(&path, &eps).unwrap();
    let back = load_episodes(&path).unwrap();
    assert_eq!(back, eps);
    std::fs::remove_dir_all(&dir).unwrap();
}
