//! What every reasoning role does around its decision, whatever decides: the planner
//! ([`crate::planner`]) and its garbage and random variants, and the language-model roles
//! ([`crate::language`]).
//!
//! [`ReasonerIo`] reads every valid S_t and telemetry every poll, decides when a decision
//! is due ([`HeartbeatClock`]: once per heartbeat on the first S_t captured most of a
//! heartbeat after the last cycle's start, or on the telemetry alone when no S_t came for a
//! heartbeat and a half), stamps a decision's cycle
//! and timing, and publishes it on `reasoning/decision`. A reasoner that starts during a
//! flight (restart, hot swap) first takes the mission up at the hub's active step, read
//! from the latest `hub/setpoint` ([`hub_active_step`]).
//!
//! A poll:
//! ```text
//! io.poll()? -> Some(due) -> decide on (due.position, due.yaw, due.landed, io.state(&due))
//!            -> io.stamp(&mut d, &due, reasoning_start) -> io.publish(&mut d, report)?
//! ```

use crate::heartbeat_clock::{Basis, HeartbeatClock};
use crate::planner::Planner;
use aeris_llm::{MissionBrief, StepBrief};
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::{monotonic_ns, wall_ns};
use aeris_runtime::{ConfigError, CycleReport, MissionSpec, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{Decision, PerceptionState, VehicleTelemetry, topics};
use core::time::Duration;

/// How often the reasoning roles look for a fresh S_t.
pub const POLL: Duration = Duration::from_millis(50);

/// Telemetry samples kept to find the vehicle's state at an S_t's capture (2.5 s at the
/// controller's 50 Hz: longer than any S_t that is not stale).
pub const TELEMETRY_KEPT: usize = 128;

/// How long a starting reasoner waits for the hub's latest setpoint (the hub publishes
/// every 20 ms once a decision is in force; at the flight's start there is none).
pub const RESUME_WAIT: Duration = Duration::from_millis(250);

/// The hub's active instruction step if the flight is under way: from the latest
/// `hub/setpoint`, which its history hands to a new subscriber, waited for up to `wait`.
/// `None` before the first decision of the flight.
pub fn hub_active_step(
    ctx: &RoleContext<kinds::Reasoning>,
    wait: Duration,
) -> Result<Option<u16>, RoleError> {
    let setpoints = ctx.bus.subscriber::<topics::HubSetpoint>()?;
    // a wait for another process's history to arrive: wall-clock time (on simulated time
    // the flight's time stands still while this role is built)
    let deadline = wall_ns().saturating_add(aeris_runtime::clock::duration_ns(wait));
    loop {
        if let Some(sp) = setpoints.latest()?
            && sp.active_step >= 1
        {
            return Ok(Some(sp.active_step));
        }
        if wall_ns() >= deadline {
            return Ok(None);
        }
        #[allow(
            clippy::disallowed_methods,
            reason = "a wall-clock wait for another process's history while this role is built (the flight's time stands still then)"
        )]
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The oldest a reasoner's first S_t may be: the decision deadline less `decision` (what a
/// decision takes) and the hub's routing margin ([`ROUTING_MARGIN`]).
fn first_state_max_age(ctx: &RoleContext<kinds::Reasoning>, decision: Duration) -> u64 {
    let deadline = ctx
        .spec
        .timing
        .decision_deadline_ms
        .saturating_mul(1_000_000);
    deadline
        .saturating_sub(aeris_runtime::clock::duration_ns(decision))
        .saturating_sub(aeris_runtime::clock::duration_ns(ROUTING_MARGIN))
}

/// Time kept free between a decision's publication and its deadline at the hub (the hub
/// reads decisions every 20 ms).
pub const ROUTING_MARGIN: Duration = Duration::from_millis(100);

/// The mission as the language model reads it.
pub fn mission_brief(mission: &MissionSpec) -> Result<MissionBrief, RoleError> {
    let steps = mission
        .subgoals
        .iter()
        .map(|s| {
            Ok(StepBrief {
                text: s.text.clone(),
                action: s.action_mode().ok_or_else(|| {
                    RoleError::from(ConfigError::Mission(format!(
                        "names unknown action `{}`",
                        s.action
                    )))
                })?,
                waypoint: s.waypoint,
            })
        })
        .collect::<Result<Vec<_>, RoleError>>()?;
    Ok(MissionBrief {
        instruction: mission.instruction.clone(),
        steps,
        limits: mission.decision_limits(),
        cruise_speed: mission.cruise_speed,
        acceptance_radius: mission.acceptance_radius_m,
    })
}

/// A decision due now, and the vehicle's state it is made for (from [`ReasonerIo::poll`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecisionDue {
    /// When the poll that found it due began (ns, monotonic).
    pub poll_ns: u64,
    /// What it is based on: the fresh S_t ([`ReasonerIo::state`]), or the telemetry alone.
    pub basis: Basis,
    /// The vehicle's position `[N, E, U]`: for a decision on an S_t, from the last
    /// telemetry stamped at or before its frame's capture (so the decision depends on the
    /// S_t and not on when the reasoner looked: a replay decides alike), else from the S_t;
    /// on telemetry alone, from the latest telemetry, else
    /// the mission's start.
    pub position: [f32; 3],
    /// The vehicle's yaw (rad), from the same source.
    pub yaw: f32,
    /// Whether the vehicle is on the ground, from the same source.
    pub landed: bool,
}

