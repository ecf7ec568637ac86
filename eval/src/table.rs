//! What the evaluation commands report, as values: `aeris eval`'s table ([`EvalTable`]),
//! the per-airspace summaries it is made of ([`Summaries`], from one [`EpisodeTally`] per
//! episode, which a line of episodes.jsonl carries, so that shards flown apart merge into
//! the table one run would have printed: [`merge`]), `aeris episodes check`'s summary of an
//! episode file ([`EpisodeFileSummary`]), and the part of an episodes.jsonl line that maps
//! read back ([`ExecutedEpisode`]). Each prints as the command's text (`Display`) and
//! serialises as its `--json`.

use crate::episode::Episode;
use crate::metrics::{EpisodeMetrics, MetricsSummary};
use aeris_runtime::stats::{mean_std, percentile};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// One evaluation's summary, per airspace: the table `aeris eval` ends with.
#[derive(Debug, Clone, Serialize)]
pub struct EvalTable {
    /// The episodes' origin: the split's name, or the file's path.
    pub split: String,
    /// The agent's label (`aeris-planner`, `oracle`, ...).
    pub agent: String,
    /// The baseline flown (`oracle`, `random`); `None` for AERIS.
    pub baseline: Option<String>,
    /// The reasoning variant.
    pub reasoning: String,
    /// Every episode.
    #[serde(flatten)]
    pub all: GroupSummary,
    /// The open-airspace episodes.
    pub open: GroupSummary,
    /// The dense-airspace episodes.
    pub dense: GroupSummary,
    /// Where the episode lines are (one file, or the shards' files).
    #[serde(skip)]
    pub details: String,
}

impl fmt::Display for EvalTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}, agent {}: {} episodes (details in {})",
            self.split, self.agent, self.all.metrics.episodes, self.details
        )?;
        writeln!(
            f,
            "  {:<8} {:>4} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6} {:>8} {:>6}",
            "airspace",
            "n",
            "NE m",
            "SR%",
            "OSR%",
            "nDTW%",
            "SPL%",
            "ASR%",
            "CT s",
            "P95 s",
            "EER%",
            "CTc s",
            "EERc%"
        )?;
        let pct = |v: f64| format!("{:.1}", v * 100.0);
        for (name, g) in [
            ("open", &self.open),
            ("dense", &self.dense),
            ("full", &self.all),
        ] {
            let s = &g.metrics;
            if s.episodes == 0 {
                continue;
            }
            writeln!(
                f,
                "  {:<8} {:>4} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8.3} {:>8.3} {:>6} {:>8.3} {:>6}",
                name,
                s.episodes,
                s.ne.map(|v| format!("{v:.1}"))
                    .unwrap_or_else(|| "-".into()),
                pct(s.sr),
                pct(s.osr),
                pct(s.ndtw),
                pct(s.spl),
                s.asr.map(pct).unwrap_or_else(|| "-".into()),
                g.ct_mean_s,
                g.ct_p95_s,
                pct(g.eer),
                g.ct_compute_mean_s,
                pct(g.eer_compute)
            )?;
        }
        Ok(())
    }
}

/// The summary of a group of episodes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupSummary {
    /// The paper's metrics, averaged.
    #[serde(flatten)]
    pub metrics: MetricsSummary,
    /// Mean cycle time over every committed cycle of the group (s).
    pub ct_mean_s: f64,
    /// Its 95th percentile (s).
    pub ct_p95_s: f64,
    /// Reused cycles over all cycles of the group.
    pub eer: f64,
    /// Mean compute time of the group's committed cycles on the machines that flew them
    /// (s): what CT would be without waiting (on simulated time, where CT is 0, the figure
    /// that says whether the models keep up).
    pub ct_compute_mean_s: f64,
    /// Cycles over the deadline on compute alone, or without a fresh decision, over all
    /// cycles of the group.
    pub eer_compute: f64,
}

