//! The controller role (kind `controller`, variant `mavlink`): tracks the hub's bound
//! setpoints at the control rate and talks MAVLink v2 to a PX4-style autopilot.
//!
//! Identity: system 1, component `MAV_COMP_ID_ONBOARD_COMPUTER` (191); it commands system 1,
//! component 1 (the autopilot) and only believes messages from that system/component.
//!
//! Parameters (`params` of the [`RoleSpec`]):
//! - `autopilot`: MAVLink URL of the autopilot (`udpin:`, `udpout:`, `tcpout:`, `tcpin:`,
//!   `serial:PORT:BAUD`), default [`DEFAULT_AUTOPILOT`];
//! - `realtime`: bool, default `true`: try SCHED_FIFO priority 50 for the cycle thread, and
//!   fall back to the normal scheduler with one line on stderr when not permitted.
//! - `standby`: bool, default `false`: this controller is the hot standby of another (it
//!   loses a tie for the lease at the flight's start).
//!
//! Every tick (period `1 / timing.control_rate_hz`, default 50 Hz):
//! 1. **read**: drain `hub/setpoint`, refuse (and count) every [`BoundSetpoint`] that fails
//!    `BoundSetpoint::validate(&mission.decision_limits())`, keep the newest valid one; copy
//!    the autopilot state the receive thread decoded (HEARTBEAT, LOCAL_POSITION_NED,
//!    ATTITUDE, EXTENDED_SYS_STATE, COMMAND_ACK);
//! 2. **track** ([`Tracker`]): with no valid setpoint fresher than
//!    `timing.setpoint_timeout_ms` (or none yet), hold the position latched when the hold
//!    began (and count the tick); otherwise fly the setpoint's mode: takeoff / ascend /
//!    descend climb or sink vertically at the north/east where the mode began, goto flies to
//!    the waypoint, hover / stop hold, turn holds and yaws, land flies to the target's
//!    north/east and descends to the ground. The commanded position is a reference
//!    ("carrot") that moves towards the target at `min(setpoint.speed, v_max)` (braking
//!    before the target, waiting when the vehicle falls behind) with a velocity
//!    feed-forward of the same speed, so the vehicle never needs to fly faster than
//!    allowed. Positions stay in the geofence; altitude is clamped to `[h_min, h_max]`
//!    except while landing and on the ground before takeoff;
//! 3. **send**: one SET_POSITION_TARGET_LOCAL_NED (`MAV_FRAME_LOCAL_NED`, position +
//!    velocity + yaw; `[N, E, U]` becomes NED, `z = -U`, only here); HEARTBEAT
//!    (`MAV_TYPE_ONBOARD_CONTROLLER`, `MAV_AUTOPILOT_INVALID`) at 1 Hz; once the autopilot's
//!    heartbeat is seen and setpoints have streamed for 0.5 s, while a valid setpoint wants
//!    the vehicle flying, `MAV_CMD_DO_SET_MODE` (PX4 offboard) and
//!    `MAV_CMD_COMPONENT_ARM_DISARM` (arm) every 0.5 s until the heartbeat reports armed and
//!    offboard; `vehicle/telemetry` ([`VehicleTelemetry`] in `[N, E, U]`).
//!
//! **Hot standby** (the autopilot lease, [`LeaseArbiter`]): a flight may run two controllers
//! on one autopilot link (the second with `params.standby = true`). Only the holder of the
//! lease writes to the autopilot; it publishes a [`ControllerLease`] on `controller/lease`
//! at every poll (the role polls [`POLLS_PER_TICK`] times per control period), carrying its
//! tracker's reference, anchor and hold latch. The other one is a standby: it keeps the
//! hub's newest setpoints and the holder's `vehicle/telemetry`, and claims the lease when no
//! lease has been heard for one control period, with an epoch above every epoch it heard and
//! at least the system's monotonic clock in milliseconds (so a controller that never heard
//! the holder, which was stopped before it came up, still outranks every earlier claim when
//! that holder resumes); its tracker then adopts
//! the holder's last published state ([`Tracker::adopt`]) and it sends in the same poll: the
//! autopilot sees at most a period and a poll without a setpoint, and the reference goes on
//! from where it was, when the holder is killed or stopped. A holder that
//! hears a higher claim steps down before its next send. A controller listens
//! [`LEASE_LISTEN_PERIODS`] control periods after it starts before it claims (a standby
//! twice as long), so a restarted controller joins as the standby and at a flight's start
//! the primary (`standby` false) claims first; two claims of one epoch go to the primary.
//! A lone controller simply claims the lease and flies.
//!
//! Heartbeat [`CycleReport`] (one per control tick): stages `read`, `track`, `send`;
//! counters `[ticks, missed, refused, hold_ticks, sent, active, takeovers, epoch]`:
//! ticks and missed = control ticks run and skipped in this term of the lease, refused =
//! setpoints refused by validation, hold_ticks = ticks spent holding for lack of a fresh
//! valid setpoint, sent = SET_POSITION_TARGET_LOCAL_NED messages written to the link,
//! active = 1 while holding the lease, takeovers = leases claimed, epoch = the lease term
//! held (0 when standby). Telemetry counts the same, from this process's first tick as the
//! holder (its sequence starts again at 1, like a restarted publisher's).
//!
//! The cycle does not allocate: the subscriber, publisher, link and buffers are made in
//! `new`; the mavlink crate serialises into a stack buffer and writes it with one syscall.

use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::role::try_sched_fifo;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleSpec};
use aeris_schemas::{
    ActionMode, BoundSetpoint, ControllerLease, DecisionLimits, LEASE_HAS_HOLD,
    LEASE_HAS_REFERENCE, SetpointError, VehicleTelemetry, topics,
};
use aeris_sim::mav_vehicle::{
    LINK_POLL, LinkError, MavLink, PX4_MAIN_MODE_OFFBOARD, PendingLink, prepare_link, px4_main_mode,
};
use mavlink::MavHeader;
use mavlink::dialects::common::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavComponent, MavFrame,
    MavLandedState, MavMessage, MavModeFlag, MavState, MavType, PositionTargetTypemask,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::Duration;

