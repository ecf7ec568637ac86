//! Flying VLN episodes through the full multi-process pipeline (one supervised flight of
//! [`aeris_flight`] per episode) and scoring them: `aeris eval`.

pub use crate::agent_setup::{AgentError, AgentOptions, AgentSetup};
use crate::episode::{Episode, EpisodeError, load_episodes};
pub use crate::episode_line::EpisodeLine;
use crate::generate::{AirspaceFilter, GenerateError, Split, generate_split};
use crate::metrics::{EpisodeMetrics, EpisodeRun};
use crate::mission::{Agent, MissionError, StepReader, episode_mission};
pub use crate::shard::{Shard, ShardError};
pub use crate::table::GroupSummary;
use crate::table::{EvalTable, Summaries};
use aeris_flight::{
    Flight, FlightError, FlightWatcher, HookError, Overrides, StepContext, StepHook, StopRule,
};
use aeris_orchestrator::workflow::{Workflow, WorkflowError};
use aeris_runtime::MissionSpec;
use aeris_schemas::RoleKind;
use aeris_sim::world::World;
use std::io::Write;
use std::path::PathBuf;

/// Where the episodes come from.
#[derive(Debug, Clone)]
pub enum EpisodeSource {
    /// Generate a split over these airspaces.
    Generate {
        /// The split.
        split: Split,
        /// Open, dense or both.
        airspace: AirspaceFilter,
    },
    /// Load an episode file (ours or AerialVLN's; its scenes must be ones this simulator has).
    File(PathBuf),
}

/// What `aeris eval` flies.
#[derive(Debug, Clone)]
pub struct EvalConfig {
    /// The agent.
    pub agent: AgentSetup,
    /// The episodes.
    pub source: EpisodeSource,
    /// Episodes to fly (at least 1; a file is cut to this many).
    pub episodes: usize,
    /// Output folder for episodes.jsonl and the flights' run folders.
    pub out: PathBuf,
    /// Record every episode (`RUN_DIR/flight.mcap`, replayable; open a failed one in
    /// Foxglove or replay it with another variant).
    pub record: bool,
    /// The language-model engine's offload check for the flights
    /// ([`aeris_flight::FlightBuilder::language_offload_check`]).
    pub offload_check: Option<aeris_flight::executors::OffloadCheck>,
    /// Fly only this shard of the episodes (`aeris eval --shard K/N`); `None`: all.
    pub shard: Option<Shard>,
    /// The clock the episodes fly on ([`aeris_flight::FlightClock`]).
    pub clock: aeris_flight::FlightClock,
    /// Write training pairs (`aeris distill`): each episode's reasoning role writes its
    /// run folder's [`crate::distill::PAIRS_FILE`], gathered into OUT's after the episode
    /// (check the setup with [`crate::distill::check`] first).
    pub distill: bool,
}

/// An episode's recording, in its run folder (`aeris eval --record`).
pub const EPISODE_RECORDING: &str = "flight.mcap";

/// What an evaluation found.
#[derive(Debug, Clone)]
pub struct EvalReport {
    /// The episodes' origin: the split's name, or the file's path.
    pub label: String,
    /// Where the episode lines are.
    pub jsonl_path: PathBuf,
    /// Every episode.
    pub all: GroupSummary,
    /// The open-airspace episodes.
    pub open: GroupSummary,
    /// The dense-airspace episodes.
    pub dense: GroupSummary,
    /// With [`EvalConfig::distill`]: the training pairs gathered, and where.
    pub pairs: Option<(usize, PathBuf)>,
}

/// Who watches an evaluation: every flight's events, and each episode's start and score.
pub trait EvalWatcher: FlightWatcher {
    /// Episode `k` (0-based) of `total` is about to fly.
    fn episode_started(&mut self, k: usize, total: usize, episode: &Episode);

