//! `aeris migrate ROLE TARGET`: move a role of a running flight.

use crate::command::Execute;
use crate::inspect::{resolve_flight, tool_bus};
use aeris_orchestrator::control::MigrateReport;
use anyhow::{Context, Result};
use clap::Args;
use std::process::ExitCode;

/// Arguments of `aeris migrate`.
#[derive(Debug, Args)]
pub struct MigrateArgs {
    /// Role name (see `aeris status`).
    role: String,
    /// An executor of the workflow, `cpuN` for one CPU, a CPU list such as `0-1`, or
    /// `HOST:EXECUTOR` for an executor on another host (`[hosts]` of the workflow).
    target: String,
    /// Flight (default: the only one running).
    #[arg(long)]
    flight: Option<String>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// `aeris migrate ROLE TARGET`: live on the flight's host, make-before-break between hosts
/// (each stage printed as it comes).
impl Execute for MigrateArgs {
    fn execute(self) -> Result<ExitCode> {
        let MigrateArgs {
            role,
            target,
            flight,
            json,
        } = self;
        let (role, target) = (role.as_str(), target.as_str());
        let flight = resolve_flight(flight)?;
        let bus = tool_bus(&flight, "migrate")?;
        let mut replies = Vec::new();
        let outcome = aeris_orchestrator::control::request_migrate(&bus, role, target, |r| {
            // the final reply is printed below; a refusal is the error
            if !json
                && !matches!(
                    r.stage(),
                    Some(aeris_schemas::ReplyStage::Failed | aeris_schemas::ReplyStage::Done)
                )
            {
                eprintln!("[{:>6} ms] {}", r.elapsed_ms, r.message.as_str_lossy());
            }
            replies.push(*r);
        });
        let report = MigrateReport::new(&flight, role, target, &replies, &outcome);
        if json {
            println!("{}", serde_json::to_string(&report)?);
        }
        outcome.with_context(|| {
            format!("moving role `{role}` to `{target}` in flight `{flight}` failed")
        })?;
        if !json {
            println!("{report}");
        }
        Ok(ExitCode::SUCCESS)
    }
}
