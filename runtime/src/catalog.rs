//! The role catalog: every role kind, its variants, and the topics it reads and writes.
//!
//! The supervisor validates workflow files against this table; the `aeris role` entry point
//! dispatches on it. Adding a variant means adding it here and to the kind's constructor.

use aeris_schemas::topics;

/// One role kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RoleKind {
    /// Kind name as written in workflow files.
    pub kind: &'static str,
    /// Variants this build can run.
    pub variants: &'static [&'static str],
    /// Topics the kind subscribes to.
    pub subscribes: &'static [&'static str],
    /// Topics the kind publishes (besides `heartbeat`, which every role publishes).
    pub publishes: &'static [&'static str],
    /// Topics the kind reads the latest sample of now and then, never waiting for one (a
    /// reasoner reads the hub's last setpoint when it starts, to resume at the hub's active
    /// step). Such a read orders nothing, so it closes no cycle in the flight's graph; it
    /// still crosses hosts like a subscription.
    pub reads_latest: &'static [&'static str],
    /// What it does, for `--help` and errors.
    pub summary: &'static str,
    /// `None`: a running role of this kind can be hot-swapped make-before-break (old and new
    /// process overlap, publishing the same topics for a moment). `Some(why)`: it cannot.
    pub swap_refusal: Option<&'static str>,
}

