//! What the model-backed perception roles share: frame selection, the model cache and the
//! frame fields every block carries.

use aeris_geometry::CAMERA_MOUNT_HEIGHT_M;
use aeris_models::{Accelerator, ModelStore, SessionOptions};
use aeris_runtime::bus::{FrameSample, FrameSubscriber};
use aeris_runtime::{RoleContext, RoleError};
use aeris_schemas::{FrameHeader, PerceptionState};
use std::path::Path;

/// Default interval between the frames a model role processes (ms).
pub const DEFAULT_INTERVAL_MS: f64 = 2000.0;

/// Picks the frames a model role works on: the first frame captured in each interval of
/// `interval_ns` of the monotonic clock. Every role with the same interval picks the same
/// frames (they share the capture stamps), so blocks of one frame can be joined by `seq`.
#[derive(Debug, Clone, Copy)]
pub struct FrameStride {
    interval_ns: u64,
    last_bucket: u64,
}

impl FrameStride {
    /// A stride of `interval_ms` (at least 1 ms).
    pub fn new(interval_ms: f64) -> Self {
        Self {
            interval_ns: (interval_ms.max(1.0) * 1e6) as u64,
            last_bucket: u64::MAX,
        }
    }

    /// The stride from the role's `interval_ms` parameter (default [`DEFAULT_INTERVAL_MS`]).
    pub fn from_ctx<K>(ctx: &RoleContext<K>) -> Self {
        Self::new(
            ctx.spec
                .param_f64("interval_ms")
                .unwrap_or(DEFAULT_INTERVAL_MS),
        )
    }

    /// `true` (once) for the first frame of a new interval.
    pub fn take(&mut self, capture_ns: u64) -> bool {
        let bucket = capture_ns / self.interval_ns;
        if bucket != self.last_bucket {
            self.last_bucket = bucket;
            true
        } else {
            false
        }
    }

    /// Drain `frames`; return the newest frame that starts an interval, if one arrived.
    pub fn next_frame(
        &mut self,
        frames: &FrameSubscriber,
    ) -> Result<Option<FrameSample>, RoleError> {
        let mut picked = None;
        while let Some(s) = frames.next()? {
            if self.take(s.user_header().capture_ns) {
                picked = Some(s);
            }
        }
        Ok(picked)
    }
}

/// The model cache a role reads: the `models_dir` parameter, else `$AERIS_MODELS`, else
/// `~/.cache/aeris/models`. Errors name the provisioning command.
pub fn open_store<K>(ctx: &RoleContext<K>) -> Result<ModelStore, RoleError> {
    ModelStore::open(ctx.spec.param_str("models_dir").map(Path::new))
        .map_err(|e| RoleError::step("opening the model cache", e))
}

/// The role's `model` parameter, or `default`.
pub fn model_file<'a, K>(ctx: &'a RoleContext<K>, default: &'a str) -> &'a str {
    ctx.spec.param_str("model").unwrap_or(default)
}

/// Threads for a model role (`threads` parameter, default 1: the LM needs the rest).
pub fn threads<K>(ctx: &RoleContext<K>) -> usize {
    ctx.spec
        .param_f64("threads")
        .unwrap_or(1.0)
        .clamp(1.0, 64.0) as usize
}

/// Where a model role's sessions run: its `threads`, on its executor's accelerator if the
/// spec names one (`cuda:0`). Loading checks the accelerator's execution provider, and the
/// error names the providers the ONNX Runtime offers.
pub fn session_options<K>(ctx: &RoleContext<K>) -> Result<SessionOptions, RoleError> {
    Ok(SessionOptions {
        threads: threads(ctx),
        accelerator: accelerator(ctx)?,
    })
}

/// The accelerator of the role's executor (`cuda:0`), if its spec names one.
pub fn accelerator<K>(ctx: &RoleContext<K>) -> Result<Option<Accelerator>, RoleError> {
    ctx.spec
        .accelerator
        .as_deref()
        .map(str::parse::<Accelerator>)
        .transpose()
        .map_err(|e| RoleError::step("reading the role's accelerator", e))
}

/// Reset `state` to an empty block for the frame `header` describes.
pub fn begin_block(state: &mut PerceptionState, header: &FrameHeader, blocks: u32) {
    *state = PerceptionState::default();
    let p = header.camera_position;
    state.frame_seq = header.seq;
    state.capture_ns = header.capture_ns;
    state.position = [p[0], p[1], p[2] - CAMERA_MOUNT_HEIGHT_M];
    state.yaw = header.camera_yaw;
    state.blocks = blocks;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_frame_of_each_interval_is_taken_once() {
        let mut s = FrameStride::new(1000.0);
        let ms = 1_000_000u64;
        let taken: Vec<u64> = [0, 100, 900, 1000, 1100, 1999, 2500, 2600, 5000]
            .into_iter()
            .filter(|t| s.take(t * ms))
            .collect();
        assert_eq!(taken, vec![0, 1000, 2500, 5000]);
        // two roles with the same interval pick the same frames
        let mut a = FrameStride::new(500.0);
        let mut b = FrameStride::new(500.0);
        for t in (0..5000).step_by(100) {
            assert_eq!(a.take(t * ms), b.take(t * ms));
        }
    }
}
