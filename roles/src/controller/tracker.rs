//! The tracker: the controller's setpoint gate and trajectory reference. Pure: no I/O, no
//! allocation; one [`Tracker::tick`] per control period turns the newest valid setpoint
//! (or a hold, without a fresh one) into the position target, feed-forward and yaw to send.
//!
//! With no valid setpoint fresher than the timeout (or none yet), it holds the position
//! latched when the hold began; otherwise it flies the setpoint's mode: takeoff / ascend /
//! descend climb or sink vertically at the north/east where the mode began, goto flies to
//! the waypoint, hover / stop hold, turn holds and yaws, land flies to the target's
//! north/east and descends to the ground. The commanded position is a reference ("carrot")
//! that moves towards the target at `min(setpoint.speed, v_max)` (braking before the
//! target, waiting when the vehicle falls behind) with a velocity feed-forward of the same
//! speed, so the vehicle never needs to fly faster than allowed. Positions stay in the
//! geofence; altitude is clamped to `[h_min, h_max]` except while landing and on the
//! ground before takeoff.

use aeris_runtime::RoleSpec;
use aeris_schemas::{
    ActionMode, BoundSetpoint, ControllerLease, DecisionLimits, LEASE_HAS_HOLD,
    LEASE_HAS_REFERENCE, SetpointError,
};

/// How the tracker turns setpoints into position targets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerConfig {
    /// The flight's limits (validation, geofence, altitude band, v_max).
    pub limits: DecisionLimits,
    /// Position assumed before the autopilot reports one `[N, E, U]`.
    pub start: [f32; 3],
    /// Control period (s).
    pub period_s: f32,
    /// A valid setpoint older than this no longer counts (ns).
    pub setpoint_timeout_ns: u64,
    /// Speed used to return to a hold position (m/s, capped by v_max).
    pub hold_speed: f32,
    /// Final descent speed when landing (m/s, capped by v_max).
    pub land_speed: f32,
    /// Deceleration the reference plans with before the target (m/s^2).
    pub brake_accel: f32,
    /// The reference waits when it is further ahead of the vehicle than
    /// `max(leash_min_m, speed * leash_s)`.
    pub leash_s: f32,
    /// Minimum leash (m).
    pub leash_min_m: f32,
}

impl TrackerConfig {
    /// Configuration from a role spec (mission limits, start, timing).
    pub fn from_spec(spec: &RoleSpec) -> Self {
        let limits = spec.mission.decision_limits();
        let rate = spec.timing.control_rate_hz;
        let period_s = if rate.is_finite() && rate > 0.0 {
            (1.0 / rate) as f32
        } else {
            0.02
        };
        Self {
            limits,
            start: spec.mission.start,
            period_s,
            setpoint_timeout_ns: spec.timing.setpoint_timeout_ms.saturating_mul(1_000_000),
            hold_speed: spec.mission.cruise_speed.min(limits.v_max),
            land_speed: 1.0_f32.min(limits.v_max),
            brake_accel: 2.0,
            leash_s: 1.0,
            leash_min_m: 2.0,
        }
    }

    /// The ground the tracker lands on: the geofence floor (m, up).
    pub fn floor(&self) -> f32 {
        self.limits.geofence_min[2]
    }
}

/// What the tracker knows about the vehicle this tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleView {
    /// Position `[N, E, U]`, when the autopilot reported one.
    pub position: Option<[f32; 3]>,
    /// Yaw (rad), when reported.
    pub yaw: Option<f32>,
    /// On the ground.
    pub landed: bool,
}

/// One tick's target in `[N, E, U]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackCommand {
    /// Position target `[N, E, U]`.
    pub position: [f32; 3],
    /// Velocity feed-forward `[N, E, U]`.
    pub velocity: [f32; 3],
    /// Yaw target (rad).
    pub yaw: f32,
    /// The mode flown; `None` while holding for lack of a fresh valid setpoint.
    pub mode: Option<ActionMode>,
}

#[derive(Debug, Clone, Copy)]
struct Current {
    sp: BoundSetpoint,
    mode: ActionMode,
    fresh_until_ns: u64,
}

/// Setpoint gate and trajectory reference of the controller (pure: no I/O, no allocation).
#[derive(Debug, Clone)]
pub struct Tracker {
    cfg: TrackerConfig,
    current: Option<Current>,
    carrot: Option<[f32; 3]>,
    anchor: Option<(ActionMode, [f32; 3])>,
    hold: Option<([f32; 3], f32)>,
    last_good: [f32; 3],
    refused: u64,
    accepted: u64,
    hold_ticks: u64,
}