/// Autopilot URL used when the spec gives none.
pub const DEFAULT_AUTOPILOT: &str = "udpout:127.0.0.1:14600";
/// Our MAVLink system id.
pub const COMPANION_SYSTEM_ID: u8 = 1;
/// Our MAVLink component id (`MAV_COMP_ID_ONBOARD_COMPUTER`).
pub const COMPANION_COMPONENT_ID: u8 = MavComponent::MAV_COMP_ID_ONBOARD_COMPUTER as u8;
/// The autopilot's system id.
pub const AUTOPILOT_SYSTEM_ID: u8 = 1;
/// The autopilot's component id.
pub const AUTOPILOT_COMPONENT_ID: u8 = 1;
/// The link counts as up while the autopilot's heartbeat is younger than this.
pub const LINK_TIMEOUT_NS: u64 = 2_000_000_000;
/// Setpoints must stream this long before the controller asks for offboard.
pub const STREAM_BEFORE_OFFBOARD_NS: u64 = 500_000_000;
/// Mode / arm commands are repeated at this interval until they take effect.
pub const COMMAND_RETRY_NS: u64 = 500_000_000;
const HEARTBEAT_PERIOD_NS: u64 = 1_000_000_000;
/// A vehicle below the floor plus this is on the ground when the autopilot reports no
/// landed state (m).
const GROUND_MARGIN_M: f32 = 0.15;
/// Polls of the autopilot lease per control period.
pub const POLLS_PER_TICK: u32 = 4;
/// Control periods a primary controller listens for a lease holder after it starts before
/// it claims the lease itself (a standby listens twice as long).
pub const LEASE_LISTEN_PERIODS: u64 = 10;

/// What [`LeaseArbiter::decide`] did this poll.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeaseChange {
    /// Nothing changed.
    Kept,
    /// This controller claimed the lease: it is the holder from now on.
    TookOver,
    /// A higher claim was heard: this controller is a standby from now on.
    SteppedDown,
}

/// The autopilot lease as one controller sees it (pure: no I/O, no allocation).
#[derive(Debug, Clone, Copy)]
pub struct LeaseArbiter {
    pid: u32,
    rank: u8,
    silence_ns: u64,
    listen_until_ns: u64,
    epoch: u64,
    active: bool,
    /// The newest sample of the highest claim heard from another controller (its tracking
    /// state is what a takeover adopts).
    highest_seen: Option<ControllerLease>,
    last_heard_ns: Option<u64>,
    takeovers: u64,
}

impl LeaseArbiter {
    /// A standby controller `pid` started at `now_ns`: it claims the lease after
    /// `listen_ns` of silence from start, and later when no other holder was heard for
    /// `silence_ns`. `primary` wins a tie of epochs.
    pub fn new(pid: u32, primary: bool, now_ns: u64, silence_ns: u64, listen_ns: u64) -> Self {
        Self {
            pid,
            rank: u8::from(primary),
            silence_ns,
            listen_until_ns: now_ns.saturating_add(listen_ns),
            epoch: 0,
            active: false,
            highest_seen: None,
            last_heard_ns: None,
            takeovers: 0,
        }
    }

    /// Take in a lease another controller published; samples of this process are ignored.
    /// `now_ns` bounds the sample's stamp (a stamp from the future counts as now).
    pub fn observe(&mut self, lease: &ControllerLease, now_ns: u64) {
        if lease.holder_pid == self.pid {
            return;
        }
        if self
            .highest_seen
            .is_none_or(|h| (lease.key(), lease.stamp_ns) >= (h.key(), h.stamp_ns))
        {
            self.highest_seen = Some(*lease);
        }
        let stamp = lease.stamp_ns.min(now_ns);
        if self.last_heard_ns.is_none_or(|t| stamp > t) {
            self.last_heard_ns = Some(stamp);
        }
    }

    /// Claim or give up the lease at `now_ns` on what was observed.
    pub fn decide(&mut self, now_ns: u64) -> LeaseChange {
        let heard_recently = self
            .last_heard_ns
            .is_some_and(|t| now_ns.saturating_sub(t) <= self.silence_ns);
        if self.active {
            let outranked = self.highest_seen.is_some_and(|h| h.key() > self.key());
            if outranked && heard_recently {
                self.active = false;
                self.epoch = 0;
                return LeaseChange::SteppedDown;
            }
            return LeaseChange::Kept;
        }
        if heard_recently || now_ns < self.listen_until_ns {
            return LeaseChange::Kept;
        }
        // above every claim heard, and above every claim made before now by anyone (the
        // clock is CLOCK_MONOTONIC, one for every process of the host; a term lasts longer
        // than a millisecond)
        self.epoch = (self.highest_seen.map_or(0, |h| h.epoch) + 1).max(now_ns / 1_000_000);
        self.active = true;
        self.takeovers += 1;
        LeaseChange::TookOver
    }

    /// This controller holds the lease.
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// The epoch held (0 when standby).
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// The newest sample of the highest claim another controller made (what a takeover
    /// goes on from).
    pub fn highest_seen(&self) -> Option<&ControllerLease> {
        self.highest_seen.as_ref()
    }

    /// Leases claimed so far.
    pub fn takeovers(&self) -> u64 {
        self.takeovers
    }

    fn key(&self) -> (u64, u8, u32) {
        (self.epoch, self.rank, self.pid)
    }