    /// Episode `k` of `total` flew and was scored (what episodes.jsonl got).
    fn episode_scored(&mut self, k: usize, total: usize, line: &EpisodeLine<'_>);
}

/// Why an evaluation could not run to the end.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// No episodes asked for.
    #[error("--episodes must be at least 1")]
    NoEpisodes,
    /// The episode file could not be loaded.
    #[error(transparent)]
    Episodes(#[from] EpisodeError),
    /// The split could not be generated.
    #[error(transparent)]
    Generate(#[from] GenerateError),
    /// A file or folder of the output could not be written.
    #[error("writing {}", path.display())]
    Output {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// An episode could not be turned into a mission.
    #[error(transparent)]
    Mission(#[from] MissionError),
    /// A built-in workflow is not valid (a build defect).
    #[error("the built-in workflow")]
    BuiltinWorkflow(#[source] WorkflowError),
    /// A built-in workflow lacks a role the evaluation sets up.
    #[error("the built-in workflow has no {0} role")]
    MissingRole(&'static str),
    /// The workflow with the episode's mission is not valid.
    #[error("episode {episode}: mission")]
    EpisodeMission {
        /// The episode.
        episode: String,
        /// What is wrong.
        #[source]
        source: WorkflowError,
    },
    /// An episode's training pairs could not be gathered.
    #[error(transparent)]
    Distill(#[from] crate::distill::DistillError),
    /// An episode's flight could not start or ended with an error.
    #[error("episode {episode}")]
    Flight {
        /// The episode.
        episode: String,
        /// Why.
        #[source]
        source: FlightError,
    },
}

/// Radius (m) of the sphere around the vehicle's position that must stay clear of
/// obstacles.
const COLLISION_RADIUS_M: f32 = 0.3;

/// Positions are kept when the vehicle moved 5 m horizontally or 2 m vertically from the
/// last kept one: AerialVLN's action steps, the reference's sampling.
fn moved_a_step(last: [f64; 3], p: [f64; 3]) -> bool {
    (p[0] - last[0]).hypot(p[1] - last[1]) >= 5.0 || (p[2] - last[2]).abs() >= 2.0
}

/// The step hook of an episode: keeps the positions and ends the flight on a collision.
struct PathWatch {
    world: World,
    positions: Vec<[f64; 3]>,
    collided: Option<[f32; 3]>,
}

impl StepHook for PathWatch {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        if let Some(p) = ctx.monitor.position() {
            // touching an obstacle ends the episode, as in AerialVLN (the ground is not an
            // obstacle: the vehicle lands on it)
            if self
                .world
                .collides([p[0], p[1], p[2].max(0.0)], COLLISION_RADIUS_M)
            {
                self.collided = Some(p);
            }
            let p = [p[0] as f64, p[1] as f64, p[2] as f64];
            if self
                .positions
                .last()
                .is_none_or(|&last| moved_a_step(last, p))
            {
                self.positions.push(p);
            }
        }
        Ok(self.collided.is_some())
    }
}

/// The workflow episode `k` flies: the agent's roles with the episode's mission.
fn episode_workflow(
    setup: &AgentSetup,
    mission: MissionSpec,
    k: usize,
    episode_id: &str,
) -> Result<Workflow, EvalError> {
    let mut workflow = if setup.models {
        let mut w = Workflow::builtin_models().map_err(EvalError::BuiltinWorkflow)?;
        // the roofs, bridges and signs the instructions name are the palette's classes;
        // the COCO detector has none of them
        w.roles
            .iter_mut()
            .find(|r| r.kind == RoleKind::Detector)
            .ok_or(EvalError::MissingRole("detector"))?
            .variant = "palette".into();
        w
    } else {
        Workflow::builtin_default().map_err(EvalError::BuiltinWorkflow)?
    };
    workflow.mission = mission;
    let reasoning = workflow
        .roles
        .iter_mut()
        .find(|r| r.kind == RoleKind::Reasoning)
        .ok_or(EvalError::MissingRole("reasoning"))?;
    reasoning.variant = setup.reasoning.clone();
    if !reasoning.variants.iter().any(|v| v == &reasoning.variant) {
        reasoning.variants.push(reasoning.variant.clone());
    }
    reasoning
        .params
        .insert("seed".into(), serde_json::Value::from(k as u64 + 1));
    // the ladder starts on the chosen variant; a zero-shot model stays generic (the planner
    // below it on the ladder would bring the plan back)
    if setup.zero_shot || !reasoning.ladder.contains(&reasoning.variant) {
        reasoning.ladder.clear();
    }
    if setup.zero_shot {
        reasoning
            .params
            .insert("plan".into(), serde_json::Value::from(false));
    }
    if setup.aligned {
        // one aligned model: the ladder's other rungs read other prompts
        reasoning.ladder.clear();
        reasoning
            .params
            .insert("prompt".into(), serde_json::Value::from("aligned"));
    }
    if setup.single_slm {
        workflow.scheduling.adapt_variants = false;
    }
    if setup.no_att {
        workflow
            .roles
            .iter_mut()
            .find(|r| r.kind == RoleKind::Hub)
            .ok_or(EvalError::MissingRole("hub"))?
            .params
            .insert("no_att".into(), serde_json::Value::from(true));
    }
    workflow
        .validate()
        .map_err(|source| EvalError::EpisodeMission {
            episode: episode_id.to_string(),
            source,
        })?;
    Ok(workflow)
}

/// Fly every episode, write OUT/episodes.jsonl, and summarise per airspace; `reader`, when
/// given, reads each episode's instruction before it flies (the AERIS agent's steps).
pub fn run(
    config: &EvalConfig,
    watcher: &mut dyn EvalWatcher,
    mut reader: Option<&mut dyn StepReader>,
) -> Result<EvalReport, EvalError> {
    let setup = &config.agent;
    if config.episodes == 0 {
        return Err(EvalError::NoEpisodes);
    }
    let (label, episodes): (String, Vec<Episode>) = match &config.source {
        EpisodeSource::File(file) => {
            let mut list = load_episodes(file)?;
            list.truncate(config.episodes);
            if config.distill {
                crate::distill::check_episodes(&list)?;
            }
            (file.display().to_string(), list)
        }
        EpisodeSource::Generate { split, airspace } => {
            let list = generate_split(*split, *airspace, config.episodes, &mut |_, _| {})?;
            (split.as_str().to_string(), list)
        }
    };
    let out = &config.out;
    std::fs::create_dir_all(out).map_err(|source| EvalError::Output {
        path: out.clone(),
        source,
    })?;
    let jsonl_path = out.join("episodes.jsonl");
    let write_error = |source| EvalError::Output {
        path: jsonl_path.clone(),
        source,
    };
    let mut jsonl = std::fs::File::create(&jsonl_path).map_err(write_error)?;
    let chosen: Vec<(usize, &Episode)> = episodes
        .iter()
        .enumerate()
        .filter(|(k, _)| config.shard.is_none_or(|s| s.holds(*k)))
        .collect();
    let total = chosen.len();
    let baseline = match setup.agent {
        Agent::Aeris => None,
        a => Some(a.as_str()),
    };
    let mut tallies = Vec::with_capacity(total);
    let mut pairs_written = 0;
    let pairs_path = out.join(crate::distill::PAIRS_FILE);
    let mut pairs = config
        .distill
        .then(|| std::fs::File::create(&pairs_path).map(std::io::BufWriter::new))
        .transpose()
        .map_err(|source| EvalError::Output {
            path: pairs_path.clone(),
            source,
        })?;
    for (n, (k, episode)) in chosen.into_iter().enumerate() {
        let read = match (&mut reader, setup.agent) {
            (Some(r), Agent::Aeris) => r.read_steps(episode),
            _ => None,
        };
        let em = episode_mission(episode, setup.agent, read.as_deref())?;
        let mut workflow = episode_workflow(setup, em.mission, k, &episode.episode_id)?;
        let flight = format!("eval-{}-{k}", std::process::id());
        let run_dir = out.join("runs").join(&flight);
        // with --distill: where the reasoning role writes this episode's pairs
        let episode_pairs = pairs
            .is_some()
            .then(|| std::path::absolute(run_dir.join(crate::distill::PAIRS_FILE)))
            .transpose()
            .map_err(|source| EvalError::Output {
                path: run_dir.clone(),
                source,
            })?;
        if let Some(episode_pairs) = &episode_pairs {
            workflow
                .roles
                .iter_mut()
                .find(|r| r.kind == RoleKind::Reasoning)
                .ok_or(EvalError::MissingRole("reasoning"))?
                .params
                .insert(
                    aeris_runtime::DISTILL_PARAM.into(),
                    serde_json::Value::from(episode_pairs.to_string_lossy().into_owned()),
                );
        }
        watcher.episode_started(n, total, episode);
        let watch = PathWatch {
            world: em.world,
            positions: vec![episode.start_position],
            collided: None,
        };
        let flight_error = |source| EvalError::Flight {
            episode: episode.episode_id.clone(),
            source,
        };
        let mut builder = Flight::builder(workflow)
            .name(flight)
            .run_dir(&run_dir)
            .stop_when(StopRule::Landed)
            .clock(config.clock)
            .overrides(Overrides {
                dynamic: setup.no_ds.then_some(false),
                ..Overrides::default()
            });
        if let Some(check) = config.offload_check {
            builder = builder.language_offload_check(check);
        }
        let recording = config.record.then(|| run_dir.join(EPISODE_RECORDING));
        if let Some(path) = &recording {
            builder = builder.record(path);
        }
        let (outcome, watch) = builder
            .step_hook(watch)
            .start()
            .and_then(|f| f.watch(&mut *watcher))
            .map_err(flight_error)?;
        let summary = outcome.summary;
        let PathWatch {
            mut positions,
            collided,
            ..
        } = watch;
        // the final position always counts
        let last = summary.final_position;
        if positions.last() != Some(&last) && summary.controller_ticks > 0 {
            positions.push(last);
        }
        let failure = match (outcome.failure, collided) {
            (None, Some(p)) => Some(format!(
                "collided with an obstacle at [{:.1}, {:.1}, {:.1}]",
                p[0], p[1], p[2]
            )),
            (f, _) => f.map(|f| f.to_string()),
        };
        let stopped = failure.is_none();
        // instruction steps completed: those whose mission steps the attention moved past,
        // and the last one too when the agent stopped at the goal (within the acceptance
        // radius of a mission that knows it, or the success radius of the episode's)
        let at_goal = summary.reached_goal
            || crate::metrics::distance(summary.final_position, episode.goal())
                <= crate::metrics::SUCCESS_RADIUS_M;
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
        let success = m.sr > 0.5;
        let airspace = episode.airspace.as_deref().unwrap_or("unknown");
        let line = EpisodeLine {
            index: k,
            episode_id: &episode.episode_id,
            scene_id: &episode.scene_id,
            airspace,
            agent: &setup.label,
            split: &label,
            baseline,
            reasoning: &setup.reasoning,
            instruction: &episode.instruction.instruction_text,
            positions: &positions,
            reference: &reference,
            goal: episode.goal(),
            stopped,
            collided: collided.is_some(),
            subgoals_total,
            subgoals_completed,
            attention_steps: &summary.attention_steps,
            metrics: m,
            duration_s: summary.duration_s,
            ct_mean_s: summary.ct_mean_s,
            ct_p95_s: summary.ct_p95_s,
            eer: summary.eer,
            cycles: summary.cycles,
            decisions_reused: summary.hub.decisions_reused,
            ct_samples_s: &outcome.ct_samples_s,
            ct_compute_samples_s: &outcome.ct_compute_samples_s,
            compute_misses: outcome.compute_misses,
            clock: summary.clock,
            wall_s: summary.wall_s,
            failure: failure.as_deref(),
            variant_steps: summary.variant_steps,
            run_dir: &run_dir,
            recording: recording.as_deref(),
        };
        if let (Some(out), Some(episode_pairs)) = (&mut pairs, &episode_pairs) {
            let origin = crate::distill::PairOrigin {
                episode_id: &episode.episode_id,
                scene_id: &episode.scene_id,
                agent: &setup.label,
                success,
                dagger: setup.reasoning != "planner",
            };
            pairs_written += crate::distill::gather(episode_pairs, &origin, out)?;
            out.flush().map_err(|source| EvalError::Output {
                path: pairs_path.clone(),
                source,
            })?;
        }
        let text = serde_json::to_string(&line).map_err(|e| write_error(e.into()))?;
        writeln!(jsonl, "{text}").map_err(write_error)?;
        watcher.episode_scored(n, total, &line);
        tallies.push(line.tally());
    }
    let Summaries { all, open, dense } = Summaries::of(&tallies);
    Ok(EvalReport {
        label,
        jsonl_path,
        all,
        open,
        dense,
        pairs: config.distill.then_some((pairs_written, pairs_path)),
    })
}

impl EvalReport {
    /// The table of this evaluation of `setup`.
    pub fn table(&self, setup: &AgentSetup) -> EvalTable {
        EvalTable {
            split: self.label.clone(),
            agent: setup.label.clone(),
            baseline: match setup.agent {
                Agent::Aeris => None,
                a => Some(a.as_str().to_string()),
            },
            reasoning: setup.reasoning.clone(),
            all: self.all.clone(),
            open: self.open.clone(),
            dense: self.dense.clone(),
            details: self.jsonl_path.display().to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_episode_line_keeps_its_keys_in_order_with_the_metrics_inline() {
        let line = EpisodeLine {
            index: 3,
            episode_id: "e1",
            scene_id: "s",
            airspace: "open",
            agent: "oracle",
            split: "val_unseen",
            baseline: Some("oracle"),
            reasoning: "planner",
            instruction: "fly",
            positions: &[[0.0, 0.0, 0.0]],
            reference: &[],
            goal: [1.0, 2.0, 3.0],
            stopped: true,
            collided: false,
            subgoals_total: 1,
            subgoals_completed: 1,
            attention_steps: &[1],
            metrics: EpisodeMetrics {
                ne: None,
                sr: 1.0,
                osr: 1.0,
                ndtw: 0.5,
                spl: 0.25,
                asr: Some(1.0),
                path_length_m: 10.0,
            },
            duration_s: 2.0,
            ct_mean_s: 0.1,
            ct_p95_s: 0.2,
            eer: 0.0,
            cycles: 2,
            decisions_reused: 0,
            ct_samples_s: &[0.1, 0.2],
            ct_compute_samples_s: &[0.05, 0.06],
            compute_misses: 0,
            clock: aeris_flight::FlightClock::Sim,
            wall_s: 0.5,
            failure: None,
            variant_steps: 0,
            run_dir: std::path::Path::new("runs/x"),
            recording: None,
        };
        assert_eq!(
            serde_json::to_string(&line).unwrap(),
            r#"{"index":3,"episode_id":"e1","scene_id":"s","airspace":"open","agent":"oracle","split":"val_unseen","baseline":"oracle","reasoning":"planner","instruction":"fly","positions":[[0.0,0.0,0.0]],"reference":[],"goal":[1.0,2.0,3.0],"stopped":true,"collided":false,"subgoals_total":1,"subgoals_completed":1,"attention_steps":[1],"ne":null,"sr":1.0,"osr":1.0,"ndtw":0.5,"spl":0.25,"asr":1.0,"path_length_m":10.0,"duration_s":2.0,"ct_mean_s":0.1,"ct_p95_s":0.2,"eer":0.0,"cycles":2,"decisions_reused":0,"ct_samples_s":[0.1,0.2],"ct_compute_samples_s":[0.05,0.06],"compute_misses":0,"clock":"sim","wall_s":0.5,"failure":null,"variant_steps":0,"run_dir":"runs/x"}"#
        );
    }
}
