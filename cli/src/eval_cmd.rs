//! `aeris eval`: parse, fly VLN episodes through the full multi-process pipeline and score
//! them (`aeris_eval::runner`), print each episode and the table.

use crate::flight_print::FlightPrinter;
use aeris_eval::episode::Episode;
use aeris_eval::generate::{AirspaceFilter, Split};
use aeris_eval::mission::StepReader;
use aeris_eval::runner::{
    self, AgentOptions, AgentSetup, EpisodeLine, EpisodeSource, EvalConfig, EvalWatcher, Shard,
};
use aeris_flight::{FlightEvent, FlightWatcher};
use aeris_runtime::spec::SubgoalSpec;
use aeris_sim_roles::perception::LABELS;
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

/// Arguments of `aeris eval`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct EvalArgs {
    #[command(subcommand)]
    command: Option<EvalCommand>,
    /// Fly only shard K of N of the episodes (every N-th from the K-th, 1 <= K <= N), for
    /// evaluations spread over machines; `aeris eval merge` makes the one table of the
    /// shards' outputs.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,
    /// The clock the episodes fly on: `wall` (real time), or `sim`: simulated time in
    /// lockstep, as fast as the roles compute and the same on any machine (see `aeris run
    /// --clock`); NE, SR, OSR, nDTW, SPL and ASR are measured on it alike, CT and EER are
    /// on the flight's clock (0 on simulated time, where work takes no time).
    #[arg(long, value_name = "CLOCK", default_value = "wall")]
    pub clock: aeris_flight::FlightClock,
    /// Record every episode into its run folder (`runs/FLIGHT/flight.mcap`, named in
    /// episodes.jsonl as `recording`): open a failed one in Foxglove, or `aeris replay` it.
    #[arg(long)]
    pub record: bool,
    /// Split to generate and fly: train, val_unseen or test_unseen.
    #[arg(long, default_value = "val_unseen")]
    pub split: String,
    /// Fly these episodes instead of generating a split (our JSON or AerialVLN's; the
    /// scenes must be ones this simulator has).
    #[arg(long, value_name = "FILE")]
    pub episodes_file: Option<PathBuf>,
    /// Episodes to fly.
    #[arg(long, default_value_t = 10)]
    pub episodes: usize,
    /// Airspace: open, dense or full (both, alternating).
    #[arg(long, default_value = "full")]
    pub airspace: String,
    /// Fly a baseline instead of AERIS: `oracle` (the planner on the reference path: the
    /// upper bound) or `random` (uniform AerialVLN actions).
    #[arg(long)]
    pub baseline: Option<String>,
    /// Reasoning variant of the AERIS agent: `planner` (deterministic, grounded in S_t;
    /// the default), `smollm2` or `gemma3` (language models from the provisioned cache,
    /// shown the planner's plan), `smollm2-aligned` (SmolLM2 with its task-aligned adapter,
    /// never shown the plan).
    #[arg(long)]
    pub reasoning: Option<String>,
    /// Perception of the AERIS agent: `models` (the model roles of workflows/models.toml:
    /// PP-OCRv4 sign reader, colour-palette detector, MiniLM cues, depth occupancy, compose;
    /// the default) or `geometric` (one process segmenting frames by colour, no sign
    /// reading). Baselines fly with `geometric`.
    #[arg(long)]
    pub perception: Option<String>,
    /// The language model reads the task-aligned prompt (short, no plan, what perception
    /// saw placed on the ground): the prompt the aligned reasoner is trained on (`aeris
    /// distill`). Needs a language-model variant.
    #[arg(long)]
    pub aligned: bool,
    /// A language model (`qwen-coder`, `gemma3`, `smollm2`) reads each episode's
    /// instruction before it flies, each part under a grammar made for it: an instruction
    /// without step annotation (AerialVLN's own files) is split, word for word, into steps
    /// with their actions, and every step's turn, relation, landmark (one of perception's
    /// labels), sign text and height are read (`aeris_llm::InstructionReader`). The planner
    /// flies what was read and reads what a reading leaves out by its phrase rules, as it
    /// does every step without this option. Without it an unannotated episode flies two
    /// steps: take off, then the whole instruction.
    #[arg(long, value_name = "VARIANT")]
    pub read_with: Option<String>,
    /// Ablation: the hub's ATT off (the active step is the reasoner's declared step).
    #[arg(long)]
    pub no_att: bool,
    /// Ablation: the language model without the planner's plan in its prompt (a generic
    /// model on its own). Needs a language-model variant (default smollm2).
    #[arg(long)]
    pub zero_shot: bool,
    /// Ablation: one fixed model instead of the role-adaptive stack: the reasoner (and every
    /// role with a variant ladder) stays on its starting variant whatever its latency.
    /// Without it, a language-model reasoner steps down its ladder (gemma3, smollm2,
    /// planner) when it keeps missing its budget, and back up when the heavier one fits.
    #[arg(long)]
    pub single_slm: bool,
    /// Ablation: no dynamic scheduling (roles stay on their declared executors; the
    /// supervisor neither checks the initial binding nor re-binds on latency).
    #[arg(long)]
    pub no_ds: bool,
    /// Output folder for episodes.jsonl and the flights' logs (default:
    /// runs/eval-SPLIT-AGENT, e.g. runs/eval-val_unseen-aeris-planner; with --shard K/N,
    /// runs/eval-SPLIT-AGENT-shard-K-of-N).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print one JSON object with the summary on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// What else `aeris eval` does.
