//! `aeris eval`: fly VLN episodes through the full multi-process pipeline and score them.

use crate::run_cmd::{FlightOutcome, FlightPlan, StopRule, fly};
use aeris_eval::episode::{Episode, load_episodes};
use aeris_eval::generate::{AirspaceFilter, Split, generate_split};
use aeris_eval::metrics::{EpisodeMetrics, EpisodeRun, MetricsSummary};
use aeris_eval::mission::{Agent, episode_mission};
use aeris_orchestrator::Workflow;
use aeris_runtime::stats::{mean_std, percentile};
use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

/// Arguments of `aeris eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
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
    /// shown the planner's plan).
    #[arg(long)]
    pub reasoning: Option<String>,
    /// Perception of the AERIS agent: `models` (the model roles of workflows/models.toml:
    /// PP-OCRv4 sign reader, colour-palette detector, MiniLM cues, depth occupancy, compose;
    /// the default) or `geometric` (one process segmenting frames by colour, no sign
    /// reading). Baselines fly with `geometric`.
    #[arg(long)]
    pub perception: Option<String>,
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
    /// runs/eval-SPLIT-AGENT, e.g. runs/eval-val_unseen-aeris-planner).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print one JSON object with the summary on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// One line of episodes.jsonl.
#[derive(Debug, Serialize)]
struct EpisodeLine<'a> {
    episode_id: &'a str,
    scene_id: &'a str,
    airspace: &'a str,
    agent: &'a str,
    instruction: &'a str,
    positions: &'a [[f64; 3]],
    reference: &'a [[f64; 3]],
    goal: [f64; 3],
    stopped: bool,
    collided: bool,
    subgoals_total: usize,
    subgoals_completed: usize,
    attention_steps: &'a [u16],
    ne: Option<f64>,
    sr: f64,
    osr: f64,
    ndtw: f64,
    spl: f64,
    asr: Option<f64>,
    path_length_m: f64,
    duration_s: f64,
    ct_mean_s: f64,
    ct_p95_s: f64,
    eer: f64,
    failure: Option<&'a str>,
    /// Automatic variant swaps (the role-adaptive stack's steps) during the flight.
    variant_steps: u64,
    /// The flight's run folder: cycles.jsonl, role specs and logs (`aeris plot`).
    run_dir: &'a std::path::Path,
}

/// The summary of a group of episodes.
#[derive(Debug, Clone, Serialize)]
struct GroupSummary {
    #[serde(flatten)]
    m: MetricsSummary,
    ct_mean_s: f64,
    ct_p95_s: f64,
    eer: f64,
}

#[derive(Default)]
struct Group {
    metrics: Vec<EpisodeMetrics>,
    ct: Vec<f64>,
    cycles: u64,
    reused: u64,
}

impl Group {
    fn summary(&self) -> GroupSummary {
        let m = MetricsSummary::of(&self.metrics);
        GroupSummary {
            m,
            ct_mean_s: mean_std(&self.ct).map_or(0.0, |(mean, _)| mean),
            ct_p95_s: percentile(&self.ct, 95.0).unwrap_or(0.0),
            eer: if self.cycles == 0 {
                0.0
            } else {
                self.reused as f64 / self.cycles as f64
            },
        }
    }
}

/// Radius (m) of the sphere around the vehicle's position that must stay clear of
/// obstacles.
const COLLISION_RADIUS_M: f32 = 0.3;

/// Positions are kept when the vehicle moved 5 m horizontally or 2 m vertically from the
/// last kept one: AerialVLN's action steps, the reference's sampling.
fn moved_a_step(last: [f64; 3], p: [f64; 3]) -> bool {
    (p[0] - last[0]).hypot(p[1] - last[1]) >= 5.0 || (p[2] - last[2]).abs() >= 2.0
}

