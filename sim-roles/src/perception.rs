//! Geometric perception (kind `perception`, variant `geometric`): RGB + depth frames ->
//! the typed state S_t (MISSION §2).
//!
//! Per frame pair (same `seq` on `camera/rgb` and `camera/depth`):
//! - **segment**: every pixel is classified by colour against the palette of the built-in
//!   worlds ([`aeris_sim::world::palette`], times the renderer's face shades) through a
//!   32768-entry lookup table; per class it accumulates pixel count, bounding box, mean
//!   column and a range histogram. Each class seen on at least [`MIN_PIXELS`] pixels
//!   becomes one [`Detection`](aeris_schemas::Detection) (label from [`LABELS`], score from its pixel share, range =
//!   median distance of its pixels);
//! - **occupancy**: every depth return is back-projected with the frame's pose, field of
//!   view and the shared camera model into `[N, E, U]`
//!   ([`aeris_roles::depth_occupancy::fill_occupancy`], as the `occupancy` role does); each
//!   cell of the 64x64, 2 m grid centred on the vehicle keeps the highest obstacle top seen
//!   (ground returns give 0, cells without returns stay unknown);
//! - **summary**: instruction cues (detection labels whose words overlap a subgoal's words,
//!   score = overlap x detection score) and a bounded scene summary such as
//!   `"red roof ahead-right 34 m; road ahead; lake left"`.
//!
//! [`perceive`] is the whole pipeline as a pure function (tests run it on rendered frames);
//! the role keeps a [`Segmenter`] so that processing a frame never touches the heap.
//!
//! Heartbeat counters: [`GeometricPerceptionCounters`].

use aeris_geometry::{CAMERA_MOUNT_HEIGHT_M, CAMERA_PITCH_RAD, CameraModel, CameraModelError};
use aeris_roles::depth_occupancy::fill_occupancy;
use aeris_runtime::bus::{FrameSample, FrameSubscriber, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{CycleOutcome, CycleReport, MissionSpec, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    Cue, FixedText, FrameError, FrameFormat, FrameHeader, GeometricPerceptionCounters, MAX_CUES,
    MAX_DETECTIONS, PerceptionState, block, topics,
};
use aeris_sim::render::FACE_SHADES;
use aeris_sim::world::palette;
use core::time::Duration;

/// Cycle period of the role.
pub const PERIOD: Duration = Duration::from_millis(20);
/// Detection labels; a detection's `class_id` indexes this table.
pub const LABELS: [&str; 12] = [
    "helipad",
    "road",
    "building",
    "red roof",
    "beige building",
    "blue water tower",
    "lake",
    "yellow sign",
    "tree",
    "blue roof",
    "green roof",
    "bridge",
];
/// Fewest pixels of a class that make a detection.
pub const MIN_PIXELS: u32 = 12;
/// Pixel share at which a detection's score reaches 1 - 1/e (score = 1 - exp(-share / this)).
pub const SCORE_SHARE_SCALE: f32 = 0.01;
/// Width of one bin of the per-class range histogram (m).
pub const RANGE_BIN_M: f32 = 0.5;
/// Detections mentioned in the summary.
pub const SUMMARY_ITEMS: usize = 6;

const N_CLASSES: usize = LABELS.len();
const GRASS: u8 = N_CLASSES as u8;
const UNCLASSIFIED: u8 = u8::MAX;
const RANGE_BINS: usize = 256;
const LUT_LEN: usize = 1 << 15;
/// Largest L1 colour distance (over the three channels) still matched to a palette colour.
const COLOUR_TOLERANCE: u32 = 30;

/// `(class, colour, ground patch)`: ground patches are only ever seen from above (shade 1).
const PALETTE: [(u8, [u8; 3], bool); 16] = [
    (0, palette::HELIPAD, true),
    (1, palette::ROAD, true),
    (2, palette::GREY_WALL, false),
    (2, palette::GREY_ROOF, false),
    (3, palette::RED_ROOF, false),
    (4, palette::BEIGE_WALL, false),
    (5, palette::TOWER_BLUE, false),
    (5, palette::TOWER_TOP, false),
    (6, palette::WATER, true),
    (7, palette::SIGN_YELLOW, false),
    (8, palette::TREE_SIDE, false),
    (8, palette::TREE_TOP, false),
    (9, palette::BLUE_ROOF, false),
    (10, palette::GREEN_ROOF, false),
    (11, palette::BRIDGE, false),
    (GRASS, palette::GRASS, true),
];

/// Why a frame pair could not be perceived.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PerceiveError {
    /// The RGB header does not describe the RGB payload.
    #[error("rgb frame: {0}")]
    Rgb(FrameError),
    /// The header given for the RGB payload is not an RGB8 header.
    #[error("the rgb frame's header has format {0}, expected RGB8")]
    NotRgb(u8),
    /// The depth payload does not match the frame's size.
    #[error("depth frame is {actual} bytes, expected {expected}")]
    DepthLength {
        /// Expected bytes.
        expected: usize,
        /// Actual bytes.
        actual: usize,
    },
    /// The RGB and depth frames of one `seq` disagree (size, pose, time) or one is invalid.
    #[error("the rgb and depth frames of one seq do not match or are invalid")]
    PairMismatch,
    /// The camera geometry is unusable.
    #[error("camera geometry: {0}")]
    Geometry(CameraModelError),
}

