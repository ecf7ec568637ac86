//! Occupancy (kind `occupancy`) -> the occupancy block of S_t on `perception/occupancy`.
//!
//! Variants:
//! - `depth`: every depth return of the frame is back-projected with the frame's pose into
//!   the ego-centred 64 x 64, 2 m grid (highest obstacle top per cell), as in the
//!   `geometric` perception role ([`crate::depth_occupancy::occupancy_from_depth`]);
//! - `onnx`: the slot for the paper's learned occupancy models through ONNX Runtime. Input
//!   `[1, 1, H, W]` depth in metres, output `[1, 64, 64]` (or `[64, 64]`) obstacle heights in
//!   metres, NaN for unknown. No such weights are published on the package registries, so
//!   the variant needs `params.model` naming a provisioned file and refuses to start
//!   without one.
//!
//! Parameters: `interval_ms` (default 2000), `model`, `threads`, `models_dir`.
//! Heartbeat counters: [`BlockCounters`] (items: observed cells in the last block).

use crate::depth_occupancy::{OCCUPANCY_RESOLUTION_M, occupancy_from_depth};
use crate::vision::{FrameStride, begin_block, open_store, session_options};
use aeris_models::OnnxModel;
use aeris_runtime::bus::{FrameSubscriber, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::error_chain::chain;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    BlockCounters, FrameFormat, FrameHeader, OCCUPANCY_CELLS, OCCUPANCY_UNKNOWN, OccupancyStatus,
    PerceptionState, block, topics,
};
use core::time::Duration;

/// Poll period.
pub const PERIOD: Duration = Duration::from_millis(20);

/// Why the `onnx` variant cannot start without a model.
pub const NO_OCCUPANCY_WEIGHTS: &str = "occupancy/onnx: no occupancy-model weights are published on the package \
registries, so none is provisioned; set params.model to an ONNX file in the model cache \
(input [1,1,H,W] depth in metres, output [1,64,64] heights in metres), or use variant `depth`";

/// The learned-model slot.
struct LearnedGrid {
    model: OnnxModel,
    input: Vec<f32>,
}

impl LearnedGrid {
    fn run(
        &mut self,
        depth: &[u8],
        header: &FrameHeader,
        state: &mut PerceptionState,
    ) -> Result<(), String> {
        self.input.clear();
        self.input.extend(
            depth
                .chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]) as f32 * 0.001),
        );
        let (w, h) = (header.width as usize, header.height as usize);
        let cells = &mut state.occupancy.cells;
        self.model
            .run_f32(&[1, 1, h, w], &self.input, |shape, data| {
                if data.len() != OCCUPANCY_CELLS {
                    return Err(format!("output {shape:?} is not a 64 x 64 grid"));
                }
                for (c, v) in cells.iter_mut().zip(data) {
                    *c = if v.is_finite() {
                        v.clamp(0.0, 254.0) as u8
                    } else {
                        OCCUPANCY_UNKNOWN
                    };
                }
                Ok(())
            })
            .map_err(|e| chain(&e).to_string())?;
        let p = header.camera_position;
        state.occupancy.origin = [p[0], p[1]];
        state.occupancy.resolution_m = OCCUPANCY_RESOLUTION_M;
        state.occupancy.status = OccupancyStatus::Present as u8;
        Ok(())
    }
}

/// The occupancy role.
pub struct OccupancyRole {
    depth: FrameSubscriber,
    out: TypedPublisher<PerceptionState>,
    learned: Option<LearnedGrid>,
    stride: FrameStride,
    state: Box<PerceptionState>,
    seq: u64,
    rejected: u64,
}

impl Role for OccupancyRole {
    type Kind = kinds::Occupancy;

    fn new(ctx: &mut RoleContext<kinds::Occupancy>) -> Result<Self, RoleError> {
        let learned = if ctx.spec.variant == "onnx" {
            let file = ctx
                .spec
                .param_str("model")
                .ok_or(ConfigError::NoWeights(NO_OCCUPANCY_WEIGHTS))?
                .to_string();
            let store = open_store(ctx)?;
            let model = OnnxModel::load_with(&store, &file, &session_options(ctx)?)
                .map_err(|e| RoleError::step(format!("loading the occupancy model {file}"), e))?;
            Some(LearnedGrid {
                model,
                input: Vec::new(),
            })
        } else {
            None
        };
        Ok(Self {
            depth: ctx.bus.frame_subscriber::<topics::CameraDepth>()?,
            out: ctx.bus.publisher::<topics::PerceptionOccupancy>()?,
            learned,
            stride: FrameStride::from_ctx(ctx),
            state: Box::default(),
            seq: 0,
            rejected: 0,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Occupancy>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(frame) = self.stride.next_frame(&self.depth)? else {
            return Ok(CycleOutcome::Idle);
        };
        let header = *frame.user_header();
        let t0 = monotonic_ns();
        let result = if header.validate(frame.payload().len()) != Ok(FrameFormat::DepthU16Mm) {
            Err("not a depth frame".to_string())
        } else {
            match &mut self.learned {
                None => occupancy_from_depth(frame.payload(), &header, &mut self.state)
                    .map_err(|e| e.to_string()),
                Some(l) => {
                    begin_block(&mut self.state, &header, block::OCCUPANCY);
                    l.run(frame.payload(), &header, &mut self.state)
                }
            }
        };
        drop(frame);
        if let Err(e) = result {
            self.rejected += 1;
            BlockCounters::update(&mut report.counters, |c| c.frames_rejected = self.rejected);
            tracing::warn!("occupancy: frame {} rejected: {e}", header.seq);
            return Ok(CycleOutcome::Idle);
        }
        // occupancy_from_depth fills the frame fields; the block holds nothing else
        self.state.detection_count = 0;
        self.state.cue_count = 0;
        self.state.summary = Default::default();
        report.stage("grid", monotonic_ns() - t0);
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.out.publish(&self.state)?;
        BlockCounters::update(&mut report.counters, |c| c.blocks = self.seq);
        let observed = self
            .state
            .occupancy
            .cells
            .iter()
            .filter(|&&c| c != OCCUPANCY_UNKNOWN)
            .count() as u64;
        BlockCounters::update(&mut report.counters, |c| c.items = observed);
        Ok(CycleOutcome::Worked)
    }
}
