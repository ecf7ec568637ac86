//! `aeris bench swap`: hot swaps of one role during the model flight, make-before-break:
//! per swap the time to ready and to done, the heartbeats without a fresh decision and the
//! longest interval between hub setpoints from its start to one heartbeat after its end.

use super::cycle::{DecisionCost, DecisionLog};
use super::{
    BusyProcesses, FlightBenchConfig, FlightBenchError, flight_name_and_dir, load_workflow,
    no_role, with_variants,
};
use aeris_flight::{Flight, FlightWatcher, HookError, StepContext, StepHook, StopRule};
use aeris_orchestrator::supervisor::{DEFAULT_SWAP_READY_TIMEOUT, SupervisorEvent};
use aeris_runtime::clock::monotonic_ns;
use serde::Serialize;
use std::time::{Duration, Instant};

/// Settings of `aeris bench swap`.
#[derive(Debug, Clone)]
pub struct SwapConfig {
    /// Swaps to make.
    pub swaps: u32,
    /// Role to swap.
    pub role: String,
    /// Variants to swap to, in turn (empty: the role's pool, the running one last).
    pub variants: Vec<String>,
    /// Seconds of flight between the end of one swap and the start of the next.
    pub every_s: f64,
    /// The flight.
    pub flight: FlightBenchConfig,
}

/// One swap of `aeris bench swap`.
#[derive(Debug, Clone, Serialize)]
pub struct SwapRow {
    /// Variant replaced.
    pub from: String,
    /// Variant brought in.
    pub to: String,
    /// The new process (its decisions carry this pid), if it started.
    pub pid: Option<u32>,
    /// `true` when it completed (the old process exited).
    pub done: bool,
    /// From the swap's start to the new process's first heartbeat after warm-up (ms).
    pub ready_ms: f64,
    /// From the swap's start to the old process's exit (ms).
    pub done_ms: f64,
    /// Heartbeats without a fresh valid decision from the swap's start to one heartbeat
    /// and one decision deadline after it ended.
    pub missed_heartbeats: u64,
    /// Decisions the hub received late in that window (past the deadline; either process's).
    pub late_decisions: u64,
    /// Decisions the hub rejected in that window (late ones included).
    pub rejected_decisions: u64,
    /// Longest interval between hub setpoints in that window (ms).
    pub max_setpoint_gap_ms: f64,
    /// Why it failed, if it did.
    pub error: Option<String>,
}

/// `aeris bench swap --json`.
#[derive(Debug, Serialize)]
pub struct SwapReport {
    /// Role swapped.
    pub role: String,
    /// Swaps completed.
    pub swaps: u32,
    /// Swaps that failed (rolled back).
    pub swaps_failed: u32,
    /// Heartbeats missed during all swap windows.
    pub missed_heartbeats: u64,
    /// Heartbeats missed in the whole flight, swap windows or not.
    pub flight_missed_heartbeats: u64,
    /// Longest setpoint interval during any swap window (ms).
    pub max_setpoint_gap_ms: f64,
    /// Median setpoint interval over the whole flight (ms): the normal period.
    pub setpoint_period_ms: f64,
    /// Longest setpoint interval over the whole flight (ms).
    pub flight_max_setpoint_gap_ms: f64,
    /// One row per swap.
    pub rows: Vec<SwapRow>,
    /// Busy processes outside the flight during the run.
    pub outside_load: usize,
    /// How the roles got priority over them (`cgroup-v2`, `cgroup-v1`, `nice`, `none`).
    pub priority: String,
    /// The same in words.
    pub priority_detail: String,
    /// What each language-model decision of the flight cost, either side of every swap (a
    /// row's `pid` names its new process): which side's decision was slow, and in which part.
    pub decisions: Vec<DecisionCost>,
}

/// Cycles the flight completes before the first swap: the start, with every model's first
/// inference, is not what a swap is measured against.
const STEADY_CYCLES: u64 = 3;

/// Where the swap schedule is.
enum Phase {
    /// Flying until the next swap is due.
    Waiting { since: Instant },
    /// A swap under way.
    Swapping {
        row: SwapRow,
        started: Instant,
        start_ns: u64,
        at_start: [u64; 3],
    },
    /// The swap ended; its window stays open one heartbeat longer.
    Settling {
        row: SwapRow,
        start_ns: u64,
        until: Instant,
        at_start: [u64; 3],
    },
}

