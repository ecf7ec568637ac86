//! Every role kind as a type, declaring the topics it reads and writes: the one place a
//! kind's ports are written down. A role names its kind (`type Kind = kinds::Hub` on its
//! `Role` impl) and can open a port only on a topic its kind declares: `Publishes<T>` and
//! `Subscribes<T>` are implemented here for the topics of `schemas` (and the kinds are
//! sealed: no other crate declares one), so an undeclared port is a compile error. The flight's graph (the supervisor's wiring, the bridge's plan, the recorder's
//! topics, `aeris roles`) reads the same declarations through [`RoleKind::info`].

use crate::role_kinds::{RoleKind, RoleKindInfo};
use crate::topics::{self, Topic};

mod sealed {
    /// Only this module's kinds are kinds: a crate cannot declare a kind of its own with
    /// other ports.
    pub trait Sealed {}
}

/// A role kind as a type: its [`RoleKind`] and what it is (implemented here only).
pub trait DeclaredKind: sealed::Sealed + 'static {
    /// The kind's name in workflows.
    const KIND: RoleKind;
    /// Its variants, ports and swap policy.
    const INFO: RoleKindInfo;
}

/// The kind publishes topic `T` (to other roles or to tools).
pub trait Publishes<T: Topic>: DeclaredKind {}

/// The kind subscribes to topic `T` (waits on it, reads the latest of it, or takes it from
/// a tool).
pub trait Subscribes<T: Topic>: DeclaredKind {}

/// The kind moves topics as raw bytes, named at run time (the recorder, the bridge): it may
/// reach the whole flight bus.
pub trait RawPorts: DeclaredKind {}

/// The name of topic `T`, in a const context.
const fn name<T: Topic>() -> &'static str {
    T::INFO.name
}

