//! A mission flown with its eyes on decoded video (the short hop: the video, not the route,
//! is the subject): the camera role is the
//! `gstreamer` variant on an RTP/H.264 stream, and the stream comes from a second process,
//! `aeris scene video --follow`, that renders the scene at the flying vehicle's telemetry pose
//! every frame (a simulated FPV transmitter). The loop closes through telemetry → renderer →
//! x264 → UDP → avdec_h264 → `camera/rgb`. Mid-flight the video is cut (the transmitter is
//! killed): the camera reports the stall (`degraded`) and the flight goes on; a new
//! transmitter restores the video and the camera publishes again without a restart. The
//! flight must reach its goal with no setpoint refused and no role restarted, and the
//! transmitter must have rendered at the vehicle's pose. A second flight replaces the
//! geometric perception (which needs depth) by RGB-only roles, so S_t itself is built
//! from the decoded video.

use aeris_runtime::FlightBus;
use aeris_schemas::{CameraCounters, RoleStatus, topics};
use aeris_tests::*;
use std::process::{Command, Stdio};
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(900);

/// The default workflow with its camera the `gstreamer` variant on an RTP/H.264 stream
/// arriving at UDP `port`.
fn video_workflow(port: u16) -> toml::Table {
    let mut workflow = default_workflow();
    set_variant(&mut workflow, "camera", "gstreamer");
    let pipeline = format!(
        "udpsrc port={port} caps=\"application/x-rtp,media=video,clock-rate=90000,\
         encoding-name=H264,payload=96\" ! rtph264depay ! avdec_h264 ! appsink sync=false"
    );
    let camera = workflow["roles"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .filter_map(|r| r.as_table_mut())
        .find(|r| r.get("name").and_then(|n| n.as_str()) == Some("camera"))
        .unwrap();
    let mut params = toml::Table::new();
    params.insert("pipeline".into(), toml::Value::String(pipeline));
    camera.insert("params".into(), toml::Value::Table(params));
    workflow
}

/// A node on `flight`'s bus, once the flight is up.
fn join_flight(flight: &str) -> FlightBus {
    poll_until(Duration::from_secs(120), || {
        aeris_runtime::bus::list_flights()
            .iter()
            .any(|f| f == flight)
            .then(|| {
                FlightBus::builder(flight)
                    .node_name("test-observer")
                    .create()
                    .ok()
            })
            .flatten()
    })
    .expect("the flight starts")
}

#[test]
fn a_mission_flies_on_decoded_video_from_a_following_transmitter() {
    let dir = TempDir::new("flight-video");
    let flight = unique_flight("flight-video");
    let port = free_udp_port();
    let mut workflow = video_workflow(port);
    short_hop(&mut workflow);
    let path = write_workflow(&dir.0, "video", &workflow);

    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let tx_log = dir.0.join("transmitter.stderr");
    let tx_out = dir.0.join("transmitter.stdout");
    let transmitter = || {
        ChildGuard::spawn(
            Command::new(aeris_bin())
                .args(["scene", "video", "village", "--follow", &flight])
                .arg("--udp")
                .arg(format!("127.0.0.1:{port}"))
                .stdin(Stdio::null())
                .stdout(std::fs::File::create(&tx_out).unwrap())
                .stderr(std::fs::File::create(&tx_log).unwrap()),
        )
        .unwrap()
    };
    let mut tx = Some(transmitter());

    // the camera's heartbeats: frames published from the decoded stream
    let observer = join_flight(&flight);
    let heartbeats = observer.subscriber::<topics::Heartbeat>().unwrap();
    // phases: 0 video up; 1 cut (transmitter killed), waiting for the stall; 2 stalled,
    // transmitter restarted, waiting for frames again; 3 restored
    let mut phase = 0;
    let (mut camera_frames, mut camera_status, mut frames_at_cut) = (0, 0u8, 0);
    let start = std::time::Instant::now();
    let status = loop {
        heartbeats
            .drain(|h| {
                if h.role.as_str_lossy() == "camera" {
                    camera_frames =
                        camera_frames.max(CameraCounters::from_heartbeat(&h.counters).rgb_frames);
                    camera_status = h.status;
                }
            })
            .unwrap();
        match phase {
            0 if camera_frames >= 30 => {
                tx = None; // SIGKILL: the video stops mid-stream
                frames_at_cut = camera_frames;
                phase = 1;
            }
            1 if camera_status == RoleStatus::Degraded as u8 => {
                tx = Some(transmitter());
                phase = 2;
            }
            2 if camera_frames > frames_at_cut + 10
                && camera_status == RoleStatus::Running as u8 =>
            {
                phase = 3;
            }
            _ => {}
        }
        if let Ok(Some(s)) = run.0.try_wait() {
            break Some(s);
        }
        if start.elapsed() > FLIGHT_BOUND {
            break None;
        }
        // polling interval of the heartbeat reader, not a synchronisation
        std::thread::sleep(Duration::from_millis(200));
    };
    let (stdout, stderr) = run_output(&dir.0);
    let status = status.unwrap_or_else(|| panic!("flight did not finish\n{stderr}"));
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(
        summary["reached_goal"],
        true,
        "{summary}\n{stderr}\n{}",
        run_logs_tail(&dir.0, 20)
    );
    assert_eq!(
        phase,
        3,
        "video cut and restored during the flight (camera frames {camera_frames}, at the cut \
         {frames_at_cut})\n{}",
        run_logs_tail(&dir.0, 20)
    );
    assert_eq!(summary["controller_refused_setpoints"], 0, "{summary}");
    assert_eq!(summary["role_restarts"], 0, "{summary}");
    let camera_log = run_logs_tail(&dir.0, 200);
    assert!(camera_log.contains("`pipeline` stalled"), "{camera_log}");
    assert!(camera_log.contains("`pipeline` resumed"), "{camera_log}");
    // and the flight says so as it happens
    assert!(
        stderr.contains("role `camera` is degraded")
            && stderr.contains("role `camera` runs normally again"),
        "{stderr}"
    );
    // the second transmitter ends with its flight and says how many frames it rendered at
    // the vehicle's pose
    let mut tx = tx.expect("the second transmitter");
    let tx_status = wait_bounded(&mut tx.0, Duration::from_secs(60));
    let tx_stdout = std::fs::read_to_string(&tx_out).unwrap_or_default();
    let tx_stderr = std::fs::read_to_string(&tx_log).unwrap_or_default();
    assert!(
        tx_status.is_some_and(|s| s.success()),
        "transmitter: {tx_status:?}\n{tx_stdout}{tx_stderr}"
    );
    let posed: u64 = tx_stdout
        .split(" frames (")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(
        posed > 0,
        "no frame rendered at the vehicle's pose: {tx_stdout}"
    );
}

/// The model perception on the decoded stream: the geometric perception (which needs depth)
/// is replaced by roles that read RGB alone, the PP-OCR text reader and the palette detector,
/// joined by compose; S_t is built from the decoded frames (text or detections in it, its
/// occupancy absent), the hub gates every commit without occupancy, and the mission reaches
/// its goal.
#[test]
fn rgb_perception_builds_s_t_from_the_decoded_video_and_the_mission_reaches_its_goal() {
    let dir = TempDir::new("flight-video-rgb");
    let flight = unique_flight("flight-video-rgb");
    let port = free_udp_port();
    let mut workflow = video_workflow(port);
    // S_t from decoded video is the subject: a short hop
    short_hop(&mut workflow);
    let roles = workflow["roles"].as_array_mut().unwrap();
    roles.retain(|r| r.get("name").and_then(|n| n.as_str()) != Some("perception"));
    for (name, kind, variant) in [
        ("text", "text-reader", "ppocr"),
        ("detector", "detector", "palette"),
        ("scene", "image-to-text", "compose"),
    ] {
        let mut role = toml::Table::new();
        role.insert("name".into(), name.into());
        role.insert("kind".into(), kind.into());
        role.insert("variant".into(), variant.into());
        role.insert("executor".into(), "perception".into());
        if kind == "image-to-text" {
            // the blocks there are: text and detections (no depth, so no occupancy)
            let topics = vec![
                toml::Value::from("perception/text"),
                toml::Value::from("perception/detections"),
            ];
            role.insert("subscribes".into(), toml::Value::Array(topics));
        }
        roles.push(toml::Value::Table(role));
    }
    let path = write_workflow(&dir.0, "video-rgb", &workflow);
    let mut run = spawn_run(&dir.0, &flight, &[path.to_str().unwrap()]);
    let _tx = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["scene", "video", "village", "--follow", &flight])
            .arg("--udp")
            .arg(format!("127.0.0.1:{port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null()),
    )
    .unwrap();
    let observer = join_flight(&flight);
    let states = observer.subscriber::<topics::PerceptionState>().unwrap();
    let (mut seen, mut with_content, mut with_occupancy) = (0u64, 0u64, 0u64);
    let start = std::time::Instant::now();
    let status = loop {
        states
            .drain(|s| {
                seen += 1;
                let blocks = aeris_schemas::block::TEXT | aeris_schemas::block::DETECTIONS;
                if s.frame_seq > 0
                    && s.blocks & blocks != 0
                    && (s.detection_count > 0 || !s.summary.is_empty())
                {
                    with_content += 1;
                }
                if s.occupancy.is_present() {
                    with_occupancy += 1;
                }
            })
            .unwrap();
        if let Ok(Some(s)) = run.0.try_wait() {
            break Some(s);
        }
        if start.elapsed() > FLIGHT_BOUND {
            break None;
        }
        // polling interval of the state reader, not a synchronisation
        std::thread::sleep(Duration::from_millis(200));
    };
    let (stdout, stderr) = run_output(&dir.0);
    let status = status.unwrap_or_else(|| panic!("flight did not finish\n{stderr}"));
    let logs = run_logs_tail(&dir.0, 20);
    assert!(
        status.success(),
        "aeris run failed: {status}\n{stderr}\n{logs}"
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{logs}");
    // the figure of how soon the stack decides on the video once it starts was taken
    assert!(
        summary["first_decision_on_video_s"]
            .as_f64()
            .is_some_and(|s| s > 0.0),
        "{summary}"
    );
    assert!(
        with_content > 0,
        "no S_t with text or detections from the decoded video ({seen} seen)\n{logs}"
    );
    assert_eq!(with_occupancy, 0, "no depth, so no occupancy");
    assert!(
        summary["commits_without_occupancy"].as_u64().unwrap_or(0) > 0,
        "{summary}"
    );
}
