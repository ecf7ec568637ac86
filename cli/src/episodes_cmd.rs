//! `aeris episodes ...`: generate a split's VLN episodes, check an episode file.

use aeris_eval::episode::{load_episodes, save_episodes};
use aeris_eval::generate::{AirspaceFilter, Split, generate_split};
use aeris_eval::table::EpisodeFileSummary;
use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `aeris episodes`.
#[derive(Debug, Args)]
pub struct EpisodesArgs {
    #[command(subcommand)]
    pub command: EpisodesCommand,
}

/// What `aeris episodes` does.
#[derive(Debug, Subcommand)]
pub enum EpisodesCommand {
    /// Generate a split's episodes (AerialVLN JSON with our subgoal annotation).
    Generate {
        /// Split: train, val_unseen or test_unseen (their scenes do not overlap).
        #[arg(long)]
        split: String,
        /// Episodes to generate.
        #[arg(long, default_value_t = 20)]
        episodes: usize,
        /// Airspace: open, dense or full (both, alternating).
        #[arg(long, default_value = "full")]
        airspace: String,
        /// Output file (JSON).
        #[arg(long)]
        out: PathBuf,
    },
    /// Load and validate an episode file (ours or AerialVLN's) and summarise it.
    Check {
        /// Episode file (JSON).
        file: PathBuf,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

/// Run `aeris episodes`.
pub fn episodes(args: EpisodesArgs) -> anyhow::Result<()> {
    match args.command {
        EpisodesCommand::Generate {
            split,
            episodes,
            airspace,
            out,
        } => {
            let split = Split::parse(&split).with_context(|| {
                format!("unknown split `{split}`: use train, val_unseen or test_unseen")
            })?;
            let filter = AirspaceFilter::parse(&airspace).with_context(|| {
                format!("unknown airspace `{airspace}`: use open, dense or full")
            })?;
            if episodes == 0 {
                bail!("--episodes must be at least 1");
            }
            let mut stderr = std::io::stderr();
            let list = generate_split(split, filter, episodes, &mut |done, total| {
                let _ = write!(stderr, "\rgenerating episodes: {done}/{total}");
                if done == total {
                    let _ = writeln!(stderr);
                }
            })?;
            save_episodes(&out, &list)?;
            println!(
                "wrote {} {} episodes ({airspace}) to {}",
                list.len(),
                split.as_str(),
                out.display()
            );
            Ok(())
        }
        EpisodesCommand::Check { file, json } => {
            let summary = EpisodeFileSummary::of(&file, &load_episodes(&file)?);
            if json {
                println!("{}", serde_json::to_string(&summary)?);
            } else {
                print!("{summary}");
            }
            Ok(())
        }
    }
}

impl crate::command::Execute for EpisodesArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        episodes(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
