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
//! Which type runs which kind and variant is the binary's role registry.

#![deny(missing_docs)]

pub mod camera;
pub mod palette;
pub mod perception;
pub mod vehicle;