/// A reasoning role's ports, its inputs so far and its decision numbering.
pub struct ReasonerIo {
    states: TypedSubscriber<PerceptionState>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    decisions: TypedPublisher<Decision>,
    clock: HeartbeatClock,
    state: Option<PerceptionState>,
    fresh_state: bool,
    telemetry_last: Option<VehicleTelemetry>,
    telemetry_kept: TelemetryRing,
    start: [f32; 3],
    seq: u64,
    cycle: u64,
    source: u32,
    /// Where the process is with standing by (a hot swap's new side, not yet the role).
    standby: Standby,
}

/// A reasoner's standing by, as its polls found it. The supervisor only ever lifts a
/// process out of SCHED_IDLE, so once a poll finds it the role the policy is not read again.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Standby {
    /// No poll yet.
    Unknown,
    /// The last poll found it standing by.
    Standing,
    /// It is the role.
    Over,
}

impl ReasonerIo {
    /// Resume `planner` at the hub's active step when the flight is under way (waiting up
    /// to [`RESUME_WAIT`] for it), then open the ports; the heartbeat clock starts now.
    /// `decision` is how long a decision takes (the warm-up's): started during a flight, the
    /// reasoner takes its first S_t only if it can decide on it within the deadline, not the
    /// topic's last, up to a heartbeat old (a flight's or replay's start is unchanged, so a
    /// replay still decides alike).
    pub fn new(
        ctx: &mut RoleContext<kinds::Reasoning>,
        planner: &mut Planner,
        decision: Duration,
    ) -> Result<Self, RoleError> {
        let mut clock = HeartbeatClock::new(ctx.spec.timing.heartbeat_period_ms.max(1) * 1_000_000);
        if let Some(step) = hub_active_step(ctx, RESUME_WAIT)? {
            planner.resume(step);
            // the flight is under way: its S_t's come from the topic's history first
            clock = clock.first_state_max_age(first_state_max_age(ctx, decision));
        }
        Ok(Self {
            states: ctx.bus.subscriber::<topics::PerceptionState>()?,
            telemetry: ctx.bus.subscriber::<topics::VehicleTelemetry>()?,
            decisions: ctx.bus.publisher::<topics::ReasoningDecision>()?,
            clock,
            state: None,
            fresh_state: false,
            telemetry_last: None,
            telemetry_kept: TelemetryRing::default(),
            start: ctx.spec.mission.start,
            seq: 0,
            cycle: 0,
            source: ctx.spec.instance,
            standby: Standby::Unknown,
        })
    }

    /// Read every new valid S_t and telemetry; when a decision is due, take it as made now
    /// and say what it is based on.
    ///
    /// While the process stands by (the new side of a hot swap, not yet the role:
    /// [`aeris_runtime::role::standing_by`]) it keeps the telemetry and lets every S_t go
    /// undecided: the running process decides them, and this one's schedule starts with the
    /// first S_t captured after it became the role ([`HeartbeatClock::resume`]). Deciding
    /// on idle CPU time beside the running reasoner made the new one's first decisions late
    /// (2.2-3.1 s after their frames, on 2 cores), and the hub takes the newest instance's
    /// decision as soon as it comes.
    pub fn poll(&mut self) -> Result<Option<DecisionDue>, RoleError> {
        let poll_ns = monotonic_ns();
        let (kept, last) = (&mut self.telemetry_kept, &mut self.telemetry_last);
        let heard = self.telemetry.drain(|t| {
            if t.validate().is_ok() {
                kept.push(*t);
                *last = Some(*t);
            }
        })?;
        if self.standby != Standby::Over {
            if aeris_runtime::role::standing_by() {
                self.states.drain(|_| {})?;
                self.standby = Standby::Standing;
                return Ok(None);
            }
            if self.standby == Standby::Standing {
                self.clock.resume(poll_ns);
            }
            self.standby = Standby::Over;
        }
        // the first S_t that starts the next cycle, in the order perception published them
        let (clock, state, fresh) = (&mut self.clock, &mut self.state, &mut self.fresh_state);
        let heard = heard
            + self.states.drain(|s| {
                if !*fresh
                    && s.validate().is_ok()
                    && state.as_ref().is_none_or(|old| old.seq != s.seq)
                    && clock.takes(s.capture_ns, poll_ns)
                {
                    *state = Some(*s);
                    *fresh = true;
                }
            })?;
        if heard > 0 {
            self.clock.heard(poll_ns);
        }
        let Some(basis) = self.clock.due(poll_ns, self.fresh_state) else {
            return Ok(None);
        };
        self.fresh_state = false;
        let (position, yaw, landed, cycle_start) = match (basis, &self.state) {
            (Basis::State, Some(s)) => {
                let (p, y, l) = match self.telemetry_kept.at(s.capture_ns) {
                    Some(t) => (t.position, t.attitude[2], t.landed == 1),
                    None => (s.position, s.yaw, s.position[2] < 0.3),
                };
                (p, y, l, s.capture_ns)
            }
            _ => {
                let (p, y, l) = match (&self.telemetry_last, &self.state) {
                    (Some(t), _) => (t.position, t.attitude[2], t.landed == 1),
                    (None, Some(s)) => (s.position, s.yaw, s.position[2] < 0.3),
                    (None, None) => (self.start, 0.0, true),
                };
                (p, y, l, poll_ns)
            }
        };
        self.clock.decided(poll_ns, cycle_start);
        Ok(Some(DecisionDue {
            poll_ns,
            basis,
            position,
            yaw,
            landed,
        }))
    }

