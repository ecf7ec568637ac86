//! `aeris roles`: the role kinds and the variants this build runs (a build without the
//! simulator runs none of the simulator's).

use crate::command::Execute;
use crate::role_registry;
use aeris_schemas::RoleKind;
use clap::Args;
use serde::Serialize;
use std::fmt;
use std::process::ExitCode;

/// Arguments of `aeris roles`.
#[derive(Debug, Args)]
pub struct RolesArgs {
    /// Print one JSON array instead of the table.
    #[arg(long)]
    json: bool,
}

/// A role kind this build runs, with the variants it has runners for.
#[derive(Debug, Serialize)]
struct KindLine {
    kind: RoleKind,
    variants: Vec<&'static str>,
    summary: &'static str,
}

impl fmt::Display for KindLine {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<11} variants: {:<24} {}",
            self.kind.name(),
            self.variants.join(", "),
            self.summary
        )
    }
}

/// Every kind this build runs at least one variant of.
fn kinds_run_here() -> Vec<KindLine> {
    RoleKind::ALL
        .into_iter()
        .map(|kind| KindLine {
            kind,
            variants: kind
                .info()
                .variants
                .iter()
                .copied()
                .filter(|v| role_registry::runner(kind, v).is_some())
                .collect(),
            summary: kind.info().summary,
        })
        .filter(|k| !k.variants.is_empty())
        .collect()
}

impl Execute for RolesArgs {
    fn execute(self) -> anyhow::Result<ExitCode> {
        let kinds = kinds_run_here();
        if self.json {
            println!("{}", serde_json::to_string(&kinds)?);
        } else {
            for k in &kinds {
                println!("{k}");
            }
        }
        Ok(ExitCode::SUCCESS)
    }
}
