//! The decision gate: validate D_t, make it feasible (occupancy and geofence), bind it to an
//! executable [`BoundSetpoint`] (MISSION §3, §4).
//!
//! Everything here is a pure function of its inputs and never allocates, so the gate can be
//! fuzzed and benchmarked on its own ([`DecisionGate::admit`] = validate + clamp + bind).
//!
//! # Binding
//! | action | bound position `[N, E, U]` |
//! |---|---|
//! | takeoff, ascend, descend | vehicle N, E; h_t |
//! | turn | vehicle N, E; h_t (yaw psi_t) |
//! | goto | g_t N, E; h_t |
//! | hover, stop | hold at g_t N, E; h_t |
//! | land | g_t N, E; 0 |
//!
//! The vehicle's horizontal position is first projected into the geofence (a vehicle that
//! drifted out is brought back to the nearest point inside).
//!
//! # Feasibility
//! - Altitude: h_t is kept inside the band `[max(h_min, fence_min.U), min(h_max,
//!   fence_max.U)]`; an empty band rejects ([`GateError::NoAltitude`]).
//! - Horizontal motion (goto, hover, stop, land): the horizontal segment from the vehicle to
//!   the target is walked through every occupancy cell it touches (an exact grid traversal,
//!   which never skips a cell the way fixed half-cell sampling can at corners). The first
//!   cell whose obstacle top is `> 0` and `>= h - clearance` blocks (UNKNOWN cells count as
//!   free; `h` is h_t, and for land the lower of h_t and the vehicle's altitude, since the
//!   vehicle crosses at its height before descending). The target is pulled back along the
//!   segment to `clearance` metres before the point where the segment enters that cell
//!   (`clamped`). If that leaves less than one cell of motion (the vehicle stands at the
//!   obstacle), a goto, hover or stop is raised over it instead: h_t becomes the top plus
//!   the clearance plus [`OVER_MARGIN_M`] and the way is walked again at that height
//!   (`clamped`); while the vehicle is more than half the clearance below that height it is
//!   held where it is, climbing there, and the way is flown once up there. Only an obstacle
//!   whose raised height is above the band rejects ([`GateError::Blocked`]), as does a land
//!   blocked that close (it crosses at the vehicle's height). A land whose touchdown cell
//!   holds an obstacle is rejected.
//! - In place (takeoff, ascend, descend, turn): when the cell under the vehicle holds an
//!   obstacle with top `>= h_t - clearance`, h_t is raised to `top + clearance` (`clamped`),
//!   or the decision is rejected when that is above the band.
//! - Speed is clamped to `[0, v_max]` (validation already guarantees it).
//! - **No occupancy** (no grid given, or its status absent or stale: no depth source, or
//!   an old one): unknown space is not free, so the gate keeps to the geofence and the
//!   conservative altitude `b` = [`DecisionLimits::blind_altitude`] (the band's top). A
//!   goto, hover or stop whose target lies more than [`BLIND_MOVE_M`] from the vehicle
//!   flies at `h_t >= b`, and while the vehicle is more than [`BLIND_CLIMB_SLACK_M`] below
//!   `b` it is held where the vehicle is (climbing there) instead; a land that far away
//!   from a vehicle that low is rejected ([`GateError::NoOccupancy`]: the touchdown is
//!   reached at the vehicle's altitude); anything else stays in place and is never bound
//!   below `min(b, vehicle altitude)`. The touchdown cell cannot be checked.
//!
//! Every clamp is flagged `clamped`, its reasons in [`Feasible::reasons`]
//! ([`aeris_schemas::clamp`] bits, which the hub reports).
//!
//! The bound setpoint is finally checked with [`BoundSetpoint::validate`], so the gate and the
//! controller agree: a land setpoint is at U = 0, which `validate` accepts below h_min for
//! land (and takeoff, hover, stop) by design.

