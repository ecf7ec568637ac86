//! When a reasoning role decides: once per semantic heartbeat, on a fresh S_t.
//!
//! A decision is only as recent as the S_t it uses: the hub measures its cycle from that
//! state's frame capture and rejects it after the deadline. So a reasoner decides on the
//! first S_t *captured* most of a heartbeat after the start of its last cycle, and never on
//! a stale one: when no S_t arrived for one and a half heartbeats (perception slow or down),
//! it decides on the telemetry alone and the cycle starts then.
//!
//! Which S_t starts a cycle depends only on the capture times of the states, not on when
//! the reasoner happened to look: a replayed flight (the same frames at the same relative
//! times) decides on the same frames, which is what makes its decisions comparable, byte
//! for byte, with the recorded ones.
//!
//! One exception, for a reasoner that starts during a flight (a hot swap, a restart): its
//! first S_t is the one the topic's history hands it, up to a heartbeat old. A decision on
//! it would reach the hub after the deadline (measured: 2.2-2.8 s after its capture for
//! Gemma-3, and the replaced reasoner had already been stopped, so a heartbeat went without
//! a decision). So such a reasoner takes its first S_t only if it is young enough to be
//! decided within the deadline ([`HeartbeatClock::first_state_max_age`]); an older one is
//! counted as its predecessor's cycle, so the next S_t in the flight's rhythm starts its
//! first. A reasoner at a flight's start (or a replay's) has no such limit.
//!
//! The new side of a hot swap stands by until the supervisor makes it the role, while the
//! running process decides; from then ([`HeartbeatClock::resume`]) it takes the first S_t
//! captured after that moment: the ones before were its predecessor's.

/// Share of a heartbeat after a cycle's start from which a captured S_t starts the next
/// cycle (the rest absorbs the jitter of the perception pipeline), as tenths: 9 = 0.9
/// heartbeats. Integer so the schedule is exact in nanoseconds.
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
    /// When the first input (S_t or telemetry) came; `None` before.
    started_ns: Option<u64>,
    /// When the last decision was made (this machine's clock).
    last_ns: Option<u64>,
    /// When the last cycle started: its S_t's capture, or the decision itself.
    last_cycle_ns: Option<u64>,
    /// The oldest the first S_t may be when looked at (ns).
    first_max_age_ns: u64,
    /// S_t's captured before this (ns) were decided by another process.
    not_before_ns: u64,
}

impl HeartbeatClock {
    /// A clock for heartbeats of `period_ns`: the first fresh S_t is decided on at once;
    /// without one, the first decision comes half a heartbeat after the first input
    /// ([`HeartbeatClock::heard`]); with no input at all there is nothing to decide on.
    pub fn new(period_ns: u64) -> Self {
        Self {
            period_ns: period_ns.max(1),
            started_ns: None,
            last_ns: None,
            last_cycle_ns: None,
            first_max_age_ns: u64::MAX,
            not_before_ns: 0,
        }
    }

    /// Take a first S_t only if, when looked at, it is at most `max_age_ns` old: the
    /// decision deadline less the time a decision takes, so that the first decision of a
    /// reasoner started during a flight is not late (default: any age).
    pub fn first_state_max_age(mut self, max_age_ns: u64) -> Self {
        self.first_max_age_ns = max_age_ns;
        self
    }

    fn tenths(&self, n: u64) -> u64 {
        self.period_ns.saturating_mul(n) / 10
    }

    /// Some input (S_t or telemetry) came at `now_ns`: the first one starts the clock.
    pub fn heard(&mut self, now_ns: u64) {
        self.started_ns.get_or_insert(now_ns);
    }

    /// Whether an S_t captured at `capture_ns`, looked at `now_ns`, starts the next cycle:
    /// the first S_t does if it is young enough ([`HeartbeatClock::first_state_max_age`]),
    /// else it counts as a cycle decided before this reasoner (at `now_ns`); after that, one
    /// captured at least 0.9 heartbeats after the last cycle's start.
    /// An S_t captured before the reasoner [resumed](HeartbeatClock::resume) is never taken.
    pub fn takes(&mut self, capture_ns: u64, now_ns: u64) -> bool {
        if capture_ns < self.not_before_ns {
            return false;
        }
        match self.last_cycle_ns {
            None if now_ns.saturating_sub(capture_ns) <= self.first_max_age_ns => true,
            None => {
                self.decided(now_ns, capture_ns);
                false
            }
            Some(last) => capture_ns >= last.saturating_add(self.tenths(FRESH_AFTER_TENTHS)),
        }
    }

