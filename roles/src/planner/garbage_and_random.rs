//! The planner's decisions made unreliable on purpose: two reasoning variants for tests and
//! the evaluation's baseline.
//!
//! [`GarbageRole`] (variant `garbage`) runs the planner but corrupts most decisions in
//! rotating ways (NaN, infinities, out-of-range fields, unknown actions, bad steps, stale
//! cycle starts, duplicate and skipped sequence numbers) — a hostile reasoner for tests.
//!
//! [`RandomRole`] (variant `random`) is the random baseline of the VLN evaluation: it takes
//! off like the planner, then draws AerialVLN's discrete actions uniformly ([`RandomAction`]).
//!
//! Both decide when the planner would ([`crate::reasoner_io::ReasonerIo`]) and report the
//! planner's heartbeat counters ([`super::role`]).

use super::role::PlannerReasoner;
use crate::reasoner_io::POLL;
use aeris_geometry::wrap_pi;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{ActionMode, Decision, PlannerCounters};
use core::time::Duration;

/// allocation-free, for the fault injector and the random baseline.
fn xorshift64star(state: &mut u64) -> u64 {
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    state.wrapping_mul(0x2545_F491_4F6C_DD1D)
}

/// A reasoner that corrupts most of its decisions (fault injection).
pub struct GarbageRole {
    reasoner: PlannerReasoner,
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
            10 => d.seq = self.reasoner.io.last_seq().saturating_sub(1).max(1),
            _ => return false,
        }
        true
    }
}

impl Role for GarbageRole {
    type Kind = kinds::Reasoning;

    fn new(ctx: &mut RoleContext<kinds::Reasoning>) -> Result<Self, RoleError> {
        let seed = ctx.spec.param_f64("seed").unwrap_or(7.0) as u64;
        Ok(Self {
            reasoner: PlannerReasoner::new(ctx)?,
            rng: seed.max(1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            corrupted: 0,
        })
    }

    fn period(&self) -> Duration {
        POLL
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Reasoning>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.reasoner.think(report)? else {
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
                self.reasoner.send(&mut bad, report)?;
            }
        }
        if !self.next_rand().is_multiple_of(4) {
            d.seq = 0;
            self.reasoner.send(&mut d, report)?;
        }
        let mut c = PlannerCounters::from_heartbeat(&report.counters);
        c.corrupted = self.corrupted;
        report.counters = c.to_heartbeat();
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
    reasoner: PlannerReasoner,
    rng: u64,
    airborne: bool,
    stopped: bool,
    h_min: f32,
}

impl Role for RandomRole {
    type Kind = kinds::Reasoning;

    fn new(ctx: &mut RoleContext<kinds::Reasoning>) -> Result<Self, RoleError> {
        let seed = ctx.spec.param_f64("seed").unwrap_or(1.0) as u64;
        Ok(Self {
            reasoner: PlannerReasoner::new(ctx)?,
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
        _ctx: &mut RoleContext<kinds::Reasoning>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.reasoner.think(report)? else {
            return Ok(CycleOutcome::Idle);
        };
        let (position, yaw) = match self.reasoner.io.telemetry() {
            Some(t) => (t.position, t.attitude[2]),
            None => (self.reasoner.io.start(), 0.0),
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
        self.reasoner.send(&mut d, report)?;
        Ok(CycleOutcome::Worked)
    }
}
