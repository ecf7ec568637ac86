//! A role's last few worked cycles, as the re-binding policy reads them: their latencies,
//! and each one's own cost — its latency over the scheduler slowdown measured while it ran.
//!
//! The own cost is what lets the policy see a hog before a cycle finishes late: the
//! latency a role's executor gives it *now* is its own cost times the slowdown of the last
//! scheduling samples. A reasoner deciding once per heartbeat reported only its pre-hog
//! decisions (0.5 s) until the first hogged one ended, 3 s later, two heartbeats lost; its
//! own cost times the slowdown it sees half a second into that decision says 3 s at once.

use crate::executors::SchedTime;
use crate::executors::shares;
use aeris_runtime::stats::LatencyWindow;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Worked cycles kept (the DS signal).
pub(super) const RECENT_CYCLES: usize = 8;

/// The last [`RECENT_CYCLES`] worked cycles of one process of a role.
#[derive(Debug, Clone)]
pub(super) struct RecentCycles {
    latency: LatencyWindow,
    own: LatencyWindow,
}

impl Default for RecentCycles {
    fn default() -> Self {
        Self {
            latency: LatencyWindow::new(RECENT_CYCLES),
            own: LatencyWindow::new(RECENT_CYCLES),
        }
    }
}

impl RecentCycles {
    /// Record a cycle of `ms` that ended at `end`, with the role's scheduler samples
    /// (`sched`, oldest first) to measure the slowdown it ran under.
    pub(super) fn push(&mut self, ms: f64, end: Instant, sched: &VecDeque<(Instant, SchedTime)>) {
        let slowdown = slowdown_over(sched, end, Duration::from_secs_f64(ms.max(0.0) / 1e3));
        self.latency.push(ms);
        self.own.push(ms / slowdown);
    }

    /// Median and 95th percentile of the latencies (ms); `None` before a cycle.
    fn latency_percentiles(&mut self) -> Option<[f64; 2]> {
        self.latency.percentiles([50.0, 95.0])
    }

    /// Median own cost (ms, the latency without the slowdown it ran under); `None`
    /// before a cycle.
    fn own_ms(&mut self) -> Option<f64> {
        self.own.percentiles([50.0]).map(|[p]| p)
    }

    /// The latency its executor gives it now (ms): the larger of the recent 95th
    /// percentile and its own cost at the slowdown `slowdown_now` measured over the last
    /// samples (1 when it barely ran then: nothing to say).
    pub(super) fn expected_ms(&mut self, slowdown_now: f64) -> Option<f64> {
        let [_, p95] = self.latency_percentiles()?;
        let own = self.own_ms()?;
        Some(p95.max(own * slowdown_now.max(1.0)))
    }
}

/// The scheduler slowdown `(run + wait) / run` over the samples that span a cycle of
/// `latency` ending at `end`: from the newest sample taken before it began (the oldest
/// kept when none was) to the newest. 1 when fewer than two samples span it or it barely
/// ran between them.
fn slowdown_over(sched: &VecDeque<(Instant, SchedTime)>, end: Instant, latency: Duration) -> f64 {
    let Some(last) = sched.back() else {
        return 1.0;
    };
    let began = end.checked_sub(latency).unwrap_or(end);
    let first = sched
        .iter()
        .rev()
        .find(|(t, _)| *t <= began)
        .or(sched.front())
        .unwrap_or(last);
    shares(first, last).map_or(1.0, |(s, _, _)| s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t0: Instant, ms: u64, run_ms: u64, wait_ms: u64) -> (Instant, SchedTime) {
        (
            t0 + Duration::from_millis(ms),
            SchedTime {
                run_ns: run_ms * 1_000_000,
                wait_ns: wait_ms * 1_000_000,
            },
        )
    }

    #[test]
    fn a_hog_shows_in_the_expected_latency_before_a_cycle_ends_late() {
        // a reasoner deciding in 500 ms every 2 s on a CPU of its own (slowdown 1.25)
        let t0 = Instant::now();
        let mut sched = VecDeque::new();
        let mut recent = RecentCycles::default();
        let (mut run, mut wait) = (0, 0);
        for beat in 0..4u64 {
            let start = beat * 2000;
            for k in 0..=8u64 {
                let ms = start + k * 250;
                if k > 0 && k <= 2 {
                    run += 200;
                    wait += 50;
                }
                sched.push_back(at(t0, ms, run, wait));
                if sched.len() > 9 {
                    sched.pop_front();
                }
                if k == 2 {
                    recent.push(500.0, t0 + Duration::from_millis(ms), &sched);
                }
            }
        }
        assert_eq!(recent.own_ms(), Some(400.0));
        // before the hog: what it reported
        assert_eq!(recent.expected_ms(1.0), Some(500.0));
        // 500 ms into a decision under a hog (slowdown 6), nothing finished late yet: its
        // own 400 ms at six times, over a 1 s budget at once
        assert_eq!(recent.expected_ms(6.0), Some(2400.0));
        // the pre-hog figures never read lower than they were
        assert_eq!(recent.expected_ms(0.5), Some(500.0));
    }

    #[test]
    fn a_cycle_spanned_by_no_two_samples_counts_as_unslowed() {
        let t0 = Instant::now();
        let mut recent = RecentCycles::default();
        recent.push(80.0, t0, &VecDeque::new());
        let one: VecDeque<_> = [at(t0, 0, 10, 90)].into();
        recent.push(80.0, t0 + Duration::from_millis(100), &one);
        assert_eq!(recent.own_ms(), Some(80.0));
        // under 2 ms of run time between the samples: no slowdown is measured
        let idle: VecDeque<_> = [at(t0, 0, 0, 0), at(t0, 250, 1, 100)].into();
        recent.push(80.0, t0 + Duration::from_millis(250), &idle);
        assert_eq!(recent.own_ms(), Some(80.0));
        // a slowdown of 2 over the samples spanning it halves its own cost
        let slowed: VecDeque<_> = [at(t0, 0, 0, 0), at(t0, 250, 100, 100)].into();
        for _ in 0..3 {
            recent.push(80.0, t0 + Duration::from_millis(250), &slowed);
        }
        assert_eq!(recent.own_ms(), Some(40.0));
    }
}
