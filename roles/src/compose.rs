//! Image-to-text (kind `image-to-text`) -> the full S_t on `perception/state`.
//!
//! Variants:
//! - `compose`: joins the blocks of one frame (text, detections, cues, occupancy) and writes
//!   the bounded scene summary from them, e.g. `reads "LAKE VIEW"; bus ahead 21 m; person
//!   left 8 m`. It publishes when the cue block of a frame arrives (the last stage of the
//!   pipeline), when every kind of block that has ever come (text, detections, cues) is
//!   there for that frame (a pipeline without a cue role), or, failing both, `join_ms`
//!   (default 1500) after the first block of that frame, with whatever blocks are there. The occupancy block may come from an earlier
//!   frame than the others (the newest the occupancy role published); its status in S_t
//!   says what it is worth: **absent** when no occupancy block ever came (no depth source:
//!   a camera without depth, or no occupancy role), **stale** when the newest one's frame
//!   was captured more than [`STALE_AFTER_TENTHS`] tenths of a heartbeat (1.5 heartbeats,
//!   the rule by which a reasoner stops deciding on an old S_t) before this S_t's frame
//!   (the depth source stopped), **present** otherwise;
//! - `vlm`: the slot for a captioning model (the paper's image-to-text VLMs). No captioning
//!   weights are published on the package registries, so this variant refuses to start with
//!   an error that says so; it never makes up a caption.
//!
//! Heartbeat counters: [`ComposeCounters`].

use crate::heartbeat_clock::STALE_AFTER_TENTHS;
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    ComposeCounters, FixedText, OccupancyStatus, PerceptionState, SUMMARY_MAX, block, topics,
};
use core::fmt::Write;
use core::time::Duration;

/// Poll period.
pub const PERIOD: Duration = Duration::from_millis(20);

/// Why the `vlm` variant does not start.
pub const NO_CAPTIONING_WEIGHTS: &str = "image-to-text/vlm: no captioning (VLM) weights are published on the package \
registries (PyPI, crates.io, npm, Debian), so this build has none to run; use variant \
`compose`, which writes the summary from the other perception roles' outputs";

/// Where a normalised box centre lies, as a word.
fn side_word(cx: f32) -> &'static str {
    if cx < 0.35 {
        "left"
    } else if cx > 0.65 {
        "right"
    } else {
        "ahead"
    }
}

/// The text a composed S_t says was read on signs (the words inside `reads "..."` of its
/// summary): `Some("")` when it carries a text block that read nothing, `None` when it
/// carries no text block (no reader in the flight, or not for this frame).
pub fn read_text(state: &PerceptionState) -> Option<&str> {
    if state.blocks & block::TEXT == 0 {
        return None;
    }
    let summary = state.summary.as_str_lossy();
    let Some(rest) = summary.strip_prefix("reads \"") else {
        return Some("");
    };
    Some(rest.split('"').next().unwrap_or(""))
}

/// The oldest an occupancy block may be, relative to the frame of the S_t it joins, and
/// still count as present: [`STALE_AFTER_TENTHS`] tenths of the heartbeat `period_ns`.
pub fn occupancy_max_age_ns(period_ns: u64) -> u64 {
    period_ns.saturating_mul(STALE_AFTER_TENTHS) / 10
}

