//! The PP-OCR text reader reads the LAKE VIEW sign off decoded video: `aeris scene video`
//! streams the village, seen from 6 m north of the sign and facing it, as RTP/H.264; the
//! `gstreamer` camera role decodes it onto `camera/rgb`; the `ppocr` text-reader role reads
//! the frames and publishes the text block on `perception/text`. Three real processes, real
//! GStreamer, the provisioned models (`aeris-models`' cache). What it reads must be what the
//! same reader reads on the frame rendered at that pose without any video in between
//! (`aeris bench models --only ppocr`, whose probe frame is that view): the words, in any
//! order of regions. (The reader makes `UIEW LAKE` of both today: the renderer's glyphs, not
//! the video, cost the `V`.)

use aeris_runtime::FlightBus;
use aeris_schemas::topics;
use aeris_tests::*;
use std::process::{Command, Stdio};
use std::time::Duration;

const BOUND: Duration = Duration::from_secs(180);

fn spawn_role(dir: &TempDir, spec: &aeris_runtime::RoleSpec) -> ChildGuard {
    let path = write_spec(&dir.0, spec);
    let log = std::fs::File::create(dir.0.join(format!("{}.log", spec.name))).unwrap();
    ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(path)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(log),
    )
    .unwrap()
}

fn logs(dir: &TempDir) -> String {
    ["camera", "text-reader", "transmitter"]
        .iter()
        .map(|n| {
            let text = std::fs::read_to_string(dir.0.join(format!("{n}.log"))).unwrap_or_default();
            let tail: Vec<&str> = text.lines().rev().take(15).collect();
            format!(
                "== {n}\n{}\n",
                tail.into_iter().rev().collect::<Vec<_>>().join("\n")
            )
        })
        .collect()
}

#[test]
fn the_text_reader_reads_the_sign_off_decoded_video() {
    let dir = TempDir::new("video-ocr");
    let flight = unique_flight("video-ocr");
    let port = free_udp_port();
    let bus = FlightBus::builder(&flight)
        .node_name("test")
        .create()
        .unwrap();
    let text = bus.subscriber::<topics::PerceptionText>().unwrap();
    let pipeline = format!(
        "udpsrc port={port} caps=\"application/x-rtp,media=video,clock-rate=90000,\
         encoding-name=H264,payload=96\" ! rtph264depay ! avdec_h264 ! appsink sync=false"
    );
    let _camera = spawn_role(
        &dir,
        &role_spec(
            &flight,
            "camera",
            aeris_schemas::RoleKind::Camera,
            "gstreamer",
            serde_json::json!({ "pipeline": pipeline }),
        ),
    );
    let _reader = spawn_role(
        &dir,
        &role_spec(
            &flight,
            "text-reader",
            aeris_schemas::RoleKind::TextReader,
            "ppocr",
            serde_json::json!({ "interval_ms": 500 }),
        ),
    );
    // the camera 4 m up (vehicle at 3.75 m + the mount), 6 m north of the sign, facing south
    let _transmitter = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["scene", "video", "village", "--path", "40,88,3.75"])
            .args(["--yaw", "180", "--hold", "600", "--udp"])
            .arg(format!("127.0.0.1:{port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.0.join("transmitter.log")).unwrap()),
    )
    .unwrap();

    // the reader on the clean render of the same view
    let out = Command::new(aeris_bin())
        .args([
            "bench", "models", "--only", "ppocr", "--runs", "1", "--json",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let clean = last_json_line(&String::from_utf8_lossy(&out.stdout));
    let expected = words(clean["rows"][0]["output"].as_str().unwrap());
    assert!(expected.contains("LAKE"), "clean render reads {expected:?}");

    let mut read = Vec::new();
    let found = poll_until(BOUND, || {
        while let Some(s) = text.next().unwrap() {
            let summary = s.summary.as_str_lossy().to_string();
            if words(&summary) == expected {
                return Some(summary);
            }
            read.push(summary);
        }
        None
    });
    assert!(
        found.is_some(),
        "the sign was not read as on the clean render ({expected:?}); read so far: {read:?}\n{}",
        logs(&dir)
    );
}

/// The upper-case words of a reading (regions joined by `" | "` or spaces).
fn words(text: &str) -> std::collections::BTreeSet<String> {
    text.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_uppercase)
        .collect()
}
