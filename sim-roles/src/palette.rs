//! The `palette` detector engine: the geometric perception's colour segmentation of the
//! built-in worlds ([`Segmenter`]) as a [`DetectionEngine`] of the detector role, for flights
//! where COCO classes are not what matters. It needs the frame's depth (a frame without it
//! gives no block).

use crate::perception::{InstructionWords, Segmenter};
use aeris_roles::detector::{DetectionEngine, DetectorRole};
use aeris_runtime::{RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{FrameHeader, PerceptionState};

/// Frames in a row without depth after which the engine says it cannot detect (once).
const NO_DEPTH_SAID_AFTER: u32 = 10;

/// The colour segmentation as a detection engine.
pub struct PaletteDetection {
    /// Frames in a row without their depth frame (a depth frame may come a little late; a
    /// camera without depth never sends one).
    without_depth: u32,
    segmenter: Box<Segmenter>,
    words: InstructionWords,
    /// The whole S_t the segmentation fills; the detections are copied out of it.
    full: Box<PerceptionState>,
}

/// The detector role on the colour segmentation (variant `palette`).
pub type PaletteDetectorRole = DetectorRole<PaletteDetection>;

impl DetectionEngine for PaletteDetection {
    fn new(ctx: &mut RoleContext<kinds::Detector>) -> Result<Self, RoleError> {
        Ok(Self {
            without_depth: 0,
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
            self.without_depth = self.without_depth.saturating_add(1);
            if self.without_depth == NO_DEPTH_SAID_AFTER {
                tracing::info!(
                    "detector: palette: no depth frame came with the last \
                     {NO_DEPTH_SAID_AFTER} frames; the colour segmentation needs depth, so \
                     they give no detections (a camera without depth wants the yolo detector)"
                );
            }
            return false;
        };
        self.without_depth = 0;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::perceive;
    use aeris_geometry::CAMERA_MOUNT_HEIGHT_M;
    use aeris_schemas::FrameFormat;
    use aeris_sim::render::Renderer;
    use aeris_sim::world::World;

    /// The engine fills the detection block exactly as the geometric perception fills
    /// its detections, and nothing without the frame's depth.
    #[test]
    fn the_palette_block_is_the_geometric_perceptions_detections() {
        let (w, h, hfov) = (160, 120, core::f32::consts::FRAC_PI_2);
        let r = Renderer::new(w, h, hfov).unwrap();
        let (mut rgb, mut depth) = (vec![0; r.rgb_len()], vec![0; r.depth_len()]);
        let cam = [40.0, 18.0, 20.0 + CAMERA_MOUNT_HEIGHT_M];
        let world = World::builtin("village").unwrap();
        r.render(&world, cam, 0.3, &mut rgb, &mut depth).unwrap();
        let header = FrameHeader {
            seq: 7,
            capture_ns: 1,
            width: w,
            height: h,
            camera_position: cam,
            camera_yaw: 0.3,
            hfov,
            format: FrameFormat::Rgb8 as u8,
            reserved: [0; 3],
        };
        let words = InstructionWords::new(["turn right at the red-roofed building"]);
        let mut full = PerceptionState::default();
        perceive(&rgb, &depth, &header, &words, &mut full).unwrap();
        assert!(full.detection_count > 0, "a scene with something in it");

        let mut engine = PaletteDetection {
            without_depth: 0,
            segmenter: Box::default(),
            words,
            full: Box::default(),
        };
        let mut block = PerceptionState::default();
        assert!(engine.detect(&rgb, Some(&depth), &header, &mut block));
        assert_eq!(block.detection_count, full.detection_count);
        assert_eq!(block.detections, full.detections);
        assert_eq!(block.cue_count, 0, "only the detection block");

        let mut without_depth = PerceptionState::default();
        assert!(!engine.detect(&rgb, None, &header, &mut without_depth));
        assert!(!engine.detect(&rgb, Some(&depth[2..]), &header, &mut without_depth));
    }
}
