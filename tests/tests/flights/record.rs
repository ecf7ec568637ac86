//! Every flight recorded, any flight replayed: `aeris run --record` writes an MCAP file
//! that an independent reader, the `mcap` package from PyPI (tests/py/mcap_read.py), reads
//! back, with as many messages per topic as the flight's summary counts and every frame
//! exact; `aeris replay` of it with the deterministic planner decides every cycle
//! identically, byte for byte; and a recorder killed with SIGKILL mid-flight neither stops
//! the flight nor spoils what it had written (which a replay refuses, clearly).

use aeris_runtime::bus::FlightBus;
use aeris_tests::*;
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

/// What tests/py/mcap_read.py says of `file` (with `extra` arguments).
fn read_back_with(file: &Path, extra: &[&std::ffi::OsStr]) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("py/mcap_read.py");
    let out = Command::new(python())
        .arg(&script)
        .arg(file)
        .args(extra)
        .output()
        .expect("run the python MCAP reader");
    assert!(
        out.status.success(),
        "{} failed (is `mcap` installed? scripts/setup-test-deps.sh): {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    last_json_line(&String::from_utf8_lossy(&out.stdout))
}

/// What tests/py/mcap_read.py says of `file`.
pub(crate) fn read_back(file: &Path) -> Value {
    read_back_with(file, &[])
}

pub(crate) fn count(read: &Value, topic: &str) -> u64 {
    read["counts"][topic].as_u64().unwrap_or(0)
}

/// Checks every recording passes, whole or cut short: schemas and JSON messages parse, raw
/// payloads have their layout's size, and every typed message has its raw twin.
pub(crate) fn assert_well_formed(read: &Value, what: &str) {
    assert_eq!(read["schemas_valid_json"], true, "{what}: {read}");
    assert_eq!(read["json_messages_valid"], true, "{what}: {read}");
    assert_eq!(read["raw_sizes_ok"], true, "{what}: {read}");
    let channels = read["channels"].as_object().expect("channels");
    for (topic, ch) in channels {
        let side = ["/raw", "/image", "/pose", "/frame"];
        if side.iter().any(|s| topic.ends_with(s)) {
            continue;
        }
        assert_eq!(ch["message_encoding"], "json", "{what}: {topic}");
        assert_eq!(ch["schema_encoding"], "jsonschema", "{what}: {topic}");
        let raw = &channels[&format!("{topic}/raw")];
        assert_eq!(raw["message_encoding"], "aeris-raw", "{what}: {topic}");
        assert!(
            raw["schema_name"].as_str().unwrap().contains("@s"),
            "{what}: {topic}: {raw}"
        );
        // JSON and raw come from one queued sample: a file cut short may hold the JSON of
        // its last sample without the raw bytes that follow it
        let (j, r) = (count(read, topic), count(read, &format!("{topic}/raw")));
        assert!(
            j == r || (j == r + 1 && read["complete"] == false),
            "{what}: {topic} {j} json, {r} raw"
        );
    }
}

