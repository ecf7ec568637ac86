//! Cue extractor (kind `cues`, variant `minilm`): the scene text and detection labels of a
//! frame, embedded with all-MiniLM-L6-v2 through ONNX Runtime and compared with each
//! subgoal of the instruction -> the cue block of S_t on `perception/cues`: the top-k
//! phrases with their best cosine similarity to a subgoal, and the relevance of the frame
//! to every subgoal (`subgoal_relevance`, what the hub's ATT scores).
//!
//! Blocks of one frame are joined by `frame_seq`; a block whose partner has not arrived
//! after `join_ms` (default 1000) is scored alone. Parameters: `join_ms`, `threads`
//! (default 1), `models_dir`. Heartbeat counters: [`BlockCounters`] (items:
//! phrases scored in the last block).

use crate::vision::{open_store, session_options};
use aeris_models::embed::Embedding;
use aeris_models::{TextEmbedder, cosine};
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::error_chain::chain;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    BlockCounters, Cue, FixedText, MAX_CUES, MAX_DETECTIONS, MAX_SUBGOALS, PerceptionState, block,
    topics,
};
use core::time::Duration;

/// Poll period.
pub const PERIOD: Duration = Duration::from_millis(20);

/// The phrases of a frame worth scoring: each text read (and all of them together, when
/// there are several), then each distinct detection label. At most `MAX_CUES +
/// MAX_DETECTIONS + 1`.
pub fn phrases(text: Option<&PerceptionState>, dets: Option<&PerceptionState>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    if let Some(t) = text {
        for c in t.cues() {
            let s = c.text.as_str_lossy().trim();
            if !s.is_empty() {
                out.push(format!("a sign that says {s}"));
            }
        }
        if t.cue_count > 1 {
            let all: Vec<&str> = t
                .cues()
                .iter()
                .map(|c| c.text.as_str_lossy().trim())
                .collect();
            out.push(format!("a sign that says {}", all.join(" ")));
        }
    }
    if let Some(d) = dets {
        for det in d.detections() {
            let label = det.label.as_str_lossy().trim().to_string();
            if !label.is_empty() && !out.contains(&label) {
                out.push(label);
            }
        }
    }
    out.truncate(MAX_CUES + MAX_DETECTIONS + 1);
    out
}

/// Score `phrases` (embedded as `embedded`) against the subgoal embeddings: fill the cue
/// block of `state` (top-k phrases by best similarity, clamped to [0, 1]) and its
/// `subgoal_relevance` (per subgoal, the best similarity of any phrase, clamped at 0).
pub fn score_phrases(
    phrases: &[String],
    embedded: &[Embedding],
    subgoals: &[Embedding],
    state: &mut PerceptionState,
) {
    let l = subgoals.len().min(MAX_SUBGOALS);
    state.relevance_count = l as u32;
    state.subgoal_relevance = [0.0; MAX_SUBGOALS];
    let mut scored: Vec<(f32, usize)> = Vec::with_capacity(phrases.len());
    for (p, e) in embedded.iter().enumerate() {
        let mut best = 0.0f32;
        for (i, g) in subgoals.iter().take(l).enumerate() {
            let c = cosine(e, g).clamp(0.0, 1.0);
            best = best.max(c);
            state.subgoal_relevance[i] = state.subgoal_relevance[i].max(c);
        }
        scored.push((best, p));
    }
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut n = 0;
    for &(score, p) in scored.iter().take(MAX_CUES) {
        state.cues[n] = Cue {
            text: FixedText::from_str_truncated(&phrases[p]),
            score,
        };
        n += 1;
    }
    state.cue_count = n as u32;
}

/// The cue-extractor role.
pub struct CueRole {
    texts: TypedSubscriber<PerceptionState>,
    detections: TypedSubscriber<PerceptionState>,
    out: TypedPublisher<PerceptionState>,
    embedder: TextEmbedder,
    subgoals: Vec<Embedding>,
    text: Option<Box<PerceptionState>>,
    dets: Option<Box<PerceptionState>>,
    /// Newest frame seen in any block and when it was first seen.
    pending: Option<(u64, u64)>,
    done_frame: u64,
    join_ns: u64,
    embedded: Vec<Embedding>,
    state: Box<PerceptionState>,
    seq: u64,
}

impl Role for CueRole {
    type Kind = kinds::Cues;