/// The step hook: starts the swaps in turn and measures each.
struct SwapSchedule {
    role: String,
    /// Variants to swap to, in turn.
    cycle: Vec<String>,
    next: usize,
    /// The variant running now.
    current: String,
    every: Duration,
    /// How long a window stays open after its swap ended: one heartbeat plus the decision
    /// deadline, the longest the hub waits before it counts a heartbeat without a decision
    /// (a swap's miss shows by then).
    settle: Duration,
    swaps: usize,
    phase: Phase,
    rows: Vec<SwapRow>,
    /// Longest and median setpoint interval over the whole flight (ms).
    flight_gaps: (f64, f64),
    decisions: DecisionLog,
}

impl StepHook for SwapSchedule {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        let monitor = ctx.monitor;
        self.decisions.observe(ctx.supervisor);
        self.flight_gaps = monitor.setpoint_gaps_ms(0, u64::MAX);
        let waiting = Phase::Waiting {
            since: Instant::now(),
        };
        self.phase = match std::mem::replace(&mut self.phase, waiting) {
            // swaps start once the flight is in its steady state (decisions committed)
            Phase::Waiting { since }
                if since.elapsed() >= self.every && monitor.cycles() >= STEADY_CYCLES =>
            {
                let to = self.cycle[self.next % self.cycle.len()].clone();
                self.next += 1;
                let mut row = SwapRow {
                    from: self.current.clone(),
                    to: to.clone(),
                    pid: None,
                    done: false,
                    ready_ms: 0.0,
                    done_ms: 0.0,
                    missed_heartbeats: 0,
                    late_decisions: 0,
                    rejected_decisions: 0,
                    max_setpoint_gap_ms: 0.0,
                    error: None,
                };
                let start_ns = monotonic_ns();
                let at_start = [monitor.reused(), monitor.late(), monitor.rejected()];
                match ctx
                    .supervisor
                    .begin_swap(&self.role, &to, DEFAULT_SWAP_READY_TIMEOUT)
                {
                    Ok(pid) => {
                        row.pid = Some(pid);
                        ctx.note(format!("bench swap: {} -> {to} (pid {pid})", row.from));
                        Phase::Swapping {
                            row,
                            started: Instant::now(),
                            start_ns,
                            at_start,
                        }
                    }
                    Err(e) => {
                        row.error = Some(e.to_string());
                        self.rows.push(row);
                        Phase::Waiting {
                            since: Instant::now(),
                        }
                    }
                }
            }
            Phase::Swapping {
                mut row,
                started,
                start_ns,
                at_start,
            } => {
                let mut ended = false;
                for event in ctx.events {
                    match event {
                        SupervisorEvent::SwapReady { name, .. } if *name == self.role => {
                            row.ready_ms = started.elapsed().as_secs_f64() * 1e3;
                        }
                        SupervisorEvent::SwapDone { name, .. } if *name == self.role => {
                            row.done = true;
                            row.done_ms = started.elapsed().as_secs_f64() * 1e3;
                            self.current = row.to.clone();
                            ended = true;
                        }
                        SupervisorEvent::SwapFailed { name, reason, .. } if *name == self.role => {
                            row.error = Some(reason.clone());
                            ended = true;
                        }
                        _ => {}
                    }
                }
                if ended {
                    Phase::Settling {
                        row,
                        start_ns,
                        until: Instant::now() + self.settle,
                        at_start,
                    }
                } else {
                    Phase::Swapping {
                        row,
                        started,
                        start_ns,
                        at_start,
                    }
                }
            }
            Phase::Settling {
                mut row,
                start_ns,
                until,
                at_start,
            } if Instant::now() >= until => {
                row.missed_heartbeats = monitor.reused().saturating_sub(at_start[0]);
                row.late_decisions = monitor.late().saturating_sub(at_start[1]);
                row.rejected_decisions = monitor.rejected().saturating_sub(at_start[2]);
                row.max_setpoint_gap_ms = monitor.setpoint_gaps_ms(start_ns, monotonic_ns()).0;
                ctx.note(format!(
                    "bench swap: {} -> {}: {} ({:.0} ms to ready, {:.0} ms to done), {} missed heartbeats, longest setpoint gap {:.1} ms",
                    row.from,
                    row.to,
                    if row.done { "done" } else { "FAILED" },
                    row.ready_ms,
                    row.done_ms,
                    row.missed_heartbeats,
                    row.max_setpoint_gap_ms
                ));
                self.rows.push(row);
                Phase::Waiting {
                    since: Instant::now(),
                }
            }
            other => other,
        };
        Ok(self.rows.len() >= self.swaps)
    }
}

