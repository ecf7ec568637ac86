//! Planning without occupancy: when the S_t the planner decides on carries no present
//! occupancy grid (no depth source, or a stale one), unknown space is not free. The
//! planner then keeps to the rule the hub's gate enforces, so its decisions are flown as
//! planned rather than clamped: a horizontal move of more than [`BLIND_MOVE_M`] flies at
//! the conservative altitude ([`aeris_schemas::DecisionLimits::blind_altitude`]), climbing
//! where the vehicle is first while it is more than [`BLIND_CLIMB_SLACK_M`] below it (a
//! landing far away too); nothing in place goes below that altitude, or below the vehicle
//! when it is lower. The geofence is kept as always.

use super::Planner;
use super::geometry::horizontal;
use aeris_schemas::{ActionMode, BLIND_CLIMB_SLACK_M, BLIND_MOVE_M};

/// `true` for the actions the gate binds where the vehicle is.
fn in_place(action: ActionMode) -> bool {
    matches!(
        action,
        ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn
    )
}

impl Planner {
    /// The altitude a decision of `action` toward `target` from `position` flies at
    /// without occupancy, for the `asked` one: the conservative altitude for a move, else
    /// `asked` but not below `min(conservative, vehicle altitude)`.
    pub(super) fn blind_height(
        &self,
        action: ActionMode,
        position: [f32; 3],
        target: [f32; 3],
        asked: f32,
    ) -> f32 {
        let b = self.blind_altitude;
        if !in_place(action) && horizontal(position, target) > BLIND_MOVE_M {
            b
        } else {
            asked.max(b.min(position[2]))
        }
    }

    /// A decision `(action, target, altitude)` made to keep to the rule without
    /// occupancy (module documentation).
    pub(super) fn keep_blind(
        &self,
        action: ActionMode,
        target: [f32; 3],
        altitude: f32,
        position: [f32; 3],
    ) -> (ActionMode, [f32; 3], f32) {
        let b = self.blind_altitude;
        let moves = !in_place(action) && horizontal(position, target) > BLIND_MOVE_M;
        let low = position[2] < b - BLIND_CLIMB_SLACK_M;
        if moves && low {
            // climb where the vehicle is; the move (or the landing's approach) comes after
            return (ActionMode::Goto, [position[0], position[1], b], b);
        }
        let h = self.blind_height(action, position, target, altitude);
        match action {
            ActionMode::Land => (action, target, altitude),
            ActionMode::Goto | ActionMode::Hover | ActionMode::Stop => {
                (action, [target[0], target[1], h], h)
            }
            _ => (action, target, h),
        }
    }
}