/// The words of each subgoal of the instruction, lower-cased; built once per mission.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InstructionWords {
    subgoals: Vec<Vec<String>>,
}

impl InstructionWords {
    /// Words of each text (one text per subgoal), split at anything not alphanumeric.
    pub fn new<'a>(texts: impl IntoIterator<Item = &'a str>) -> Self {
        let subgoals = texts
            .into_iter()
            .map(|t| {
                t.split(|c: char| !c.is_alphanumeric())
                    .filter(|w| !w.is_empty())
                    .map(|w| w.to_lowercase())
                    .collect()
            })
            .collect();
        Self { subgoals }
    }

    /// The words of the mission's subgoal texts.
    pub fn from_mission(mission: &MissionSpec) -> Self {
        Self::new(mission.subgoals.iter().map(|s| s.text.as_str()))
    }

    /// Number of subgoals.
    pub fn len(&self) -> usize {
        self.subgoals.len()
    }

    /// `true` when there are no subgoals.
    pub fn is_empty(&self) -> bool {
        self.subgoals.is_empty()
    }

    /// Best share, over the subgoals, of `label`'s words (space separated, lower case) that
    /// occur in one subgoal (allowing plural and `-ed`/`-ing` forms). Never allocates.
    pub fn overlap(&self, label: &str) -> f32 {
        let total = label.split(' ').filter(|w| !w.is_empty()).count();
        if total == 0 {
            return 0.0;
        }
        self.subgoals
            .iter()
            .map(|words| {
                let hits = label
                    .split(' ')
                    .filter(|lw| !lw.is_empty() && words.iter().any(|w| word_matches(lw, w)))
                    .count();
                hits as f32 / total as f32
            })
            .fold(0.0, f32::max)
    }
}

/// `true` when `word` is `base` or `base` with a plural / participle suffix.
fn word_matches(base: &str, word: &str) -> bool {
    word == base
        || word
            .strip_prefix(base)
            .is_some_and(|rest| matches!(rest, "s" | "es" | "ed" | "ing"))
}

#[derive(Debug, Clone, Copy)]
struct ClassAcc {
    pixels: u32,
    min_col: u32,
    max_col: u32,
    min_row: u32,
    max_row: u32,
    sum_col: u64,
    ranged: u32,
    hist: [u32; RANGE_BINS],
}

