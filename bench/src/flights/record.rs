//! `aeris bench record`: what recording costs a flight. The default flight and the model
//! flight, each without and with the recorder (every frame exact, LZ4), side by side in one
//! run: controller missed ticks (must stay 0), cycle time, EER, the recorder's CPU, MB per
//! minute and samples dropped; optionally beside `outside_load` busy threads that are not
//! part of the flight.

use super::{BusyProcesses, FlightBenchError, flight_name_and_dir};
use aeris_flight::{Flight, FlightWatcher, HookError, StepContext, StepHook, StopRule};
use aeris_orchestrator::executors::process_sched_time;
use aeris_orchestrator::workflow::Workflow;
use aeris_schemas::RoleKind;
use serde::Serialize;

/// Settings of `aeris bench record`.
#[derive(Debug, Clone)]
pub struct RecordBenchConfig {
    /// Semantic heartbeats each flight flies.
    pub heartbeats: u64,
    /// Busy processes started outside the flight (unpinned, normal priority) for the whole run.
    pub outside_load: usize,
    /// Also the model flight (workflows/models.toml), not only the default one.
    pub models: bool,
}

/// One flight of the benchmark.
#[derive(Debug, Clone, Serialize)]
pub struct RecordRow {
    /// `default` or `models`.
    pub workflow: String,
    /// Recorded or not.
    pub recorded: bool,
    /// Semantic cycles flown.
    pub cycles: u64,
    /// Controller ticks that missed their deadline.
    pub controller_missed_ticks: u64,
    /// Mean cycle time (s).
    pub ct_mean_s: f64,
    /// 95th percentile of it (s).
    pub ct_p95_s: f64,
    /// Execution error rate.
    pub eer: f64,
    /// The recorder process's CPU over the flight, in % of one core.
    pub recorder_cpu_percent: Option<f64>,
    /// Recording size per minute of flight (MB = 10^6 bytes).
    pub mb_per_minute: Option<f64>,
    /// Samples the recorder dropped.
    pub dropped: Option<u64>,
    /// Flight duration (s).
    pub duration_s: f64,
}

/// `aeris bench record --json`.
#[derive(Debug, Clone, Serialize)]
pub struct RecordBenchReport {
    /// Busy processes outside the flight.
    pub outside_load: usize,
    /// One row per flight.
    pub rows: Vec<RecordRow>,
}

/// Samples the recorder's CPU time (every thread's time on a CPU) while it runs.
#[derive(Default)]
struct RecorderCpu {
    pid: Option<u32>,
    first: Option<(u64, std::time::Instant)>,
    last: Option<(u64, std::time::Instant)>,
}

impl StepHook for RecorderCpu {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        let pid = ctx
            .supervisor
            .roles()
            .iter()
            .find(|r| r.kind() == RoleKind::Recorder)
            .and_then(|r| r.pid());
        if let Some(pid) = pid
            && let Some(t) = process_sched_time(pid)
        {
            if self.pid != Some(pid) {
                self.pid = Some(pid);
                self.first = Some((t.run_ns, std::time::Instant::now()));
            }
            self.last = Some((t.run_ns, std::time::Instant::now()));
        }
        Ok(false)
    }
}

impl RecorderCpu {
    fn percent(&self) -> Option<f64> {
        let ((r0, i0), (r1, i1)) = (self.first?, self.last?);
        let wall = i1.duration_since(i0).as_secs_f64();
        (wall > 0.0).then(|| r1.saturating_sub(r0) as f64 * 1e-9 / wall * 100.0)
    }
}

/// Fly the benchmark's flights one after the other; `watcher` gets every event.
pub fn run(
    config: &RecordBenchConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<RecordBenchReport, FlightBenchError> {
    if config.heartbeats == 0 {
        return Err(FlightBenchError::Settings(
            "heartbeats must be at least 1".into(),
        ));
    }
    let mut workflows = vec![(
        "default",
        Workflow::builtin_default().map_err(FlightBenchError::BuiltinWorkflow)?,
    )];
    if config.models {
        workflows.push((
            "models",
            Workflow::builtin_models().map_err(FlightBenchError::BuiltinWorkflow)?,
        ));
    }
    let _load = BusyProcesses::start(None, config.outside_load)?;
    let mut rows = Vec::new();
    for (label, workflow) in workflows {
        for recorded in [false, true] {
            let mut w = workflow.clone();
            let period_s = w.timing.heartbeat_period_ms as f64 / 1000.0;
            w.mission.max_duration_s = w
                .mission
                .max_duration_s
                .max(config.heartbeats as f64 * period_s * 3.0 + 60.0);
            let tag = format!("record-{label}-{}", if recorded { "on" } else { "off" });
            let (name, run_dir) = flight_name_and_dir(&tag, None);
            let mut builder = Flight::builder(w)
                .name(name)
                .language_offload_check(aeris_llm::offload_check)
                .run_dir(run_dir)
                .stop_when(StopRule::Cycles(config.heartbeats));
            if recorded {
                builder = builder.record("flight.mcap");
            }
            let (outcome, cpu) = builder
                .step_hook(RecorderCpu::default())
                .start()?
                .watch(watcher)?;
            if let Some(failure) = outcome.failure {
                return Err(FlightBenchError::EndedEarly {
                    bench: format!("bench record ({tag})"),
                    failure,
                });
            }
            let s = outcome.summary;
            let minutes = s.duration_s / 60.0;
            let size = s.recording.as_ref().map(|r| {
                r.files
                    .iter()
                    .filter_map(|f| std::fs::metadata(f).ok())
                    .map(|m| m.len())
                    .sum::<u64>()
            });
            rows.push(RecordRow {
                workflow: label.to_string(),
                recorded,
                cycles: s.cycles,
                controller_missed_ticks: s.controller_missed_ticks,
                ct_mean_s: s.ct_mean_s,
                ct_p95_s: s.ct_p95_s,
                eer: s.eer,
                recorder_cpu_percent: if recorded { cpu.percent() } else { None },
                mb_per_minute: size
                    .filter(|_| minutes > 0.0)
                    .map(|b| b as f64 / 1e6 / minutes),
                dropped: s.recording.as_ref().map(|r| r.dropped),
                duration_s: s.duration_s,
            });
        }
    }
    Ok(RecordBenchReport {
        outside_load: config.outside_load,
        rows,
    })
}
