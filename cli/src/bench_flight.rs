//! Benchmarks that fly the model pipeline end to end (every role its own process):
//! `aeris bench cycle` (cycle time per stage and EER over N heartbeats) and
//! `aeris bench swap` (hot swaps during the flight: missed heartbeats, setpoint gaps).

use crate::run_cmd::{FlightPlan, StopRule, apply_overrides, fly};
use aeris_flight::StageMeans;
use aeris_orchestrator::supervisor::{DEFAULT_SWAP_READY_TIMEOUT, Supervisor, SupervisorEvent};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::clock::monotonic_ns;
use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Arguments shared by the flight benchmarks.
#[derive(Debug, Args)]
pub struct FlightBenchArgs {
    /// Workflow to fly (default: the built-in model flight, workflows/models.toml).
    #[arg(long)]
    pub workflow: Option<PathBuf>,
    /// Run a role with another variant, e.g. --variant reasoning=gemma3 (repeatable).
    #[arg(long, value_name = "ROLE=VARIANT")]
    pub variant: Vec<String>,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `aeris bench cycle`.
#[derive(Debug, Args)]
pub struct CycleArgs {
    /// Semantic heartbeats (committed or reused cycles) to measure.
    #[arg(long, default_value_t = 30)]
    pub heartbeats: u64,
    #[command(flatten)]
    pub flight: FlightBenchArgs,
}

/// Arguments of `aeris bench swap`.
#[derive(Debug, Args)]
pub struct SwapArgs {
    /// Swaps to make.
    #[arg(long, default_value_t = 4)]
    pub swaps: u32,
    /// Role to swap.
    #[arg(long, default_value = "reasoning")]
    pub role: String,
    /// Variants to swap to, in turn (default: the role's pool, the running one last).
    #[arg(long, value_delimiter = ',')]
    pub variants: Vec<String>,
    /// Seconds of flight between the end of one swap and the start of the next.
    #[arg(long, default_value_t = 8.0)]
    pub every: f64,
    #[command(flatten)]
    pub flight: FlightBenchArgs,
}

fn workflow(a: &FlightBenchArgs) -> Result<Workflow> {
    let mut w = match &a.workflow {
        Some(p) => Workflow::from_path(p).with_context(|| format!("workflow {}", p.display()))?,
        None => Workflow::builtin_models().context("built-in model workflow")?,
    };
    apply_overrides(&mut w, &a.variant, None)?;
    // the benchmark makes its own swaps: the variant ladder must not start others
    w.scheduling.adapt_variants = false;
    Ok(w)
}

fn plan(a: &FlightBenchArgs, tag: &str, stop: StopRule) -> FlightPlan {
    let flight = format!("bench-{tag}-{}", std::process::id());
    FlightPlan {
        run_dir: a
            .run_dir
            .clone()
            .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight)),
        flight,
        autopilot: None,
        stop,
        progress: true,
        dynamic: None,
    }
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

fn role_latencies(sup: &Supervisor) -> Vec<RoleLatency> {
    sup.roles()
        .iter()
        .filter_map(|r| {
            r.latency_ms().map(|l| RoleLatency {
                role: r.name().to_string(),
                variant: r.variant().to_string(),
                p50_ms: l[0],
                p95_ms: l[1],
            })
        })
        .collect()
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
}