    /// The lease sample to publish at `now_ns` (`sent`: setpoints sent in this term).
    /// (The tracking state is left empty: [`Tracker::write_handover`] fills it in.)
    pub fn lease(&self, now_ns: u64, sent: u64) -> ControllerLease {
        ControllerLease {
            epoch: self.epoch,
            stamp_ns: now_ns,
            sent,
            holder_pid: self.pid,
            rank: self.rank,
            ..ControllerLease::default()
        }
    }
}

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

fn norm(v: [f32; 3]) -> f32 {
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

/// `[N, E, U]` -> NED.
pub fn neu_to_ned(v: [f32; 3]) -> [f32; 3] {
    [v[0], v[1], -v[2]]
}

/// NED -> `[N, E, U]`.
pub fn ned_to_neu(v: [f32; 3]) -> [f32; 3] {
    [v[0], v[1], -v[2]]
}

/// The `type_mask` the controller sends: position, velocity and yaw used; acceleration and
/// yaw rate ignored.
pub fn position_velocity_yaw_mask() -> PositionTargetTypemask {
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
}

/// The SET_POSITION_TARGET_LOCAL_NED for `cmd` (the only place `[N, E, U]` becomes NED).
pub fn position_target_message(cmd: &TrackCommand, time_boot_ms: u32) -> MavMessage {
    let p = neu_to_ned(cmd.position);
    let v = neu_to_ned(cmd.velocity);
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms,
        x: p[0],
        y: p[1],
        z: p[2],
        vx: v[0],
        vy: v[1],
        vz: v[2],
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: cmd.yaw,
        yaw_rate: 0.0,
        type_mask: position_velocity_yaw_mask(),
        target_system: AUTOPILOT_SYSTEM_ID,
        target_component: AUTOPILOT_COMPONENT_ID,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

/// What the receive thread decoded from the autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct AutopilotState {
    last_heartbeat_ns: Option<u64>,
    armed: bool,
    offboard: bool,
    landed_state: Option<MavLandedState>,
    position_ned: Option<[f32; 3]>,
    velocity_ned: [f32; 3],
    attitude: Option<[f32; 3]>,
    time_boot_ms: u32,
    acks: u64,
}

impl AutopilotState {
    fn apply(&mut self, msg: &MavMessage, now_ns: u64) {
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                self.last_heartbeat_ns = Some(now_ns);
                self.armed = hb
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                self.offboard = hb
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                    && px4_main_mode(hb.custom_mode) == PX4_MAIN_MODE_OFFBOARD;
            }
            MavMessage::LOCAL_POSITION_NED(p)
                if [p.x, p.y, p.z, p.vx, p.vy, p.vz]
                    .iter()
                    .all(|v| v.is_finite()) =>
            {
                self.position_ned = Some([p.x, p.y, p.z]);
                self.velocity_ned = [p.vx, p.vy, p.vz];
                self.time_boot_ms = p.time_boot_ms;
            }
            MavMessage::ATTITUDE(a) if [a.roll, a.pitch, a.yaw].iter().all(|v| v.is_finite()) => {
                // the yaw goes back out as a hold's setpoint yaw: the same heading in [-pi, pi]
                self.attitude = Some([a.roll, a.pitch, wrap_pi(a.yaw)]);
            }
            MavMessage::EXTENDED_SYS_STATE(e) => {
                self.landed_state = Some(e.landed_state);
            }
            MavMessage::COMMAND_ACK(_) => self.acks += 1,
            _ => {}
        }
    }

    fn link_up(&self, now_ns: u64) -> bool {
        self.last_heartbeat_ns
            .is_some_and(|t| now_ns.saturating_sub(t) <= LINK_TIMEOUT_NS)
    }

    /// The state another controller reported in `t` (a standby's view of the vehicle).
    fn from_telemetry(t: &VehicleTelemetry) -> Self {
        Self {
            last_heartbeat_ns: (t.link_up == 1).then_some(t.stamp_ns),
            armed: t.armed == 1,
            offboard: t.offboard == 1,
            landed_state: Some(if t.landed == 1 {
                MavLandedState::MAV_LANDED_STATE_ON_GROUND
            } else {
                MavLandedState::MAV_LANDED_STATE_IN_AIR
            }),
            position_ned: Some(neu_to_ned(t.position)),
            velocity_ned: neu_to_ned(t.velocity),
            attitude: Some(t.attitude),
            time_boot_ms: t.autopilot_time_ms,
            acks: 0,
        }
    }

    /// This link's state, with what it has not received yet taken from `standby` (what
    /// the previous holder reported, for the first ticks after a takeover).
    fn or_else(self, standby: &AutopilotState) -> Self {
        let heard = self.last_heartbeat_ns.is_some();
        Self {
            last_heartbeat_ns: self.last_heartbeat_ns.or(standby.last_heartbeat_ns),
            armed: if heard { self.armed } else { standby.armed },
            offboard: if heard {
                self.offboard
            } else {
                standby.offboard
            },
            landed_state: self.landed_state.or(standby.landed_state),
            velocity_ned: if self.position_ned.is_some() {
                self.velocity_ned
            } else {
                standby.velocity_ned
            },
            position_ned: self.position_ned.or(standby.position_ned),
            attitude: self.attitude.or(standby.attitude),
            time_boot_ms: if self.position_ned.is_some() {
                self.time_boot_ms
            } else {
                standby.time_boot_ms
            },
            acks: self.acks,
        }
    }

    /// What the tracker sees of the vehicle (`floor`: the ground, m up).
    fn vehicle_view(&self, floor: f32) -> VehicleView {
        VehicleView {
            position: self.position_ned.map(ned_to_neu),
            yaw: self.attitude.map(|a| a[2]),
            landed: self.landed(floor),
        }
    }

    fn landed(&self, floor: f32) -> bool {
        match self.landed_state {
            Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND) => true,
            Some(MavLandedState::MAV_LANDED_STATE_UNDEFINED) | None => self
                .position_ned
                .is_some_and(|p| -p[2] <= floor + GROUND_MARGIN_M),
            Some(_) => false,
        }
    }
}

