//! `aeris eval` flies generated VLN episodes through the full multi-process pipeline: the
//! oracle baseline (the planner on the reference path) succeeds, the random baseline does
//! not, the AERIS agent flies from the instruction alone, and every episode is written to
//! episodes.jsonl with its trajectory, metrics and run folder (and with `--record` its
//! recording), which `aeris plot` draws; `aeris eval merge` of a run's output is its table.
//! Their subject is the evaluation and the mission logic, so they fly on simulated time
//! (`--clock sim`): as fast as the roles compute, and the same beside other flights; so the
//! shards the Ray launcher flies merge into the very table of one run.

use aeris_tests::*;
use std::process::Command;

fn eval(dir: &std::path::Path, args: &[&str]) -> (serde_json::Value, Vec<serde_json::Value>) {
    let out = Command::new(aeris_bin())
        .arg("eval")
        .args(["--clock", "sim"])
        .args(args)
        .arg("--json")
        .arg("--out")
        .arg(dir)
        .output()
        .expect("run aeris eval");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "eval {args:?} failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    // the harness shows what the test printed only when it fails: the flights' events
    eprintln!(
        "aeris eval {args:?}:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines = std::fs::read_to_string(dir.join("episodes.jsonl")).expect("episodes.jsonl");
    let episodes = lines
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    (last_json_line(&stdout), episodes)
}

/// The shortest of the first 8 episodes of the unseen validation split in `airspace` (by
/// its reference path), alone in an episode file under `dir`: the suite flies a short one
/// (the first in open airspace is more than twice as long).
fn shortest_val_unseen(dir: &std::path::Path, airspace: &str) -> String {
    std::fs::create_dir_all(dir).unwrap();
    let generated = dir.join(format!("val_unseen-{airspace}.json"));
    let out = Command::new(aeris_bin())
        .args(["episodes", "generate", "--split", "val_unseen"])
        .args(["--airspace", airspace, "--episodes", "8", "--out"])
        .arg(&generated)
        .output()
        .expect("run aeris episodes generate");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&generated).expect("the generated episodes");
    let split: serde_json::Value = serde_json::from_str(&text).expect("episodes JSON");
    let length = |e: &serde_json::Value| {
        let points: Vec<[f64; 3]> = e["reference_path"]
            .as_array()
            .expect("a reference path")
            .iter()
            .map(|p| std::array::from_fn(|i| p[i].as_f64().expect("a coordinate")))
            .collect();
        points
            .windows(2)
            .map(|w| {
                (0..3)
                    .map(|i| (w[1][i] - w[0][i]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .sum::<f64>()
    };
    let shortest = split["episodes"]
        .as_array()
        .expect("episodes")
        .iter()
        .min_by(|a, b| length(a).total_cmp(&length(b)))
        .expect("an episode")
        .clone();
    assert_eq!(shortest["airspace"], airspace, "{shortest}");
    let file = dir.join(format!("shortest-{airspace}.json"));
    let one = serde_json::json!({ "episodes": [shortest] });
    std::fs::write(&file, one.to_string()).unwrap();
    file.to_str().unwrap().to_string()
}

/// The oracle flies one episode of the unseen validation split in `airspace` to success,
/// and the episode's record has every field.
fn the_oracle_succeeds_in(airspace: &str) {
    let dir = TempDir::new(&format!("vln-eval-{airspace}"));
    let oracle_dir = dir.0.join("oracle");
    let episode = shortest_val_unseen(&dir.0, airspace);
    let (summary, episodes) = eval(
        &oracle_dir,
        &[
            "--episodes-file",
            &episode,
            "--episodes",
            "1",
            "--baseline",
            "oracle",
            // the one shard of one: what `aeris eval merge` makes of its output is the
            // table this run printed
            "--shard",
            "1/1",
        ],
    );
    let merged = Command::new(aeris_bin())
        .args(["eval", "merge", "--json"])
        .arg(&oracle_dir)
        .output()
        .expect("run aeris eval merge");
    let merged_out = String::from_utf8_lossy(&merged.stdout);
    assert!(
        merged.status.success(),
        "{merged_out}{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    assert_eq!(last_json_line(&merged_out), summary, "{merged_out}");
    assert_eq!(summary["episodes"], 1, "{summary}");
    assert_eq!(summary["sr"], 1.0, "{summary}");
    assert_eq!(summary["osr"], 1.0, "{summary}");
    assert_eq!(summary["asr"], 1.0, "{summary}");
    assert_eq!(summary[airspace]["episodes"], 1, "{summary}");
    assert!(summary["ne"].as_f64().unwrap() < 3.0, "{summary}");
    assert!(summary["ndtw"].as_f64().unwrap() > 0.5, "{summary}");
    for key in ["spl", "ct_mean_s", "ct_p95_s", "eer"] {
        assert!(summary[key].is_number(), "{key}: {summary}");
    }
    assert_eq!(episodes.len(), 1);
    for e in &episodes {
        for key in [
            "episode_id",
            "airspace",
            "positions",
            "reference",
            "goal",
            "stopped",
            "subgoals_total",
            "subgoals_completed",
            "ne",
            "sr",
            "osr",
            "ndtw",
            "spl",
            "asr",
        ] {
            assert!(!e[key].is_null(), "{key} missing: {e}");
        }
        assert_eq!(e["airspace"], airspace, "{e}");
        assert_eq!(e["stopped"], true, "{e}");
        assert_eq!(e["collided"], false, "{e}");
        let positions = e["positions"].as_array().unwrap();
        // the executed path starts at the start position and has flown the reference
        assert_eq!(positions[0], serde_json::json!([0.0, 0.0, 0.0]), "{e}");
        assert!(positions.len() > 10, "{e}");
    }
}

// One test per airspace, so the harness flies them side by side (as one test the two
// episodes flew one after the other, the longest test of the binary, alone at its end).
#[test]
fn the_oracle_succeeds_in_open_airspace() {
    the_oracle_succeeds_in("open");
}

#[test]
fn the_oracle_succeeds_in_dense_airspace() {
    the_oracle_succeeds_in("dense");
}

#[test]
fn the_random_baseline_does_not_succeed_and_its_episode_is_recorded() {
    let dir = TempDir::new("vln-eval-random");
    let (summary, episodes) = eval(
        &dir.0.join("random"),
        &[
            "--split",
            "val_unseen",
            "--episodes",
            "1",
            "--baseline",
            "random",
            "--record",
        ],
    );
    assert_eq!(summary["episodes"], 1, "{summary}");
    // --record: the episode's recording, named in its line, in its run folder, closed (an
    // MCAP file begins and ends with the magic)
    let recording = std::path::PathBuf::from(episodes[0]["recording"].as_str().unwrap());
    assert!(
        recording.starts_with(episodes[0]["run_dir"].as_str().unwrap()),
        "{}",
        episodes[0]
    );
    let bytes = std::fs::read(&recording).expect("the episode's recording");
    let magic = b"\x89MCAP0\r\n";
    assert!(
        bytes.len() > 16 && bytes.starts_with(magic) && bytes.ends_with(magic),
        "{}: {} bytes",
        recording.display(),
        bytes.len()
    );
    // every goal is 50 m or more from the start; a random walk of 5 m steps that stops
    // with probability 1/8 per heartbeat does not get there
    assert_eq!(summary["sr"], 0.0, "{summary}");
    assert_eq!(episodes[0]["sr"], 0.0);
}

/// The launcher never uses a Ray cluster without token authentication: a Ray cluster runs
/// whatever code its clients send.
#[test]
fn the_ray_launcher_refuses_a_cluster_without_token_authentication() {
    let dir = TempDir::new("vln-eval-ray-auth");
    let launcher = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scripts")
        .join("eval-ray.py");
    for address in [None, Some("10.0.0.1:6379")] {
        let mut cmd = Command::new(python());
        cmd.arg(&launcher)
            .env("RAY_AUTH_MODE", "disabled")
            .args(["--shards", "1", "--out"])
            .arg(dir.0.join("out"));
        if let Some(a) = address {
            cmd.args(["--address", a]);
        }
        let out = cmd
            .args(["--", "--episodes", "1"])
            .stdin(std::process::Stdio::null())
            .output()
            .expect("run scripts/eval-ray.py");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{address:?}: {stderr}");
        assert!(
            stderr.contains("RAY_AUTH_MODE=disabled: refused"),
            "{address:?}: {stderr}"
        );
    }
}

/// The launcher (`scripts/eval-ray.py`) flies two episodes as two shards on a local Ray
/// cluster, and its merged table is the table of one run of the same two episodes: on
/// simulated time the flights, hence every metric, are the same wherever they fly (all but
/// the compute times, which are this machine's wall-clock measurements).
#[test]
fn shards_flown_by_ray_on_a_local_cluster_merge_into_the_table_of_one_run() {
    let dir = TempDir::new("vln-eval-ray");
    // the shortest episode of each airspace, in one file
    let episodes: Vec<serde_json::Value> = ["open", "dense"]
        .iter()
        .map(|a| {
            let file = shortest_val_unseen(&dir.0.join("episodes"), a);
            let one: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap();
            one["episodes"][0].clone()
        })
        .collect();
    let file = dir.0.join("two.json");
    std::fs::write(
        &file,
        serde_json::json!({ "episodes": episodes }).to_string(),
    )
    .unwrap();
    let file = file.to_str().unwrap();
    let eval_args = [
        "--episodes-file",
        file,
        "--episodes",
        "2",
        "--baseline",
        "oracle",
    ];
    let (one_run, _) = eval(&dir.0.join("one-run"), &eval_args);
    assert_eq!(one_run["episodes"], 2, "{one_run}");
    let launcher = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("scripts")
        .join("eval-ray.py");
    // the local cluster's token lives in the processes' environment, never in a file
    let home = dir.0.join("home");
    std::fs::create_dir_all(&home).unwrap();
    let out = Command::new(python())
        .arg(&launcher)
        .env("HOME", &home)
        .env_remove("RAY_AUTH_MODE")
        .env_remove("RAY_AUTH_TOKEN")
        .args([
            "--shards",
            "2",
            "--cpus-per-shard",
            "1",
            "--json",
            "--aeris",
        ])
        .arg(aeris_bin())
        .arg("--out")
        .arg(dir.0.join("ray"))
        .args(["--", "--clock", "sim"])
        .args(eval_args)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run scripts/eval-ray.py");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "eval-ray.py failed: {stderr}\n{stdout}"
    );
    assert!(
        !home.join(".ray").join("auth_token").exists(),
        "the launcher wrote Ray's token to a file"
    );
    // each shard flew on the cluster and said so
    for k in 1..=2 {
        assert!(stderr.contains(&format!("shard {k}/2 done")), "{stderr}");
        assert!(
            dir.0
                .join(format!("ray/shard-{k}-of-2/episodes.jsonl"))
                .is_file()
        );
    }
    // the same table, but for what the work took on the machine (wall-clock measurements)
    let without_compute = |mut table: serde_json::Value| {
        for group in [None, Some("open"), Some("dense")] {
            let g = match group {
                None => &mut table,
                Some(name) => &mut table[name],
            };
            for key in ["ct_compute_mean_s", "eer_compute"] {
                let removed = g.as_object_mut().and_then(|o| o.remove(key));
                assert!(removed.is_some_and(|v| v.is_number()), "{key}");
            }
        }
        table
    };
    assert_eq!(
        without_compute(last_json_line(&stdout)),
        without_compute(one_run),
        "{stdout}"
    );
}

fn plot(args: &[&str]) -> String {
    let out = Command::new(aeris_bin())
        .arg("plot")
        .args(args)
        .output()
        .expect("run aeris plot");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "plot {args:?} failed: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Width and height of a PNG file, read from its header.
fn png_size(path: &std::path::Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("the PNG exists");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", path.display());
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn the_aeris_agent_flies_from_the_instruction_alone_and_its_flight_can_be_plotted() {
    let dir = TempDir::new("vln-eval-aeris");
    let episode = shortest_val_unseen(&dir.0.join("episodes"), "open");
    let (summary, episodes) = eval(
        &dir.0,
        // the one-process perception keeps the suite short; the model roles are the
        // default of `aeris eval` and have their own tests
        &[
            "--episodes-file",
            &episode,
            "--episodes",
            "1",
            "--perception",
            "geometric",
        ],
    );
    assert_eq!(summary["agent"], "aeris-planner-geometric", "{summary}");
    assert_eq!(summary["episodes"], 1, "{summary}");
    let e = &episodes[0];
    assert_eq!(e["agent"], "aeris-planner-geometric");
    // it took off (the first step) and flew somewhere from the start
    assert!(e["subgoals_completed"].as_u64().unwrap() >= 1, "{e}");
    assert!(e["positions"].as_array().unwrap().len() > 3, "{e}");
    for key in ["ne", "sr", "osr", "ndtw", "spl"] {
        assert!(e[key].is_number(), "{key}: {e}");
    }
    // the pictures of that episode
    let run = std::path::PathBuf::from(e["run_dir"].as_str().expect("run_dir"));
    let trace = std::fs::read_to_string(run.join("cycles.jsonl")).expect("cycles.jsonl");
    let cycles = trace.lines().count();
    assert!(cycles > 5, "{trace}");
    // each row says what the hub had bound: this flight flew legs
    let rows: Vec<serde_json::Value> = trace
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON row"))
        .collect();
    assert!(
        rows.iter().any(|r| r["setpoint_mode"] == "goto"
            && r["setpoint"].as_array().is_some_and(|p| p.len() == 3)),
        "{trace}"
    );
    let timing = dir.0.join("timing.png");
    let out = plot(&[
        "timing",
        "--run",
        run.to_str().unwrap(),
        "--out",
        timing.to_str().unwrap(),
    ]);
    assert!(out.contains(&format!("{cycles} cycles")), "{out}");
    assert!(png_size(&timing).0 >= 560);
    let fpv = dir.0.join("fpv.png");
    plot(&[
        "fpv",
        "--run",
        run.to_str().unwrap(),
        "--frames",
        "4",
        "--out",
        fpv.to_str().unwrap(),
    ]);
    let (w, h) = png_size(&fpv);
    // four 320x240 frames side by side, captions under them
    assert!(w >= 4 * 320 && h > 240, "{w}x{h}");
    let map = dir.0.join("map.png");
    let jsonl = dir.0.join("episodes.jsonl");
    plot(&[
        "map",
        "--run",
        jsonl.to_str().unwrap(),
        "--out",
        map.to_str().unwrap(),
    ]);
    assert!(png_size(&map).0 > 100);
}

#[test]
fn bad_arguments_are_clear_errors() {
    let dir = TempDir::new("vln-eval-args");
    for (args, needle) in [
        (vec!["--baseline", "psychic"], "unknown baseline `psychic`"),
        (
            vec!["--baseline", "oracle", "--split", "test_seen"],
            "unknown split `test_seen`",
        ),
        (
            vec!["--baseline", "oracle", "--airspace", "space"],
            "unknown airspace `space`",
        ),
        (
            vec!["--baseline", "oracle", "--episodes", "0"],
            "--episodes must be at least 1",
        ),
        (
            vec!["--baseline", "oracle", "--shard", "0/2"],
            "not K/N with 1 <= K <= N",
        ),
        (
            vec!["--baseline", "random", "--single-slm"],
            "apply to the AERIS agent, not to a --baseline",
        ),
        (
            vec!["--baseline", "random", "--no-ds"],
            "apply to the AERIS agent, not to a --baseline",
        ),
        (
            vec!["--zero-shot", "--reasoning", "planner"],
            "--zero-shot ablates the language model's plan",
        ),
        (
            vec!["--baseline", "oracle", "--no-att"],
            "apply to the AERIS agent, not to a --baseline",
        ),
        (
            vec!["--reasoning", "oracle"],
            "unknown reasoning variant `oracle`",
        ),
        (
            vec!["--perception", "telepathy"],
            "unknown perception `telepathy`",
        ),
    ] {
        let out = Command::new(aeris_bin())
            .arg("eval")
            .args(&args)
            .arg("--out")
            .arg(&dir.0)
            .output()
            .expect("run aeris eval");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
    // an episode file naming a scene this simulator does not have
    let file = dir.0.join("aerialvln.json");
    std::fs::write(
        &file,
        r#"{"episodes": [{"episode_id": 1, "trajectory_id": 1, "scene_id": 3,
            "start_position": [0, 0, 0], "start_rotation": [1, 0, 0, 0],
            "goals": [{"position": [50, 0, 0]}], "reference_path": [[0, 0, 0], [50, 0, 0]],
            "instruction": {"instruction_text": "fly north"}}]}"#,
    )
    .unwrap();
    let out = Command::new(aeris_bin())
        .args(["eval", "--baseline", "oracle", "--episodes-file"])
        .arg(&file)
        .arg("--out")
        .arg(&dir.0)
        .output()
        .expect("run aeris eval");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("scene `3` is not a scene this simulator has"),
        "{stderr}"
    );
}
