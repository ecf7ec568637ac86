//! A link that hears no autopilot is an error, never a silent hover: `aeris run --autopilot
//! URL` ends with a non-zero exit within the link timeout (5 s by default) and a message
//! that names the URL and what was heard: nothing at all, only a ground station, an
//! autopilot speaking MAVLink 1 to a controller set to MAVLink 2 only, or an autopilot whose
//! frames all fail their CRC. The peers are real pymavlink processes.

use aeris_tests::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Generous bound on a run that must end by itself (the roles start, then 5 s of link
/// timeout): only a hang exceeds it.
const BOUND: Duration = Duration::from_secs(180);

/// Run the default flight against `url` (with the workflow in `workflow`, if any) and
/// return its exit code and stdout + stderr.
fn run_against(tag: &str, url: &str, workflow: Option<&Path>) -> (Option<i32>, String) {
    let dir = TempDir::new(tag);
    let flight = unique_flight(tag);
    let mut args = vec!["--autopilot", url];
    let wf;
    if let Some(w) = workflow {
        wf = w.to_string_lossy().into_owned();
        args.insert(0, &wf);
    }
    let mut run = spawn_run(&dir.0, &flight, &args);
    let status = wait_bounded(&mut run.0, BOUND)
        .unwrap_or_else(|| panic!("aeris run hung on a silent link: {:?}", run_output(&dir.0)));
    let (stdout, stderr) = run_output(&dir.0);
    (status.code(), format!("{stdout}\n{stderr}"))
}

fn peer(port: u16, extra: &[&str]) -> ChildGuard {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("py/gcs_peer.py");
    ChildGuard::spawn(
        Command::new(python())
            .arg(&script)
            .args(["--listen", &format!("udpin:127.0.0.1:{port}")])
            .args(["--timeout", "170"])
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::inherit()),
    )
    .expect("start the pymavlink peer")
}

#[test]
fn a_link_that_hears_nothing_ends_the_run_naming_the_url() {
    let port = free_udp_port();
    let url = format!("udpout:127.0.0.1:{port}");
    let (code, out) = run_against("silent", &url, None);
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}: {out}");
    assert!(
        out.contains(&format!(
            "no autopilot HEARTBEAT on {url} within 5.0 s; heard: nothing"
        )),
        "{out}"
    );
    assert!(out.contains("autopilot never heard"), "{out}");
}

#[test]
fn a_link_with_only_a_ground_station_says_whom_it_heard() {
    let port = free_udp_port();
    let _gcs = peer(port, &[]);
    let url = format!("udpout:127.0.0.1:{port}");
    let (code, out) = run_against("gcs-only", &url, None);
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}: {out}");
    assert!(
        out.contains(&format!("no autopilot HEARTBEAT on {url}")),
        "{out}"
    );
    assert!(
        out.contains("frames from system 255 component 190"),
        "{out}"
    );
    assert!(out.contains("MAV_TYPE_GCS"), "{out}");
}

/// Signing on, an autopilot that does not sign: its frames are refused, and the run says so.
#[test]
fn an_unsigned_autopilot_on_a_signed_link_is_named() {
    let port = free_udp_port();
    let _autopilot = peer(port, &["--as-autopilot"]);
    let dir = TempDir::new("signed-wf");
    let key = dir.0.join("key");
    std::fs::write(&key, "a passphrase\n").unwrap();
    let mut wf = default_workflow();
    for role in wf["roles"].as_array_mut().unwrap() {
        let t = role.as_table_mut().unwrap();
        if t["kind"].as_str() == Some("controller") {
            t["params"].as_table_mut().unwrap().insert(
                "signing_key_file".into(),
                toml::Value::String(key.to_string_lossy().into_owned()),
            );
        }
    }
    let path = write_workflow(&dir.0, "signed", &wf);
    let url = format!("udpout:127.0.0.1:{port}");
    let (code, out) = run_against("signed", &url, Some(&path));
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}: {out}");
    assert!(
        out.contains("unsigned frames, refused because signing is on"),
        "{out}"
    );
}

#[test]
fn mavlink_1_to_a_controller_set_to_mavlink_2_only_is_named() {
    let port = free_udp_port();
    let _autopilot = peer(port, &["--as-autopilot", "--mavlink", "1"]);
    let dir = TempDir::new("v2only-wf");
    let mut wf = default_workflow();
    for role in wf["roles"].as_array_mut().unwrap() {
        let t = role.as_table_mut().unwrap();
        if t["kind"].as_str() == Some("controller") {
            t["params"]
                .as_table_mut()
                .unwrap()
                .insert("mavlink".into(), toml::Value::Integer(2));
        }
    }
    let path = write_workflow(&dir.0, "v2only", &wf);
    let url = format!("udpout:127.0.0.1:{port}");
    let (code, out) = run_against("v2only", &url, Some(&path));
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}: {out}");
    assert!(out.contains("MAVLink 1 frames, refused"), "{out}");
    assert!(out.contains("params.mavlink = 2"), "{out}");
}

#[test]
fn an_autopilot_whose_frames_fail_their_crc_is_named() {
    let port = free_udp_port();
    let _autopilot = peer(port, &["--as-autopilot", "--damage-crc"]);
    let url = format!("udpout:127.0.0.1:{port}");
    let (code, out) = run_against("bad-crc", &url, None);
    assert!(code.is_some_and(|c| c != 0), "exit {code:?}: {out}");
    assert!(
        out.contains(&format!("no autopilot HEARTBEAT on {url}")),
        "{out}"
    );
    assert!(out.contains("frames that failed their CRC"), "{out}");
    assert!(!out.contains("heard: nothing"), "{out}");
}
