//! What a grounded step takes in from S_t: its landmark's sightings (and which are of
//! another landmark), what the reader read of a quoted sign (and the signs rejected for it),
//! the touchdown beside a landmark, and the transit height over what the grid shows.

use super::geometry::{ahead, ground_distance, transit_altitude};
use super::{
    APPROACH_LEG_M, CORRIDOR_M, DESCENT_AROUND_M, GROUNDED_REACH_M, LOOKAHEAD_M, OBSTACLE_MARGIN_M,
    Planner, READ_RANGE_M, SAME_PLACE_M, TOUCHDOWN_CLEAR_M, TOUCHDOWN_KEEP_M,
};
use crate::grounding::{LandmarkPhrase, Relation, SignReading, sight, sign_reading};
use crate::height_map::CELL_M;
use aeris_schemas::{Detection, FixedText, PerceptionState};

/// The memory of a grounded step: where its landmark was seen and how the search goes.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Search {
    /// Heading to search along, fixed when the step starts.
    pub(super) heading: Option<f32>,
    /// The landmark's ground point `[N, E]` from its latest ranged sighting.
    pub(super) found: Option<[f32; 2]>,
    /// A point being flown to: toward an unranged sighting, or a search leg.
    pub(super) toward: Option<[f32; 2]>,
    /// Heartbeats spent scanning at the current spot.
    pub(super) scan: usize,
    /// Search legs flown.
    pub(super) legs: u32,
    /// Signs seen close up that read otherwise than the step quotes (ground points).
    pub(super) rejected: [Option<[f32; 2]>; 4],
    /// Signs rejected so far.
    pub(super) rejections: usize,
    /// A sign read close up as another text: where, and how many times in a row.
    pub(super) strike: Option<([f32; 2], u8)>,
    /// The quoted text was read close to the landmark found.
    pub(super) confirmed: bool,
    /// Heartbeats spent at the sign found without reading the quoted text there.
    pub(super) unread: u32,
    /// Where a step to a quoted sign reads it: in front of the face of its board nearer
    /// the vehicle ([`crate::height_map::HeightMap::board`]); `None` until the map shows the board.
    pub(super) face: Option<[f32; 2]>,
    /// The centre of the board whose face is [`Search::face`].
    pub(super) board: Option<[f32; 2]>,
    /// Where a "land next to" step touches down: beside the landmark's footprint, on
    /// ground the flight has seen clear ([`crate::height_map::HeightMap::next_to`]).
    pub(super) touchdown: Option<[f32; 2]>,
    /// Where the vehicle was when the step began: "land next to X" comes down on the side
    /// of X facing it, as the instruction's author would picture it.
    pub(super) origin: Option<[f32; 2]>,
    /// Where a landing given up after the search legs comes down (kept while the map shows
    /// no obstacle within a cell of it).
    pub(super) given_up: Option<[f32; 2]>,
    /// Heartbeats waited over the stand-off point for a clear touchdown.
    pub(super) waited: u32,
    /// An occupancy grid came with S_t during this step (else there is no clear ground
    /// to wait for).
    pub(super) grid_seen: bool,
}

