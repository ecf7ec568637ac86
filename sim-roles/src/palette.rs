//! The `palette` detector engine: the geometric perception's colour segmentation of the
//! built-in worlds ([`Segmenter`]) as a [`DetectionEngine`] of the detector role, for flights
//! where COCO classes are not what matters. It needs the frame's depth (a frame without it
//! gives no block).

use crate::perception::{InstructionWords, Segmenter};
use aeris_roles::detector::{DetectionEngine, DetectorRole};
use aeris_runtime::{RoleContext, RoleError};
use aeris_schemas::{FrameHeader, PerceptionState};

/// The colour segmentation as a detection engine.
pub struct PaletteDetection {
    segmenter: Box<Segmenter>,
    words: InstructionWords,
    /// The whole S_t the segmentation fills; the detections are copied out of it.
    full: Box<PerceptionState>,
}

/// The detector role on the colour segmentation (variant `palette`).
pub type PaletteDetectorRole = DetectorRole<PaletteDetection>;

impl DetectionEngine for PaletteDetection {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        Ok(Self {
            segmenter: Box::default(),
            words: InstructionWords::from_mission(&ctx.spec.mission),
            full: Box::default(),
        })
    }

    fn detect(
        &mut self,
        rgb: &[u8],
        depth: Option<&[u8]>,
        header: &FrameHeader,
        state: &mut PerceptionState,
    ) -> bool {
        let Some(depth) = depth else {
            return false;
        };
        let perceived = self.segmenter.perceive(
            rgb,
            depth,
            header,
            &self.words,
            &mut self.full,
            &mut |_, _| {},
        );
        state.detections = self.full.detections;
        state.detection_count = self.full.detection_count;
        perceived.is_ok()
    }
}