    /// The S_t `due` is based on; `None` for a decision on the telemetry alone (which
    /// must not show the reasoner an old view).
    pub fn state(&self, due: &DecisionDue) -> Option<&PerceptionState> {
        match due.basis {
            Basis::State => self.state.as_ref(),
            Basis::TelemetryOnly => None,
        }
    }

    /// The latest valid telemetry, if any came.
    pub fn telemetry(&self) -> Option<&VehicleTelemetry> {
        self.telemetry_last.as_ref()
    }

    /// The mission's start `[N, E, U]` (where the vehicle is before anything says otherwise).
    pub fn start(&self) -> [f32; 3] {
        self.start
    }

    /// The sequence number of the latest decision published (0 before the first).
    pub fn last_seq(&self) -> u64 {
        self.seq
    }

    /// Number `d` as this role's next cycle and stamp its timing: the cycle starts at the
    /// capture of the S_t it is based on (at the poll, on the telemetry alone); the
    /// reasoning at `reasoning_start_ns`.
    pub fn stamp(&mut self, d: &mut Decision, due: &DecisionDue, reasoning_start_ns: u64) {
        self.cycle += 1;
        d.cycle = self.cycle;
        d.source = self.source;
        match self.state(due) {
            Some(s) => {
                d.cycle_start_ns = s.capture_ns;
                d.state_stamp_ns = s.publish_ns;
            }
            None => {
                d.cycle_start_ns = due.poll_ns;
                d.state_stamp_ns = due.poll_ns;
            }
        }
        d.reasoning_start_ns = reasoning_start_ns;
    }

    /// Publish `d`: a `seq` of 0 takes the next sequence number (any other is sent as it
    /// is: the garbage role replays old ones). Reports the `publish` stage; the variant
    /// reports [`ReasonerIo::published`] among its counters.
    pub fn publish(&mut self, d: &mut Decision, report: &mut CycleReport) -> Result<(), RoleError> {
        let t = monotonic_ns();
        if d.seq == 0 {
            self.seq += 1;
            d.seq = self.seq;
        }
        d.publish_ns = monotonic_ns();
        self.decisions.publish(d)?;
        report.stage("publish", monotonic_ns() - t);
        Ok(())
    }

    /// Decisions published so far.
    pub fn published(&self) -> u64 {
        self.seq
    }
}

/// The last [`TELEMETRY_KEPT`] telemetry samples, in arrival order (no allocation).
struct TelemetryRing {
    samples: [VehicleTelemetry; TELEMETRY_KEPT],
    next: usize,
    len: usize,
}

impl Default for TelemetryRing {
    fn default() -> Self {
        Self {
            samples: [VehicleTelemetry::default(); TELEMETRY_KEPT],
            next: 0,
            len: 0,
        }
    }
}

impl TelemetryRing {
    fn push(&mut self, t: VehicleTelemetry) {
        self.samples[self.next] = t;
        self.next = (self.next + 1) % TELEMETRY_KEPT;
        self.len = (self.len + 1).min(TELEMETRY_KEPT);
    }

    /// The latest sample stamped at or before `ns`; `None` when every kept one is later.
    fn at(&self, ns: u64) -> Option<&VehicleTelemetry> {
        (1..=self.len)
            .map(|back| &self.samples[(self.next + TELEMETRY_KEPT - back) % TELEMETRY_KEPT])
            .find(|t| t.stamp_ns <= ns)
    }
}

#[cfg(test)]
mod ring_tests {
    use super::*;

    #[test]
    fn the_vehicle_at_a_capture_is_the_last_sample_stamped_before_it() {
        let mut ring = TelemetryRing::default();
        assert!(ring.at(5).is_none());
        for k in 1..=(TELEMETRY_KEPT as u64 + 10) {
            ring.push(VehicleTelemetry {
                seq: k,
                stamp_ns: k * 20,
                ..VehicleTelemetry::default()
            });
        }
        assert_eq!(ring.at(20 * 100 + 5).map(|t| t.seq), Some(100));
        assert_eq!(
            ring.at(u64::MAX).map(|t| t.seq),
            Some(TELEMETRY_KEPT as u64 + 10)
        );
        // older than everything kept: none
        assert!(ring.at(20 * 5).is_none());
    }
}