/// `a` (finite, rad) as the same angle in `[-pi, pi]`.
fn wrap_pi(a: f32) -> f32 {
    use core::f32::consts::{PI, TAU};
    let w = (a + PI).rem_euclid(TAU) - PI;
    w.clamp(-PI, PI)
}

/// Whether a message comes from the autopilot we command (the only one we believe).
fn from_autopilot(h: &MavHeader) -> bool {
    h.system_id == u32::from(AUTOPILOT_SYSTEM_ID) && h.component_id == AUTOPILOT_COMPONENT_ID
}

fn controller_rx(
    pending: PendingLink,
    slot: Arc<OnceLock<MavLink>>,
    shared: Arc<Mutex<AutopilotState>>,
    stop: Arc<AtomicBool>,
) {
    let link = match pending.establish(&stop) {
        Ok(Some(link)) => link,
        Ok(None) => return,
        Err(e) => {
            eprintln!("aeris controller: autopilot link failed: {e}");
            return;
        }
    };
    let _ = slot.set(link);
    let Some(link) = slot.get() else { return };
    while !stop.load(Ordering::Relaxed) {
        match link.recv() {
            Ok(Some((h, msg))) if from_autopilot(&h) => {
                let now = monotonic_ns();
                if let Ok(mut s) = shared.lock() {
                    s.apply(&msg, now);
                }
            }
            Ok(_) | Err(LinkError::Decode) => {}
            Err(_) => std::thread::sleep(LINK_POLL),
        }
    }
}

/// The 50 Hz MAVLink controller role.
pub struct ControllerRole {
    link: Arc<OnceLock<MavLink>>,
    shared: Arc<Mutex<AutopilotState>>,
    /// The last autopilot state copied out of `shared` (used when the lock is busy).
    ap_cache: AutopilotState,
    stop: Arc<AtomicBool>,
    rx: Option<JoinHandle<()>>,
    setpoints: TypedSubscriber<BoundSetpoint>,
    telemetry: TypedPublisher<VehicleTelemetry>,
    /// The holder's telemetry, read while standing by.
    telemetry_in: TypedSubscriber<VehicleTelemetry>,
    lease_out: TypedPublisher<ControllerLease>,
    lease_in: TypedSubscriber<ControllerLease>,
    arbiter: LeaseArbiter,
    /// What the holder last reported (the standby's view of the vehicle).
    standby_ap: AutopilotState,
    tracker: Tracker,
    period: Duration,
    period_ns: u64,
    next_tick_ns: u64,
    /// Control ticks run and skipped in the current term of the lease.
    ticks: u64,
    missed_ticks: u64,
    /// The tracker's hold ticks when this process last took the lease.
    hold_ticks_base: u64,
    /// Setpoints sent in the current term.
    term_sent: u64,
    start_ns: u64,
    next_heartbeat_ns: u64,
    next_command_ns: u64,
    stream_since_ns: Option<u64>,
    sent: u64,
    send_errors: u64,
    commands_sent: u64,
    telemetry_seq: u64,
    confirmation: u8,
    header: MavHeader,
}

impl core::fmt::Debug for ControllerRole {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ControllerRole")
            .field("sent", &self.sent)
            .field("refused", &self.tracker.refused())
            .finish_non_exhaustive()
    }
}

fn param_bool(spec: &RoleSpec, key: &str, default: bool) -> Result<bool, RoleError> {
    match spec.params.get(key) {
        None => Ok(default),
        Some(v) => v
            .as_bool()
            .ok_or_else(|| RoleError::Config(format!("param `{key}` must be true or false"))),
    }
}

impl ControllerRole {
    /// MAVLink messages of the last run written successfully (setpoints only).
    pub fn setpoints_sent(&self) -> u64 {
        self.sent
    }

    /// Writes to the autopilot link that failed.
    pub fn send_errors(&self) -> u64 {
        self.send_errors
    }

    /// The tracker (setpoint gate and reference).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The heartbeat counters (see the module documentation).
    fn counters(&self) -> [u64; 8] {
        [
            self.ticks,
            self.missed_ticks,
            self.tracker.refused(),
            self.tracker.hold_ticks() - self.hold_ticks_base,
            self.sent,
            u64::from(self.arbiter.is_active()),
            self.arbiter.takeovers(),
            self.arbiter.epoch(),
        ]
    }

    fn send(&mut self, msg: &MavMessage) -> bool {
        let Some(link) = self.link.get() else {
            return false;
        };
        match link.send(&self.header, msg) {
            Ok(n) => n > 0,
            Err(_) => {
                self.send_errors += 1;
                false
            }
        }
    }

    fn command(&mut self, command: MavCmd, p1: f32, p2: f32) {
        let msg = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: p1,
            param2: p2,
            param3: 0.0,
            param4: 0.0,
            param5: 0.0,
            param6: 0.0,
            param7: 0.0,
            command,
            target_system: AUTOPILOT_SYSTEM_ID,
            target_component: AUTOPILOT_COMPONENT_ID,
            confirmation: self.confirmation,
        });
        if self.send(&msg) {
            self.commands_sent += 1;
        }
    }
}

