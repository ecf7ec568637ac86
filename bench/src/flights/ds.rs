//! `aeris bench ds`: the closed loop under a standard interference scenario, flown three
//! times — re-binding and the variant ladder (the runtime's default), re-binding alone, and
//! neither. Partway through each flight a CPU hog (busy processes pinned to the CPUs of the
//! role with the highest latency, the heaviest) lands; the figures are taken over the cycles
//! from the hog's landing to the end.

use super::{
    BusyProcesses, FlightBenchConfig, FlightBenchError, flight_name_and_dir, load_workflow,
    with_variants_and_ladder,
};
use aeris_flight::{
    CycleTrace, Flight, FlightWatcher, HookError, Overrides, StepContext, StepHook, StopRule,
};
use aeris_orchestrator::ladder::StepDirection;
use aeris_orchestrator::supervisor::SupervisorEvent;
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::{mean_std, percentile};
use aeris_schemas::RoleKind;
use serde::Serialize;

/// Settings of `aeris bench ds`.
#[derive(Debug, Clone)]
pub struct DsConfig {
    /// Semantic heartbeats per flight (committed or reused cycles).
    pub heartbeats: u64,
    /// Heartbeats flown before the hog lands.
    pub hog_after: u64,
    /// Busy processes of the hog, all pinned to the heaviest role's CPUs.
    pub hog_threads: usize,
    /// The flights (a run directory gets `ds-ladder/`, `ds-on/` and `ds-off/` under it).
    pub flight: FlightBenchConfig,
}

/// One flight of the scenario.
#[derive(Debug, Clone, Serialize)]
pub struct DsRun {
    /// Mean cycle time over the committed cycles after the hog landed (s); `None` (JSON
    /// null) when none committed: a cycle time of 0 would read as a perfect one.
    pub ct_mean_s: Option<f64>,
    /// Its 95th percentile (s); `None` when no cycle committed.
    pub ct_p95_s: Option<f64>,
    /// Execution error rate over those cycles (reused / all).
    pub eer: f64,
    /// Automatic live moves after the hog landed.
    pub migrations: u64,
    /// Steps down the variant ladder in the whole flight, before the hog landed too (a
    /// model that does not fit its executor steps down whatever the hog does; always 0
    /// without the ladder).
    pub variant_steps_down: u64,
    /// From the hog's landing to the first completed automatic move (ms); `None` without one.
    pub slip_to_migrated_ms: Option<f64>,
    /// The role the hog landed on, and its CPUs then.
    pub hogged_role: String,
    /// CPUs the hog ran on.
    pub hog_cpus: String,
    /// Cycles measured (after the hog landed).
    pub cycles: usize,
    /// Every move and variant step of the flight (initial binding included), as printed.
    pub moves: Vec<String>,
}

/// `aeris bench ds --json`.
#[derive(Debug, Serialize)]
pub struct DsReport {
    /// Dynamic scheduling (re-binding) and the variant ladder on: the runtime's default.
    pub ds_ladder: DsRun,
    /// Dynamic scheduling (re-binding) on, the variant ladder off.
    pub ds_on: DsRun,
    /// Both off.
    pub ds_off: DsRun,
}

/// Which adaptation a flight of the scenario has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DsMode {
    /// Re-binding and the variant ladder (a model role that no executor holds within its
    /// budget steps down to a lighter variant): what `aeris run` flies by default.
    Ladder,
    /// Re-binding (live moves between executors) alone, every role on its declared variant.
    Rebinding,
    /// Neither: every role stays where it was bound at start, on its declared variant.
    Off,
}

impl DsMode {
    /// The flight's tag (its run directory and name).
    pub fn tag(self) -> &'static str {
        match self {
            DsMode::Ladder => "ds-ladder",
            DsMode::Rebinding => "ds-on",
            DsMode::Off => "ds-off",
        }
    }

    /// Roles move live between executors (dynamic scheduling on).
    pub fn rebinds(self) -> bool {
        self != DsMode::Off
    }

    /// The variant ladder steps model roles down and up.
    pub fn steps_variants(self) -> bool {
        self == DsMode::Ladder
    }
}

fn workflow(config: &FlightBenchConfig, mode: DsMode) -> Result<Workflow, FlightBenchError> {
    let mut w = load_workflow(config)?;
    // the built-in model flight runs its reasoner on every CPU, where a hog on "its
    // executor" leaves nowhere to go: bind it to the perception executor instead
    if config.workflow.is_none()
        && let Some(r) = w.roles.iter_mut().find(|r| r.kind == RoleKind::Reasoning)
    {
        r.executor = Some("perception".into());
    }
    // the ladder answers the hog with a lighter reasoner: only in its own flight, so the
    // other two show re-binding's figures alone
    with_variants_and_ladder(w, config, mode.steps_variants())
}

/// The step hook: lands the hog once enough heartbeats flew, and records the moves.
struct HogScenario {
    hog_after: u64,
    hog_threads: usize,
    hog: Option<BusyProcesses>,
    /// When the hog landed, and the trace's length then.
    landed: Option<(u64, usize)>,
    hogged_role: String,
    hog_cpus: String,
    first_move_ns: Option<u64>,
    migrations: u64,
    variant_steps_down: u64,
    moves: Vec<String>,
}