/// Compose S_t from the blocks at hand (each `None` when missing): copy every block and
/// write the summary (text read first, then the detections with side and range, then the
/// best cue). `state`'s frame fields come from the first block present. The occupancy
/// grid is marked absent without an occupancy block, stale when its frame was captured
/// more than `occupancy_max_age_ns` before `state`'s, and keeps its own status otherwise.
pub fn compose(
    text: Option<&PerceptionState>,
    dets: Option<&PerceptionState>,
    cues: Option<&PerceptionState>,
    occupancy: Option<&PerceptionState>,
    occupancy_max_age_ns: u64,
    state: &mut PerceptionState,
) {
    *state = PerceptionState::default();
    let Some(base) = cues.or(dets).or(text).or(occupancy) else {
        return;
    };
    state.frame_seq = base.frame_seq;
    state.capture_ns = base.capture_ns;
    state.position = base.position;
    state.yaw = base.yaw;
    let mut summary = String::with_capacity(SUMMARY_MAX);
    if let Some(t) = text {
        state.blocks |= block::TEXT;
        let read: Vec<&str> = t.cues().iter().map(|c| c.text.as_str_lossy()).collect();
        if !read.is_empty() {
            let _ = write!(summary, "reads \"{}\"", read.join(" "));
        }
    }
    if let Some(d) = dets {
        state.blocks |= block::DETECTIONS;
        state.detections = d.detections;
        state.detection_count = d.detection_count;
        for det in d.detections().iter().take(6) {
            if !summary.is_empty() {
                summary.push_str("; ");
            }
            let cx = det.bbox[0] + 0.5 * det.bbox[2];
            let _ = write!(summary, "{} {}", det.label.as_str_lossy(), side_word(cx));
            if det.range_m > 0.0 {
                let _ = write!(summary, " {:.0} m", det.range_m);
            }
        }
    }
    if let Some(c) = cues {
        state.blocks |= block::CUES;
        state.cues = c.cues;
        state.cue_count = c.cue_count;
        state.subgoal_relevance = c.subgoal_relevance;
        state.relevance_count = c.relevance_count;
        if let Some(best) = c.cues().first() {
            if !summary.is_empty() {
                summary.push_str("; ");
            }
            let _ = write!(
                summary,
                "cue: {} ({:.2})",
                best.text.as_str_lossy(),
                best.score
            );
        }
    }
    if let Some(o) = occupancy {
        state.blocks |= block::OCCUPANCY;
        state.occupancy = o.occupancy;
        if state.capture_ns.saturating_sub(o.capture_ns) > occupancy_max_age_ns
            && o.occupancy.is_present()
        {
            state.occupancy.status = OccupancyStatus::Stale as u8;
        }
    }
    if summary.is_empty() {
        summary.push_str("nothing recognised");
    }
    state.summary = FixedText::from_str_truncated(&summary);
    state.blocks |= block::SUMMARY;
}

/// The compose variant of the image-to-text role.
pub struct ComposeRole {
    subs: [TypedSubscriber<PerceptionState>; 4],
    held: [Option<Box<PerceptionState>>; 4],
    out: TypedPublisher<PerceptionState>,
    pending: Option<(u64, u64)>,
    done_frame: u64,
    /// Which of text, detections and cues have ever arrived (bit i: `subs[i]`).
    kinds_seen: u8,
    join_ns: u64,
    occupancy_max_age_ns: u64,
    state: Box<PerceptionState>,
    seq: u64,
}

const TEXT: usize = 0;
const DETS: usize = 1;
const CUES: usize = 2;
const OCC: usize = 3;

impl Role for ComposeRole {
    type Kind = kinds::ImageToText;

