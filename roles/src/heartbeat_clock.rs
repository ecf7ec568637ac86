//! When a reasoning role decides: once per semantic heartbeat, on a fresh S_t.
//!
//! A decision is only as recent as the S_t it uses: the hub measures its cycle from that
//! state's frame capture and rejects it after the deadline. So a reasoner decides on the
//! first fresh S_t once most of a heartbeat has passed since its last decision, and never
//! on a stale one: when no S_t arrived for one and a half heartbeats (perception slow or
//! down), it decides on the telemetry alone and the cycle starts then.

/// Share of a heartbeat after a decision from which a fresh S_t is decided on (the rest
/// absorbs the jitter of the perception pipeline, whose S_t come once per heartbeat), as
/// tenths: 9 = 0.9 heartbeats. Integer so the schedule is exact in nanoseconds.
pub const FRESH_AFTER_TENTHS: u64 = 9;
/// Heartbeats without a fresh S_t after which the reasoner decides without one, as
/// tenths: 15 = 1.5 heartbeats.
pub const STALE_AFTER_TENTHS: u64 = 15;

/// What the next decision is based on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Basis {
    /// The fresh S_t: the cycle starts at its frame capture.
    State,
    /// No fresh S_t in time: telemetry only, the cycle starts now.
    TelemetryOnly,
}

/// The decision schedule of a reasoning role (pure: the caller passes the time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeartbeatClock {
    period_ns: u64,
    started_ns: u64,
    last_ns: Option<u64>,
}

impl HeartbeatClock {
    /// A clock for heartbeats of `period_ns`, started at `now_ns`: the first fresh S_t is
    /// decided on at once; without one, the first decision comes half a heartbeat later.
    pub fn new(period_ns: u64, now_ns: u64) -> Self {
        Self {
            period_ns: period_ns.max(1),
            started_ns: now_ns,
            last_ns: None,
        }
    }

    /// Whether to decide now, and on what; `fresh_state` says a new valid S_t arrived
    /// since the last decision.
    pub fn due(&self, now_ns: u64, fresh_state: bool) -> Option<Basis> {
        let tenths = |n: u64| self.period_ns.saturating_mul(n) / 10;
        let Some(last) = self.last_ns else {
            // nothing decided yet: the first S_t at once, else half a heartbeat from start
            let waited = now_ns.saturating_sub(self.started_ns);
            return if fresh_state {
                Some(Basis::State)
            } else if waited >= tenths(STALE_AFTER_TENTHS - 10) {
                Some(Basis::TelemetryOnly)
            } else {
                None
            };
        };
        let since = now_ns.saturating_sub(last);
        if fresh_state && since >= tenths(FRESH_AFTER_TENTHS) {
            Some(Basis::State)
        } else if since >= tenths(STALE_AFTER_TENTHS) {
            Some(Basis::TelemetryOnly)
        } else {
            None
        }
    }

    /// A decision started at `now_ns`.
    pub fn decided(&mut self, now_ns: u64) {
        self.last_ns = Some(now_ns);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000_000;

    #[test]
    fn one_decision_per_heartbeat_on_fresh_states_whatever_their_rate() {
        // S_t every 2 s, arriving with jitter: every one is decided on
        let mut c = HeartbeatClock::new(2 * S, 0);
        let mut decided = 0;
        for k in 0..10u64 {
            let t = k * 2 * S + if k % 2 == 0 { 190 } else { 260 } * 1_000_000;
            assert_eq!(c.due(t, true), Some(Basis::State), "state {k}");
            c.decided(t);
            decided += 1;
        }
        assert_eq!(decided, 10);
        // S_t at 10 Hz over 20 s: one decision every 0.9 heartbeat (0, 1.8 s, .., 19.8 s),
        // not one per state
        let mut c = HeartbeatClock::new(2 * S, 0);
        let mut times = Vec::new();
        for k in 0..200u64 {
            let t = k * S / 10;
            if c.due(t, true).is_some() {
                c.decided(t);
                times.push(t);
            }
        }
        assert_eq!(times.len(), 12, "{times:?}");
        assert!(times.windows(2).all(|w| w[1] - w[0] == 18 * S / 10));
    }

    #[test]
    fn without_fresh_states_it_decides_on_telemetry_every_heartbeat_and_a_half() {
        let mut c = HeartbeatClock::new(2 * S, 10 * S);
        assert_eq!(c.due(10 * S, false), None);
        assert_eq!(c.due(10 * S + S - 1, false), None);
        assert_eq!(c.due(11 * S, false), Some(Basis::TelemetryOnly));
        c.decided(11 * S);
        assert_eq!(
            c.due(13 * S, false),
            None,
            "a stale state is never decided on"
        );
        assert_eq!(c.due(14 * S, false), Some(Basis::TelemetryOnly));
        assert_eq!(c.due(13 * S, true), Some(Basis::State));
    }
}
