//! The deterministic planner: the reasoning role's first variant, and the plan the
//! language-model variants are shown.
//!
//! [`Planner`] is pure: it turns the mission's subgoals, the vehicle's state and the S_t a
//! decision is based on into decisions D_t. Its memory M_{t-1} is the index of the subgoal
//! in progress; it advances when the vehicle reaches that subgoal's waypoint (or lands, for
//! a land step), or, for a step that names a landmark instead (the VLN setting), when it
//! reaches the landmark it found in S_t.
//!
//! - this file: the steps, the memory, the decision rule and when a step is done;
//! - `search`: what a grounded step takes in from S_t (sightings, sign
//!   readings and rejections, the touchdown beside a landmark, the transit height);
//! - `grounded`: the decision of a grounded step (approach, reading a
//!   board from low down, scanning, search legs, landing);
//! - `geometry`: ground distances, bearings and the transit height over
//!   the occupancy grid;
//! - `blind`: planning without occupancy (no depth source, or a stale one): the geofence
//!   and the conservative altitude, as the hub's gate enforces them;
//! - [`role`]: [`PlannerRole`], the planner as a reasoning process (over the shared
//!   [`crate::reasoner_io::ReasonerIo`]);
//! - [`garbage_and_random`]: [`GarbageRole`] (fault injection) and [`RandomRole`] (the
//!   VLN random baseline), both built on the planner's decisions.

mod blind;
mod geometry;
mod grounded;
mod search;

pub mod garbage_and_random;
pub mod role;

#[cfg(test)]
mod landing_tests;
#[cfg(test)]
mod reading_tests;
#[cfg(test)]
mod tests;

pub use garbage_and_random::{GarbageRole, RandomAction, RandomRole};
pub use role::{PlannerRole, mission_planner};

use crate::grounding::{LandmarkPhrase, Relation, height_of, turn_of};
use crate::height_map::HeightMap;
use aeris_geometry::CameraModel;
use aeris_geometry::wrap_pi;
use aeris_runtime::spec::CameraSpec;
use aeris_schemas::state::CUE_MAX;
use aeris_schemas::{
    ActionMode, Decision, FixedText, MAX_SUBGOALS, OccupancyStatus, PerceptionState, Turn,
};
use geometry::{distance, ground_distance, heading, horizontal};
use search::Search;

/// A turn step is done when the yaw is this close to the bearing of its waypoint.
const TURN_TOLERANCE_RAD: f32 = 0.15;
/// Cruise height (m above the start) of a mission whose take-off names no height.
pub const DEFAULT_CRUISE_HEIGHT_M: f32 = 20.0;
/// "fly to X" / "land next to X" stop this far (m) short of X's seen surface.
pub const STANDOFF_M: f32 = 12.0;
/// Slack (m) on the stand-off point and on "fly over X" when X's position is an estimate.
pub const GROUNDED_REACH_M: f32 = 8.0;
/// A take-off, climb or descent step is done within this height of its target (m).
pub const ALTITUDE_REACH_M: f32 = 1.0;
/// How far short of its setpoint the vehicle may settle (m): the tracker approaches a
/// setpoint from one side and stops a fraction of a millimetre before it, so a setpoint
/// exactly [`ALTITUDE_REACH_M`] off the step's target (a language model's take-off to 11 m
/// for a 12 m step) left the vehicle 1.00005 m away and the step never done.
const SETTLE_MARGIN_M: f32 = 0.01;
/// Yaw offsets (rad) from the search heading, one heartbeat each, while the landmark of a
/// step is not in view: ahead, then ever wider left/right, then behind.
const SCAN_OFFSETS: [f32; 6] = [0.0, -1.05, 1.05, -2.09, 2.09, core::f32::consts::PI];
/// How close (rad) to its heading a step that only turns must face to be done.
const TURNED_RAD: f32 = 0.26;
/// Heartbeats after which a step that only turns is done however the vehicle faces.
const TURN_WAIT: u32 = 5;
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

/// The planner's pure logic: memory (the subgoal in progress) and the decision rule.
///
/// A step with a waypoint is flown to it. A step without one (the VLN setting) is grounded
/// in S_t ([`crate::grounding`]): its landmark is looked for among the detections (after
/// the turn its text asks for, then scanning around, then flying search legs), located
/// from the detection's bearing and range, and approached at a height that clears the
/// obstacle tops the occupancy grid shows ahead.
///
/// Until an S_t brings present occupancy, and from any S_t without it (absent or stale)
/// until one brings it back, every decision keeps to the geofence and the conservative
/// altitude instead of taking unknown space for free (`blind`), as the hub's gate does: a
/// flight whose perception publishes no S_t at all (a camera without depth feeding a
/// perception that needs it) is flown blind, not over space assumed free.
#[derive(Debug, Clone)]
pub struct Planner {
    steps: [Option<Step>; MAX_SUBGOALS],
    count: usize,
    current: usize,
    issued: u32,
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
    /// The occupancy status of the latest S_t decided on (`None` before the first).
    occupancy: Option<OccupancyStatus>,
    /// The altitude flown without occupancy (the mission's band top).
    blind_altitude: f32,
    /// Decisions made without occupancy.
    blind_decisions: u64,
}

