//! A flight whose eyes are a video file and which has no depth source: the camera is the
//! `gstreamer` variant on `filesrc ! decodebin` of an H.264 MP4 that `aeris scene video`
//! rendered along the short hop's route (a recorded FPV video played back at its own
//! rate), with no `depth_pipeline`; perception is the model pipeline's layout (the YOLO
//! detector on the decoded frames + compose) instead of the geometric perception, and there is no occupancy role, so S_t
//! never carries occupancy. The hub gates every decision without occupancy and says so in
//! its reports, the planner keeps to the conservative altitude (the band's top) rather than
//! taking unknown space for free, and the flight still reaches its goal.

use aeris_tests::*;
use std::process::Command;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

#[test]
fn on_a_video_file_without_depth_the_hub_reports_no_occupancy_and_the_flight_keeps_high() {
    let dir = TempDir::new("nodepth");
    let flight = unique_flight("nodepth");
    // the route of the short hop at 5 m/s, then 20 s over the landing point (the file
    // restarts at its end)
    let video = dir.0.join("route.mp4");
    let rendered = Command::new(aeris_bin())
        .args(["scene", "video", "village", "--fps", "5", "--hold", "20"])
        .args(["--path", "0,0,20", "--path", "30,0,20", "--path", "30,0,2"])
        .arg("--out")
        .arg(&video)
        .output()
        .expect("aeris scene video runs");
    assert!(
        rendered.status.success(),
        "aeris scene video failed: {}",
        String::from_utf8_lossy(&rendered.stderr)
    );
    let mut workflow = default_workflow();
    short_hop(&mut workflow);
    set_variant(&mut workflow, "camera", "gstreamer");
    let roles = workflow
        .get_mut("roles")
        .and_then(|r| r.as_array_mut())
        .expect("roles");
    roles.retain(|r| r.get("name").and_then(|n| n.as_str()) != Some("perception"));
    for (name, kind, variant) in [
        ("detector", "detector", "yolo"),
        ("scene", "image-to-text", "compose"),
    ] {
        let mut role = toml::Table::new();
        role.insert("name".into(), name.into());
        role.insert("kind".into(), kind.into());
        role.insert("variant".into(), variant.into());
        role.insert("executor".into(), "perception".into());
        if kind == "image-to-text" {
            // compose joins the blocks there are: here, detections only
            let topics = vec![toml::Value::from("perception/detections")];
            role.insert("subscribes".into(), toml::Value::Array(topics));
        }
        roles.push(toml::Value::Table(role));
    }
    let camera = roles
        .iter_mut()
        .filter_map(|r| r.as_table_mut())
        .find(|r| r.get("name").and_then(|n| n.as_str()) == Some("camera"))
        .expect("camera role");
    let mut params = toml::Table::new();
    // played at the file's own rate (sync=true), as a camera would deliver it
    let pipeline = format!(
        "filesrc location=\"{}\" ! decodebin ! appsink sync=true",
        video.display()
    );
    params.insert("pipeline".into(), pipeline.into());
    camera.insert("params".into(), toml::Value::Table(params));
    let path = write_workflow(&dir.0, "nodepth", &workflow);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    let logs = run_logs_tail(&dir.0, 20);
    assert!(
        status.success(),
        "aeris run failed: {status}\n{stderr}\n{logs}"
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{logs}");
    assert!(
        summary["first_decision_on_video_s"]
            .as_f64()
            .is_some_and(|s| s > 0.0),
        "a decision on the file's frames: {summary}"
    );
    // every committed decision was gated without occupancy, and the reports say so
    let committed = summary["cycles_committed"].as_u64().unwrap();
    assert!(committed > 0, "{summary}");
    assert_eq!(
        summary["commits_without_occupancy"].as_u64(),
        Some(committed),
        "{summary}"
    );
    // it kept high: up to the band's top, not the take-off's 12 m (the progress lines' alt)
    let highest = stderr
        .lines()
        .filter_map(|l| {
            l.split("  alt ")
                .nth(1)?
                .split(' ')
                .next()?
                .parse::<f64>()
                .ok()
        })
        .fold(0.0, f64::max);
    assert!(
        highest > HOP_CEILING_M - 1.0,
        "highest {highest} m, ceiling {HOP_CEILING_M} m\n{stderr}"
    );
    // the file was played without a failure (its end is a restart, not an error)
    let camera = std::fs::read_to_string(dir.0.join("run").join("logs").join("camera.log"))
        .unwrap_or_default();
    assert!(!camera.contains("failed"), "camera log:\n{camera}");
    // the hub and the planner say so in their logs (once, when it happens): S_t came, built
    // from the decoded frames
    for (role, line) in [
        ("hub", "hub: occupancy absent"),
        ("reasoning", "occupancy absent: unknown space is not free"),
    ] {
        let log =
            std::fs::read_to_string(dir.0.join("run").join("logs").join(format!("{role}.log")))
                .unwrap_or_default();
        assert!(log.contains(line), "{role} log lacks {line:?}:\n{log}");
    }
}
