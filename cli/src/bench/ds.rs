//! `aeris bench ds`: parse, fly the interference scenario with re-binding and the variant
//! ladder, re-binding alone, and neither (`aeris_bench::flights::ds`), print the comparison.

use crate::bench::flight::FlightBenchArgs;
use crate::flight_print::FlightPrinter;
use aeris_bench::flights::ds::{self, DsConfig};
use anyhow::Result;
use clap::Args;

/// Arguments of `aeris bench ds`.
#[derive(Debug, Args)]
pub struct DsArgs {
    /// Semantic heartbeats per flight (committed or reused cycles).
    #[arg(long, default_value_t = 40)]
    pub heartbeats: u64,
    /// Heartbeats flown before the hog lands.
    #[arg(long, default_value_t = 10)]
    pub hog_after: u64,
    /// Busy processes of the hog, all pinned to the heaviest role's CPUs.
    #[arg(long, default_value_t = 4)]
    pub hog_threads: usize,
    #[command(flatten)]
    pub flight: FlightBenchArgs,
}

/// `aeris bench ds`.
pub fn ds(a: DsArgs) -> Result<()> {
    let config = DsConfig {
        heartbeats: a.heartbeats,
        hog_after: a.hog_after,
        hog_threads: a.hog_threads,
        flight: a.flight.config()?,
    };
    let report = ds::run(&config, &mut FlightPrinter::new(true, "aeris: ")?)?;
    println!(
        "dynamic scheduling under a CPU hog of {} busy processes landing after {} heartbeats (figures from the landing on)",
        a.hog_threads, a.hog_after
    );
    println!(
        "  {:<12} {:>10} {:>10} {:>7} {:>10} {:>10} {:>16}  hogged role (CPUs)",
        "", "CT mean s", "CT p95 s", "EER %", "migrations", "steps down", "slip->moved ms"
    );
    let seconds = |s: Option<f64>| s.map_or_else(|| "-".into(), |s| format!("{s:.3}"));
    let flights = [
        ("DS + ladder", &report.ds_ladder),
        ("DS on", &report.ds_on),
        ("DS off", &report.ds_off),
    ];
    for (name, r) in flights {
        println!(
            "  {:<12} {:>10} {:>10} {:>7.1} {:>10} {:>10} {:>16}  {} ({})",
            name,
            seconds(r.ct_mean_s),
            seconds(r.ct_p95_s),
            r.eer * 100.0,
            r.migrations,
            r.variant_steps_down,
            r.slip_to_migrated_ms
                .map(|m| format!("{m:.0}"))
                .unwrap_or_else(|| "-".into()),
            r.hogged_role,
            r.hog_cpus
        );
    }
    for (name, r) in &flights[..2] {
        for m in &r.moves {
            println!("  {name}: {m}");
        }
    }
    if a.flight.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}
