//! `aeris bench cycle`: the model flight end to end over N heartbeats: cycle time per
//! stage (mean, std, p95), EER, each role's heartbeat latency.

use super::{
    BusyProcesses, FlightBenchConfig, FlightBenchError, flight_name_and_dir, load_workflow,
    role_latencies, with_variants,
};
use aeris_flight::{Flight, FlightWatcher, HookError, StageMeans, StepContext, StepHook, StopRule};
use aeris_orchestrator::supervisor::SupervisorEvent;
use aeris_roles::language::heartbeat as language;
use aeris_runtime::stats::{mean_std, percentile};
use aeris_schemas::LanguageCounters;
use aeris_schemas::RoleKind;
use serde::Serialize;
use std::time::Instant;

/// Settings of `aeris bench cycle`.
#[derive(Debug, Clone)]
pub struct CycleConfig {
    /// Semantic heartbeats (committed or reused cycles) to measure.
    pub heartbeats: u64,
    /// The flight.
    pub flight: FlightBenchConfig,
}

/// One role's latency over the flight, from its heartbeats.
#[derive(Debug, Clone, Serialize)]
pub struct RoleLatency {
    /// Role name.
    pub role: String,
    /// Variant.
    pub variant: String,
    /// Cycle latency p50 (ms).
    pub p50_ms: f64,
    /// Cycle latency p95 (ms).
    pub p95_ms: f64,
}

/// `aeris bench cycle --json`.
#[derive(Debug, Serialize)]
pub struct CycleReport {
    /// Heartbeats measured (committed + reused cycles).
    pub heartbeats: u64,
    /// The reasoning variant flown.
    pub reasoning: String,
    /// Mean cycle time, frame capture -> committed decision (s).
    pub ct_mean_s: f64,
    /// Its standard deviation (s).
    pub ct_std_s: f64,
    /// Its 95th percentile (s).
    pub ct_p95_s: f64,
    /// Execution error rate: heartbeats that reused the last valid decision.
    pub eer: f64,
    /// Mean per stage (s): perception, reasoning, routing, binding.
    pub stages: StageMeans,
    /// Each role's cycle latency from its heartbeats.
    pub roles: Vec<RoleLatency>,
    /// Decisions that arrived after the deadline.
    pub decisions_late: u64,
    /// Controller ticks that missed their deadline.
    pub controller_missed_ticks: u64,
    /// Busy processes outside the flight during the run.
    pub outside_load: usize,
    /// How the roles got priority over them (`cgroup-v2`, `cgroup-v1`, `nice`, `none`).
    pub priority: String,
    /// The same in words.
    pub priority_detail: String,
    /// The roles' memory: each role's peak and the flight's (PSS summed).
    pub memory: aeris_flight::MemorySummary,
    /// Whether the supervisor and the machine's CPUs kept running.
    pub pauses: Pauses,
    /// What each language-model decision cost, from the reasoner's heartbeats (empty for a
    /// reasoner that is not a language model): the next regression shows here at once.
    pub decisions: Vec<DecisionCost>,
    /// The same figures over the heartbeats flown in the air: the mission lands after ~30
    /// heartbeats and waits, and a landed reasoner's prompt barely changes.
    pub in_flight: AirborneCycles,
}

/// Cycle time and EER over the heartbeats the hub reported while the vehicle was airborne.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct AirborneCycles {
    /// Heartbeats reported while the vehicle was above [`AIRBORNE_M`].
    pub heartbeats: u64,
    /// Mean cycle time of their committed decisions (s).
    pub ct_mean_s: f64,
    /// Its 95th percentile (s).
    pub ct_p95_s: f64,
    /// Of them, the share that reused the last valid decision.
    pub eer: f64,
}

/// Height above the start (m) over which a heartbeat counts as flown in the air.
pub const AIRBORNE_M: f32 = 0.5;

impl AirborneCycles {
    /// The airborne heartbeats of a flight's trace.
    pub fn of(trace: &[aeris_flight::CycleTrace]) -> Self {
        let airborne: Vec<_> = trace
            .iter()
            .filter(|c| c.position.is_some_and(|p| p[2] > AIRBORNE_M))
            .collect();
        let ct: Vec<f64> = airborne
            .iter()
            .filter(|c| c.committed)
            .map(|c| c.ct_s)
            .collect();
        let reused = airborne.iter().filter(|c| c.reused).count();
        Self {
            heartbeats: airborne.len() as u64,
            ct_mean_s: mean_std(&ct).map_or(0.0, |(mean, _)| mean),
            ct_p95_s: percentile(&ct, 95.0).unwrap_or(0.0),
            eer: if airborne.is_empty() {
                0.0
            } else {
                reused as f64 / airborne.len() as f64
            },
        }
    }
}