/// Fly the benchmark; `watcher` gets every event of the flight (the swaps' lines as
/// [`aeris_flight::FlightEvent::Note`]).
pub fn run(
    config: &SwapConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<SwapReport, FlightBenchError> {
    if config.swaps == 0 {
        return Err(FlightBenchError::Settings(
            "swaps must be at least 1".into(),
        ));
    }
    if !(config.every_s.is_finite() && config.every_s >= 0.0) {
        return Err(FlightBenchError::Settings(
            "the time between swaps must be a number of seconds >= 0".into(),
        ));
    }
    let mut w = with_variants(load_workflow(&config.flight)?, &config.flight)?;
    let decl = w
        .roles
        .iter()
        .find(|r| r.name == config.role)
        .ok_or_else(|| no_role(&w, &config.role))?;
    let mut cycle: Vec<String> = if config.variants.is_empty() {
        let mut pool: Vec<String> = decl
            .variants
            .iter()
            .filter(|v| **v != decl.variant)
            .cloned()
            .collect();
        pool.push(decl.variant.clone());
        pool
    } else {
        config.variants.clone()
    };
    cycle.retain(|v| !v.is_empty());
    if cycle.len() < 2 && cycle.first() == Some(&decl.variant) {
        return Err(FlightBenchError::NothingToSwap {
            role: config.role.clone(),
        });
    }
    let current = decl.variant.clone();
    let settle = Duration::from_millis(
        w.timing
            .heartbeat_period_ms
            .saturating_add(w.timing.decision_deadline_ms),
    );
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max((config.every_s + 60.0) * config.swaps as f64 + 60.0);
    let schedule = SwapSchedule {
        role: config.role.clone(),
        cycle,
        next: 0,
        current,
        every: Duration::from_secs_f64(config.every_s),
        settle,
        swaps: config.swaps as usize,
        phase: Phase::Waiting {
            since: Instant::now(),
        },
        rows: Vec::new(),
        flight_gaps: (0.0, 0.0),
        decisions: DecisionLog::default(),
    };
    if let Some(mode) = config.flight.priority {
        w.scheduling.priority = mode;
    }
    let (name, run_dir) = flight_name_and_dir("swap", config.flight.run_dir.clone());
    let _load = BusyProcesses::start(None, config.flight.outside_load)?;
    // the swaps end the flight, not the goal (the vehicle lands and the loop goes on)
    let (outcome, schedule) = Flight::builder(w)
        .name(name)
        .language_offload_check(aeris_llm::offload_check)
        .run_dir(run_dir)
        .stop_when(StopRule::Hook)
        .step_hook(schedule)
        .start()?
        .watch(watcher)?;
    let rows = schedule.rows;
    if rows.len() < config.swaps as usize {
        return Err(FlightBenchError::SwapsCut {
            made: rows.len(),
            asked: config.swaps,
            failure: outcome.failure,
        });
    }
    Ok(SwapReport {
        role: config.role.clone(),
        swaps: rows.iter().filter(|r| r.done).count() as u32,
        swaps_failed: rows.iter().filter(|r| !r.done).count() as u32,
        missed_heartbeats: rows.iter().map(|r| r.missed_heartbeats).sum(),
        flight_missed_heartbeats: outcome.summary.hub.decisions_reused,
        max_setpoint_gap_ms: rows
            .iter()
            .map(|r| r.max_setpoint_gap_ms)
            .fold(0.0, f64::max),
        setpoint_period_ms: schedule.flight_gaps.1,
        flight_max_setpoint_gap_ms: schedule.flight_gaps.0,
        rows,
        outside_load: config.flight.outside_load,
        priority: outcome.summary.priority.clone(),
        priority_detail: outcome.summary.priority_detail.clone(),
        decisions: schedule.decisions.decisions,
    })
}
