//! # aeris-sim-roles
//!
//! The roles that exist because a flight runs in the built-in simulator, beside it and out
//! of the flight roles (`aeris-roles` and `aeris-hub` do not depend on `aeris-sim`):
//! - [`vehicle`]: the simulated multirotor behind its PX4-like MAVLink endpoint;
//! - [`camera`]: renders FPV RGB + depth frames of the mission's world;
//! - [`perception`]: the geometric perception, which segments frames by the simulator's
//!   colour palette;
//! - [`palette`]: the same segmentation as the detector role's `palette` engine.
//!
//! `aeris role` runs a spec with [`runner`] here when it names one of these, and with
//! `aeris_roles::runner` otherwise (the hub with `aeris_hub`).

#![deny(missing_docs)]

pub mod camera;
pub mod palette;
pub mod perception;
pub mod vehicle;

use aeris_roles::RoleRunner;
use aeris_runtime::RoleHost;

/// The runner of `kind`/`variant`, if it is one of the simulator's roles.
pub fn runner(kind: &str, variant: &str) -> Option<RoleRunner> {
    let run: RoleRunner = match (kind, variant) {
        ("vehicle", "sim-multirotor") => RoleHost::run::<vehicle::VehicleRole>,
        ("camera", "sim-render") => RoleHost::run::<camera::CameraRole>,
        ("perception", "geometric") => RoleHost::run::<perception::PerceptionRole>,
        ("detector", "palette") => RoleHost::run::<palette::PaletteDetectorRole>,
        _ => return None,
    };
    Some(run)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The catalog the supervisor validates workflows against and the dispatch that runs
    /// them must agree, or a workflow passes validation and then fails at start: every
    /// variant outside the hub and the bridge (run by `aeris-hub` and `aeris-hosts`) has a
    /// runner here or in `aeris-roles`, and never in both (the binary would run one of them
    /// silently).
    #[test]
    fn every_catalog_variant_outside_the_hub_has_exactly_one_runner() {
        for k in aeris_runtime::catalog::ROLE_KINDS
            .iter()
            .filter(|k| k.kind != "hub" && k.kind != "bridge")
        {
            for v in k.variants {
                let here = runner(k.kind, v).is_some();
                let roles = aeris_roles::runner(k.kind, v).is_some();
                assert!(
                    here || roles,
                    "{}/{v} is in the catalog but not dispatched",
                    k.kind
                );
                assert!(
                    !(here && roles),
                    "{}/{v} is dispatched by aeris-roles and aeris-sim-roles",
                    k.kind
                );
            }
        }
        assert!(runner("reasoning", "gpt-9").is_none());
        assert!(aeris_roles::runner("reasoning", "gpt-9").is_none());
        assert!(runner("vehicle", "px4").is_none());
    }
}