impl Planner {
    /// A planner for the mission in `spec` seen through `camera`; `None` when an action
    /// name is unknown or the camera's geometry is invalid (a validated spec has neither).
    pub fn new(mission: &aeris_runtime::MissionSpec, camera: &CameraSpec) -> Option<Self> {
        let mut steps = [None; MAX_SUBGOALS];
        let mut cruise_height = None;
        for (slot, s) in steps.iter_mut().zip(mission.subgoals.iter()) {
            let action = s.action_mode()?;
            // what a model read in the step first, the phrase rules for what it left out
            let reading = s.reading.as_ref();
            let target = match (s.waypoint, action) {
                (Some(w), _) => StepTarget::At(w),
                (None, ActionMode::Takeoff | ActionMode::Ascend) => {
                    let h = reading
                        .and_then(|r| r.height_m)
                        .or_else(|| height_of(&s.text))
                        .unwrap_or(DEFAULT_CRUISE_HEIGHT_M);
                    StepTarget::At([mission.start[0], mission.start[1], mission.start[2] + h])
                }
                (None, _) => reading
                    .and_then(|r| LandmarkPhrase::from_reading(r, action))
                    .or_else(|| LandmarkPhrase::parse(&s.text))
                    .map(StepTarget::Find)
                    .unwrap_or(StepTarget::Here),
            };
            let turn = match reading.map(|r| r.turn) {
                Some(t) if t != Turn::None => t.radians(),
                _ => turn_of(&s.text),
            };
            if let (StepTarget::At(w), ActionMode::Takeoff) = (target, action) {
                cruise_height.get_or_insert(w[2]);
            }
            *slot = Some(Step {
                action,
                target,
                turn,
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
            occupancy: None,
            blind_altitude: mission.decision_limits().blind_altitude(),
            blind_decisions: 0,
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

    /// The occupancy status of the latest S_t decided on (`None` before the first; a
    /// status byte that is none reads as absent).
    pub fn occupancy(&self) -> Option<OccupancyStatus> {
        self.occupancy
    }

    /// `true` while the planner decides without occupancy (no S_t yet, or the latest had
    /// none present): moves keep to the conservative altitude.
    pub fn blind(&self) -> bool {
        self.occupancy != Some(OccupancyStatus::Present)
    }

    /// Decisions made without occupancy so far.
    pub fn blind_decisions(&self) -> u64 {
        self.blind_decisions
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
                    // a step that only turns ("hang a right") is done facing its heading
                    // (or after TURN_WAIT heartbeats: the vehicle may not yaw)
                    _ if step.turn != 0.0 => {
                        issued >= TURN_WAIT
                            || (issued >= 1
                                && self
                                    .search
                                    .heading
                                    .is_some_and(|h| wrap_pi(yaw - h).abs() <= TURNED_RAD))
                    }
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
        // without occupancy the waypoint's height is the one the decision flies at
        let w = if self.blind() {
            [
                w[0],
                w[1],
                self.blind_height(step.action, position, w, w[2]),
            ]
        } else {
            w
        };
        match step.action {
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend => {
                (position[2] - w[2]).abs() <= ALTITUDE_REACH_M + SETTLE_MARGIN_M
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
            self.occupancy = Some(s.occupancy.status().unwrap_or(OccupancyStatus::Absent));
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
                // turn in place to the heading the step asks for, taken when it starts
                _ if step.turn != 0.0 => {
                    let h = *self.search.heading.get_or_insert(wrap_pi(yaw + step.turn));
                    let altitude = position[2].max(self.h_min);
                    (
                        ActionMode::Goto,
                        [position[0], position[1], altitude],
                        altitude,
                        Some(h),
                    )
                }
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
        let (action, target, altitude) = if self.blind() {
            self.blind_decisions = self.blind_decisions.saturating_add(1);
            self.keep_blind(action, target, altitude, position)
        } else {
            (action, target, altitude)
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

    /// Ground point `p` moved inside the geofence, as [`Planner::inside_fence`] moves a
    /// decision's target.
    pub(super) fn ground_inside_fence(&self, p: [f32; 2]) -> [f32; 2] {
        let q = self.inside_fence([p[0], p[1], 0.0]);
        [q[0], q[1]]
    }

    /// `p` moved inside the geofence (by a metre's margin).
    pub(super) fn inside_fence(&self, p: [f32; 3]) -> [f32; 3] {
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