    fn new(ctx: &mut RoleContext<kinds::ImageToText>) -> Result<Self, RoleError> {
        if ctx.spec.variant == "vlm" {
            return Err(ConfigError::NoWeights(NO_CAPTIONING_WEIGHTS).into());
        }
        Ok(Self {
            subs: [
                ctx.bus.subscriber::<topics::PerceptionText>()?,
                ctx.bus.subscriber::<topics::PerceptionDetections>()?,
                ctx.bus.subscriber::<topics::PerceptionCues>()?,
                ctx.bus.subscriber::<topics::PerceptionOccupancy>()?,
            ],
            held: [None, None, None, None],
            out: ctx.bus.publisher::<topics::PerceptionState>()?,
            pending: None,
            done_frame: 0,
            kinds_seen: 0,
            join_ns: (ctx.spec.param_f64("join_ms").unwrap_or(1500.0).max(0.0) * 1e6) as u64,
            occupancy_max_age_ns: occupancy_max_age_ns(
                ctx.spec
                    .timing
                    .heartbeat_period_ms
                    .saturating_mul(1_000_000),
            ),
            state: Box::default(),
            seq: 0,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::ImageToText>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        for (i, (sub, slot)) in self.subs.iter().zip(self.held.iter_mut()).enumerate() {
            if let Some(s) = sub.latest()?
                && s.validate().is_ok()
            {
                if i != OCC {
                    self.kinds_seen |= 1 << i;
                }
                if s.frame_seq > self.done_frame
                    && self.pending.is_none_or(|(f, _)| s.frame_seq > f)
                {
                    self.pending = Some((s.frame_seq, now));
                }
                *slot = Some(Box::new(s));
            }
        }
        let Some((frame, since)) = self.pending else {
            return Ok(CycleOutcome::Idle);
        };
        // blocks of this frame; occupancy may come from the newest frame it has
        let of_frame = |i: usize| self.held[i].as_deref().filter(|s| s.frame_seq == frame);
        let cue_ready = of_frame(CUES).is_some();
        let all_kinds_ready = frame_complete(self.kinds_seen, |i| of_frame(i).is_some());
        if !cue_ready && !all_kinds_ready && now.saturating_sub(since) < self.join_ns {
            return Ok(CycleOutcome::Idle);
        }
        self.pending = None;
        self.done_frame = frame;
        let occupancy = self.held[OCC].as_deref();
        let t0 = monotonic_ns();
        compose(
            of_frame(TEXT),
            of_frame(DETS),
            of_frame(CUES),
            occupancy,
            self.occupancy_max_age_ns,
            &mut self.state,
        );
        report.stage("compose", monotonic_ns() - t0);
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.out.publish(&self.state)?;
        report.counters = ComposeCounters {
            states: self.seq,
            blocks: self.state.blocks.count_ones() as u64,
        }
        .to_heartbeat();
        Ok(CycleOutcome::Worked)
    }
}

/// Whether every kind of block in `kinds_seen` (bits over text, detections, cues) is held
/// for the frame (`held(i)`); never for no kind at all.
fn frame_complete(kinds_seen: u8, held: impl Fn(usize) -> bool) -> bool {
    kinds_seen != 0
        && [TEXT, DETS, CUES]
            .into_iter()
            .all(|i| kinds_seen & (1 << i) == 0 || held(i))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_complete_when_every_kind_seen_is_there() {
        let text_and_dets = (1 << TEXT) | (1 << DETS);
        assert!(frame_complete(text_and_dets, |i| i == TEXT || i == DETS));
        assert!(!frame_complete(text_and_dets, |i| i == TEXT));
        // cues seen once: they are waited for too
        assert!(!frame_complete(text_and_dets | (1 << CUES), |i| i != CUES));
        assert!(!frame_complete(0, |_| true));
    }
    use aeris_schemas::OCCUPANCY_UNKNOWN;

    #[test]
    fn composes_every_block_and_a_bounded_summary() {
        let mut text = PerceptionState {
            frame_seq: 7,
            blocks: block::TEXT,
            cue_count: 2,
            ..PerceptionState::default()
        };
        text.cues[0].text = FixedText::from_str_truncated("LAKE");
        text.cues[1].text = FixedText::from_str_truncated("VIEW");
        let mut dets = PerceptionState {
            frame_seq: 7,
            detection_count: 1,
            ..PerceptionState::default()
        };
        dets.detections[0].label = FixedText::from_str_truncated("bus");
        dets.detections[0].bbox = [0.4, 0.2, 0.2, 0.5];
        dets.detections[0].range_m = 21.3;
        let mut cues = PerceptionState {
            frame_seq: 7,
            cue_count: 1,
            relevance_count: 3,
            ..PerceptionState::default()
        };
        cues.cues[0].text = FixedText::from_str_truncated("a sign that says LAKE VIEW");
        cues.cues[0].score = 0.61;
        cues.subgoal_relevance[2] = 0.61;
        let mut occ = PerceptionState {
            frame_seq: 7,
            ..PerceptionState::default()
        };
        occ.occupancy = aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0);
        occ.occupancy.cells[5] = 12;
        let mut s = PerceptionState::default();
        let age = occupancy_max_age_ns(2_000_000_000);
        compose(
            Some(&text),
            Some(&dets),
            Some(&cues),
            Some(&occ),
            age,
            &mut s,
        );
        assert_eq!(
            s.summary.as_str(),
            Some("reads \"LAKE VIEW\"; bus ahead 21 m; cue: a sign that says LAKE VIEW (0.61)")
        );
        assert_eq!(read_text(&s), Some("LAKE VIEW"));
        assert_eq!(s.blocks, block::ALL);
        assert_eq!(s.frame_seq, 7);
        assert_eq!(s.subgoal_relevance(), &[0.0, 0.0, 0.61]);
        assert_eq!(s.occupancy.cells[5], 12);
        assert_eq!(s.occupancy.status(), Some(OccupancyStatus::Present));
        assert!(s.validate().is_ok());
        // a missing block is simply absent
        compose(None, Some(&dets), None, None, age, &mut s);
        assert_eq!(s.blocks, block::DETECTIONS | block::SUMMARY);
        assert_eq!(s.occupancy.cells[5], OCCUPANCY_UNKNOWN);
        assert_eq!(s.occupancy.status(), Some(OccupancyStatus::Absent));
        // a huge text stays inside the summary's bound
        text.cues[0].text = FixedText::from_str_truncated(&"W".repeat(500));
        for c in text.cues.iter_mut() {
            c.text = FixedText::from_str_truncated(&"X".repeat(60));
        }
        text.cue_count = 8;
        compose(Some(&text), Some(&dets), None, None, age, &mut s);
        assert!(s.validate().is_ok());
    }

    #[test]
    fn occupancy_is_absent_without_a_block_and_stale_when_old() {
        let period = 2_000_000_000u64;
        let age = occupancy_max_age_ns(period);
        assert_eq!(age, 3_000_000_000, "1.5 heartbeats");
        let dets = |capture_ns| PerceptionState {
            frame_seq: 40,
            capture_ns,
            detection_count: 0,
            ..PerceptionState::default()
        };
        let mut occ = PerceptionState {
            frame_seq: 20,
            capture_ns: 10_000_000_000,
            blocks: block::OCCUPANCY,
            ..PerceptionState::default()
        };
        occ.occupancy = aeris_schemas::OccupancyGrid::observed([1.0, 2.0], 2.0);
        occ.occupancy.cells.fill(0);
        let mut s = PerceptionState::default();
        // no depth source: no occupancy block ever came -> absent, not an empty grid
        compose(None, Some(&dets(12_000_000_000)), None, None, age, &mut s);
        assert_eq!(s.occupancy.status(), Some(OccupancyStatus::Absent));
        assert!(!s.has(block::OCCUPANCY));
        // a block one heartbeat older than the frame (the occupancy role's last interval)
        compose(
            None,
            Some(&dets(12_000_000_000)),
            None,
            Some(&occ),
            age,
            &mut s,
        );
        assert_eq!(s.occupancy.status(), Some(OccupancyStatus::Present));
        assert!(s.occupancy.is_present() && s.has(block::OCCUPANCY));
        // exactly 1.5 heartbeats old: still present; older: stale, kept for diagnostics
        compose(
            None,
            Some(&dets(13_000_000_000)),
            None,
            Some(&occ),
            age,
            &mut s,
        );
        assert!(s.occupancy.is_present());
        compose(
            None,
            Some(&dets(13_000_000_001)),
            None,
            Some(&occ),
            age,
            &mut s,
        );
        assert_eq!(s.occupancy.status(), Some(OccupancyStatus::Stale));
        assert!(!s.occupancy.is_present());
        assert_eq!(s.occupancy.origin, [1.0, 2.0]);
        assert_eq!(s.validate(), Ok(()));
    }
}