/// One language-model decision: its prompt, what of it was new, what was generated, and
/// the time of each (`reasoning/*` heartbeat counters and stages, see `roles::language`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DecisionCost {
    /// The reasoner's process (a restart or swap starts another).
    pub pid: u32,
    /// When its heartbeat was stamped (`CLOCK_MONOTONIC`, ns: the clock of the roles'
    /// log headers).
    pub stamp_ns: u64,
    /// Tokens in the prompt.
    pub prompt_tokens: u64,
    /// Of which evaluated anew (the rest was reused from the last decision's cache).
    pub new_prompt_tokens: u64,
    /// Tokens generated.
    pub generated_tokens: u64,
    /// Of which verified from the draft (the plan) in a batch: all of them when the model
    /// wrote the plan's decision.
    pub drafted_tokens: u64,
    /// Whether the decision's step departed from the plan's.
    pub departed_from_plan: bool,
    /// Time evaluating the new prompt tokens (ms).
    pub prompt_ms: f64,
    /// Time generating (ms).
    pub generate_ms: f64,
    /// The whole decision, S_t read to decision published (ms).
    pub decision_ms: f64,
}

impl DecisionCost {
    /// The cost in the heartbeat of a language-model reasoner's working cycle; `None` for
    /// any other heartbeat.
    fn from_heartbeat(hb: &aeris_schemas::RoleHeartbeat) -> Option<Self> {
        if hb.worked != 1 {
            return None;
        }
        let stage = |name: &str| {
            hb.stages
                .iter()
                .find(|s| s.name.as_str() == Some(name))
                .map(|s| s.ns as f64 / 1e6)
        };
        let (prompt_ms, generate_ms) = (
            stage(language::PROMPT_STAGE)?,
            stage(language::GENERATE_STAGE)?,
        );
        let c = LanguageCounters::from_heartbeat(&hb.counters);
        Some(Self {
            pid: hb.pid,
            stamp_ns: hb.stamp_ns,
            prompt_tokens: c.prompt_tokens,
            new_prompt_tokens: c.prompt_tokens.saturating_sub(c.reused_prompt_tokens),
            generated_tokens: c.generated_tokens,
            drafted_tokens: c.drafted_tokens,
            departed_from_plan: c.departed_from_plan == 1,
            prompt_ms,
            generate_ms,
            decision_ms: hb.cycle_latency_ns as f64 / 1e6,
        })
    }
}

/// The supervisor's step gaps and the machine's CPU pauses over a flight.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Pauses {
    /// The longest time between two steps of the flight's loop (it steps every ~20 ms), ms.
    pub step_gap_max_ms: f64,
    /// Steps that came over 100 ms after the one before.
    pub step_gaps_over_100ms: u64,
    /// Pauses of the supervisor over 300 ms it reported (its silence discounted).
    pub supervisor_pauses: u64,
    /// Times one CPU ran no ordinary thread for over 300 ms (paused, or held by real-time work).
    pub cpu_pauses: u64,
    /// The longest of those pauses, either kind, ms.
    pub pause_max_ms: u64,
}

/// The language-model decisions of a flight, read from its reasoners' heartbeats as the
/// flight steps (every working heartbeat once, whichever process sent it).
#[derive(Debug, Default)]
pub(super) struct DecisionLog {
    /// The decisions so far.
    pub(super) decisions: Vec<DecisionCost>,
    /// The reasoner heartbeat last read: (pid, seq).
    last: Option<(u32, u64)>,
}

impl DecisionLog {
    /// Add the reasoners' newest heartbeat if it is a decision not yet read.
    pub(super) fn observe(&mut self, supervisor: &aeris_orchestrator::supervisor::Supervisor) {
        for role in supervisor
            .roles()
            .iter()
            .filter(|r| r.kind() == RoleKind::Reasoning)
        {
            let Some(hb) = role.last_heartbeat() else {
                continue;
            };
            if self.last.replace((hb.pid, hb.seq)) != Some((hb.pid, hb.seq))
                && let Some(cost) = DecisionCost::from_heartbeat(hb)
            {
                self.decisions.push(cost);
            }
        }
    }
}

/// Keeps the roles' latest heartbeat latencies and the flight's pauses.
#[derive(Default)]
struct LatencyWatch {
    roles: Vec<RoleLatency>,
    pauses: Pauses,
    last_step: Option<Instant>,
    decisions: DecisionLog,
}

impl StepHook for LatencyWatch {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        self.roles = role_latencies(ctx.supervisor);
        self.decisions.observe(ctx.supervisor);
        let now = Instant::now();
        if let Some(last) = self.last_step.replace(now) {
            let gap_ms = now.duration_since(last).as_secs_f64() * 1e3;
            self.pauses.step_gap_max_ms = self.pauses.step_gap_max_ms.max(gap_ms);
            self.pauses.step_gaps_over_100ms += u64::from(gap_ms > 100.0);
        }
        for event in ctx.events {
            if let SupervisorEvent::Unwatched { gap_ms, cpu } = event {
                match cpu {
                    Some(_) => self.pauses.cpu_pauses += 1,
                    None => self.pauses.supervisor_pauses += 1,
                }
                self.pauses.pause_max_ms = self.pauses.pause_max_ms.max(*gap_ms);
            }
        }
        Ok(false)
    }
}

