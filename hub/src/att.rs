//! ATT: attention-subgoal alignment (MISSION §4).
//!
//! The instruction is segmented into H subgoals g_1..g_H ([`segment_instruction`] for an
//! instruction that comes without explicit subgoals). Every new state S_t, [`Attention`]
//! scores `e_i = f_att(S_t, g_i) + prior_i + bonus_i`, normalises `alpha = softmax(e / T)`
//! and picks the active subgoal `i* = argmax alpha`, with monotone progress (see
//! [`AttentionPrior`]). The sequence of `i*` is the attention trace.
//!
//! `f_att` is pluggable ([`AttentionScorer`]): [`EmbeddingScorer`] reads the subgoal
//! relevance the cue extractor computed from sentence embeddings (all-MiniLM-L6-v2 of the
//! state's text and cues against each subgoal) and falls back to [`LexicalScorer`] (word
//! overlap) for states that carry no cue block. Scoring and updating never allocate.

use aeris_schemas::{MAX_SUBGOALS, PerceptionState, block};

/// Split an instruction into subgoal texts.
///
/// Splits on sentence ends (`.`, `!`, `?` followed by white space or the end, so `2.5 m` is
/// kept whole), new lines, `;`, `, then`, ` then ` and ` and then ` (case-insensitive);
/// pieces are trimmed of white space and punctuation, a leading `then` / `and then` is
/// dropped, and empty pieces are skipped. The result is not capped: callers keep at most
/// [`MAX_SUBGOALS`].
pub fn segment_instruction(instruction: &str) -> Vec<String> {
    // Longest separators first, so ", and then" wins over " then ".
    const SEPARATORS: [&str; 5] = [", and then ", " and then ", ", then ", ", then", " then "];
    let bytes = instruction.as_bytes();
    let mut out = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        let sentence_end = matches!(b, b'.' | b'!' | b'?')
            && bytes.get(i + 1).is_none_or(|n| n.is_ascii_whitespace());
        if sentence_end || b == b';' || b == b'\n' {
            push_piece(&mut out, &instruction[start..i]);
            i += 1;
            start = i;
            continue;
        }
        // Separators are ASCII, so a match starts and ends on character boundaries.
        if let Some(sep) = SEPARATORS.iter().find(|s| {
            bytes.len() - i >= s.len() && bytes[i..i + s.len()].eq_ignore_ascii_case(s.as_bytes())
        }) {
            push_piece(&mut out, &instruction[start..i]);
            i += sep.len();
            start = i;
            continue;
        }
        i += 1;
    }
    push_piece(&mut out, &instruction[start..]);
    out
}

fn push_piece(out: &mut Vec<String>, piece: &str) {
    let is_trim = |c: char| c.is_whitespace() || matches!(c, ',' | '.' | '!' | '?' | ';' | ':');
    let mut p = piece.trim_matches(is_trim);
    for lead in ["and then ", "then "] {
        if p.len() >= lead.len() && p.as_bytes()[..lead.len()].eq_ignore_ascii_case(lead.as_bytes())
        {
            p = p[lead.len()..].trim_matches(is_trim);
        }
    }
    if !p.is_empty() {
        out.push(p.to_string());
    }
}

/// The compatibility function `f_att(S_t, g_i)`: how well state `state` matches subgoal
/// `index` (0-based). Built once per mission from the subgoal texts.
///
/// Implementations must not allocate in `score` (it runs in the hub's hot path) and
/// should return a finite value; [`Attention`] treats NaN/inf as 0.
pub trait AttentionScorer {
    /// Score of subgoal `index` (0-based) under `state`; larger means more compatible.
    fn score(&mut self, state: &PerceptionState, index: usize) -> f32;
}

/// Words that carry no subgoal identity (function words and generic motion verbs).
const STOPWORDS: &[&str] = &[
    "a", "about", "above", "after", "again", "all", "along", "an", "and", "around", "at", "before",
    "by", "continue", "do", "down", "each", "every", "fly", "for", "from", "go", "head", "heading",
    "in", "into", "is", "it", "its", "make", "meter", "meters", "metre", "metres", "move", "near",
    "next", "of", "off", "on", "once", "onto", "or", "over", "proceed", "reach", "see", "some",
    "that", "the", "then", "there", "this", "to", "toward", "towards", "until", "up", "via",
    "when", "where", "with", "you", "your",
];