/// Run `aeris eval`.
pub fn run(args: EvalArgs) -> Result<()> {
    let setup = EvalSetup::from_args(&args)?;
    let agent = setup.agent;
    if args.episodes == 0 {
        bail!("--episodes must be at least 1");
    }
    let (label, episodes): (String, Vec<Episode>) = match &args.episodes_file {
        Some(file) => {
            let mut list = load_episodes(file)?;
            list.truncate(args.episodes);
            (file.display().to_string(), list)
        }
        None => {
            let split = Split::parse(&args.split).with_context(|| {
                format!(
                    "unknown split `{}`: use train, val_unseen or test_unseen",
                    args.split
                )
            })?;
            let filter = AirspaceFilter::parse(&args.airspace).with_context(|| {
                format!(
                    "unknown airspace `{}`: use open, dense or full",
                    args.airspace
                )
            })?;
            let list = generate_split(split, filter, args.episodes, &mut |_, _| {})?;
            (split.as_str().to_string(), list)
        }
    };
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from("runs").join(format!("eval-{}-{}", args.split, setup.label))
    });
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let jsonl_path = out.join("episodes.jsonl");
    let mut jsonl = std::fs::File::create(&jsonl_path)
        .with_context(|| format!("creating {}", jsonl_path.display()))?;
    let total = episodes.len();
    let mut all = Group::default();
    let mut open = Group::default();
    let mut dense = Group::default();
    for (k, episode) in episodes.iter().enumerate() {
        let em = episode_mission(episode, agent)?;
        let mut workflow = if setup.models {
            let mut w = Workflow::builtin_models().context("the built-in model workflow")?;
            // the roofs, bridges and signs the instructions name are the palette's classes;
            // the COCO detector has none of them
            w.roles
                .iter_mut()
                .find(|r| r.kind == "detector")
                .context("the model workflow has no detector")?
                .variant = "palette".into();
            w
        } else {
            Workflow::builtin_default().context("the built-in workflow")?
        };
        workflow.mission = em.mission.clone();
        let reasoning = workflow
            .roles
            .iter_mut()
            .find(|r| r.kind == "reasoning")
            .context("the built-in workflow has no reasoning role")?;
        reasoning.variant = setup.reasoning.clone();
        if !reasoning.variants.iter().any(|v| v == &reasoning.variant) {
            reasoning.variants.push(reasoning.variant.clone());
        }
        reasoning
            .params
            .insert("seed".into(), serde_json::Value::from(k as u64 + 1));
        // the ladder starts on the chosen variant; a zero-shot model stays generic (the
        // planner below it on the ladder would bring the plan back)
        if setup.zero_shot || !reasoning.ladder.contains(&reasoning.variant) {
            reasoning.ladder.clear();
        }
        if setup.zero_shot {
            reasoning
                .params
                .insert("plan".into(), serde_json::Value::from(false));
        }
        if setup.single_slm {
            workflow.scheduling.adapt_variants = false;
        }
        if setup.no_att {
            workflow
                .roles
                .iter_mut()
                .find(|r| r.kind == "hub")
                .context("the built-in workflow has no hub")?
                .params
                .insert("no_att".into(), serde_json::Value::from(true));
        }
        workflow
            .validate()
            .with_context(|| format!("episode {}: mission", episode.episode_id))?;
        let flight = format!("eval-{}-{k}", std::process::id());
        let plan = FlightPlan {
            run_dir: out.join("runs").join(&flight),
            flight,
            autopilot: None,
            stop: StopRule::Landed,
            progress: false,
            dynamic: setup.no_ds.then_some(false),
        };
        eprintln!(
            "[{}/{total}] {} ({}): {}",
            k + 1,
            episode.episode_id,
            episode.scene_id,
            episode.instruction.instruction_text
        );
        let start = episode.start_position;
        let mut positions: Vec<[f64; 3]> = vec![start];
        let mut collided = None;
        let FlightOutcome {
            summary,
            failure,
            ct_samples_s,
            ..
        } = fly(workflow, &plan, |_, monitor, _| {
            if let Some(p) = monitor.position() {
                // touching an obstacle ends the episode, as in AerialVLN (the ground is
                // not an obstacle: the vehicle lands on it)
                if em
                    .world
                    .collides([p[0], p[1], p[2].max(0.0)], COLLISION_RADIUS_M)
                {
                    collided = Some(p);
                }
                let p = [p[0] as f64, p[1] as f64, p[2] as f64];
                if positions.last().is_none_or(|&last| moved_a_step(last, p)) {
                    positions.push(p);
                }
            }
            Ok(collided.is_some())
        })
        .with_context(|| format!("episode {}", episode.episode_id))?;
        // the final position always counts
        let last = summary.final_position;
        if positions.last() != Some(&last) && summary.controller_ticks > 0 {
            positions.push(last);
        }
        let failure = match (failure, collided) {
            (None, Some(p)) => Some(format!(
                "collided with an obstacle at [{:.1}, {:.1}, {:.1}]",
                p[0], p[1], p[2]
            )),
            (f, _) => f,
        };
        let stopped = failure.is_none();
        // instruction steps completed: those whose mission steps the attention moved past,
        // and the last one too when the agent stopped at the goal (within the acceptance
        // radius of a mission that knows it, or the success radius of the episode's)
        let at_goal = summary.reached_goal
            || aeris_eval::metrics::distance(summary.final_position, episode.goal())
                <= aeris_eval::metrics::SUCCESS_RADIUS_M;
        let done_steps =
            (summary.max_active_step as usize).saturating_sub(1) + usize::from(stopped && at_goal);
        let subgoals_total = episode.subgoals.len().max(1);
        let subgoals_completed = (0..subgoals_total)
            .filter(|&j| {
                em.step_subgoal
                    .iter()
                    .enumerate()
                    .filter(|&(_, &s)| s == j)
                    .all(|(i, _)| i < done_steps)
            })
            .count();
        let reference = episode.reference_positions();
        let run = EpisodeRun {
            positions: &positions,
            reference: &reference,
            goal: episode.goal(),
            stopped,
            subgoals_completed,
            subgoals_total: if episode.subgoals.is_empty() {
                0
            } else {
                subgoals_total
            },
        };
        let m = EpisodeMetrics::compute(&run);
        let airspace = episode.airspace.as_deref().unwrap_or("unknown");
        let line = EpisodeLine {
            episode_id: &episode.episode_id,
            scene_id: &episode.scene_id,
            airspace,
            agent: &setup.label,
            instruction: &episode.instruction.instruction_text,
            positions: &positions,
            reference: &reference,
            goal: episode.goal(),
            stopped,
            collided: collided.is_some(),
            subgoals_total,
            subgoals_completed,
            attention_steps: &summary.attention_steps,
            ne: m.ne,
            sr: m.sr,
            osr: m.osr,
            ndtw: m.ndtw,
            spl: m.spl,
            asr: m.asr,
            path_length_m: m.path_length_m,
            duration_s: summary.duration_s,
            ct_mean_s: summary.ct_mean_s,
            ct_p95_s: summary.ct_p95_s,
            eer: summary.eer,
            failure: failure.as_deref(),
            variant_steps: summary.variant_steps,
            run_dir: &plan.run_dir,
        };
        writeln!(jsonl, "{}", serde_json::to_string(&line)?)
            .with_context(|| format!("writing {}", jsonl_path.display()))?;
        eprintln!(
            "[{}/{total}] {}: NE {} SR {} OSR {} nDTW {:.3} SPL {:.3} ASR {}/{} ({:.0} s{})",
            k + 1,
            episode.episode_id,
            m.ne.map(|v| format!("{v:.1} m"))
                .unwrap_or_else(|| "-".into()),
            m.sr,
            m.osr,
            m.ndtw,
            m.spl,
            subgoals_completed,
            subgoals_total,
            summary.duration_s,
            failure
                .as_deref()
                .map(|f| format!(", {f}"))
                .unwrap_or_default(),
        );
        for group in [
            Some(&mut all),
            (airspace == "open").then_some(&mut open),
            (airspace == "dense").then_some(&mut dense),
        ]
        .into_iter()
        .flatten()
        {
            group.metrics.push(m);
            group.ct.extend_from_slice(&ct_samples_s);
            group.cycles += summary.cycles;
            group.reused += summary.decisions_reused;
        }
    }
    let overall = all.summary();
    println!(
        "{label}, agent {}: {} episodes (details in {})",
        setup.label,
        overall.m.episodes,
        jsonl_path.display()
    );
    println!(
        "  {:<8} {:>4} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6}",
        "airspace", "n", "NE m", "SR%", "OSR%", "nDTW%", "SPL%", "ASR%", "CT s", "P95 s", "EER%"
    );
    let pct = |v: f64| format!("{:.1}", v * 100.0);
    let groups = [("open", &open), ("dense", &dense), ("full", &all)];
    for (name, g) in groups {
        let GroupSummary {
            m: s,
            ct_mean_s,
            ct_p95_s,
            eer,
        } = g.summary();
        if s.episodes == 0 {
            continue;
        }
        println!(
            "  {:<8} {:>4} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8.3} {:>8.3} {:>6}",
            name,
            s.episodes,
            s.ne.map(|v| format!("{v:.1}"))
                .unwrap_or_else(|| "-".into()),
            pct(s.sr),
            pct(s.osr),
            pct(s.ndtw),
            pct(s.spl),
            s.asr.map(pct).unwrap_or_else(|| "-".into()),
            ct_mean_s,
            ct_p95_s,
            pct(eer)
        );
    }
    if args.json {
        let mut obj = serde_json::to_value(&overall)?;
        obj["split"] = serde_json::Value::from(label);
        obj["agent"] = serde_json::Value::from(setup.label.as_str());
        obj["baseline"] = match agent {
            Agent::Aeris => serde_json::Value::Null,
            a => serde_json::Value::from(a.as_str()),
        };
        obj["reasoning"] = serde_json::Value::from(setup.reasoning.as_str());
        obj["open"] = serde_json::to_value(open.summary())?;
        obj["dense"] = serde_json::to_value(dense.summary())?;
        println!("{obj}");
    }
    Ok(())
}

