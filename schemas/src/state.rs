//! The typed state S_t (perception -> reasoning / hub), MISSION §2.

use crate::text::FixedText;
use crate::{MAX_SUBGOALS, all_finite};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Maximum bytes of the scene summary S-bar_t.
pub const SUMMARY_MAX: usize = 512;
/// k of the top-k detections I_t.
pub const MAX_DETECTIONS: usize = 16;
/// k of the top-k instruction cues C_t.
pub const MAX_CUES: usize = 8;
/// Side of the ego occupancy grid O_t in cells.
pub const OCCUPANCY_SIDE: usize = 64;
/// Number of cells of O_t.
pub const OCCUPANCY_CELLS: usize = OCCUPANCY_SIDE * OCCUPANCY_SIDE;
/// Cell value meaning "not observed".
pub const OCCUPANCY_UNKNOWN: u8 = 255;
/// Maximum bytes of a detection label.
pub const LABEL_MAX: usize = 32;
/// Maximum bytes of a cue text.
pub const CUE_MAX: usize = 64;

/// Which blocks of S_t a [`PerceptionState`] carries (bits of `blocks`).
///
/// The perception roles each publish one block on their own topic (a state with only that
/// bit set); the image-to-text role composes them into the full S_t on `perception/state`.
pub mod block {
    /// Scene text read from signs: `summary` holds the texts joined by `" | "`, `cues`
    /// the regions (text, reader confidence).
    pub const TEXT: u32 = 1 << 0;
    /// Object detections in `detections`.
    pub const DETECTIONS: u32 = 1 << 1;
    /// Instruction cues in `cues`, and `subgoal_relevance`.
    pub const CUES: u32 = 1 << 2;
    /// The occupancy grid in `occupancy`.
    pub const OCCUPANCY: u32 = 1 << 3;
    /// The composed scene summary in `summary`.
    pub const SUMMARY: u32 = 1 << 4;
    /// Every block.
    pub const ALL: u32 = TEXT | DETECTIONS | CUES | OCCUPANCY | SUMMARY;
}

/// One detection: class, score and box.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
pub struct Detection {
    /// Class label (e.g. "building", "red roof").
    pub label: FixedText<LABEL_MAX>,
    /// Class index in the detector's label set.
    pub class_id: u32,
    /// Score in [0, 1].
    pub score: f32,
    /// Box `[x, y, w, h]` normalised to [0, 1] image coordinates.
    pub bbox: [f32; 4],
    /// Estimated range in metres (0 = unknown).
    pub range_m: f32,
}

impl Default for Detection {
    fn default() -> Self {
        Self {
            label: FixedText::new(),
            class_id: 0,
            score: 0.0,
            bbox: [0.0; 4],
            range_m: 0.0,
        }
    }
}

/// One instruction cue: a phrase with a relevance score.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct Cue {
    /// Cue text.
    pub text: FixedText<CUE_MAX>,
    /// Score in [0, 1].
    pub score: f32,
}

/// Whether the occupancy block of S_t holds observations a consumer may use
/// ([`OccupancyGrid::status`] is the wire byte).
///
/// "Absent" is not "empty": a present grid whose cells are all free or all unknown is what a
/// depth sensor saw; an absent or stale one says nothing about the space around the vehicle,
/// and the hub's gate and the planner treat that space as unknown, not as free (they keep to
/// the geofence and [`crate::DecisionLimits::blind_altitude`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum OccupancyStatus {
    /// No grid: no depth source, or none received yet. The cells mean nothing.
    Absent = 0,
    /// Built from a recent depth frame: the cells are observations.
    Present = 1,
    /// The last grid, built from a depth frame older than its producer's freshness rule
    /// allows (the depth source stopped): kept for diagnostics only, used as absent.
    Stale = 2,
}

impl OccupancyStatus {
    /// Every status, in wire order.
    pub const ALL: [OccupancyStatus; 3] = [
        OccupancyStatus::Absent,
        OccupancyStatus::Present,
        OccupancyStatus::Stale,
    ];

    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        Self::ALL.iter().copied().find(|s| *s as u8 == v)
    }

    /// Lower-case name, as logs and reports print it.
    pub fn name(self) -> &'static str {
        match self {
            OccupancyStatus::Absent => "absent",
            OccupancyStatus::Present => "present",
            OccupancyStatus::Stale => "stale",
        }
    }
}

