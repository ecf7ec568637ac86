//! What the flight's monitors read from telemetry and reports: counters of publishers
//! that may restart, the controller's counters, whether the vehicle is flying. The flight's
//! monitor and the fleet's monitor both read them.

use aeris_schemas::VehicleTelemetry;

/// Cumulative counters of a publisher that may be restarted: a restarted process starts its
/// counters (and its sequence numbers) from zero, so the totals of the earlier processes are
/// kept as a base.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RestartSafeCounters<const N: usize> {
    base: [u64; N],
    last: [u64; N],
    last_seq: u64,
}

impl<const N: usize> Default for RestartSafeCounters<N> {
    fn default() -> Self {
        Self {
            base: [0; N],
            last: [0; N],
            last_seq: 0,
        }
    }
}

impl<const N: usize> RestartSafeCounters<N> {
    /// Record the counters of a sample with publisher sequence `seq`.
    pub(crate) fn update(&mut self, seq: u64, counters: [u64; N]) {
        if seq <= self.last_seq {
            // a new process: bank what the old one had counted
            for (b, l) in self.base.iter_mut().zip(self.last) {
                *b = b.saturating_add(l);
            }
        }
        self.last_seq = seq;
        self.last = counters;
    }

    pub(crate) fn total(&self, i: usize) -> u64 {
        self.base[i].saturating_add(self.last[i])
    }
}

/// The controller's counters a telemetry sample carries, in the order the monitors keep
/// them: ticks, missed ticks, refused setpoints, hold ticks.
pub(crate) fn controller_counters(t: &VehicleTelemetry) -> [u64; 4] {
    [
        t.controller_ticks,
        t.controller_missed_ticks,
        t.setpoints_refused,
        t.hold_ticks,
    ]
}

/// The vehicle is flying: above 1 m and not landed.
pub(crate) fn in_the_air(t: &VehicleTelemetry) -> bool {
    t.position[2] > 1.0 && t.landed == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_survive_a_publisher_restart() {
        let mut c = RestartSafeCounters::<2>::default();
        c.update(1, [1, 0]);
        c.update(2, [5, 1]);
        // the process restarts: sequence and counters from zero
        c.update(1, [2, 0]);
        c.update(2, [3, 2]);
        assert_eq!((c.total(0), c.total(1)), (8, 3));
    }
}