impl ClassAcc {
    const EMPTY: ClassAcc = ClassAcc {
        pixels: 0,
        min_col: u32::MAX,
        max_col: 0,
        min_row: u32::MAX,
        max_row: 0,
        sum_col: 0,
        ranged: 0,
        hist: [0; RANGE_BINS],
    };

    fn median_range(&self) -> f32 {
        if self.ranged == 0 {
            return 0.0;
        }
        let half = self.ranged.div_ceil(2);
        let mut seen = 0;
        for (i, n) in self.hist.iter().enumerate() {
            seen += n;
            if seen >= half {
                return (i as f32 + 0.5) * RANGE_BIN_M;
            }
        }
        (RANGE_BINS as f32) * RANGE_BIN_M
    }
}

/// The colour lookup table and per-class accumulators: everything a frame needs, allocated
/// once.
pub struct Segmenter {
    lut: Box<[u8; LUT_LEN]>,
    acc: [ClassAcc; N_CLASSES],
}

impl Default for Segmenter {
    fn default() -> Self {
        Self::new()
    }
}

#[inline]
fn lut_index(p: [u8; 3]) -> usize {
    ((p[0] as usize >> 3) << 10) | ((p[1] as usize >> 3) << 5) | (p[2] as usize >> 3)
}

impl Segmenter {
    /// Build the lookup table (each 5-bit-per-channel colour cell -> nearest shaded palette
    /// colour within tolerance).
    pub fn new() -> Self {
        // every colour the renderer can produce for each class
        let mut shaded = [(0u8, [0u8; 3]); PALETTE.len() * FACE_SHADES.len()];
        let mut n = 0;
        for (class, colour, ground) in PALETTE {
            for (k, s) in FACE_SHADES.iter().enumerate() {
                if ground && k > 0 {
                    break;
                }
                shaded[n] = (class, aeris_sim::render::shaded(colour, *s));
                n += 1;
            }
        }
        let shaded = &shaded[..n];
        let mut lut = Box::new([UNCLASSIFIED; LUT_LEN]);
        for (i, slot) in lut.iter_mut().enumerate() {
            let centre = [
                (((i >> 10) & 31) * 8 + 4) as i32,
                (((i >> 5) & 31) * 8 + 4) as i32,
                ((i & 31) * 8 + 4) as i32,
            ];
            let mut best = (u32::MAX, UNCLASSIFIED);
            for (class, c) in shaded {
                let d = (0..3)
                    .map(|k| (centre[k] - c[k] as i32).unsigned_abs())
                    .sum::<u32>();
                if d < best.0 {
                    best = (d, *class);
                }
            }
            if best.0 <= COLOUR_TOLERANCE {
                *slot = best.1;
            }
        }
        Self {
            lut,
            acc: [ClassAcc::EMPTY; N_CLASSES],
        }
    }

    /// Class index into [`LABELS`] of a pixel colour; `None` for grass, sky and anything
    /// unknown.
    pub fn classify(&self, p: [u8; 3]) -> Option<usize> {
        let c = self.lut[lut_index(p)] as usize;
        (c < N_CLASSES).then_some(c)
    }

