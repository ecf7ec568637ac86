//! Reasoning role, language-model variants (kind `reasoning`, variants `smollm2`, `gemma3`):
//! a GGUF model in llama.cpp turns (S_t, G, M_{t-1}) into D_t under the decision grammar
//! ([`aeris_llm`]).
//!
//! The prompt carries a plan: the deterministic [`Planner`]'s decision for this heartbeat
//! (it tracks which subgoal is in progress from the vehicle's state). The small untuned
//! models do not track multi-step progress from the mission text on their own (measured:
//! SmolLM2-135M kept answering step 1, Gemma-3-270M step 4, whatever the state); shown the
//! plan in their own output format, they follow it and can depart from it. The plan is also
//! the draft the decoder verifies in one batch.
//!
//! The role polls every 50 ms and decides once per heartbeat on the first fresh S_t, or on
//! the telemetry alone when no S_t came for a heartbeat and a half
//! ([`HeartbeatClock`]). The model is loaded and warmed up (one decision) in `new`, before
//! the first heartbeat, so a swapped-in reasoner is ready when the supervisor sees it.
//!
//! Parameters: `model` (cache-relative GGUF, default per variant), `threads` (default 2, at most the CPUs of its executor),
//! `context_tokens` (default 2048), `models_dir`, `plan` (bool, default true; false leaves
//! the planner's plan out of the prompt: the generic model on its own, the evaluation's
//! zero-shot ablation).
//! Heartbeat stages: `read`, `prompt` (evaluating the new prompt tokens), `generate`,
//! `publish`; the cycle latency is the decision latency. Counters: `[decisions,
//! tokens_per_s x 100 (last decision), generated tokens (last decision), failures,
//! prompt tokens reused (last decision), prompt tokens (last decision), generated tokens
//! verified from the draft (last decision), 1 when the last decision's step departed from
//! the plan's]`.

use crate::heartbeat_clock::{Basis, HeartbeatClock};
use crate::planner::{Planner, RESUME_WAIT, hub_active_step};
use crate::vision::open_store;
use aeris_llm::{
    DecisionView, GEMMA3_270M, LanguageReasoner, MissionBrief, Observation, ReasonerConfig,
    SMOLLM2_135M, StepBrief,
};
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{CycleOutcome, CycleReport, MissionSpec, Role, RoleContext, RoleError};
use aeris_schemas::{Decision, PerceptionState, VehicleTelemetry, topics};
use core::time::Duration;

pub use crate::planner::POLL;

