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
//! - [`distill`]: what an aligned reasoner reads (no plan) and the training pairs written
//!   from it;
//! - [`reasoner_io`]: what every reasoning variant does around its decision (inputs, when to
//!   decide, stamping and publishing);
//! - [`controller`]: tracks bound setpoints at the control rate over MAVLink;
//! - [`formation_role`]: the ground station of a flight of several vehicles (a formation
//!   program written, checked and flown slot by slot through every vehicle's controller);
//! - [`gstreamer_camera`]: a real camera (any GStreamer pipeline ending in an appsink).
//!
//! Which type runs which kind and variant is the binary's role registry.

#![deny(missing_docs)]

pub mod compose;
pub mod controller;
pub mod cues;
pub mod depth_occupancy;
pub mod detector;
pub mod distill;
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
