//! # aeris-video
//!
//! The GStreamer glue of AERIS (GStreamer 1.22 system libraries, `gstreamer-rs` 0.25):
//! - [`capture`]: frames from any user pipeline that ends in an `appsink`, forced to RGB
//!   (or GRAY16_LE depth) at the workflow's camera size, copied once into a caller's buffer
//!   (a loaned shared-memory sample), stamped with their capture time on CLOCK_MONOTONIC;
//!   errors, end of stream and stalls come back as [`capture::CaptureEvent`]s;
//! - [`encode`]: RGB frames into H.264 (`x264enc`, else `openh264enc`), written to an MP4
//!   file or sent as RTP over UDP;
//! - `scene_video` (feature `sim`): the built-in scene rendered along a path, or at the pose
//!   of a live flight's vehicle (a simulated FPV transmitter), into the encoder.
//!
//! Nothing here panics on bad input: every operation has its own error enum.

#![deny(missing_docs)]

pub mod capture;
pub mod encode;
#[cfg(feature = "sim")]
pub mod scene_video;

pub use capture::{
    BuildError, Capture, CaptureConfig, CaptureEvent, CapturedFrame, CopyError, GstText,
    PixelFormat, StartError,
};
pub use encode::{Encoder, EncoderConfig, EncoderStartError, FinishError, PushError, VideoSink};

/// GStreamer could not be initialised (no usable GStreamer installation).
#[derive(Debug, thiserror::Error)]
#[error("cannot initialise GStreamer")]
pub struct InitError(#[source] pub gstreamer::glib::Error);

/// Initialise GStreamer once per process (later calls are free).
pub fn init() -> Result<(), InitError> {
    gstreamer::init().map_err(InitError)
}

/// Whether this GStreamer installation has an element factory named `name`.
pub fn has_element(name: &str) -> bool {
    init().is_ok() && gstreamer::ElementFactory::find(name).is_some()
}
