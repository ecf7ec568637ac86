//! `aeris distill`: fly `train` episodes with a teacher and write the aligned reasoner's
//! training pairs (`aeris_eval::distill`); prints each episode and where the pairs are.

use crate::eval_cmd::EpisodePrinter;
use crate::flight_print::FlightPrinter;
use aeris_eval::generate::{AirspaceFilter, Split};
use aeris_eval::runner::{self, AgentOptions, AgentSetup, EpisodeSource, EvalConfig, Shard};
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `aeris distill`.
#[derive(Debug, Args)]
pub struct DistillArgs {
    /// Split to generate and fly: only `train` (the held-out splits measure the models).
    #[arg(long, default_value = "train")]
    pub split: String,
    /// Fly these episodes instead of generating the split (our JSON or AerialVLN's): every
    /// one must be on a `train` scene.
    #[arg(long, value_name = "FILE")]
    pub episodes_file: Option<PathBuf>,
    /// Episodes to fly.
    #[arg(long, default_value_t = 10)]
    pub episodes: usize,
    /// Airspace: open, dense or full (both, alternating).
    #[arg(long, default_value = "full")]
    pub airspace: String,
    /// A DAgger round: this language-model variant (`smollm2-aligned`, the model being
    /// trained; or a base, `smollm2`, `gemma3`) flies with the aligned prompt and the
    /// planner labels every state it reaches. Without it the
    /// planner flies and its own decisions are the labels.
    #[arg(long, value_name = "VARIANT")]
    pub student: Option<String>,
    /// Perception: `models` (the model roles the evaluation flies with; the default) or
    /// `geometric` (one process segmenting frames by colour: faster, no sign reading).
    #[arg(long)]
    pub perception: Option<String>,
    /// The clock the episodes fly on: `sim` (simulated time, as fast as the roles compute;
    /// the default) or `wall`.
    #[arg(long, value_name = "CLOCK", default_value = "sim")]
    pub clock: aeris_flight::FlightClock,
    /// Fly only shard K of N of the episodes (for data written on several machines).
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// Output folder: OUT/pairs.jsonl (one training pair a line: `system`, `user`,
    /// `target`, and the episode, scene and agent it came from), OUT/episodes.jsonl (how
    /// the teacher flew) and the flights' logs (default: runs/distill-SPLIT-AGENT).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print one JSON object with the teacher's table and the pairs on the last line.
    #[arg(long)]
    pub json: bool,
}

impl crate::command::Execute for DistillArgs {
    fn execute(self) -> Result<std::process::ExitCode> {
        let agent = AgentSetup::resolve(&AgentOptions {
            reasoning: self.student.clone(),
            perception: self.perception.clone(),
            aligned: self.student.is_some(),
            ..AgentOptions::default()
        })?;
        let split = Split::parse(&self.split)
            .with_context(|| format!("unknown split `{}`: use train", self.split))?;
        aeris_eval::distill::check(&agent, split)?;
        let airspace = AirspaceFilter::parse(&self.airspace).with_context(|| {
            format!(
                "unknown airspace `{}`: use open, dense or full",
                self.airspace
            )
        })?;
        let out = self.out.clone().unwrap_or_else(|| {
            PathBuf::from("runs").join(format!("distill-{}-{}", self.split, agent.label))
        });
        let config = EvalConfig {
            agent,
            source: match &self.episodes_file {
                Some(file) => EpisodeSource::File(file.clone()),
                None => EpisodeSource::Generate { split, airspace },
            },
            episodes: self.episodes,
            out,
            record: false,
            offload_check: Some(aeris_llm::offload_check),
            shard: self.shard,
            clock: self.clock,
            distill: true,
        };
        let mut printer = EpisodePrinter(FlightPrinter::new(false, "aeris: ")?);
        let report = runner::run(&config, &mut printer, None)?;
        let table = report.table(&config.agent);
        print!("{table}");
        let (pairs, path) = report
            .pairs
            .clone()
            .context("the evaluation wrote no training pairs")?;
        println!("{pairs} training pairs in {}", path.display());
        if self.json {
            let mut value = serde_json::to_value(&table)?;
            value["pairs"] = pairs.into();
            value["pairs_file"] = path.display().to_string().into();
            println!("{}", serde_json::to_string(&value)?);
        }
        Ok(std::process::ExitCode::SUCCESS)
    }
}
