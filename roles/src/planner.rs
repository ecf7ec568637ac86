//! Reasoning role, first variant: a deterministic planner, a fault injector, and the random
//! baseline of the VLN evaluation ([`RandomRole`]).
//!
//! [`PlannerRole`] turns the mission's subgoals into decisions D_t through exactly the path a
//! language model's decisions take (`reasoning/decision` -> hub gate -> controller). Its
//! memory M_{t-1} is the index of the subgoal in progress; it advances when the vehicle
//! reaches that subgoal's waypoint (or lands, for a land step).
//!
//! [`GarbageRole`] (variant `garbage`) runs the same planner but corrupts most decisions in
//! rotating ways (NaN, infinities, out-of-range fields, unknown actions, bad steps, stale
//! cycle starts, duplicate and skipped sequence numbers) — a hostile reasoner for tests.
//!
//! Both decide once per heartbeat on the first fresh S_t, or on the telemetry alone when no
//! S_t came for a heartbeat and a half ([`HeartbeatClock`]); they poll every 50 ms.
//!
//! Heartbeat counters: `[decisions, subgoal_index (0-based), corrupted, 0, 0, 0, 0, 0]`.

use crate::grounding::{
    LandmarkPhrase, Relation, SignReading, height_of, sight, sign_reading, turn_of,
};
use crate::heartbeat_clock::{Basis, HeartbeatClock};
use crate::height_map::HeightMap;
use aeris_geometry::{CameraModel, wrap_pi};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::spec::CameraSpec;
use aeris_runtime::{
    CycleOutcome, CycleReport, Role, RoleContext, RoleError, bus::TypedPublisher,
    bus::TypedSubscriber,
};
use aeris_schemas::state::CUE_MAX;
use aeris_schemas::{
    ActionMode, Decision, Detection, FixedText, MAX_SUBGOALS, PerceptionState, VehicleTelemetry,
    topics,
};
use core::time::Duration;

/// A turn step is done when the yaw is this close to the bearing of its waypoint.
const TURN_TOLERANCE_RAD: f32 = 0.15;
/// Cruise height (m above the start) of a mission whose take-off names no height.
pub const DEFAULT_CRUISE_HEIGHT_M: f32 = 20.0;
/// "fly to X" / "land next to X" stop this far (m) short of X's seen surface.
pub const STANDOFF_M: f32 = 12.0;
/// Slack (m) on the stand-off point and on "fly over X" when X's position is an estimate.
pub const GROUNDED_REACH_M: f32 = 8.0;
/// Yaw offsets (rad) from the search heading, one heartbeat each, while the landmark of a
/// step is not in view: ahead, then ever wider left/right, then behind.
const SCAN_OFFSETS: [f32; 6] = [0.0, -1.05, 1.05, -2.09, 2.09, core::f32::consts::PI];
/// Length (m) of a search leg along the search heading after a scan found nothing.
pub const SEARCH_LEG_M: f32 = 40.0;
/// Search legs flown before the planner gives up on a landmark and lands where it is.
pub const MAX_SEARCH_LEGS: u32 = 4;
/// A sign seen this close (m) whose text the reader read otherwise than the step quotes
/// is another sign (PP-OCR reads the 8 m billboards from about 30 m).
const READ_RANGE_M: f32 = 30.0;
/// Sightings this close (m) to a landmark an earlier step found are of that landmark.
const SAME_PLACE_M: f32 = 15.0;
/// Length (m) of a leg toward a landmark seen beyond the depth sensor's range.
const APPROACH_LEG_M: f32 = 30.0;
/// Heartbeats a step that quotes a sign's text waits at the sign it found, facing it, for
/// the reader to read the quoted text before it takes the sign unread (a reader that never
/// reads the text must not stop the flight). Sign ground points are estimates that can be
/// 15-20 m off, so a sign rejected from one side can be found again from the other: only
/// a reading at the sign tells them apart.
const READ_WAIT: u32 = 3;
/// Within this (m) of a board's reading point, the vehicle comes down to read it: the
/// camera looks 15 degrees down with a 74-degree vertical field, so a board 8 m tall seen
/// from 12 m in front of it is below the frame from above about 24 m.
const READ_DESCENT_REACH_M: f32 = 3.0;
/// The descent to read a board needs the map to know every cell within this (m) of the
/// reading point, and then keeps [`OBSTACLE_MARGIN_M`] above the highest top there and
/// above the board's.
const READ_CLEAR_M: f32 = 6.0;
/// Heartbeats a landing waits over the stand-off point for clear ground to show.
const TOUCHDOWN_WAIT: u32 = 3;
/// Half-side (m) of the square around a touchdown point that must hold no obstacle.
const TOUCHDOWN_CLEAR_M: f32 = 4.0;
/// A touchdown chosen before is kept unless a point this much (m) nearer to where the
/// step began shows up (and always once the vehicle is over it).
const TOUCHDOWN_KEEP_M: f32 = 4.0;
/// With no touchdown beside the landmark, a landing takes the nearest clear ground within
/// this (m) of its stand-off point rather than come down on whatever is under it.
const FALLBACK_CLEAR_M: f32 = 30.0;
/// Below the transit height by more than this (m), a grounded step climbs in place first.
const CLIMB_FIRST_M: f32 = 3.0;
/// Height (m) kept above the obstacle tops seen on the way.
const OBSTACLE_MARGIN_M: f32 = 6.0;
/// How far ahead (m) the transit height looks at the occupancy grid.
const LOOKAHEAD_M: f32 = 40.0;
/// Half-width (m) of the corridor the transit height clears: the vehicle's clearance.
const CORRIDOR_M: f32 = 4.0;
/// The transit height comes down only when the height map knows every cell this close (m)
/// to the vehicle (what it flies over next, out of the camera's view).
const DESCENT_AROUND_M: f32 = 12.0;

/// Bearing from `from` to `to` (rad, 0 = north, clockwise), or `fallback` when they coincide.
fn heading(from: [f32; 3], to: [f32; 3], fallback: f32) -> f32 {
    let (dn, de) = (to[0] - from[0], to[1] - from[1]);
    if dn.hypot(de) > 1.0 {
        de.atan2(dn)
    } else {
        fallback
    }
}

/// What a step flies to.
#[derive(Debug, Clone, Copy)]
enum StepTarget {
    /// The waypoint the mission gives.
    At([f32; 3]),
    /// The landmark the step's text names, found in S_t.
    Find(LandmarkPhrase),
    /// Neither: done after one decision (a land step lands where it is).
    Here,
}

/// One subgoal as the planner needs it (copied from the mission at start).
#[derive(Debug, Clone, Copy)]
struct Step {
    action: ActionMode,
    target: StepTarget,
    /// Heading change the step's text asks for before it flies (rad).
    turn: f32,
}

/// The memory of a grounded step: where its landmark was seen and how the search goes.
#[derive(Debug, Clone, Copy, Default)]
struct Search {
    /// Heading to search along, fixed when the step starts.
    heading: Option<f32>,
    /// The landmark's ground point `[N, E]` from its latest ranged sighting.
    found: Option<[f32; 2]>,
    /// A point being flown to: toward an unranged sighting, or a search leg.
    toward: Option<[f32; 2]>,
    /// Heartbeats spent scanning at the current spot.
    scan: usize,
    /// Search legs flown.
    legs: u32,
    /// Signs seen close up that read otherwise than the step quotes (ground points).
    rejected: [Option<[f32; 2]>; 4],
    /// Signs rejected so far.
    rejections: usize,
    /// A sign read close up as another text: where, and how many times in a row.
    strike: Option<([f32; 2], u8)>,
    /// The quoted text was read close to the landmark found.
    confirmed: bool,
    /// Heartbeats spent at the sign found without reading the quoted text there.
    unread: u32,
    /// Where a step to a quoted sign reads it: in front of the face of its board nearer
    /// the vehicle ([`HeightMap::board`]); `None` until the map shows the board.
    face: Option<[f32; 2]>,
    /// The centre of the board whose face is [`Search::face`].
    board: Option<[f32; 2]>,
    /// Where a "land next to" step touches down: beside the landmark's footprint, on
    /// ground the flight has seen clear ([`HeightMap::next_to`]).
    touchdown: Option<[f32; 2]>,
    /// Where the vehicle was when the step began: "land next to X" comes down on the side
    /// of X facing it, as the instruction's author would picture it.
    origin: Option<[f32; 2]>,
    /// Heartbeats waited over the stand-off point for a clear touchdown.
    waited: u32,
    /// An occupancy grid came with S_t during this step (else there is no clear ground
    /// to wait for).
    grid_seen: bool,
}

