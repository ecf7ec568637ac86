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

use crate::heartbeat_clock::{Basis, HeartbeatClock};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{
    CycleOutcome, CycleReport, Role, RoleContext, RoleError, bus::TypedPublisher,
    bus::TypedSubscriber,
};
use aeris_schemas::{
    ActionMode, Decision, MAX_SUBGOALS, PerceptionState, VehicleTelemetry, topics,
};
use aeris_sim::multirotor::wrap_pi;
use core::time::Duration;

/// A turn step is done when the yaw is this close to the bearing of its waypoint.
const TURN_TOLERANCE_RAD: f32 = 0.15;

/// Bearing from `from` to `to` (rad, 0 = north, clockwise), or `fallback` when they coincide.
fn heading(from: [f32; 3], to: [f32; 3], fallback: f32) -> f32 {
    let (dn, de) = (to[0] - from[0], to[1] - from[1]);
    if dn.hypot(de) > 1.0 {
        de.atan2(dn)
    } else {
        fallback
    }
}

/// One subgoal as the planner needs it (copied from the mission at start).
#[derive(Debug, Clone, Copy)]
struct Step {
    action: ActionMode,
    waypoint: [f32; 3],
}

/// The planner's pure logic: memory (the subgoal in progress) and the decision rule.
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
}

impl Planner {
    /// A planner for the mission in `spec`; `None` when an action name is unknown (the
    /// mission was validated, so this does not happen for supervisor-written specs).
    pub fn new(mission: &aeris_runtime::MissionSpec) -> Option<Self> {
        let mut steps = [None; MAX_SUBGOALS];
        for (slot, s) in steps.iter_mut().zip(mission.subgoals.iter()) {
            *slot = Some(Step {
                action: s.action_mode()?,
                waypoint: s.waypoint,
            });
        }
        Some(Self {
            steps,
            count: mission.subgoals.len().min(MAX_SUBGOALS),
            current: 0,
            issued: 0,
            start: mission.start,
            cruise: mission.cruise_speed,
            radius: mission.acceptance_radius_m,
            h_min: mission.limits.h_min,
        })
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
    }

    /// Whether the step in progress is done, given how many decisions were already issued
    /// for it (a hover holds for one heartbeat; stop never completes).
    fn reached(
        step: &Step,
        position: [f32; 3],
        yaw: f32,
        landed: bool,
        radius: f32,
        issued: u32,
    ) -> bool {
        let w = step.waypoint;
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

    /// Advance the memory on the vehicle's state and return the decision for this cycle
    /// (timing fields left for the caller).
    pub fn decide(&mut self, position: [f32; 3], yaw: f32, landed: bool) -> Decision {
        while self.current + 1 < self.count {
            let Some(step) = self.steps[self.current] else {
                break;
            };
            if !Self::reached(&step, position, yaw, landed, self.radius, self.issued) {
                break;
            }
            self.current += 1;
            self.issued = 0;
        }
        self.issued = self.issued.saturating_add(1);
        let step = self.steps[self.current].unwrap_or(Step {
            action: ActionMode::Hover,
            waypoint: position,
        });
        let w = step.waypoint;
        let (target, altitude) = match step.action {
            ActionMode::Takeoff | ActionMode::Ascend | ActionMode::Descend => {
                ([position[0], position[1], w[2]], w[2])
            }
            // land: fly (or stay) over the touchdown point at the current height; the gate
            // binds the descent to U=0
            ActionMode::Land => ([w[0], w[1], w[2]], position[2].max(self.h_min).max(w[2])),
            _ => (w, w[2].max(self.h_min)),
        };
        let dn = target[0] - position[0];
        let de = target[1] - position[1];
        let heading = if dn.hypot(de) > 1.0 {
            de.atan2(dn)
        } else {
            yaw
        };
        Decision {
            target,
            yaw: wrap_pi(heading),
            speed: self.cruise,
            altitude,
            acceptance_radius: self.radius,
            confidence: 1.0,
            step: (self.current + 1) as u16,
            action: step.action as u8,
            ..Decision::default()
        }
    }
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
        let mut planner = Planner::new(&ctx.spec.mission)
            .ok_or_else(|| RoleError::Config("the mission names an unknown action".into()))?;
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
        let reasoning_start = monotonic_ns();
        let mut d = self.planner.decide(position, yaw, landed);
        self.cycle += 1;
        d.cycle = self.cycle;
        d.source = self.source;
        let state = match basis {
            Basis::State => self.last_state.as_ref(),
            Basis::TelemetryOnly => None,
        };
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
                    waypoint: [0.0, 0.0, 10.0],
                },
                SubgoalSpec {
                    text: "fly north".into(),
                    action: "goto".into(),
                    waypoint: [30.0, 0.0, 10.0],
                },
                SubgoalSpec {
                    text: "land".into(),
                    action: "land".into(),
                    waypoint: [30.0, 10.0, 0.0],
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
        let mut p = Planner::new(&m).unwrap();
        let d = p.decide([0.0, 0.0, 0.0], 0.0, true);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (1, Some(ActionMode::Takeoff))
        );
        assert!(d.validate(&limits).is_ok());
        let d = p.decide([0.0, 0.0, 9.5], 0.0, false);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (2, Some(ActionMode::Goto))
        );
        assert_eq!(d.target, [30.0, 0.0, 10.0]);
        assert!(d.validate(&limits).is_ok());
        // not there yet: memory holds
        let d = p.decide([15.0, 0.0, 10.0], 0.0, false);
        assert_eq!(d.step, 2);
        let d = p.decide([29.0, 0.5, 10.0], 0.0, false);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Land))
        );
        assert!(d.validate(&limits).is_ok());
        // the last step stays active
        let d = p.decide([30.0, 10.0, 0.0], 0.0, true);
        assert_eq!(d.step, 3);
    }

    #[test]
    fn a_huge_or_odd_yaw_never_hangs_and_stays_in_range() {
        let mut p = Planner::new(&mission()).unwrap();
        for yaw in [1.0e9, -3.0e38, f32::MAX, 7.0] {
            let d = p.decide([0.0, 0.0, 0.0], yaw, true);
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
                waypoint: [0.0, 0.0, 10.0],
            },
        );
        m.subgoals.insert(
            2,
            SubgoalSpec {
                text: "face east".into(),
                action: "turn".into(),
                waypoint: [0.0, 30.0, 10.0],
            },
        );
        let mut p = Planner::new(&m).unwrap();
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 0.0, false).step,
            2,
            "takeoff done -> hover"
        );
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 0.0, false).step,
            3,
            "hovered one heartbeat -> turn"
        );
        let d = p.decide([0.0, 0.0, 10.0], 0.0, false);
        assert_eq!(
            (d.step, ActionMode::from_u8(d.action)),
            (3, Some(ActionMode::Turn)),
            "still facing north"
        );
        assert!((d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3);
        assert_eq!(
            p.decide([0.0, 0.0, 10.0], 1.55, false).step,
            4,
            "facing east -> next"
        );
    }

    #[test]
    fn yaw_points_at_the_target() {
        let mut p = Planner::new(&mission()).unwrap();
        let _ = p.decide([0.0, 0.0, 10.0], 0.0, false);
        let d = p.decide([30.0, -20.0, 10.0], 0.0, false);
        assert!(
            (d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
            "{}",
            d.yaw
        );
    }
}
