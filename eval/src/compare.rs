//! The ablation table (issue 37, item 5): several evaluations of the **same** episodes, one
//! per row (AERIS, Single-SLM, Zero-shot, No-ATT, No-DS, the planner: each an `aeris eval`
//! output), with a 95 % interval for each row's metrics and for each row's difference to the
//! first row, bootstrapped over scenes (`aeris eval compare`).
//!
//! The rows are paired: every row must have flown exactly the episodes of the first. One
//! bootstrap draw picks as many scenes as there are, with replacement, and takes every
//! episode of each picked scene in every row, so an interval counts how much a result hangs
//! on which scenes were flown (episodes of one scene are not independent), and a row's
//! difference to the first is measured on the same draw. Intervals are the 2.5th and 97.5th
//! percentiles of `resamples` draws from a seeded generator: the same files give the same
//! table.

use crate::table::{EpisodeTally, GroupSummary, MergeError, Summaries, read_tallies};
use aeris_runtime::stats::percentile;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;

/// Bootstrap draws when none are asked for.
pub const DEFAULT_RESAMPLES: usize = 2000;
/// The generator's seed: the same files always give the same intervals.
pub const SEED: u64 = 37;

/// A 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// 2.5th percentile of the draws.
    pub low: f64,
    /// 97.5th percentile of the draws.
    pub high: f64,
}

/// Intervals of the paper's navigation metrics (NE in m, the others as shares in [0, 1]);
/// `None` where no draw had the metric (NE without positions, ASR without annotation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MetricIntervals {
    /// Navigation error.
    pub ne: Option<Interval>,
    /// Success rate.
    pub sr: Option<Interval>,
    /// Oracle success rate.
    pub osr: Option<Interval>,
    /// nDTW.
    pub ndtw: Option<Interval>,
    /// SPL.
    pub spl: Option<Interval>,
    /// Subgoal success rate.
    pub asr: Option<Interval>,
}

/// One row: an evaluation, its summary over all its episodes, and its intervals.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompareRow {
    /// The row's name (`aeris eval compare NAME=DIR`).
    pub name: String,
    /// The agent the evaluation flew.
    pub agent: String,
    /// Its reasoning variant.
    pub reasoning: String,
    /// The metrics and timing over all its episodes.
    pub summary: GroupSummary,
    /// The metrics' 95 % intervals.
    pub interval: MetricIntervals,
    /// The 95 % intervals of this row's metrics minus the first row's (paired, same
    /// draws); `None` for the first row.
    pub difference: Option<MetricIntervals>,
}

/// The ablation table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompareTable {
    /// Episodes every row flew.
    pub episodes: usize,
    /// Scenes they are in (what a draw resamples).
    pub scenes: usize,
    /// Bootstrap draws.
    pub resamples: usize,
    /// The rows, in the order given.
    pub rows: Vec<CompareRow>,
}

/// Why evaluations do not make one table.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A row has no name, or no episodes, or none were given.
    #[error("give at least one row NAME=DIR whose episodes.jsonl holds episodes")]
    Nothing,
    /// An output could not be read.
    #[error("row `{row}`")]
    Read {
        /// The row.
        row: String,
        /// Why.
        source: MergeError,
    },
    /// A row did not fly the first row's episodes.
    #[error(
        "row `{row}` did not fly the episodes of row `{first}`: episode `{episode}` is in one and not the other (rows must be paired)"
    )]
    NotPaired {
        /// The row.
        row: String,
        /// The first row.
        first: String,
        /// An episode in one of them only.
        episode: String,
    },
    /// An episode is twice in a row.
    #[error("row `{row}` holds episode `{episode}` twice")]
    Duplicate {
        /// The row.
        row: String,
        /// The episode.
        episode: String,
    },
}

/// The metric means of `members` as NE, SR, OSR, nDTW, SPL, ASR (`None`: none has it).
fn means(members: &[&EpisodeTally]) -> [Option<f64>; 6] {
    let mut sums = [0.0; 6];
    let mut counts = [0usize; 6];
    for t in members {
        let m = &t.metrics;
        for (i, v) in [
            m.ne,
            Some(m.sr),
            Some(m.osr),
            Some(m.ndtw),
            Some(m.spl),
            m.asr,
        ]
        .into_iter()
        .enumerate()
        {
            if let Some(v) = v {
                sums[i] += v;
                counts[i] += 1;
            }
        }
    }
    core::array::from_fn(|i| (counts[i] > 0).then(|| sums[i] / counts[i] as f64))
}

