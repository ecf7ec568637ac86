//! Object detector (kind `detector`) -> the detection block of S_t on
//! `perception/detections`.
//!
//! Variants:
//! - `yolo`: a COCO detector through ONNX Runtime (default `detect/yolov3-tiny.onnx`,
//!   Darknet weights converted by `scripts/models/darknet_to_onnx.py`, YOLOv5 output layout);
//! - `yolov8`: any Ultralytics-layout model (YOLOv8/YOLO11 `[1, 4 + classes, anchors]`;
//!   default the one such model on the registries, `detect/nudenet-320n.onnx`);
//! - `palette`: the colour segmentation of the built-in worlds (no model; what the
//!   `geometric` perception role uses), for flights where COCO classes are not what matters;
//!   a [`DetectionEngine`] of the simulator's (`aeris-sim-roles`), run by this role.
//!
//! Each detection's range is the median depth inside the middle of its box, when the depth
//! frame of the same `seq` is at hand. Parameters: `model`, `interval_ms` (default 2000),
//! `threads` (default 1), `min_score`, `models_dir`.
//! Heartbeat counters: [`BlockCounters`] (items: detections in the last block).

use crate::vision::{FrameStride, begin_block, model_file, open_store, session_options};
use aeris_models::detect::{COCO_DETECTOR, YOLOV8_DETECTOR};
use aeris_models::{DetectedBox, Detector};
use aeris_runtime::bus::{FrameSample, FrameSubscriber, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    BlockCounters, Detection, FixedText, FrameFormat, FrameHeader, MAX_DETECTIONS, PerceptionState,
    block, topics,
};
use core::time::Duration;

/// Poll period.
pub const PERIOD: Duration = Duration::from_millis(20);

/// Median of the valid depth samples (u16 LE mm) in the middle half of `bbox` (pixels),
/// in metres; 0 when there are none. `scratch` is reused between calls.
pub fn box_range_m(
    depth: &[u8],
    width: usize,
    height: usize,
    bbox: [f32; 4],
    scratch: &mut Vec<u16>,
) -> f32 {
    scratch.clear();
    if depth.len() != width * height * 2 {
        return 0.0;
    }
    let x0 = (bbox[0] + 0.25 * bbox[2]).max(0.0) as usize;
    let y0 = (bbox[1] + 0.25 * bbox[3]).max(0.0) as usize;
    let x1 = ((bbox[0] + 0.75 * bbox[2]).ceil() as usize).min(width);
    let y1 = ((bbox[1] + 0.75 * bbox[3]).ceil() as usize).min(height);
    for y in y0..y1 {
        for x in x0..x1 {
            let i = 2 * (y * width + x);
            let z = u16::from_le_bytes([depth[i], depth[i + 1]]);
            if z > 0 {
                scratch.push(z);
            }
        }
    }
    if scratch.is_empty() {
        return 0.0;
    }
    let mid = scratch.len() / 2;
    let (_, m, _) = scratch.select_nth_unstable(mid);
    *m as f32 * 0.001
}

/// What a detector role runs on the frames it picks: it fills the detection block of S_t.
/// [`ModelDetection`] runs the YOLO models; the simulator's colour segmentation (variant
/// `palette`) is another engine, beside the simulator (`aeris-sim-roles`).
pub trait DetectionEngine: Sized {
    /// The engine for the role's spec (loads and warms up its models, if any).
    fn new(ctx: &mut RoleContext<kinds::Detector>) -> Result<Self, RoleError>;

    /// Detect in `rgb` (RGB8, described by `header`, already validated), with the same
    /// frame's `depth` (u16 LE mm z-depth) when at hand, into `state.detections` and
    /// `state.detection_count` (`state` is an empty block of this frame). `false` when the
    /// frame gave no block; the role counts it as rejected. Must not allocate.
    fn detect(
        &mut self,
        rgb: &[u8],
        depth: Option<&[u8]>,
        header: &FrameHeader,
        state: &mut PerceptionState,
    ) -> bool;
}

/// The model engine (variants `yolo` and `yolov8`): boxes from the detector, each with the
/// median depth of its middle as its range.
pub struct ModelDetection {
    detector: Box<Detector>,
    boxes: Vec<DetectedBox>,
    scratch: Vec<u16>,
}

impl DetectionEngine for ModelDetection {
    fn new(ctx: &mut RoleContext<kinds::Detector>) -> Result<Self, RoleError> {
        let default = if ctx.spec.variant == "yolov8" {
            YOLOV8_DETECTOR
        } else {
            COCO_DETECTOR
        };
        let store = open_store(ctx)?;
        let file = model_file(ctx, default).to_string();
        let mut det = Detector::load(&store, &file, &session_options(ctx)?)
            .map_err(|e| RoleError::step(format!("loading the detector {file}"), e))?;
        if let Some(s) = ctx.spec.param_f64("min_score") {
            det.min_score = s as f32;
        }
        det.warm_up()
            .map_err(|e| RoleError::step(format!("warming up the detector {file}"), e))?;
        Ok(Self {
            detector: Box::new(det),
            boxes: Vec::with_capacity(256),
            scratch: Vec::with_capacity(320 * 240),
        })
    }

