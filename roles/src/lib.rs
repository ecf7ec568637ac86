//! # aeris-roles
//!
//! The flight roles that run as their own processes (the hub lives in `aeris-hub`; the
//! simulator's roles, vehicle, camera, geometric perception and the `palette` detector
//! engine, in `aeris-sim-roles`: nothing here depends on the simulator):
//! - [`text_reader`], [`detector`], [`cues`], [`occupancy`], [`compose`]: the model-backed
//!   perception roles, each filling its block of S_t ([`vision`] holds what they share,
//!   [`depth_occupancy`] the back-projection of depth frames);
//! - [`planner`]: the deterministic reasoning variant (and a garbage-emitting fault injector);
//! - [`language`]: the language-model reasoning variants (llama.cpp, grammar-constrained);
//! - [`reasoner_io`]: what every reasoning variant does around its decision (inputs, when to
//!   decide, stamping and publishing);
//! - [`controller`]: tracks bound setpoints at the control rate over MAVLink;
//! - [`formation_role`]: the ground station of a flight of several vehicles (a formation
//!   program written, checked and flown slot by slot through every vehicle's controller);
//! - [`gstreamer_camera`]: a real camera (any GStreamer pipeline ending in an appsink);
//! - the flight recorder (kind `recorder`) is `aeris-record`'s, dispatched here.

#![deny(missing_docs)]

pub mod compose;
pub mod controller;
pub mod cues;
pub mod depth_occupancy;
pub mod detector;
pub mod formation_role;
pub mod grounding;
pub mod gstreamer_camera;
pub mod heartbeat_clock;
pub mod height_map;
pub mod language;
pub mod occupancy;
pub mod planner;
pub mod reasoner_io;
pub mod text_reader;
pub mod vision;

use aeris_runtime::{RoleError, RoleHost, RoleSpec};

/// How a role process runs: the [`RoleHost`] instantiated for one role type.
pub type RoleRunner = fn(RoleSpec) -> Result<(), RoleError>;

/// The runner of `kind`/`variant`, if this crate implements it (every kind except `hub` and
/// the simulator's roles; `aeris-sim-roles` checks that the catalog is covered).
pub fn runner(kind: &str, variant: &str) -> Option<RoleRunner> {
    let run: RoleRunner = match (kind, variant) {
        ("reasoning", "planner") => RoleHost::run::<planner::PlannerRole>,
        ("reasoning", "garbage") => RoleHost::run::<planner::GarbageRole>,
        ("reasoning", "random") => RoleHost::run::<planner::RandomRole>,
        ("reasoning", "smollm2" | "gemma3") => RoleHost::run::<language::LanguageRole>,
        ("text-reader", "ppocr") => RoleHost::run::<text_reader::TextReaderRole>,
        ("detector", "yolo" | "yolov8") => RoleHost::run::<detector::ModelDetectorRole>,
        ("cues", "minilm") => RoleHost::run::<cues::CueRole>,
        ("occupancy", "depth" | "onnx") => RoleHost::run::<occupancy::OccupancyRole>,
        ("image-to-text", "compose" | "vlm") => RoleHost::run::<compose::ComposeRole>,
        ("controller", "mavlink") => RoleHost::run::<controller::ControllerRole>,
        ("formation", "parser" | "qwen-coder" | "smollm2" | "gemma3") => {
            RoleHost::run::<formation_role::FormationRole>
        }
        ("camera", "gstreamer") => RoleHost::run::<gstreamer_camera::GstreamerCameraRole>,
        ("recorder", "mcap") => RoleHost::run::<aeris_record::RecorderRole>,
        ("replay", "mcap") => RoleHost::run::<aeris_record::replay::ReplaySource>,
        _ => return None,
    };
    Some(run)
}

/// Run the role described by `spec` in this process (the kinds [`runner`] knows).
pub fn run(spec: RoleSpec) -> Result<(), RoleError> {
    match runner(&spec.kind, &spec.variant) {
        Some(run) => run(spec),
        None => Err(aeris_runtime::ConfigError::UnknownVariant {
            kind: spec.kind,
            variant: spec.variant,
        }
        .into()),
    }
}