fn intervals(draws: &[Vec<f64>; 6]) -> MetricIntervals {
    let one = |d: &Vec<f64>| {
        Some(Interval {
            low: percentile(d, 2.5)?,
            high: percentile(d, 97.5)?,
        })
    };
    MetricIntervals {
        ne: one(&draws[0]),
        sr: one(&draws[1]),
        osr: one(&draws[2]),
        ndtw: one(&draws[3]),
        spl: one(&draws[4]),
        asr: one(&draws[5]),
    }
}

/// The table of `rows` (name, episodes) with `resamples` bootstrap draws over scenes.
pub fn compare(
    rows: &[(String, Vec<EpisodeTally>)],
    resamples: usize,
) -> Result<CompareTable, CompareError> {
    let Some((first_name, first)) = rows.first() else {
        return Err(CompareError::Nothing);
    };
    if rows.iter().any(|(name, t)| name.is_empty() || t.is_empty()) {
        return Err(CompareError::Nothing);
    }
    // each row's episodes by id, checked paired with the first row's
    let mut by_id: Vec<BTreeMap<&str, &EpisodeTally>> = Vec::with_capacity(rows.len());
    for (name, tallies) in rows {
        let mut map = BTreeMap::new();
        for t in tallies {
            if map.insert(t.episode_id.as_str(), t).is_some() {
                return Err(CompareError::Duplicate {
                    row: name.clone(),
                    episode: t.episode_id.clone(),
                });
            }
        }
        by_id.push(map);
    }
    for ((name, _), map) in rows.iter().zip(&by_id).skip(1) {
        let unpaired = by_id[0]
            .keys()
            .find(|id| !map.contains_key(*id))
            .or_else(|| map.keys().find(|id| !by_id[0].contains_key(*id)));
        if let Some(id) = unpaired {
            return Err(CompareError::NotPaired {
                row: name.clone(),
                first: first_name.clone(),
                episode: id.to_string(),
            });
        }
    }
    // the scenes, and the episodes of each (a line without its scene is its own cluster)
    let mut scenes: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for t in first {
        let scene = if t.scene_id.is_empty() {
            t.episode_id.as_str()
        } else {
            t.scene_id.as_str()
        };
        scenes.entry(scene).or_default().push(t.episode_id.as_str());
    }
    let clusters: Vec<&Vec<&str>> = scenes.values().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut draws: Vec<[Vec<f64>; 6]> = vec![Default::default(); rows.len()];
    let mut diffs: Vec<[Vec<f64>; 6]> = vec![Default::default(); rows.len()];
    let mut members: Vec<&EpisodeTally> = Vec::with_capacity(first.len() * 2);
    for _ in 0..resamples {
        let picked: Vec<usize> = (0..clusters.len())
            .map(|_| rng.random_range(0..clusters.len()))
            .collect();
        let mut row_means = Vec::with_capacity(rows.len());
        for map in &by_id {
            members.clear();
            for &c in &picked {
                members.extend(clusters[c].iter().filter_map(|id| map.get(id).copied()));
            }
            row_means.push(means(&members));
        }
        for (r, m) in row_means.iter().enumerate() {
            for i in 0..6 {
                if let Some(v) = m[i] {
                    draws[r][i].push(v);
                    if let (true, Some(base)) = (r > 0, row_means[0][i]) {
                        diffs[r][i].push(v - base);
                    }
                }
            }
        }
    }
    let rows = rows
        .iter()
        .enumerate()
        .map(|(r, (name, tallies))| {
            let mut ordered = tallies.clone();
            ordered.sort_by_key(|t| t.index);
            CompareRow {
                name: name.clone(),
                agent: ordered[0].agent.clone(),
                reasoning: ordered[0].reasoning.clone(),
                summary: Summaries::of(&ordered).all,
                interval: intervals(&draws[r]),
                difference: (r > 0).then(|| intervals(&diffs[r])),
            }
        })
        .collect();
    Ok(CompareTable {
        episodes: first.len(),
        scenes: clusters.len(),
        resamples,
        rows,
    })
}

/// Read each `(name, path)` row's episodes.jsonl (or output folder) and make the table.
pub fn compare_outputs(
    rows: &[(String, PathBuf)],
    resamples: usize,
) -> Result<CompareTable, CompareError> {
    let read = rows
        .iter()
        .map(|(name, path)| {
            read_tallies(path)
                .map(|(_, t)| (name.clone(), t))
                .map_err(|source| CompareError::Read {
                    row: name.clone(),
                    source,
                })
        })
        .collect::<Result<Vec<_>, _>>()?;
    compare(&read, resamples)
}