#[test]
fn a_recorded_flight_reads_back_with_the_summarys_counts() {
    let dir = TempDir::new("record");
    let flight = unique_flight("record");
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(
        &dir.0,
        &flight,
        &[
            hop.to_str().unwrap(),
            "--record",
            "--record-frame-every",
            "10",
        ],
    );
    // `aeris record` attaches a second recorder to the running flight, which stops when
    // the flight ends
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    poll_flight(
        &mut run,
        &dir.0,
        "the flight came up",
        Duration::from_secs(180),
        || {
            let b = observer.read_status_board().ok()?;
            (b.supervisor_pid != 0 && b.roles().iter().all(|r| r.heartbeats > 0)).then_some(())
        },
    );
    let attached = dir.0.join("attached.mcap");
    let attach_out = dir.0.join("attach.stdout");
    let attach_err = dir.0.join("attach.stderr");
    let mut attach = ChildGuard::spawn(
        Command::new(aeris_bin())
            .arg("record")
            .arg(&attached)
            .arg("--flight")
            .arg(&flight)
            .arg("--run-dir")
            .arg(dir.0.join("run"))
            .stdin(std::process::Stdio::null())
            .stdout(std::fs::File::create(&attach_out).unwrap())
            .stderr(std::fs::File::create(&attach_err).unwrap()),
    )
    .expect("spawn aeris record");
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let attach_status = wait_bounded(&mut attach.0, FLIGHT_BOUND).expect("aeris record ended");
    let attach_log = std::fs::read_to_string(&attach_err).unwrap_or_default();
    assert!(
        attach_status.success(),
        "aeris record: {attach_status}\n{attach_log}"
    );
    assert!(attach_log.contains("the flight ended"), "{attach_log}");
    let read = read_back(&attached);
    assert_eq!(read["complete"], true, "{read}");
    assert_well_formed(&read, "attached.mcap");
    for topic in ["hub/report", "camera/rgb/frame", "vehicle/telemetry"] {
        assert!(count(&read, topic) > 0, "{topic}: {read}");
    }
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");

    // the default file, in the run directory, reported by the summary
    let file = dir.0.join("run").join("flight.mcap");
    let rec = &summary["recording"];
    assert_eq!(rec["path"], file.to_str().unwrap(), "{summary}");
    assert_eq!(rec["files"], serde_json::json!([file.to_str().unwrap()]));
    assert_eq!(rec["failed"], false, "{summary}");
    assert!(rec["messages"].as_u64().unwrap() > 0, "{summary}");
    let dropped = rec["dropped"].as_u64().unwrap();

    // read with the repository's Foxglove layout; the first pictures dumped
    let layout =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../record/foxglove/aeris-flight-layout.json");
    let read = read_back_with(
        &file,
        &[
            "--layout".as_ref(),
            layout.as_os_str(),
            "--dump".as_ref(),
            dir.0.as_os_str(),
        ],
    );
    assert_eq!(
        read["complete"], true,
        "a stopped recorder finishes its file: {read}"
    );
    // everything the layout shows is in the recording
    assert_eq!(read["layout_missing"], serde_json::json!([]), "{read}");
    // pictures as Foxglove's CompressedImage: JPEG for colour, PNG (16-bit) for depth,
    // whole files that an independent decoder reads at the camera's size
    assert_eq!(read["images_ok"], true, "{read}");
    assert_eq!(
        read["image_formats"]["camera/rgb/image"],
        serde_json::json!(["jpeg"])
    );
    assert_eq!(
        read["image_formats"]["camera/depth/image"],
        serde_json::json!(["png"])
    );
    for (name, colour) in [
        ("camera_rgb_image.jpeg", true),
        ("camera_depth_image.png", false),
    ] {
        let picture = image::open(dir.0.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((picture.width(), picture.height()), (320, 240), "{name}");
        assert_eq!(picture.color().has_color(), colour, "{name}");
    }
    // the vehicle's pose beside every telemetry message, for the 3D panel
    assert_eq!(
        count(&read, "vehicle/telemetry/pose"),
        count(&read, "vehicle/telemetry")
    );
    let pose = &read["first_json"]["vehicle/telemetry/pose"];
    assert_eq!(pose["frame_id"], "map", "{pose}");
    let telemetry = &read["first_json"]["vehicle/telemetry"];
    let (x, east) = (
        pose["pose"]["position"]["x"].as_f64().unwrap(),
        telemetry["position"][1].as_f64().unwrap(),
    );
    // the same f32, printed at two precisions
    assert!((x - east).abs() < 1e-4, "x is east: {pose} {telemetry}");
    assert_eq!(read["error"], Value::Null, "{read}");
    assert_well_formed(&read, "flight.mcap");
    for topic in [
        "camera/rgb",
        "camera/depth",
        "perception/state",
        "reasoning/decision",
        "hub/setpoint",
        "hub/report",
        "vehicle/telemetry",
        "controller/lease",
        "controller/link",
        "heartbeat",
    ] {
        assert!(
            count(&read, topic) > 0,
            "nothing recorded on {topic}: {read}"
        );
    }
    // a topic nobody in this flight publishes is not recorded
    assert!(read["channels"].get("perception/text").is_none(), "{read}");

    // The summary's counts, within one message at either end: the recorder starts first,
    // but nothing makes the others wait for its ports, so the first decision or report may
    // come before it listens (decisions have no history); and the summary is taken at the
    // flight's last step, while the reasoner and the hub run on until they are stopped, so
    // one more decision or report may be recorded that the summary does not count. Dropped
    // samples (reported, normally none) widen the bound.
    let near = |recorded: u64, summary_count: u64, what: &str| {
        assert!(
            recorded + 1 + dropped >= summary_count && recorded <= summary_count + 1,
            "{what}: recorded {recorded}, summary {summary_count} (dropped {dropped})\n{summary}"
        );
    };
    near(
        count(&read, "hub/report"),
        summary["cycles"].as_u64().unwrap(),
        "hub reports vs cycles",
    );
    near(
        count(&read, "reasoning/decision"),
        summary["decisions_received"].as_u64().unwrap(),
        "decisions vs decisions received",
    );
    // images at the reduced rate: every 10th frame, the first included
    let frames = count(&read, "camera/rgb");
    let images = count(&read, "camera/rgb/image");
    assert!(
        images > 0 && images <= frames.div_ceil(10) + dropped,
        "{frames} frames, {images} images"
    );
    let decision = &read["first_json"]["reasoning/decision"];
    assert!(decision["publish_ns"].as_u64().unwrap() > 0, "{decision}");
    // every frame exact (header and pixels, checked against the header by the reader)
    for topic in ["camera/rgb", "camera/depth"] {
        let exact = count(&read, &format!("{topic}/frame"));
        assert!(
            exact + dropped >= count(&read, topic) && exact > 0,
            "{topic}: {exact} exact frames: {read}"
        );
    }

    // replayed: the same frames and telemetry, perception, the planner and the hub live;
    // the planner decides on the same frames what it decided in flight, bit for bit
    let replay = replay_json(&dir.0, &flight, &file, &["--to", "20"]);
    let (recorded, identical) = (
        replay["recorded_cycles"].as_u64().unwrap(),
        replay["identical"].as_u64().unwrap(),
    );
    assert!(recorded >= 5, "20 s hold several heartbeats: {replay}");
    assert_eq!(identical, recorded, "every cycle identical: {replay}");
    assert_eq!(replay["replayed_cycles"], recorded, "{replay}");
    assert_eq!(replay["agreement"], 1.0, "{replay}");
    assert_eq!(replay["recorded_without_frame"], 0, "{replay}");
    // the replay recorded its own decisions, for Foxglove
    let own = read_back(Path::new(replay["replay_recording"].as_str().unwrap()));
    assert_eq!(own["complete"], true, "{own}");
    // (and, after the range, a decision on the telemetry alone once the frames stopped)
    assert!(count(&own, "reasoning/decision") >= recorded, "{own}");

    // A/B on the same frames, twice as fast (the heartbeat with them): the planner agrees
    // with the recording, the garbage reasoner does not; one table, one JSON object
    let rows = replay_json(
        &dir.0,
        &flight,
        &file,
        &[
            "--to",
            "12",
            "--speed",
            "2",
            "--compare",
            "reasoning=planner,garbage",
        ],
    );
    let rows = rows.as_array().expect("one row per variant");
    assert_eq!(rows.len(), 2, "{rows:?}");
    assert_eq!(rows[0]["variant"], "reasoning=planner");
    assert_eq!(rows[0]["summary"]["agreement"], 1.0, "{:?}", rows[0]);
    assert!(
        rows[1]["summary"]["agreement"].as_f64().unwrap() < 1.0,
        "garbage agrees with the planner's flight: {:?}",
        rows[1]
    );
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row["agreement_with"][i], 1.0, "itself: {row}");
    }
    assert_eq!(rows[0]["agreement_with"][1], rows[1]["agreement_with"][0]);
}

