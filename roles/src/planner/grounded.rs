//! The decision of a grounded step (one that names a landmark, not a waypoint): fly to the
//! landmark found (in front of a quoted sign's board, coming down to read it; beside a
//! landmark to land next to it, waiting for clear ground), else scan around and fly search
//! legs, and give up with a landing where the search ended; always above the obstacle tops
//! the height map knows on the way.

use super::geometry::{ahead, ground_distance, short_of};
use super::{
    CLIMB_FIRST_M, CORRIDOR_M, FALLBACK_CLEAR_M, GROUNDED_REACH_M, LOOKAHEAD_M, MAX_SEARCH_LEGS,
    OBSTACLE_MARGIN_M, Planner, READ_CLEAR_M, READ_DESCENT_REACH_M, READ_WAIT, SCAN_OFFSETS,
    SEARCH_LEG_M, STANDOFF_M, Step, TOUCHDOWN_CLEAR_M, TOUCHDOWN_WAIT,
};
use crate::grounding::{LandmarkPhrase, Relation};
use crate::height_map::CELL_M;
use aeris_geometry::wrap_pi;
use aeris_schemas::ActionMode;

impl Planner {
    /// The decision of a grounded step: `(action, target, altitude, facing)`.
    pub(super) fn grounded(
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
            // a landing comes down where the map shows no obstacle within a cell: the gate
            // refuses a touchdown on an obstacle (a landing "over" a sign's board) or in the
            // hub's cell of a roof beside it, every heartbeat, and the planner hears no
            // refusal
            let goal = if action == ActionMode::Land && !self.map.no_obstacle_near(goal, CELL_M) {
                self.map
                    .nearest_clear(goal, FALLBACK_CLEAR_M, TOUCHDOWN_CLEAR_M)
                    .unwrap_or(goal)
            } else {
                goal
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
        // not found: give up and land (the episode ends where the search did), here unless
        // the map shows an obstacle within a cell of it, else on the nearest ground it shows
        // clear: straight down beside a building, the hub's grid (centred on the vehicle,
        // its cells straddling the map's) can hold the roof in the touchdown's cell, and
        // the gate refused that descent every heartbeat until the time limit
        let kept = self
            .search
            .given_up
            .filter(|&t| self.map.no_obstacle_near(t, CELL_M));
        let t = kept.unwrap_or_else(|| {
            if self.map.no_obstacle_near(here, CELL_M) {
                here
            } else {
                self.map
                    .nearest_clear(here, FALLBACK_CLEAR_M, TOUCHDOWN_CLEAR_M)
                    .unwrap_or(here)
            }
        });
        self.search.given_up = Some(t);
        (
            ActionMode::Land,
            [t[0], t[1], 0.0],
            position[2].max(self.h_min),
            None,
        )
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
    pub(super) fn sign_settled(&self, phrase: &LandmarkPhrase) -> bool {
        phrase.sign_text.is_empty() || self.search.confirmed || self.search.unread >= READ_WAIT
    }

    /// A grounded decision checked against the height map: a leg (or a landing's approach)
    /// whose way passes a top the map knows (seen in an earlier frame, perhaps behind the
    /// camera now: a scan looks around before a search leg) flies above it by
    /// [`OBSTACLE_MARGIN_M`], climbing in place first when it is far below.
    pub(super) fn over_known_tops(
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
}