impl Planner {
    /// Take in what `state` shows of the landmark of the step in progress and of the
    /// obstacles ahead.
    pub(super) fn observe(
        &mut self,
        phrase: &LandmarkPhrase,
        position: [f32; 3],
        state: Option<&PerceptionState>,
    ) {
        self.search.origin.get_or_insert([position[0], position[1]]);
        let Some(s) = state else {
            return;
        };
        // not this step's landmark: one an earlier step found that is certainly another
        // (a sign with another text), or a sign this step rejected
        let (camera, visited, rejected) = (
            &self.camera,
            &self.visited[..self.current],
            &self.search.rejected,
        );
        let elsewhere = |d: &Detection| {
            let Some(p) = sight(d, s.position, s.yaw, camera).point else {
                return true;
            };
            let near = |q: &[f32; 2]| ground_distance(p, *q) <= SAME_PLACE_M;
            !visited
                .iter()
                .flatten()
                .any(|(q, other)| phrase.differs_from(other) && near(q))
                && !rejected.iter().flatten().any(near)
        };
        // a sign close enough to read that reads otherwise is not the quoted one
        let quoted = phrase.sign_text.as_str_lossy();
        let read = crate::compose::read_text(s);
        let reading = match read {
            Some(read) if !quoted.is_empty() => sign_reading(read, quoted),
            _ => SignReading::Nothing,
        };
        if let Some(d) = phrase.best_match_where(s, elsewhere) {
            let seen = sight(d, s.position, s.yaw, &self.camera);
            let close = seen
                .point
                .filter(|p| ground_distance(*p, [s.position[0], s.position[1]]) <= READ_RANGE_M);
            if reading == SignReading::Quoted && close.is_some() {
                self.search.confirmed = true;
            }
            // a misreading (one frame at a slant) must not cost the right sign: two
            // readings of another text at the same place, and none of the quoted one
            let strikes = match (reading, close, self.search.strike) {
                (SignReading::Other, Some(p), Some((q, n)))
                    if ground_distance(p, q) <= SAME_PLACE_M =>
                {
                    n + 1
                }
                (SignReading::Other, Some(_), _) => 1,
                _ => 0,
            };
            if let Some(p) = close
                && strikes > 0
            {
                self.search.strike = Some((p, strikes));
            }
            if strikes >= 2
                && !self.search.confirmed
                && let Some(p) = close
            {
                self.search.strike = None;
                let slot = self.search.rejections % self.search.rejected.len();
                self.search.rejected[slot] = Some(p);
                self.search.rejections += 1;
                self.rejections += 1;
                self.last_rejection = Some((p, FixedText::from_str_truncated(read.unwrap_or(""))));
                self.search.found = None;
                self.search.toward = None;
                self.search.scan = 0;
                self.search.unread = 0;
                self.search.face = None;
                return;
            }
            match seen.point {
                Some(p) => {
                    self.search.found = Some(p);
                    self.search.toward = None;
                }
                None if self.search.found.is_none() => {
                    // toward it, unless the fence is in the way
                    let t =
                        self.ground_inside_fence(ahead(s.position, seen.bearing, APPROACH_LEG_M));
                    if ground_distance(t, [position[0], position[1]]) > GROUNDED_REACH_M {
                        self.search.toward = Some(t);
                    }
                }
                None => {}
            }
        }
        self.search.grid_seen |= s.occupancy.is_present();
        if let (Some(p), Relation::NextTo) = (self.search.found, phrase.relation) {
            let here = [position[0], position[1]];
            let from = self.search.origin.unwrap_or(here);
            // a better point replaces the one chosen, except once the vehicle is over it
            let previous = self.search.touchdown;
            let over = previous.is_some_and(|t| ground_distance(here, t) <= GROUNDED_REACH_M);
            let keep_m = if over {
                f32::INFINITY
            } else {
                TOUCHDOWN_KEEP_M
            };
            // over it, the touchdown stays while the cells around it are free ground: the
            // landmark's sighting can drift onto a neighbour (another footprint) and a wall
            // seen in the descent can spoil its wider clear square, and either made the dense
            // landing climb away to another point and come back for the rest of the episode.
            // One cell around it, not only its own: the hub's grid is centred on the vehicle,
            // so its cells straddle this map's, and a roof in a neighbouring cell of this map
            // can share the hub's cell of the touchdown, whose descent the gate then refuses
            // every heartbeat (the landing beside a building held at 10-20 m till time ran out)
            self.search.touchdown = match previous {
                Some(t) if over && self.map.is_clear(t, CELL_M) => Some(t),
                _ => self
                    .map
                    .next_to(p, from, TOUCHDOWN_CLEAR_M, previous, keep_m),
            };
        }
        let goal = self
            .search
            .found
            .or(self.search.toward)
            .unwrap_or([position[0], position[1]]);
        // what this frame's grid shows on the way (0 without a grid)
        let seen_ahead = transit_altitude(s, position, goal, 0.0);
        self.transit = self.transit.max(seen_ahead).min(self.h_max - 1.0);
        // back down once the height map knows everything around the vehicle and on the way
        // clears a lower height: over open ground after a tall landmark, a sign can be read
        // only from close to it (PP-OCR reads the billboards from about 30 m)
        let here = [position[0], position[1]];
        let (top, known) =
            self.map
                .top_along(here, goal, CORRIDOR_M, DESCENT_AROUND_M, LOOKAHEAD_M);
        if known {
            let needed = (top + OBSTACLE_MARGIN_M)
                .max(seen_ahead)
                .max(self.cruise_height);
            if needed < self.transit {
                self.transit = needed;
            }
        }
    }
}