/// The mission as the language model reads it.
pub fn mission_brief(mission: &MissionSpec) -> Result<MissionBrief, RoleError> {
    let steps = mission
        .subgoals
        .iter()
        .map(|s| {
            Ok(StepBrief {
                text: s.text.clone(),
                action: s.action_mode().ok_or_else(|| {
                    RoleError::Config(format!("unknown action `{}` in the mission", s.action))
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

/// The default model file of a language-model variant.
pub fn default_model(variant: &str) -> Option<&'static str> {
    match variant {
        "smollm2" => Some(SMOLLM2_135M),
        "gemma3" => Some(GEMMA3_270M),
        _ => None,
    }
}

/// The language-model reasoning role.
pub struct LanguageRole {
    reasoner: LanguageReasoner,
    planner: Planner,
    states: TypedSubscriber<PerceptionState>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    decisions: TypedPublisher<Decision>,
    clock: HeartbeatClock,
    state: Option<Box<PerceptionState>>,
    fresh_state: bool,
    telemetry_last: Option<VehicleTelemetry>,
    previous: Option<DecisionView>,
    start: [f32; 3],
    seq: u64,
    cycle: u64,
    failures: u64,
    source: u32,
    /// Whether the prompt shows the planner's plan.
    show_plan: bool,
}

impl LanguageRole {
    fn read_inputs(&mut self) -> Result<(), RoleError> {
        if let Some(s) = self.states.latest()?
            && s.validate().is_ok()
            && self.state.as_ref().is_none_or(|old| old.seq != s.seq)
        {
            self.state = Some(Box::new(s));
            self.fresh_state = true;
        }
        if let Some(t) = self.telemetry.latest()?
            && t.validate().is_ok()
        {
            self.telemetry_last = Some(t);
        }
        Ok(())
    }
}

impl Role for LanguageRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let variant = ctx.spec.variant.clone();
        let file = ctx
            .spec
            .param_str("model")
            .or(default_model(&variant))
            .ok_or_else(|| RoleError::Config(format!("no model for variant `{variant}`")))?
            .to_string();
        // never more threads than CPUs the process may run on: ggml's workers spin at their
        // barriers, and two spinning on one CPU (a role bound to a one-CPU executor) starve
        // each other and every role beside them (measured: no decision in 300 s)
        let cpus = aeris_runtime::affinity::CpuSet::of_task(0)
            .map(|s| s.cpus().len())
            .unwrap_or(1)
            .max(1);
        let config = ReasonerConfig {
            threads: (ctx
                .spec
                .param_f64("threads")
                .unwrap_or(2.0)
                .clamp(1.0, 64.0) as i32)
                .min(cpus as i32),
            context_tokens: ctx
                .spec
                .param_f64("context_tokens")
                .unwrap_or(2048.0)
                .clamp(256.0, 32768.0) as u32,
            ..ReasonerConfig::default()
        };
        let show_plan = ctx.spec.param_bool("plan", true)?;
        let store = open_store(ctx)?;
        let brief = mission_brief(&ctx.spec.mission)?;
        let mut planner = Planner::new(&ctx.spec.mission, &ctx.spec.camera).ok_or_else(|| {
            RoleError::Config("the mission names an unknown action or the camera is invalid".into())
        })?;
        let start = ctx.spec.mission.start;
        let mut reasoner = LanguageReasoner::load(&store, &file, brief, config)
            .map_err(|e| RoleError::Config(format!("reasoning/{variant}: {e}")))?;
        // warm-up: the first decision pays for page faults and graph allocation
        // (on a copy of the planner: the flight's own starts at the first subgoal)
        let plan = DecisionView::from_decision(&planner.clone().decide(start, 0.0, true, None));
        let warm = Observation {
            position: start,
            yaw: 0.0,
            landed: true,
            state: None,
            previous: None,
            plan: Some(&plan),
        };
        reasoner
            .decide(&warm)
            .map_err(|e| RoleError::Config(format!("reasoning/{variant} warm-up: {e}")))?;
        // started during a flight (restart, hot swap): take the mission up where it is
        if let Some(step) = hub_active_step(ctx, RESUME_WAIT)? {
            planner.resume(step);
        }
        Ok(Self {
            reasoner,
            planner,
            states: ctx.bus.subscriber(topics::PERCEPTION_STATE)?,
            telemetry: ctx.bus.subscriber(topics::VEHICLE_TELEMETRY)?,
            decisions: ctx.bus.publisher(topics::REASONING_DECISION)?,
            clock: HeartbeatClock::new(
                ctx.spec.timing.heartbeat_period_ms.max(1) * 1_000_000,
                monotonic_ns(),
            ),
            state: None,
            fresh_state: false,
            telemetry_last: None,
            previous: None,
            start,
            seq: 0,
            cycle: 0,
            failures: 0,
            source: ctx.spec.instance,
            show_plan,
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
        let t0 = monotonic_ns();
        self.read_inputs()?;
        let Some(basis) = self.clock.due(t0, self.fresh_state) else {
            return Ok(CycleOutcome::Idle);
        };
        self.fresh_state = false;
        self.clock.decided(t0);
        // a decision on telemetry alone does not show the model an old view
        let state = match basis {
            Basis::State => self.state.as_deref(),
            Basis::TelemetryOnly => None,
        };
        let (position, yaw, landed) = match (&self.telemetry_last, &self.state) {
            (Some(t), _) => (t.position, t.attitude[2], t.landed == 1),
            (None, Some(s)) => (s.position, s.yaw, s.position[2] < 0.3),
            (None, None) => (self.start, 0.0, true),
        };
        let plan = DecisionView::from_decision(&self.planner.decide(position, yaw, landed, state));
        let obs = Observation {
            position,
            yaw,
            landed,
            state,
            previous: self.previous.as_ref(),
            plan: self.show_plan.then_some(&plan),
        };
        let reasoning_start = monotonic_ns();
        report.stage("read", reasoning_start - t0);
        let thought = match self.reasoner.decide(&obs) {
            Ok(t) => t,
            Err(e) => {
                // no decision this heartbeat: the hub reuses the last valid one
                self.failures += 1;
                report.counters[3] = self.failures;
                eprintln!("reasoning: no decision this heartbeat: {e}");
                return Ok(CycleOutcome::Worked);
            }
        };
        report.stage("prompt", (thought.prompt_s * 1e9) as u64);
        report.stage("generate", (thought.generate_s * 1e9) as u64);
        let mut d = thought.decision;
        self.cycle += 1;
        self.seq += 1;
        d.seq = self.seq;
        d.cycle = self.cycle;
        d.source = self.source;
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
        let tp = monotonic_ns();
        d.publish_ns = tp;
        self.decisions.publish(&d)?;
        report.stage("publish", monotonic_ns() - tp);
        report.counters[0] = self.seq;
        report.counters[1] = (thought.tokens_per_s() * 100.0) as u64;
        report.counters[2] = thought.generated_tokens as u64;
        report.counters[3] = self.failures;
        report.counters[4] = thought.reused_tokens as u64;
        report.counters[5] = thought.prompt_tokens as u64;
        report.counters[6] = thought.drafted_tokens as u64;
        report.counters[7] = u64::from(thought.view.step != plan.step);
        self.previous = Some(thought.view);
        Ok(CycleOutcome::Worked)
    }
}