fn is_stopword(word: &str) -> bool {
    STOPWORDS.iter().any(|s| s.eq_ignore_ascii_case(word))
}

/// Crude plural stemming without allocation: the stem is `prefix` followed by `tail`.
///
/// `cities -> city`, `boxes -> box`, `churches -> church`, `glasses -> glass`,
/// `buildings -> building`, `houses -> house`; words ending in `ss`, `us`, `is` are kept.
fn stem(word: &str) -> (&str, &'static str) {
    let b = word.as_bytes();
    let n = b.len();
    let ends = |s: &str| n >= s.len() && b[n - s.len()..].eq_ignore_ascii_case(s.as_bytes());
    // Every suffix tested is ASCII, so cutting it leaves a character boundary.
    if n > 4 && ends("ies") {
        return (&word[..n - 3], "y");
    }
    if n > 4 && (ends("sses") || ends("xes") || ends("ches") || ends("shes") || ends("zzes")) {
        return (&word[..n - 2], "");
    }
    if n > 3 && ends("s") && !ends("ss") && !ends("us") && !ends("is") {
        return (&word[..n - 1], "");
    }
    (word, "")
}

/// `true` when `word` (any case) stems to `stem_lower` (stored lower-case).
fn matches_stem(word: &str, stem_lower: &str) -> bool {
    let (prefix, tail) = stem(word);
    let s = stem_lower.as_bytes();
    s.len() == prefix.len() + tail.len()
        && s[..prefix.len()].eq_ignore_ascii_case(prefix.as_bytes())
        && &s[prefix.len()..] == tail.as_bytes()
}

/// Words of `text`: maximal runs of alphanumeric characters.
fn words(text: &str) -> impl Iterator<Item = &str> {
    text.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
}

/// Weight of a match in the scene summary.
const SUMMARY_WEIGHT: f32 = 1.0;

/// Lexical `f_att`: lower-cased word overlap between a subgoal's content words and the
/// state's texts.
///
/// Content words are the subgoal's words minus stopwords, one-letter words and numbers,
/// plural-stemmed and de-duplicated (precomputed in [`LexicalScorer::new`]). Each content
/// word contributes the best weight among its matches in the state: 1.0 in the scene
/// summary, `0.5 + 0.5 * score` in a detection label, `0.5 + score` in an instruction cue
/// (cues are extracted *for* the instruction, so they weigh most). The score is the sum over
/// content words divided by their number, in `[0, 1.5]`; 0 for a subgoal without content
/// words.
#[derive(Debug, Clone)]
pub struct LexicalScorer {
    subgoal_words: Vec<Vec<String>>,
    best: Vec<f32>,
}

impl LexicalScorer {
    /// Precompute the content words of every subgoal text (index = subgoal index).
    pub fn new<S: AsRef<str>>(subgoals: &[S]) -> Self {
        let subgoal_words: Vec<Vec<String>> = subgoals
            .iter()
            .map(|text| {
                let mut list: Vec<String> = Vec::new();
                for w in words(text.as_ref()) {
                    if w.chars().count() < 2
                        || w.chars().all(|c| c.is_ascii_digit())
                        || is_stopword(w)
                    {
                        continue;
                    }
                    let (prefix, tail) = stem(w);
                    let mut s = String::with_capacity(prefix.len() + tail.len());
                    s.push_str(prefix);
                    s.push_str(tail);
                    s.make_ascii_lowercase();
                    if !list.contains(&s) {
                        list.push(s);
                    }
                }
                list
            })
            .collect();
        let most = subgoal_words.iter().map(Vec::len).max().unwrap_or(0);
        Self {
            subgoal_words,
            best: vec![0.0; most],
        }
    }