/// `v` raised to `lo`, then lowered to `hi`: `f32::clamp` without its panic when limits
/// that were never validated (a hand-written role spec) have `lo > hi`; `hi` wins then.
fn bound(v: f32, lo: f32, hi: f32) -> f32 {
    v.max(lo).min(hi)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(super) fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn scale(v: [f32; 3], k: f32) -> [f32; 3] {
    [v[0] * k, v[1] * k, v[2] * k]
}

impl Tracker {
    /// A tracker with no setpoint yet.
    pub fn new(cfg: TrackerConfig) -> Self {
        let start = cfg.start;
        let mut t = Self {
            cfg,
            current: None,
            carrot: None,
            anchor: None,
            hold: None,
            last_good: [0.0; 3],
            refused: 0,
            accepted: 0,
            hold_ticks: 0,
        };
        t.last_good = if start.iter().all(|v| v.is_finite()) {
            t.fence(start)
        } else {
            [0.0; 3]
        };
        t
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.cfg
    }

    /// Offer a setpoint received at `now_ns`: refused (and counted) when it fails
    /// validation, otherwise it becomes the current setpoint. It stays fresh until
    /// `min(publish_ns, now_ns) + setpoint_timeout`.
    pub fn offer(&mut self, sp: &BoundSetpoint, now_ns: u64) -> Result<ActionMode, SetpointError> {
        match sp.validate(&self.cfg.limits) {
            Ok(mode) => {
                self.accepted += 1;
                self.current = Some(Current {
                    sp: *sp,
                    mode,
                    fresh_until_ns: sp
                        .publish_ns
                        .min(now_ns)
                        .saturating_add(self.cfg.setpoint_timeout_ns),
                });
                Ok(mode)
            }
            Err(e) => {
                self.refused += 1;
                Err(e)
            }
        }
    }

    /// The current setpoint if it is still fresh at `now_ns`.
    pub fn active(&self, now_ns: u64) -> Option<(&BoundSetpoint, ActionMode)> {
        self.current
            .as_ref()
            .filter(|c| now_ns <= c.fresh_until_ns)
            .map(|c| (&c.sp, c.mode))
    }

    /// Setpoints refused by validation so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// Setpoints accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }

    /// Ticks spent holding for lack of a fresh valid setpoint.
    pub fn hold_ticks(&self) -> u64 {
        self.hold_ticks
    }

    /// Write this tracker's reference, anchor and hold latch into `lease`, for a standby
    /// that may have to go on from here.
    pub fn write_handover(&self, lease: &mut ControllerLease) {
        lease.flags = 0;
        if let Some(c) = self.carrot {
            lease.reference = c;
            lease.flags |= LEASE_HAS_REFERENCE;
        }
        match self.anchor {
            Some((mode, a)) => {
                lease.anchor_mode = mode as u8;
                lease.anchor = a;
            }
            None => lease.anchor_mode = 0,
        }
        if let Some((h, yaw)) = self.hold {
            lease.hold = h;
            lease.hold_yaw = yaw;
            lease.flags |= LEASE_HAS_HOLD;
        }
    }

    /// Go on from the reference, anchor and hold latch another tracker wrote into `lease`
    /// (non-finite parts are dropped; the reference is kept in the geofence).
    pub fn adopt(&mut self, lease: &ControllerLease) {
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        self.carrot = (lease.flags & LEASE_HAS_REFERENCE != 0 && finite(&lease.reference))
            .then(|| self.fence(lease.reference));
        self.anchor = ActionMode::from_u8(lease.anchor_mode)
            .filter(|_| finite(&lease.anchor))
            .map(|m| (m, lease.anchor));
        self.hold = (lease.flags & LEASE_HAS_HOLD != 0
            && finite(&lease.hold)
            && lease.hold_yaw.is_finite())
        .then_some((lease.hold, lease.hold_yaw));
    }

    /// `true` when the active setpoint wants the vehicle armed and in offboard: a fresh,
    /// valid setpoint of a flying mode, or any fresh setpoint while airborne.
    pub fn wants_flight(&self, now_ns: u64, landed: bool) -> bool {
        self.active(now_ns).is_some_and(|(_, mode)| {
            !landed
                || matches!(
                    mode,
                    ActionMode::Takeoff
                        | ActionMode::Goto
                        | ActionMode::Ascend
                        | ActionMode::Descend
                )
        })
    }

    fn clamp_alt(&self, u: f32) -> f32 {
        bound(u, self.cfg.limits.h_min, self.cfg.limits.h_max)
    }

    /// Keep `p` in the geofence and under h_max (the hard guarantee on every output).
    fn fence(&self, p: [f32; 3]) -> [f32; 3] {
        let l = &self.cfg.limits;
        [
            bound(p[0], l.geofence_min[0], l.geofence_max[0]),
            bound(p[1], l.geofence_min[1], l.geofence_max[1]),
            bound(p[2], l.geofence_min[2], l.geofence_max[2].min(l.h_max)),
        ]
    }

    /// Altitude of a holding position: on the ground it stays there (before takeoff),
    /// in the air it is clamped into the altitude band.
    fn hold_alt(&self, u: f32, landed: bool) -> f32 {
        if landed { u } else { self.clamp_alt(u) }
    }

    /// Move the reference towards `target` at up to `speed`; the feed-forward velocity.
    fn advance(&mut self, target: [f32; 3], speed: f32, vehicle: Option<[f32; 3]>) -> [f32; 3] {
        let carrot = self.carrot.unwrap_or(target);
        let d = sub(target, carrot);
        let dist = norm(d);
        if dist < 1e-4 || speed <= 0.0 {
            self.carrot = Some(if dist < 1e-4 { target } else { carrot });
            return [0.0; 3];
        }
        let dir = scale(d, 1.0 / dist);
        let v = speed.min((2.0 * self.cfg.brake_accel * dist).sqrt());
        let leash = self.cfg.leash_min_m.max(speed * self.cfg.leash_s);
        let waiting = vehicle.is_some_and(|p| norm(sub(carrot, p)) > leash);
        if !waiting {
            let step = (v * self.cfg.period_s).min(dist);
            self.carrot = Some([
                carrot[0] + dir[0] * step,
                carrot[1] + dir[1] * step,
                carrot[2] + dir[2] * step,
            ]);
        }
        scale(dir, v)
    }

    /// One control tick at `now_ns`: the position target, feed-forward and yaw to send.
    pub fn tick(&mut self, now_ns: u64, vehicle: &VehicleView) -> TrackCommand {
        let seed = vehicle.position.unwrap_or(self.cfg.start);
        if self.carrot.is_none() {
            self.carrot = Some(self.fence(seed));
        }
        let v_max = self.cfg.limits.v_max;
        let Some((sp, mode)) = self.active(now_ns).map(|(sp, m)| (*sp, m)) else {
            // Hold the position latched when the hold began.
            self.hold_ticks += 1;
            self.anchor = None;
            let (pos, yaw) = *self.hold.get_or_insert((seed, vehicle.yaw.unwrap_or(0.0)));
            let target = self.fence([pos[0], pos[1], self.hold_alt(pos[2], vehicle.landed)]);
            let speed = self.cfg.hold_speed.min(v_max);
            let ff = self.advance(target, speed, vehicle.position);
            return self.output(ff, yaw, None);
        };
        self.hold = None;
        let carrot = self.carrot.unwrap_or(seed);
        let anchor = match self.anchor {
            Some((m, a)) if m == mode => a,
            _ => {
                self.anchor = Some((mode, carrot));
                carrot
            }
        };
        let speed = sp.speed.min(v_max);
        let [n, e, u] = sp.position;
        let ff = match mode {
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend => {
                let target = self.fence([anchor[0], anchor[1], self.clamp_alt(u)]);
                self.advance(target, speed, vehicle.position)
            }
            ActionMode::Goto => {
                let target = self.fence([n, e, self.clamp_alt(u)]);
                self.advance(target, speed, vehicle.position)
            }
            ActionMode::Hover | ActionMode::Stop | ActionMode::Turn => {
                let target = self.fence([
                    anchor[0],
                    anchor[1],
                    self.hold_alt(anchor[2], vehicle.landed),
                ]);
                self.advance(
                    target,
                    speed.max(self.cfg.hold_speed.min(v_max)),
                    vehicle.position,
                )
            }
            ActionMode::Land => {
                // First over the target at the current altitude, then straight down.
                let land_speed = self.cfg.land_speed.min(v_max);
                let horizontal = ((carrot[0] - n).powi(2) + (carrot[1] - e).powi(2)).sqrt();
                if horizontal > 0.05 {
                    let target = self.fence([n, e, carrot[2]]);
                    self.advance(target, speed.max(land_speed), vehicle.position)
                } else {
                    let floor = self.cfg.floor();
                    let target = self.fence([n, e, floor]);
                    let ff = self.advance(target, land_speed, vehicle.position);
                    let above = vehicle
                        .position
                        .is_some_and(|p| p[2] > floor + 0.05 && !vehicle.landed);
                    if norm(ff) < 1e-6 && above {
                        // Keep pushing down for a firm touchdown.
                        [0.0, 0.0, -land_speed]
                    } else {
                        ff
                    }
                }
            }
        };
        self.output(ff, sp.yaw, Some(mode))
    }

    fn output(&mut self, ff: [f32; 3], yaw: f32, mode: Option<ActionMode>) -> TrackCommand {
        let mut position = self.fence(self.carrot.unwrap_or(self.cfg.start));
        let mut ff = ff;
        if !position.iter().chain(ff.iter()).all(|v| v.is_finite()) {
            // Defence in depth (inputs are validated): never put a non-finite number on
            // the wire; stay at the last good reference instead.
            position = self.last_good;
            ff = [0.0; 3];
        }
        self.carrot = Some(position);
        self.last_good = position;
        let v_max = self.cfg.limits.v_max;
        let s = norm(ff);
        let velocity = if s > v_max { scale(ff, v_max / s) } else { ff };
        TrackCommand {
            position,
            velocity,
            yaw: if yaw.is_finite() { yaw } else { 0.0 },
            mode,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::lease::LeaseArbiter;

    const MS: u64 = 1_000_000;
    const PERIOD: u64 = 20 * MS;
    const LISTEN: u64 = 200 * MS;

    fn tracker_config() -> TrackerConfig {
        TrackerConfig {
            limits: DecisionLimits {
                v_max: 8.0,
                h_min: 0.0,
                h_max: 60.0,
                r_max: 10.0,
                geofence_min: [-20.0, -40.0, 0.0],
                geofence_max: [160.0, 140.0, 60.0],
                subgoals: 4,
                obstacle_clearance_m: 3.0,
            },
            start: [0.0; 3],
            period_s: 0.02,
            setpoint_timeout_ns: 500 * MS,
            hold_speed: 5.0,
            land_speed: 1.0,
            brake_accel: 2.0,
            leash_s: 1.0,
            leash_min_m: 2.0,
        }
    }

    #[test]
    fn a_standby_that_adopts_the_holders_lease_commands_what_the_holder_would_have() {
        let cfg = tracker_config();
        let goto = BoundSetpoint {
            seq: 1,
            decision_seq: 1,
            position: [62.0, 0.0, 12.0],
            speed: 5.0,
            acceptance_radius: 3.0,
            active_step: 2,
            mode: ActionMode::Goto as u8,
            ..BoundSetpoint::default()
        };
        let mut holder = Tracker::new(cfg);
        // the standby joined mid-flight: it never ticked, its reference would start at `start`
        let mut standby = Tracker::new(cfg);
        let mut view = VehicleView {
            position: Some([20.0, 0.0, 12.0]),
            yaw: Some(0.0),
            landed: false,
        };
        let mut t = 1_000 * MS;
        for _ in 0..40 {
            let mut sp = goto;
            sp.publish_ns = t;
            holder.offer(&sp, t).unwrap();
            standby.offer(&sp, t).unwrap();
            holder.tick(t, &view);
            view.position = view.position.map(|p| [p[0] + 0.1, p[1], p[2]]);
            t += PERIOD;
        }
        let mut lease = LeaseArbiter::new(1, true, 0, PERIOD, LISTEN).lease(t, 0);
        holder.write_handover(&mut lease);
        assert_eq!(lease.flags & LEASE_HAS_REFERENCE, LEASE_HAS_REFERENCE);
        standby.adopt(&lease);
        for _ in 0..10 {
            assert_eq!(standby.tick(t, &view), holder.tick(t, &view));
            t += PERIOD;
        }
        // a hold latch goes over too
        let (mut a, mut b) = (holder.clone(), standby.clone());
        let late = t + 2_000 * MS;
        a.tick(late, &view);
        a.write_handover(&mut lease);
        assert_eq!(lease.flags & LEASE_HAS_HOLD, LEASE_HAS_HOLD);
        b.adopt(&lease);
        let moved = VehicleView {
            position: Some([30.0, 1.0, 11.0]),
            ..view
        };
        assert_eq!(a.tick(late + PERIOD, &moved), b.tick(late + PERIOD, &moved));
        // a lease with non-finite parts adopts none of them
        lease.reference = [f32::NAN, 0.0, 0.0];
        lease.hold_yaw = f32::INFINITY;
        let mut c = Tracker::new(cfg);
        c.adopt(&lease);
        assert!(c.carrot.is_none() && c.hold.is_none());
    }

    #[test]
    fn unvalidated_limits_with_no_altitude_band_do_not_panic_the_tracker() {
        let mut cfg = tracker_config();
        // h_max below the geofence floor: a hand-written spec the supervisor never checked
        cfg.limits.h_max = 5.0;
        cfg.limits.geofence_min[2] = 10.0;
        let mut t = Tracker::new(cfg);
        let cmd = t.tick(
            MS,
            &VehicleView {
                position: Some([0.0, 0.0, 20.0]),
                yaw: None,
                landed: false,
            },
        );
        assert!(cmd.position.iter().all(|v| v.is_finite()));
        assert!(cmd.position[2] <= 5.0, "{cmd:?}");
    }
}