/// The planner's pure logic: memory (the subgoal in progress) and the decision rule.
///
/// A step with a waypoint is flown to it. A step without one (the VLN setting) is grounded
/// in S_t ([`crate::grounding`]): its landmark is looked for among the detections (after
/// the turn its text asks for, then scanning around, then flying search legs), located
/// from the detection's bearing and range, and approached at a height that clears the
/// obstacle tops the occupancy grid shows ahead.
#[derive(Debug, Clone)]
pub struct Planner {
    steps: [Option<Step>; MAX_SUBGOALS],
    count: usize,
    current: usize,
    issued: u32,
    start: [f32; 3],
    cruise: f32,
    radius: f32,
    h_min: f32,
    h_max: f32,
    fence: ([f32; 3], [f32; 3]),
    camera: CameraModel,
    cruise_height: f32,
    /// Height of grounded legs (m): the cruise height, raised over obstacles seen ahead,
    /// lowered again when the height map shows the way and the ground around clear of them.
    transit: f32,
    search: Search,
    /// Where each completed grounded step found its landmark.
    visited: [Option<([f32; 2], LandmarkPhrase)>; MAX_SUBGOALS],
    /// Signs rejected in the whole flight.
    rejections: u64,
    /// The latest rejected sign: its ground point and what it read.
    last_rejection: Option<([f32; 2], FixedText<CUE_MAX>)>,
    /// Every occupancy grid of the flight, in the world frame: where a landing may come
    /// down (the ego grid does not see under the vehicle).
    map: HeightMap,
}

impl Planner {
    /// A planner for the mission in `spec` seen through `camera`; `None` when an action
    /// name is unknown or the camera's geometry is invalid (a validated spec has neither).
    pub fn new(mission: &aeris_runtime::MissionSpec, camera: &CameraSpec) -> Option<Self> {
        let mut steps = [None; MAX_SUBGOALS];
        let mut cruise_height = None;
        for (slot, s) in steps.iter_mut().zip(mission.subgoals.iter()) {
            let action = s.action_mode()?;
            let target = match (s.waypoint, action) {
                (Some(w), _) => StepTarget::At(w),
                (None, ActionMode::Takeoff | ActionMode::Ascend) => {
                    let h = height_of(&s.text).unwrap_or(DEFAULT_CRUISE_HEIGHT_M);
                    StepTarget::At([mission.start[0], mission.start[1], mission.start[2] + h])
                }
                (None, _) => LandmarkPhrase::parse(&s.text)
                    .map(StepTarget::Find)
                    .unwrap_or(StepTarget::Here),
            };
            if let (StepTarget::At(w), ActionMode::Takeoff) = (target, action) {
                cruise_height.get_or_insert(w[2]);
            }
            *slot = Some(Step {
                action,
                target,
                turn: turn_of(&s.text),
            });
        }
        let l = &mission.limits;
        let camera =
            CameraModel::new(camera.width, camera.height, camera.hfov_deg.to_radians()).ok()?;
        Some(Self {
            steps,
            count: mission.subgoals.len().min(MAX_SUBGOALS),
            current: 0,
            issued: 0,
            start: mission.start,
            cruise: mission.cruise_speed,
            radius: mission.acceptance_radius_m,
            h_min: l.h_min,
            h_max: l.h_max,
            fence: (l.geofence_min, l.geofence_max),
            camera,
            cruise_height: cruise_height
                .unwrap_or(mission.start[2] + DEFAULT_CRUISE_HEIGHT_M)
                .clamp(l.h_min, l.h_max),
            transit: 0.0,
            search: Search::default(),
            visited: [None; MAX_SUBGOALS],
            rejections: 0,
            last_rejection: None,
            map: HeightMap::covering(
                [l.geofence_min[0], l.geofence_min[1]],
                [l.geofence_max[0], l.geofence_max[1]],
            ),
        })
    }

    /// Signs rejected so far in the flight (read close up, another text than quoted), and
    /// the latest one's ground point and reading.
    pub fn rejections(&self) -> (u64, Option<([f32; 2], &str)>) {
        (
            self.rejections,
            self.last_rejection
                .as_ref()
                .map(|(p, t)| (*p, t.as_str_lossy())),
        )
    }

    /// Index (0-based) of the subgoal in progress.
    pub fn current(&self) -> usize {
        self.current
    }

    /// Resume at instruction step `step` (1-based, clamped to the mission): a reasoner
    /// that starts during a flight (restart, hot swap) takes the mission up where the hub
    /// has it instead of at its first subgoal.
    pub fn resume(&mut self, step: u16) {
        self.current = (step as usize)
            .saturating_sub(1)
            .min(self.count.saturating_sub(1));
        self.issued = 0;
        self.search = Search::default();
    }

    /// Whether the step in progress is done, given how many decisions were already issued
    /// for it (a hover holds for one heartbeat; stop never completes).
    fn reached(&self, step: &Step, position: [f32; 3], yaw: f32, landed: bool) -> bool {
        let (radius, issued) = (self.radius, self.issued);
        let w = match step.target {
            StepTarget::At(w) => w,
            StepTarget::Here => {
                return match step.action {
                    ActionMode::Land => landed,
                    ActionMode::Stop => false,
                    _ => issued >= 1,
                };
            }
            StepTarget::Find(phrase) => {
                let Some(p) = self.search.found else {
                    return false;
                };
                let d = ground_distance([position[0], position[1]], p);
                let at_touchdown = self.search.touchdown.is_some_and(|t| {
                    ground_distance([position[0], position[1]], t) <= GROUNDED_REACH_M
                });
                return match (step.action, phrase.relation) {
                    (ActionMode::Land, _) => {
                        landed && (at_touchdown || d <= STANDOFF_M + GROUNDED_REACH_M)
                    }
                    (_, Relation::Over) => d <= GROUNDED_REACH_M && self.sign_settled(&phrase),
                    // a board is passed edge-on on the way to its face: not there yet
                    _ => match self.search.face {
                        Some(f) => {
                            ground_distance([position[0], position[1]], f) <= GROUNDED_REACH_M
                                && self.sign_settled(&phrase)
                        }
                        None => d <= STANDOFF_M + GROUNDED_REACH_M && self.sign_settled(&phrase),
                    },
                };
            }
        };
        match step.action {
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend => {
                (position[2] - w[2]).abs() <= 1.0
            }
            ActionMode::Land => landed && horizontal(position, w) <= radius.max(1.0) + 1.0,
            ActionMode::Hover => issued >= 1,
            ActionMode::Turn => {
                issued >= 1 && wrap_pi(heading(position, w, yaw) - yaw).abs() <= TURN_TOLERANCE_RAD
            }
            ActionMode::Stop => false,
            ActionMode::Goto => distance(position, w) <= radius,
        }
    }

    /// For a step to a quoted sign: [`STANDOFF_M`] in front of the face of its board on
    /// the vehicle's side (the side chosen before while it still is one), remembered in
    /// the search. `None` for other steps, or while the map does not show the board.
    fn reading_point(
        &mut self,
        phrase: &LandmarkPhrase,
        p: [f32; 2],
        here: [f32; 2],
    ) -> Option<[f32; 2]> {
        if phrase.sign_text.is_empty() {
            return None;
        }
        let Some((c, n)) = self.map.board(p) else {
            return self.search.face;
        };
        let front = [c[0] + n[0] * STANDOFF_M, c[1] + n[1] * STANDOFF_M];
        let back = [c[0] - n[0] * STANDOFF_M, c[1] - n[1] * STANDOFF_M];
        let toward = self.search.face.unwrap_or(here);
        let face = if ground_distance(toward, front) <= ground_distance(toward, back) {
            front
        } else {
            back
        };
        self.search.face = Some(face);
        self.search.board = Some(c);
        Some(face)
    }

    /// The height from which to read the board of a quoted sign step, once within
    /// [`READ_DESCENT_REACH_M`] of its reading point and below `altitude`: the highest top
    /// the map knows within [`READ_CLEAR_M`] of the point and up to the board, plus
    /// [`OBSTACLE_MARGIN_M`]. `None` (stay at `altitude`) elsewhere, once the sign is
    /// settled, or while the map does not know every cell there.
    fn reading_height(
        &self,
        phrase: &LandmarkPhrase,
        here: [f32; 2],
        altitude: f32,
    ) -> Option<f32> {
        let (face, board) = (self.search.face?, self.search.board?);
        if self.sign_settled(phrase) || ground_distance(here, face) > READ_DESCENT_REACH_M {
            return None;
        }
        let (top, known) = self
            .map
            .top_along(face, board, 0.0, READ_CLEAR_M, STANDOFF_M);
        let height = (top + OBSTACLE_MARGIN_M).max(self.h_min);
        (known && height < altitude).then_some(height)
    }