    /// The content words of subgoal `index` (stemmed, lower-case).
    pub fn content_words(&self, index: usize) -> &[String] {
        self.subgoal_words.get(index).map_or(&[], Vec::as_slice)
    }

    fn credit(best: &mut [f32], list: &[String], text: &str, weight: f32) {
        for w in words(text) {
            for (slot, s) in best.iter_mut().zip(list) {
                if weight > *slot && matches_stem(w, s) {
                    *slot = weight;
                }
            }
        }
    }
}

impl AttentionScorer for LexicalScorer {
    fn score(&mut self, state: &PerceptionState, index: usize) -> f32 {
        let Some(list) = self.subgoal_words.get(index) else {
            return 0.0;
        };
        if list.is_empty() {
            return 0.0;
        }
        let best = &mut self.best[..list.len()];
        best.fill(0.0);
        Self::credit(best, list, state.summary.as_str_lossy(), SUMMARY_WEIGHT);
        for d in state.detections() {
            let w = 0.5 + 0.5 * unit(d.score);
            Self::credit(best, list, d.label.as_str_lossy(), w);
        }
        for c in state.cues() {
            let w = 0.5 + unit(c.score);
            Self::credit(best, list, c.text.as_str_lossy(), w);
        }
        best.iter().sum::<f32>() / list.len() as f32
    }
}

/// Default gain of [`EmbeddingScorer`]: cosine similarities of related phrases differ from
/// unrelated ones by ~0.2-0.4; times 3 that is comparable to the progress prior.
pub const EMBEDDING_GAIN: f32 = 3.0;

/// `f_att` from sentence embeddings: `gain * subgoal_relevance[i]` of the state (cosine
/// similarity in [0, 1], computed by the cue extractor); a state without a cue block is
/// scored by the lexical fallback.
pub struct EmbeddingScorer {
    gain: f32,
    fallback: LexicalScorer,
}

impl EmbeddingScorer {
    /// A scorer with `gain` (non-finite or negative: [`EMBEDDING_GAIN`]) and the lexical
    /// fallback for `subgoals`.
    pub fn new<S: AsRef<str>>(subgoals: &[S], gain: f32) -> Self {
        Self {
            gain: if gain.is_finite() && gain >= 0.0 {
                gain
            } else {
                EMBEDDING_GAIN
            },
            fallback: LexicalScorer::new(subgoals),
        }
    }
}

impl AttentionScorer for EmbeddingScorer {
    fn score(&mut self, state: &PerceptionState, index: usize) -> f32 {
        let relevance = state.subgoal_relevance();
        if state.has(block::CUES) && !relevance.is_empty() {
            self.gain * relevance.get(index).copied().map(unit).unwrap_or(0.0)
        } else {
            self.fallback.score(state, index)
        }
    }
}

fn unit(v: f32) -> f32 {
    if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// The progress prior and its thresholds (all in units of `e`, before the temperature).
///
/// With the current active index `c`:
/// - `e_c += current`, `e_{c+1} += next` (progress favours the current and the next step);
/// - `e_i -= skip_penalty * (i - c - 1)` for `i > c + 1` (skipping ahead needs evidence);
/// - `e_i -= backward_penalty * (c - i)` for `i < c` (monotone progress: going back needs
///   overwhelming evidence);
/// - `e_s += declared_bonus` for the reasoner's declared step `s`;
/// - every score is `evidence_weight * f_att`.
///
/// Backtracking rule: even when an earlier subgoal wins the argmax, the active index only
/// moves back when its `e` exceeds the current subgoal's `e` by more than `backtrack_gap`;
/// otherwise it stays. Forward moves need no gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttentionPrior {
    /// Multiplier of `f_att`.
    pub evidence_weight: f32,
    /// Bonus of the current subgoal.
    pub current: f32,
    /// Bonus of the next subgoal.
    pub next: f32,
    /// Penalty per subgoal skipped beyond the next one.
    pub skip_penalty: f32,
    /// Penalty per step backwards.
    pub backward_penalty: f32,
    /// Bonus of the step the reasoner declared.
    pub declared_bonus: f32,
    /// Margin an earlier subgoal needs over the current one to move the active index back.
    pub backtrack_gap: f32,
}

