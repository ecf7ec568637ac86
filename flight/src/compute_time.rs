//! What each semantic cycle's work took on this machine, on either clock: on simulated
//! time the flight's clock stands still while a role works, so the hub's cycle time is 0;
//! whether the models would keep up on this machine is read from the work itself.
//!
//! A cycle's compute time is the sum of the wall-clock latencies of the last cycle each
//! stage's role worked (from its heartbeats, measured on the wall clock in both modes):
//! the slowest of the perception models (detector, text reader, cues, occupancy,
//! image-to-text, which run side by side on a frame), then the role that composes S_t
//! (`perception`), then the reasoner's decision. Read when the hub reports the cycle, so a
//! stage's last worked cycle is the one behind the decision, or the one after it when the
//! next has already run (an approximation, the same on both clocks). A committed cycle
//! whose compute time exceeds the decision deadline, and a cycle without a fresh decision,
//! count in `eer_compute`: the decisions that would have missed their deadline on the wall
//! clock of this machine.

use crate::monitor::CycleTrace;
use aeris_orchestrator::supervisor::Supervisor;
use aeris_schemas::RoleKind;

/// The perception models that work on a frame side by side.
const MODEL_STAGES: [RoleKind; 5] = [
    RoleKind::Detector,
    RoleKind::TextReader,
    RoleKind::Cues,
    RoleKind::Occupancy,
    RoleKind::ImageToText,
];

/// Every reported cycle's compute time, as the flight goes.
#[derive(Debug, Default)]
pub(crate) struct ComputeWatch {
    /// Trace rows seen so far.
    seen: usize,
    /// Committed cycles' compute times (s).
    samples_s: Vec<f64>,
    /// Cycles over the deadline on compute, or without a fresh decision.
    misses: u64,
}

impl ComputeWatch {
    /// Take the cycles `trace` holds beyond those seen, each with the compute time the
    /// roles of `sup` report now, against `deadline_ns`.
    pub(crate) fn observe(&mut self, trace: &[CycleTrace], sup: &Supervisor, deadline_ns: u64) {
        let Some(new) = trace.get(self.seen..).filter(|n| !n.is_empty()) else {
            return;
        };
        let ns = cycle_compute_ns(sup);
        for row in new {
            if row.committed {
                self.samples_s.push(ns as f64 * 1e-9);
            }
            if !row.committed || ns > deadline_ns {
                self.misses += 1;
            }
        }
        self.seen = trace.len();
    }

    /// Committed cycles' compute times (s).
    pub(crate) fn samples_s(&self) -> &[f64] {
        &self.samples_s
    }

    /// Cycles over the deadline on compute, or without a fresh decision.
    pub(crate) fn misses(&self) -> u64 {
        self.misses
    }

    /// [`ComputeWatch::misses`] over the cycles seen.
    pub(crate) fn eer(&self) -> f64 {
        match self.seen {
            0 => 0.0,
            n => self.misses as f64 / n as f64,
        }
    }
}

/// The slowest model stage, the S_t composer and the reasoner, by their last worked cycle.
fn cycle_compute_ns(sup: &Supervisor) -> u64 {
    let last = |kinds: &[RoleKind]| {
        sup.roles()
            .iter()
            .filter(|r| kinds.contains(&r.kind()))
            .filter_map(|r| r.last_heartbeat())
            .map(|hb| hb.cycle_latency_ns)
            .max()
            .unwrap_or(0)
    };
    last(&MODEL_STAGES)
        .saturating_add(last(&[RoleKind::Perception]))
        .saturating_add(last(&[RoleKind::Reasoning]))
}