    /// A step that quotes a sign's text takes the sign it found once the text was read
    /// there, or after [`READ_WAIT`] heartbeats there without a reading; other steps at once.
    fn sign_settled(&self, phrase: &LandmarkPhrase) -> bool {
        phrase.sign_text.is_empty() || self.search.confirmed || self.search.unread >= READ_WAIT
    }

    /// Advance the memory on the vehicle's state and on `state`, the S_t this decision is
    /// based on (`None` for a decision on telemetry alone), and return the decision for
    /// this cycle (timing fields left for the caller).
    pub fn decide(
        &mut self,
        position: [f32; 3],
        yaw: f32,
        landed: bool,
        state: Option<&PerceptionState>,
    ) -> Decision {
        if let Some(s) = state {
            self.map.absorb(&s.occupancy);
        }
        while let Some(step) = self.steps[self.current] {
            if let StepTarget::Find(phrase) = step.target {
                self.observe(&phrase, position, state);
            }
            if self.current + 1 >= self.count || !self.reached(&step, position, yaw, landed) {
                break;
            }
            if let (StepTarget::Find(phrase), Some(p)) = (step.target, self.search.found) {
                self.visited[self.current] = Some((p, phrase));
            }
            self.current += 1;
            self.issued = 0;
            self.search = Search::default();
        }
        self.issued = self.issued.saturating_add(1);
        let step = self.steps[self.current].unwrap_or(Step {
            action: ActionMode::Hover,
            target: StepTarget::Here,
            turn: 0.0,
        });
        let (action, target, altitude, facing) = match step.target {
            StepTarget::At(w) => {
                let (target, altitude) = match step.action {
                    ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend => {
                        ([position[0], position[1], w[2]], w[2])
                    }
                    // land: fly (or stay) over the touchdown point at the current height;
                    // the gate binds the descent to U=0
                    ActionMode::Land => ([w[0], w[1], w[2]], position[2].max(self.h_min).max(w[2])),
                    _ => (w, w[2].max(self.h_min)),
                };
                (step.action, target, altitude, None)
            }
            StepTarget::Here => match step.action {
                ActionMode::Land | ActionMode::Stop => (
                    step.action,
                    [position[0], position[1], 0.0],
                    position[2].max(self.h_min),
                    None,
                ),
                _ => (
                    ActionMode::Hover,
                    position,
                    position[2].max(self.h_min),
                    None,
                ),
            },
            StepTarget::Find(phrase) => {
                let (action, target, altitude, facing) =
                    self.grounded(&step, &phrase, position, yaw);
                self.over_known_tops(position, action, target, altitude, facing)
            }
        };
        let target = self.inside_fence(target);
        let dn = target[0] - position[0];
        let de = target[1] - position[1];
        let heading = match facing {
            Some(h) => h,
            None if dn.hypot(de) > 1.0 => de.atan2(dn),
            None => yaw,
        };
        Decision {
            target,
            yaw: wrap_pi(heading),
            speed: self.cruise,
            altitude: altitude.clamp(self.h_min, self.h_max),
            acceptance_radius: self.radius,
            confidence: 1.0,
            step: (self.current + 1) as u16,
            action: action as u8,
            ..Decision::default()
        }
    }

