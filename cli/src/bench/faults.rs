//! `aeris bench faults`: parse, fly the fault table (`aeris_bench::flights::faults`), print
//! it.

use crate::flight_print::FlightPrinter;
use aeris_bench::flights::faults::{self, FaultKind, FaultRow, FaultsConfig};
use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// A kind of fault on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FaultArg {
    /// SIGKILL the role's process.
    Sigkill,
    /// SIGSTOP the role's process (alive, silent).
    Sigstop,
    /// Hot-swap the reasoner to its `garbage` variant, then back.
    Garbage,
    /// Delete the files of the `camera/rgb` service under its subscriber.
    ServiceRemoved,
}

impl From<FaultArg> for FaultKind {
    fn from(a: FaultArg) -> Self {
        match a {
            FaultArg::Sigkill => FaultKind::Sigkill,
            FaultArg::Sigstop => FaultKind::Sigstop,
            FaultArg::Garbage => FaultKind::Garbage,
            FaultArg::ServiceRemoved => FaultKind::ServiceRemoved,
        }
    }
}

/// Arguments of `aeris bench faults`.
#[derive(Debug, Args)]
pub struct FaultsArgs {
    /// Workflow to fly (default: the built-in default flight, workflows/default.toml).
    #[arg(long)]
    pub workflow: Option<PathBuf>,
    /// Faults to inject, comma-separated (default: all four kinds).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub faults: Vec<FaultArg>,
    /// Roles to SIGKILL / SIGSTOP, comma-separated (default: every role of the workflow but
    /// standby controllers; a controller row hits the controller holding the lease).
    #[arg(long, value_delimiter = ',')]
    pub roles: Vec<String>,
    /// Give up on a fault's recovery after this many seconds (the row shows no recovery).
    #[arg(long, default_value_t = 30)]
    pub recover_timeout_s: u64,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// `aeris bench faults`.
pub fn faults(a: FaultsArgs) -> Result<()> {
    let config = FaultsConfig {
        workflow: a.workflow.clone(),
        faults: a.faults.iter().map(|&f| f.into()).collect(),
        roles: a.roles.clone(),
        recover_timeout_s: a.recover_timeout_s,
        run_dir: a.run_dir.clone(),
    };
    let outcome = faults::run(&config, &mut FlightPrinter::new(true, "aeris: ")?)?;
    let report = &outcome.report;
    print_table(&report.rows);
    println!(
        "  flight: goal {} after {:.1} s, {} restarts",
        if report.reached_goal {
            "reached"
        } else {
            "NOT reached"
        },
        report.duration_s,
        report.role_restarts
    );
    if let Some(f) = &outcome.failure {
        println!("  flight ended early: {f}");
    }
    if a.json {
        crate::bench::json::print(report)?;
    }
    if let Some(f) = outcome.failure {
        bail!("bench faults: the flight ended early: {f}");
    }
    Ok(())
}

fn print_table(rows: &[FaultRow]) {
    println!(
        "  {:<16} {:<26} {:>10} {:>11} {:>12} {:>14} {:>17}",
        "fault",
        "role",
        "detect ms",
        "recover ms",
        "missed ticks",
        "lost decisions",
        "invalid setpoints"
    );
    let f = |v: Option<f64>| v.map(|v| format!("{v:.0}")).unwrap_or_else(|| "-".into());
    for r in rows {
        println!(
            "  {:<16} {:<26} {:>10} {:>11} {:>12} {:>14} {:>17}",
            r.fault.as_str(),
            r.role,
            f(r.detect_ms),
            f(r.recover_ms),
            r.missed_ticks,
            r.lost_decisions,
            r.invalid_setpoints
        );
    }
}
