//! Who runs what: the one place that maps a role kind and variant to the code that runs it
//! in a role process (`aeris role --spec`). What each kind is (its variants, topics, swap
//! policy) is [`RoleKind::info`], which the supervisor validates workflows against; the
//! runners live here, at the top of the graph, because they link every role's crate: the
//! flight roles (`aeris-roles`), the hub (`aeris-hub`), the bridge (`aeris-hosts`), the
//! recorder and the replay source (`aeris-record`) and, in a build with the simulator, its
//! roles (`aeris-sim-roles`). The match is on the kind first, so a new kind does not compile
//! until it is given its runners, and each runner carries the kind its role type declares
//! (`Role::Kind`), which the tests hold to the kind it runs for.

use aeris_runtime::{Role, RoleError, RoleHost, RoleSpec};
use aeris_schemas::RoleKind;
use aeris_schemas::kinds::DeclaredKind;

/// How a role process runs: the [`RoleHost`] instantiated for one role type, and the kind
/// that type declares it is.
#[derive(Clone, Copy)]
pub struct RoleRunner {
    /// The kind of the role type ([`Role::Kind`]); the tests hold it to the kind the
    /// runner is registered for (a role process checks it again from its spec).
    #[cfg_attr(not(test), allow(dead_code))]
    pub kind: RoleKind,
    /// Runs it in this process.
    pub run: fn(RoleSpec) -> Result<(), RoleError>,
}

impl RoleRunner {
    /// The runner of role type `R`.
    fn of<R: Role>() -> Self {
        Self {
            kind: <R::Kind as DeclaredKind>::KIND,
            run: RoleHost::run::<R>,
        }
    }
}

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
            "gstreamer" => RoleRunner::of::<gstreamer_camera::GstreamerCameraRole>(),
            _ => return sim_runner(kind, variant),
        },
        RoleKind::Detector => match variant {
            "yolo" | "yolov8" => RoleRunner::of::<detector::ModelDetectorRole>(),
            _ => return sim_runner(kind, variant),
        },
        RoleKind::TextReader => match variant {
            "ppocr" => RoleRunner::of::<text_reader::TextReaderRole>(),
            _ => return None,
        },
        RoleKind::Cues => match variant {
            "minilm" => RoleRunner::of::<cues::CueRole>(),
            _ => return None,
        },
        RoleKind::Occupancy => match variant {
            "depth" | "onnx" => RoleRunner::of::<occupancy::OccupancyRole>(),
            _ => return None,
        },
        RoleKind::ImageToText => match variant {
            "compose" | "vlm" => RoleRunner::of::<compose::ComposeRole>(),
            _ => return None,
        },
        RoleKind::Reasoning => match variant {
            "planner" => RoleRunner::of::<planner::PlannerRole>(),
            "garbage" => RoleRunner::of::<planner::GarbageRole>(),
            "random" => RoleRunner::of::<planner::RandomRole>(),
            "smollm2" | "gemma3" | "smollm2-aligned" => RoleRunner::of::<language::LanguageRole>(),
            _ => return None,
        },
        RoleKind::Hub => match variant {
            "gate" => RoleRunner::of::<aeris_hub::HubRole>(),
            _ => return None,
        },
        RoleKind::Controller => match variant {
            "mavlink" => RoleRunner::of::<controller::ControllerRole>(),
            _ => return None,
        },
        RoleKind::Recorder => match variant {
            "mcap" => RoleRunner::of::<aeris_record::RecorderRole>(),
            _ => return None,
        },
        RoleKind::Replay => match variant {
            "mcap" => RoleRunner::of::<aeris_record::replay::ReplaySource>(),
            _ => return None,
        },
        RoleKind::Bridge => match variant {
            "zenoh" => RoleRunner::of::<aeris_hosts::bridge::BridgeRole>(),
            _ => return None,
        },
        RoleKind::Formation => match variant {
            "parser" | "qwen-coder" | "smollm2" | "gemma3" => {
                RoleRunner::of::<formation_role::FormationRole>()
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
        (RoleKind::Vehicle, "sim-multirotor") => RoleRunner::of::<vehicle::VehicleRole>(),
        (RoleKind::Camera, "sim-render") => RoleRunner::of::<camera::CameraRole>(),
        (RoleKind::Perception, "geometric") => RoleRunner::of::<perception::PerceptionRole>(),
        (RoleKind::Detector, "palette") => RoleRunner::of::<palette::PaletteDetectorRole>(),
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
        Some(runner) => (runner.run)(spec),
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
                let r = runner(kind, v).unwrap_or_else(|| panic!("{kind}/{v} has no runner"));
                assert_eq!(r.kind, kind, "{kind}/{v} runs a role of another kind");
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
                let r = runner(kind, v);
                assert_eq!(r.is_none(), simulated, "{kind}/{v}");
                assert!(r.is_none_or(|r| r.kind == kind), "{kind}/{v}: another kind");
            }
        }
    }
}