/// Fly the benchmark; `watcher` gets every event of the flight.
pub fn run(
    config: &CycleConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<CycleReport, FlightBenchError> {
    if config.heartbeats == 0 {
        return Err(FlightBenchError::Settings(
            "heartbeats must be at least 1".into(),
        ));
    }
    let mut w = with_variants(load_workflow(&config.flight)?, &config.flight)?;
    let reasoning = w
        .roles
        .iter()
        .find(|r| r.kind == RoleKind::Reasoning)
        .map(|r| r.variant.clone())
        .unwrap_or_default();
    // time for N heartbeats, whatever the mission does meanwhile (it lands and waits)
    let period_s = w.timing.heartbeat_period_ms as f64 / 1000.0;
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max(config.heartbeats as f64 * period_s * 3.0 + 60.0);
    if let Some(mode) = config.flight.priority {
        w.scheduling.priority = mode;
    }
    let (name, run_dir) = flight_name_and_dir("cycle", config.flight.run_dir.clone());
    let _load = BusyProcesses::start(None, config.flight.outside_load)?;
    let (outcome, watch) = Flight::builder(w)
        .name(name)
        .language_offload_check(aeris_llm::offload_check)
        .run_dir(run_dir)
        .stop_when(StopRule::Cycles(config.heartbeats))
        .step_hook(LatencyWatch::default())
        .start()?
        .watch(watcher)?;
    if let Some(failure) = outcome.failure {
        return Err(FlightBenchError::EndedEarly {
            bench: "bench cycle".into(),
            failure,
        });
    }
    let s = outcome.summary;
    Ok(CycleReport {
        heartbeats: s.cycles,
        reasoning,
        ct_mean_s: s.ct_mean_s,
        ct_std_s: s.ct_std_s,
        ct_p95_s: s.ct_p95_s,
        eer: s.eer,
        stages: s.stages_mean_s,
        roles: watch.roles,
        decisions_late: s.hub.decisions_late,
        controller_missed_ticks: s.controller_missed_ticks,
        outside_load: config.flight.outside_load,
        priority: s.priority,
        priority_detail: s.priority_detail,
        memory: s.memory,
        pauses: watch.pauses,
        decisions: watch.decisions.decisions,
        in_flight: AirborneCycles::of(&outcome.trace),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_schemas::{FixedText, RoleHeartbeat};

    fn heartbeat(stages: &[(&str, u64)]) -> RoleHeartbeat {
        let mut hb = RoleHeartbeat {
            pid: 42,
            worked: 1,
            cycle_latency_ns: 900_000_000,
            ..RoleHeartbeat::default()
        };
        for (slot, (name, ns)) in hb.stages.iter_mut().zip(stages) {
            slot.name = FixedText::from_str_truncated(name);
            slot.ns = *ns;
        }
        hb.counters = LanguageCounters {
            generated_tokens: 31,
            reused_prompt_tokens: 250,
            prompt_tokens: 290,
            ..LanguageCounters::default()
        }
        .to_heartbeat();
        hb
    }

    #[test]
    fn a_language_model_heartbeat_gives_its_decision_cost() {
        let hb = heartbeat(&[
            ("read", 1_000),
            ("prompt", 120_000_000),
            ("generate", 700_000_000),
        ]);
        let cost = DecisionCost::from_heartbeat(&hb).unwrap();
        assert_eq!(cost.pid, 42);
        assert_eq!(
            (
                cost.prompt_tokens,
                cost.new_prompt_tokens,
                cost.generated_tokens
            ),
            (290, 40, 31)
        );
        assert_eq!(
            (cost.prompt_ms, cost.generate_ms, cost.decision_ms),
            (120.0, 700.0, 900.0)
        );
    }

    fn cycle(up: f32, ct_s: f64, reused: bool) -> aeris_flight::CycleTrace {
        aeris_flight::CycleTrace {
            cycle: 0,
            t_s: 0.0,
            ct_s,
            stages_s: [0.0; 4],
            committed: !reused,
            reused,
            active_step: 1,
            position: Some([0.0, 0.0, up]),
            yaw: None,
            setpoint: None,
            setpoint_mode: None,
        }
    }

    #[test]
    fn only_heartbeats_reported_in_the_air_count_as_in_flight() {
        let trace = [
            cycle(0.0, 0.4, false),
            cycle(6.0, 1.0, false),
            cycle(12.0, 0.0, true),
            cycle(12.0, 2.0, false),
            cycle(0.1, 0.3, false),
        ];
        let air = AirborneCycles::of(&trace);
        assert_eq!(air.heartbeats, 3);
        assert_eq!((air.ct_mean_s, air.ct_p95_s), (1.5, 2.0));
        assert!((air.eer - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(AirborneCycles::of(&[]), AirborneCycles::default());
    }

    #[test]
    fn an_idle_or_planner_heartbeat_gives_none() {
        let mut idle = heartbeat(&[("prompt", 1), ("generate", 1)]);
        idle.worked = 0;
        assert_eq!(DecisionCost::from_heartbeat(&idle), None);
        let planner = heartbeat(&[("read", 1), ("plan", 1)]);
        assert_eq!(DecisionCost::from_heartbeat(&planner), None);
    }
}
