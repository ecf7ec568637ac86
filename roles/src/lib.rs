//! # aeris-roles
//!
//! The role implementations that run as their own processes (the hub lives in `aeris-hub`):
//! - [`vehicle`]: the built-in simulated multirotor behind a MAVLink endpoint;
//! - [`camera`]: renders FPV RGB + depth frames and publishes them over iceoryx2;
//! - [`perception`]: frames -> typed state S_t;
//! - [`planner`]: the deterministic reasoning variant (and a garbage-emitting fault injector);
//! - [`controller`]: tracks bound setpoints at the control rate over MAVLink.

#![deny(missing_docs)]

pub mod camera;
pub mod controller;
pub mod perception;
pub mod planner;
pub mod vehicle;

use aeris_runtime::{RoleError, RoleHost, RoleSpec};

/// Run the role described by `spec` in this process (every kind except `hub`).
pub fn run(spec: RoleSpec) -> Result<(), RoleError> {
    match (spec.kind.as_str(), spec.variant.as_str()) {
        ("vehicle", "sim-multirotor") => RoleHost::run::<vehicle::VehicleRole>(spec),
        ("camera", "sim-render") => RoleHost::run::<camera::CameraRole>(spec),
        ("perception", "geometric") => RoleHost::run::<perception::PerceptionRole>(spec),
        ("reasoning", "planner") => RoleHost::run::<planner::PlannerRole>(spec),
        ("reasoning", "garbage") => RoleHost::run::<planner::GarbageRole>(spec),
        ("controller", "mavlink") => RoleHost::run::<controller::ControllerRole>(spec),
        (kind, variant) => Err(RoleError::Config(format!(
            "no role kind `{kind}` with variant `{variant}` in this build (see `aeris roles`)"
        ))),
    }
}
