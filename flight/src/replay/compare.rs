//! The comparison of a replay with its recording, and of variants with each other: cycles
//! paired by the frame they started on, decisions compared bit for bit, cycle-time figures
//! from hub reports.

use super::{ReplayError, ReplayRequest, ReplaySummary, replay};
use crate::FlightWatcher;
use crate::overrides::VariantChoice;
use aeris_schemas::{ActionMode, Decision, HubReport};
use serde::Serialize;

/// Two cycle starts this close (ns, recording clock) are the same frame (a scaled replay
/// rounds its stamps).
const PAIR_TOLERANCE_NS: u64 = 500_000;

/// One decision as the table shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DecisionView {
    /// Its cycle number (per reasoner process).
    pub cycle: u64,
    /// Action mode.
    pub action: String,
    /// Active instruction step.
    pub step: u16,
    /// Waypoint `[N, E, U]` (m).
    pub target: [f32; 3],
    /// From its frame's capture to its publication (s).
    pub latency_s: f64,
}

impl DecisionView {
    fn of(d: &Decision) -> Self {
        Self {
            cycle: d.cycle,
            action: ActionMode::from_u8(d.action)
                .map_or_else(|| format!("mode {}", d.action), |a| a.name().to_string()),
            step: d.step,
            target: d.target,
            latency_s: d.publish_ns.saturating_sub(d.cycle_start_ns) as f64 * 1e-9,
        }
    }
}

/// One semantic cycle of the replay.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayCycle {
    /// Capture time of its frame, seconds into the recording.
    pub t_s: f64,
    /// The recorded decision (`None`: only the replay decided here).
    pub recorded: Option<DecisionView>,
    /// The replayed decision (`None`: the replay did not decide on this frame).
    pub replayed: Option<DecisionView>,
    /// Both decided, and their content is equal bit for bit.
    pub identical: bool,
    /// Distance between the two waypoints (m), when both decided.
    pub target_delta_m: Option<f64>,
}

/// Cycle times and errors of one run, from its hub reports.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunFigures {
    /// Decisions.
    pub decisions: usize,
    /// Semantic cycles the hub closed (committed or reused).
    pub cycles: u64,
    /// Mean cycle time of the committed cycles (s).
    pub ct_mean_s: f64,
    /// 95th percentile of it (s).
    pub ct_p95_s: f64,
    /// Execution error rate: reused cycles over cycles.
    pub eer: f64,
}

/// The content of a decision, bit for bit: what a replay must reproduce.
pub fn same_content(a: &Decision, b: &Decision) -> bool {
    let bits = |d: &Decision| {
        (
            d.target.map(f32::to_bits),
            [
                d.yaw,
                d.speed,
                d.altitude,
                d.acceptance_radius,
                d.confidence,
            ]
            .map(f32::to_bits),
            d.step,
            d.action,
            d.reserved,
        )
    };
    bits(a) == bits(b)
}

/// Recorded and replayed decisions (each with its cycle start on the recording's clock)
/// side by side, in order of capture.
pub(super) fn pair(
    recorded: &[(u64, Decision)],
    replayed: &[(u64, Decision)],
    start: u64,
) -> Vec<ReplayCycle> {
    let mut cycles = Vec::new();
    let mut used = vec![false; replayed.len()];
    for (t, rec) in recorded {
        let m = replayed
            .iter()
            .enumerate()
            .filter(|(i, (u, _))| !used[*i] && u.abs_diff(*t) <= PAIR_TOLERANCE_NS)
            .min_by_key(|(_, (u, _))| u.abs_diff(*t))
            .map(|(i, _)| i);
        let rep = m.map(|i| {
            used[i] = true;
            &replayed[i].1
        });
        cycles.push(ReplayCycle {
            t_s: t.saturating_sub(start) as f64 * 1e-9,
            recorded: Some(DecisionView::of(rec)),
            replayed: rep.map(DecisionView::of),
            identical: rep.is_some_and(|d| same_content(rec, d)),
            target_delta_m: rep.map(|d| {
                (0..3)
                    .map(|k| (f64::from(d.target[k]) - f64::from(rec.target[k])).powi(2))
                    .sum::<f64>()
                    .sqrt()
            }),
        });
    }
    for (i, (u, d)) in replayed.iter().enumerate() {
        if !used[i] {
            cycles.push(ReplayCycle {
                t_s: u.saturating_sub(start) as f64 * 1e-9,
                recorded: None,
                replayed: Some(DecisionView::of(d)),
                identical: false,
                target_delta_m: None,
            });
        }
    }
    cycles.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    cycles
}

/// Cycle-time figures from hub reports (compute time, which a faster replay does not
/// scale).
pub(super) fn figures(decisions: usize, reports: &[HubReport]) -> RunFigures {
    let ct: Vec<f64> = reports
        .iter()
        .filter(|r| r.committed == 1)
        .map(|r| r.ct_ns as f64 * 1e-9)
        .collect();
    let reused = reports.iter().filter(|r| r.reused == 1).count() as u64;
    let cycles = ct.len() as u64 + reused;
    RunFigures {
        decisions,
        cycles,
        ct_mean_s: if ct.is_empty() {
            0.0
        } else {
            ct.iter().sum::<f64>() / ct.len() as f64
        },
        ct_p95_s: aeris_runtime::stats::percentile(&ct, 95.0).unwrap_or(0.0),
        eer: if cycles == 0 {
            0.0
        } else {
            reused as f64 / cycles as f64
        },
    }
}

/// One variant's row of an A/B comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CompareRow {
    /// The variant (`ROLE=VARIANT`).
    pub variant: String,
    /// Its replay's summary.
    pub summary: ReplaySummary,
    /// Agreement with every other variant: identical decisions over the cycles either
    /// decided, in the order of the rows.
    pub agreement_with: Vec<f64>,
}

/// Replay `request` once per variant of `role` and compare them: with the recording and
/// with each other. `watcher` sees every replayed flight's events.
pub fn compare(
    request: &ReplayRequest,
    role: &str,
    variants: &[String],
    watcher: &mut dyn FlightWatcher,
) -> Result<Vec<CompareRow>, ReplayError> {
    let mut reports = Vec::with_capacity(variants.len());
    for (k, v) in variants.iter().enumerate() {
        let mut r = request.clone();
        r.variants.retain(|c| c.role != role);
        r.variants.push(VariantChoice {
            role: role.to_string(),
            variant: v.clone(),
        });
        // one flight name and run directory per variant: each keeps its own replay.mcap
        let base = request
            .name
            .clone()
            .unwrap_or_else(|| format!("replay-{}", std::process::id()));
        r.name = Some(format!("{base}-{k}"));
        r.run_dir = request.run_dir.as_ref().map(|d| d.join(v));
        reports.push(replay(&r, watcher)?);
    }
    let rows = reports
        .iter()
        .zip(variants)
        .map(|(rep, v)| CompareRow {
            variant: format!("{role}={v}"),
            summary: rep.summary.clone(),
            agreement_with: reports
                .iter()
                .map(|other| mutual_agreement(&rep.decisions, &other.decisions))
                .collect(),
        })
        .collect();
    Ok(rows)
}

/// Identical decisions over the frames either of two replays decided on.
fn mutual_agreement(a: &[(u64, Decision)], b: &[(u64, Decision)]) -> f64 {
    let cycles = pair(a, b, 0);
    match cycles.len() {
        0 => 1.0,
        n => cycles.iter().filter(|c| c.identical).count() as f64 / n as f64,
    }
}