#[derive(Debug, Subcommand)]
enum EvalCommand {
    /// Merge the outputs of `aeris eval --shard K/N` runs (their folders or episodes.jsonl
    /// files) into the table one run of all their episodes prints.
    Merge {
        /// The shards' output folders or episodes.jsonl files.
        #[arg(required = true)]
        paths: Vec<PathBuf>,
        /// Print one JSON object with the summary on the last line of stdout.
        #[arg(long)]
        json: bool,
    },
    /// The ablation table: evaluations of the same episodes side by side (e.g. `aeris
    /// eval compare planner=runs/a aligned=runs/b`), each metric with its 95 % interval
    /// bootstrapped over scenes, and each row's paired difference to the first row.
    Compare {
        /// The rows, in order: NAME=DIR, DIR an `aeris eval` output folder (or its
        /// episodes.jsonl). Every row must have flown the first row's episodes.
        #[arg(required = true, value_name = "NAME=DIR")]
        rows: Vec<String>,
        /// Bootstrap draws.
        #[arg(long, default_value_t = aeris_eval::compare::DEFAULT_RESAMPLES)]
        resamples: usize,
        /// Print one JSON object with the table on the last line of stdout.
        #[arg(long)]
        json: bool,
    },
}

/// Prints each episode's flight (without progress lines), start and score.
pub(crate) struct EpisodePrinter(pub(crate) FlightPrinter);

impl FlightWatcher for EpisodePrinter {
    fn event(&mut self, event: &FlightEvent) {
        self.0.event(event);
    }

    fn interrupted(&self) -> bool {
        self.0.interrupted()
    }
}

impl EvalWatcher for EpisodePrinter {
    fn episode_started(&mut self, k: usize, total: usize, episode: &Episode) {
        eprintln!(
            "[{}/{total}] {} ({}): {}",
            k + 1,
            episode.episode_id,
            episode.scene_id,
            episode.instruction.instruction_text
        );
    }

    fn episode_scored(&mut self, k: usize, total: usize, line: &EpisodeLine<'_>) {
        eprintln!(
            "[{}/{total}] {}: NE {} SR {} OSR {} nDTW {:.3} SPL {:.3} ASR {}/{} ({:.0} s{})",
            k + 1,
            line.episode_id,
            line.metrics
                .ne
                .map(|v| format!("{v:.1} m"))
                .unwrap_or_else(|| "-".into()),
            line.metrics.sr,
            line.metrics.osr,
            line.metrics.ndtw,
            line.metrics.spl,
            line.subgoals_completed,
            line.subgoals_total,
            line.duration_s,
            line.failure.map(|f| format!(", {f}")).unwrap_or_default(),
        );
    }
}