/// `aeris bench cycle`.
pub fn cycle(a: CycleArgs) -> Result<()> {
    if a.heartbeats == 0 {
        bail!("--heartbeats must be at least 1");
    }
    let mut w = workflow(&a.flight)?;
    let reasoning = w
        .roles
        .iter()
        .find(|r| r.kind == "reasoning")
        .map(|r| r.variant.clone())
        .unwrap_or_default();
    // time for N heartbeats, whatever the mission does meanwhile (it lands and waits)
    let period_s = w.timing.heartbeat_period_ms as f64 / 1000.0;
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max(a.heartbeats as f64 * period_s * 3.0 + 60.0);
    let plan = plan(&a.flight, "cycle", StopRule::Cycles(a.heartbeats));
    let mut roles = Vec::new();
    let outcome = fly(w, &plan, |sup, _, _| {
        roles = role_latencies(sup);
        Ok(false)
    })?;
    if let Some(f) = outcome.failure {
        bail!("bench cycle: the flight ended early: {f}");
    }
    let s = outcome.summary;
    let report = CycleReport {
        heartbeats: s.cycles,
        reasoning,
        ct_mean_s: s.ct_mean_s,
        ct_std_s: s.ct_std_s,
        ct_p95_s: s.ct_p95_s,
        eer: s.eer,
        stages: s.stages_mean_s,
        roles,
        decisions_late: s.decisions_late,
        controller_missed_ticks: s.controller_missed_ticks,
    };
    println!(
        "cycle time over {} heartbeats (reasoning: {}), frame capture -> committed decision",
        report.heartbeats, report.reasoning
    );
    println!(
        "  CT mean {:.3} s  std {:.3} s  p95 {:.3} s   EER {:.1}% ({} late)",
        report.ct_mean_s,
        report.ct_std_s,
        report.ct_p95_s,
        report.eer * 100.0,
        report.decisions_late
    );
    println!(
        "  stages (mean): perception {:.3} s  reasoning {:.3} s  routing {:.4} s  binding {:.5} s",
        report.stages.perception,
        report.stages.reasoning,
        report.stages.routing,
        report.stages.binding
    );
    println!("  role latency from heartbeats (p50 / p95 ms):");
    for r in &report.roles {
        println!(
            "    {:<11} {:<15} {:>9.1} {:>9.1}",
            r.role, r.variant, r.p50_ms, r.p95_ms
        );
    }
    if a.flight.json {
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}

/// One swap of `aeris bench swap`.
#[derive(Debug, Clone, Serialize)]
pub struct SwapRow {
    /// Variant replaced.
    pub from: String,
    /// Variant brought in.
    pub to: String,
    /// `true` when it completed (the old process exited).
    pub done: bool,
    /// From the swap's start to the new process's first heartbeat after warm-up (ms).
    pub ready_ms: f64,
    /// From the swap's start to the old process's exit (ms).
    pub done_ms: f64,
    /// Heartbeats without a fresh valid decision from the swap's start to one heartbeat
    /// after it ended.
    pub missed_heartbeats: u64,
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
    /// Longest setpoint interval during any swap window (ms).
    pub max_setpoint_gap_ms: f64,
    /// Median setpoint interval over the whole flight (ms): the normal period.
    pub setpoint_period_ms: f64,
    /// Longest setpoint interval over the whole flight (ms).
    pub flight_max_setpoint_gap_ms: f64,
    /// One row per swap.
    pub rows: Vec<SwapRow>,
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
        reused_at_start: u64,
    },
    /// The swap ended; its window stays open one heartbeat longer.
    Settling {
        row: SwapRow,
        start_ns: u64,
        until: Instant,
        reused_at_start: u64,
    },
}