/// Every role kind this build knows.
pub const ROLE_KINDS: &[RoleKind] = &[
    RoleKind {
        kind: "vehicle",
        variants: &["sim-multirotor"],
        subscribes: &[],
        publishes: &[],
        reads_latest: &[],
        summary: "built-in simulated multirotor behind a MAVLink 1/2 endpoint, playing PX4 (offboard) or ArduPilot Copter (guided)",
        swap_refusal: Some("two vehicles would share one MAVLink endpoint"),
    },
    RoleKind {
        kind: "camera",
        variants: &["sim-render", "gstreamer"],
        subscribes: &[topics::VEHICLE_TELEMETRY],
        publishes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
        reads_latest: &[],
        summary: "FPV frames: `sim-render` renders the built-in world at the vehicle's pose; `gstreamer` captures any GStreamer pipeline (params.pipeline, depth_pipeline)",
        swap_refusal: Some("two cameras would number the same frames twice"),
    },
    RoleKind {
        kind: "perception",
        variants: &["geometric"],
        subscribes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
        publishes: &[topics::PERCEPTION_STATE],
        reads_latest: &[],
        summary: "frames -> S_t: colour-segment detections, scene summary, depth occupancy grid",
        swap_refusal: None,
    },
    RoleKind {
        kind: "text-reader",
        variants: &["ppocr"],
        subscribes: &[topics::CAMERA_RGB],
        publishes: &[topics::PERCEPTION_TEXT],
        reads_latest: &[],
        summary: "reads sign text in FPV frames (PP-OCRv4 detection + recognition, ONNX Runtime)",
        swap_refusal: None,
    },
    RoleKind {
        kind: "detector",
        variants: &["yolo", "yolov8", "palette"],
        subscribes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
        publishes: &[topics::PERCEPTION_DETECTIONS],
        reads_latest: &[],
        summary: "object detections with range (YOLO COCO / YOLOv8-layout via ONNX Runtime, or palette)",
        swap_refusal: None,
    },
    RoleKind {
        kind: "cues",
        variants: &["minilm"],
        subscribes: &[topics::PERCEPTION_TEXT, topics::PERCEPTION_DETECTIONS],
        publishes: &[topics::PERCEPTION_CUES],
        reads_latest: &[],
        summary: "top-k instruction cues and subgoal relevance from MiniLM sentence embeddings",
        swap_refusal: None,
    },
    RoleKind {
        kind: "occupancy",
        variants: &["depth", "onnx"],
        subscribes: &[topics::CAMERA_DEPTH],
        publishes: &[topics::PERCEPTION_OCCUPANCY],
        reads_latest: &[],
        summary: "ego occupancy grid from depth (`onnx`: slot for a learned model, needs params.model)",
        swap_refusal: None,
    },
    RoleKind {
        kind: "image-to-text",
        variants: &["compose", "vlm"],
        subscribes: &[
            topics::PERCEPTION_TEXT,
            topics::PERCEPTION_DETECTIONS,
            topics::PERCEPTION_CUES,
            topics::PERCEPTION_OCCUPANCY,
        ],
        publishes: &[topics::PERCEPTION_STATE],
        reads_latest: &[],
        summary: "composes S_t and its scene summary from the blocks (`vlm`: no weights exist, refuses)",
        swap_refusal: None,
    },
    RoleKind {
        kind: "reasoning",
        variants: &["planner", "garbage", "random", "smollm2", "gemma3"],
        subscribes: &[topics::PERCEPTION_STATE, topics::VEHICLE_TELEMETRY],
        publishes: &[topics::REASONING_DECISION],
        reads_latest: &[topics::HUB_SETPOINT],
        summary: "(S_t, G, M) -> D_t every heartbeat: planner, GGUF language models under the D_t grammar, `garbage` fault injector, `random` VLN baseline",
        swap_refusal: None,
    },
    RoleKind {
        kind: "hub",
        variants: &["gate"],
        subscribes: &[
            topics::REASONING_DECISION,
            topics::PERCEPTION_STATE,
            topics::VEHICLE_TELEMETRY,
        ],
        publishes: &[topics::HUB_SETPOINT, topics::HUB_REPORT],
        reads_latest: &[],
        summary: "decision gate (validate, clamp, bind), deadline, ordered delivery, ATT",
        swap_refusal: Some("two hubs would both send setpoints"),
    },
    RoleKind {
        kind: "controller",
        variants: &["mavlink"],
        subscribes: &[
            topics::HUB_SETPOINT,
            topics::VEHICLE_TELEMETRY,
            topics::CONTROLLER_LEASE,
        ],
        publishes: &[
            topics::VEHICLE_TELEMETRY,
            topics::CONTROLLER_LEASE,
            topics::CONTROLLER_LINK,
        ],
        reads_latest: &[],
        summary: "tracks setpoints at the control rate and talks MAVLink 1 or 2 to a PX4 or ArduPilot autopilot; a hot standby takes the autopilot lease when the holder goes silent",
        swap_refusal: Some(
            "a controller is replaced by its hot standby (a second controller role), not swapped",
        ),
    },
    RoleKind {
        kind: "recorder",
        variants: &["mcap"],
        // every topic; a workflow's recorder is fitted to the topics its flight publishes
        // (`Workflow::fit_recorders`)
        subscribes: &topics::ALL,
        publishes: &[],
        reads_latest: &[],
        summary: "records every topic of the flight into an MCAP file (JSON and raw shared-memory bytes, images at a reduced rate); never slows the flight",
        swap_refusal: None,
    },
    RoleKind {
        kind: "bridge",
        variants: &["zenoh"],
        // the topics that cross between two hosts, given in its params by the supervisor
        subscribes: &[],
        publishes: &[],
        reads_latest: &[],
        summary: "carries the topics that cross between the flight's host and another host over zenoh: exact bytes, schema checked per message (added by the supervisor)",
        swap_refusal: Some(
            "a bridge is a flight's link to another host: it restarts, it is not swapped",
        ),
    },
    RoleKind {
        kind: "replay",
        variants: &["mcap"],
        subscribes: &[],
        publishes: &[
            topics::CAMERA_RGB,
            topics::CAMERA_DEPTH,
            topics::VEHICLE_TELEMETRY,
        ],
        reads_latest: &[],
        summary: "the camera and the vehicle of a replayed flight: a recording's exact frames and telemetry at their recorded times (`aeris replay`)",
        swap_refusal: Some("two sources would publish the recording twice"),
    },
    RoleKind {
        kind: "formation",
        variants: &["parser", "qwen-coder", "smollm2", "gemma3"],
        subscribes: &[topics::VEHICLE_TELEMETRY],
        publishes: &[topics::HUB_SETPOINT],
        reads_latest: &[],
        summary: "flies several vehicles in formation from the mission's instruction: writes a formation program (parser or a GGUF model under a grammar), checks and repairs it in simulation, then tracks every vehicle's slot at the control rate (the vehicles' `hub/setpoint`), replanning when a vehicle is lost",
        swap_refusal: Some("the program being flown lives in the formation process"),
    },
];

/// The catalog entry of `kind`.
pub fn role_kind(kind: &str) -> Option<&'static RoleKind> {
    ROLE_KINDS.iter().find(|k| k.kind == kind)
}
