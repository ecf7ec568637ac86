//! # aeris-sim
//!
//! The built-in simulation, so the default flight needs no external simulator:
//! - [`world`]: procedurally described scenes of boxes (buildings, towers, signs, ground
//!   patches) with named landmarks;
//! - [`scene_gen`]: seeded open and dense scenes for evaluation (`open-7`, `dense-42`);
//! - [`render`]: a CPU ray-caster producing FPV RGB and depth frames of a world;
//! - [`multirotor`]: simple multirotor kinematics with velocity and acceleration limits;
//! - [`formation_vehicle`]: the multirotor as the vehicle model that flies formation
//!   programs before they fly;
//! - [`mav_vehicle`]: a MAVLink v2 endpoint that behaves like a PX4 multirotor in offboard mode
//!   (on the links of `aeris-mavlink`).
//!
//! The roles that run the simulation in a flight (vehicle, camera, geometric perception,
//! palette detector) are in `aeris-sim-roles`; no flight role outside it depends on this
//! crate.

#![deny(missing_docs)]

mod builtin;
pub mod formation_vehicle;
pub mod mav_vehicle;
pub mod multirotor;
pub mod render;
pub mod scene_gen;
pub mod world;
