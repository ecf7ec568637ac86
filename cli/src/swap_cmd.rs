//! `aeris swap ROLE VARIANT`: hot-swap a role of a running flight.

use crate::command::Execute;
use crate::inspect::{resolve_flight, tool_bus};
use aeris_orchestrator::control::SwapReport;
use anyhow::{Context, Result, bail};
use clap::Args;
use core::time::Duration;
use std::process::ExitCode;

/// Arguments of `aeris swap`.
#[derive(Debug, Args)]
pub struct SwapArgs {
    /// Role name (see `aeris status`).
    role: String,
    /// Variant from the role's pool (the workflow's `variants`).
    variant: String,
    /// Flight (default: the only one running).
    #[arg(long)]
    flight: Option<String>,
    /// Seconds the new process may take to load, warm up and send its first heartbeat
    /// before the swap is rolled back (default: 90).
    #[arg(long, value_name = "SECONDS")]
    timeout: Option<f64>,
    /// Print one JSON object instead of progress lines.
    #[arg(long)]
    json: bool,
}

/// `aeris swap ROLE VARIANT`: hot-swap a role of a running flight, make-before-break, and
/// print each step as the supervisor reports it.
impl Execute for SwapArgs {
    fn execute(self) -> Result<ExitCode> {
        let SwapArgs {
            role,
            variant,
            flight,
            timeout: timeout_s,
            json,
        } = self;
        let (role, variant) = (role.as_str(), variant.as_str());
        let flight = resolve_flight(flight)?;
        let bus = tool_bus(&flight, "swap")?;
        let timeout = match timeout_s {
            Some(s) if s.is_finite() && s > 0.0 => Duration::from_secs_f64(s),
            Some(s) => bail!("--timeout must be a positive number of seconds, got {s}"),
            None => Duration::ZERO,
        };
        let mut replies = Vec::new();
        let outcome =
            aeris_orchestrator::control::request_swap(&bus, role, variant, timeout, |r| {
                // a refusal or rollback is the error printed below
                if !json && r.stage() != Some(aeris_schemas::ReplyStage::Failed) {
                    eprintln!("[{:>6} ms] {}", r.elapsed_ms, r.message.as_str_lossy());
                }
                replies.push(*r);
            });
        let report = SwapReport::new(&flight, role, variant, &replies, &outcome);
        if json {
            println!("{}", serde_json::to_string(&report)?);
        }
        outcome.with_context(|| {
            format!("swap of role `{role}` to `{variant}` in flight `{flight}` failed")
        })?;
        if !json {
            println!("{report}");
        }
        Ok(ExitCode::SUCCESS)
    }
}
