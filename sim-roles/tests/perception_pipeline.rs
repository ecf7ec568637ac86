//! The camera and perception roles in one process, over real iceoryx2 services: telemetry ->
//! camera frames in shared memory -> perception state.

use aeris_runtime::{CycleOutcome, CycleReport, FlightBus, Role, RoleContext, RoleError, RoleSpec};
use aeris_schemas::kinds::DeclaredKind;
use aeris_schemas::{
    CameraCounters, FrameFormat, FrameHeader, GeometricPerceptionCounters, VehicleTelemetry, topics,
};
use aeris_sim::render::CAMERA_MOUNT_HEIGHT_M;
use aeris_sim_roles::camera::CameraRole;
use aeris_sim_roles::perception::PerceptionRole;

fn spec(flight: &str, kind: &str, variant: &str, world: &str) -> RoleSpec {
    let json = serde_json::json!({
        "flight": flight,
        "name": kind,
        "kind": kind,
        "variant": variant,
        "camera": { "width": 160, "height": 120, "fps": 10.0, "hfov_deg": 90.0 },
        "mission": {
            "instruction": "take off, fly north along the road, turn right at the red-roofed building, land by the LAKE VIEW sign",
            "world": world,
            "start": [0.0, 0.0, 0.0],
            "subgoals": [
                { "text": "take off from the helipad", "action": "takeoff", "waypoint": [0.0, 0.0, 12.0] },
                { "text": "turn right at the red-roofed building", "action": "goto", "waypoint": [62.0, 64.0, 12.0] },
                { "text": "land next to the yellow sign that says LAKE VIEW", "action": "land", "waypoint": [42.0, 88.0, 0.0] }
            ]
        }
    });
    serde_json::from_value(json).unwrap()
}

fn ctx<K: DeclaredKind>(flight: &str, kind: &str, variant: &str, world: &str) -> RoleContext<K> {
    let bus = FlightBus::builder(flight).node_name(kind).create().unwrap();
    RoleContext::new(spec(flight, kind, variant, world), bus).unwrap()
}

fn flight(tag: &str) -> String {
    format!("t-{tag}-{}", std::process::id())
}

#[test]
fn frames_from_the_camera_become_perception_states() {
    let f = flight("campipe");
    let mut cam_ctx = ctx(&f, "camera", "sim-render", "village");
    let mut per_ctx = ctx(&f, "perception", "geometric", "village");
    let tool = FlightBus::builder(&f).node_name("tool").create().unwrap();
    let mut camera = CameraRole::new(&mut cam_ctx).unwrap();
    let mut perception = PerceptionRole::new(&mut per_ctx).unwrap();
    assert_eq!(camera.period(), std::time::Duration::from_millis(100));
    assert_eq!(perception.period(), std::time::Duration::from_millis(20));
    let telemetry = tool.publisher::<topics::VehicleTelemetry>().unwrap();
    let states = tool.subscriber::<topics::PerceptionState>().unwrap();
    let rgb_frames = tool.frame_subscriber::<topics::CameraRgb>().unwrap();

    // before any telemetry: the mission start, yaw 0
    let mut report = CycleReport::default();
    assert_eq!(
        camera.cycle(&mut cam_ctx, &mut report).unwrap(),
        CycleOutcome::Worked
    );
    assert_eq!(
        CameraCounters::from_heartbeat(&report.counters).rgb_frames,
        1
    );
    {
        let frame = rgb_frames.latest().unwrap().expect("an rgb frame");
        let h = frame.user_header();
        assert_eq!(h.seq, 1);
        assert_eq!(h.camera_position, [0.0, 0.0, CAMERA_MOUNT_HEIGHT_M]);
        assert_eq!(h.camera_yaw, 0.0);
        assert_eq!(h.validate(frame.payload().len()), Ok(FrameFormat::Rgb8));
    }

    // the vehicle at 20 m south of the red-roofed building, facing north
    telemetry
        .publish(&VehicleTelemetry {
            seq: 1,
            position: [40.0, 18.0, 20.0],
            attitude: [0.05, -0.02, 0.0],
            ..VehicleTelemetry::default()
        })
        .unwrap();
    let mut report = CycleReport::default();
    camera.cycle(&mut cam_ctx, &mut report).unwrap();
    assert_eq!(
        CameraCounters::from_heartbeat(&report.counters).rgb_frames,
        2
    );

    let mut report = CycleReport::default();
    assert_eq!(
        perception.cycle(&mut per_ctx, &mut report).unwrap(),
        CycleOutcome::Worked
    );
    assert_eq!(
        GeometricPerceptionCounters::from_heartbeat(&report.counters),
        GeometricPerceptionCounters {
            states: 1,
            frames_rejected: 0
        }
    );
    let state = states.latest().unwrap().expect("a state");
    assert_eq!(state.validate(), Ok(()));
    assert_eq!(state.seq, 1);
    assert_eq!(state.frame_seq, 2, "the newest pair");
    assert_eq!(state.position, [40.0, 18.0, 20.0]);
    assert!(state.publish_ns >= state.capture_ns);
    assert!(
        state
            .detections()
            .iter()
            .any(|d| d.label.as_str() == Some("red roof") && d.range_m > 0.0),
        "{:?}",
        state.summary
    );
    assert!(
        state
            .cues()
            .iter()
            .any(|c| c.text.as_str() == Some("red roof"))
    );
    let h = state.occupancy.height_at([72.5, 18.0]).unwrap();
    assert!((h - 14.0).abs() <= 1.0, "{h}");

    // nothing new: idle; a new frame: a new state
    let mut report = CycleReport::default();
    assert_eq!(
        perception.cycle(&mut per_ctx, &mut report).unwrap(),
        CycleOutcome::Idle
    );
    camera
        .cycle(&mut cam_ctx, &mut CycleReport::default())
        .unwrap();
    perception
        .cycle(&mut per_ctx, &mut CycleReport::default())
        .unwrap();
    let state = states.latest().unwrap().expect("a second state");
    assert_eq!((state.seq, state.frame_seq), (2, 3));
}

