//! `aeris validate WORKFLOW`: check a workflow file and print what it would start.

use crate::command::Execute;
use crate::run_cmd::load;
use aeris_flight::executors::check_accelerators;
use aeris_flight::workflow_check::WorkflowCheck;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `aeris validate`.
#[derive(Debug, Args)]
pub struct ValidateArgs {
    /// Workflow file (TOML).
    workflow: PathBuf,
    /// Print one JSON object instead of the text.
    #[arg(long)]
    json: bool,
}

impl Execute for ValidateArgs {
    fn execute(self) -> Result<ExitCode> {
        let path = self.workflow.as_path();
        let w = load(Some(path))?;
        let check = WorkflowCheck::of(&path.display().to_string(), &w)
            .context("resolving the executors")?;
        if self.json {
            println!("{}", serde_json::to_string(&check)?);
        } else {
            print!("{check}");
        }
        check_accelerators(&w, Some(aeris_llm::offload_check))?;
        Ok(ExitCode::SUCCESS)
    }
}
