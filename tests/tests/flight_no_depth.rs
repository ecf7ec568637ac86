//! A flight whose perception has no depth source: the default mission with the model
//! pipeline's layout (detector + compose) instead of the geometric perception, and no
//! occupancy role, so S_t never carries occupancy (the sim camera still renders depth: a
//! camera without depth is the gstreamer variant's job, not the simulator's). The hub
//! gates every decision without occupancy and says so in its reports, the planner keeps to
//! the conservative altitude (the band's top) rather than taking unknown space for free,
//! and the flight still reaches its goal.

use aeris_tests::*;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

#[test]
fn without_depth_the_hub_reports_no_occupancy_and_the_flight_keeps_high() {
    let dir = TempDir::new("nodepth");
    let flight = unique_flight("nodepth");
    let mut workflow = default_workflow();
    let roles = workflow
        .get_mut("roles")
        .and_then(|r| r.as_array_mut())
        .expect("roles");
    roles.retain(|r| r.get("name").and_then(|n| n.as_str()) != Some("perception"));
    for (name, kind, variant) in [
        ("detector", "detector", "palette"),
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
    // every committed decision was gated without occupancy, and the reports say so
    let committed = summary["cycles_committed"].as_u64().unwrap();
    assert!(committed > 0, "{summary}");
    assert_eq!(
        summary["commits_without_occupancy"].as_u64(),
        Some(committed),
        "{summary}"
    );
    // the hub and the planner say so in their logs (once, when it happens)
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