/// What one flown episode adds to the summaries of its groups: read from its line of
/// episodes.jsonl (the fields of [`crate::episode_line::EpisodeLine`] of the same names).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeTally {
    /// The episode's place in the evaluated list.
    pub index: usize,
    /// Episode id.
    pub episode_id: String,
    /// Its scene (empty in lines written before it was read back).
    #[serde(default)]
    pub scene_id: String,
    /// `open`, `dense` or `unknown`.
    pub airspace: String,
    /// The agent's label.
    pub agent: String,
    /// The episodes' origin.
    pub split: String,
    /// The baseline flown; `None` for AERIS.
    pub baseline: Option<String>,
    /// The reasoning variant.
    pub reasoning: String,
    /// Its metrics.
    #[serde(flatten)]
    pub metrics: EpisodeMetrics,
    /// Committed cycles.
    pub cycles: u64,
    /// Cycles that reused the previous decision.
    pub decisions_reused: u64,
    /// Every committed cycle's time (s).
    pub ct_samples_s: Vec<f64>,
    /// Every committed cycle's compute time on this machine (s); none in lines written
    /// before it was measured.
    #[serde(default)]
    pub ct_compute_samples_s: Vec<f64>,
    /// Cycles over the deadline on compute alone, or without a fresh decision.
    #[serde(default)]
    pub compute_misses: u64,
    /// The clock the episode flew on (`wall` in lines written before simulated time).
    #[serde(default = "wall_clock")]
    pub clock: String,
}

fn wall_clock() -> String {
    "wall".into()
}

/// The summaries of an evaluation: every episode, the open-airspace ones, the dense ones.
#[derive(Debug, Clone, PartialEq)]
pub struct Summaries {
    /// Every episode.
    pub all: GroupSummary,
    /// The open-airspace episodes.
    pub open: GroupSummary,
    /// The dense-airspace episodes.
    pub dense: GroupSummary,
}

impl Summaries {
    /// The summaries of `tallies`, taken in their order.
    pub fn of(tallies: &[EpisodeTally]) -> Self {
        let group = |keep: &dyn Fn(&EpisodeTally) -> bool| {
            let members: Vec<&EpisodeTally> = tallies.iter().filter(|t| keep(t)).collect();
            let ct: Vec<f64> = members
                .iter()
                .flat_map(|t| t.ct_samples_s.iter().copied())
                .collect();
            let cycles: u64 = members.iter().map(|t| t.cycles).sum();
            let reused: u64 = members.iter().map(|t| t.decisions_reused).sum();
            let compute: Vec<f64> = members
                .iter()
                .flat_map(|t| t.ct_compute_samples_s.iter().copied())
                .collect();
            let misses: u64 = members.iter().map(|t| t.compute_misses).sum();
            let share = |n: u64| {
                if cycles == 0 {
                    0.0
                } else {
                    n as f64 / cycles as f64
                }
            };
            GroupSummary {
                metrics: MetricsSummary::of(members.iter().map(|t| &t.metrics)),
                ct_mean_s: mean_std(&ct).map_or(0.0, |(mean, _)| mean),
                ct_p95_s: percentile(&ct, 95.0).unwrap_or(0.0),
                eer: share(reused),
                ct_compute_mean_s: mean_std(&compute).map_or(0.0, |(mean, _)| mean),
                eer_compute: share(misses),
            }
        };
        Self {
            all: group(&|_| true),
            open: group(&|t| t.airspace == "open"),
            dense: group(&|t| t.airspace == "dense"),
        }
    }
}

/// Why shards' episodes.jsonl files do not merge into one table.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// Nothing to merge.
    #[error("give the episodes.jsonl files (or the shards' output folders) to merge")]
    Nothing,
    /// A file could not be read.
    #[error("cannot read {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A line is not one of `aeris eval` (or one written before shards could be merged).
    #[error(
        "{path} line {line}: not an episodes.jsonl line of this `aeris eval` (lines written \
         before `--shard` carry no cycle times: fly them again)"
    )]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based.
        line: usize,
        /// Why.
        source: serde_json::Error,
    },
    /// Two files come from different evaluations.
    #[error(
        "{path}: {field} `{found}`, but the first file's is `{expected}`: not shards of one evaluation"
    )]
    Mixed {
        /// The file that differs.
        path: PathBuf,
        /// `agent`, `split`, `baseline`, `reasoning` or `clock`.
        field: &'static str,
        /// The first file's.
        expected: String,
        /// This one's.
        found: String,
    },
    /// An episode is in two shards.
    #[error("{path}: episode {index} (`{episode}`) is in an earlier file too")]
    Duplicate {
        /// The file it came up again in.
        path: PathBuf,
        /// Its index in the evaluated list.
        index: usize,
        /// Its id.
        episode: String,
    },
}