/// Who flies and how, from the command line.
struct EvalSetup {
    agent: Agent,
    /// Reasoning variant of the flights.
    reasoning: String,
    no_att: bool,
    zero_shot: bool,
    /// Dynamic scheduling off in every flight.
    no_ds: bool,
    /// The variant ladder off in every flight (Single-SLM).
    single_slm: bool,
    /// Fly with the model perception roles (else the geometric one).
    models: bool,
    /// `aeris-planner`, `aeris-smollm2-zero-shot`, `oracle`, ...: the `agent` of
    /// episodes.jsonl and the default output folder's suffix.
    label: String,
}

impl EvalSetup {
    fn from_args(args: &EvalArgs) -> Result<Self> {
        let agent = match &args.baseline {
            None => Agent::Aeris,
            Some(name) => match Agent::parse(name) {
                Some(a @ (Agent::Oracle | Agent::Random)) => a,
                _ => bail!("unknown baseline `{name}`: use oracle or random"),
            },
        };
        if agent != Agent::Aeris
            && (args.reasoning.is_some()
                || args.no_att
                || args.zero_shot
                || args.no_ds
                || args.single_slm
                || args.perception.is_some())
        {
            bail!(
                "--reasoning, --perception, --no-att, --no-ds, --single-slm and --zero-shot apply \
                 to the AERIS agent, not to a --baseline"
            );
        }
        let models = match args.perception.as_deref() {
            None => agent == Agent::Aeris,
            Some("models") => true,
            Some("geometric") => false,
            Some(other) => bail!("unknown perception `{other}`: use models or geometric"),
        };
        let reasoning = match (&args.reasoning, args.zero_shot) {
            (Some(r), _) => r.clone(),
            (None, true) => "smollm2".to_string(),
            (None, false) => agent.reasoning_variant().to_string(),
        };
        let language = matches!(reasoning.as_str(), "smollm2" | "gemma3");
        if agent == Agent::Aeris && !(language || reasoning == "planner") {
            bail!("unknown reasoning variant `{reasoning}`: use planner, smollm2 or gemma3");
        }
        if args.zero_shot && !language {
            bail!(
                "--zero-shot ablates the language model's plan: use --reasoning smollm2 or gemma3"
            );
        }
        let label = match agent {
            Agent::Aeris => {
                let mut l = format!("aeris-{reasoning}");
                if !models {
                    l.push_str("-geometric");
                }
                if args.no_att {
                    l.push_str("-no-att");
                }
                if args.zero_shot {
                    l.push_str("-zero-shot");
                }
                if args.no_ds {
                    l.push_str("-no-ds");
                }
                if args.single_slm {
                    l.push_str("-single-slm");
                }
                l
            }
            a => a.as_str().to_string(),
        };
        Ok(Self {
            agent,
            reasoning,
            no_att: args.no_att,
            zero_shot: args.zero_shot,
            no_ds: args.no_ds,
            single_slm: args.single_slm,
            models,
            label,
        })
    }
}