impl Default for AttentionPrior {
    fn default() -> Self {
        Self {
            evidence_weight: 1.0,
            current: 0.6,
            next: 0.4,
            skip_penalty: 1.0,
            backward_penalty: 1.0,
            declared_bonus: 0.8,
            backtrack_gap: 0.5,
        }
    }
}

impl AttentionPrior {
    fn is_finite(&self) -> bool {
        [
            self.evidence_weight,
            self.current,
            self.next,
            self.skip_penalty,
            self.backward_penalty,
            self.declared_bonus,
            self.backtrack_gap,
        ]
        .iter()
        .all(|v| v.is_finite())
    }
}

/// One ATT update: the attention distribution and the active subgoal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttentionResult {
    /// `alpha` over the subgoals (first H entries valid, the rest 0); sums to 1.
    pub alpha: [f32; MAX_SUBGOALS],
    /// Active subgoal `i*`, 0-based.
    pub active: usize,
}

impl AttentionResult {
    /// All attention on subgoal `active` (0-based, clamped to `subgoals - 1`).
    pub fn one_hot(active: usize, subgoals: usize) -> Self {
        let active = active.min(subgoals.clamp(1, MAX_SUBGOALS) - 1);
        let mut alpha = [0.0; MAX_SUBGOALS];
        alpha[active] = 1.0;
        Self { alpha, active }
    }
}

/// One entry of the attention trace.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TraceEntry {
    /// ATT update number (1-based).
    pub cycle: u64,
    /// Frame sequence number of the state scored.
    pub frame_seq: u64,
    /// Active subgoal after the update, 0-based.
    pub active: usize,
}

/// Why an [`Attention`] could not be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum AttentionError {
    /// The subgoal count is 0 or above [`MAX_SUBGOALS`].
    #[error("attention needs 1..={MAX_SUBGOALS} subgoals, got {0}")]
    SubgoalCount(usize),
    /// The temperature is not finite and positive.
    #[error("attention temperature {0} must be finite and > 0")]
    Temperature(f32),
    /// A prior weight is NaN or infinite.
    #[error("attention prior weights must be finite")]
    Prior,
}

/// The ATT state machine: scorer, temperature, prior, active index and trace.
pub struct Attention {
    scorer: Box<dyn AttentionScorer>,
    subgoals: usize,
    temperature: f32,
    prior: AttentionPrior,
    active: usize,
    updates: u64,
    trace: Vec<TraceEntry>,
    trace_capacity: usize,
    trace_head: usize,
    energies: [f32; MAX_SUBGOALS],
}

impl std::fmt::Debug for Attention {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Attention")
            .field("subgoals", &self.subgoals)
            .field("temperature", &self.temperature)
            .field("prior", &self.prior)
            .field("active", &self.active)
            .field("updates", &self.updates)
            .finish_non_exhaustive()
    }
}

impl Attention {
    /// ATT over `subgoals` subgoals (1..=[`MAX_SUBGOALS`]) with softmax temperature
    /// `temperature` (> 0) and a trace ring of `trace_capacity` entries (0 = no trace).
    pub fn new(
        scorer: Box<dyn AttentionScorer>,
        subgoals: usize,
        temperature: f32,
        prior: AttentionPrior,
        trace_capacity: usize,
    ) -> Result<Self, AttentionError> {
        if subgoals == 0 || subgoals > MAX_SUBGOALS {
            return Err(AttentionError::SubgoalCount(subgoals));
        }
        if !(temperature.is_finite() && temperature > 0.0) {
            return Err(AttentionError::Temperature(temperature));
        }
        if !prior.is_finite() {
            return Err(AttentionError::Prior);
        }
        Ok(Self {
            scorer,
            subgoals,
            temperature,
            prior,
            active: 0,
            updates: 0,
            trace: Vec::with_capacity(trace_capacity),
            trace_capacity,
            trace_head: 0,
            energies: [0.0; MAX_SUBGOALS],
        })
    }

