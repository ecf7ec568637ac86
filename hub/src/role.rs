//! The hub role (kind `hub`, variant `gate`): a thin shell that feeds [`HubCore`] the
//! messages and the clock, and publishes what it returns.
//!
//! Every 20 ms: drain `vehicle/telemetry` (latest valid position), `perception/state`
//! (every sample: validate, ATT), `reasoning/decision` (every sample, in arrival order:
//! order, deadline, gate), then tick: publish `hub/setpoint` (whenever there is a valid
//! decision to fly) and `hub/report` (per committed or reused cycle).
//!
//! Parameters: `no_att` (bool, default false: the active step is the reasoner's declared
//! step), `att_temperature` (number > 0, default 0.5), `realtime` (bool, default true: try
//! SCHED_FIFO priority 49, just below the controller, so model roles loading or deciding on
//! the same CPUs never delay a setpoint).
//!
//! Heartbeat stages: `route` (transport: draining and publishing), `gate` (decisions, and the
//! tick: reuse slots, the committed setpoint's way check after a new S_t), `att` (states and
//! ATT). A change of the occupancy status the gate works with (present, absent, stale) is
//! one line in the role's log; every report carries it. Heartbeat counters: `[decisions received,
//! rejected, late, reused cycles, sequence gaps, reorders, states received, decisions
//! superseded]` ([`HubBeatCounters`]).