/// `aeris replay FILE --json [extra..]` as flight `FLIGHT-replay` in `dir/replay`: its
/// summary (the last JSON line), after asserting it succeeded.
fn replay_json(dir: &Path, flight: &str, file: &Path, extra: &[&str]) -> Value {
    let (status, stdout, stderr) = replay_run(dir, flight, file, extra);
    assert!(
        status.success(),
        "aeris replay failed: {status}\n{stdout}\n{stderr}"
    );
    last_json_line(&stdout)
}

/// Run `aeris replay FILE --json [extra..]` to its end: status, stdout, stderr.
pub(crate) fn replay_run(
    dir: &Path,
    flight: &str,
    file: &Path,
    extra: &[&str],
) -> (std::process::ExitStatus, String, String) {
    let out = dir.join("replay.stdout");
    let err = dir.join("replay.stderr");
    let mut cmd = Command::new(aeris_bin());
    cmd.arg("replay")
        .arg(file)
        .arg("--json")
        .arg("--flight")
        .arg(format!("{flight}-replay"))
        .arg("--run-dir")
        .arg(dir.join("replay"))
        .args(extra)
        .stdin(std::process::Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(std::fs::File::create(&err).unwrap());
    let mut child = ChildGuard::spawn(&mut cmd).expect("spawn aeris replay");
    let status = wait_bounded(&mut child.0, FLIGHT_BOUND).expect("replay finished");
    (
        status,
        std::fs::read_to_string(out).unwrap_or_default(),
        std::fs::read_to_string(err).unwrap_or_default(),
    )
}

#[test]
fn a_killed_recorder_is_restarted_into_a_new_file_and_its_first_file_reads_back() {
    let dir = TempDir::new("record-kill");
    let flight = unique_flight("record-kill");
    let file = dir.0.join("flight.mcap");
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(
        &dir.0,
        &flight,
        &[
            hop.to_str().unwrap(),
            "--record",
            file.to_str().unwrap(),
            "--record-frame-every",
            "0",
        ],
    );
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let recorder = |b: &aeris_schemas::SupervisorStatus| {
        b.roles()
            .iter()
            .find(|r| r.name.as_str() == Some("recorder"))
            .copied()
    };
    // several chunks on disk (64 KiB each, ended at least every 250 ms): something to read
    let before = poll_until(Duration::from_secs(180), || {
        let b = observer.read_status_board().ok()?;
        let r = recorder(&b)?;
        let len = std::fs::metadata(&file).ok()?.len();
        (r.pid != 0 && len > 4 * 64 * 1024).then_some(r)
    })
    .unwrap_or_else(|| panic!("the recorder never wrote: {:?}", run_output(&dir.0)));
    // SAFETY: kill(2) with a pid the supervisor reports for a child it owns.
    assert_eq!(unsafe { libc::kill(before.pid as i32, libc::SIGKILL) }, 0);
    poll_until(Duration::from_secs(60), || {
        let r = recorder(&observer.read_status_board().ok()?)?;
        (r.pid != 0 && r.pid != before.pid && r.restarts == before.restarts + 1).then_some(())
    })
    .unwrap_or_else(|| panic!("the recorder was not restarted: {:?}", run_output(&dir.0)));

    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");
    let second = dir.0.join("flight.mcap.1");
    assert_eq!(
        summary["recording"]["files"],
        serde_json::json!([file.to_str().unwrap(), second.to_str().unwrap()]),
        "{summary}"
    );

    // the killed recorder's file: no summary section, read as a stream up to where it stops
    let first = read_back(&file);
    assert_eq!(first["complete"], false, "{first}");
    // ... which a replay refuses, saying why, before starting anything
    let (status, _, stderr) = replay_run(&dir.0, &flight, &file, &[]);
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains(file.to_str().unwrap()) && stderr.contains("did not close it"),
        "{stderr}"
    );
    assert_well_formed(&first, "the killed recorder's file");
    // killed early in the flight: the roles' heartbeats at least are in it
    assert!(count(&first, "heartbeat") > 0, "{first}");
    // the restarted recorder's file: whole, and the flight's end is in it
    let after = read_back(&second);
    assert_eq!(after["complete"], true, "{after}");
    assert_well_formed(&after, "the restarted recorder's file");
    assert!(count(&after, "hub/report") > 0, "{after}");
}