use aeris_schemas::{
    ActionMode, BLIND_CLIMB_SLACK_M, BLIND_MOVE_M, BoundSetpoint, Decision, DecisionError,
    DecisionLimits, OCCUPANCY_SIDE, OCCUPANCY_UNKNOWN, OccupancyGrid, OccupancyStatus,
    SetpointError, all_finite, clamp,
};

/// How far above the clearance a way raised over an obstacle passes its top (m): a way at
/// exactly top + clearance would still count that cell as blocking.
pub const OVER_MARGIN_M: f32 = 0.5;

/// Why a decision was not admitted.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GateError {
    /// Valid(D_t) failed: a field is missing, NaN/inf, or out of range.
    #[error("invalid decision")]
    Invalid(#[from] DecisionError),
    /// The vehicle position given to the gate is NaN or infinite.
    #[error("vehicle position {0:?} is not finite")]
    BadPosition([f32; 3]),
    /// The occupancy grid is malformed (unknown status byte; present with a NaN/inf
    /// origin or resolution, or a resolution <= 0).
    #[error(
        "occupancy grid is malformed (unknown status, or origin or resolution not finite / positive)"
    )]
    BadGrid,
    /// No occupancy is present and the decision would cross unknown space below the
    /// conservative altitude (a land far from a vehicle flying lower than that).
    #[error(
        "no occupancy: a land {distance_m} m away would cross unknown space at {altitude_m} m, \
         below the conservative altitude {needed_m} m"
    )]
    NoOccupancy {
        /// Horizontal distance from the vehicle to the touchdown (m).
        distance_m: f32,
        /// The vehicle's altitude (m).
        altitude_m: f32,
        /// The conservative altitude (m).
        needed_m: f32,
    },
    /// An obstacle blocks the way and pulling back leaves less than one cell of motion.
    #[error(
        "blocked by an obstacle {top_m} m high at [N, E] = {at:?}: only {free_m} m of motion left"
    )]
    Blocked {
        /// Centre `[N, E]` of the blocking cell.
        at: [f32; 2],
        /// Obstacle top in that cell (m).
        top_m: f32,
        /// Motion left after pulling back (m, >= 0).
        free_m: f32,
    },
    /// No altitude in the band (or above an obstacle) is allowed.
    #[error("no feasible altitude: needs >= {min} m but the band ends at {max} m")]
    NoAltitude {
        /// Lowest altitude needed (m).
        min: f32,
        /// Highest altitude allowed (m).
        max: f32,
    },
    /// The bound setpoint failed [`BoundSetpoint::validate`] (limits that admit no
    /// setpoint for this action, e.g. h_max < 0 for a land).
    #[error("the bound setpoint is not flyable: {0}")]
    Unbindable(SetpointError),
}

/// Why a gate could not be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GateConfigError {
    /// The decision limits are incoherent (NaN, h_min > h_max, empty geofence, ...).
    #[error("decision limits are incoherent")]
    IncoherentLimits,
    /// The obstacle clearance is NaN, infinite or negative.
    #[error("obstacle clearance {0} m must be finite and >= 0")]
    BadClearance(f32),
}

/// A decision made feasible, before binding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Feasible {
    /// The validated action.
    pub mode: ActionMode,
    /// Target position `[N, E, U]` (altitude applied).
    pub position: [f32; 3],
    /// Speed limit (m/s).
    pub speed: f32,
    /// `true` when anything was changed to make it feasible.
    pub clamped: bool,
    /// Why: [`aeris_schemas::clamp`] bits (0 when not clamped).
    pub reasons: u32,
}

/// Where the segment walk first met a blocking cell.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Hit {
    /// Segment parameter in [0, 1] at which the segment enters the cell.
    t: f64,
    /// Cell index (row-major).
    cell: usize,
    /// Obstacle top (m).
    top: f32,
}

/// The decision gate of one flight: its limits, obstacle clearance included.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecisionGate {
    limits: DecisionLimits,
}