use crate::att::{Attention, AttentionPrior, EMBEDDING_GAIN, EmbeddingScorer};
use crate::core::{DecisionVerdict, HubConfig, HubCore};
use crate::gate::DecisionGate;
use aeris_runtime::bus::{BusError, TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::role::try_sched_fifo;
use aeris_runtime::spec::TimingSpec;
use aeris_runtime::{
    ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleSpec,
};
use aeris_schemas::kinds;
use aeris_schemas::{
    BLIND_MOVE_M, BoundSetpoint, Decision, HubBeatCounters, HubReport, MAX_SUBGOALS,
    OccupancyStatus, PerceptionState, RoleStatus, VehicleTelemetry, topics,
};
use std::time::Duration;

/// Period of the hub's cycle.
pub const HUB_PERIOD: Duration = Duration::from_millis(20);
/// Default softmax temperature of ATT.
pub const DEFAULT_ATT_TEMPERATURE: f32 = 0.5;
/// SCHED_FIFO priority of the hub's thread (the controller runs at 50).
pub const HUB_FIFO_PRIORITY: i32 = 49;
/// Entries kept in the attention trace.
pub const TRACE_CAPACITY: usize = 4096;

/// The hub's timing from the flight's (milliseconds to nanoseconds, period at least 1 ms).
pub fn hub_config(timing: &TimingSpec, no_att: bool) -> HubConfig {
    HubConfig {
        heartbeat_period_ns: timing.heartbeat_period_ms.max(1).saturating_mul(1_000_000),
        decision_deadline_ns: timing.decision_deadline_ms.saturating_mul(1_000_000),
        no_att,
    }
}

/// Build the hub's core from a role spec (mission, timing, `no_att`, `att_temperature`).
pub fn core_from_spec(spec: &RoleSpec) -> Result<HubCore, RoleError> {
    let no_att = spec.param_bool("no_att", false)?;
    let temperature = match spec.params.get("att_temperature") {
        None => DEFAULT_ATT_TEMPERATURE,
        Some(v) => match v.as_f64() {
            Some(t) if t.is_finite() && t > 0.0 && t <= f32::MAX as f64 => t as f32,
            _ => {
                return Err(RoleError::param(
                    "att_temperature",
                    format!("must be a number > 0, got {v}"),
                ));
            }
        },
    };
    let mission = &spec.mission;
    let count = mission.subgoals.len();
    if count == 0 || count > MAX_SUBGOALS {
        return Err(ConfigError::Mission(format!(
            "has {count} subgoals; the hub needs 1..={MAX_SUBGOALS}"
        ))
        .into());
    }
    let gate = DecisionGate::new(mission.decision_limits())
        .map_err(|e| ConfigError::refused("the hub's gate", e))?;
    let texts: Vec<&str> = mission.subgoals.iter().map(|s| s.text.as_str()).collect();
    let attention = Attention::new(
        Box::new(EmbeddingScorer::new(
            &texts,
            spec.param_f64("att_gain")
                .map(|g| g as f32)
                .unwrap_or(EMBEDDING_GAIN),
        )),
        count,
        temperature,
        AttentionPrior::default(),
        TRACE_CAPACITY,
    )
    .map_err(|e| ConfigError::refused("the hub's attention", e))?;
    HubCore::new(
        gate,
        attention,
        hub_config(&spec.timing, no_att),
        mission.start,
    )
    .map_err(|e| ConfigError::refused("the hub's core", e).into())
}

/// The hub role.
pub struct HubRole {
    core: HubCore,
    states: TypedSubscriber<PerceptionState>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    decisions: TypedSubscriber<Decision>,
    setpoints: TypedPublisher<BoundSetpoint>,
    reports: TypedPublisher<HubReport>,
    /// The occupancy status last logged.
    occupancy: Option<OccupancyStatus>,
    /// Lines logged about rejected decisions and missed heartbeats (at most
    /// [`VERDICT_LOG_LINES`]).
    verdicts_logged: u32,
}

/// Lines the hub logs, at most, about rejected or late decisions and heartbeats that
/// closed without a decision: enough to see who was late in a flight, bounded so a reasoner
/// sending garbage cannot fill the disk.
pub const VERDICT_LOG_LINES: u32 = 200;

/// Log a rejected or late decision (which instance sent it, which cycle, why), while fewer
/// than [`VERDICT_LOG_LINES`] lines were logged.
fn log_verdict(logged: &mut u32, d: &Decision, verdict: &DecisionVerdict) {
    if *logged >= VERDICT_LOG_LINES {
        return;
    }
    let slot = |report: &Option<HubReport>| {
        if report.is_some() {
            "its heartbeat is missed"
        } else {
            "no heartbeat missed"
        }
    };
    match verdict {
        DecisionVerdict::Late { age_ns, report } => tracing::warn!(
            "hub: late decision from reasoner instance {} (cycle {}, seq {}): received {:.0} ms after its cycle start; {}",
            d.source,
            d.cycle,
            d.seq,
            *age_ns as f64 / 1e6,
            slot(report)
        ),
        DecisionVerdict::Rejected { reason, report } => tracing::warn!(
            "hub: rejected decision from reasoner instance {} (cycle {}, seq {}): {reason}; {}",
            d.source,
            d.cycle,
            d.seq,
            slot(report)
        ),
        DecisionVerdict::Committed { .. } | DecisionVerdict::Superseded { .. } => return,
    }
    *logged += 1;
    if *logged == VERDICT_LOG_LINES {
        tracing::warn!("hub: {VERDICT_LOG_LINES} lines about rejected decisions logged; no more");
    }
}

impl HubRole {
    /// The pure state machine inside (for inspection).
    pub fn core(&self) -> &HubCore {
        &self.core
    }
}

impl Role for HubRole {
    type Kind = kinds::Hub;

    fn new(ctx: &mut RoleContext<kinds::Hub>) -> Result<Self, RoleError> {
        let core = core_from_spec(&ctx.spec)?;
        let realtime = ctx.spec.param_bool("realtime", true)?;
        if realtime && !try_sched_fifo(HUB_FIFO_PRIORITY) {
            tracing::warn!(
                "aeris hub `{}`: SCHED_FIFO not permitted, running with the normal scheduler",
                ctx.spec.name
            );
        }
        Ok(Self {
            core,
            states: ctx.bus.subscriber::<topics::PerceptionState>()?,
            telemetry: ctx.bus.subscriber::<topics::VehicleTelemetry>()?,
            decisions: ctx.bus.subscriber::<topics::ReasoningDecision>()?,
            setpoints: ctx.bus.publisher::<topics::HubSetpoint>()?,
            reports: ctx.bus.publisher::<topics::HubReport>()?,
            occupancy: None,
            verdicts_logged: 0,
        })
    }

    fn period(&self) -> Duration {
        HUB_PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Hub>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let start = monotonic_ns();
        let mut gate_ns = 0u64;
        let mut att_ns = 0u64;
        let mut publish_error: Option<BusError> = None;

        let mut position = None;
        let telemetry = self.telemetry.drain(|t| {
            if t.validate().is_ok() {
                position = Some(t.position);
            }
        })?;
        if let Some(p) = position {
            self.core.on_telemetry(p);
        }

        let core = &mut self.core;
        let states = self.states.drain(|s| {
            let t = monotonic_ns();
            let _ = core.on_state(s, t);
            att_ns += monotonic_ns().saturating_sub(t);
        })?;

        let status = self.core.occupancy().status();
        if states > 0 && status != self.occupancy {
            self.occupancy = status;
            if status == Some(OccupancyStatus::Present) {
                tracing::info!("hub: occupancy present: the gate clamps against the grid");
            } else {
                let b = self.core.gate().limits().blind_altitude();
                tracing::warn!(
                    "hub: occupancy {}: unknown space is not free; moves over {BLIND_MOVE_M} m \
                     are flown at the conservative altitude {b} m, inside the geofence",
                    status.map_or("unknown", OccupancyStatus::name)
                );
            }
        }
        let core = &mut self.core;
        let reports = &self.reports;
        let logged = &mut self.verdicts_logged;
        let decisions = self.decisions.drain(|d| {
            let receive = monotonic_ns();
            let verdict = core.on_decision_timed(d, receive, monotonic_ns);
            gate_ns += monotonic_ns().saturating_sub(receive);
            log_verdict(logged, d, &verdict);
            let out = match verdict {
                DecisionVerdict::Committed { report, .. } => Some(report),
                DecisionVerdict::Rejected { report, .. } | DecisionVerdict::Late { report, .. } => {
                    report
                }
                DecisionVerdict::Superseded { .. } => None,
            };
            if let Some(r) = out
                && let Err(e) = reports.publish(&r)
                && publish_error.is_none()
            {
                publish_error = Some(e);
            }
        })?;
        if let Some(e) = publish_error {
            return Err(e.into());
        }

        let now = monotonic_ns();
        let tick = self.core.on_tick(now);
        gate_ns += monotonic_ns().saturating_sub(now);
        if let Some(r) = tick.report {
            if r.reused == 1 && r.committed == 0 && self.verdicts_logged < VERDICT_LOG_LINES {
                self.verdicts_logged += 1;
                tracing::warn!(
                    "hub: a heartbeat closed without a fresh decision from reasoner instance {}: the last one is reused ({} reused in this flight)",
                    r.decision_source,
                    r.counts.decisions_reused
                );
            }
            self.reports.publish(&r)?;
        }
        if let Some(sp) = tick.setpoint {
            self.setpoints.publish(&sp)?;
        }

        let total = monotonic_ns().saturating_sub(start);
        report.stage("route", total.saturating_sub(gate_ns + att_ns));
        report.stage("gate", gate_ns);
        report.stage("att", att_ns);
        let c = self.core.counters();
        report.counters = HubBeatCounters {
            received: c.decisions_received,
            rejected: c.decisions_rejected,
            late: c.decisions_late,
            reused: c.decisions_reused,
            sequence_gaps: c.sequence_gaps,
            reorders: c.sequence_reorders,
            states_received: c.states_received,
            superseded: c.decisions_superseded,
        }
        .to_heartbeat();
        report.status = if self.core.reusing() {
            RoleStatus::Degraded
        } else {
            RoleStatus::Running
        };
        let worked =
            tick.setpoint.is_some() || tick.report.is_some() || telemetry + states + decisions > 0;
        Ok(if worked {
            CycleOutcome::Worked
        } else {
            CycleOutcome::Idle
        })
    }
}