    /// Take in what `state` shows of the landmark of the step in progress and of the
    /// obstacles ahead.
    fn observe(
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
            // over it, the touchdown stays while its own cell is free ground: the landmark's
            // sighting can drift onto a neighbour (another footprint) and a wall cell seen
            // close by in the descent can spoil its clear square, and either made the dense
            // landing climb away to another point and come back for the rest of the episode
            self.search.touchdown = match previous {
                Some(t) if over && self.map.is_clear(t, 0.0) => Some(t),
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

    /// The decision of a grounded step: `(action, target, altitude, facing)`.
    fn grounded(
        &mut self,
        step: &Step,
        phrase: &LandmarkPhrase,
        position: [f32; 3],
        yaw: f32,
    ) -> (ActionMode, [f32; 3], f32, Option<f32>) {
        let search_heading = *self.search.heading.get_or_insert(wrap_pi(yaw + step.turn));
        let altitude = self.transit.max(self.cruise_height);
        let here = [position[0], position[1]];
        // an obstacle ahead raised the transit height: climb in place before going on
        let climbing = position[2] < altitude - CLIMB_FIRST_M;
        let climb = |facing: Option<f32>| {
            (
                ActionMode::Goto,
                [position[0], position[1], altitude],
                altitude,
                facing,
            )
        };
        if let Some(p) = self.search.found {
            // at a board's reading point, low enough for the camera to see the board
            let reading_height = match (phrase.relation, step.action) {
                (Relation::To, ActionMode::Goto) => self.reading_height(phrase, here, altitude),
                _ => None,
            };
            if climbing && step.action != ActionMode::Land && reading_height.is_none() {
                return climb(Some((p[1] - here[1]).atan2(p[0] - here[0])));
            }
            let goal = match phrase.relation {
                Relation::Over => p,
                Relation::NextTo => self.search.touchdown.unwrap_or_else(|| {
                    let standoff = short_of(here, p, STANDOFF_M);
                    self.map
                        .nearest_clear(standoff, FALLBACK_CLEAR_M, TOUCHDOWN_CLEAR_M)
                        .unwrap_or(standoff)
                }),
                Relation::To => match self.reading_point(phrase, p, here) {
                    Some(face) => face,
                    None => short_of(here, p, STANDOFF_M),
                },
            };

            // no clear ground seen next to it yet: wait over the stand-off point (the grid
            // fills in as the camera looks around), then land there after all
            let waiting = step.action == ActionMode::Land
                && self.search.touchdown.is_none()
                && self.search.grid_seen
                && phrase.relation == Relation::NextTo
                && self.search.waited < TOUCHDOWN_WAIT;
            // where the step goes, facing the sign (down at the reading height, when there is
            // one): a heartbeat its text was not read there
            let down = reading_height.is_none_or(|h| position[2] <= h + CLIMB_FIRST_M);
            if !self.sign_settled(phrase) && ground_distance(here, goal) <= GROUNDED_REACH_M && down
            {
                self.search.unread += 1;
            }
            // a landing by a quoted sign reads it first, as a step that flies to one does
            let waiting =
                waiting || (step.action == ActionMode::Land && !self.sign_settled(phrase));
            if waiting && ground_distance(here, goal) <= GROUNDED_REACH_M {
                self.search.waited += 1;
            }
            let action = if step.action == ActionMode::Land && !waiting {
                ActionMode::Land
            } else {
                ActionMode::Goto
            };
            // a landing approaches at the transit height too: the gate binds the descent
            // once over the touchdown point
            let (u, alt) = if action == ActionMode::Land {
                (0.0, altitude.max(position[2]).max(self.h_min))
            } else {
                let h = reading_height.unwrap_or(altitude);
                (h, h)
            };
            // face the landmark, not the stand-off point, once there
            let facing = ground_distance(here, p) > 1.0;
            let face = facing.then(|| (p[1] - here[1]).atan2(p[0] - here[0]));
            return (action, [goal[0], goal[1], u], alt, face);
        }
        if let Some(t) = self.search.toward {
            if ground_distance(here, t) > GROUNDED_REACH_M {
                if climbing {
                    return climb(Some((t[1] - here[1]).atan2(t[0] - here[0])));
                }
                return (ActionMode::Goto, [t[0], t[1], altitude], altitude, None);
            }
            self.search.toward = None;
            self.search.scan = 0;
        }
        if self.search.scan < SCAN_OFFSETS.len() {
            let face = wrap_pi(search_heading + SCAN_OFFSETS[self.search.scan]);
            self.search.scan += 1;
            return (
                ActionMode::Goto,
                [position[0], position[1], altitude],
                altitude,
                Some(face),
            );
        }
        if self.search.legs < MAX_SEARCH_LEGS {
            // down from reading a board: up to the transit height before a leg
            if climbing {
                return climb(Some(search_heading));
            }
            self.search.legs += 1;
            self.search.scan = 0;
            let t = ahead(position, search_heading, SEARCH_LEG_M);
            // a leg the fence cuts short ends there (else the vehicle would hover at
            // the fence for ever, short of a point it may not reach)
            let t = self.ground_inside_fence(t);
            self.search.toward = Some(t);
            return (ActionMode::Goto, [t[0], t[1], altitude], altitude, None);
        }
        // not found: give up and land here (the episode ends where the search did)
        (
            ActionMode::Land,
            [position[0], position[1], 0.0],
            position[2].max(self.h_min),
            None,
        )
    }

    /// A grounded decision checked against the height map: a leg (or a landing's approach)
    /// whose way passes a top the map knows (seen in an earlier frame, perhaps behind the
    /// camera now: a scan looks around before a search leg) flies above it by
    /// [`OBSTACLE_MARGIN_M`], climbing in place first when it is far below.
    fn over_known_tops(
        &mut self,
        position: [f32; 3],
        action: ActionMode,
        target: [f32; 3],
        altitude: f32,
        facing: Option<f32>,
    ) -> (ActionMode, [f32; 3], f32, Option<f32>) {
        let here = [position[0], position[1]];
        let to = [target[0], target[1]];
        if !matches!(action, ActionMode::Goto | ActionMode::Land)
            || ground_distance(here, to) <= 1.0
        {
            return (action, target, altitude, facing);
        }
        let (top, _) = self.map.top_along(here, to, CORRIDOR_M, 0.0, LOOKAHEAD_M);
        let needed = (top + OBSTACLE_MARGIN_M).min(self.h_max - 1.0);
        if needed <= altitude {
            return (action, target, altitude, facing);
        }
        self.transit = self.transit.max(needed);
        let toward = (to[1] - here[1]).atan2(to[0] - here[0]);
        if position[2] < needed - CLIMB_FIRST_M {
            return (
                ActionMode::Goto,
                [position[0], position[1], needed],
                needed,
                Some(facing.unwrap_or(toward)),
            );
        }
        let u = if action == ActionMode::Land {
            target[2]
        } else {
            needed
        };
        (action, [target[0], target[1], u], needed, facing)
    }

    /// Ground point `p` moved inside the geofence, as [`Planner::inside_fence`] moves a
    /// decision's target.
    fn ground_inside_fence(&self, p: [f32; 2]) -> [f32; 2] {
        let q = self.inside_fence([p[0], p[1], 0.0]);
        [q[0], q[1]]
    }

    /// `p` moved inside the geofence (by a metre's margin).
    fn inside_fence(&self, p: [f32; 3]) -> [f32; 3] {
        let (lo, hi) = self.fence;
        let mut out = p;
        for i in 0..3 {
            if lo[i] + 1.0 <= hi[i] - 1.0 {
                out[i] = out[i].clamp(lo[i] + if i == 2 { 0.0 } else { 1.0 }, hi[i] - 1.0);
            }
        }
        out
    }
}

/// Distance (m) between two ground points `[N, E]`.
fn ground_distance(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The point `len` metres from `from` along `bearing`.
fn ahead(from: [f32; 3], bearing: f32, len: f32) -> [f32; 2] {
    [from[0] + len * bearing.cos(), from[1] + len * bearing.sin()]
}

/// The point `standoff` metres short of `p` on the line from `here`; `here` itself when
/// it is already that close.
fn short_of(here: [f32; 2], p: [f32; 2], standoff: f32) -> [f32; 2] {
    let (dn, de) = (here[0] - p[0], here[1] - p[1]);
    let d = dn.hypot(de);
    if d <= standoff {
        return here;
    }
    [p[0] + dn / d * standoff, p[1] + de / d * standoff]
}

/// The height to fly toward `goal` at: `previous`, raised to clear by
/// [`OBSTACLE_MARGIN_M`] every obstacle top the occupancy grid of `s` shows within
/// [`LOOKAHEAD_M`] on the way. It never comes down here: the grid is rebuilt from every
/// frame and does not see under the vehicle, so a roof just flown over would read as
/// unknown, not as an obstacle. The planner lowers it only on the height map, which
/// remembers what the vehicle is over.
fn transit_altitude(s: &PerceptionState, position: [f32; 3], goal: [f32; 2], previous: f32) -> f32 {
    let grid = &s.occupancy;
    if !grid.is_present() {
        return previous;
    }
    let (dn, de) = (goal[0] - position[0], goal[1] - position[1]);
    let dist = dn.hypot(de);
    if dist < 1e-3 {
        return previous;
    }
    let (un, ue) = (dn / dist, de / dist);
    let len = dist.min(LOOKAHEAD_M);
    let mut top = 0.0f32;
    let mut t = 0.0;
    while t <= len {
        // the line and two parallels 4 m to either side (the vehicle's clearance)
        for side in [-4.0f32, 0.0, 4.0] {
            let p = [
                position[0] + un * t - ue * side,
                position[1] + ue * t + un * side,
            ];
            if let Some(h) = grid.height_at(p) {
                top = top.max(h);
            }
        }
        t += 2.0;
    }
    previous.max(top + OBSTACLE_MARGIN_M)
}

fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn horizontal(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Ports and timing shared by both variants.
struct ReasonerIo {
    planner: Planner,
    states: TypedSubscriber<PerceptionState>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    decisions: TypedPublisher<Decision>,
    clock: HeartbeatClock,
    last_state: Option<PerceptionState>,
    fresh_state: bool,
    last_telemetry: Option<VehicleTelemetry>,
    seq: u64,
    cycle: u64,
    source: u32,
}

/// How often the reasoning roles look for a fresh S_t.
pub const POLL: Duration = Duration::from_millis(50);

/// How long a starting reasoner waits for the hub's latest setpoint (the hub publishes
/// every 20 ms once a decision is in force; at the flight's start there is none).
pub const RESUME_WAIT: Duration = Duration::from_millis(250);

/// The hub's active instruction step if the flight is under way: from the latest
/// `hub/setpoint`, which its history hands to a new subscriber, waited for up to `wait`.
/// `None` before the first decision of the flight.
pub fn hub_active_step(ctx: &RoleContext, wait: Duration) -> Result<Option<u16>, RoleError> {
    let setpoints = ctx
        .bus
        .subscriber::<aeris_schemas::BoundSetpoint>(topics::HUB_SETPOINT)?;
    let deadline = monotonic_ns().saturating_add(aeris_runtime::clock::duration_ns(wait));
    loop {
        if let Some(sp) = setpoints.latest()?
            && sp.active_step >= 1
        {
            return Ok(Some(sp.active_step));
        }
        if monotonic_ns() >= deadline {
            return Ok(None);
        }
        aeris_runtime::role::sleep(Duration::from_millis(10));
    }
}

impl ReasonerIo {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let mut planner = Planner::new(&ctx.spec.mission, &ctx.spec.camera).ok_or_else(|| {
            RoleError::Config("the mission names an unknown action or the camera is invalid".into())
        })?;
        if let Some(step) = hub_active_step(ctx, RESUME_WAIT)? {
            planner.resume(step);
        }
        Ok(Self {
            planner,
            states: ctx.bus.subscriber(topics::PERCEPTION_STATE)?,
            telemetry: ctx.bus.subscriber(topics::VEHICLE_TELEMETRY)?,
            decisions: ctx.bus.publisher(topics::REASONING_DECISION)?,
            clock: HeartbeatClock::new(
                ctx.spec.timing.heartbeat_period_ms.max(1) * 1_000_000,
                monotonic_ns(),
            ),
            last_state: None,
            fresh_state: false,
            last_telemetry: None,
            seq: 0,
            cycle: 0,
            source: ctx.spec.instance,
        })
    }

    /// Read inputs and, when a decision is due, make it (not yet published).
    fn think(&mut self, report: &mut CycleReport) -> Result<Option<Decision>, RoleError> {
        let t0 = monotonic_ns();
        if let Some(s) = self.states.latest()?
            && s.validate().is_ok()
            && self.last_state.is_none_or(|old| old.seq != s.seq)
        {
            self.last_state = Some(s);
            self.fresh_state = true;
        }
        if let Some(t) = self.telemetry.latest()?
            && t.validate().is_ok()
        {
            self.last_telemetry = Some(t);
        }
        let (position, yaw, landed) = match (&self.last_telemetry, &self.last_state) {
            (Some(t), _) => (t.position, t.attitude[2], t.landed == 1),
            (None, Some(s)) => (s.position, s.yaw, s.position[2] < 0.3),
            (None, None) => (self.planner.start, 0.0, true),
        };
        let Some(basis) = self.clock.due(t0, self.fresh_state) else {
            return Ok(None);
        };
        self.fresh_state = false;
        self.clock.decided(t0);
        let state = match basis {
            Basis::State => self.last_state.as_ref(),
            Basis::TelemetryOnly => None,
        };
        let reasoning_start = monotonic_ns();
        let before = self.planner.rejections().0;
        let mut d = self.planner.decide(position, yaw, landed, state);
        if let (n, Some((p, read))) = self.planner.rejections()
            && n > before
        {
            // rare (a few per flight): worth a line in the role's log
            eprintln!(
                "reasoning: step {}: the sign at [{:.0}, {:.0}] reads \"{read}\", not the one \
                 the instruction quotes; searching on",
                d.step, p[0], p[1]
            );
        }
        self.cycle += 1;
        d.cycle = self.cycle;
        d.source = self.source;
        match state {
            Some(s) => {
                d.cycle_start_ns = s.capture_ns;
                d.state_stamp_ns = s.publish_ns;
            }
            None => {
                d.cycle_start_ns = t0;
                d.state_stamp_ns = t0;
            }
        }
        d.reasoning_start_ns = reasoning_start;
        report.stage("read", reasoning_start - t0);
        report.stage("plan", monotonic_ns() - reasoning_start);
        Ok(Some(d))
    }

    fn send(&mut self, d: &mut Decision, report: &mut CycleReport) -> Result<(), RoleError> {
        let t = monotonic_ns();
        if d.seq == 0 {
            self.seq += 1;
            d.seq = self.seq;
        }
        d.publish_ns = monotonic_ns();
        self.decisions.publish(d)?;
        report.stage("publish", monotonic_ns() - t);
        report.counters[0] = self.seq;
        report.counters[1] = self.planner.current() as u64;
        Ok(())
    }
}

/// The deterministic planner variant of the reasoning role.
pub struct PlannerRole {
    io: ReasonerIo,
}

impl Role for PlannerRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        Ok(Self {
            io: ReasonerIo::new(ctx)?,
        })
    }

    fn period(&self) -> Duration {
        POLL
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.io.think(report)? else {
            return Ok(CycleOutcome::Idle);
        };
        self.io.send(&mut d, report)?;
        Ok(CycleOutcome::Worked)
    }
}

/// xorshift64*: the next number of the stream in `state` (non-zero); deterministic and
/// allocation-free, for the fault injector and the random baseline.
fn xorshift64star(state: &mut u64) -> u64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    state.wrapping_mul(0x2545_F491_4F6C_DD1D)
}

