//! Reasoning role, language-model variants (kind `reasoning`, variants `smollm2`, `gemma3`,
//! and `smollm2-aligned`: SmolLM2 with its task-aligned adapter, reading the aligned prompt):
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
//! the telemetry alone when no S_t came for a heartbeat and a half ([`ReasonerIo`], shared
//! with the planner's variants). The model is loaded and warmed up (one decision) in `new`,
//! before the first heartbeat, so a swapped-in reasoner is ready when the supervisor sees it.
//!
//! Parameters: `model` (cache-relative GGUF, default per variant), `threads` (default 2, at most the CPUs of its executor),
//! `context_tokens` (default 2048), `models_dir`, `plan` (bool, default true; false leaves
//! the planner's plan out of the prompt: the generic model on its own, the evaluation's
//! zero-shot ablation), `prompt` (`planned`, the default, or `aligned`: the task-aligned
//! models' short prompt, [`aeris_llm::aligned_prompt`], which never shows the plan),
//! `adapter` (a cache-relative LoRA GGUF, with `prompt = aligned` only: the task-aligned model
//! `scripts/train-reasoner.sh` made for this base, hash-checked like every model),
//! `distill` (a file path, with `prompt = aligned` only: every heartbeat the student's
//! observation is written there as a training pair labelled with the planner's decision for
//! it, a DAgger round; [`crate::distill`]).
//! Heartbeat stages: `read`, `prompt` (evaluating the new prompt tokens), `generate`,
//! `publish`; the cycle latency is the decision latency. Counters:
//! [`aeris_schemas::LanguageCounters`].

/// Where this role's heartbeat says how long its last decision's stages took (see the
/// module docs): stage names, read by `aeris bench cycle`.
pub mod heartbeat {
    /// Stage: evaluating the new prompt tokens.
    pub const PROMPT_STAGE: &str = "prompt";
    /// Stage: generating.
    pub const GENERATE_STAGE: &str = "generate";
}

use crate::distill::{DISTILL_PARAM, DistillWriter, StudentView};
use crate::planner::{Planner, mission_planner};
use crate::reasoner_io::ReasonerIo;
use crate::vision::open_store;
use aeris_llm::{DecisionView, LanguageReasoner, Observation, PromptStyle, ReasonerConfig};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::error_chain::chain;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{Decision, LanguageCounters};
use core::time::Duration;

pub use crate::reasoner_io::{POLL, mission_brief};

/// The language-model reasoning role.
pub struct LanguageRole {
    reasoner: LanguageReasoner,
    planner: Planner,
    io: ReasonerIo,
    previous: Option<DecisionView>,
    failures: u64,
    /// Whether the prompt shows the planner's plan.
    show_plan: bool,
    /// With the aligned prompt: what the student sees (its memory included).
    student: Option<StudentView>,
    /// Training pairs of the student's observations, labelled by the planner.
    distill: Option<DistillWriter>,
}

impl Role for LanguageRole {
    type Kind = kinds::Reasoning;