    fn new(ctx: &mut RoleContext<kinds::Cues>) -> Result<Self, RoleError> {
        let store = open_store(ctx)?;
        let mut embedder = TextEmbedder::load(&store, &session_options(ctx)?)
            .map_err(|e| RoleError::step("loading the sentence embedder", e))?;
        let texts: Vec<&str> = ctx
            .spec
            .mission
            .subgoals
            .iter()
            .map(|s| s.text.as_str())
            .collect();
        let mut subgoals = Vec::new();
        embedder
            .embed_into(&texts, &mut subgoals)
            .map_err(|e| RoleError::step("embedding the mission's subgoals", e))?;
        Ok(Self {
            texts: ctx.bus.subscriber::<topics::PerceptionText>()?,
            detections: ctx.bus.subscriber::<topics::PerceptionDetections>()?,
            out: ctx.bus.publisher::<topics::PerceptionCues>()?,
            embedder,
            subgoals,
            text: None,
            dets: None,
            pending: None,
            done_frame: 0,
            join_ns: (ctx.spec.param_f64("join_ms").unwrap_or(1000.0).max(0.0) * 1e6) as u64,
            embedded: Vec::with_capacity(MAX_CUES + MAX_DETECTIONS + 1),
            state: Box::default(),
            seq: 0,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Cues>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        for (sub, slot) in [
            (&self.texts, &mut self.text),
            (&self.detections, &mut self.dets),
        ] {
            if let Some(s) = sub.latest()?
                && s.validate().is_ok()
                && s.frame_seq > self.done_frame
            {
                if self.pending.is_none_or(|(f, _)| s.frame_seq > f) {
                    self.pending = Some((s.frame_seq, now));
                }
                *slot = Some(Box::new(s));
            }
        }
        let Some((frame, since)) = self.pending else {
            return Ok(CycleOutcome::Idle);
        };
        fn of_frame(b: &Option<Box<PerceptionState>>, frame: u64) -> Option<&PerceptionState> {
            b.as_deref().filter(|s| s.frame_seq == frame)
        }
        let (text, dets) = (of_frame(&self.text, frame), of_frame(&self.dets, frame));
        if (text.is_none() || dets.is_none()) && now.saturating_sub(since) < self.join_ns {
            return Ok(CycleOutcome::Idle);
        }
        let Some(base) = text.or(dets) else {
            return Ok(CycleOutcome::Idle);
        };
        let t0 = monotonic_ns();
        let phrases = phrases(text, dets);
        let refs: Vec<&str> = phrases.iter().map(String::as_str).collect();
        let (frame_seq, capture_ns, position, yaw) =
            (base.frame_seq, base.capture_ns, base.position, base.yaw);
        self.pending = None;
        self.done_frame = frame;
        if let Err(e) = self.embedder.embed_into(&refs, &mut self.embedded) {
            tracing::warn!("cues: frame {frame}: {}", chain(&e));
            return Ok(CycleOutcome::Idle);
        }
        *self.state = PerceptionState::default();
        self.state.frame_seq = frame_seq;
        self.state.capture_ns = capture_ns;
        self.state.position = position;
        self.state.yaw = yaw;
        self.state.blocks = block::CUES;
        score_phrases(&phrases, &self.embedded, &self.subgoals, &mut self.state);
        report.stage("embed", monotonic_ns() - t0);
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.out.publish(&self.state)?;
        BlockCounters::update(&mut report.counters, |c| {
            c.blocks = self.seq;
            c.items = phrases.len() as u64;
        });
        Ok(CycleOutcome::Worked)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(v: &[f32]) -> Embedding {
        let mut e = [0.0; aeris_models::EMBEDDING_DIM];
        let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
        for (i, x) in v.iter().enumerate() {
            e[i] = x / n;
        }
        e
    }

    #[test]
    fn phrases_come_from_text_and_labels_without_repeats() {
        let mut t = PerceptionState {
            cue_count: 2,
            ..PerceptionState::default()
        };
        t.cues[0].text = FixedText::from_str_truncated("LAKE");
        t.cues[1].text = FixedText::from_str_truncated("VIEW");
        let mut d = PerceptionState {
            detection_count: 3,
            ..PerceptionState::default()
        };
        for (i, l) in ["bus", "person", "bus"].iter().enumerate() {
            d.detections[i].label = FixedText::from_str_truncated(l);
        }
        let p = phrases(Some(&t), Some(&d));
        assert_eq!(
            p,
            vec![
                "a sign that says LAKE",
                "a sign that says VIEW",
                "a sign that says LAKE VIEW",
                "bus",
                "person"
            ]
        );
        assert!(phrases(None, None).is_empty());
    }

    #[test]
    fn relevance_is_the_best_phrase_per_subgoal_and_cues_are_ranked() {
        let subgoals = [unit(&[1.0, 0.0, 0.0]), unit(&[0.0, 1.0, 0.0])];
        let phrases = vec!["a".to_string(), "b".to_string(), "c".to_string()];
        let embedded = [
            unit(&[0.6, 0.8, 0.0]),
            unit(&[1.0, 0.0, 0.0]),
            unit(&[-1.0, 0.0, 0.0]),
        ];
        let mut s = PerceptionState::default();
        score_phrases(&phrases, &embedded, &subgoals, &mut s);
        assert_eq!(s.relevance_count, 2);
        assert!((s.subgoal_relevance[0] - 1.0).abs() < 1e-6);
        assert!((s.subgoal_relevance[1] - 0.8).abs() < 1e-6);
        assert_eq!(s.cues[0].text.as_str(), Some("b"));
        assert_eq!(s.cues[2].text.as_str(), Some("c"));
        assert_eq!(s.cues[2].score, 0.0, "negative similarity clamps at 0");
        assert!(s.validate().is_ok());
    }
}