/// Run `aeris eval`.
pub fn run(args: EvalArgs) -> Result<()> {
    if let Some(EvalCommand::Merge { paths, json }) = &args.command {
        let table = aeris_eval::table::merge(paths)?;
        print!("{table}");
        if *json {
            println!("{}", serde_json::to_string(&table)?);
        }
        return Ok(());
    }
    if let Some(EvalCommand::Compare {
        rows,
        resamples,
        json,
    }) = &args.command
    {
        let rows = rows
            .iter()
            .map(|r| match r.split_once('=') {
                Some((name, dir)) if !name.is_empty() && !dir.is_empty() => {
                    Ok((name.to_string(), PathBuf::from(dir)))
                }
                _ => anyhow::bail!("row `{r}`: expected NAME=DIR"),
            })
            .collect::<Result<Vec<_>>>()?;
        if *resamples == 0 {
            anyhow::bail!("--resamples must be at least 1");
        }
        let table = aeris_eval::compare::compare_outputs(&rows, *resamples)?;
        print!("{table}");
        if *json {
            println!("{}", serde_json::to_string(&table)?);
        }
        return Ok(());
    }
    let agent = AgentSetup::resolve(&AgentOptions {
        baseline: args.baseline.clone(),
        reasoning: args.reasoning.clone(),
        perception: args.perception.clone(),
        no_att: args.no_att,
        zero_shot: args.zero_shot,
        single_slm: args.single_slm,
        no_ds: args.no_ds,
        aligned: args.aligned,
    })?;
    let source = match &args.episodes_file {
        Some(file) => EpisodeSource::File(file.clone()),
        None => EpisodeSource::Generate {
            split: Split::parse(&args.split).with_context(|| {
                format!(
                    "unknown split `{}`: use train, val_unseen or test_unseen",
                    args.split
                )
            })?,
            airspace: AirspaceFilter::parse(&args.airspace).with_context(|| {
                format!(
                    "unknown airspace `{}`: use open, dense or full",
                    args.airspace
                )
            })?,
        },
    };
    let out = args.out.clone().unwrap_or_else(|| {
        let shard = args
            .shard
            .map(|s| format!("-shard-{}-of-{}", s.index + 1, s.count))
            .unwrap_or_default();
        PathBuf::from("runs").join(format!("eval-{}-{}{shard}", args.split, agent.label))
    });
    let mut reader = match &args.read_with {
        Some(variant) => Some(ModelStepReader::load(variant)?),
        None => None,
    };
    let config = EvalConfig {
        agent,
        source,
        episodes: args.episodes,
        out,
        record: args.record,
        offload_check: Some(aeris_llm::offload_check),
        shard: args.shard,
        clock: args.clock,
        distill: false,
    };
    let mut printer = EpisodePrinter(FlightPrinter::new(false, "aeris: ")?);
    let report = runner::run(
        &config,
        &mut printer,
        reader.as_mut().map(|r| r as &mut dyn StepReader),
    )?;
    let table = report.table(&config.agent);
    print!("{table}");
    if args.json {
        println!("{}", serde_json::to_string(&table)?);
    }
    Ok(())
}

/// A language model that reads each episode's instruction before it flies
/// (`--read-with`): segments it when it has no steps, reads every step. What fails is said
/// and left to the phrase rules.
struct ModelStepReader {
    reader: aeris_llm::InstructionReader,
    variant: String,
}

impl ModelStepReader {
    fn load(variant: &str) -> Result<Self> {
        let model = aeris_llm::variant_model(variant).with_context(|| {
            format!(
                "--read-with {variant}: not a language model (use qwen-coder, gemma3 or smollm2)"
            )
        })?;
        let store = aeris_models::ModelStore::open(None)?;
        let threads = reader_threads();
        let reader = aeris_llm::InstructionReader::load(&store, model, threads)
            .with_context(|| format!("loading the instruction reader {variant}"))?;
        Ok(Self {
            reader,
            variant: variant.to_string(),
        })
    }
}