#[test]
fn a_recording_that_cannot_be_written_stops_and_the_flight_goes_on() {
    let dir = TempDir::new("record-full");
    let flight = unique_flight("record-full");
    let file = dir.0.join("flight.mcap");
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(
        &dir.0,
        &flight,
        &[
            hop.to_str().unwrap(),
            "--record",
            file.to_str().unwrap(),
            "--record-frame-every",
            "0",
        ],
    );
    // A disk that fills up mid-flight, played by a file-size limit (RLIMIT_FSIZE) on the
    // recorder process alone (iceoryx2 sizes its shared memory with ftruncate, which the
    // limit would refuse elsewhere), set once the recorder has created its file (after
    // it stopped SIGXFSZ from killing it) at 512 KiB beyond what it holds.
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let (pid, len) = poll_until(Duration::from_secs(180), || {
        let b = observer.read_status_board().ok()?;
        let r = *b
            .roles()
            .iter()
            .find(|r| r.name.as_str() == Some("recorder"))?;
        let len = std::fs::metadata(&file).ok()?.len();
        (r.pid != 0 && len > 0).then_some((r.pid, len))
    })
    .unwrap_or_else(|| {
        panic!(
            "the recorder never created its file: {:?}",
            run_output(&dir.0)
        )
    });
    let limit = libc::rlimit {
        rlim_cur: len + 512 * 1024,
        rlim_max: len + 512 * 1024,
    };
    // SAFETY: prlimit(2) on a pid the supervisor reports for its child, with a valid limit.
    let rc = unsafe {
        libc::prlimit(
            pid as libc::pid_t,
            libc::RLIMIT_FSIZE,
            &limit,
            std::ptr::null_mut(),
        )
    };
    assert_eq!(rc, 0, "prlimit: {}", std::io::Error::last_os_error());
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}");
    // stopped, not crashed: no restart, one file, reported failed
    assert_eq!(summary["role_restarts"], 0, "{summary}");
    let rec = &summary["recording"];
    assert_eq!(rec["failed"], true, "{summary}");
    assert_eq!(rec["files"], serde_json::json!([file.to_str().unwrap()]));
    assert!(rec["dropped"].as_u64().unwrap() > 0, "{summary}");
    // one error line naming the file and the cause
    let log = std::fs::read_to_string(dir.0.join("run/logs/recorder.log")).unwrap();
    let lines: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("recording stopped"))
        .collect();
    assert_eq!(lines.len(), 1, "{log}");
    assert!(
        lines[0].contains(file.to_str().unwrap()) && lines[0].contains("too large"),
        "{}",
        lines[0]
    );
    // what was written before the limit reads back
    let read = read_back(&file);
    assert_eq!(read["complete"], false, "{read}");
    assert_well_formed(&read, "the cut-off recording");
    assert!(count(&read, "heartbeat") > 0, "{read}");
}