    /// Run the whole pipeline on one frame pair into `state` (see the module docs);
    /// `stage` receives each stage's name and duration. Never allocates.
    pub fn perceive(
        &mut self,
        rgb: &[u8],
        depth: &[u8],
        header: &FrameHeader,
        words: &InstructionWords,
        state: &mut PerceptionState,
        stage: &mut dyn FnMut(&'static str, u64),
    ) -> Result<(), PerceiveError> {
        let format = header.validate(rgb.len()).map_err(PerceiveError::Rgb)?;
        if format != FrameFormat::Rgb8 {
            return Err(PerceiveError::NotRgb(header.format));
        }
        let expected = header.width as usize * header.height as usize * 2;
        if depth.len() != expected {
            return Err(PerceiveError::DepthLength {
                expected,
                actual: depth.len(),
            });
        }
        let camera =
            CameraModel::with_pitch(header.width, header.height, header.hfov, CAMERA_PITCH_RAD)
                .map_err(PerceiveError::Geometry)?;

        let t0 = monotonic_ns();
        self.segment(rgb, depth, &camera);
        self.fill_detections(&camera, state);
        let t1 = monotonic_ns();
        stage("segment", t1.saturating_sub(t0));

        fill_occupancy(depth, header, &camera, state);
        let t2 = monotonic_ns();
        stage("occupancy", t2.saturating_sub(t1));

        fill_cues(words, state);
        fill_summary(&self.acc, &camera, state);
        let p = header.camera_position;
        state.frame_seq = header.seq;
        state.capture_ns = header.capture_ns;
        state.position = [p[0], p[1], p[2] - CAMERA_MOUNT_HEIGHT_M];
        state.yaw = header.camera_yaw;
        state.blocks = block::DETECTIONS | block::CUES | block::OCCUPANCY | block::SUMMARY;
        stage("summary", monotonic_ns().saturating_sub(t2));
        Ok(())
    }

    fn segment(&mut self, rgb: &[u8], depth: &[u8], camera: &CameraModel) {
        for a in self.acc.iter_mut() {
            *a = ClassAcc::EMPTY;
        }
        let w = camera.width as usize;
        let f = camera.focal_px();
        let (cx, cy) = (0.5 * camera.width as f32, 0.5 * camera.height as f32);
        for (i, (px, dz)) in rgb.chunks_exact(3).zip(depth.chunks_exact(2)).enumerate() {
            let class = self.lut[lut_index([px[0], px[1], px[2]])] as usize;
            if class >= N_CLASSES {
                continue;
            }
            let (col, row) = ((i % w) as u32, (i / w) as u32);
            let a = &mut self.acc[class];
            a.pixels += 1;
            a.min_col = a.min_col.min(col);
            a.max_col = a.max_col.max(col);
            a.min_row = a.min_row.min(row);
            a.max_row = a.max_row.max(row);
            a.sum_col += col as u64;
            let z = u16::from_le_bytes([dz[0], dz[1]]);
            if z > 0 {
                let rx = (col as f32 + 0.5 - cx) / f;
                let ry = (row as f32 + 0.5 - cy) / f;
                // range = z * |axis-scaled ray| = z * sqrt(1 + rx^2 + ry^2)
                let range = z as f32 * 0.001 * (1.0 + rx * rx + ry * ry).sqrt();
                let bin = ((range / RANGE_BIN_M) as usize).min(RANGE_BINS - 1);
                a.hist[bin] += 1;
                a.ranged += 1;
            }
        }
    }

    fn fill_detections(&self, camera: &CameraModel, state: &mut PerceptionState) {
        let total = (camera.width as f32) * (camera.height as f32);
        // (score, class) of the classes seen, best first
        let mut order = [(0.0f32, 0usize); N_CLASSES];
        let mut n = 0;
        for (class, a) in self.acc.iter().enumerate() {
            if a.pixels < MIN_PIXELS {
                continue;
            }
            let share = a.pixels as f32 / total;
            let score = (1.0 - (-share / SCORE_SHARE_SCALE).exp()).clamp(0.0, 1.0);
            let mut k = n;
            while k > 0 && order[k - 1].0 < score {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = (score, class);
            n += 1;
        }
        let n = n.min(MAX_DETECTIONS);
        let (w, h) = (camera.width as f32, camera.height as f32);
        for (slot, (score, class)) in state.detections.iter_mut().zip(order[..n].iter()) {
            let a = &self.acc[*class];
            slot.label.set(LABELS[*class]);
            slot.class_id = *class as u32;
            slot.score = *score;
            slot.bbox = [
                (a.min_col as f32 / w).clamp(0.0, 1.0),
                (a.min_row as f32 / h).clamp(0.0, 1.0),
                ((a.max_col + 1 - a.min_col) as f32 / w).clamp(0.0, 1.0),
                ((a.max_row + 1 - a.min_row) as f32 / h).clamp(0.0, 1.0),
            ];
            slot.range_m = a.median_range();
        }
        for slot in state.detections[n..].iter_mut() {
            *slot = Default::default();
        }
        state.detection_count = n as u32;
    }
}

/// The whole per-frame pipeline as a pure function: classify `rgb` (RGB8, described by
/// `header`), back-project `depth` (u16 LE mm z-depth of the same frame), and fill
/// `state`'s summary, detections, cues, occupancy, `frame_seq`, `capture_ns`, `position`
/// and `yaw` (`seq` and `publish_ns` are the publisher's). Builds a [`Segmenter`] on every
/// call; hot paths keep one and call [`Segmenter::perceive`].
pub fn perceive(
    rgb: &[u8],
    depth: &[u8],
    header: &FrameHeader,
    words: &InstructionWords,
    state: &mut PerceptionState,
) -> Result<(), PerceiveError> {
    Segmenter::new().perceive(rgb, depth, header, words, state, &mut |_, _| {})
}

fn fill_cues(words: &InstructionWords, state: &mut PerceptionState) {
    // (score, detection index), best first
    let mut order = [(0.0f32, 0usize); MAX_DETECTIONS];
    let mut n = 0;
    let count = (state.detection_count as usize).min(MAX_DETECTIONS);
    for (i, d) in state.detections[..count].iter().enumerate() {
        let overlap = words.overlap(d.label.as_str_lossy());
        if overlap <= 0.0 {
            continue;
        }
        let score = (overlap * d.score).clamp(0.0, 1.0);
        let mut k = n;
        while k > 0 && order[k - 1].0 < score {
            order[k] = order[k - 1];
            k -= 1;
        }
        order[k] = (score, i);
        n += 1;
    }
    let n = n.min(MAX_CUES);
    for (slot, (score, i)) in state.cues.iter_mut().zip(order[..n].iter()) {
        slot.text.set(state.detections[*i].label.as_str_lossy());
        slot.score = *score;
    }
    for c in state.cues[n..].iter_mut() {
        *c = Cue::default();
    }
    state.cue_count = n as u32;
}

/// Direction word of a horizontal bearing (rad, positive right).
pub fn direction_word(bearing: f32) -> &'static str {
    let deg = bearing.to_degrees();
    if deg.abs() <= 12.0 {
        "ahead"
    } else if deg.abs() <= 35.0 {
        if deg < 0.0 {
            "ahead-left"
        } else {
            "ahead-right"
        }
    } else if deg < 0.0 {
        "left"
    } else {
        "right"
    }
}

/// Append the decimal digits of `v` to `text` (no allocation).
pub fn push_u32<const N: usize>(text: &mut FixedText<N>, mut v: u32) {
    let mut buf = [0u8; 10];
    let mut i = buf.len();
    loop {
        i -= 1;
        buf[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 || i == 0 {
            break;
        }
    }
    if let Ok(s) = core::str::from_utf8(&buf[i..]) {
        text.push_str(s);
    }
}

fn fill_summary(acc: &[ClassAcc; N_CLASSES], camera: &CameraModel, state: &mut PerceptionState) {
    let summary = &mut state.summary;
    summary.set("");
    let count = (state.detection_count as usize).min(MAX_DETECTIONS);
    if count == 0 {
        summary.set("nothing recognised");
        return;
    }
    for (i, d) in state.detections[..count]
        .iter()
        .take(SUMMARY_ITEMS)
        .enumerate()
    {
        let Some(a) = acc.get(d.class_id as usize) else {
            continue;
        };
        if i > 0 {
            summary.push_str("; ");
        }
        summary.push_str(d.label.as_str_lossy());
        summary.push_str(" ");
        let mean_col = a.sum_col as f32 / a.pixels.max(1) as f32 + 0.5;
        summary.push_str(direction_word(camera.bearing_of_column(mean_col)));
        if d.range_m > 0.0 {
            summary.push_str(" ");
            push_u32(summary, (d.range_m + 0.5) as u32);
            summary.push_str(" m");
        }
    }
}

/// The perception role: newest RGB + depth pair with the same `seq` -> `perception/state`.
pub struct PerceptionRole {
    rgb: FrameSubscriber,
    depth: FrameSubscriber,
    publisher: TypedPublisher<PerceptionState>,
    held_rgb: Option<FrameSample>,
    held_depth: Option<FrameSample>,
    segmenter: Segmenter,
    words: InstructionWords,
    state: Box<PerceptionState>,
    /// `(seq, capture_ns)` of the last frame pair handled (published or rejected).
    last_frame: (u64, u64),
    seq: u64,
    states: u64,
    rejected: u64,
}

impl PerceptionRole {
    fn check_pair(rgb: &FrameSample, depth: &FrameSample) -> bool {
        let (hr, hd) = (rgb.user_header(), depth.user_header());
        matches!(hr.validate(rgb.payload().len()), Ok(FrameFormat::Rgb8))
            && matches!(
                hd.validate(depth.payload().len()),
                Ok(FrameFormat::DepthU16Mm)
            )
            && hr.width == hd.width
            && hr.height == hd.height
            && hr.capture_ns == hd.capture_ns
            && hr.camera_position == hd.camera_position
            && hr.camera_yaw == hd.camera_yaw
            && hr.hfov == hd.hfov
    }
}

impl Role for PerceptionRole {
    type Kind = kinds::Perception;

    fn new(ctx: &mut RoleContext<kinds::Perception>) -> Result<Self, RoleError> {
        let rgb = ctx.bus.frame_subscriber::<topics::CameraRgb>()?;
        let depth = ctx.bus.frame_subscriber::<topics::CameraDepth>()?;
        let publisher = ctx.bus.publisher::<topics::PerceptionState>()?;
        Ok(Self {
            rgb,
            depth,
            publisher,
            held_rgb: None,
            held_depth: None,
            segmenter: Segmenter::new(),
            words: InstructionWords::from_mission(&ctx.spec.mission),
            state: Box::default(),
            last_frame: (0, 0),
            seq: 0,
            states: 0,
            rejected: 0,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Perception>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        // keep the newest sample of each stream (at most one held plus one being received)
        while let Some(s) = self.rgb.next()? {
            self.held_rgb = Some(s);
        }
        while let Some(s) = self.depth.next()? {
            self.held_depth = Some(s);
        }
        report.counters = GeometricPerceptionCounters {
            states: self.states,
            frames_rejected: self.rejected,
        }
        .to_heartbeat();
        let (Some(rgb), Some(depth)) = (&self.held_rgb, &self.held_depth) else {
            return Ok(CycleOutcome::Idle);
        };
        let header = *rgb.user_header();
        let key = (header.seq, header.capture_ns);
        if header.seq != depth.user_header().seq || key == self.last_frame {
            return Ok(CycleOutcome::Idle);
        }
        self.last_frame = key;
        let result = if Self::check_pair(rgb, depth) {
            self.segmenter.perceive(
                rgb.payload(),
                depth.payload(),
                &header,
                &self.words,
                &mut self.state,
                &mut |name, ns| report.stage(name, ns),
            )
        } else {
            Err(PerceiveError::PairMismatch)
        };
        self.held_rgb = None;
        self.held_depth = None;
        if result.is_err() {
            self.rejected += 1;
            GeometricPerceptionCounters::update(&mut report.counters, |c| {
                c.frames_rejected = self.rejected
            });
            return Ok(CycleOutcome::Idle);
        }
        self.seq += 1;
        self.state.seq = self.seq;
        self.state.publish_ns = monotonic_ns();
        self.publisher.publish(&self.state)?;
        self.states += 1;
        GeometricPerceptionCounters::update(&mut report.counters, |c| c.states = self.states);
        Ok(CycleOutcome::Worked)
    }
}