    fn detect(
        &mut self,
        rgb: &[u8],
        depth: Option<&[u8]>,
        header: &FrameHeader,
        state: &mut PerceptionState,
    ) -> bool {
        let (w, h) = (header.width as usize, header.height as usize);
        if self.detector.detect(rgb, w, h, &mut self.boxes).is_err() {
            return false;
        }
        let mut n = 0;
        for b in self.boxes.iter().take(MAX_DETECTIONS) {
            let range_m = depth
                .map(|d| box_range_m(d, w, h, b.bbox, &mut self.scratch))
                .unwrap_or(0.0);
            let name = self
                .detector
                .names()
                .get(b.class_id)
                .map(String::as_str)
                .unwrap_or("object");
            state.detections[n] = Detection {
                label: FixedText::from_str_truncated(name),
                class_id: b.class_id as u32,
                score: b.score.clamp(0.0, 1.0),
                bbox: [
                    (b.bbox[0] / w as f32).clamp(0.0, 1.0),
                    (b.bbox[1] / h as f32).clamp(0.0, 1.0),
                    (b.bbox[2] / w as f32).clamp(0.0, 1.0),
                    (b.bbox[3] / h as f32).clamp(0.0, 1.0),
                ],
                range_m,
            };
            n += 1;
        }
        state.detection_count = n as u32;
        true
    }
}

/// The detector role, running engine `E` on the frames its stride picks.
pub struct DetectorRole<E> {
    rgb: FrameSubscriber,
    depth: FrameSubscriber,
    held_depth: Option<FrameSample>,
    out: TypedPublisher<PerceptionState>,
    engine: E,
    stride: FrameStride,
    state: Box<PerceptionState>,
    seq: u64,
    rejected: u64,
}

/// The detector role on the YOLO models (variants `yolo`, `yolov8`).
pub type ModelDetectorRole = DetectorRole<ModelDetection>;

impl<E: DetectionEngine> Role for DetectorRole<E> {
    type Kind = kinds::Detector;

    fn new(ctx: &mut RoleContext<kinds::Detector>) -> Result<Self, RoleError> {
        let engine = E::new(ctx)?;
        Ok(Self {
            rgb: ctx.bus.frame_subscriber::<topics::CameraRgb>()?,
            depth: ctx.bus.frame_subscriber::<topics::CameraDepth>()?,
            held_depth: None,
            out: ctx.bus.publisher::<topics::PerceptionDetections>()?,
            engine,
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
        _ctx: &mut RoleContext<kinds::Detector>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        while let Some(d) = self.depth.next()? {
            self.held_depth = Some(d);
        }
        let Some(frame) = self.stride.next_frame(&self.rgb)? else {
            return Ok(CycleOutcome::Idle);
        };
        let header = *frame.user_header();
        if header.validate(frame.payload().len()) != Ok(FrameFormat::Rgb8) {
            self.rejected += 1;
            BlockCounters::update(&mut report.counters, |c| c.frames_rejected = self.rejected);
            return Ok(CycleOutcome::Idle);
        }
        let t0 = monotonic_ns();
        begin_block(&mut self.state, &header, block::DETECTIONS);
        let depth = self
            .held_depth
            .as_ref()
            .filter(|d| d.user_header().seq == header.seq)
            .map(|d| d.payload());
        let ok = self
            .engine
            .detect(frame.payload(), depth, &header, &mut self.state);
        drop(frame);
        if !ok {
            self.rejected += 1;
            BlockCounters::update(&mut report.counters, |c| c.frames_rejected = self.rejected);
            return Ok(CycleOutcome::Idle);
        }
        report.stage("detect", monotonic_ns() - t0);
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.out.publish(&self.state)?;
        BlockCounters::update(&mut report.counters, |c| c.blocks = self.seq);
        BlockCounters::update(&mut report.counters, |c| {
            c.items = self.state.detection_count as u64
        });
        Ok(CycleOutcome::Worked)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_is_the_median_of_the_box_middle() {
        let (w, h) = (8usize, 4usize);
        let mut depth = vec![0u8; w * h * 2];
        for (i, px) in depth.chunks_exact_mut(2).enumerate() {
            let mm: u16 = if i % w < 4 { 5000 } else { 9000 };
            px.copy_from_slice(&mm.to_le_bytes());
        }
        let mut scratch = Vec::new();
        // a box over the left half: middle is all 5 m
        assert_eq!(
            box_range_m(&depth, w, h, [0.0, 0.0, 4.0, 4.0], &mut scratch),
            5.0
        );
        assert_eq!(
            box_range_m(&depth, w, h, [4.0, 0.0, 4.0, 4.0], &mut scratch),
            9.0
        );
        // wrong size: unknown
        assert_eq!(
            box_range_m(&depth[2..], w, h, [0.0, 0.0, 4.0, 4.0], &mut scratch),
            0.0
        );
    }
}