/// The episodes an `aeris eval` wrote at `path` (its episodes.jsonl, or the output folder
/// holding one), in the file's order, and the file read.
pub fn read_tallies(path: &Path) -> Result<(PathBuf, Vec<EpisodeTally>), MergeError> {
    let file = if path.is_dir() {
        path.join("episodes.jsonl")
    } else {
        path.to_path_buf()
    };
    let text = std::fs::read_to_string(&file).map_err(|source| MergeError::Read {
        path: file.clone(),
        source,
    })?;
    let mut tallies = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        tallies.push(
            serde_json::from_str(line).map_err(|source| MergeError::Line {
                path: file.clone(),
                line: n + 1,
                source,
            })?,
        );
    }
    Ok((file, tallies))
}

/// The table of the evaluation whose shards wrote `paths` (each an episodes.jsonl, or the
/// output folder holding one): their episodes in the whole list's order, summarised as one
/// run of them all would have been.
pub fn merge(paths: &[PathBuf]) -> Result<EvalTable, MergeError> {
    let mut tallies: Vec<EpisodeTally> = Vec::new();
    let mut files = Vec::new();
    for path in paths {
        let (file, read) = read_tallies(path)?;
        for t in read {
            if let Some(first) = tallies.first() {
                let fields = [
                    ("agent", &first.agent, &t.agent),
                    ("split", &first.split, &t.split),
                    ("reasoning", &first.reasoning, &t.reasoning),
                    ("clock", &first.clock, &t.clock),
                ];
                let baseline = |b: &Option<String>| b.clone().unwrap_or_else(|| "none".into());
                let (b0, b1) = (baseline(&first.baseline), baseline(&t.baseline));
                for (field, expected, found) in fields.into_iter().chain([("baseline", &b0, &b1)]) {
                    if expected != found {
                        return Err(MergeError::Mixed {
                            path: file.clone(),
                            field,
                            expected: expected.clone(),
                            found: found.clone(),
                        });
                    }
                }
            }
            if tallies.iter().any(|o| o.index == t.index) {
                return Err(MergeError::Duplicate {
                    path: file.clone(),
                    index: t.index,
                    episode: t.episode_id,
                });
            }
            tallies.push(t);
        }
        files.push(file.display().to_string());
    }
    let Some(first) = tallies.first() else {
        return Err(MergeError::Nothing);
    };
    let (split, agent, baseline, reasoning) = (
        first.split.clone(),
        first.agent.clone(),
        first.baseline.clone(),
        first.reasoning.clone(),
    );
    tallies.sort_by_key(|t| t.index);
    let Summaries { all, open, dense } = Summaries::of(&tallies);
    Ok(EvalTable {
        split,
        agent,
        baseline,
        reasoning,
        all,
        open,
        dense,
        details: files.join(", "),
    })
}

/// What an episode file holds, checked: `aeris episodes check`.
#[derive(Debug, Clone, Serialize)]
pub struct EpisodeFileSummary {
    /// The file.
    pub file: String,
    /// Episodes in it.
    pub episodes: usize,
    /// Distinct scenes.
    pub scenes: usize,
    /// Episodes with a subgoal annotation.
    pub annotated: usize,
    /// Mean reference-path steps.
    pub mean_reference_steps: f64,
    /// Mean reference-path length (m).
    pub mean_reference_length_m: f64,
}

impl EpisodeFileSummary {
    /// The summary of `list`, loaded (and so validated) from `file`.
    pub fn of(file: &Path, list: &[Episode]) -> Self {
        let mean = |v: &[f64]| aeris_runtime::stats::mean_std(v).map_or(0.0, |(m, _)| m);
        let steps: Vec<f64> = list.iter().map(|e| e.reference_path.len() as f64).collect();
        let lengths: Vec<f64> = list
            .iter()
            .map(|e| crate::metrics::path_length(&e.reference_positions()))
            .collect();
        let scenes: std::collections::BTreeSet<&str> =
            list.iter().map(|e| e.scene_id.as_str()).collect();
        Self {
            file: file.display().to_string(),
            episodes: list.len(),
            scenes: scenes.len(),
            annotated: list.iter().filter(|e| !e.subgoals.is_empty()).count(),
            mean_reference_steps: mean(&steps),
            mean_reference_length_m: mean(&lengths),
        }
    }
}