    /// Number of subgoals H.
    pub fn subgoals(&self) -> usize {
        self.subgoals
    }

    /// Current active subgoal, 0-based.
    pub fn active(&self) -> usize {
        self.active
    }

    /// The energies `e` of the last update (first H entries).
    pub fn energies(&self) -> &[f32] {
        &self.energies[..self.subgoals]
    }

    /// Score every subgoal under `state`, normalise and move the active index.
    /// `declared_step` is the reasoner's declared step s-hat (1-based); out-of-range values
    /// are ignored. Never allocates.
    pub fn update(
        &mut self,
        state: &PerceptionState,
        declared_step: Option<u16>,
    ) -> AttentionResult {
        let h = self.subgoals;
        let cur = self.active;
        let p = self.prior;
        let declared = declared_step
            .map(|s| s as usize)
            .filter(|s| (1..=h).contains(s))
            .map(|s| s - 1);
        for i in 0..h {
            let f = self.scorer.score(state, i);
            let f = if f.is_finite() { f } else { 0.0 };
            let mut e = p.evidence_weight * f;
            if i == cur {
                e += p.current;
            } else if i == cur + 1 {
                e += p.next;
            } else if i > cur + 1 {
                e -= p.skip_penalty * (i - cur - 1) as f32;
            } else {
                e -= p.backward_penalty * (cur - i) as f32;
            }
            if declared == Some(i) {
                e += p.declared_bonus;
            }
            // keep e finite whatever the scorer returned
            self.energies[i] = e.clamp(-1e6, 1e6);
        }
        let alpha = softmax(&self.energies[..h], self.temperature);
        let best = argmax(&self.energies[..h]);
        let active = if best < cur && self.energies[best] - self.energies[cur] <= p.backtrack_gap {
            cur
        } else {
            best
        };
        self.active = active;
        self.updates += 1;
        self.record(TraceEntry {
            cycle: self.updates,
            frame_seq: state.frame_seq,
            active,
        });
        AttentionResult { alpha, active }
    }

    fn record(&mut self, entry: TraceEntry) {
        if self.trace_capacity == 0 {
            return;
        }
        if self.trace.len() < self.trace_capacity {
            self.trace.push(entry); // within the capacity reserved in `new`
        } else {
            self.trace[self.trace_head] = entry;
            self.trace_head = (self.trace_head + 1) % self.trace_capacity;
        }
    }

    /// The attention trace, oldest first (at most the capacity given to [`Attention::new`]).
    pub fn trace(&self) -> impl Iterator<Item = &TraceEntry> {
        let (newer, older) = self.trace.split_at(self.trace_head.min(self.trace.len()));
        older.iter().chain(newer.iter())
    }

    /// Number of ATT updates so far.
    pub fn updates(&self) -> u64 {
        self.updates
    }
}

/// Numerically stable softmax of `e / temperature` into a fixed array (rest 0).
fn softmax(e: &[f32], temperature: f32) -> [f32; MAX_SUBGOALS] {
    let mut out = [0.0f32; MAX_SUBGOALS];
    let n = e.len().min(MAX_SUBGOALS);
    if n == 0 {
        return out;
    }
    let max = e[..n].iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut sum = 0.0f32;
    for (o, v) in out.iter_mut().zip(&e[..n]) {
        // (v - max) <= 0, so exp is in (0, 1] and the max term is exactly 1: sum >= 1
        *o = ((v - max) / temperature).exp();
        sum += *o;
    }
    for o in out.iter_mut().take(n) {
        *o = (*o / sum).clamp(0.0, 1.0);
    }
    out
}