/// A reasoner that corrupts most of its decisions (fault injection).
pub struct GarbageRole {
    io: ReasonerIo,
    rng: u64,
    corrupted: u64,
}

impl GarbageRole {
    fn next_rand(&mut self) -> u64 {
        xorshift64star(&mut self.rng)
    }

    /// Corrupt `d` in the way selected by `kind`; returns false for "leave it valid".
    fn corrupt(&mut self, d: &mut Decision, kind: u64) -> bool {
        let r = self.next_rand();
        let huge = f32::from_bits(r as u32) * 1e30;
        match kind % 12 {
            0 => d.speed = f32::NAN,
            1 => d.target[0] = f32::INFINITY,
            2 => d.target = [1e6, -1e6, 5e3],
            3 => d.altitude = -50.0,
            4 => d.speed = 1e3,
            5 => d.yaw = 7.0,
            6 => d.action = 0xEE,
            7 => d.step = 999,
            8 => d.confidence = huge,
            // stale: claims its cycle started long ago (late at the hub)
            9 => d.cycle_start_ns = d.cycle_start_ns.saturating_sub(3_600_000_000_000),
            // replay an old sequence number (reorder / duplicate)
            10 => d.seq = self.io.seq.saturating_sub(1).max(1),
            _ => return false,
        }
        true
    }
}

impl Role for GarbageRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let seed = ctx.spec.param_f64("seed").unwrap_or(7.0) as u64;
        Ok(Self {
            io: ReasonerIo::new(ctx)?,
            rng: seed.max(1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            corrupted: 0,
        })
    }

    fn period(&self) -> Duration {
        POLL
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.io.think(report)? else {
            return Ok(CycleOutcome::Idle);
        };
        // Send a burst: several corrupted decisions, then (usually) the valid one, so the
        // flight can still make progress through the gate.
        let burst = 1 + self.next_rand() % 3;
        for _ in 0..burst {
            let mut bad = d;
            let kind = self.next_rand();
            if self.corrupt(&mut bad, kind) {
                self.corrupted += 1;
                self.io.send(&mut bad, report)?;
            }
        }
        if !self.next_rand().is_multiple_of(4) {
            d.seq = 0;
            self.io.send(&mut d, report)?;
        }
        report.counters[2] = self.corrupted;
        Ok(CycleOutcome::Worked)
    }
}

/// AerialVLN's discrete actions, which the random baseline draws from uniformly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RandomAction {
    /// Forward 5 m.
    Forward,
    /// Turn left 15 degrees.
    TurnLeft,
    /// Turn right 15 degrees.
    TurnRight,
    /// Up 2 m.
    Up,
    /// Down 2 m.
    Down,
    /// Strafe left 5 m.
    Left,
    /// Strafe right 5 m.
    Right,
    /// Stop: land where it is.
    Stop,
}

impl RandomAction {
    /// Every action, in AerialVLN's order.
    pub const ALL: [RandomAction; 8] = [
        RandomAction::Forward,
        RandomAction::TurnLeft,
        RandomAction::TurnRight,
        RandomAction::Up,
        RandomAction::Down,
        RandomAction::Left,
        RandomAction::Right,
        RandomAction::Stop,
    ];

    /// Turn the action into a decision from `position`/`yaw` (`d` carries the step and
    /// timing fields; speed and radius are kept).
    pub fn apply(self, d: &mut Decision, position: [f32; 3], yaw: f32, h_min: f32) {
        let turn = 15f32.to_radians();
        let (fwd, right) = ([yaw.cos(), yaw.sin()], [(-yaw).sin(), yaw.cos()]);
        let mut target = position;
        let mut heading = yaw;
        let mut action = ActionMode::Goto;
        match self {
            RandomAction::Forward => {
                target[0] += 5.0 * fwd[0];
                target[1] += 5.0 * fwd[1];
            }
            RandomAction::TurnLeft => heading = wrap_pi(yaw - turn),
            RandomAction::TurnRight => heading = wrap_pi(yaw + turn),
            RandomAction::Up => target[2] += 2.0,
            RandomAction::Down => target[2] = (target[2] - 2.0).max(h_min.max(1.0)),
            RandomAction::Left => {
                target[0] -= 5.0 * right[0];
                target[1] -= 5.0 * right[1];
            }
            RandomAction::Right => {
                target[0] += 5.0 * right[0];
                target[1] += 5.0 * right[1];
            }
            RandomAction::Stop => action = ActionMode::Land,
        }
        d.target = target;
        d.yaw = heading;
        d.altitude = target[2];
        d.action = action as u8;
        d.confidence = 1.0 / RandomAction::ALL.len() as f32;
    }
}

/// The random baseline (variant `random`): takes off like the planner, then every
/// heartbeat draws one of AerialVLN's actions uniformly ([`RandomAction`]); `stop` lands
/// where it is and ends its flight. Seeded by the `seed` parameter.
pub struct RandomRole {
    io: ReasonerIo,
    rng: u64,
    airborne: bool,
    stopped: bool,
    h_min: f32,
}

