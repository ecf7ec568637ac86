//! Sign / text reader (kind `text-reader`, variant `ppocr`): PP-OCRv4 text detection and
//! recognition through ONNX Runtime on FPV frames -> the scene-text block of S_t on
//! `perception/text` (`summary` = the texts joined by `" | "`, `cues` = one per region with
//! the reader's confidence).
//!
//! Parameters: `interval_ms` (frame stride, default 2000), `threads` (default 1),
//! `models_dir`. Heartbeat counters: [`BlockCounters`] (items: regions read).

use crate::vision::{FrameStride, begin_block, open_store, session_options};
use aeris_models::ocr::{OcrReader, TextRegion};
use aeris_runtime::bus::{FrameSubscriber, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::error_chain::chain;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    BlockCounters, FixedText, FrameFormat, MAX_CUES, PerceptionState, block, topics,
};
use core::time::Duration;

/// Poll period (frames arrive at the camera rate; the stride picks which to read).
pub const PERIOD: Duration = Duration::from_millis(20);

/// Fill the text block of `state` from the regions read (best first as given).
pub fn fill_text_block(regions: &[TextRegion], state: &mut PerceptionState) {
    state.summary = FixedText::new();
    let mut n = 0;
    for r in regions.iter().filter(|r| !r.text.trim().is_empty()) {
        if !state.summary.is_empty() {
            let _ = state.summary.push_str(" | ");
        }
        let _ = state.summary.push_str(r.text.trim());
        if n < MAX_CUES {
            state.cues[n].text = FixedText::from_str_truncated(r.text.trim());
            state.cues[n].score = r.score.clamp(0.0, 1.0);
            n += 1;
        }
    }
    state.cue_count = n as u32;
}

/// The text-reader role.
pub struct TextReaderRole {
    rgb: FrameSubscriber,
    out: TypedPublisher<PerceptionState>,
    reader: OcrReader,
    stride: FrameStride,
    regions: Vec<TextRegion>,
    state: Box<PerceptionState>,
    seq: u64,
    read: u64,
    rejected: u64,
}

impl Role for TextReaderRole {
    type Kind = kinds::TextReader;

    fn new(ctx: &mut RoleContext<kinds::TextReader>) -> Result<Self, RoleError> {
        let store = open_store(ctx)?;
        let mut reader = OcrReader::load(&store, &session_options(ctx)?)
            .map_err(|e| RoleError::step("loading PP-OCR", e))?;
        let camera = &ctx.spec.camera;
        reader
            .warm_up(camera.width as usize, camera.height as usize)
            .map_err(|e| RoleError::step("warming up PP-OCR", e))?;
        Ok(Self {
            rgb: ctx.bus.frame_subscriber::<topics::CameraRgb>()?,
            out: ctx.bus.publisher::<topics::PerceptionText>()?,
            reader,
            stride: FrameStride::from_ctx(ctx),
            regions: Vec::with_capacity(aeris_models::ocr::MAX_REGIONS),
            state: Box::default(),
            seq: 0,
            read: 0,
            rejected: 0,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::TextReader>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
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
        let result = self.reader.read(
            frame.payload(),
            header.width as usize,
            header.height as usize,
            &mut self.regions,
        );
        drop(frame);
        report.stage("ocr", monotonic_ns() - t0);
        if let Err(e) = result {
            // a frame the reader cannot take is dropped, the role keeps running
            self.rejected += 1;
            BlockCounters::update(&mut report.counters, |c| c.frames_rejected = self.rejected);
            tracing::warn!("text-reader: frame {} rejected: {}", header.seq, chain(&e));
            return Ok(CycleOutcome::Idle);
        }
        begin_block(&mut self.state, &header, block::TEXT);
        fill_text_block(&self.regions, &mut self.state);
        self.read += self.state.cue_count as u64;
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.out.publish(&self.state)?;
        BlockCounters::update(&mut report.counters, |c| c.blocks = self.seq);
        BlockCounters::update(&mut report.counters, |c| c.items = self.read);
        Ok(CycleOutcome::Worked)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_become_summary_and_cues() {
        let regions = vec![
            TextRegion {
                text: "LAKE".into(),
                score: 0.97,
                bbox: [0.0; 4],
            },
            TextRegion {
                text: "  ".into(),
                score: 0.5,
                bbox: [0.0; 4],
            },
            TextRegion {
                text: "VIEW".into(),
                score: 1.2,
                bbox: [0.0; 4],
            },
        ];
        let mut s = PerceptionState::default();
        fill_text_block(&regions, &mut s);
        assert_eq!(s.summary.as_str(), Some("LAKE | VIEW"));
        assert_eq!(s.cue_count, 2);
        assert_eq!(s.cues[1].score, 1.0);
        assert!(s.validate().is_ok());
    }
}
