//! `aeris bench formation`: the formation benchmark's program stage and, with `--fly`, its
//! flight stage (the library is `aeris_bench::formation` and
//! `aeris_bench::flights::formation`; this parses arguments and prints).

use crate::flight_print::FlightPrinter;
use aeris_bench::flights::FormationFlightConfig;
use aeris_bench::formation::{FormationBenchConfig, INSTRUCTION_SETS, bench_programs};
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;

/// Arguments of `aeris bench formation`.
#[derive(Debug, Args)]
pub struct FormationArgs {
    /// Variants that write the programs: parser, qwen-coder, smollm2, gemma3.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "parser,qwen-coder,smollm2,gemma3"
    )]
    pub variants: Vec<String>,
    /// The instruction set: `benchmark` (reported) or `development` (prompts are developed
    /// on it).
    #[arg(long, default_value = "benchmark")]
    pub instructions: String,
    /// Vehicles the flight has (1-8).
    #[arg(long, default_value_t = 4)]
    pub vehicles: u8,
    /// Repairs tried before a program is refused.
    #[arg(long, value_name = "K", default_value_t = 3)]
    pub max_repairs: usize,
    /// CPU threads a language model evaluates on.
    #[arg(long, default_value_t = 2)]
    pub threads: i32,
    /// Busy processes started outside the benchmark for its whole run (unpinned, normal
    /// priority).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub outside_load: usize,
    /// Model cache (default: $AERIS_MODELS or ~/.cache/aeris/models).
    #[arg(long, value_name = "DIR")]
    pub models_dir: Option<PathBuf>,
    /// Then fly each instruction with real processes (the built-in formation flight: a
    /// vehicle and a controller process per vehicle, as many vehicles as the parser reads
    /// in the instruction, at most --vehicles), the program written in flight by
    /// --fly-variant: time, the longest wait at a phase's end, the closest two vehicles came,
    /// every controller's missed ticks.
    #[arg(long)]
    pub fly: bool,
    /// Who writes the program in the flights of --fly.
    #[arg(long, default_value = "parser", requires = "fly")]
    pub fly_variant: String,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// Run `aeris bench formation`.
pub fn run(a: FormationArgs) -> anyhow::Result<()> {
    let instructions = INSTRUCTION_SETS
        .iter()
        .find(|(name, _)| *name == a.instructions)
        .map(|(_, set)| *set)
        .with_context(|| {
            format!(
                "--instructions {}: the sets are benchmark and development",
                a.instructions
            )
        })?;
    let store = aeris_models::ModelStore::open(a.models_dir.as_deref())?;
    eprintln!(
        "formation programs: {} {} instructions x {} variants ({}), {} vehicles, {} busy processes outside",
        instructions.len(),
        a.instructions,
        a.variants.len(),
        a.variants.join(", "),
        a.vehicles,
        a.outside_load
    );
    let config = FormationBenchConfig {
        variants: a.variants,
        vehicles: a.vehicles,
        max_repairs: a.max_repairs,
        threads: a.threads,
        outside_load: a.outside_load,
        instructions,
    };
    let mut report = bench_programs(&config, &store).context("formation benchmark")?;
    if a.fly {
        let flights = FormationFlightConfig {
            instructions: instructions.iter().map(|s| s.to_string()).collect(),
            variant: a.fly_variant.clone(),
            vehicles: a.vehicles,
            outside_load: a.outside_load,
        };
        eprintln!(
            "formation flights: {} instructions, programs written by {}, {} busy processes outside",
            flights.instructions.len(),
            flights.variant,
            flights.outside_load
        );
        let mut printer = FlightPrinter::new(false, "")?;
        report.flights = aeris_bench::flights::formation::run(&flights, &mut printer)
            .context("formation flights")?;
    }
    for (variant, s) in &report.load_s {
        println!("{variant}: loaded in {s:.2} s");
    }
    println!(
        "{:<10} {:>2} {:>9} {:>6} {:>5} {:<9} {:>7} {:>9} {:>7} {:>8} {:>8} {:>7} {:>6}",
        "variant",
        "#",
        "write ms",
        "tokens",
        "valid",
        "outcome",
        "repairs",
        "plan ms",
        "parser",
        "closest",
        "flown",
        "settle",
        "lag"
    );
    for (i, r) in report.rows.iter().enumerate() {
        let n = i % instructions.len() + 1;
        println!(
            "{:<10} {:>2} {:>9.1} {:>6} {:>5} {:<9} {:>7} {:>9.2} {:>7} {:>8} {:>8} {:>7} {:>6}",
            r.variant,
            n,
            r.write_ms,
            r.generated_tokens.map_or("-".into(), |t| t.to_string()),
            if r.valid_as_written { "yes" } else { "no" },
            r.outcome,
            r.repairs,
            r.plan_ms,
            if r.same_phases_as_parser {
                "same"
            } else {
                "differs"
            },
            r.min_separation_m
                .filter(|m| m.is_finite())
                .map_or("-".into(), |m| format!("{m:.2} m")),
            r.flown_min_separation_m
                .map_or("-".into(), |m| format!("{m:.2} m")),
            r.settle_max_s.map_or("-".into(), |s| format!("{s:.1} s")),
            r.max_tracking_error_m
                .map_or("-".into(), |m| format!("{m:.2} m")),
        );
        if let Some(p) = &r.problem {
            println!("      {p}");
        }
    }
    for variant in &config_variants(&report) {
        let rows: Vec<_> = report
            .rows
            .iter()
            .filter(|r| &r.variant == variant)
            .collect();
        let as_written = rows.iter().filter(|r| r.outcome == "accepted").count();
        println!(
            "{variant}: {as_written} of {} accepted as written",
            rows.len()
        );
    }
    if !report.flights.is_empty() {
        println!(
            "{:>2} {:>8} {:<8} {:>8} {:>8} {:>6} {:>7} {:>8} {:>9}  missed ticks per vehicle (of ticks)",
            "#", "vehicles", "outcome", "program", "time", "phases", "replans", "settle", "closest",
        );
    }
    for (i, f) in report.flights.iter().enumerate() {
        println!(
            "{:>2} {:>8} {:<8} {:>6.1} s {:>6.1} s {:>6} {:>7} {:>6.1} s {:>9}  {}",
            i + 1,
            f.vehicles,
            if f.landed { "landed" } else { "FAILED" },
            f.program_s,
            f.duration_s,
            f.phases,
            f.replans,
            f.settle_max_s,
            f.min_separation_m
                .map_or("-".into(), |m| format!("{m:.2} m")),
            f.missed_ticks
                .iter()
                .zip(&f.controller_ticks)
                .map(|(m, t)| format!("{m}/{t}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        if let Some(why) = &f.failure {
            println!("      {why}");
        }
    }
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

/// The variants of `report`'s rows, in order.
fn config_variants(report: &aeris_bench::formation::FormationReport) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in &report.rows {
        if !out.contains(&r.variant) {
            out.push(r.variant.clone());
        }
    }
    out
}
