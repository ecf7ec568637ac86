//! # aeris-geometry
//!
//! The geometry every side of a flight agrees on, in a leaf crate (no other crate of ours):
//! - [`camera`]: the pinhole FPV camera on its stabilised mount ([`CameraModel`],
//!   [`CAMERA_PITCH_RAD`], [`CAMERA_MOUNT_HEIGHT_M`]) and the level-body-to-world rotation;
//!   the renderer draws with it, perception and the planner back-project with it;
//! - [`angle`]: angles in `[-pi, pi]` ([`wrap_pi`]).
//!
//! Frames: the world is `[N, E, U]` (metres, up positive); yaw is 0 = north, positive
//! towards east.

#![deny(missing_docs)]

pub mod angle;
pub mod camera;

pub use angle::wrap_pi;
pub use camera::{
    CAMERA_MOUNT_HEIGHT_M, CAMERA_PITCH_RAD, CameraModel, CameraModelError, body_to_world,
};