/// Threads for the instruction reader: the CPUs this process may run on, less the ones
/// other work keeps busy (measured over [`LOAD_SAMPLE`]), at least one. llama.cpp's workers
/// meet at every layer, so one that shares its core with a busy thread holds the others up:
/// on 2 cores beside two busy threads, reading with two threads took 5-25 times as long as
/// idle. Said on stderr.
fn reader_threads() -> i32 {
    use aeris_orchestrator::executors::{busy_cores, read_proc_stat};
    let cpus = aeris_runtime::affinity::CpuSet::available();
    let before = read_proc_stat();
    std::thread::sleep(LOAD_SAMPLE);
    let busy = busy_cores(&before, &read_proc_stat(), cpus.cpus());
    let threads = threads_beside(cpus.cpus().len(), busy);
    eprintln!(
        "aeris: the instruction reader computes on {threads} thread(s) ({:.1} of {} CPUs busy \
         with other work)",
        busy,
        cpus.cpus().len()
    );
    threads
}

/// How long [`reader_threads`] watches the CPUs.
const LOAD_SAMPLE: std::time::Duration = std::time::Duration::from_millis(300);

/// Threads on `cpus` CPUs of which `busy` are kept busy by other work: the idle ones,
/// rounded to the nearest whole, at least one.
fn threads_beside(cpus: usize, busy: f64) -> i32 {
    let idle = cpus as f64 - busy.max(0.0);
    (idle.round() as i32).clamp(1, cpus.max(1) as i32)
}

impl StepReader for ModelStepReader {
    fn read_steps(&mut self, episode: &Episode) -> Option<Vec<SubgoalSpec>> {
        let started = std::time::Instant::now();
        let id = &episode.episode_id;
        let steps: Vec<(String, String)> = if episode.subgoals.is_empty() {
            match self.reader.segment(&episode.instruction.instruction_text) {
                Ok(steps) => steps.into_iter().map(|s| (s.text, s.action)).collect(),
                Err(err) => {
                    eprintln!(
                        "aeris: {}: episode {id} not segmented ({:#}); it flies take-off, then \
                         the whole instruction",
                        self.variant,
                        anyhow::Error::from(err)
                    );
                    return None;
                }
            }
        } else {
            episode
                .subgoals
                .iter()
                .map(|s| (s.text.clone(), s.action.clone()))
                .collect()
        };
        let mut read = 0;
        let subgoals = steps
            .into_iter()
            .enumerate()
            .map(|(i, (text, action))| {
                let reading = match self.reader.read_step(&text, &LABELS) {
                    Ok(r) => {
                        read += 1;
                        Some(r)
                    }
                    Err(err) => {
                        eprintln!(
                            "aeris: {}: episode {id}, step {} not read ({:#}); the phrase rules \
                             read it",
                            self.variant,
                            i + 1,
                            anyhow::Error::from(err)
                        );
                        None
                    }
                };
                SubgoalSpec {
                    text,
                    action,
                    waypoint: None,
                    reading,
                }
            })
            .collect::<Vec<_>>();
        eprintln!(
            "aeris: {} read episode {id}: {} steps, {read} with a reading, in {:.1} s",
            self.variant,
            subgoals.len(),
            started.elapsed().as_secs_f64()
        );
        Some(subgoals)
    }
}

impl crate::command::Execute for EvalArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}

#[cfg(test)]
mod tests {
    use super::threads_beside;

    #[test]
    fn the_reader_computes_on_the_cpus_other_work_leaves_idle_and_never_on_none() {
        assert_eq!(threads_beside(2, 0.05), 2);
        assert_eq!(threads_beside(2, 1.0), 1);
        assert_eq!(threads_beside(2, 1.97), 1);
        assert_eq!(threads_beside(8, 2.4), 6);
        assert_eq!(threads_beside(1, 0.0), 1);
        assert_eq!(threads_beside(4, -1.0), 4);
    }
}