impl Role for ControllerRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let rate = spec.timing.control_rate_hz;
        if !(rate.is_finite() && rate > 0.0 && rate <= 1000.0) {
            return Err(RoleError::Config(format!(
                "timing.control_rate_hz = {rate} must be in (0, 1000]"
            )));
        }
        let url = match spec.params.get("autopilot") {
            None => DEFAULT_AUTOPILOT.to_string(),
            Some(v) => v
                .as_str()
                .ok_or_else(|| RoleError::Config("param `autopilot` must be a string".into()))?
                .to_string(),
        };
        let realtime = param_bool(spec, "realtime", true)?;
        let standby = param_bool(spec, "standby", false)?;
        let tracker = Tracker::new(TrackerConfig::from_spec(spec));
        let setpoints = ctx.bus.subscriber::<BoundSetpoint>(topics::HUB_SETPOINT)?;
        let telemetry = ctx
            .bus
            .publisher::<VehicleTelemetry>(topics::VEHICLE_TELEMETRY)?;
        let telemetry_in = ctx
            .bus
            .subscriber::<VehicleTelemetry>(topics::VEHICLE_TELEMETRY)?;
        let lease_out = ctx
            .bus
            .publisher::<ControllerLease>(topics::CONTROLLER_LEASE)?;
        let lease_in = ctx
            .bus
            .subscriber::<ControllerLease>(topics::CONTROLLER_LEASE)?;
        let pending = prepare_link(&url, LINK_POLL)
            .map_err(|e| RoleError::Config(format!("autopilot link: {e}")))?;
        let link = Arc::new(OnceLock::new());
        let shared = Arc::new(Mutex::new(AutopilotState::default()));
        let stop = Arc::new(AtomicBool::new(false));
        // Spawned before switching to SCHED_FIFO so the receive thread keeps the normal policy.
        let rx = {
            let (link, shared, stop) = (link.clone(), shared.clone(), stop.clone());
            std::thread::Builder::new()
                .name("controller-rx".into())
                .spawn(move || controller_rx(pending, link, shared, stop))
                .map_err(|e| RoleError::Fatal(format!("cannot spawn the receive thread: {e}")))?
        };
        if realtime && !try_sched_fifo(50) {
            eprintln!(
                "aeris controller `{}`: SCHED_FIFO not permitted, running with the normal scheduler",
                spec.name
            );
        }
        let now = monotonic_ns();
        let period = Duration::from_secs_f64(1.0 / rate);
        let period_ns = (period.as_nanos() as u64).max(1);
        Ok(Self {
            link,
            shared,
            ap_cache: AutopilotState::default(),
            stop,
            rx: Some(rx),
            setpoints,
            telemetry,
            telemetry_in,
            lease_out,
            lease_in,
            arbiter: LeaseArbiter::new(
                std::process::id(),
                !standby,
                now,
                period_ns,
                // a standby listens twice as long, so that at a flight's start the primary
                // claims first
                period_ns.saturating_mul(LEASE_LISTEN_PERIODS * if standby { 2 } else { 1 }),
            ),
            standby_ap: AutopilotState::default(),
            tracker,
            period,
            period_ns,
            next_tick_ns: now,
            ticks: 0,
            missed_ticks: 0,
            hold_ticks_base: 0,
            term_sent: 0,
            start_ns: now,
            next_heartbeat_ns: now,
            next_command_ns: now,
            stream_since_ns: None,
            sent: 0,
            send_errors: 0,
            commands_sent: 0,
            telemetry_seq: 0,
            confirmation: 0,
            header: MavHeader {
                system_id: u32::from(COMPANION_SYSTEM_ID),
                component_id: COMPANION_COMPONENT_ID,
                sequence: 0,
            },
        })
    }

    fn period(&self) -> Duration {
        self.period / POLLS_PER_TICK
    }

    fn cycle(
        &mut self,
        ctx: &mut RoleContext,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        // lease: who may write to the autopilot
        let t0 = monotonic_ns();
        let arbiter = &mut self.arbiter;
        self.lease_in.drain(|l| arbiter.observe(l, t0))?;
        let standby_ap = &mut self.standby_ap;
        let holding = self.arbiter.is_active();
        self.telemetry_in.drain(|t| {
            if !holding && t.validate().is_ok() {
                *standby_ap = AutopilotState::from_telemetry(t);
            }
        })?;
        let change = self.arbiter.decide(t0);
        let active = self.arbiter.is_active();
        if change == LeaseChange::TookOver {
            // fly from this poll on (the holder's last tick was a period or more ago), from
            // the reference the holder last published
            self.next_tick_ns = t0;
            if let Some(l) = self.arbiter.highest_seen() {
                self.tracker.adopt(l);
            }
            self.hold_ticks_base = self.tracker.hold_ticks();
            self.term_sent = 0;
            // a new term publishes like a new process: sequence and counters from zero
            self.telemetry_seq = 0;
            self.ticks = 0;
            self.missed_ticks = 0;
            eprintln!(
                "aeris controller `{}`: took the autopilot lease (epoch {})",
                ctx.spec.name,
                self.arbiter.epoch()
            );
        } else if change == LeaseChange::SteppedDown {
            eprintln!(
                "aeris controller `{}`: another controller holds the autopilot lease, standing by",
                ctx.spec.name
            );
        }
        if active {
            let mut lease = self.arbiter.lease(t0, self.term_sent);
            self.tracker.write_handover(&mut lease);
            self.lease_out.publish(&lease)?;
        }
        if t0 < self.next_tick_ns {
            return Ok(CycleOutcome::Idle);
        }
        self.next_tick_ns += self.period_ns;
        if t0 > self.next_tick_ns {
            // a control tick was skipped: count it and re-anchor instead of bursting
            let late = t0 - self.next_tick_ns;
            if active {
                self.missed_ticks += late / self.period_ns + 1;
            }
            self.next_tick_ns = t0 + self.period_ns - late % self.period_ns;
        }

        // read
        let tracker = &mut self.tracker;
        self.setpoints.drain(|sp| {
            let _ = tracker.offer(sp, t0);
        })?;
        // Never block the real-time tick on the receive thread (std mutexes have no
        // priority inheritance): when the lock is busy, fly on the previous copy.
        if let Ok(s) = self.shared.try_lock() {
            self.ap_cache = *s;
        }
        let t1 = monotonic_ns();
        if !active {
            // a standby keeps the setpoints and the holder's view, and writes nothing; its
            // tracker takes the holder's reference when it takes over
            report.stage("read", t1 - t0);
            report.counters = self.counters();
            return Ok(CycleOutcome::Worked);
        }
        let ap = self.ap_cache.or_else(&self.standby_ap);

        // track
        let view = ap.vehicle_view(self.tracker.config().floor());
        let landed = view.landed;
        let cmd = self.tracker.tick(t1, &view);
        let t2 = monotonic_ns();
        self.ticks += 1;

        // send
        let time_boot_ms = ((t2.saturating_sub(self.start_ns)) / 1_000_000) as u32;
        if self.send(&position_target_message(&cmd, time_boot_ms)) {
            self.sent += 1;
            self.term_sent += 1;
            self.stream_since_ns.get_or_insert(t2);
        }
        if t2 >= self.next_heartbeat_ns {
            self.next_heartbeat_ns = t2 + HEARTBEAT_PERIOD_NS;
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            }));
        }
        let link_up = ap.link_up(t2);
        let streamed = self
            .stream_since_ns
            .is_some_and(|s| t2.saturating_sub(s) >= STREAM_BEFORE_OFFBOARD_NS);
        if link_up
            && streamed
            && !(ap.armed && ap.offboard)
            && self.tracker.wants_flight(t2, landed)
            && t2 >= self.next_command_ns
        {
            self.next_command_ns = t2 + COMMAND_RETRY_NS;
            if !ap.offboard {
                let custom = f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits());
                self.command(
                    MavCmd::MAV_CMD_DO_SET_MODE,
                    custom,
                    f32::from(PX4_MAIN_MODE_OFFBOARD),
                );
            }
            if !ap.armed {
                self.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0);
            }
            self.confirmation = self.confirmation.wrapping_add(1);
        }
        // Telemetry carries what the autopilot reported; nothing is published before its
        // first LOCAL_POSITION_NED (a made-up position would be taken as real downstream).
        let Some(position_ned) = ap.position_ned else {
            report.stage("read", t1 - t0);
            report.stage("track", t2 - t1);
            report.counters = self.counters();
            return Ok(CycleOutcome::Worked);
        };
        let attitude = ap.attitude.unwrap_or([0.0; 3]);
        self.telemetry_seq += 1;
        let telemetry = VehicleTelemetry {
            seq: self.telemetry_seq,
            stamp_ns: t2,
            autopilot_time_ms: ap.time_boot_ms,
            armed: u8::from(ap.armed),
            offboard: u8::from(ap.offboard),
            link_up: u8::from(link_up),
            landed: u8::from(landed),
            position: ned_to_neu(position_ned),
            velocity: ned_to_neu(ap.velocity_ned),
            attitude,
            controller_ticks: self.ticks,
            controller_missed_ticks: self.missed_ticks,
            setpoints_refused: self.tracker.refused(),
            hold_ticks: self.tracker.hold_ticks() - self.hold_ticks_base,
        };
        self.telemetry.publish(&telemetry)?;
        let t3 = monotonic_ns();

        report.stage("read", t1 - t0);
        report.stage("track", t2 - t1);
        report.stage("send", t3 - t2);
        report.counters = self.counters();
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.rx.take() {
            let _ = h.join();
        }
    }
}

