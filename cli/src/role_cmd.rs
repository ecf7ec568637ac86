//! `aeris role --spec FILE` (hidden): run one role in this process, as the supervisor
//! starts every role.

use crate::command::Execute;
use crate::role_registry;
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `aeris role`.
#[derive(Debug, Args)]
pub struct RoleArgs {
    /// Role spec (JSON) written by the supervisor.
    #[arg(long)]
    spec: PathBuf,
    /// Instance number the supervisor gave this process (overrides the spec's).
    #[arg(long)]
    instance: Option<u32>,
}

impl Execute for RoleArgs {
    fn execute(self) -> anyhow::Result<ExitCode> {
        run_role(self.spec, self.instance)
    }
}

/// Exit code of a role that refused to join a flight of another schema (the supervisor
/// never restarts a role that exits with it).
pub(crate) const EXIT_SCHEMA_MISMATCH: u8 = aeris_orchestrator::restart::EXIT_SCHEMA_MISMATCH as u8;

fn run_role(spec: PathBuf, instance: Option<u32>) -> anyhow::Result<ExitCode> {
    let mut spec = aeris_runtime::RoleSpec::load(&spec)?;
    if let Some(n) = instance {
        spec.instance = n;
    }
    let name = spec.name.clone();
    // a role on another host stamps in the flight's host's clock
    aeris_runtime::clock::set_flight_clock_offset_ns(spec.flight_clock_offset_ns);
    if spec.remote.is_some() {
        // on another host: this process is the role's handle there
        let exit = aeris_hosts::handle::run_remote(spec)
            .with_context(|| format!("role `{name}` on its host"))?;
        return Ok(ExitCode::from(exit.exit_code()));
    }
    let result = role_registry::run(spec);
    result.with_context(|| format!("role `{name}` failed"))?;
    Ok(ExitCode::SUCCESS)
}
