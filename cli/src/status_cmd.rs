//! `aeris status`: every role of a running flight.

use crate::command::Execute;
use crate::inspect::{resolve_flight, tool_bus};
use anyhow::Result;
use clap::Args;
use std::process::ExitCode;

/// Arguments of `aeris status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    /// Flight to show (default: the only one running).
    #[arg(long)]
    flight: Option<String>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

impl Execute for StatusArgs {
    fn execute(self) -> Result<ExitCode> {
        let StatusArgs { flight, json } = self;
        let flight = resolve_flight(flight)?;
        let bus = tool_bus(&flight, "status")?;
        let report = aeris_flight::status_report::FlightStatusReport::read(&bus, &flight)?;
        if json {
            println!("{}", serde_json::to_string(&report)?);
        } else {
            print!("{report}");
        }
        Ok(ExitCode::SUCCESS)
    }
}
