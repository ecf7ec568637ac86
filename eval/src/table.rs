//! What the evaluation commands report, as values: `aeris eval`'s table ([`EvalTable`]),
//! `aeris episodes check`'s summary of an episode file ([`EpisodeFileSummary`]), and the part
//! of an episodes.jsonl line that maps and plots read back ([`ExecutedEpisode`]). Each
//! prints as the command's text (`Display`) and serialises as its `--json`.

use crate::episode::Episode;
use crate::mission::Agent;
use crate::runner::{AgentSetup, EvalReport, GroupSummary};
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
    /// Where the episode lines are.
    #[serde(skip)]
    pub episodes_jsonl: PathBuf,
}

impl EvalTable {
    /// The table of `report`, an evaluation of `setup`.
    pub fn new(report: &EvalReport, setup: &AgentSetup) -> Self {
        Self {
            split: report.label.clone(),
            agent: setup.label.clone(),
            baseline: match setup.agent {
                Agent::Aeris => None,
                a => Some(a.as_str().to_string()),
            },
            reasoning: setup.reasoning.clone(),
            all: report.all.clone(),
            open: report.open.clone(),
            dense: report.dense.clone(),
            episodes_jsonl: report.jsonl_path.clone(),
        }
    }
}

impl fmt::Display for EvalTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}, agent {}: {} episodes (details in {})",
            self.split,
            self.agent,
            self.all.metrics.episodes,
            self.episodes_jsonl.display()
        )?;
        writeln!(
            f,
            "  {:<8} {:>4} {:>8} {:>6} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>6}",
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
            "EER%"
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
                g.ct_mean_s,
                g.ct_p95_s,
                pct(g.eer)
            )?;
        }
        Ok(())
    }
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

/// The part of an episodes.jsonl line ([`crate::runner::EpisodeLine`]) that a map of the
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
        for (n, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let e: ExecutedEpisode =
                serde_json::from_str(line).map_err(|source| ExecutedEpisodeError::Line {
                    path: file.to_path_buf(),
                    line: n + 1,
                    source,
                })?;
            if episode.is_none_or(|id| id == e.episode_id) {
                return Ok(e);
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