/// Ego-centred, north-aligned 2.5-D occupancy grid O_t.
///
/// Cell `(row, col)` covers north offset `(row - SIDE/2) * resolution` and east offset
/// `(col - SIDE/2) * resolution` from `origin` (the vehicle position when it was built).
/// A cell holds the height in metres of the highest obstacle top seen there, 0 for free
/// ground, [`OCCUPANCY_UNKNOWN`] for not observed. Only a grid whose `status` is
/// [`OccupancyStatus::Present`] carries observations ([`OccupancyGrid::is_present`]).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
pub struct OccupancyGrid {
    /// Grid centre `[N, E]` in metres.
    pub origin: [f32; 2],
    /// Metres per cell (> 0 when present).
    pub resolution_m: f32,
    /// [`OccupancyStatus`] wire byte (a raw byte: a sample from another process is decoded
    /// with [`OccupancyStatus::from_u8`], never transmuted).
    pub status: u8,
    /// Reserved, zero.
    pub reserved: [u8; 3],
    /// Cell heights, row-major (row = north index).
    pub cells: [u8; OCCUPANCY_CELLS],
}

impl Default for OccupancyGrid {
    /// An absent grid: no observations, every cell unknown.
    fn default() -> Self {
        Self {
            origin: [0.0; 2],
            resolution_m: 0.0,
            status: OccupancyStatus::Absent as u8,
            reserved: [0; 3],
            cells: [OCCUPANCY_UNKNOWN; OCCUPANCY_CELLS],
        }
    }
}

impl OccupancyGrid {
    /// A present grid centred on `origin` with cells of `resolution_m`, nothing observed
    /// yet (every cell unknown): what a producer fills from a depth frame.
    pub fn observed(origin: [f32; 2], resolution_m: f32) -> Self {
        Self {
            origin,
            resolution_m,
            status: OccupancyStatus::Present as u8,
            ..Self::default()
        }
    }

    /// The grid's status; `None` for a byte that is no [`OccupancyStatus`].
    pub fn status(&self) -> Option<OccupancyStatus> {
        OccupancyStatus::from_u8(self.status)
    }

    /// `true` when the grid carries usable observations: status
    /// [`OccupancyStatus::Present`] and a positive resolution.
    pub fn is_present(&self) -> bool {
        self.status == OccupancyStatus::Present as u8 && self.resolution_m > 0.0
    }

    /// Cell index of the point `[N, E]`, if the grid is present and the point inside it.
    pub fn cell_of(&self, p: [f32; 2]) -> Option<usize> {
        if !self.is_present() {
            return None;
        }
        let half = (OCCUPANCY_SIDE / 2) as f32;
        let r = ((p[0] - self.origin[0]) / self.resolution_m + half).floor();
        let c = ((p[1] - self.origin[1]) / self.resolution_m + half).floor();
        if r >= 0.0 && c >= 0.0 && (r as usize) < OCCUPANCY_SIDE && (c as usize) < OCCUPANCY_SIDE {
            Some(r as usize * OCCUPANCY_SIDE + c as usize)
        } else {
            None
        }
    }

    /// Obstacle top height at `[N, E]`: `Some(h)` when observed, `None` when unknown,
    /// outside the grid, or the grid is not present.
    pub fn height_at(&self, p: [f32; 2]) -> Option<f32> {
        let v = self.cells[self.cell_of(p)?];
        (v != OCCUPANCY_UNKNOWN).then_some(v as f32)
    }
}

/// The typed state S_t (`perception/state`).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::PerceptionState@s8")]
#[repr(C)]
pub struct PerceptionState {
    /// Publisher sequence number.
    pub seq: u64,
    /// Sequence number of the frame this state was computed from.
    pub frame_seq: u64,
    /// CLOCK_MONOTONIC ns of that frame's capture (start of the semantic cycle).
    pub capture_ns: u64,
    /// CLOCK_MONOTONIC ns at which the state was published.
    pub publish_ns: u64,
    /// Vehicle position at capture `[N, E, U]`.
    pub position: [f32; 3],
    /// Vehicle yaw at capture (rad).
    pub yaw: f32,
    /// Scene summary S-bar_t.
    pub summary: FixedText<SUMMARY_MAX>,
    /// Number of valid entries in `detections`.
    pub detection_count: u32,
    /// Number of valid entries in `cues`.
    pub cue_count: u32,
    /// Top-k detections I_t, best first.
    pub detections: [Detection; MAX_DETECTIONS],
    /// Top-k instruction cues C_t, best first.
    pub cues: [Cue; MAX_CUES],
    /// Ego occupancy O_t (its `status` says whether it is present, absent or stale).
    pub occupancy: OccupancyGrid,
    /// Which blocks this state carries ([`block`] bits).
    pub blocks: u32,
    /// Number of valid entries in `subgoal_relevance` (the mission's L, or 0).
    pub relevance_count: u32,
    /// Relevance of the state to each subgoal g_i, in [0, 1] (cosine similarity of sentence
    /// embeddings of the state's text and cues with the subgoal's text, clamped at 0);
    /// the hub's ATT uses it when present.
    pub subgoal_relevance: [f32; MAX_SUBGOALS],
}