impl DecisionGate {
    /// A gate for `limits`, keeping `limits.obstacle_clearance_m` metres from obstacles (a
    /// flight's gate: `DecisionGate::new(mission.decision_limits())`).
    pub fn new(limits: DecisionLimits) -> Result<Self, GateConfigError> {
        if !limits.is_coherent() {
            return Err(GateConfigError::IncoherentLimits);
        }
        let clearance_m = limits.obstacle_clearance_m;
        if !(clearance_m.is_finite() && clearance_m >= 0.0) {
            return Err(GateConfigError::BadClearance(clearance_m));
        }
        Ok(Self { limits })
    }

    /// The limits decisions are checked against.
    pub fn limits(&self) -> &DecisionLimits {
        &self.limits
    }

    /// The obstacle clearance (m).
    pub fn clearance_m(&self) -> f32 {
        self.limits.obstacle_clearance_m
    }

    /// The altitude band `[max(h_min, fence_min.U), min(h_max, fence_max.U)]` (may be empty).
    pub fn altitude_band(&self) -> (f32, f32) {
        self.limits.altitude_band()
    }

    /// Valid(D_t): [`Decision::validate`] against the flight's limits.
    pub fn validate(&self, d: &Decision) -> Result<ActionMode, GateError> {
        Ok(d.validate(&self.limits)?)
    }

    /// Project `[N, E]` into the geofence.
    fn project(&self, p: [f32; 2]) -> [f32; 2] {
        let l = &self.limits;
        [
            p[0].clamp(l.geofence_min[0], l.geofence_max[0]),
            p[1].clamp(l.geofence_min[1], l.geofence_max[1]),
        ]
    }

    /// Occupancy-aware feasibility of a validated decision (`mode` from
    /// [`DecisionGate::validate`]) for a vehicle at `position` `[N, E, U]`: clamp or reject.
    /// `grid` is what perception sees; `None`, or a grid that is not present, is no
    /// occupancy (see the module documentation).
    pub fn feasible(
        &self,
        d: &Decision,
        mode: ActionMode,
        position: [f32; 3],
        grid: Option<&OccupancyGrid>,
    ) -> Result<Feasible, GateError> {
        if !all_finite(&position) {
            return Err(GateError::BadPosition(position));
        }
        let grid = usable_grid(grid)?;
        let (lo, hi) = self.altitude_band();
        if lo > hi {
            return Err(GateError::NoAltitude { min: lo, max: hi });
        }
        let here = self.project([position[0], position[1]]);
        let mut reasons = 0;
        if here != [position[0], position[1]]
            && matches!(
                mode,
                ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn
            )
        {
            reasons |= clamp::GEOFENCE;
        }
        let mut h = d.altitude;
        if h < lo || h > hi {
            h = h.clamp(lo, hi);
            reasons |= clamp::ALTITUDE;
        }
        let speed = if d.speed >= 0.0 && d.speed <= self.limits.v_max {
            d.speed
        } else {
            reasons |= clamp::SPEED;
            if d.speed > self.limits.v_max {
                self.limits.v_max
            } else {
                0.0
            }
        };
        let c = self.clearance_m();
        let target = [d.target[0], d.target[1]];
        let position = match (mode, grid) {
            (_, None) => {
                let (p, h) = self.blind(mode, here, target, position, h, &mut reasons)?;
                [p[0], p[1], h]
            }
            (
                ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn,
                Some(g),
            ) => {
                if let Some(top) = obstacle_top(g, here)
                    && top >= h - c
                {
                    let need = top + c;
                    if need > hi {
                        return Err(GateError::NoAltitude { min: need, max: hi });
                    }
                    h = need;
                    reasons |= clamp::OBSTACLE;
                }
                [here[0], here[1], h]
            }
            (ActionMode::Goto | ActionMode::Hover | ActionMode::Stop, Some(g)) => {
                self.way_over(here, target, h, position[2], hi, g, &mut reasons)?
            }
            (ActionMode::Land, Some(g)) => {
                let cross = h.min(position[2]);
                let (p, pulled) = self.walk(here, target, cross, g)?;
                if pulled {
                    reasons |= clamp::OBSTACLE;
                }
                if let Some(cell) = g.cell_of(p)
                    && let Some(top) = obstacle(g.cells[cell])
                {
                    return Err(GateError::Blocked {
                        at: cell_centre(g, cell),
                        top_m: top,
                        free_m: 0.0,
                    });
                }
                [p[0], p[1], 0.0]
            }
        };
        Ok(Feasible {
            mode,
            position,
            speed,
            clamped: reasons != 0,
            reasons,
        })
    }