    /// Whether to decide now, and on what; `fresh_state` says an S_t the clock
    /// [takes](HeartbeatClock::takes) is waiting.
    pub fn due(&self, now_ns: u64, fresh_state: bool) -> Option<Basis> {
        if fresh_state {
            return Some(Basis::State);
        }
        let (since, stale) = match (self.last_ns, self.started_ns) {
            // nothing heard yet: nothing to decide on
            (None, None) => return None,
            // nothing decided yet: without an S_t, half a heartbeat from the first input
            (None, Some(started)) => (
                now_ns.saturating_sub(started),
                self.tenths(STALE_AFTER_TENTHS - 10),
            ),
            (Some(last), _) => (now_ns.saturating_sub(last), self.tenths(STALE_AFTER_TENTHS)),
        };
        (since >= stale).then_some(Basis::TelemetryOnly)
    }

    /// A decision made at `now_ns` whose cycle started at `cycle_start_ns`.
    pub fn decided(&mut self, now_ns: u64, cycle_start_ns: u64) {
        self.last_ns = Some(now_ns);
        self.last_cycle_ns = Some(cycle_start_ns);
    }

    /// The reasoner became the role at `now_ns` after standing by beside the running one (a
    /// hot swap's new side): the running process decided every S_t captured before then,
    /// so the first cycle starts on the first S_t captured from `now_ns` on, whatever its
    /// age when looked at (it is fresh: the supervisor hands over right after the running
    /// process's decision, and the first-S_t age limit, from a warm-up on the whole prompt,
    /// would let a fresh one go); without one, the decision on the telemetry alone comes a
    /// heartbeat and a half from `now_ns`, as after any decision.
    pub fn resume(&mut self, now_ns: u64) {
        self.not_before_ns = now_ns;
        self.first_max_age_ns = u64::MAX;
        self.last_ns = Some(now_ns);
        self.last_cycle_ns = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000_000;

    #[test]
    fn one_decision_per_heartbeat_on_fresh_states_whatever_their_rate() {
        // S_t every 2 s, arriving with jitter: every one is decided on
        let mut c = HeartbeatClock::new(2 * S);
        let mut decided = 0;
        for k in 0..10u64 {
            let capture = k * 2 * S;
            let t = capture + if k % 2 == 0 { 190 } else { 260 } * 1_000_000;
            assert!(c.takes(capture, t), "state {k}");
            assert_eq!(c.due(t, true), Some(Basis::State), "state {k}");
            c.decided(t, capture);
            decided += 1;
        }
        assert_eq!(decided, 10);
        // S_t at 10 Hz over 20 s: one decision every 0.9 heartbeat (0, 1.8 s, .., 19.8 s),
        // not one per state
        let mut c = HeartbeatClock::new(2 * S);
        let mut times = Vec::new();
        for k in 0..200u64 {
            let t = k * S / 10;
            if c.takes(t, t) {
                c.decided(t, t);
                times.push(t);
            }
        }
        assert_eq!(times.len(), 12, "{times:?}");
        assert!(times.windows(2).all(|w| w[1] - w[0] == 18 * S / 10));
    }

    #[test]
    fn the_frames_decided_on_depend_on_their_capture_times_not_on_when_they_arrive() {
        // the same 10 Hz states, once arriving 40 ms after capture and once with 40-390 ms
        // of jitter: the same captures start the cycles
        let run = |latency: &dyn Fn(u64) -> u64| {
            let mut c = HeartbeatClock::new(2 * S);
            let mut chosen = Vec::new();
            for k in 0..100u64 {
                let capture = k * S / 10;
                if c.takes(capture, capture + latency(k)) {
                    c.decided(capture + latency(k), capture);
                    chosen.push(capture);
                }
            }
            chosen
        };
        let steady = run(&|_| 40_000_000);
        let jittery = run(&|k| 40_000_000 + (k * 7919 % 351) * 1_000_000);
        assert_eq!(steady, jittery);
        assert_eq!(steady.len(), 6);
    }

    #[test]
    fn without_fresh_states_it_decides_on_telemetry_every_heartbeat_and_a_half() {
        let mut c = HeartbeatClock::new(2 * S);
        assert_eq!(
            c.due(10 * S, false),
            None,
            "nothing heard: nothing to decide on"
        );
        c.heard(10 * S);
        c.heard(10 * S + 5);
        assert_eq!(c.due(10 * S, false), None);
        assert_eq!(c.due(10 * S + S - 1, false), None);
        assert_eq!(c.due(11 * S, false), Some(Basis::TelemetryOnly));
        c.decided(11 * S, 11 * S);
        assert_eq!(
            c.due(13 * S, false),
            None,
            "a stale state is never decided on"
        );
        assert_eq!(c.due(14 * S, false), Some(Basis::TelemetryOnly));
        assert!(
            !c.takes(12 * S, 13 * S),
            "captured too soon after the cycle's start"
        );
        assert!(c.takes(11 * S + 18 * S / 10, 13 * S));
        assert_eq!(c.due(13 * S, true), Some(Basis::State));
    }

    #[test]
    fn a_reasoner_started_during_a_flight_skips_a_first_state_too_old_to_decide_in_time() {
        // deadline 2 s, decisions take 0.7 s: a first S_t may be at most 1.3 s old
        let mut c = HeartbeatClock::new(2 * S).first_state_max_age(13 * S / 10);
        // the topic's history hands it an S_t captured 1.8 s before it looks: skipped, as
        // its predecessor's cycle
        assert!(!c.takes(10 * S, 11 * S + 8 * S / 10));
        c.heard(11 * S + 8 * S / 10);
        assert_eq!(
            c.due(12 * S, false),
            None,
            "no decision on the telemetry at once"
        );
        // one captured out of the flight's rhythm is not taken either
        assert!(!c.takes(11 * S, 12 * S));
        // the next in the rhythm, captured 2 s after it and looked at 50 ms later: taken
        assert!(c.takes(12 * S, 12 * S + S / 20));
        c.decided(12 * S + S / 20, 12 * S);
        // after the first cycle the age plays no part: the capture times alone decide
        assert!(c.takes(14 * S, 20 * S));
        // by default any first S_t is taken (the first of a flight arrives fresh)
        assert!(HeartbeatClock::new(2 * S).takes(0, 100 * S));
    }

    #[test]
    fn a_reasoner_that_stood_by_takes_the_first_state_captured_after_it_became_the_role() {
        // a warm-up on the whole prompt estimated 3.1 s: the first-S_t limit takes none
        let mut c = HeartbeatClock::new(2 * S).first_state_max_age(0);
        c.heard(10 * S);
        // handed over at 11.3 s, right after the running process decided the S_t of 10 s
        c.resume(11 * S + 3 * S / 10);
        // that S_t, looked at only now, was its predecessor's
        assert!(!c.takes(10 * S, 11 * S + 35 * S / 100));
        assert_eq!(
            c.due(12 * S, false),
            None,
            "no decision on the telemetry at once"
        );
        // the next, captured at 12 s and looked at 0.3 s later, is decided on: fresh, not
        // held to the warm-up's estimate
        assert!(c.takes(12 * S, 12 * S + 3 * S / 10));
        assert_eq!(c.due(12 * S + 3 * S / 10, true), Some(Basis::State));
        c.decided(12 * S + 3 * S / 10, 12 * S);
        assert!(c.takes(14 * S, 14 * S + 3 * S / 10));
        // had no S_t come, the telemetry alone would have been decided on 3 s after it
        let mut quiet = HeartbeatClock::new(2 * S);
        quiet.heard(10 * S);
        quiet.resume(11 * S);
        assert_eq!(quiet.due(14 * S - 1, false), None);
        assert_eq!(quiet.due(14 * S, false), Some(Basis::TelemetryOnly));
    }
}
