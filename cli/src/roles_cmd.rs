//! `aeris roles`: the role kinds and the variants this build runs (a build without the
//! simulator runs none of the simulator's).

use crate::command::Execute;
use crate::role_registry;
use aeris_schemas::RoleKind;
use clap::Args;
use std::process::ExitCode;

/// Arguments of `aeris roles` (none).
#[derive(Debug, Args)]
pub struct RolesArgs {}

impl Execute for RolesArgs {
    fn execute(self) -> anyhow::Result<ExitCode> {
        for kind in RoleKind::ALL {
            let info = kind.info();
            let variants: Vec<&str> = info
                .variants
                .iter()
                .copied()
                .filter(|v| role_registry::runner(kind, v).is_some())
                .collect();
            if variants.is_empty() {
                continue;
            }
            println!(
                "{:<11} variants: {:<24} {}",
                kind.name(),
                variants.join(", "),
                info.summary
            );
        }
        Ok(ExitCode::SUCCESS)
    }
}