impl fmt::Display for CompareTable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} episodes in {} scenes, every row paired; 95 % intervals from {} bootstrap draws over scenes",
            self.episodes, self.scenes, self.resamples
        )?;
        let iv = |i: Option<Interval>, scale: f64| match i {
            Some(i) => format!("[{:.1}, {:.1}]", i.low * scale, i.high * scale),
            None => "-".into(),
        };
        writeln!(
            f,
            "  {:<14} {:>6} {:>16} {:>6} {:>16} {:>6} {:>6} {:>6} {:>6} {:>7} {:>6} {:>16} {:>16}",
            "row",
            "NE m",
            "",
            "SR%",
            "",
            "OSR%",
            "nDTW%",
            "SPL%",
            "ASR%",
            "CTc s",
            "EER%",
            "NE - first",
            "SR - first"
        )?;
        for r in &self.rows {
            let m = &r.summary.metrics;
            let d = r.difference.as_ref();
            writeln!(
                f,
                "  {:<14} {:>6} {:>16} {:>6.1} {:>16} {:>6.1} {:>6.1} {:>6.1} {:>6} {:>7.3} {:>6.1} {:>16} {:>16}",
                r.name,
                m.ne.map_or("-".into(), |v| format!("{v:.1}")),
                iv(r.interval.ne, 1.0),
                m.sr * 100.0,
                iv(r.interval.sr, 100.0),
                m.osr * 100.0,
                m.ndtw * 100.0,
                m.spl * 100.0,
                m.asr.map_or("-".into(), |v| format!("{:.1}", v * 100.0)),
                r.summary.ct_compute_mean_s,
                r.summary.eer * 100.0,
                d.map_or("".into(), |d| iv(d.ne, 1.0)),
                d.map_or("".into(), |d| iv(d.sr, 100.0)),
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::merge_tests::tally;

    fn row(name: &str, sr_of: impl Fn(usize) -> f64) -> (String, Vec<EpisodeTally>) {
        let tallies = (0..8)
            .map(|i| {
                let mut t = tally(i);
                t.metrics.sr = sr_of(i);
                t
            })
            .collect();
        (name.into(), tallies)
    }

    #[test]
    fn a_row_is_compared_with_the_first_on_the_same_draws() {
        let rows = [
            row("planner", |i| f64::from(i % 2 == 0)),
            row("same", |i| f64::from(i % 2 == 0)),
            row("better", |_| 1.0),
        ];
        let t = compare(&rows, 500).unwrap();
        assert_eq!((t.episodes, t.scenes, t.rows.len()), (8, 4, 3));
        let first = &t.rows[0];
        assert_eq!(first.summary.metrics.sr, 0.5);
        let sr = first.interval.sr.unwrap();
        assert!(sr.low <= 0.5 && 0.5 <= sr.high, "{sr:?}");
        assert!(first.difference.is_none());
        // the same results: every paired draw differs by nothing
        let same = t.rows[1].difference.unwrap().sr.unwrap();
        assert_eq!((same.low, same.high), (0.0, 0.0));
        // every scene holds one success and one failure of the first row: +0.5 on every draw
        let better = t.rows[2].difference.unwrap().sr.unwrap();
        assert_eq!((better.low, better.high), (0.5, 0.5));
        // seeded: the same files, the same table
        assert_eq!(compare(&rows, 500).unwrap(), t);
        assert!(t.to_string().contains("better"));
    }

    #[test]
    fn rows_that_flew_other_episodes_are_refused_by_name() {
        let mut other = row("other", |_| 0.0);
        other.1[3].episode_id = "ep-99".into();
        let err = compare(&[row("planner", |_| 0.0), other], 10).unwrap_err();
        assert!(
            matches!(&err, CompareError::NotPaired { row, episode, .. } if row == "other" && episode == "ep-3"),
            "{err}"
        );
        let mut twice = row("twice", |_| 0.0);
        twice.1[1].episode_id = "ep-0".into();
        assert!(matches!(
            compare(&[twice], 10),
            Err(CompareError::Duplicate { .. })
        ));
        assert!(matches!(compare(&[], 10), Err(CompareError::Nothing)));
    }
}