impl fmt::Display for EpisodeFileSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}: {} episodes, valid", self.file, self.episodes)?;
        writeln!(f, "  scenes:                 {}", self.scenes)?;
        writeln!(f, "  with subgoal annotation: {}", self.annotated)?;
        writeln!(
            f,
            "  reference steps (mean): {:.1}",
            self.mean_reference_steps
        )?;
        writeln!(
            f,
            "  reference length (mean): {:.1} m",
            self.mean_reference_length_m
        )
    }
}

/// The part of an episodes.jsonl line ([`crate::episode_line::EpisodeLine`]) that a map of the
/// evaluated episode needs: where it flew, where it should have, in which scene.
#[derive(Debug, Clone, Deserialize)]
pub struct ExecutedEpisode {
    /// Episode id.
    pub episode_id: String,
    /// Scene id.
    pub scene_id: String,
    /// Positions kept (one per AerialVLN action step, and the final one).
    pub positions: Vec<[f64; 3]>,
    /// The reference path.
    pub reference: Vec<[f64; 3]>,
    /// The goal.
    pub goal: [f64; 3],
}

/// Why an episodes.jsonl line could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum ExecutedEpisodeError {
    /// The file could not be read.
    #[error("cannot read {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A line is not an episode line.
    #[error("{path} line {line}: not an episodes.jsonl line of `aeris eval`")]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based.
        line: usize,
        /// Why.
        source: serde_json::Error,
    },
    /// No line has the episode asked for.
    #[error("no episode `{episode}` in {path}")]
    NoSuchEpisode {
        /// The file.
        path: PathBuf,
        /// The id asked for.
        episode: String,
    },
    /// The file has no lines.
    #[error("{0} has no episodes")]
    Empty(PathBuf),
}