macro_rules! declare_kinds {
    ($(
        $(#[$doc:meta])*
        $kind:ident {
            variants: $variants:expr,
            subscribes: [$($sub:ident),* $(,)?],
            publishes: [$($publ:ident),* $(,)?],
            reads_latest: [$($latest:ident),* $(,)?],
            from_tools: [$($tool_in:ident),* $(,)?],
            to_tools: [$($tool_out:ident),* $(,)?],
            summary: $summary:expr,
            swap_refusal: $refusal:expr $(,)?
        }
    )*) => {$(
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
        pub struct $kind;

        impl sealed::Sealed for $kind {}
        impl DeclaredKind for $kind {
            const KIND: RoleKind = RoleKind::$kind;
            const INFO: RoleKindInfo = RoleKindInfo {
                variants: $variants,
                subscribes: &[$(name::<topics::$sub>()),*],
                publishes: &[$(name::<topics::$publ>()),*],
                reads_latest: &[$(name::<topics::$latest>()),*],
                with_tools: &[$(name::<topics::$tool_in>(),)* $(name::<topics::$tool_out>()),*],
                summary: $summary,
                swap_refusal: $refusal,
            };
        }
        $(impl Subscribes<topics::$sub> for $kind {})*
        $(impl Subscribes<topics::$latest> for $kind {})*
        $(impl Subscribes<topics::$tool_in> for $kind {})*
        $(impl Publishes<topics::$publ> for $kind {})*
        $(impl Publishes<topics::$tool_out> for $kind {})*
    )*};
}

declare_kinds! {
    /// `vehicle`: the built-in simulated multirotor (its MAVLink endpoint is its only port).
    Vehicle {
        variants: &["sim-multirotor"],
        subscribes: [],
        publishes: [],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "built-in simulated multirotor behind a MAVLink 1/2 endpoint, playing PX4 (offboard) or ArduPilot Copter (guided)",
        swap_refusal: Some("two vehicles would share one MAVLink endpoint"),
    }
    /// `camera`: FPV frames.
    Camera {
        variants: &["sim-render", "gstreamer"],
        subscribes: [VehicleTelemetry],
        publishes: [CameraRgb, CameraDepth],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "FPV frames: `sim-render` renders the built-in world at the vehicle's pose; `gstreamer` captures any GStreamer pipeline (params.pipeline, depth_pipeline)",
        swap_refusal: Some("two cameras would number the same frames twice"),
    }
    /// `perception`: frames to S_t in one role.
    Perception {
        variants: &["geometric"],
        subscribes: [CameraRgb, CameraDepth],
        publishes: [PerceptionState],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "frames -> S_t: colour-segment detections, scene summary, depth occupancy grid",
        swap_refusal: None,
    }
    /// `text-reader`: the scene-text block of S_t.
    TextReader {
        variants: &["ppocr"],
        subscribes: [CameraRgb],
        publishes: [PerceptionText],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "reads sign text in FPV frames (PP-OCRv4 detection + recognition, ONNX Runtime)",
        swap_refusal: None,
    }
    /// `detector`: the detection block of S_t.
    Detector {
        variants: &["yolo", "yolov8", "palette"],
        subscribes: [CameraRgb, CameraDepth],
        publishes: [PerceptionDetections],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "object detections with range (YOLO COCO / YOLOv8-layout via ONNX Runtime, or palette)",
        swap_refusal: None,
    }
    /// `cues`: the cue block of S_t.
    Cues {
        variants: &["minilm"],
        subscribes: [PerceptionText, PerceptionDetections],
        publishes: [PerceptionCues],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "top-k instruction cues and subgoal relevance from MiniLM sentence embeddings",
        swap_refusal: None,
    }
    /// `occupancy`: the occupancy block of S_t.
    Occupancy {
        variants: &["depth", "onnx"],
        subscribes: [CameraDepth],
        publishes: [PerceptionOccupancy],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "ego occupancy grid from depth (`onnx`: slot for a learned model, needs params.model)",
        swap_refusal: None,
    }
    /// `image-to-text`: composes S_t from the blocks.
    ImageToText {
        variants: &["compose", "vlm"],
        subscribes: [PerceptionText, PerceptionDetections, PerceptionCues, PerceptionOccupancy],
        publishes: [PerceptionState],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "composes S_t and its scene summary from the blocks (`vlm`: no weights exist, refuses)",
        swap_refusal: None,
    }
    /// `reasoning`: D_t every heartbeat. It reads the hub's last setpoint when it starts (to
    /// resume at the hub's active step) without waiting for one: no cycle in the graph.
    Reasoning {
        variants: &["planner", "garbage", "random", "smollm2", "gemma3", "smollm2-aligned"],
        subscribes: [PerceptionState, VehicleTelemetry],
        publishes: [ReasoningDecision],
        reads_latest: [HubSetpoint],
        from_tools: [],
        to_tools: [],
        summary: "(S_t, G, M) -> D_t every heartbeat: planner, GGUF language models under the D_t grammar (`smollm2-aligned`: SmolLM2 with its task-aligned LoRA adapter, no plan), `garbage` fault injector, `random` VLN baseline",
        swap_refusal: None,
    }
    /// `hub`: the decision gate.
    Hub {
        variants: &["gate"],
        subscribes: [ReasoningDecision, PerceptionState, VehicleTelemetry],
        publishes: [HubSetpoint, HubReport],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "decision gate (validate, clamp, bind), deadline, ordered delivery, ATT",
        swap_refusal: Some("two hubs would both send setpoints"),
    }
    /// `controller`: setpoints to MAVLink at the control rate.
    Controller {
        variants: &["mavlink"],
        subscribes: [HubSetpoint, VehicleTelemetry, ControllerLease],
        publishes: [VehicleTelemetry, ControllerLease, ControllerLink],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "tracks setpoints at the control rate and talks MAVLink 1 or 2 to a PX4 or ArduPilot autopilot; a hot standby takes the autopilot lease when the holder goes silent",
        swap_refusal: Some(
            "a controller is replaced by its hot standby (a second controller role), not swapped",
        ),
    }
    /// `replay`: a recording's camera and vehicle.
    Replay {
        variants: &["mcap"],
        subscribes: [],
        publishes: [CameraRgb, CameraDepth, VehicleTelemetry],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "the camera and the vehicle of a replayed flight: a recording's exact frames and telemetry at their recorded times (`aeris replay`)",
        swap_refusal: Some("two sources would publish the recording twice"),
    }
    /// `formation`: several vehicles in formation; `aeris formation say` asks it to reshape
    /// the formation and reads its reply.
    Formation {
        variants: &["parser", "qwen-coder", "smollm2", "gemma3"],
        subscribes: [VehicleTelemetry],
        publishes: [HubSetpoint],
        reads_latest: [],
        from_tools: [FormationSay],
        to_tools: [FormationReply],
        summary: "flies several vehicles in formation from the mission's instruction: writes a formation program (parser or a GGUF model under a grammar), checks and repairs it in simulation, then tracks every vehicle's slot at the control rate (the vehicles' `hub/setpoint`), replanning when a vehicle is lost",
        swap_refusal: Some("the program being flown lives in the formation process"),
    }
    /// `bridge`: the topics that cross between two hosts, as raw bytes named in its params
    /// by the supervisor ([`RawPorts`]); it publishes the link's measurements itself.
    Bridge {
        variants: &["zenoh"],
        subscribes: [],
        publishes: [HostsLink],
        reads_latest: [],
        from_tools: [],
        to_tools: [],
        summary: "carries the topics that cross between the flight's host and another host over zenoh: exact bytes, schema checked per message (added by the supervisor)",
        swap_refusal: Some(
            "a bridge is a flight's link to another host: it restarts, it is not swapped",
        ),
    }
}

impl RawPorts for Bridge {}

/// `recorder`: every topic of the flight as raw bytes ([`RawPorts`]); a workflow's recorder
/// is fitted to the topics its flight publishes (`Workflow::fit_recorders`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Recorder;

impl sealed::Sealed for Recorder {}
impl DeclaredKind for Recorder {
    const KIND: RoleKind = RoleKind::Recorder;
    const INFO: RoleKindInfo = RoleKindInfo {
        variants: &["mcap"],
        subscribes: &topics::ALL,
        publishes: &[],
        reads_latest: &[],
        with_tools: &[],
        summary: "records every topic of the flight into an MCAP file (JSON and raw shared-memory bytes, images at a reduced rate); never slows the flight",
        swap_refusal: None,
    };
}

impl RawPorts for Recorder {}

impl RoleKind {
    /// What this kind is (its [`DeclaredKind::INFO`]).
    pub const fn info(self) -> &'static RoleKindInfo {
        match self {
            RoleKind::Vehicle => &<Vehicle as DeclaredKind>::INFO,
            RoleKind::Camera => &<Camera as DeclaredKind>::INFO,
            RoleKind::Perception => &<Perception as DeclaredKind>::INFO,
            RoleKind::TextReader => &<TextReader as DeclaredKind>::INFO,
            RoleKind::Detector => &<Detector as DeclaredKind>::INFO,
            RoleKind::Cues => &<Cues as DeclaredKind>::INFO,
            RoleKind::Occupancy => &<Occupancy as DeclaredKind>::INFO,
            RoleKind::ImageToText => &<ImageToText as DeclaredKind>::INFO,
            RoleKind::Reasoning => &<Reasoning as DeclaredKind>::INFO,
            RoleKind::Hub => &<Hub as DeclaredKind>::INFO,
            RoleKind::Controller => &<Controller as DeclaredKind>::INFO,
            RoleKind::Recorder => &<Recorder as DeclaredKind>::INFO,
            RoleKind::Bridge => &<Bridge as DeclaredKind>::INFO,
            RoleKind::Replay => &<Replay as DeclaredKind>::INFO,
            RoleKind::Formation => &<Formation as DeclaredKind>::INFO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_type_names_its_kind_and_every_kind_has_one() {
        let kinds = [
            Vehicle::KIND,
            Camera::KIND,
            Perception::KIND,
            TextReader::KIND,
            Detector::KIND,
            Cues::KIND,
            Occupancy::KIND,
            ImageToText::KIND,
            Reasoning::KIND,
            Hub::KIND,
            Controller::KIND,
            Recorder::KIND,
            Bridge::KIND,
            Replay::KIND,
            Formation::KIND,
        ];
        assert_eq!(kinds, RoleKind::ALL);
        assert_eq!(
            Reasoning::INFO.reads_latest,
            [topics::HUB_SETPOINT],
            "declared by type, read by name"
        );
        assert_eq!(
            Formation::INFO.with_tools,
            [topics::FORMATION_SAY, topics::FORMATION_REPLY]
        );
    }
}
