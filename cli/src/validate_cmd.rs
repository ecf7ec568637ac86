//! `aeris validate WORKFLOW`: check a workflow file and print what it would start.

use crate::command::Execute;
use crate::run_cmd::load;
use aeris_flight::executors::{accelerator_line, check_accelerators, planned_registry};
use aeris_orchestrator::executors::ExecutorOrigin;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `aeris validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Workflow file (TOML).
    workflow: PathBuf,
}

impl Execute for ValidateArgs {
    fn execute(self) -> Result<ExitCode> {
        let path = self.workflow.as_path();
        let w = load(Some(path))?;
        println!(
            "{}: ok — {} roles, {} subgoals",
            path.display(),
            w.roles.len(),
            w.mission.subgoals.len()
        );
        for r in &w.roles {
            let host = w
                .role_host(r)
                .map(|h| format!(" on host {}", h.name))
                .unwrap_or_default();
            println!(
                "  {:<18} {:<10} {:<15} executor {}{host}",
                r.name,
                r.kind,
                r.variant,
                r.executor.as_deref().unwrap_or("-")
            );
        }
        if !w.hosts.is_empty() {
            println!("hosts (an `aeris agent` runs on each):");
            for h in &w.hosts {
                let link = match &h.keys {
                    Some(k) => format!("mutual TLS, keys {k}"),
                    None => "INSECURE plain TCP".to_string(),
                };
                println!(
                    "  {:<18} {:<22} {link}, link timeout {} ms",
                    h.name, h.endpoint, h.link_timeout_ms
                );
            }
            for b in w.bridge_plans() {
                println!(
                    "  bridge to {}: sends {}; receives {}",
                    b.host.name,
                    b.to_host.join(", "),
                    b.from_host.join(", ")
                );
            }
            for ex in w.executors.iter().filter(|e| e.host.is_some()) {
                let host = ex.host.as_deref().unwrap_or_default();
                println!(
                    "  executor {:<9} CPUs {:<8} on host {host}",
                    ex.name,
                    ex.cpus.to_string()
                );
            }
        }
        // the executor registry a flight of it would start with
        let registry = planned_registry(&w).context("resolving the executors")?;
        println!("executors:");
        for e in registry.executors() {
            let origin = match e.origin {
                ExecutorOrigin::Declared => "declared",
                ExecutorOrigin::Discovered => "discovered",
            };
            println!("  {:<18} CPUs {:<8} {origin}", e.name, e.cpus.to_string());
        }
        println!("{}", accelerator_line(&registry));
        for ex in w.executors.iter().filter(|e| e.accelerator.is_some()) {
            println!(
                "  executor {} runs its model roles on {}",
                ex.name,
                ex.accelerator.map(|a| a.to_string()).unwrap_or_default()
            );
        }
        check_accelerators(&w, Some(aeris_llm::offload_check))?;
        Ok(ExitCode::SUCCESS)
    }
}