/// Index of the largest value; the earliest on ties.
fn argmax(e: &[f32]) -> usize {
    let mut best = 0;
    for (i, v) in e.iter().enumerate() {
        if *v > e[best] {
            best = i;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedding_relevance_moves_attention_and_lexical_covers_states_without_it() {
        let subgoals = [
            "take off",
            "fly to the red roof",
            "land by the LAKE VIEW sign",
        ];
        let mut att = Attention::new(
            Box::new(EmbeddingScorer::new(&subgoals, EMBEDDING_GAIN)),
            3,
            0.5,
            AttentionPrior::default(),
            16,
        )
        .unwrap();
        let mut s = PerceptionState {
            blocks: block::CUES,
            relevance_count: 3,
            frame_seq: 1,
            ..PerceptionState::default()
        };
        // the frame matches the first subgoal: stay
        s.subgoal_relevance[..3].copy_from_slice(&[0.7, 0.2, 0.1]);
        assert_eq!(att.update(&s, None).active, 0);
        // the frame matches the second: progress to it
        s.frame_seq = 2;
        s.subgoal_relevance[..3].copy_from_slice(&[0.1, 0.75, 0.2]);
        let r = att.update(&s, None);
        assert_eq!(r.active, 1);
        assert!(r.alpha[1] > r.alpha[0] && r.alpha[1] > r.alpha[2]);
        // weak evidence for the first again does not move back (monotone progress)
        s.frame_seq = 3;
        s.subgoal_relevance[..3].copy_from_slice(&[0.45, 0.3, 0.1]);
        assert_eq!(att.update(&s, None).active, 1);
        // no cue block: the lexical fallback scores the summary
        let mut plain = PerceptionState {
            frame_seq: 4,
            ..PerceptionState::default()
        };
        plain.summary = aeris_schemas::FixedText::from_str_truncated("LAKE VIEW sign ahead");
        assert_eq!(att.update(&plain, None).active, 2);
        let trace: Vec<(u64, usize)> = att.trace().map(|e| (e.frame_seq, e.active)).collect();
        assert_eq!(trace, vec![(1, 0), (2, 1), (3, 1), (4, 2)]);
    }

    #[test]
    fn segments_on_sentences_and_then() {
        assert_eq!(
            segment_instruction(
                "Take off to 10 m. Fly north 2.5 m past the red roof, then turn left; \
                 hover and then land"
            ),
            vec![
                "Take off to 10 m",
                "Fly north 2.5 m past the red roof",
                "turn left",
                "hover",
                "land"
            ]
        );
        assert_eq!(
            segment_instruction("Go to the tower Then land!"),
            vec!["Go to the tower", "land"]
        );
        assert_eq!(
            segment_instruction("climb. Then fly east, and then land."),
            vec!["climb", "fly east", "land"]
        );
        assert!(segment_instruction(" .; , then ").is_empty());
        assert_eq!(
            segment_instruction("fly to the café"),
            vec!["fly to the café"]
        );
    }

    #[test]
    fn stems_plurals() {
        assert_eq!(stem("cities"), ("cit", "y"));
        assert!(matches_stem("Cities", "city"));
        assert!(matches_stem("boxes", "box"));
        assert!(matches_stem("buildings", "building"));
        assert!(matches_stem("HOUSES", "house"));
        assert!(matches_stem("bus", "bus"));
        assert!(!matches_stem("bu", "bus"));
        assert!(!matches_stem("roof", "roofs"));
    }

    #[test]
    fn lexical_scorer_counts_content_word_overlap() {
        let mut s = LexicalScorer::new(&["fly to the red roofs", "land near the blue tower"]);
        assert_eq!(s.content_words(0), ["red", "roof"]);
        assert_eq!(s.content_words(1), ["land", "blue", "tower"]);
        let mut st = PerceptionState::default();
        st.summary.set("A RED roof ahead, trees left");
        assert!((s.score(&st, 0) - 1.0).abs() < 1e-6);
        assert_eq!(s.score(&st, 1), 0.0);
        st.summary.set("a roof");
        assert!((s.score(&st, 0) - 0.5).abs() < 1e-6);
        // a cue outweighs the summary
        st.cue_count = 1;
        st.cues[0].text.set("red roof");
        st.cues[0].score = 1.0;
        assert!((s.score(&st, 0) - 1.5).abs() < 1e-6);
        assert_eq!(s.score(&st, 7), 0.0);
    }
}
