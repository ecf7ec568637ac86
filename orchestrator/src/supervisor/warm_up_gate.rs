//! The new side of a reasoner's hot swap warms up only between the running process's
//! decisions: the supervisor stops it (SIGSTOP) from shortly before the running process's
//! next decision is due until that decision is in (its working heartbeat), and lets it go
//! on (SIGCONT) in the gap after, until it is ready.
//!
//! Why, measured on a 2-core VM (`aeris bench swap`, 4 swaps a run, per-decision costs in
//! its JSON): with the new side only under SCHED_IDLE, the running SmolLM2's token
//! generation slowed up to 3x while a new Gemma-3 loaded and warmed up, and its decisions
//! came late: 0-2 missed heartbeats a run idle, 1-4 beside two busy processes. Warming up
//! on one thread helped idle (0 in 12 swaps) but not loaded (7 in 12), and its switch to
//! two threads (a new context) made the new side's first decisions slow; a CPU group of
//! its own with the lowest weight starved it (80 s to ready) and still slowed the running
//! one. Stopped between the decisions: 0 missed in 12 idle and 12 loaded swaps. A stopped
//! process is on no run queue at all.
//!
//! The schedule is predicted from the running process's last decision: it ended at its
//! heartbeat's stamp and took its cycle latency, so the next starts about a heartbeat
//! period after the last one started. The gate never holds longer than to a margin past
//! the predicted end of the next decision (a skipped or late one does not keep the new
//! process stopped), and not at all when the decisions leave too small a gap to warm up in.

use aeris_schemas::RoleHeartbeat;

/// How long before the predicted start of the running process's next decision the new
/// process stops, and how long after its predicted end it stays stopped at most (ns).
const MARGIN_NS: u64 = 300_000_000;
/// The least gap between decisions worth warming up in (ns): with less, the gate stays
/// open (the new process loads under SCHED_IDLE alone, as without the gate).
const MIN_GAP_NS: u64 = 300_000_000;

/// Whether the new side of a swap may run now, from the running process's decisions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct WarmUpGate {
    period_ns: u64,
    /// The running process's last decision: when its heartbeat was stamped (its end) and
    /// how long it took (ns).
    last_decision: Option<(u64, u64)>,
    /// The new process is stopped now.
    stopped: bool,
}

impl WarmUpGate {
    /// A gate for decisions every `period_ns` (the heartbeat period).
    pub(super) fn new(period_ns: u64) -> Self {
        Self {
            period_ns,
            last_decision: None,
            stopped: false,
        }
    }

    /// Read the running process's latest heartbeat: a working one is a decision.
    pub(super) fn observe(&mut self, hb: &RoleHeartbeat) {
        if hb.worked == 1 {
            self.last_decision = Some((hb.stamp_ns, hb.cycle_latency_ns));
        }
    }

    /// Whether the new process should be stopped at `now_ns`: from [`MARGIN_NS`] before
    /// the running process's next decision is predicted to start until [`MARGIN_NS`] after
    /// it is predicted to end (a decision that came in moves the prediction on).
    pub(super) fn holds(&self, now_ns: u64) -> bool {
        let Some((end, took)) = self.last_decision else {
            return false;
        };
        let gap = self.period_ns.saturating_sub(took);
        if gap < MIN_GAP_NS + MARGIN_NS {
            return false;
        }
        let next_start = end + gap - MARGIN_NS;
        let next_end = end + self.period_ns + MARGIN_NS;
        (next_start..next_end).contains(&now_ns)
    }

    /// Stop or continue process `pid` as [`WarmUpGate::holds`] says at `now_ns`
    /// (`ready`: it is ready, and runs from now on).
    pub(super) fn apply(&mut self, pid: u32, now_ns: u64, ready: bool) {
        let hold = !ready && self.holds(now_ns);
        if hold != self.stopped
            && let Ok(raw) = libc::pid_t::try_from(pid)
            && raw > 0
        {
            let signal = if hold { libc::SIGSTOP } else { libc::SIGCONT };
            // SAFETY: kill has no memory-safety preconditions; the pid is the supervisor's
            // unreaped child, so it cannot have been reused.
            if unsafe { libc::kill(raw, signal) } == 0 {
                self.stopped = hold;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    fn decision(end_ms: u64, took_ms: u64) -> RoleHeartbeat {
        RoleHeartbeat {
            worked: 1,
            stamp_ns: end_ms * MS,
            cycle_latency_ns: took_ms * MS,
            ..RoleHeartbeat::default()
        }
    }

    #[test]
    fn it_holds_from_before_the_next_decision_until_it_is_in() {
        let mut g = WarmUpGate::new(2000 * MS);
        assert!(!g.holds(5_000 * MS), "no decision seen: it runs");
        // a decision of 1.1 s ended at 10.0 s: the next runs about 10.9 - 12.0 s
        g.observe(&decision(10_000, 1100));
        assert!(!g.holds(10_001 * MS));
        assert!(!g.holds(10_599 * MS));
        assert!(g.holds(10_600 * MS));
        assert!(g.holds(12_200 * MS));
        // it came in at 12.05 s: the gap after it is open again
        g.observe(&decision(12_050, 1150));
        assert!(!g.holds(12_060 * MS));
        assert!(g.holds(12_600 * MS));
        // an idle heartbeat is no decision
        g.observe(&RoleHeartbeat {
            stamp_ns: 12_700 * MS,
            ..RoleHeartbeat::default()
        });
        assert!(g.holds(12_700 * MS));
    }

    #[test]
    fn a_missing_decision_or_no_gap_never_keeps_it_stopped() {
        let mut g = WarmUpGate::new(2000 * MS);
        g.observe(&decision(10_000, 1100));
        // the next decision did not come: held only to its predicted end plus the margin
        assert!(g.holds(12_299 * MS));
        assert!(!g.holds(12_300 * MS));
        assert!(!g.holds(20_000 * MS));
        // decisions of 1.5 s leave 0.5 s: too little to warm up in, it is never held
        g.observe(&decision(30_000, 1500));
        assert!((30_000..33_000).all(|ms| !g.holds(ms * MS)));
    }
}
