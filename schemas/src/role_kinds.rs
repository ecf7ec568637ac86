//! The role kinds: what a workflow's `kind = "..."` names, and what each kind is: the
//! variants this build can run, the topics it reads and writes, whether it can be
//! hot-swapped. The supervisor validates workflows against it, hosts' agents admit roles by
//! it, and `aeris role` dispatches on it (the runners are the binary's, one per variant).

use crate::topics;

/// A role kind, as written in workflow files and role specs (`text-reader`, `hub`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(rename_all = "kebab-case")
)]
pub enum RoleKind {
    /// `vehicle`.
    Vehicle,
    /// `camera`.
    Camera,
    /// `perception`.
    Perception,
    /// `text-reader`.
    TextReader,
    /// `detector`.
    Detector,
    /// `cues`.
    Cues,
    /// `occupancy`.
    Occupancy,
    /// `image-to-text`.
    ImageToText,
    /// `reasoning`.
    Reasoning,
    /// `hub`.
    Hub,
    /// `controller`.
    Controller,
    /// `recorder`.
    Recorder,
    /// `bridge`.
    Bridge,
    /// `replay`.
    Replay,
    /// `formation`.
    Formation,
}

/// What a role kind is: its variants, its ports, its swap policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RoleKindInfo {
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
    /// Topics it exchanges with tools outside the flight (`aeris formation say`), not with
    /// other roles: the flight's graph leaves them out.
    pub with_tools: &'static [&'static str],
    /// What it does, for `--help` and errors.
    pub summary: &'static str,
    /// `None`: a running role of this kind can be hot-swapped make-before-break (old and new
    /// process overlap, publishing the same topics for a moment). `Some(why)`: it cannot.
    pub swap_refusal: Option<&'static str>,
}

impl RoleKind {
    /// Every role kind this build knows, in the order `aeris roles` lists them.
    pub const ALL: [RoleKind; 15] = [
        RoleKind::Vehicle,
        RoleKind::Camera,
        RoleKind::Perception,
        RoleKind::TextReader,
        RoleKind::Detector,
        RoleKind::Cues,
        RoleKind::Occupancy,
        RoleKind::ImageToText,
        RoleKind::Reasoning,
        RoleKind::Hub,
        RoleKind::Controller,
        RoleKind::Recorder,
        RoleKind::Bridge,
        RoleKind::Replay,
        RoleKind::Formation,
    ];