impl ExecutedEpisode {
    /// Episode `episode` (default: the first) of `file`, an episodes.jsonl of `aeris eval`.
    pub fn read(file: &Path, episode: Option<&str>) -> Result<Self, ExecutedEpisodeError> {
        let text = std::fs::read_to_string(file).map_err(|source| ExecutedEpisodeError::Read {
            path: file.to_path_buf(),
            source,
        })?;
        // only the episode asked for must have every field; the others need only be JSON
        #[derive(Deserialize)]
        struct Id {
            #[serde(default)]
            episode_id: String,
        }
        let line_error = |n: usize, source| ExecutedEpisodeError::Line {
            path: file.to_path_buf(),
            line: n + 1,
            source,
        };
        for (n, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let id: Id = serde_json::from_str(line).map_err(|e| line_error(n, e))?;
            if episode.is_none_or(|e| e == id.episode_id) {
                return serde_json::from_str(line).map_err(|e| line_error(n, e));
            }
        }
        Err(match episode {
            Some(id) => ExecutedEpisodeError::NoSuchEpisode {
                path: file.to_path_buf(),
                episode: id.to_string(),
            },
            None => ExecutedEpisodeError::Empty(file.to_path_buf()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_episode_line_is_read_back_by_id_and_a_missing_one_is_named() {
        let dir = std::env::temp_dir().join(format!("aeris-executed-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("episodes.jsonl");
        let line = |id: &str| {
            serde_json::json!({
                "episode_id": id, "scene_id": "open-3", "airspace": "open",
                "positions": [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]],
                "reference": [[0.0, 0.0, 0.0]], "goal": [1.0, 2.0, 0.0], "sr": 1.0
            })
            .to_string()
        };
        std::fs::write(&file, format!("{}\n{}\n", line("a"), line("b"))).unwrap();
        let b = ExecutedEpisode::read(&file, Some("b")).unwrap();
        assert_eq!(
            (b.episode_id.as_str(), b.scene_id.as_str()),
            ("b", "open-3")
        );
        assert_eq!(b.positions[1], [1.0, 2.0, 3.0]);
        assert_eq!(ExecutedEpisode::read(&file, None).unwrap().episode_id, "a");
        let err = ExecutedEpisode::read(&file, Some("z")).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("no episode `z` in {}", file.display())
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[cfg(test)]
pub(crate) mod merge_tests {
    use super::*;

    /// A made-up episode line: episodes 2k and 2k+1 share a scene.
    pub(crate) fn tally(index: usize) -> EpisodeTally {
        let x = index as f64;
        EpisodeTally {
            index,
            episode_id: format!("ep-{index}"),
            scene_id: format!("scene-{}", index / 2),
            airspace: if index.is_multiple_of(3) {
                "open"
            } else {
                "dense"
            }
            .into(),
            agent: "aeris-planner".into(),
            split: "test_unseen".into(),
            baseline: None,
            reasoning: "planner".into(),
            metrics: EpisodeMetrics {
                ne: Some(3.1 * x + 0.7),
                sr: f64::from(index.is_multiple_of(2)),
                osr: 1.0,
                ndtw: 0.1 + 0.13 * x,
                spl: 0.3 / (x + 1.0),
                asr: Some(0.25 * (index % 4) as f64),
                path_length_m: 100.0 + x,
            },
            cycles: 40 + index as u64,
            decisions_reused: index as u64 % 3,
            ct_samples_s: (0..7)
                .map(|c| 0.05 + 0.011 * (c as f64) * (x + 1.0))
                .collect(),
            ct_compute_samples_s: (0..7).map(|c| 0.01 * (c as f64) + x).collect(),
            compute_misses: index as u64 % 2,
            clock: "sim".into(),
        }
    }

    fn write(dir: &Path, name: &str, tallies: &[EpisodeTally]) -> PathBuf {
        let path = dir.join(name);
        let text: String = tallies
            .iter()
            .map(|t| serde_json::to_string(t).unwrap() + "\n")
            .collect();
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn shards_merge_into_the_table_of_one_run_and_other_evaluations_do_not() {
        let dir = std::env::temp_dir().join(format!("aeris-merge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let all: Vec<EpisodeTally> = (0..7).map(tally).collect();
        let one_run = Summaries::of(&all);
        // two shards (`--shard 1/2`, `2/2`), given in either order
        let shard = |k: usize| -> Vec<EpisodeTally> {
            let s = crate::runner::Shard { index: k, count: 2 };
            all.iter().filter(|t| s.holds(t.index)).cloned().collect()
        };
        let (a, b) = (
            write(&dir, "a.jsonl", &shard(0)),
            write(&dir, "b.jsonl", &shard(1)),
        );
        let merged = merge(&[b.clone(), a.clone()]).unwrap();
        assert_eq!(merged.all.metrics.episodes, 7);
        assert_eq!(
            (merged.all, merged.open, merged.dense),
            (one_run.all, one_run.open, one_run.dense),
            "to the last bit"
        );
        assert_eq!(
            (merged.agent.as_str(), merged.baseline),
            ("aeris-planner", None)
        );
        // a shard twice, or a shard of another agent, is refused by name
        let err = merge(&[a.clone(), a.clone()]).unwrap_err();
        assert!(
            err.to_string()
                .contains("episode 0 (`ep-0`) is in an earlier file too"),
            "{err}"
        );
        let mut other = shard(1);
        other.iter_mut().for_each(|t| t.agent = "oracle".into());
        let c = write(&dir, "c.jsonl", &other);
        let err = merge(&[a.clone(), c]).unwrap_err();
        assert!(
            err.to_string()
                .ends_with("agent `oracle`, but the first file's is `aeris-planner`: not shards of one evaluation"),
            "{err}"
        );
        // nor one flown on the wall clock with one on simulated time
        let mut wall = shard(1);
        wall.iter_mut().for_each(|t| t.clock = "wall".into());
        let w = write(&dir, "w.jsonl", &wall);
        let err = merge(&[a, w]).unwrap_err();
        assert!(
            err.to_string()
                .contains("clock `wall`, but the first file's is `sim`"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_shard_is_k_of_n_and_the_shards_cover_the_list_once() {
        use crate::runner::Shard;
        assert_eq!("2/3".parse(), Ok(Shard { index: 1, count: 3 }));
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        let shards: Vec<Shard> = (1..=3).map(|k| format!("{k}/3").parse().unwrap()).collect();
        for k in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.holds(k)).count(), 1, "{k}");
        }
    }
}
