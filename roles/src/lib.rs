//! # aeris-roles
//!
//! The role implementations that run as their own processes (the hub lives in `aeris-hub`):
//! - [`vehicle`]: the built-in simulated multirotor behind a MAVLink endpoint;
//! - [`camera`]: renders FPV RGB + depth frames and publishes them over iceoryx2;
//! - [`perception`]: frames -> typed state S_t;
//! - [`text_reader`], [`detector`], [`cues`], [`occupancy`], [`compose`]: the model-backed
//!   perception roles, each filling its block of S_t ([`vision`] holds what they share);
//! - [`planner`]: the deterministic reasoning variant (and a garbage-emitting fault injector);
//! - [`language`]: the language-model reasoning variants (llama.cpp, grammar-constrained);
//! - [`reasoner_io`]: what every reasoning variant does around its decision (inputs, when to
//!   decide, stamping and publishing);
//! - [`controller`]: tracks bound setpoints at the control rate over MAVLink.

#![deny(missing_docs)]

pub mod camera;
pub mod compose;
pub mod controller;
pub mod cues;
pub mod detector;
pub mod grounding;
pub mod heartbeat_clock;
pub mod height_map;
pub mod language;
pub mod occupancy;
pub mod perception;
pub mod planner;
pub mod reasoner_io;
pub mod text_reader;
pub mod vehicle;
pub mod vision;

use aeris_runtime::{RoleError, RoleHost, RoleSpec};

/// How a role process runs: the [`RoleHost`] instantiated for one role type.
pub type RoleRunner = fn(RoleSpec) -> Result<(), RoleError>;

/// The runner of `kind`/`variant`, if this crate implements it (every kind except `hub`).
pub fn runner(kind: &str, variant: &str) -> Option<RoleRunner> {
    let run: RoleRunner = match (kind, variant) {
        ("vehicle", "sim-multirotor") => RoleHost::run::<vehicle::VehicleRole>,
        ("camera", "sim-render") => RoleHost::run::<camera::CameraRole>,
        ("perception", "geometric") => RoleHost::run::<perception::PerceptionRole>,
        ("reasoning", "planner") => RoleHost::run::<planner::PlannerRole>,
        ("reasoning", "garbage") => RoleHost::run::<planner::GarbageRole>,
        ("reasoning", "random") => RoleHost::run::<planner::RandomRole>,
        ("reasoning", "smollm2" | "gemma3") => RoleHost::run::<language::LanguageRole>,
        ("text-reader", "ppocr") => RoleHost::run::<text_reader::TextReaderRole>,
        ("detector", "yolo" | "yolov8" | "palette") => RoleHost::run::<detector::DetectorRole>,
        ("cues", "minilm") => RoleHost::run::<cues::CueRole>,
        ("occupancy", "depth" | "onnx") => RoleHost::run::<occupancy::OccupancyRole>,
        ("image-to-text", "compose" | "vlm") => RoleHost::run::<compose::ComposeRole>,
        ("controller", "mavlink") => RoleHost::run::<controller::ControllerRole>,
        _ => return None,
    };
    Some(run)
}

/// Run the role described by `spec` in this process (every kind except `hub`).
pub fn run(spec: RoleSpec) -> Result<(), RoleError> {
    match runner(&spec.kind, &spec.variant) {
        Some(run) => run(spec),
        None => Err(RoleError::Config(format!(
            "no role kind `{}` with variant `{}` in this build (see `aeris roles`)",
            spec.kind, spec.variant
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The catalog the supervisor validates workflows against and the dispatch that runs
    /// them must agree, or a workflow passes validation and then fails at start.
    #[test]
    fn every_catalog_variant_outside_the_hub_has_a_runner() {
        for k in aeris_runtime::catalog::ROLE_KINDS
            .iter()
            .filter(|k| k.kind != "hub")
        {
            for v in k.variants {
                assert!(
                    runner(k.kind, v).is_some(),
                    "{}/{v} is in the catalog but not dispatched",
                    k.kind
                );
            }
        }
        assert!(runner("reasoning", "gpt-9").is_none());
    }
}
