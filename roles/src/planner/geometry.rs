//! Plane geometry of the planner: ground distances, bearings, points along a bearing, and
//! the transit height over what an occupancy grid shows ahead.

use super::{LOOKAHEAD_M, OBSTACLE_MARGIN_M};
use aeris_schemas::PerceptionState;

/// Bearing from `from` to `to` (rad, 0 = north, clockwise), or `fallback` when they coincide.
pub(super) fn heading(from: [f32; 3], to: [f32; 3], fallback: f32) -> f32 {
    let (dn, de) = (to[0] - from[0], to[1] - from[1]);
    if dn.hypot(de) > 1.0 {
        de.atan2(dn)
    } else {
        fallback
    }
}

/// Distance (m) between two ground points `[N, E]`.
pub(super) fn ground_distance(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The point `len` metres from `from` along `bearing`.
pub(super) fn ahead(from: [f32; 3], bearing: f32, len: f32) -> [f32; 2] {
    [from[0] + len * bearing.cos(), from[1] + len * bearing.sin()]
}

/// The point `standoff` metres short of `p` on the line from `here`; `here` itself when
/// it is already that close.
pub(super) fn short_of(here: [f32; 2], p: [f32; 2], standoff: f32) -> [f32; 2] {
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
pub(super) fn transit_altitude(
    s: &PerceptionState,
    position: [f32; 3],
    goal: [f32; 2],
    previous: f32,
) -> f32 {
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

/// Distance (m) between two points `[N, E, U]`.
pub(super) fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Horizontal distance (m) between two points `[N, E, U]`.
pub(super) fn horizontal(a: [f32; 3], b: [f32; 3]) -> f32 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}