impl Drop for ControllerRole {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.rx.take() {
            let _ = h.join();
        }
    }
}

// --- Fuzzing support -------------------------------------------------------------------------
// Shared by the `controller_mavlink` target in `fuzz/` and the corpus replay test. Not API.

/// Replay `data` as bytes from the autopilot link and check what the controller would send.
///
/// `data[0]` sets the scene: bits 0-3 the hub's setpoint (0 or > 8: none, the controller
/// holds; 1..=8: one valid setpoint of that [`ActionMode`] wire value), bit 4 keeps it fresh
/// (offered again every tick instead of once), bit 5 also accepts MAVLink 1 frames (the link
/// itself reads MAVLink 2 only), bits 6-7 the control ticks after each read (1, 2, 5 or 25:
/// 25 ticks outlast the default setpoint timeout). The rest is the byte stream, decoded by
/// the mavlink crate's reader exactly like the receive thread's link; every message from the
/// autopilot goes through the receive thread's state update, and after each read (message or
/// decode error) come the control ticks. Panics when a tick's output breaks the controller's
/// promises: finite, inside the geofence and under h_max, feed-forward no faster than v_max,
/// and the SET_POSITION_TARGET_LOCAL_NED the same numbers in NED, surviving its own encoding.
#[doc(hidden)]
pub fn fuzz_check_mavlink(cfg: TrackerConfig, data: &[u8]) {
    use mavlink::error::MessageReadError;
    use mavlink::{MavlinkReader, MavlinkVersion};
    let Some((&scene, stream)) = data.split_first() else {
        return;
    };
    let l = cfg.limits;
    let t0: u64 = 1_000_000_000;
    let period_ns = ((cfg.period_s as f64 * 1e9) as u64).max(1);
    let setpoint = ActionMode::from_u8(scene & 0x0f).map(|mode| {
        let lo = l.h_min.max(l.geofence_min[2]);
        let hi = l.h_max.min(l.geofence_max[2]);
        let u = match mode {
            ActionMode::Land => l.geofence_min[2],
            _ => (lo + hi) / 2.0,
        };
        BoundSetpoint {
            seq: 1,
            decision_seq: 1,
            publish_ns: t0,
            position: [
                (l.geofence_min[0] + l.geofence_max[0]) / 2.0,
                (l.geofence_min[1] + l.geofence_max[1]) / 2.0,
                u,
            ],
            yaw: 0.5,
            speed: l.v_max * 0.6,
            acceptance_radius: 0.0,
            active_step: 1,
            mode: mode as u8,
            ..BoundSetpoint::default()
        }
    });
    let keep_fresh = scene & 0x10 != 0;
    let any_version = scene & 0x20 != 0;
    let ticks = [1, 2, 5, 25][usize::from(scene >> 6)];
    let mut tracker = Tracker::new(cfg);
    let mut ap = AutopilotState::default();
    let mut reader = MavlinkReader::new(stream);
    let mut now = t0;
    // every read consumes at least one byte or ends the stream
    for i in 0..=stream.len() {
        if let Some(sp) = &setpoint
            && (i == 0 || keep_fresh)
        {
            let mut sp = *sp;
            sp.publish_ns = now;
            assert!(
                tracker.offer(&sp, now).is_ok(),
                "valid setpoint refused: {sp:?}"
            );
        }
        let read = if any_version {
            reader.read_any_message::<MavMessage>()
        } else {
            reader.read_message::<MavMessage>(MavlinkVersion::V2)
        };
        match read {
            Ok((h, msg)) if from_autopilot(&h) => ap.apply(&msg, now),
            Ok(_) | Err(MessageReadError::Parse(_)) => {}
            Err(MessageReadError::Io(_)) => break,
        }
        let view = ap.vehicle_view(cfg.floor());
        for _ in 0..ticks {
            let cmd = tracker.tick(now, &view);
            fuzz_check_command(&cfg, &cmd, &view);
            now += period_ns;
        }
    }
}