    /// Feasibility without occupancy (module documentation): the horizontal target and
    /// h_t (0 for a land), adding [`clamp::NO_OCCUPANCY`] to `reasons` when either moved.
    fn blind(
        &self,
        mode: ActionMode,
        here: [f32; 2],
        target: [f32; 2],
        position: [f32; 3],
        h: f32,
        reasons: &mut u32,
    ) -> Result<([f32; 2], f32), GateError> {
        let b = self.limits.blind_altitude();
        let low = position[2] < b - BLIND_CLIMB_SLACK_M;
        let away = horizontal_distance(here, target);
        let moves = away > BLIND_MOVE_M;
        let (to, floor) = match mode {
            ActionMode::Land if moves && low => {
                return Err(GateError::NoOccupancy {
                    distance_m: away,
                    altitude_m: position[2],
                    needed_m: b,
                });
            }
            ActionMode::Land => return Ok((target, 0.0)),
            ActionMode::Goto | ActionMode::Hover | ActionMode::Stop if moves => {
                if low {
                    // climb where the vehicle is first; the way is flown once up there
                    *reasons |= clamp::NO_OCCUPANCY;
                    (here, b)
                } else {
                    (target, b)
                }
            }
            ActionMode::Goto | ActionMode::Hover | ActionMode::Stop => (target, b.min(position[2])),
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn => {
                (here, b.min(position[2]))
            }
        };
        if h < floor {
            *reasons |= clamp::NO_OCCUPANCY;
            return Ok((to, floor));
        }
        Ok((to, h))
    }