impl StepHook for HogScenario {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        for e in ctx.events {
            if let SupervisorEvent::RoleMigrated(m) = e {
                self.moves.push(e.to_string());
                if let Some((at, _)) = self.landed
                    && m.trigger.is_some()
                {
                    self.migrations += 1;
                    self.first_move_ns
                        .get_or_insert(m.done_ns.saturating_sub(at));
                }
            }
            if let SupervisorEvent::VariantStepped { direction, .. } = e {
                self.moves.push(e.to_string());
                if *direction == StepDirection::Down {
                    self.variant_steps_down += 1;
                }
            }
        }
        if self.hog.is_none() && ctx.monitor.cycles() >= self.hog_after {
            // the heaviest role: the highest p50 latency among the roles with a budget
            let heaviest = ctx
                .supervisor
                .roles()
                .iter()
                .filter(|r| r.budget_ms().is_some() && !r.cpus().is_empty())
                .filter_map(|r| Some((r.latency_ms()?[0], r)))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, r)| r);
            if let Some(r) = heaviest
                && let Ok(set) = CpuSet::parse(r.cpus())
            {
                self.hogged_role = r.name().to_string();
                self.hog_cpus = set.to_string();
                ctx.note(format!(
                    "bench ds: hog of {} busy processes lands on CPUs {set} (role `{}`)",
                    self.hog_threads,
                    r.name()
                ));
                self.hog = Some(BusyProcesses::start(Some(&set), self.hog_threads)?);
                self.landed = Some((monotonic_ns(), ctx.monitor.trace().len()));
            }
        }
        Ok(false)
    }
}

fn fly_once(
    config: &DsConfig,
    mode: DsMode,
    watcher: &mut dyn FlightWatcher,
) -> Result<DsRun, FlightBenchError> {
    let mut w = workflow(&config.flight, mode)?;
    let period_s = w.timing.heartbeat_period_ms as f64 / 1000.0;
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max(config.heartbeats as f64 * period_s * 4.0 + 60.0);
    let tag = mode.tag();
    let (name, run_dir) =
        flight_name_and_dir(tag, config.flight.run_dir.as_ref().map(|d| d.join(tag)));
    let scenario = HogScenario {
        hog_after: config.hog_after,
        hog_threads: config.hog_threads,
        hog: None,
        landed: None,
        hogged_role: String::new(),
        hog_cpus: String::new(),
        first_move_ns: None,
        migrations: 0,
        variant_steps_down: 0,
        moves: Vec::new(),
    };
    let (outcome, mut scenario) = Flight::builder(w)
        .name(name)
        .language_offload_check(aeris_llm::offload_check)
        .run_dir(run_dir)
        .stop_when(StopRule::Cycles(config.heartbeats))
        .overrides(Overrides {
            dynamic: Some(mode.rebinds()),
            ..Overrides::default()
        })
        .step_hook(scenario)
        .start()?
        .watch(watcher)?;
    drop(scenario.hog.take());
    if let Some(failure) = outcome.failure {
        return Err(FlightBenchError::EndedEarly {
            bench: format!("bench ds ({tag})"),
            failure,
        });
    }
    let Some((_, from)) = scenario.landed else {
        return Err(FlightBenchError::HogNeverLanded { run: tag });
    };
    let after: &[CycleTrace] = outcome.trace.get(from..).unwrap_or(&[]);
    let ct: Vec<f64> = after
        .iter()
        .filter(|c| c.committed)
        .map(|c| c.ct_s)
        .collect();
    let reused = after.iter().filter(|c| c.reused).count();
    Ok(DsRun {
        ct_mean_s: mean_std(&ct).map(|(m, _)| m),
        ct_p95_s: percentile(&ct, 95.0),
        eer: if after.is_empty() {
            0.0
        } else {
            reused as f64 / after.len() as f64
        },
        migrations: scenario.migrations,
        variant_steps_down: scenario.variant_steps_down,
        slip_to_migrated_ms: scenario.first_move_ns.map(|ns| ns as f64 / 1e6),
        hogged_role: scenario.hogged_role,
        hog_cpus: scenario.hog_cpus,
        cycles: after.len(),
        moves: scenario.moves,
    })
}

/// Fly the scenario with re-binding and the ladder, with re-binding alone, then with
/// neither; `watcher` gets every event of the three flights (the hog's landing as
/// [`aeris_flight::FlightEvent::Note`]).
pub fn run(
    config: &DsConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<DsReport, FlightBenchError> {
    if config.heartbeats <= config.hog_after {
        return Err(FlightBenchError::Settings(
            "heartbeats must be more than hog_after".into(),
        ));
    }
    if config.hog_threads == 0 {
        return Err(FlightBenchError::Settings(
            "hog threads must be at least 1".into(),
        ));
    }
    let ds_ladder = fly_once(config, DsMode::Ladder, watcher)?;
    let ds_on = fly_once(config, DsMode::Rebinding, watcher)?;
    let ds_off = fly_once(config, DsMode::Off, watcher)?;
    Ok(DsReport {
        ds_ladder,
        ds_on,
        ds_off,
    })
}
