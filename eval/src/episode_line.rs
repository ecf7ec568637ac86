//! One line of episodes.jsonl: what `aeris eval` writes of each flown episode, and what it
//! adds to the summaries of its groups ([`EpisodeLine::tally`]).

use crate::metrics::EpisodeMetrics;
use crate::table::EpisodeTally;
use serde::Serialize;
use std::path::Path;

/// One line of episodes.jsonl.
#[derive(Debug, Serialize)]
pub struct EpisodeLine<'a> {
    /// The episode's place in the evaluated list (0-based; with `--shard`, in the whole
    /// list, so that merged shards are summed in one run's order).
    pub index: usize,
    /// Episode id.
    pub episode_id: &'a str,
    /// Scene id.
    pub scene_id: &'a str,
    /// `open`, `dense` or `unknown`.
    pub airspace: &'a str,
    /// The agent's label.
    pub agent: &'a str,
    /// The episodes' origin: the split's name, or the file's path.
    pub split: &'a str,
    /// The baseline flown; `None` for AERIS.
    pub baseline: Option<&'a str>,
    /// The reasoning variant.
    pub reasoning: &'a str,
    /// The instruction.
    pub instruction: &'a str,
    /// Positions kept (one per AerialVLN action step, and the final one).
    pub positions: &'a [[f64; 3]],
    /// The reference path.
    pub reference: &'a [[f64; 3]],
    /// The goal.
    pub goal: [f64; 3],
    /// The agent stopped (no failure).
    pub stopped: bool,
    /// The vehicle touched an obstacle.
    pub collided: bool,
    /// Subgoals of the episode.
    pub subgoals_total: usize,
    /// Subgoals completed.
    pub subgoals_completed: usize,
    /// The attention trace (distinct active steps).
    pub attention_steps: &'a [u16],
    /// The paper's metrics (`ne`, `sr`, `osr`, `ndtw`, `spl`, `asr`, `path_length_m`).
    #[serde(flatten)]
    pub metrics: EpisodeMetrics,
    /// Flight duration (s).
    pub duration_s: f64,
    /// Mean cycle time (s).
    pub ct_mean_s: f64,
    /// 95th percentile of the cycle time (s).
    pub ct_p95_s: f64,
    /// Execution error rate.
    pub eer: f64,
    /// Committed cycles of the flight.
    pub cycles: u64,
    /// Cycles the hub reused the previous decision in (the EER's numerator).
    pub decisions_reused: u64,
    /// Every committed cycle's time (s): what the group's CT mean and P95 are taken over.
    pub ct_samples_s: &'a [f64],
    /// Every committed cycle's compute time on this machine (s; the flight's
    /// `ct_compute_mean_s`): what the group's compute CT is taken over.
    pub ct_compute_samples_s: &'a [f64],
    /// Cycles over the deadline on compute alone, or without a fresh decision (the
    /// group's `eer_compute` numerator).
    pub compute_misses: u64,
    /// The clock the episode flew on (`wall` or `sim`).
    pub clock: aeris_flight::FlightClock,
    /// Wall-clock time the episode's flight took (s; its `duration_s` on simulated time
    /// is simulated).
    pub wall_s: f64,
    /// Why the flight ended early, if it did.
    pub failure: Option<&'a str>,
    /// Automatic variant swaps (the role-adaptive stack's steps) during the flight.
    pub variant_steps: u64,
    /// The flight's run folder: cycles.jsonl, role specs and logs (`aeris plot`).
    pub run_dir: &'a Path,
    /// The episode's recording (`aeris eval --record`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recording: Option<&'a Path>,
}

impl EpisodeLine<'_> {
    /// What this episode adds to its groups' summaries.
    pub fn tally(&self) -> EpisodeTally {
        EpisodeTally {
            index: self.index,
            episode_id: self.episode_id.to_string(),
            scene_id: self.scene_id.to_string(),
            airspace: self.airspace.to_string(),
            agent: self.agent.to_string(),
            split: self.split.to_string(),
            baseline: self.baseline.map(str::to_string),
            reasoning: self.reasoning.to_string(),
            metrics: self.metrics,
            cycles: self.cycles,
            decisions_reused: self.decisions_reused,
            ct_samples_s: self.ct_samples_s.to_vec(),
            ct_compute_samples_s: self.ct_compute_samples_s.to_vec(),
            compute_misses: self.compute_misses,
            clock: self.clock.name().to_string(),
        }
    }
}