fn fuzz_check_command(cfg: &TrackerConfig, cmd: &TrackCommand, view: &VehicleView) {
    let l = &cfg.limits;
    let p = cmd.position;
    let mut all = p
        .iter()
        .chain(&cmd.velocity)
        .chain(core::iter::once(&cmd.yaw));
    assert!(all.all(|v| v.is_finite()), "{cmd:?} for {view:?}");
    assert!(
        l.inside_geofence(p) && p[2] <= l.h_max,
        "outside the fence: {cmd:?} for {view:?}"
    );
    let speed = norm(cmd.velocity);
    assert!(
        speed <= l.v_max * (1.0 + 1e-5),
        "{speed} m/s > v_max: {cmd:?}"
    );
    let msg = position_target_message(cmd, 1234);
    let MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) = &msg else {
        panic!("not a position target: {msg:?}");
    };
    assert_eq!([m.x, m.y, -m.z], p);
    assert_eq!([m.vx, m.vy, -m.vz], cmd.velocity);
    assert_eq!(m.yaw, cmd.yaw);
    // the frame the autopilot receives decodes back to the same message
    let mut frame = [0u8; 300];
    let header = MavHeader {
        system_id: u32::from(COMPANION_SYSTEM_ID),
        component_id: COMPANION_COMPONENT_ID,
        sequence: 7,
    };
    let n = mavlink::write_v2_msg(&mut &mut frame[..], header, &msg).expect("encodes");
    let mut back = mavlink::MavlinkReader::new(&frame[..n]);
    let (h, decoded) = back
        .read_message::<MavMessage>(mavlink::MavlinkVersion::V2)
        .expect("decodes");
    assert_eq!((h.system_id, decoded), (header.system_id, msg));
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const PERIOD: u64 = 20 * MS;
    const LISTEN: u64 = 200 * MS;

    fn lease_of(a: &LeaseArbiter, now: u64) -> ControllerLease {
        a.lease(now, 0)
    }

    #[test]
    fn a_lone_controller_claims_the_lease_after_listening() {
        let mut a = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(a.decide(LISTEN - 1), LeaseChange::Kept);
        assert!(!a.is_active());
        assert_eq!(a.decide(LISTEN), LeaseChange::TookOver);
        assert!(a.is_active());
        assert_eq!(
            (a.epoch(), a.takeovers()),
            (200, 1),
            "the claim's time in ms"
        );
        // its own samples are no competition
        let own = lease_of(&a, LISTEN);
        a.observe(&own, LISTEN + PERIOD);
        assert_eq!(a.decide(LISTEN + PERIOD), LeaseChange::Kept);
        assert!(a.is_active());
    }

    #[test]
    fn a_standby_waits_while_the_holder_is_heard_and_takes_over_after_one_period_of_silence() {
        let mut holder = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(holder.decide(LISTEN), LeaseChange::TookOver);
        // the standby starts later (a restarted controller) and hears the holder every poll
        let start = LISTEN + 5 * PERIOD;
        let mut standby = LeaseArbiter::new(11, false, start, PERIOD, LISTEN);
        let mut t = start;
        while t < start + 3 * LISTEN {
            standby.observe(&lease_of(&holder, t), t);
            assert_eq!(standby.decide(t), LeaseChange::Kept, "at {t}");
            t += 5 * MS;
        }
        assert!(!standby.is_active());
        // the holder goes silent after its sample at `last`
        let last = t - 5 * MS;
        assert_eq!(standby.decide(last + PERIOD), LeaseChange::Kept);
        assert_eq!(standby.decide(last + PERIOD + 1), LeaseChange::TookOver);
        assert!(
            standby.epoch() > holder.epoch(),
            "above the silent holder's"
        );
        // the old holder wakes up (SIGCONT), hears the new term and steps down
        let now = last + PERIOD + 5 * MS;
        holder.observe(&lease_of(&standby, now), now);
        assert_eq!(holder.decide(now), LeaseChange::SteppedDown);
        assert!(!holder.is_active());
        assert_eq!(holder.epoch(), 0);
        // and the new holder is not moved by the old term's late samples
        standby.observe(
            &ControllerLease {
                epoch: 200,
                rank: 1,
                holder_pid: 10,
                stamp_ns: now,
                ..Default::default()
            },
            now,
        );
        assert_eq!(standby.decide(now), LeaseChange::Kept);
        assert!(standby.is_active());
    }

    #[test]
    fn a_claimant_that_never_heard_the_stopped_holder_still_outranks_it_when_it_resumes() {
        // the holder claims, then is stopped before the restarted standby comes up: the
        // standby hears nothing at all and claims on its own
        let mut holder = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        assert_eq!(holder.decide(LISTEN), LeaseChange::TookOver);
        let start = LISTEN + 3 * PERIOD;
        let mut standby = LeaseArbiter::new(11, false, start, PERIOD, 2 * LISTEN);
        assert_eq!(standby.decide(start + 2 * LISTEN), LeaseChange::TookOver);
        assert!(standby.epoch() > holder.epoch());
        // SIGCONT: each hears the other; the stale holder steps down, the new one stays
        let now = start + 2 * LISTEN + 5 * MS;
        holder.observe(&lease_of(&standby, now), now);
        standby.observe(&lease_of(&holder, now - MS), now);
        assert_eq!(holder.decide(now), LeaseChange::SteppedDown);
        assert_eq!(standby.decide(now), LeaseChange::Kept);
    }

    #[test]
    fn at_the_start_the_primary_wins_a_tie_and_the_standby_steps_down() {
        let mut primary = LeaseArbiter::new(20, true, 0, PERIOD, LISTEN);
        let mut standby = LeaseArbiter::new(30, false, 0, PERIOD, LISTEN);
        assert_eq!(primary.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!(standby.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!((primary.epoch(), standby.epoch()), (200, 200));
        let t = LISTEN + 5 * MS;
        let (p, s) = (lease_of(&primary, t), lease_of(&standby, t));
        primary.observe(&s, t);
        standby.observe(&p, t);
        // the standby's higher pid does not beat the primary's rank
        assert_eq!(primary.decide(t), LeaseChange::Kept);
        assert_eq!(standby.decide(t), LeaseChange::SteppedDown);
        assert!(primary.is_active() && !standby.is_active());
    }

    #[test]
    fn a_higher_claim_heard_long_ago_does_not_unseat_the_holder() {
        let mut a = LeaseArbiter::new(10, true, 0, PERIOD, LISTEN);
        let ghost = ControllerLease {
            epoch: 7000,
            stamp_ns: 5 * MS,
            holder_pid: 99,
            ..Default::default()
        };
        a.observe(&ghost, 5 * MS);
        assert_eq!(a.decide(LISTEN), LeaseChange::TookOver);
        assert_eq!(a.epoch(), 7001, "above every epoch heard");
        // a stamp from the future counts as now, not as forever
        let future = ControllerLease {
            epoch: 1,
            stamp_ns: u64::MAX,
            holder_pid: 98,
            ..Default::default()
        };
        let mut b = LeaseArbiter::new(11, false, 0, PERIOD, LISTEN);
        b.observe(&future, MS);
        assert_eq!(b.decide(LISTEN), LeaseChange::TookOver);
    }

    fn tracker_config() -> TrackerConfig {
        TrackerConfig {
            limits: DecisionLimits {
                v_max: 8.0,
                h_min: 0.0,
                h_max: 60.0,
                r_max: 10.0,
                geofence_min: [-20.0, -40.0, 0.0],
                geofence_max: [160.0, 140.0, 60.0],
                obstacle_clearance_m: 3.0,
                subgoals: 4,
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

    #[test]
    fn an_autopilot_yaw_out_of_range_is_wrapped_before_it_is_flown() {
        let mut s = AutopilotState::default();
        for (yaw, want) in [
            (0.5f32, 0.5f32),
            (7.0, 7.0 - core::f32::consts::TAU),
            (-4.0, -4.0 + core::f32::consts::TAU),
            (1e6, f32::NAN),
        ] {
            s.apply(
                &MavMessage::ATTITUDE(mavlink::dialects::common::ATTITUDE_DATA {
                    time_boot_ms: 1,
                    roll: 0.0,
                    pitch: 0.0,
                    yaw,
                    rollspeed: 0.0,
                    pitchspeed: 0.0,
                    yawspeed: 0.0,
                }),
                1,
            );
            let got = s.attitude.unwrap()[2];
            let pi = core::f32::consts::PI;
            assert!((-pi..=pi).contains(&got), "{yaw} -> {got}");
            if !want.is_nan() {
                assert!((got - want).abs() < 1e-4, "{yaw} -> {got}, want {want}");
            }
        }
    }

    #[test]
    fn after_a_takeover_the_link_state_is_completed_from_the_holders_telemetry() {
        let t = VehicleTelemetry {
            stamp_ns: 7,
            armed: 1,
            offboard: 1,
            link_up: 1,
            landed: 0,
            position: [10.0, 5.0, 12.0],
            velocity: [1.0, 0.0, -0.5],
            attitude: [0.0, 0.0, 0.3],
            autopilot_time_ms: 1234,
            ..Default::default()
        };
        let standby = AutopilotState::from_telemetry(&t);
        let view = AutopilotState::default()
            .or_else(&standby)
            .vehicle_view(0.0);
        assert_eq!(view.position, Some([10.0, 5.0, 12.0]));
        assert_eq!(view.yaw, Some(0.3));
        assert!(!view.landed);
        let merged = AutopilotState::default().or_else(&standby);
        assert!(merged.armed && merged.offboard && merged.link_up(7));
        // what the link itself reports wins
        let mut link = AutopilotState::default();
        link.apply(
            &MavMessage::LOCAL_POSITION_NED(mavlink::dialects::common::LOCAL_POSITION_NED_DATA {
                time_boot_ms: 2000,
                x: 11.0,
                y: 5.0,
                z: -12.0,
                vx: 0.0,
                vy: 0.0,
                vz: 0.0,
            }),
            9,
        );
        let merged = link.or_else(&standby);
        assert_eq!(merged.position_ned, Some([11.0, 5.0, -12.0]));
        assert_eq!(merged.time_boot_ms, 2000);
        assert!(
            merged.armed,
            "no heartbeat on the link yet: the holder's word"
        );
    }
}