impl Role for RandomRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let seed = ctx.spec.param_f64("seed").unwrap_or(1.0) as u64;
        Ok(Self {
            io: ReasonerIo::new(ctx)?,
            rng: seed.wrapping_add(1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            airborne: false,
            stopped: false,
            h_min: ctx.spec.mission.limits.h_min,
        })
    }

    fn period(&self) -> Duration {
        POLL
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.io.think(report)? else {
            return Ok(CycleOutcome::Idle);
        };
        let (position, yaw) = match &self.io.last_telemetry {
            Some(t) => (t.position, t.attitude[2]),
            None => (self.io.planner.start, 0.0),
        };
        let takeoff = d.action == ActionMode::Takeoff as u8;
        if !self.airborne && takeoff && (position[2] - d.altitude).abs() > 1.0 {
            // the planner's takeoff stands until the vehicle is up
        } else {
            self.airborne = true;
            if !self.stopped {
                let r = xorshift64star(&mut self.rng) >> 32;
                let a = RandomAction::ALL[(r % RandomAction::ALL.len() as u64) as usize];
                self.stopped = a == RandomAction::Stop;
                a.apply(&mut d, position, yaw, self.h_min);
            } else {
                RandomAction::Stop.apply(&mut d, position, yaw, self.h_min);
            }
        }
        self.io.send(&mut d, report)?;
        Ok(CycleOutcome::Worked)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_runtime::spec::{LimitsSpec, SubgoalSpec};

    fn mission() -> aeris_runtime::MissionSpec {
        aeris_runtime::MissionSpec {
            instruction: "take off, fly north, land".into(),
            subgoals: vec![
                SubgoalSpec {
                    text: "take off".into(),
                    action: "takeoff".into(),
                    waypoint: Some([0.0, 0.0, 10.0]),
                },
                SubgoalSpec {
                    text: "fly north".into(),
                    action: "goto".into(),
                    waypoint: Some([30.0, 0.0, 10.0]),
                },
                SubgoalSpec {
                    text: "land".into(),
                    action: "land".into(),
                    waypoint: Some([30.0, 10.0, 0.0]),
                },
            ],
            world: "village".into(),
            start: [0.0; 3],
            cruise_speed: 5.0,
            acceptance_radius_m: 2.0,
            max_duration_s: 60.0,
            limits: LimitsSpec::default(),
        }
    }

    #[test]
    fn advances_through_subgoals_and_every_decision_is_valid() {
        let m = mission();
        let limits = m.decision_limits();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let d = p.decide([0.0, 0.0, 0.0], 0.0, true, None);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (1, Some(ActionMode::Takeoff))
        );
        assert!(d.validate(&limits).is_ok());
        let d = p.decide([0.0, 0.0, 9.5], 0.0, false, None);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (2, Some(ActionMode::Goto))
        );
        assert_eq!(d.target, [30.0, 0.0, 10.0]);
        assert!(d.validate(&limits).is_ok());
        // not there yet: memory holds
        let d = p.decide([15.0, 0.0, 10.0], 0.0, false, None);
        assert_eq!(d.step, 2);
        let d = p.decide([29.0, 0.5, 10.0], 0.0, false, None);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Land))
        );
        assert!(d.validate(&limits).is_ok());
        // the last step stays active
        let d = p.decide([30.0, 10.0, 0.0], 0.0, true, None);
        assert_eq!(d.step, 3);
    }

    #[test]
    fn a_huge_or_odd_yaw_never_hangs_and_stays_in_range() {
        let mut p = Planner::new(&mission(), &CameraSpec::default()).unwrap();
        for yaw in [1.0e9, -3.0e38, f32::MAX, 7.0] {
            let d = p.decide([0.0, 0.0, 0.0], yaw, true, None);
            assert!(d.yaw.abs() <= core::f32::consts::PI, "{yaw} -> {}", d.yaw);
        }
    }

    #[test]
    fn hover_holds_one_heartbeat_and_turn_waits_for_the_heading() {
        let mut m = mission();
        m.subgoals.insert(
            1,
            SubgoalSpec {
                text: "hover".into(),
                action: "hover".into(),
                waypoint: Some([0.0, 0.0, 10.0]),
            },
        );
        m.subgoals.insert(
            2,
            SubgoalSpec {
                text: "face east".into(),
                action: "turn".into(),
                waypoint: Some([0.0, 30.0, 10.0]),
            },
        );
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 0.0, false, None).step,
            2,
            "takeoff done -> hover"
        );
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 0.0, false, None).step,
            3,
            "hovered one heartbeat -> turn"
        );
        let d = p.decide([0.0, 0.0, 10.0], 0.0, false, None);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Turn)),
            "still facing north"
        );
        assert!((d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3);
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 1.55, false, None).step,
            4,
            "facing east -> next"
        );
    }

    #[test]
    fn yaw_points_at_the_target() {
        let mut p = Planner::new(&mission(), &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0, 0.0, 10.0], 0.0, false, None);
        let d = p.decide([30.0, -20.0, 10.0], 0.0, false, None);
        assert!(
            (d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
            "{}",
            d.yaw
        );
    }

    /// The VLN setting: steps name landmarks, no waypoints.
    fn vln_mission() -> aeris_runtime::MissionSpec {
        let step = |text: &str, action: &str| SubgoalSpec {
            text: text.into(),
            action: action.into(),
            waypoint: None,
        };
        aeris_runtime::MissionSpec {
            instruction: "take off, fly to the red-roofed building, land by the sign".into(),
            subgoals: vec![
                step("take off from the helipad to 15 metres", "takeoff"),
                step("turn right and fly to the red-roofed building", "goto"),
                step("land next to the yellow sign that says HOTEL", "land"),
            ],
            world: "village".into(),
            start: [0.0; 3],
            cruise_speed: 5.0,
            acceptance_radius_m: 3.0,
            max_duration_s: 300.0,
            limits: LimitsSpec {
                h_max: 80.0,
                geofence_min: [-300.0, -300.0, 0.0],
                geofence_max: [300.0, 300.0, 80.0],
                ..LimitsSpec::default()
            },
        }
    }

    fn seen(
        label: &str,
        bbox: [f32; 4],
        range_m: f32,
        position: [f32; 3],
        yaw: f32,
    ) -> PerceptionState {
        let mut s = PerceptionState {
            position,
            yaw,
            detection_count: 1,
            ..PerceptionState::default()
        };
        s.detections[0].label.set(label);
        s.detections[0].score = 0.8;
        s.detections[0].bbox = bbox;
        s.detections[0].range_m = range_m;
        s
    }

    #[test]
    fn a_grounded_step_turns_as_told_scans_and_flies_to_what_it_sees() {
        let m = vln_mission();
        let limits = m.decision_limits();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        // the take-off height comes from the text
        let d = p.decide([0.0; 3], 0.0, true, None);
        assert_eq!((d.step, d.target[2]), (1, 15.0));
        // up: "turn right" -> face east first, holding position
        let empty = PerceptionState::default();
        let d = p.decide([0.0, 0.0, 15.0], 0.0, false, Some(&empty));
        assert_eq!(d.step, 2);
        assert!(
            (d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
            "{}",
            d.yaw
        );
        assert!(horizontal(d.target, [0.0, 0.0, 15.0]) < 1e-3);
        // nothing seen: the scan turns left of the search heading next
        let d = p.decide([0.0, 0.0, 15.0], d.yaw, false, Some(&empty));
        assert!(d.yaw < core::f32::consts::FRAC_PI_2 - 0.5, "{}", d.yaw);
        // the red roof straight ahead (east) at 40 m: fly to 12 m short of it
        let at = [0.0, 0.0, 15.0];
        let east = core::f32::consts::FRAC_PI_2;
        let s = seen("red roof", [0.45, 0.0, 0.1, 0.1], 40.0, at, east);
        let d = p.decide(at, east, false, Some(&s));
        assert!(d.validate(&limits).is_ok());
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (2, Some(ActionMode::Goto))
        );
        assert!(
            d.target[1] > 10.0 && d.target[0].abs() < 5.0,
            "{:?}",
            d.target
        );
        let seen_at = p.search.found.unwrap();
        let gap = (d.target[0] - seen_at[0]).hypot(d.target[1] - seen_at[1]);
        assert!((gap - STANDOFF_M).abs() < 0.1, "{gap}");
        // a decision on telemetry alone keeps the memory
        let d2 = p.decide([0.0, 5.0, 15.0], east, false, None);
        assert_eq!(d2.step, 2);
        // arrived at the stand-off point: the landing step searches for the sign
        let d = p.decide(d.target, east, false, Some(&empty));
        assert_eq!(d.step, 3);
        let here = d.target;
        let s = seen("yellow sign", [0.3, 0.3, 0.1, 0.1], 25.0, here, east);
        let d = p.decide(here, east, false, Some(&s));
        // the sign is HOTEL's only if it reads so: the landing waits by it for a reading,
        // and comes down unread after READ_WAIT heartbeats there
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Goto))
        );
        let there = [d.target[0], d.target[1], 15.0];
        let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, there, east);
        let mut d = d;
        for _ in 0..READ_WAIT {
            d = p.decide(there, east, false, Some(&s));
        }
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Land))
        );
        assert_eq!(d.target[2], 0.0);
        assert!(d.validate(&limits).is_ok());
    }

    /// `s` with the reader's text `read` in its summary.
    fn reading(mut s: PerceptionState, read: &str) -> PerceptionState {
        s.blocks |= aeris_schemas::block::TEXT;
        s.summary = aeris_schemas::FixedText::from_str_truncated(&format!("reads \"{read}\""));
        s
    }

    #[test]
    fn a_quoted_sign_is_taken_once_read_there_and_a_sign_found_again_is_read_first() {
        let mut m = vln_mission();
        m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        let at = [0.0, 0.0, 15.0];
        // a yellow sign 20 m north, seen without a reading: found, not yet taken
        let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 20.0, at, 0.0);
        let d = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        assert!(p.search.found.is_some());
        // there, it reads CAFE twice: not STADIUM's, the search goes on
        let cafe = reading(s, "CAFE");
        let _ = p.decide(at, 0.0, false, Some(&cafe));
        let d = p.decide(at, 0.0, false, Some(&cafe));
        assert_eq!((d.step, p.search.found), (2, None), "{d:?}");
        // the same sign seen from 20 m further east puts its estimate 18 m away from the
        // rejected one (the open episode's miss): found again, but not taken unread
        let east = [0.0, 20.0, 15.0];
        let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 38.0, east, 0.0);
        let d = p.decide(east, 0.0, false, Some(&s));
        assert!(p.search.found.is_some(), "{d:?}");
        let near = short_of([east[0], east[1]], p.search.found.unwrap(), STANDOFF_M);
        let there = [near[0], near[1], 15.0];
        let cafe = reading(
            seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, there, 0.0),
            "CAFE",
        );
        let _ = p.decide(there, 0.0, false, Some(&cafe));
        let d = p.decide(there, 0.0, false, Some(&cafe));
        assert_eq!(
            (d.step, p.search.found),
            (2, None),
            "read again, rejected again"
        );
        // the right sign reads STADIUM at once: taken without waiting
        let s = reading(
            seen(
                "yellow sign",
                [0.45, 0.3, 0.1, 0.1],
                20.0,
                [-60.0, 0.0, 15.0],
                0.0,
            ),
            "STADIUM",
        );
        let d = p.decide([-60.0, 0.0, 15.0], 0.0, false, Some(&s));
        assert_eq!(d.step, 3, "{d:?}");
    }

    #[test]
    fn a_landmark_never_seen_ends_in_a_landing_after_the_search_legs() {
        let m = vln_mission();
        let limits = m.decision_limits();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let empty = PerceptionState::default();
        let mut at = [0.0, 0.0, 15.0];
        let mut yaw = 0.0;
        let mut last = None;
        for _ in 0..200 {
            let d = p.decide(at, yaw, false, Some(&empty));
            assert!(d.validate(&limits).is_ok(), "{d:?}");
            // the vehicle goes where it is told at once
            at = d.target;
            yaw = d.yaw;
            last = Some(d);
            if ActionMode::from_u8(d.action) == Some(ActionMode::Land) {
                break;
            }
        }
        let d = last.unwrap();
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (2, Some(ActionMode::Land))
        );
        // it searched along east (turn right) for the legs' length
        assert!(
            (d.target[1] - MAX_SEARCH_LEGS as f32 * SEARCH_LEG_M).abs() < 1.0,
            "{:?}",
            d.target
        );
    }

    #[test]
    fn the_transit_height_clears_obstacles_seen_ahead_and_never_drops() {
        let m = vln_mission();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        let at = [0.0, 0.0, 15.0];
        // the red roof 60 m north, a 30 m wall 20 m ahead on the way
        let mut s = seen("red roof", [0.45, 0.3, 0.1, 0.1], 60.0, at, 0.0);
        s.occupancy.resolution_m = 2.0;
        s.occupancy.origin = [0.0, 0.0];
        s.occupancy.cells = [0; aeris_schemas::OCCUPANCY_CELLS];
        let wall = s.occupancy.cell_of([20.0, 0.0]).unwrap();
        s.occupancy.cells[wall] = 30;
        let d = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        assert!(d.altitude >= 36.0 && d.target[2] >= 36.0, "{d:?}");
        // the wall no longer in the grid: the height stays
        s.occupancy.cells[wall] = 0;
        let d = p.decide([10.0, 0.0, 36.0], 0.0, false, Some(&s));
        assert!(d.altitude >= 36.0, "{}", d.altitude);
    }

    #[test]
    fn a_sign_with_another_text_is_not_taken_for_the_next_one() {
        let mut m = vln_mission();
        m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        let at = [0.0, 0.0, 15.0];
        // STADIUM's sign ahead (north), found and reached
        let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 30.0, at, 0.0);
        let d = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        let stadium = p.search.found.unwrap();
        // at the stand-off point, the sign reads STADIUM: taken
        let d = p.decide(d.target, 0.0, false, Some(&reading(s, "STADIUM")));
        assert_eq!(d.step, 3, "reached the stand-off point");
        // the same sign seen again: not HOTEL's, the search goes on
        let here = d.target;
        let dn = stadium[0] - here[0];
        let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], dn, here, 0.0);
        let d = p.decide(here, 0.0, false, Some(&s));
        assert_eq!(p.search.found, None, "{d:?}");
        // a yellow sign elsewhere (behind, 40 m south) is taken
        let s = seen(
            "yellow sign",
            [0.45, 0.3, 0.1, 0.1],
            40.0,
            here,
            core::f32::consts::PI,
        );
        let d = p.decide(here, core::f32::consts::PI, false, Some(&s));
        let found = p.search.found.expect("the other sign");
        assert!(found[0] < here[0] - 30.0, "{found:?}");
        // approached, to be read before the landing
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Goto));
        let there = [d.target[0], d.target[1], 15.0];
        let hotel = reading(
            seen(
                "yellow sign",
                [0.45, 0.3, 0.1, 0.1],
                12.0,
                there,
                core::f32::consts::PI,
            ),
            "HOTEL",
        );
        let d = p.decide(there, core::f32::consts::PI, false, Some(&hotel));
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
    }

    #[test]
    fn a_sign_read_close_up_with_another_text_is_rejected() {
        let mut m = vln_mission();
        m.subgoals.remove(1);
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        let at = [0.0, 0.0, 15.0];
        // a yellow sign 20 m ahead that the reader reads as MUSEUM: once may be a
        // misreading, twice it is not HOTEL's
        let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 20.0, at, 0.0);
        s.blocks |= aeris_schemas::block::TEXT;
        s.summary = aeris_schemas::FixedText::from_str_truncated(
            "reads \"MUSEUM\"; yellow sign ahead 20 m",
        );
        let d = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        assert!(p.search.found.is_some(), "one misreading rejects nothing");
        let _ = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(p.search.found, None);
        assert_eq!(p.rejections().0, 1);
        assert_eq!(p.rejections().1.unwrap().1, "MUSEUM");
        // seen again from afar without a reading: still not taken
        let s = seen(
            "yellow sign",
            [0.45, 0.3, 0.1, 0.1],
            45.0,
            [-25.0, 0.0, 15.0],
            0.0,
        );
        let _ = p.decide([-25.0, 0.0, 15.0], 0.0, false, Some(&s));
        assert_eq!(p.search.found, None);
        // the one that reads HOTEL is
        let mut s = seen(
            "yellow sign",
            [0.45, 0.3, 0.1, 0.1],
            20.0,
            at,
            core::f32::consts::PI,
        );
        s.blocks |= aeris_schemas::block::TEXT;
        s.summary = aeris_schemas::FixedText::from_str_truncated("reads \"H0TEL\"");
        let d = p.decide(at, core::f32::consts::PI, false, Some(&s));
        assert!(p.search.found.is_some());
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
    }

    /// An occupancy grid around N, E = 0 showing free ground but for a board 8 m high and
    /// 12 m long north-south (facing east and west) at N 40..52, E 0.
    fn north_south_board() -> aeris_schemas::OccupancyGrid {
        let mut board = aeris_schemas::OccupancyGrid {
            origin: [0.0, 0.0],
            resolution_m: 2.0,
            ..Default::default()
        };
        let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
        for (i, cell) in board.cells.iter_mut().enumerate() {
            let n = ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            let e = ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            *cell = u8::from((40.0..52.0).contains(&n) && (-1.0..1.0).contains(&e)) * 8;
        }
        board
    }

    #[test]
    fn a_quoted_sign_is_approached_in_front_of_a_face_not_edge_on() {
        let mut m = vln_mission();
        m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        // the vehicle comes from the south, so it sees the board edge-on
        let board = north_south_board();
        let at = [0.0, 0.0, 15.0];
        let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 40.0, at, 0.0);
        s.occupancy = board;
        let d = p.decide(at, 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        // to a face: 12 m east or west of the board's middle, not short of it on the way
        assert!(
            (d.target[0] - 46.0).abs() <= 2.0 && (d.target[1].abs() - STANDOFF_M).abs() <= 2.0,
            "{:?}",
            d.target
        );
        // 12 m short of the board's end, edge-on, the step is not done (the old rule took it)
        let edge = [28.0, 0.0, 15.0];
        let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, edge, 0.0);
        s.occupancy = board;
        for _ in 0..READ_WAIT + 1 {
            let d = p.decide(edge, 0.0, false, Some(&s));
            assert_eq!(d.step, 2, "{d:?}");
        }
    }

    #[test]
    fn a_board_below_the_frame_is_read_from_low_down_and_the_next_leg_climbs_first() {
        let mut m = vln_mission();
        m.subgoals[0].text = "take off from the helipad to 28 metres".into();
        m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        let _ = p.decide([0.0; 3], 0.0, true, None);
        let board = north_south_board();
        let sign = |at: [f32; 3], range_m: f32, yaw: f32| {
            let mut s = seen("yellow sign", [0.45, 0.45, 0.1, 0.1], range_m, at, yaw);
            s.occupancy = board;
            s
        };
        let d = p.decide(
            [0.0, 0.0, 28.0],
            0.0,
            false,
            Some(&sign([0.0, 0.0, 28.0], 40.0, 0.0)),
        );
        assert_eq!((d.step, d.altitude), (2, 28.0), "{d:?}");
        let face = [d.target[0], d.target[1]];
        // at the reading point at 28 m the board is below the frame: come down to the
        // board's top + the margin, and the heartbeats up there do not count as unread
        let toward_board = if face[1] > 0.0 {
            -core::f32::consts::FRAC_PI_2
        } else {
            core::f32::consts::FRAC_PI_2
        };
        let high = [face[0], face[1], 28.0];
        for _ in 0..READ_WAIT + 2 {
            let d = p.decide(
                high,
                toward_board,
                false,
                Some(&sign(high, 12.0, toward_board)),
            );
            assert_eq!(d.step, 2, "{d:?}");
            assert_eq!(
                (d.altitude, d.target[2]),
                (8.0 + OBSTACLE_MARGIN_M, 8.0 + OBSTACLE_MARGIN_M)
            );
            assert!(horizontal(d.target, high) <= 1.0, "{d:?}");
        }
        // down there, unread for READ_WAIT heartbeats: taken unread, as before
        let low = [face[0], face[1], 8.0 + OBSTACLE_MARGIN_M];
        let mut step = 2;
        for _ in 0..READ_WAIT + 1 {
            step = p
                .decide(
                    low,
                    toward_board,
                    false,
                    Some(&sign(low, 12.0, toward_board)),
                )
                .step;
        }
        assert_eq!(step, 3);
        // the next step, still low, climbs in place (scanning) and flies no search leg
        // before it is up at the transit height
        let empty = PerceptionState::default();
        let mut yaw = toward_board;
        for k in 0..SCAN_OFFSETS.len() + 2 {
            let d = p.decide(low, yaw, false, Some(&empty));
            yaw = d.yaw;
            assert_eq!(d.step, 3);
            assert!(
                horizontal(d.target, low) <= 1e-3 && d.target[2] == 28.0,
                "decision {k} of the next step, from low down: {d:?}"
            );
        }
    }

    #[test]
    fn a_landing_next_to_a_building_comes_down_beside_it_never_on_its_roof() {
        let m = vln_mission();
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        p.current = 2;
        p.steps[2] = Some(Step {
            action: ActionMode::Land,
            target: StepTarget::Find(
                LandmarkPhrase::parse("land next to the blue-roofed building").unwrap(),
            ),
            turn: 0.0,
        });
        // a 40 m building of 25 m at N, E in [100, 140] (cells of 2 m, as perception's)
        let grid = |origin: [f32; 2], under_unknown: bool| {
            let mut g = aeris_schemas::OccupancyGrid {
                origin,
                resolution_m: 2.0,
                ..Default::default()
            };
            for (i, cell) in g.cells.iter_mut().enumerate() {
                let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
                let n = origin[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
                let e = origin[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
                let roof = (100.0..140.0).contains(&n) && (100.0..140.0).contains(&e);
                let under = (n - origin[0]).hypot(e - origin[1]) < 30.0;
                *cell = if under && under_unknown {
                    aeris_schemas::OCCUPANCY_UNKNOWN
                } else if roof {
                    25
                } else {
                    0
                };
            }
            g
        };
        // seen from afar, high, looking south-east: the range reads the roof's far side
        let at = [70.0, 70.0, 50.0];
        let se = core::f32::consts::FRAC_PI_4;
        let mut s = seen("blue roof", [0.45, 0.45, 0.1, 0.1], 90.0, at, se);
        s.occupancy = grid([70.0, 70.0], true);
        let d = p.decide(at, se, false, Some(&s));
        let on_roof =
            |t: [f32; 3]| (100.0..140.0).contains(&t[0]) && (100.0..140.0).contains(&t[1]);
        let found = p.search.found.unwrap();
        assert!(found[0] > 120.0 && found[1] > 120.0, "{found:?}");
        assert!(!on_roof(d.target), "{:?}", d.target);
        let toward = |t: [f32; 3], c: [f32; 2]| (t[0] - c[0]).hypot(t[1] - c[1]);
        assert!(
            toward(d.target, [70.0, 70.0]) < toward([120.0, 120.0, 0.0], [70.0, 70.0]) - 10.0,
            "the approach side: {:?}",
            d.target
        );
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
        // over the roof's edge now, the camera sees only the roof ahead and nothing below:
        // the touchdown stays where the flight saw clear ground
        let over = [104.0, 104.0, 40.0];
        let mut s2 = seen("blue roof", [0.45, 0.6, 0.1, 0.1], 30.0, over, se);
        s2.occupancy = grid([104.0, 104.0], true);
        let d2 = p.decide(over, se, false, Some(&s2));
        assert!(!on_roof(d2.target), "{:?}", d2.target);
        assert_eq!((d2.target[0], d2.target[1]), (d.target[0], d.target[1]));
        // over the touchdown, descending: a frame now shows a 3 m obstacle (a wall cell
        // read close by) 2 m from it, which spoils its clear square; the touchdown stays
        // (its own cell is free) and the landing goes on
        let t = p.search.touchdown.expect("a touchdown");
        let above = [t[0], t[1], 12.0];
        let mut s4 = seen("blue roof", [0.45, 0.6, 0.1, 0.1], 30.0, above, se);
        let mut near_wall = grid([t[0], t[1]], false);
        let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
        for (i, cell) in near_wall.cells.iter_mut().enumerate() {
            let n = t[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            let e = t[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            if (n - t[0] - 3.0).abs() <= 1.0 && (e - t[1]).abs() <= 1.0 {
                *cell = 3;
            }
        }
        s4.occupancy = near_wall;
        let d4 = p.decide(above, se, false, Some(&s4));
        assert!(
            !p.map.is_clear(t, TOUCHDOWN_CLEAR_M),
            "the wall cell spoils the square: {t:?} {:?} {:?} {:?}",
            p.map.height_at([t[0] + 3.0, t[1]]),
            p.map.height_at([t[0] + 2.0, t[1]]),
            p.map.height_at([t[0] + 4.0, t[1]])
        );
        assert_eq!(p.search.touchdown, Some(t));
        assert_eq!(
            (ActionMode::from_u8(d4.action), d4.target[0], d4.target[1]),
            (Some(ActionMode::Land), t[0], t[1])
        );
        // a planner that never saw clear ground beside it (only 16 m off, farther than
        // "next to" reaches) lands there rather than on the roof under it
        let mut q = Planner::new(&m, &CameraSpec::default()).unwrap();
        q.current = 2;
        q.steps[2] = p.steps[2];
        let mut roof_only = grid([120.0, 120.0], false);
        for (i, cell) in roof_only.cells.iter_mut().enumerate() {
            let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
            let n = 120.0 + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            if *cell == 0 && n > 88.0 {
                *cell = aeris_schemas::OCCUPANCY_UNKNOWN;
            }
        }
        let mut s3 = seen("blue roof", [0.45, 0.45, 0.1, 0.1], 20.0, over, se);
        s3.occupancy = roof_only;
        for _ in 0..(TOUCHDOWN_WAIT + 2) {
            let d3 = q.decide(over, se, false, Some(&s3));
            assert!(
                !on_roof(d3.target) && d3.target[0] <= 88.0,
                "{:?}",
                d3.target
            );
        }
        assert_eq!(q.search.touchdown, None);
    }
}