    fn new(ctx: &mut RoleContext<kinds::Reasoning>) -> Result<Self, RoleError> {
        let variant = ctx.spec.variant.clone();
        let file = ctx
            .spec
            .param_str("model")
            .or(aeris_llm::variant_model(&variant))
            .ok_or_else(|| ConfigError::NoModel(variant.clone()))?
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
            // bound to a `cuda:N` executor: every layer on that GPU (a build without offload,
            // or a machine without the device, stops the role with the reason)
            accelerator: crate::vision::accelerator(ctx)?,
            prompt: match ctx.spec.param_str("prompt") {
                // an aligned variant reads the prompt its adapter was trained on
                None if aeris_llm::variant_adapter(&variant).is_some() => PromptStyle::Aligned,
                None => PromptStyle::Planned,
                Some(name) => PromptStyle::from_name(name).ok_or_else(|| {
                    RoleError::param("prompt", format!("must be planned or aligned, got {name}"))
                })?,
            },
            ..ReasonerConfig::default()
        };
        let aligned = config.prompt == PromptStyle::Aligned;
        // the aligned prompt never shows the plan
        let show_plan = ctx.spec.param_bool("plan", true)? && !aligned;
        let student = aligned.then(|| StudentView::new(&ctx.spec)).transpose()?;
        let adapter = ctx
            .spec
            .param_str("adapter")
            .or(aeris_llm::variant_adapter(&variant))
            .map(str::to_string);
        if adapter.is_some() && !aligned {
            return Err(RoleError::param(
                "adapter",
                "needs prompt = aligned (an adapter is trained on the aligned prompt)",
            ));
        }
        let distill = DistillWriter::from_spec(&ctx.spec)?;
        if distill.is_some() && !aligned {
            return Err(RoleError::param(
                DISTILL_PARAM,
                "needs prompt = aligned (training pairs are written in the aligned prompt)",
            ));
        }
        let store = open_store(ctx)?;
        let brief = mission_brief(&ctx.spec.mission)?;
        let mut planner = mission_planner(&ctx.spec)?;
        let start = ctx.spec.mission.start;
        let threads = config.threads;
        let mut reasoner =
            LanguageReasoner::load_adapted(&store, &file, adapter.as_deref(), brief, config)
                .map_err(|e| {
                    RoleError::step(format!("loading reasoning/{variant} from {file}"), e)
                })?;
        // warm-up: the first decision pays for page faults and graph allocation
        // (on a copy of the planner: the flight's own starts at the first subgoal)
        let plan = DecisionView::from_decision(&planner.clone().decide(start, 0.0, true, None));
        let warm = Observation {
            position: start,
            yaw: 0.0,
            landed: true,
            state: None,
            previous: None,
            plan: show_plan.then_some(&plan),
            sighted: &[],
        };
        let (wall, cpu) = (
            aeris_runtime::clock::wall_ns(),
            aeris_runtime::clock::process_cpu_ns(),
        );
        reasoner
            .decide(&warm)
            .map_err(|e| RoleError::step(format!("warming up reasoning/{variant}"), e))?;
        let warm_up =
            std::time::Duration::from_nanos(aeris_runtime::clock::wall_ns().saturating_sub(wall));
        let decision = warm_up_decision_time(
            warm_up,
            aeris_runtime::clock::process_cpu_ns().saturating_sub(cpu),
            threads,
        );
        tracing::info!(
            "reasoning/{variant}: warmed up in {:.0} ms; a decision takes about {:.0} ms on its CPUs",
            warm_up.as_secs_f64() * 1e3,
            decision.as_secs_f64() * 1e3
        );
        // started during a flight (restart, hot swap): take the mission up where it is, on
        // a first S_t it can decide on within the deadline
        let io = ReasonerIo::new(ctx, &mut planner, decision)?;
        Ok(Self {
            reasoner,
            planner,
            io,
            previous: None,
            failures: 0,
            show_plan,
            student,
            distill,
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
        let Some(due) = self.io.poll()? else {
            return Ok(CycleOutcome::Idle);
        };
        // a decision on telemetry alone does not show the model an old view
        let state = self.io.state(&due);
        let (position, yaw, landed) = (due.position, due.yaw, due.landed);
        let planned = self.planner.decide(position, yaw, landed, state);
        let plan = DecisionView::from_decision(&planned);
        let sighted = self
            .student
            .as_ref()
            .map(|v| v.sighted(state))
            .unwrap_or_default();
        let obs = match &self.student {
            Some(view) => view.observation(&due, state, &sighted),
            None => Observation {
                position,
                yaw,
                landed,
                state,
                previous: self.previous.as_ref(),
                plan: self.show_plan.then_some(&plan),
                sighted: &[],
            },
        };
        if let (Some(writer), Some(view)) = (&mut self.distill, &self.student) {
            // the planner labels the state the student reached
            writer.write(view.brief(), &obs, &planned)?;
        }
        let reasoning_start = monotonic_ns();
        report.stage("read", reasoning_start - due.poll_ns);
        let thought = match self.reasoner.decide(&obs) {
            Ok(t) => t,
            Err(e) => {
                // no decision this heartbeat: the hub reuses the last valid one
                self.failures += 1;
                let mut c = LanguageCounters::from_heartbeat(&report.counters);
                c.failures = self.failures;
                report.counters = c.to_heartbeat();
                tracing::warn!("reasoning: no decision this heartbeat: {}", chain(&e));
                return Ok(CycleOutcome::Worked);
            }
        };
        report.stage(heartbeat::PROMPT_STAGE, (thought.prompt_s * 1e9) as u64);
        report.stage(heartbeat::GENERATE_STAGE, (thought.generate_s * 1e9) as u64);
        // the model's decision carries no numbering: the I/O gives it the next
        let mut d = Decision {
            seq: 0,
            ..thought.decision
        };
        self.io.stamp(&mut d, &due, reasoning_start);
        self.io.publish(&mut d, report)?;
        report.counters = LanguageCounters {
            decisions: self.io.published(),
            tokens_per_s_x100: (thought.tokens_per_s() * 100.0) as u64,
            generated_tokens: thought.generated_tokens as u64,
            failures: self.failures,
            reused_prompt_tokens: thought.reused_tokens as u64,
            prompt_tokens: thought.prompt_tokens as u64,
            drafted_tokens: thought.drafted_tokens as u64,
            departed_from_plan: u64::from(thought.view.step != plan.step),
        }
        .to_heartbeat();
        match &mut self.student {
            Some(view) => view.decided(thought.view),
            None => self.previous = Some(thought.view),
        }
        Ok(CycleOutcome::Worked)
    }
}

/// What a decision takes when the reasoner has its CPUs, from the warm-up's: its CPU time
/// over its threads (llama.cpp's workers compute or spin for the whole decision), at most
/// its wall time. A hot-swapped reasoner warms up under SCHED_IDLE, where the wall time
/// also counts the time it waited for a CPU (measured under two busy threads: Gemma-3
/// 2.0-4.8 s of wall time for a decision that takes ~0.9 s).
fn warm_up_decision_time(wall: Duration, cpu_ns: u64, threads: i32) -> Duration {
    let on_cpus = Duration::from_nanos(cpu_ns / threads.max(1) as u64);
    if cpu_ns == 0 { wall } else { on_cpus.min(wall) }
}
