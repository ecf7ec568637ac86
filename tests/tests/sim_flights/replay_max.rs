//! `aeris replay --speed max`: a flight recorded on simulated time, replayed on simulated
//! time with perception, the planner and the hub live, replays every recorded cycle on the
//! same frame with the same action and step. (Not every target to the bit: the replay source
//! publishes an instant's recorded telemetry before the reasoner's turn, where in the flight
//! the controller, ranked after the reasoner, published it after; a wall-clock recording,
//! whose stamps never coincide, replays at `--speed max` with every cycle identical.)

use aeris_tests::*;
use std::process::Command;

#[test]
fn a_recording_replayed_at_speed_max_replays_every_cycle_with_its_action_and_step() {
    let dir = TempDir::new("replay-max");
    let flight = unique_flight("replay-max");
    let hop = short_hop_workflow(&dir.0);
    let file = dir.0.join("flight.mcap");
    let run = Command::new(aeris_bin())
        .arg("run")
        .arg(&hop)
        .args(["--clock", "sim", "--json", "--flight", &flight, "--run-dir"])
        .arg(dir.0.join("run"))
        .arg("--record")
        .arg(&file)
        .args(["--record-frame-every", "0"])
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris run");
    assert!(
        run.status.success(),
        "aeris run --record failed: {}\n{}",
        String::from_utf8_lossy(&run.stderr),
        run_logs_tail(&dir.0, 20)
    );
    let replay = Command::new(aeris_bin())
        .arg("replay")
        .arg(&file)
        .args(["--speed", "max", "--to", "20", "--json", "--flight"])
        .arg(format!("{flight}-replay"))
        .arg("--run-dir")
        .arg(dir.0.join("replay"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run aeris replay");
    let stdout = String::from_utf8_lossy(&replay.stdout);
    assert!(
        replay.status.success(),
        "aeris replay --speed max failed: {}\n{stdout}",
        String::from_utf8_lossy(&replay.stderr)
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["clock"], "sim", "{summary}");
    let recorded = summary["recorded_cycles"].as_u64().unwrap();
    assert!(recorded >= 5, "20 s hold several heartbeats: {summary}");
    assert_eq!(summary["replayed_cycles"], recorded, "{summary}");
    assert_eq!(summary["paired"], recorded, "on the same frames: {summary}");
    assert_eq!(summary["action_agreement"], 1.0, "{summary}");
}