    /// A goto's (hover's, stop's) way from `here` to `target` at `h`, raised over an obstacle
    /// that blocks it outright (module documentation): the (possibly pulled back) target at
    /// the (possibly raised) altitude, or the vehicle's place at the raised altitude while the
    /// vehicle at `altitude` is still below it. `hi` is the band's top.
    #[allow(clippy::too_many_arguments)]
    fn way_over(
        &self,
        here: [f32; 2],
        target: [f32; 2],
        mut h: f32,
        altitude: f32,
        hi: f32,
        g: &OccupancyGrid,
        reasons: &mut u32,
    ) -> Result<[f32; 3], GateError> {
        let c = self.clearance_m();
        // bounded: a blocking top is >= h - c, so every raise lifts h by at least
        // OVER_MARGIN_M, and never above hi
        loop {
            match self.walk(here, target, h, g) {
                Ok((p, pulled)) => {
                    if pulled {
                        *reasons |= clamp::OBSTACLE;
                    }
                    return Ok([p[0], p[1], h]);
                }
                Err(GateError::Blocked { top_m, .. }) if top_m + c + OVER_MARGIN_M <= hi => {
                    let over = top_m + c + OVER_MARGIN_M;
                    *reasons |= clamp::OBSTACLE;
                    if altitude < over - c / 2.0 {
                        // climb where the vehicle is first; the way is flown once up there
                        return Ok([here[0], here[1], over]);
                    }
                    h = over;
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// Walk the segment `from -> to` at altitude `h`; the (possibly pulled back) target and
    /// whether it was pulled back.
    fn walk(
        &self,
        from: [f32; 2],
        to: [f32; 2],
        h: f32,
        g: &OccupancyGrid,
    ) -> Result<([f32; 2], bool), GateError> {
        let clearance = self.clearance_m();
        let Some(hit) = first_blocking(g, from, to, h - clearance) else {
            return Ok((to, false));
        };
        let (dn, de) = (to[0] as f64 - from[0] as f64, to[1] as f64 - from[1] as f64);
        let length = dn.hypot(de);
        let free = hit.t * length - clearance as f64;
        if free < g.resolution_m as f64 || length <= 0.0 {
            return Err(GateError::Blocked {
                at: cell_centre(g, hit.cell),
                top_m: hit.top,
                free_m: free.max(0.0) as f32,
            });
        }
        let k = free / length;
        let p = [
            (from[0] as f64 + dn * k) as f32,
            (from[1] as f64 + de * k) as f32,
        ];
        // the segment lies in the (convex) geofence; this only removes rounding
        Ok((self.project(p), true))
    }

    /// Bind a feasible decision to a setpoint and check it with
    /// [`BoundSetpoint::validate`]. `active_step` is the decision's step, `reused` 0 and
    /// `seq`/`publish_ns` 0: the hub fills them when it publishes.
    pub fn bind(&self, d: &Decision, f: &Feasible) -> Result<BoundSetpoint, GateError> {
        let sp = BoundSetpoint {
            seq: 0,
            decision_seq: d.seq,
            publish_ns: 0,
            position: f.position,
            yaw: d.yaw,
            speed: f.speed,
            acceptance_radius: d.acceptance_radius,
            active_step: d.step,
            mode: f.mode as u8,
            reused: 0,
            clamped: f.clamped as u8,
            reserved: [0; 3],
        };
        sp.validate(&self.limits).map_err(GateError::Unbindable)?;
        Ok(sp)
    }

    /// Validate, make feasible and bind `d` for a vehicle at `position` in one call
    /// (allocation-free).
    pub fn admit(
        &self,
        d: &Decision,
        position: [f32; 3],
        grid: Option<&OccupancyGrid>,
    ) -> Result<BoundSetpoint, GateError> {
        let mode = self.validate(d)?;
        let f = self.feasible(d, mode, position, grid)?;
        self.bind(d, &f)
    }

    /// Whether the setpoint `sp` this gate bound (a committed one) can still be flown from
    /// `position` with what `grid` shows now. Nothing is validated, clamped or bound again:
    /// the way is walked as [`DecisionGate::feasible`] walks a decision's, and any obstacle
    /// it meets is an error. A goto, hover or stop crosses at the setpoint's altitude, a land
    /// at the vehicle's and onto a free cell; an in-place setpoint must still clear the cell
    /// under it by the clearance. Without occupancy, a setpoint more than [`BLIND_MOVE_M`]
    /// away (other than an in-place action's) fails while the vehicle is more than
    /// [`BLIND_CLIMB_SLACK_M`] below the conservative altitude. A setpoint the gate just bound
    /// for the same `position` and `grid` passes.
    pub fn check_way(
        &self,
        sp: &BoundSetpoint,
        position: [f32; 3],
        grid: Option<&OccupancyGrid>,
    ) -> Result<(), GateError> {
        if !all_finite(&position) {
            return Err(GateError::BadPosition(position));
        }
        let here = self.project([position[0], position[1]]);
        let to = [sp.position[0], sp.position[1]];
        let Some(g) = usable_grid(grid)? else {
            let b = self.limits.blind_altitude();
            let away = horizontal_distance(here, to);
            let in_place = matches!(
                ActionMode::from_u8(sp.mode),
                Some(
                    ActionMode::Takeoff
                        | ActionMode::Ascend
                        | ActionMode::Descend
                        | ActionMode::Turn
                )
            );
            if !in_place && away > BLIND_MOVE_M && position[2] < b - BLIND_CLIMB_SLACK_M {
                return Err(GateError::NoOccupancy {
                    distance_m: away,
                    altitude_m: position[2],
                    needed_m: b,
                });
            }
            return Ok(());
        };
        let c = self.clearance_m();
        let blocked = |cell: usize, top_m: f32, free_m: f32| GateError::Blocked {
            at: cell_centre(g, cell),
            top_m,
            free_m,
        };
        let walk = |cross: f32| match first_blocking(g, here, to, cross - c) {
            None => Ok(()),
            Some(hit) => {
                let length = f64::from(to[0] - here[0]).hypot(f64::from(to[1] - here[1]));
                let free = (hit.t * length - f64::from(c)).max(0.0);
                Err(blocked(hit.cell, hit.top, free as f32))
            }
        };
        match ActionMode::from_u8(sp.mode) {
            Some(
                ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend | ActionMode::Turn,
            ) => {
                // the gate raised it to exactly top + clearance: rounding is not an obstacle
                match g.cell_of(to).and_then(|i| Some((i, obstacle(g.cells[i])?))) {
                    Some((cell, top)) if top > sp.position[2] - c + 1e-3 => {
                        Err(blocked(cell, top, 0.0))
                    }
                    _ => Ok(()),
                }
            }
            Some(ActionMode::Land) => {
                walk(position[2])?;
                match g.cell_of(to).and_then(|i| Some((i, obstacle(g.cells[i])?))) {
                    Some((cell, top)) => Err(blocked(cell, top, 0.0)),
                    None => Ok(()),
                }
            }
            _ => walk(sp.position[2]),
        }
    }

    /// A hover setpoint holding `position` (projected into the geofence, altitude capped at
    /// the band's top), with the yaw, speed and radius of `d` (sanitised) — what the hub
    /// flies when the last valid decision became infeasible.
    pub fn hold(&self, d: &Decision, position: [f32; 3]) -> Result<BoundSetpoint, GateError> {
        if !all_finite(&position) {
            return Err(GateError::BadPosition(position));
        }
        let (_, hi) = self.altitude_band();
        let here = self.project([position[0], position[1]]);
        let pi = std::f32::consts::PI;
        let finite_or = |v: f32, lo: f32, hi: f32| if v.is_finite() { v.clamp(lo, hi) } else { lo };
        let sp = BoundSetpoint {
            seq: 0,
            decision_seq: d.seq,
            publish_ns: 0,
            position: [here[0], here[1], position[2].min(hi)],
            yaw: finite_or(d.yaw, -pi, pi),
            speed: finite_or(d.speed, 0.0, self.limits.v_max),
            acceptance_radius: finite_or(d.acceptance_radius, 0.0, self.limits.r_max),
            active_step: d.step,
            mode: ActionMode::Hover as u8,
            reused: 0,
            clamped: 1,
            reserved: [0; 3],
        };
        sp.validate(&self.limits).map_err(GateError::Unbindable)?;
        Ok(sp)
    }
}

/// The grid if it is present and well-formed; `Ok(None)` when there is no occupancy (no
/// grid, or its status absent or stale).
fn usable_grid(grid: Option<&OccupancyGrid>) -> Result<Option<&OccupancyGrid>, GateError> {
    let Some(g) = grid else {
        return Ok(None);
    };
    match g.status() {
        None => Err(GateError::BadGrid),
        Some(OccupancyStatus::Absent | OccupancyStatus::Stale) => Ok(None),
        Some(OccupancyStatus::Present) => {
            let r = g.resolution_m;
            if !r.is_finite() || r <= 0.0 || !all_finite(&g.origin) {
                return Err(GateError::BadGrid);
            }
            Ok(Some(g))
        }
    }
}

/// Horizontal distance (m) between two points `[N, E]` (in f64: no overflow to inf for
/// finite inputs far apart).
fn horizontal_distance(a: [f32; 2], b: [f32; 2]) -> f32 {
    (f64::from(a[0]) - f64::from(b[0])).hypot(f64::from(a[1]) - f64::from(b[1])) as f32
}

/// Obstacle top of a cell value: observed and above the ground.
pub(crate) fn obstacle(v: u8) -> Option<f32> {
    (v != OCCUPANCY_UNKNOWN && v > 0).then_some(v as f32)
}

/// Obstacle top in the cell under `p`, if any.
pub(crate) fn obstacle_top(g: &OccupancyGrid, p: [f32; 2]) -> Option<f32> {
    g.cell_of(p).and_then(|i| obstacle(g.cells[i]))
}

/// Centre `[N, E]` of cell `i`.
fn cell_centre(g: &OccupancyGrid, i: usize) -> [f32; 2] {
    let half = (OCCUPANCY_SIDE / 2) as f32;
    let (r, c) = ((i / OCCUPANCY_SIDE) as f32, (i % OCCUPANCY_SIDE) as f32);
    [
        g.origin[0] + (r - half + 0.5) * g.resolution_m,
        g.origin[1] + (c - half + 0.5) * g.resolution_m,
    ]
}

/// The first cell touched by the segment `from -> to` (in order along it) holding an
/// obstacle with top `>= threshold`. Exact grid traversal (Amanatides & Woo) of the part of
/// the segment inside the grid, ending in the cell of its end point; at most `2 * SIDE - 1`
/// cells are visited.
fn first_blocking(g: &OccupancyGrid, from: [f32; 2], to: [f32; 2], threshold: f32) -> Option<Hit> {
    let side = OCCUPANCY_SIDE as f64;
    let res = g.resolution_m as f64;
    let half = side / 2.0;
    // continuous grid coordinates: x = row (north), y = column (east)
    let x0 = (from[0] as f64 - g.origin[0] as f64) / res + half;
    let y0 = (from[1] as f64 - g.origin[1] as f64) / res + half;
    let x1 = (to[0] as f64 - g.origin[0] as f64) / res + half;
    let y1 = (to[1] as f64 - g.origin[1] as f64) / res + half;
    let (dx, dy) = (x1 - x0, y1 - y0);
    // Liang-Barsky clip of t in [0, 1] to the square [0, side]^2
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [(-dx, x0), (dx, side - x0), (-dy, y0), (dy, side - y0)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                if r > t1 {
                    return None;
                }
                t0 = t0.max(r);
            } else {
                if r < t0 {
                    return None;
                }
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let last = OCCUPANCY_SIDE as i64 - 1;
    let cell_at = |t: f64| {
        (
            ((x0 + t * dx).floor() as i64).clamp(0, last),
            ((y0 + t * dy).floor() as i64).clamp(0, last),
        )
    };
    let (mut ix, mut iy) = cell_at(t0);
    let (end_x, end_y) = cell_at(t1);
    let axis = |d: f64, start: f64, i: i64| -> (i64, f64, f64) {
        if d > 0.0 {
            (1, ((i + 1) as f64 - start) / d, 1.0 / d)
        } else if d < 0.0 {
            (-1, (i as f64 - start) / d, -1.0 / d)
        } else {
            (0, f64::INFINITY, f64::INFINITY)
        }
    };
    let (step_x, mut t_max_x, dt_x) = axis(dx, x0, ix);
    let (step_y, mut t_max_y, dt_y) = axis(dy, y0, iy);
    // The walk takes exactly the steps from the first cell to the cell of the end point, so
    // it always ends there. (Stopping when the next crossing time passes t1 let the rounding
    // of the accumulated crossing times decide whether the cell of an end point lying on a
    // cell boundary was visited: a target on the edge of a wall's cell could skip the wall.)
    let (mut left_x, mut left_y) = ((end_x - ix).abs(), (end_y - iy).abs());
    let mut t_enter = t0;
    loop {
        let cell = ix as usize * OCCUPANCY_SIDE + iy as usize;
        if let Some(top) = obstacle(g.cells[cell])
            && top >= threshold
        {
            return Some(Hit {
                t: t_enter,
                cell,
                top,
            });
        }
        let in_x = match (left_x, left_y) {
            (0, 0) => return None,
            (_, 0) => true,
            (0, _) => false,
            _ => t_max_x < t_max_y,
        };
        if in_x {
            ix += step_x;
            left_x -= 1;
            t_enter = t_max_x;
            t_max_x += dt_x;
        } else {
            iy += step_y;
            left_y -= 1;
            t_enter = t_max_y;
            t_max_y += dt_y;
        }
    }
}

#[cfg(test)]
mod tests;
