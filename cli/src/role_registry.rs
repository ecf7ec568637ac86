//! Who runs what: the one place that maps a role kind and variant to the code that runs it
//! in a role process (`aeris role --spec`). What each kind is (its variants, topics, swap
//! policy) is [`RoleKind::info`], which the supervisor validates workflows against; the
//! runners live here, at the top of the graph, because they link every role's crate: the
//! flight roles (`aeris-roles`), the hub (`aeris-hub`), the bridge (`aeris-hosts`), the
//! recorder and the replay source (`aeris-record`) and, in a build with the simulator, its
//! roles (`aeris-sim-roles`). The match is on the kind first, so a new kind does not compile
//! until it is given its runners.

use aeris_runtime::{RoleError, RoleHost, RoleSpec};
use aeris_schemas::RoleKind;

/// How a role process runs: the [`RoleHost`] instantiated for one role type.
pub type RoleRunner = fn(RoleSpec) -> Result<(), RoleError>;

/// The runner of `kind`/`variant` in this build, if it has one (a build without the
/// simulator has none for the simulator's roles).
pub fn runner(kind: RoleKind, variant: &str) -> Option<RoleRunner> {
    use aeris_roles::{
        compose, controller, cues, detector, formation_role, gstreamer_camera, language, occupancy,
        planner, text_reader,
    };
    let run: RoleRunner = match kind {
        RoleKind::Vehicle | RoleKind::Perception => return sim_runner(kind, variant),
        RoleKind::Camera => match variant {
            "gstreamer" => RoleHost::run::<gstreamer_camera::GstreamerCameraRole>,
            _ => return sim_runner(kind, variant),
        },
        RoleKind::Detector => match variant {
            "yolo" | "yolov8" => RoleHost::run::<detector::ModelDetectorRole>,
            _ => return sim_runner(kind, variant),
        },
        RoleKind::TextReader => match variant {
            "ppocr" => RoleHost::run::<text_reader::TextReaderRole>,
            _ => return None,
        },
        RoleKind::Cues => match variant {
            "minilm" => RoleHost::run::<cues::CueRole>,
            _ => return None,
        },
        RoleKind::Occupancy => match variant {
            "depth" | "onnx" => RoleHost::run::<occupancy::OccupancyRole>,
            _ => return None,
        },
        RoleKind::ImageToText => match variant {
            "compose" | "vlm" => RoleHost::run::<compose::ComposeRole>,
            _ => return None,
        },
        RoleKind::Reasoning => match variant {
            "planner" => RoleHost::run::<planner::PlannerRole>,
            "garbage" => RoleHost::run::<planner::GarbageRole>,
            "random" => RoleHost::run::<planner::RandomRole>,
            "smollm2" | "gemma3" => RoleHost::run::<language::LanguageRole>,
            _ => return None,
        },
        RoleKind::Hub => match variant {
            "gate" => RoleHost::run::<aeris_hub::HubRole>,
            _ => return None,
        },
        RoleKind::Controller => match variant {
            "mavlink" => RoleHost::run::<controller::ControllerRole>,
            _ => return None,
        },
        RoleKind::Recorder => match variant {
            "mcap" => RoleHost::run::<aeris_record::RecorderRole>,
            _ => return None,
        },
        RoleKind::Replay => match variant {
            "mcap" => RoleHost::run::<aeris_record::replay::ReplaySource>,
            _ => return None,
        },
        RoleKind::Bridge => match variant {
            "zenoh" => RoleHost::run::<aeris_hosts::bridge::BridgeRole>,
            _ => return None,
        },
        RoleKind::Formation => match variant {
            "parser" | "qwen-coder" | "smollm2" | "gemma3" => {
                RoleHost::run::<formation_role::FormationRole>
            }
            _ => return None,
        },
    };
    Some(run)
}

/// The simulator's runner of `kind`/`variant`, in a build with the simulator.
#[cfg(feature = "sim")]
fn sim_runner(kind: RoleKind, variant: &str) -> Option<RoleRunner> {
    use aeris_sim_roles::{camera, palette, perception, vehicle};
    let run: RoleRunner = match (kind, variant) {
        (RoleKind::Vehicle, "sim-multirotor") => RoleHost::run::<vehicle::VehicleRole>,
        (RoleKind::Camera, "sim-render") => RoleHost::run::<camera::CameraRole>,
        (RoleKind::Perception, "geometric") => RoleHost::run::<perception::PerceptionRole>,
        (RoleKind::Detector, "palette") => RoleHost::run::<palette::PaletteDetectorRole>,
        _ => return None,
    };
    Some(run)
}

/// A build without the simulator runs none of its roles.
#[cfg(not(feature = "sim"))]
fn sim_runner(_kind: RoleKind, _variant: &str) -> Option<RoleRunner> {
    None
}

/// Run the role `spec` describes in this process.
pub fn run(spec: RoleSpec) -> Result<(), RoleError> {
    match runner(spec.kind, &spec.variant) {
        Some(run) => run(spec),
        None => Err(aeris_runtime::ConfigError::UnknownVariant {
            kind: spec.kind,
            variant: spec.variant,
        }
        .into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kinds' variants the supervisor validates workflows against and the runners must
    /// agree, or a workflow passes validation and then fails at start: every variant of
    /// every kind has a runner (in a build with the simulator), and nothing else has one.
    #[cfg(feature = "sim")]
    #[test]
    fn every_variant_of_every_kind_has_a_runner_and_nothing_else_has_one() {
        for kind in RoleKind::ALL {
            for v in kind.info().variants {
                assert!(runner(kind, v).is_some(), "{kind}/{v} has no runner");
            }
            assert!(runner(kind, "gpt-9").is_none(), "{kind}/gpt-9 has a runner");
        }
    }

    /// Without the simulator, exactly the simulator's variants have no runner.
    #[cfg(not(feature = "sim"))]
    #[test]
    fn a_vehicle_build_runs_every_variant_but_the_simulators() {
        let simulator = [
            (RoleKind::Vehicle, "sim-multirotor"),
            (RoleKind::Camera, "sim-render"),
            (RoleKind::Perception, "geometric"),
            (RoleKind::Detector, "palette"),
        ];
        for kind in RoleKind::ALL {
            for v in kind.info().variants {
                let simulated = simulator.contains(&(kind, *v));
                assert_eq!(runner(kind, v).is_none(), simulated, "{kind}/{v}");
            }
        }
    }
}