    /// Its name in workflow files and specs.
    pub const fn name(self) -> &'static str {
        match self {
            RoleKind::Vehicle => "vehicle",
            RoleKind::Camera => "camera",
            RoleKind::Perception => "perception",
            RoleKind::TextReader => "text-reader",
            RoleKind::Detector => "detector",
            RoleKind::Cues => "cues",
            RoleKind::Occupancy => "occupancy",
            RoleKind::ImageToText => "image-to-text",
            RoleKind::Reasoning => "reasoning",
            RoleKind::Hub => "hub",
            RoleKind::Controller => "controller",
            RoleKind::Recorder => "recorder",
            RoleKind::Bridge => "bridge",
            RoleKind::Replay => "replay",
            RoleKind::Formation => "formation",
        }
    }

    /// The kind named `name`, if there is one.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Every kind's name, comma-separated (for an error that lists them).
    pub fn known_names() -> String {
        Self::ALL.map(RoleKind::name).join(", ")
    }

    /// What this kind is.
    pub const fn info(self) -> &'static RoleKindInfo {
        match self {
            RoleKind::Vehicle => &RoleKindInfo {
                variants: &["sim-multirotor"],
                subscribes: &[],
                publishes: &[],
                reads_latest: &[],
                with_tools: &[],
                summary: "built-in simulated multirotor behind a MAVLink 1/2 endpoint, playing PX4 (offboard) or ArduPilot Copter (guided)",
                swap_refusal: Some("two vehicles would share one MAVLink endpoint"),
            },
            RoleKind::Camera => &RoleKindInfo {
                variants: &["sim-render", "gstreamer"],
                subscribes: &[topics::VEHICLE_TELEMETRY],
                publishes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
                reads_latest: &[],
                with_tools: &[],
                summary: "FPV frames: `sim-render` renders the built-in world at the vehicle's pose; `gstreamer` captures any GStreamer pipeline (params.pipeline, depth_pipeline)",
                swap_refusal: Some("two cameras would number the same frames twice"),
            },
            RoleKind::Perception => &RoleKindInfo {
                variants: &["geometric"],
                subscribes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
                publishes: &[topics::PERCEPTION_STATE],
                reads_latest: &[],
                with_tools: &[],
                summary: "frames -> S_t: colour-segment detections, scene summary, depth occupancy grid",
                swap_refusal: None,
            },
            RoleKind::TextReader => &RoleKindInfo {
                variants: &["ppocr"],
                subscribes: &[topics::CAMERA_RGB],
                publishes: &[topics::PERCEPTION_TEXT],
                reads_latest: &[],
                with_tools: &[],
                summary: "reads sign text in FPV frames (PP-OCRv4 detection + recognition, ONNX Runtime)",
                swap_refusal: None,
            },
            RoleKind::Detector => &RoleKindInfo {
                variants: &["yolo", "yolov8", "palette"],
                subscribes: &[topics::CAMERA_RGB, topics::CAMERA_DEPTH],
                publishes: &[topics::PERCEPTION_DETECTIONS],
                reads_latest: &[],
                with_tools: &[],
                summary: "object detections with range (YOLO COCO / YOLOv8-layout via ONNX Runtime, or palette)",
                swap_refusal: None,
            },
            RoleKind::Cues => &RoleKindInfo {
                variants: &["minilm"],
                subscribes: &[topics::PERCEPTION_TEXT, topics::PERCEPTION_DETECTIONS],
                publishes: &[topics::PERCEPTION_CUES],
                reads_latest: &[],
                with_tools: &[],
                summary: "top-k instruction cues and subgoal relevance from MiniLM sentence embeddings",
                swap_refusal: None,
            },
            RoleKind::Occupancy => &RoleKindInfo {
                variants: &["depth", "onnx"],
                subscribes: &[topics::CAMERA_DEPTH],
                publishes: &[topics::PERCEPTION_OCCUPANCY],
                reads_latest: &[],
                with_tools: &[],
                summary: "ego occupancy grid from depth (`onnx`: slot for a learned model, needs params.model)",
                swap_refusal: None,
            },
            RoleKind::ImageToText => &RoleKindInfo {
                variants: &["compose", "vlm"],
                subscribes: &[
                    topics::PERCEPTION_TEXT,
                    topics::PERCEPTION_DETECTIONS,
                    topics::PERCEPTION_CUES,
                    topics::PERCEPTION_OCCUPANCY,
                ],
                publishes: &[topics::PERCEPTION_STATE],
                reads_latest: &[],
                with_tools: &[],
                summary: "composes S_t and its scene summary from the blocks (`vlm`: no weights exist, refuses)",
                swap_refusal: None,
            },
            RoleKind::Reasoning => &RoleKindInfo {
                variants: &["planner", "garbage", "random", "smollm2", "gemma3"],
                subscribes: &[topics::PERCEPTION_STATE, topics::VEHICLE_TELEMETRY],
                publishes: &[topics::REASONING_DECISION],
                reads_latest: &[topics::HUB_SETPOINT],
                with_tools: &[],
                summary: "(S_t, G, M) -> D_t every heartbeat: planner, GGUF language models under the D_t grammar, `garbage` fault injector, `random` VLN baseline",
                swap_refusal: None,
            },
            RoleKind::Hub => &RoleKindInfo {
                variants: &["gate"],
                subscribes: &[
                    topics::REASONING_DECISION,
                    topics::PERCEPTION_STATE,
                    topics::VEHICLE_TELEMETRY,
                ],
                publishes: &[topics::HUB_SETPOINT, topics::HUB_REPORT],
                reads_latest: &[],
                with_tools: &[],
                summary: "decision gate (validate, clamp, bind), deadline, ordered delivery, ATT",
                swap_refusal: Some("two hubs would both send setpoints"),
            },
            RoleKind::Controller => &RoleKindInfo {
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
                with_tools: &[],
                summary: "tracks setpoints at the control rate and talks MAVLink 1 or 2 to a PX4 or ArduPilot autopilot; a hot standby takes the autopilot lease when the holder goes silent",
                swap_refusal: Some(
                    "a controller is replaced by its hot standby (a second controller role), not swapped",
                ),
            },
            RoleKind::Recorder => &RoleKindInfo {
                variants: &["mcap"],
                // every topic; a workflow's recorder is fitted to the topics its flight publishes
                // (`Workflow::fit_recorders`)
                subscribes: &topics::ALL,
                publishes: &[],
                reads_latest: &[],
                with_tools: &[],
                summary: "records every topic of the flight into an MCAP file (JSON and raw shared-memory bytes, images at a reduced rate); never slows the flight",
                swap_refusal: None,
            },
            RoleKind::Bridge => &RoleKindInfo {
                variants: &["zenoh"],
                // the topics that cross between two hosts move as raw bytes, given in its
                // params by the supervisor; it publishes the link's measurements itself
                subscribes: &[],
                publishes: &[topics::HOSTS_LINK],
                reads_latest: &[],
                with_tools: &[],
                summary: "carries the topics that cross between the flight's host and another host over zenoh: exact bytes, schema checked per message (added by the supervisor)",
                swap_refusal: Some(
                    "a bridge is a flight's link to another host: it restarts, it is not swapped",
                ),
            },
            RoleKind::Replay => &RoleKindInfo {
                variants: &["mcap"],
                subscribes: &[],
                publishes: &[
                    topics::CAMERA_RGB,
                    topics::CAMERA_DEPTH,
                    topics::VEHICLE_TELEMETRY,
                ],
                reads_latest: &[],
                with_tools: &[],
                summary: "the camera and the vehicle of a replayed flight: a recording's exact frames and telemetry at their recorded times (`aeris replay`)",
                swap_refusal: Some("two sources would publish the recording twice"),
            },
            RoleKind::Formation => &RoleKindInfo {
                variants: &["parser", "qwen-coder", "smollm2", "gemma3"],
                subscribes: &[topics::VEHICLE_TELEMETRY],
                publishes: &[topics::HUB_SETPOINT],
                reads_latest: &[],
                // `aeris formation say` asks to reshape the formation and reads the reply
                with_tools: &[topics::FORMATION_SAY, topics::FORMATION_REPLY],
                summary: "flies several vehicles in formation from the mission's instruction: writes a formation program (parser or a GGUF model under a grammar), checks and repairs it in simulation, then tracks every vehicle's slot at the control rate (the vehicles' `hub/setpoint`), replanning when a vehicle is lost",
                swap_refusal: Some("the program being flown lives in the formation process"),
            },
        }
    }
}

impl core::fmt::Display for RoleKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // `pad`, not `write_str`: `{:<10}` in a table aligns a kind as it did a string
        f.pad(self.name())
    }
}

/// A role kind that does not exist.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown role kind `{0}` (known: {known})", known = RoleKind::known_names())]
pub struct UnknownRoleKind(pub String);

impl core::str::FromStr for RoleKind {
    type Err = UnknownRoleKind;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::from_name(s).ok_or_else(|| UnknownRoleKind(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kind_is_read_back_from_its_name() {
        for k in RoleKind::ALL {
            assert_eq!(k.name().parse::<RoleKind>(), Ok(k));
            assert_eq!(k.to_string(), k.name());
        }
        assert_eq!(format!("[{:<6}]", RoleKind::Hub), "[hub   ]");
        let err = "gpt".parse::<RoleKind>().expect_err("no such kind");
        assert!(
            err.to_string()
                .starts_with("unknown role kind `gpt` (known: vehicle, camera")
        );
    }
}
