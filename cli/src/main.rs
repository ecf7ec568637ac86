//! The `aeris` command line.

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// AERIS-rs: fly a drone from natural-language instructions, every role its own process.
#[derive(Debug, Parser)]
#[command(name = "aeris", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run one role in this process (the supervisor starts roles this way).
    Role {
        /// Role spec (JSON) written by the supervisor.
        #[arg(long)]
        spec: PathBuf,
    },
}

/// Exit code of a role that refused to join a flight of another schema.
const EXIT_SCHEMA_MISMATCH: u8 = 3;

fn run_role(spec: PathBuf) -> anyhow::Result<()> {
    let spec = aeris_runtime::RoleSpec::load(&spec)?;
    let name = spec.name.clone();
    let result = if spec.kind == "hub" {
        aeris_hub::run(spec)
    } else {
        aeris_roles::run(spec)
    };
    result.with_context(|| format!("role `{name}` failed"))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Role { spec } => run_role(spec),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("aeris: error: {e:#}");
            let schema = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<aeris_runtime::RoleError>(),
                    Some(aeris_runtime::RoleError::Bus(
                        aeris_runtime::BusError::Manifest { .. }
                            | aeris_runtime::BusError::IncompatibleSchema { .. }
                    ))
                )
            });
            ExitCode::from(if schema { EXIT_SCHEMA_MISMATCH } else { 1 })
        }
    }
}
