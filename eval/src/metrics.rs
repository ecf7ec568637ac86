//! The paper's VLN metrics (MISSION §7), per episode and averaged. Pure functions.
//!
//! Per episode, from the executed positions P (the start position first), the reference
//! positions R, the goal g and whether the agent stopped:
//! - **NE**: Euclidean distance (3D) from the last position of P to g;
//! - **SR**: stopped, and the last position within [`SUCCESS_RADIUS_M`] of g;
//! - **OSR**: some position of P within [`SUCCESS_RADIUS_M`] of g;
//! - **nDTW**: `exp(-DTW(P, R) / (|R| * 20 m))`, exact dynamic-time-warping over 3D points;
//! - **SPL**: `SR * l / max(p, l)`, `l` the straight-line start-to-goal distance, `p` the
//!   length of P;
//! - **ASR**: subgoals completed / subgoals in the episode (from the attention trace).
//!
//! An empty P (the pipeline produced no position at all) scores 0 on SR, OSR, nDTW and
//! SPL and has no NE (`None`): there is no last position to measure from. An episode
//! without subgoal annotation has no ASR.

use serde::{Deserialize, Serialize};

/// Distance to the goal (m) within which an episode counts as a success.
pub const SUCCESS_RADIUS_M: f64 = 20.0;

/// Euclidean distance between two 3D points.
pub fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Length of the polyline through `points` (0 for fewer than two).
pub fn path_length(points: &[[f64; 3]]) -> f64 {
    points.windows(2).map(|w| distance(w[0], w[1])).sum()
}

/// Exact DTW between `p` and `r` with Euclidean point distance: the least sum of point
/// distances over monotone alignments that match every point of both. `+inf` when
/// either is empty. O(|p| |r|) time, O(|r|) memory.
pub fn dtw(p: &[[f64; 3]], r: &[[f64; 3]]) -> f64 {
    if p.is_empty() || r.is_empty() {
        return f64::INFINITY;
    }
    let m = r.len();
    let mut prev = vec![f64::INFINITY; m + 1];
    let mut cur = vec![f64::INFINITY; m + 1];
    prev[0] = 0.0;
    for &pi in p {
        cur[0] = f64::INFINITY;
        for j in 1..=m {
            let best = prev[j].min(cur[j - 1]).min(prev[j - 1]);
            cur[j] = distance(pi, r[j - 1]) + best;
        }
        core::mem::swap(&mut prev, &mut cur);
    }
    prev[m]
}

/// `exp(-DTW(p, r) / (|r| * 20 m))`; 0 when either is empty.
pub fn ndtw(p: &[[f64; 3]], r: &[[f64; 3]]) -> f64 {
    if p.is_empty() || r.is_empty() {
        return 0.0;
    }
    (-dtw(p, r) / (r.len() as f64 * SUCCESS_RADIUS_M)).exp()
}

/// What one episode's run produced, as the metrics need it.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeRun<'a> {
    /// Executed positions `[x, y, z]`, the start position first.
    pub positions: &'a [[f64; 3]],
    /// Reference positions.
    pub reference: &'a [[f64; 3]],
    /// The goal.
    pub goal: [f64; 3],
    /// Whether the agent stopped (landed / issued stop) before the episode ended.
    pub stopped: bool,
    /// Subgoals completed according to the attention trace.
    pub subgoals_completed: usize,
    /// Subgoals in the episode (0: not annotated).
    pub subgoals_total: usize,
}

/// The metrics of one episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EpisodeMetrics {
    /// Navigation error (m); `None` without any position.
    pub ne: Option<f64>,
    /// Success: 1 or 0.
    pub sr: f64,
    /// Oracle success: 1 or 0.
    pub osr: f64,
    /// Normalised DTW in [0, 1].
    pub ndtw: f64,
    /// Success weighted by path length in [0, 1].
    pub spl: f64,
    /// Subgoals completed / subgoals; `None` without subgoal annotation.
    pub asr: Option<f64>,
    /// Length of the executed path (m).
    pub path_length_m: f64,
}

impl EpisodeMetrics {
    /// The metrics of `run` (see the module docs for every definition).
    pub fn compute(run: &EpisodeRun<'_>) -> EpisodeMetrics {
        let asr = (run.subgoals_total > 0).then(|| {
            run.subgoals_completed.min(run.subgoals_total) as f64 / run.subgoals_total as f64
        });
        let (Some(&first), Some(&last)) = (run.positions.first(), run.positions.last()) else {
            return EpisodeMetrics {
                ne: None,
                sr: 0.0,
                osr: 0.0,
                ndtw: 0.0,
                spl: 0.0,
                asr,
                path_length_m: 0.0,
            };
        };
        let ne = distance(last, run.goal);
        let success = run.stopped && ne <= SUCCESS_RADIUS_M;
        let oracle = run
            .positions
            .iter()
            .any(|&p| distance(p, run.goal) <= SUCCESS_RADIUS_M);
        let p = path_length(run.positions);
        let l = distance(first, run.goal);
        let spl = if !success {
            0.0
        } else if p.max(l) == 0.0 {
            1.0
        } else {
            l / p.max(l)
        };
        EpisodeMetrics {
            ne: Some(ne),
            sr: f64::from(u8::from(success)),
            osr: f64::from(u8::from(oracle)),
            ndtw: ndtw(run.positions, run.reference),
            spl,
            asr,
            path_length_m: p,
        }
    }
}

/// Means over several episodes.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct MetricsSummary {
    /// Episodes averaged.
    pub episodes: usize,
    /// Mean NE (m) over the episodes that have one; `None` when none has.
    pub ne: Option<f64>,
    /// Mean SR in [0, 1].
    pub sr: f64,
    /// Mean OSR in [0, 1].
    pub osr: f64,
    /// Mean nDTW in [0, 1].
    pub ndtw: f64,
    /// Mean SPL in [0, 1].
    pub spl: f64,
    /// Mean ASR over the annotated episodes; `None` when none is.
    pub asr: Option<f64>,
}

impl MetricsSummary {
    /// The means of `metrics` (all zero for none).
    pub fn of<'a>(metrics: impl IntoIterator<Item = &'a EpisodeMetrics>) -> MetricsSummary {
        let mut s = MetricsSummary::default();
        let (mut ne_sum, mut ne_n, mut asr_sum, mut asr_n) = (0.0, 0usize, 0.0, 0usize);
        for m in metrics {
            s.episodes += 1;
            s.sr += m.sr;
            s.osr += m.osr;
            s.ndtw += m.ndtw;
            s.spl += m.spl;
            if let Some(ne) = m.ne {
                ne_sum += ne;
                ne_n += 1;
            }
            if let Some(a) = m.asr {
                asr_sum += a;
                asr_n += 1;
            }
        }
        if s.episodes > 0 {
            let n = s.episodes as f64;
            s.sr /= n;
            s.osr /= n;
            s.ndtw /= n;
            s.spl /= n;
        }
        s.ne = (ne_n > 0).then(|| ne_sum / ne_n as f64);
        s.asr = (asr_n > 0).then(|| asr_sum / asr_n as f64);
        s
    }
}