/// `aeris bench swap`.
pub fn swap(a: SwapArgs) -> Result<()> {
    if a.swaps == 0 {
        bail!("--swaps must be at least 1");
    }
    if !(a.every.is_finite() && a.every >= 0.0) {
        bail!("--every must be a number of seconds >= 0");
    }
    let mut w = workflow(&a.flight)?;
    let decl = w
        .roles
        .iter()
        .find(|r| r.name == a.role)
        .with_context(|| format!("the workflow has no role `{}`", a.role))?;
    let mut cycle: Vec<String> = if a.variants.is_empty() {
        let mut pool: Vec<String> = decl
            .variants
            .iter()
            .filter(|v| **v != decl.variant)
            .cloned()
            .collect();
        pool.push(decl.variant.clone());
        pool
    } else {
        a.variants.clone()
    };
    cycle.retain(|v| !v.is_empty());
    if cycle.len() < 2 && cycle.first() == Some(&decl.variant) {
        bail!(
            "role `{}` has no other variant to swap to; pass --variants",
            a.role
        );
    }
    let period = Duration::from_millis(w.timing.heartbeat_period_ms);
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max((a.every + 60.0) * a.swaps as f64 + 60.0);
    let mut current = decl.variant.clone();
    // the swaps end the flight, not the goal (the vehicle lands and the loop goes on)
    let plan = plan(&a.flight, "swap", StopRule::Cycles(u64::MAX));
    let every = Duration::from_secs_f64(a.every);
    let mut rows: Vec<SwapRow> = Vec::new();
    let mut phase = Phase::Waiting {
        since: Instant::now(),
    };
    let mut next = 0usize;
    let mut flight_gaps = (0.0, 0.0);
    let outcome = fly(w, &plan, |sup, monitor, events| {
        flight_gaps = monitor.setpoint_gaps_ms(0, u64::MAX);
        phase = match std::mem::replace(
            &mut phase,
            Phase::Waiting {
                since: Instant::now(),
            },
        ) {
            // swaps start once the flight is in its steady state (decisions committed)
            Phase::Waiting { since }
                if since.elapsed() >= every && monitor.cycles() >= STEADY_CYCLES =>
            {
                let to = cycle[next % cycle.len()].clone();
                next += 1;
                let mut row = SwapRow {
                    from: current.clone(),
                    to: to.clone(),
                    done: false,
                    ready_ms: 0.0,
                    done_ms: 0.0,
                    missed_heartbeats: 0,
                    max_setpoint_gap_ms: 0.0,
                    error: None,
                };
                let start_ns = monotonic_ns();
                let reused_at_start = monitor.reused();
                match sup.begin_swap(&a.role, &to, DEFAULT_SWAP_READY_TIMEOUT) {
                    Ok(pid) => {
                        eprintln!("bench swap: {} -> {to} (pid {pid})", row.from);
                        Phase::Swapping {
                            row,
                            started: Instant::now(),
                            start_ns,
                            reused_at_start,
                        }
                    }
                    Err(e) => {
                        row.error = Some(e.to_string());
                        rows.push(row);
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
                reused_at_start,
            } => {
                let mut ended = false;
                for event in events {
                    match event {
                        SupervisorEvent::SwapReady { name, .. } if *name == a.role => {
                            row.ready_ms = started.elapsed().as_secs_f64() * 1e3;
                        }
                        SupervisorEvent::SwapDone { name, .. } if *name == a.role => {
                            row.done = true;
                            row.done_ms = started.elapsed().as_secs_f64() * 1e3;
                            current = row.to.clone();
                            ended = true;
                        }
                        SupervisorEvent::SwapFailed { name, reason, .. } if *name == a.role => {
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
                        until: Instant::now() + period,
                        reused_at_start,
                    }
                } else {
                    Phase::Swapping {
                        row,
                        started,
                        start_ns,
                        reused_at_start,
                    }
                }
            }
            Phase::Settling {
                mut row,
                start_ns,
                until,
                reused_at_start,
            } if Instant::now() >= until => {
                row.missed_heartbeats = monitor.reused().saturating_sub(reused_at_start);
                row.max_setpoint_gap_ms = monitor.setpoint_gaps_ms(start_ns, monotonic_ns()).0;
                eprintln!(
                    "bench swap: {} -> {}: {} ({:.0} ms to ready, {:.0} ms to done), {} missed heartbeats, longest setpoint gap {:.1} ms",
                    row.from,
                    row.to,
                    if row.done { "done" } else { "FAILED" },
                    row.ready_ms,
                    row.done_ms,
                    row.missed_heartbeats,
                    row.max_setpoint_gap_ms
                );
                rows.push(row);
                Phase::Waiting {
                    since: Instant::now(),
                }
            }
            other => other,
        };
        Ok(rows.len() >= a.swaps as usize)
    })?;
    if rows.len() < a.swaps as usize {
        bail!(
            "bench swap: the flight ended after {} of {} swaps: {}",
            rows.len(),
            a.swaps,
            outcome.failure.unwrap_or_else(|| "no reason given".into())
        );
    }
    let report = SwapReport {
        role: a.role.clone(),
        swaps: rows.iter().filter(|r| r.done).count() as u32,
        swaps_failed: rows.iter().filter(|r| !r.done).count() as u32,
        missed_heartbeats: rows.iter().map(|r| r.missed_heartbeats).sum(),
        max_setpoint_gap_ms: rows
            .iter()
            .map(|r| r.max_setpoint_gap_ms)
            .fold(0.0, f64::max),
        setpoint_period_ms: flight_gaps.1,
        flight_max_setpoint_gap_ms: flight_gaps.0,
        rows,
    };
    println!(
        "hot swaps of role `{}` during a flight (make-before-break)",
        report.role
    );
    println!(
        "{:<9} {:<9} {:>6} {:>10} {:>10} {:>7} {:>12}",
        "from", "to", "done", "ready_ms", "done_ms", "missed", "max_gap_ms"
    );
    for r in &report.rows {
        println!(
            "{:<9} {:<9} {:>6} {:>10.0} {:>10.0} {:>7} {:>12.1}",
            r.from, r.to, r.done, r.ready_ms, r.done_ms, r.missed_heartbeats, r.max_setpoint_gap_ms
        );
        if let Some(e) = &r.error {
            println!("  error: {e}");
        }
    }
    println!(
        "swaps {} (failed {}), missed heartbeats {}, longest setpoint gap during swaps {:.1} ms (normal period {:.1} ms, longest in the flight {:.1} ms)",
        report.swaps,
        report.swaps_failed,
        report.missed_heartbeats,
        report.max_setpoint_gap_ms,
        report.setpoint_period_ms,
        report.flight_max_setpoint_gap_ms
    );
    if a.flight.json {
        println!("{}", serde_json::to_string(&report)?);
    }
    Ok(())
}