impl Default for PerceptionState {
    fn default() -> Self {
        Self {
            seq: 0,
            frame_seq: 0,
            capture_ns: 0,
            publish_ns: 0,
            position: [0.0; 3],
            yaw: 0.0,
            summary: FixedText::new(),
            detection_count: 0,
            cue_count: 0,
            detections: [Detection::default(); MAX_DETECTIONS],
            cues: [Cue::default(); MAX_CUES],
            occupancy: OccupancyGrid::default(),
            blocks: 0,
            relevance_count: 0,
            subgoal_relevance: [0.0; MAX_SUBGOALS],
        }
    }
}

/// Why a state is unusable.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum StateError {
    /// `detection_count` exceeds [`MAX_DETECTIONS`].
    #[error("detection count {0} exceeds {MAX_DETECTIONS}")]
    TooManyDetections(u32),
    /// `cue_count` exceeds [`MAX_CUES`].
    #[error("cue count {0} exceeds {MAX_CUES}")]
    TooManyCues(u32),
    /// A text field is not UTF-8 or its length is out of range.
    #[error("text field `{0}` is corrupt")]
    CorruptText(&'static str),
    /// A number is NaN/inf or a score/box is outside [0, 1].
    #[error("field `{0}` is not finite or out of range")]
    BadNumber(&'static str),
}

impl PerceptionState {
    /// The valid detections.
    pub fn detections(&self) -> &[Detection] {
        &self.detections[..(self.detection_count as usize).min(MAX_DETECTIONS)]
    }

    /// The valid cues.
    pub fn cues(&self) -> &[Cue] {
        &self.cues[..(self.cue_count as usize).min(MAX_CUES)]
    }

    /// The valid subgoal relevances (empty when no cue extractor scored this state).
    pub fn subgoal_relevance(&self) -> &[f32] {
        &self.subgoal_relevance[..(self.relevance_count as usize).min(MAX_SUBGOALS)]
    }

    /// `true` when every bit of `blocks` is set.
    pub fn has(&self, blocks: u32) -> bool {
        self.blocks & blocks == blocks
    }

    /// Deterministic validation of every block.
    pub fn validate(&self) -> Result<(), StateError> {
        if self.detection_count as usize > MAX_DETECTIONS {
            return Err(StateError::TooManyDetections(self.detection_count));
        }
        if self.cue_count as usize > MAX_CUES {
            return Err(StateError::TooManyCues(self.cue_count));
        }
        if self.relevance_count as usize > MAX_SUBGOALS {
            return Err(StateError::BadNumber("relevance_count"));
        }
        if self.blocks & !block::ALL != 0 {
            return Err(StateError::BadNumber("blocks"));
        }
        if !self
            .subgoal_relevance()
            .iter()
            .all(|v| (0.0..=1.0).contains(v))
        {
            return Err(StateError::BadNumber("subgoal_relevance"));
        }
        if !all_finite(&self.position) || !self.yaw.is_finite() {
            return Err(StateError::BadNumber("position"));
        }
        if !self.summary.is_valid() {
            return Err(StateError::CorruptText("summary"));
        }
        let unit = |v: f32| (0.0..=1.0).contains(&v);
        for d in self.detections() {
            if !d.label.is_valid() {
                return Err(StateError::CorruptText("detections.label"));
            }
            let numbers_ok = unit(d.score)
                && d.bbox.iter().all(|v| unit(*v))
                && d.range_m >= 0.0
                && d.range_m.is_finite();
            if !numbers_ok {
                return Err(StateError::BadNumber("detections"));
            }
        }
        for c in self.cues() {
            if !c.text.is_valid() {
                return Err(StateError::CorruptText("cues.text"));
            }
            if !unit(c.score) {
                return Err(StateError::BadNumber("cues.score"));
            }
        }
        let o = &self.occupancy;
        let grid_ok = all_finite(&o.origin) && (0.0..=100.0).contains(&o.resolution_m);
        if !grid_ok {
            return Err(StateError::BadNumber("occupancy"));
        }
        match o.status() {
            None => return Err(StateError::BadNumber("occupancy.status")),
            // a present grid must be usable: cells of some size
            Some(OccupancyStatus::Present) if o.resolution_m <= 0.0 => {
                return Err(StateError::BadNumber("occupancy.resolution_m"));
            }
            Some(_) => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_state_is_valid() {
        assert_eq!(PerceptionState::default().validate(), Ok(()));
    }

    #[test]
    fn rejects_corrupt_blocks() {
        let mut s = PerceptionState {
            detection_count: 17,
            ..PerceptionState::default()
        };
        assert_eq!(s.validate(), Err(StateError::TooManyDetections(17)));
        s.detection_count = 1;
        s.detections[0].score = f32::NAN;
        assert_eq!(s.validate(), Err(StateError::BadNumber("detections")));
        s.detections[0].score = 0.5;
        assert_eq!(s.validate(), Ok(()));
        s.occupancy.resolution_m = f32::INFINITY;
        assert_eq!(s.validate(), Err(StateError::BadNumber("occupancy")));
        s.occupancy.resolution_m = 2.0;
        s.occupancy.status = 7;
        assert_eq!(s.validate(), Err(StateError::BadNumber("occupancy.status")));
        s.occupancy.status = OccupancyStatus::Present as u8;
        s.relevance_count = 2;
        s.subgoal_relevance[1] = 1.5;
        assert_eq!(
            s.validate(),
            Err(StateError::BadNumber("subgoal_relevance"))
        );
        s.subgoal_relevance[1] = 0.5;
        s.blocks = 1 << 9;
        assert_eq!(s.validate(), Err(StateError::BadNumber("blocks")));
        s.blocks = block::ALL;
        assert_eq!(s.validate(), Ok(()));
        assert!(s.has(block::TEXT | block::CUES));
    }

    #[test]
    fn occupancy_cells_map_to_points() {
        let mut g = OccupancyGrid::observed([10.0, 20.0], 2.0);
        let i = g.cell_of([10.0, 20.0]).unwrap();
        assert_eq!(i, 32 * OCCUPANCY_SIDE + 32);
        g.cells[i] = 12;
        assert_eq!(g.height_at([10.5, 21.9]), Some(12.0));
        assert_eq!(g.height_at([10.0, 18.0]), None); // unknown cell
        assert_eq!(g.cell_of([10.0 + 65.0, 20.0]), None);
    }

    #[test]
    fn absent_is_not_present_and_empty() {
        // the default S_t carries no occupancy: absent, valid, and nothing reads its cells
        let absent = PerceptionState::default();
        assert_eq!(absent.validate(), Ok(()));
        assert_eq!(absent.occupancy.status(), Some(OccupancyStatus::Absent));
        assert!(!absent.occupancy.is_present());
        // a present grid in which nothing was seen yet (every cell unknown), or all free
        let mut empty = PerceptionState {
            occupancy: OccupancyGrid::observed([0.0, 0.0], 2.0),
            ..PerceptionState::default()
        };
        assert_eq!(empty.validate(), Ok(()));
        assert!(empty.occupancy.is_present());
        assert_eq!(empty.occupancy.height_at([1.0, 1.0]), None);
        empty.occupancy.cells.fill(0);
        assert_eq!(empty.occupancy.height_at([1.0, 1.0]), Some(0.0));
        // the same cells, absent or stale, are not observations
        for status in [OccupancyStatus::Absent, OccupancyStatus::Stale] {
            let mut g = empty.occupancy;
            g.status = status as u8;
            assert!(!g.is_present(), "{status:?}");
            assert_eq!(g.height_at([1.0, 1.0]), None, "{status:?}");
        }
        // present needs cells of some size
        empty.occupancy.resolution_m = 0.0;
        assert_eq!(
            empty.validate(),
            Err(StateError::BadNumber("occupancy.resolution_m"))
        );
    }

    #[test]
    fn occupancy_status_bytes_round_trip() {
        for s in OccupancyStatus::ALL {
            assert_eq!(OccupancyStatus::from_u8(s as u8), Some(s));
        }
        assert_eq!(OccupancyStatus::from_u8(3), None);
        assert_eq!(OccupancyStatus::Absent.name(), "absent");
    }
}