#[test]
fn mismatched_frame_pairs_are_rejected() {
    let f = flight("perbad");
    let mut per_ctx = ctx(&f, "perception", "geometric", "village");
    let tool = FlightBus::builder(&f).node_name("tool").create().unwrap();
    let mut perception = PerceptionRole::new(&mut per_ctx).unwrap();
    let rgb = tool.frame_publisher::<topics::CameraRgb>(24).unwrap();
    let depth = tool.frame_publisher::<topics::CameraDepth>(16).unwrap();
    let states = tool.subscriber::<topics::PerceptionState>().unwrap();
    let h = FrameHeader {
        seq: 5,
        capture_ns: 10,
        width: 4,
        height: 2,
        ..FrameHeader::default()
    };
    let hd = FrameHeader {
        format: FrameFormat::DepthU16Mm as u8,
        capture_ns: 11, // not the same capture
        ..h
    };
    rgb.publish_with(&h, 24, |b| b.fill(0)).unwrap();
    depth.publish_with(&hd, 16, |b| b.fill(0)).unwrap();
    let mut report = CycleReport::default();
    assert_eq!(
        perception.cycle(&mut per_ctx, &mut report).unwrap(),
        CycleOutcome::Idle
    );
    assert_eq!(
        GeometricPerceptionCounters::from_heartbeat(&report.counters),
        GeometricPerceptionCounters {
            states: 0,
            frames_rejected: 1
        }
    );
    assert!(states.latest().unwrap().is_none());

    // a consistent pair of the next seq goes through
    let h = FrameHeader { seq: 6, ..h };
    let hd = FrameHeader {
        seq: 6,
        capture_ns: 10,
        ..hd
    };
    depth.publish_with(&hd, 16, |b| b.fill(0)).unwrap();
    rgb.publish_with(&h, 24, |b| b.fill(0)).unwrap();
    let mut report = CycleReport::default();
    assert_eq!(
        perception.cycle(&mut per_ctx, &mut report).unwrap(),
        CycleOutcome::Worked
    );
    assert_eq!(
        GeometricPerceptionCounters::from_heartbeat(&report.counters),
        GeometricPerceptionCounters {
            states: 1,
            frames_rejected: 1
        }
    );
    assert_eq!(states.latest().unwrap().unwrap().frame_seq, 6);
}

#[test]
fn an_unknown_world_is_a_config_error_naming_the_known_ones() {
    let f = flight("camworld");
    let mut c = ctx(&f, "camera", "sim-render", "atlantis");
    match CameraRole::new(&mut c) {
        Err(RoleError::Config(e)) => {
            let msg = e.to_string();
            assert!(msg.contains("atlantis") && msg.contains("village"), "{msg}")
        }
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("unknown world accepted"),
    }
}
