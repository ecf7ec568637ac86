//! `aeris bench cycle` and `aeris bench swap`: parse, fly them (`aeris_bench::flights`),
//! print their figures.

use crate::flight_print::FlightPrinter;
use crate::run_cmd::variant_choices;
use aeris_bench::flights::{CycleConfig, FlightBenchConfig, SwapConfig, cycle, swap};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

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
    /// Busy processes started outside the flight (unpinned, normal priority) for the run: the
    /// flight on a shared machine.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub outside_load: usize,
    /// How the roles get priority over outside work: `auto` (a CPU control group where
    /// permitted, else nice -5), `nice` or `off` (default: the workflow's `[scheduling]
    /// priority`, itself `auto` by default).
    #[arg(long, value_name = "MODE", value_parser = parse_priority)]
    pub priority: Option<aeris_orchestrator::priority::PriorityMode>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn parse_priority(
    s: &str,
) -> Result<aeris_orchestrator::priority::PriorityMode, String> {
    s.parse()
}

impl FlightBenchArgs {
    /// The library's settings.
    pub fn config(&self) -> Result<FlightBenchConfig> {
        Ok(FlightBenchConfig {
            workflow: self.workflow.clone(),
            variants: variant_choices(&self.variant)?,
            run_dir: self.run_dir.clone(),
            outside_load: self.outside_load,
            priority: self.priority,
        })
    }
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

/// `aeris bench cycle`.
pub fn cycle(a: CycleArgs) -> Result<()> {
    let config = CycleConfig {
        heartbeats: a.heartbeats,
        flight: a.flight.config()?,
    };
    let report = cycle::run(&config, &mut FlightPrinter::new(true, "")?)?;
    println!(
        "cycle time over {} heartbeats (reasoning: {}), frame capture -> committed decision",
        report.heartbeats, report.reasoning
    );
    println!(
        "  {} busy processes outside the flight; roles' priority: {}",
        report.outside_load, report.priority_detail
    );
    println!(
        "  CT mean {:.3} s  std {:.3} s  p95 {:.3} s   EER {:.1}% ({} late)",
        report.ct_mean_s,
        report.ct_std_s,
        report.ct_p95_s,
        report.eer * 100.0,
        report.decisions_late
    );
    let air = &report.in_flight;
    println!(
        "  in the air ({} heartbeats): CT mean {:.3} s  p95 {:.3} s   EER {:.1}%",
        air.heartbeats,
        air.ct_mean_s,
        air.ct_p95_s,
        air.eer * 100.0
    );
    println!(
        "  stages (mean): perception {:.3} s  reasoning {:.3} s  routing {:.4} s  binding {:.5} s",
        report.stages.perception,
        report.stages.reasoning,
        report.stages.routing,
        report.stages.binding
    );
    let p = &report.pauses;
    println!(
        "  pauses: the supervisor's longest step gap {:.0} ms ({} over 100 ms); {} of the supervisor and {} of one CPU over 300 ms, the longest {} ms",
        p.step_gap_max_ms,
        p.step_gaps_over_100ms,
        p.supervisor_pauses,
        p.cpu_pauses,
        p.pause_max_ms
    );
    if !report.decisions.is_empty() {
        let n = report.decisions.len() as f64;
        let mean =
            |f: fn(&cycle::DecisionCost) -> f64| report.decisions.iter().map(f).sum::<f64>() / n;
        println!(
            "  language-model decisions ({}, means): prompt {:.0} tokens of which {:.0} new in {:.0} ms; {:.1} generated ({:.1} verified from the plan) in {:.0} ms; {:.0} ms each",
            report.decisions.len(),
            mean(|d| d.prompt_tokens as f64),
            mean(|d| d.new_prompt_tokens as f64),
            mean(|d| d.prompt_ms),
            mean(|d| d.generated_tokens as f64),
            mean(|d| d.drafted_tokens as f64),
            mean(|d| d.generate_ms),
            mean(|d| d.decision_ms),
        );
    }
    let m = &report.memory;
    println!(
        "  memory: the roles' PSS peak {} MiB (RSS summed {:.0} MiB)",
        m.total_pss_peak_mib
            .map_or_else(|| "?".into(), |p| format!("{p:.0}")),
        m.total_rss_peak_mib
    );
    println!("  role latency from heartbeats (p50 / p95 ms):");
    for r in &report.roles {
        println!(
            "    {:<11} {:<15} {:>9.1} {:>9.1}",
            r.role, r.variant, r.p50_ms, r.p95_ms
        );
    }
    if a.flight.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

/// `aeris bench swap`.
pub fn swap(a: SwapArgs) -> Result<()> {
    let config = SwapConfig {
        swaps: a.swaps,
        role: a.role.clone(),
        variants: a.variants.clone(),
        every_s: a.every,
        flight: a.flight.config()?,
    };
    let report = swap::run(&config, &mut FlightPrinter::new(true, "")?)?;
    println!(
        "hot swaps of role `{}` during a flight (make-before-break), {} busy processes outside the flight; roles' priority: {}",
        report.role, report.outside_load, report.priority_detail
    );
    println!(
        "{:<9} {:<9} {:>6} {:>10} {:>10} {:>7} {:>5} {:>9} {:>12}",
        "from", "to", "done", "ready_ms", "done_ms", "missed", "late", "rejected", "max_gap_ms"
    );
    for r in &report.rows {
        println!(
            "{:<9} {:<9} {:>6} {:>10.0} {:>10.0} {:>7} {:>5} {:>9} {:>12.1}",
            r.from,
            r.to,
            r.done,
            r.ready_ms,
            r.done_ms,
            r.missed_heartbeats,
            r.late_decisions,
            r.rejected_decisions,
            r.max_setpoint_gap_ms
        );
        if let Some(e) = &r.error {
            println!("  error: {e}");
        }
    }
    println!(
        "swaps {} (failed {}), missed heartbeats {} in the swaps ({} in the whole flight), longest setpoint gap during swaps {:.1} ms (normal period {:.1} ms, longest in the flight {:.1} ms)",
        report.swaps,
        report.swaps_failed,
        report.missed_heartbeats,
        report.flight_missed_heartbeats,
        report.max_setpoint_gap_ms,
        report.setpoint_period_ms,
        report.flight_max_setpoint_gap_ms
    );
    if a.flight.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

/// Arguments of `aeris bench record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// Semantic heartbeats each flight flies.
    #[arg(long, default_value_t = 15)]
    pub heartbeats: u64,
    /// Busy processes started outside the flight (unpinned, normal priority) for the run.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub outside_load: usize,
    /// The model flight (workflows/models.toml) too, not only the default one.
    #[arg(long)]
    pub models: bool,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// `aeris bench record`.
pub fn record(a: RecordArgs) -> Result<()> {
    let config = aeris_bench::flights::RecordBenchConfig {
        heartbeats: a.heartbeats,
        outside_load: a.outside_load,
        models: a.models,
    };
    let report = aeris_bench::flights::record::run(&config, &mut FlightPrinter::new(true, "")?)?;
    println!(
        "recording cost over {} heartbeats per flight, {} busy processes outside the flight",
        a.heartbeats, report.outside_load
    );
    println!(
        "  {:<8} {:<9} {:>6} {:>13} {:>8} {:>8} {:>6} {:>13} {:>8} {:>8}",
        "flight",
        "recorder",
        "cycles",
        "missed ticks",
        "CT mean",
        "CT p95",
        "EER",
        "recorder CPU",
        "MB/min",
        "dropped"
    );
    let opt = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map_or_else(|| "-".to_string(), f);
    for r in &report.rows {
        println!(
            "  {:<8} {:<9} {:>6} {:>13} {:>7.3}s {:>7.3}s {:>5.1}% {:>13} {:>8} {:>8}",
            r.workflow,
            if r.recorded { "on" } else { "off" },
            r.cycles,
            r.controller_missed_ticks,
            r.ct_mean_s,
            r.ct_p95_s,
            r.eer * 100.0,
            opt(r.recorder_cpu_percent, &|c| format!("{c:.1}%")),
            opt(r.mb_per_minute, &|m| format!("{m:.1}")),
            r.dropped.map_or_else(|| "-".to_string(), |d| d.to_string()),
        );
    }
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}
