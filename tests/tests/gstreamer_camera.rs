//! The `gstreamer` camera as a real role process (`aeris role --spec`) on real GStreamer
//! pipelines: `videotestsrc` frames of a known solid colour arrive on `camera/rgb` at the
//! workflow's camera size (scaled from another source size, or as they are), posed at the
//! vehicle's telemetry; a pipeline that ends is restarted and publishing resumes; a pipeline
//! string GStreamer cannot parse is a configuration error that names the parameter.
//!
//! Content checks only (colours, sizes, poses, counters): no timing thresholds, no sleeps as
//! synchronisation (every wait polls for a condition under a hang guard).

use aeris_runtime::FlightBus;
use aeris_runtime::bus::{FrameSubscriber, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::{CameraCounters, FrameFormat, VehicleTelemetry, topics};
use aeris_tests::*;
use std::process::{Command, Stdio};
use std::time::Duration;

const BOUND: Duration = Duration::from_secs(60);

/// The camera mount height above the vehicle (aeris_geometry::CAMERA_MOUNT_HEIGHT_M).
const MOUNT_M: f32 = 0.25;

struct Camera {
    _dir: TempDir,
    _child: ChildGuard,
    bus: FlightBus,
    rgb: FrameSubscriber,
    log: std::path::PathBuf,
}

impl Camera {
    fn log(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

/// Start the camera role on `pipeline` in a flight of its own, with a subscriber on its
/// frames.
fn start_camera(tag: &str, params: serde_json::Value) -> Camera {
    let dir = TempDir::new(tag);
    let flight = unique_flight(tag);
    let bus = FlightBus::builder(&flight)
        .node_name("test")
        .create()
        .unwrap();
    let rgb = bus.frame_subscriber::<topics::CameraRgb>().unwrap();
    let spec = role_spec(
        &flight,
        "camera",
        aeris_schemas::RoleKind::Camera,
        "gstreamer",
        params,
    );
    let path = write_spec(&dir.0, &spec);
    let log = dir.0.join("camera.log");
    let child = ChildGuard::spawn(
        Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&path)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap()),
    )
    .unwrap();
    Camera {
        _dir: dir,
        _child: child,
        bus,
        rgb,
        log,
    }
}

/// Mean colour of an RGB frame.
fn mean_rgb(bytes: &[u8]) -> [f64; 3] {
    let mut sum = [0f64; 3];
    for px in bytes.chunks_exact(3) {
        for c in 0..3 {
            sum[c] += f64::from(px[c]);
        }
    }
    let n = (bytes.len() / 3) as f64;
    sum.map(|s| s / n)
}

/// `videotestsrc` of one solid colour (ARGB `argb`) at `w`×`h`, live.
fn solid(argb: u32, w: u32, h: u32) -> String {
    format!(
        "videotestsrc is-live=true pattern=solid-color foreground-color={argb:#010x} \
         ! video/x-raw,width={w},height={h},framerate=30/1 ! appsink sync=false"
    )
}

fn assert_solid_frames(cam: &Camera, rgb: [u8; 3], frames: usize) {
    let mut seen = 0;
    let mut last_seq = 0;
    let got = poll_until(BOUND, || {
        while let Some(f) = cam.rgb.next().unwrap() {
            let h = *f.user_header();
            assert_eq!(
                (h.width, h.height),
                (320, 240),
                "the workflow's camera size"
            );
            assert_eq!(h.format, FrameFormat::Rgb8 as u8);
            assert_eq!(f.payload().len(), 320 * 240 * 3);
            assert!(
                h.seq > last_seq,
                "seq increases: {} after {last_seq}",
                h.seq
            );
            last_seq = h.seq;
            assert!(h.capture_ns > 0 && h.capture_ns <= monotonic_ns());
            let mean = mean_rgb(f.payload());
            for c in 0..3 {
                assert!(
                    (mean[c] - f64::from(rgb[c])).abs() < 6.0,
                    "frame {} mean colour {mean:?}, expected {rgb:?}",
                    h.seq
                );
            }
            // every pixel, not only the mean: a solid frame, no borders
            let (lo, hi) = f
                .payload()
                .chunks_exact(3)
                .fold((255u8, 0u8), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
            assert!(
                hi - lo < 12,
                "frame {} is not solid: green {lo}..{hi}",
                h.seq
            );
            seen += 1;
        }
        (seen >= frames).then_some(())
    });
    assert!(
        got.is_some(),
        "only {seen} frames arrived; camera log:\n{}",
        cam.log()
    );
}

#[test]
fn a_videotestsrc_camera_publishes_scaled_frames_of_its_colour() {
    // 640x480 source, scaled to the workflow's 320x240
    let cam = start_camera(
        "gstcam-scaled",
        serde_json::json!({ "pipeline": solid(0xff20_40c0, 640, 480) }),
    );
    assert_solid_frames(&cam, [0x20, 0x40, 0xc0], 5);
    drop(cam);
    // already at the camera size: passes through the converters as it is
    let cam = start_camera(
        "gstcam-native",
        serde_json::json!({ "pipeline": solid(0xffc0_8020, 320, 240) }),
    );
    assert_solid_frames(&cam, [0xc0, 0x80, 0x20], 5);
}

#[test]
fn frames_are_posed_at_the_vehicle_telemetry_and_no_depth_is_made_up() {
    let cam = start_camera(
        "gstcam-pose",
        serde_json::json!({ "pipeline": solid(0xff00_ff00, 160, 120) }),
    );
    let depth = cam.bus.frame_subscriber::<topics::CameraDepth>().unwrap();
    let telemetry: TypedPublisher<VehicleTelemetry> =
        cam.bus.publisher::<topics::VehicleTelemetry>().unwrap();
    let at = [12.0f32, -7.5, 20.0];
    let mut seq = 0;
    // publish the pose until a frame captured after it carries it
    let header = poll_until(BOUND, || {
        seq += 1;
        let t = VehicleTelemetry {
            seq,
            stamp_ns: monotonic_ns(),
            position: at,
            attitude: [0.0, 0.0, 1.25],
            link_up: 1,
            ..VehicleTelemetry::default()
        };
        telemetry.publish(&t).unwrap();
        while let Some(f) = cam.rgb.next().unwrap() {
            let h = *f.user_header();
            if h.camera_position == [at[0], at[1], at[2] + MOUNT_M] {
                return Some(h);
            }
            // before the first telemetry: the mission start, yaw 0
            assert_eq!(h.camera_position, [0.0, 0.0, MOUNT_M], "seq {}", h.seq);
            assert_eq!(h.camera_yaw, 0.0);
        }
        None
    })
    .unwrap_or_else(|| panic!("no frame posed at the telemetry; log:\n{}", cam.log()));
    assert_eq!(header.camera_yaw, 1.25);
    assert!((header.hfov - 90f32.to_radians()).abs() < 1e-6);
    assert!(
        depth.next().unwrap().is_none(),
        "no depth_pipeline: no depth frame"
    );
}

#[test]
fn a_pipeline_that_ends_is_restarted_and_frames_come_again() {
    // 5 buffers, then end of stream: every restart brings 5 more
    let cam = start_camera(
        "gstcam-eos",
        serde_json::json!({
            "pipeline": "videotestsrc is-live=true num-buffers=5 pattern=solid-color foreground-color=0xffffffff ! appsink sync=false",
        }),
    );
    let heartbeats = cam.bus.subscriber::<topics::Heartbeat>().unwrap();
    let mut max_seq = 0;
    let counters = poll_until(BOUND, || {
        while let Some(f) = cam.rgb.next().unwrap() {
            max_seq = max_seq.max(f.user_header().seq);
        }
        let mut last = None;
        heartbeats
            .drain(|h| last = Some(CameraCounters::from_heartbeat(&h.counters)))
            .unwrap();
        // frames after two restarts: more than one run of the pipeline has been published
        last.filter(|c| c.restarts >= 2 && c.ends_of_stream >= 2 && max_seq > 10)
    })
    .unwrap_or_else(|| panic!("no restart seen (max seq {max_seq}); log:\n{}", cam.log()));
    assert!(counters.rgb_frames > 10, "frames published: {counters:?}");
    let log = cam.log();
    assert!(
        log.contains("`pipeline` reached the end of its stream"),
        "{log}"
    );
    assert!(log.contains("`pipeline` restarted"), "{log}");
}

#[test]
fn a_bad_pipeline_is_a_configuration_error_naming_the_parameter_once() {
    let dir = TempDir::new("gstcam-bad");
    let flight = unique_flight("gstcam-bad");
    for (pipeline, says) in [
        (
            "videotestsrc ! nosuchelement ! appsink",
            "no element \"nosuchelement\"",
        ),
        ("videotestsrc ! fakesink", "must end in an `appsink`"),
    ] {
        let spec = role_spec(
            &flight,
            "camera",
            aeris_schemas::RoleKind::Camera,
            "gstreamer",
            serde_json::json!({ "pipeline": pipeline }),
        );
        let path = write_spec(&dir.0, &spec);
        let mut child = Command::new(aeris_bin())
            .args(["role", "--spec"])
            .arg(&path)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let status = wait_bounded(&mut child, BOUND).expect("the role exits");
        let mut stderr = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
        assert!(!status.success());
        assert!(stderr.contains("invalid configuration"), "{stderr}");
        assert_eq!(stderr.matches("`pipeline`").count(), 1, "{stderr}");
        assert_eq!(stderr.matches(says).count(), 1, "{stderr}");
    }
}

#[test]
fn a_video_file_plays_at_its_rate_ends_and_plays_again_from_its_start() {
    // a 2 s H.264 MP4 of the open scene (10 frames at 5 fps), decoded by `decodebin`, whose
    // decoder pad appears only once the file is read: a restart must link it again
    let dir = TempDir::new("gstcam-file-video");
    let video = dir.0.join("hover.mp4");
    let rendered = Command::new(aeris_bin())
        .args(["scene", "video", "open", "--path", "0,0,10", "--hold", "2"])
        .args(["--fps", "5", "--out"])
        .arg(&video)
        .output()
        .unwrap();
    assert!(
        rendered.status.success(),
        "{}",
        String::from_utf8_lossy(&rendered.stderr)
    );
    // "wrote N frames (...)" on stdout
    let said = String::from_utf8_lossy(&rendered.stdout).into_owned();
    let per_play: u64 = said
        .split_whitespace()
        .skip_while(|w| *w != "wrote")
        .nth(1)
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("frames written: {said}"));
    let cam = start_camera(
        "gstcam-file",
        serde_json::json!({
            "pipeline": format!(
                "filesrc location=\"{}\" ! decodebin ! appsink sync=true",
                video.display()
            ),
        }),
    );
    let heartbeats = cam.bus.subscriber::<topics::Heartbeat>().unwrap();
    let mut frames = 0u64;
    let counters = poll_until(BOUND, || {
        while let Some(f) = cam.rgb.next().unwrap() {
            assert_eq!(f.payload().len(), 320 * 240 * 3);
            frames += 1;
        }
        let mut last = None;
        heartbeats
            .drain(|h| last = Some(CameraCounters::from_heartbeat(&h.counters)))
            .unwrap();
        // two restarts, and more frames than two plays of the file hold
        last.filter(|c| c.restarts >= 2 && frames > 2 * per_play)
    })
    .unwrap_or_else(|| {
        panic!(
            "the file did not play again ({frames} frames); log:\n{}",
            cam.log()
        )
    });
    assert!(
        counters.rgb_frames > 2 * per_play,
        "frames published: {counters:?}"
    );
    let log = cam.log();
    assert!(!log.contains("failed"), "{log}");
    assert!(
        log.contains("`pipeline` reached the end of its stream"),
        "{log}"
    );
}
