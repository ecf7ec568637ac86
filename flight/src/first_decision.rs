//! A flight that never gets a decision fails with the reason instead of hovering until its
//! time limit. Before the hub commits a first decision it reports no cycle (there is nothing
//! to reuse), so a reasoner whose every decision arrives after the deadline (a model that does
//! not fit the machine's heartbeat, measured: SmolLM2 at 4.2 s a decision against a 2 s
//! deadline) left a flight "waiting for the first decision" for its whole time limit (378 s),
//! and a benchmark counting cycles waited for cycles that never came. After
//! [`FIRST_DECISION_HEARTBEATS`] heartbeats of flight without one, the flight fails and says
//! what the hub saw: decisions late (and how late is in the reasoner's log), rejected, or none.

use aeris_schemas::HubBeatCounters;
use std::time::Duration;

/// Heartbeats of flight without a first committed decision after which the flight fails:
/// long enough for a variant ladder to step down (it decides on a few heartbeats' latency)
/// and for a reasoner's fallback to take over.
pub const FIRST_DECISION_HEARTBEATS: u32 = 15;

/// Why no first decision came, when one is overdue.
#[derive(Debug, Clone, PartialEq)]
pub struct NoFirstDecision {
    /// Seconds flown without one.
    pub waited_s: f64,
    /// The hub's decision counters then.
    pub hub: HubBeatCounters,
    /// The decision deadline (ms).
    pub deadline_ms: u64,
}

impl core::fmt::Display for NoFirstDecision {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let h = &self.hub;
        write!(
            f,
            "no decision was committed in {:.0} s of flight: ",
            self.waited_s
        )?;
        if h.received == 0 {
            return f.write_str(
                "the hub received none from the reasoner (its log says why it is silent)",
            );
        }
        write!(
            f,
            "of {} received, {} came after the {} ms deadline and {} more were rejected by the gate",
            h.received,
            h.late,
            self.deadline_ms,
            h.rejected.saturating_sub(h.late)
        )?;
        if h.late * 2 >= h.received {
            f.write_str(
                "; the reasoner does not decide within the heartbeat on this machine: a lighter \
                 variant, the variant ladder (`scheduling.adapt_variants`), or a longer \
                 `flight.decision_deadline_ms`",
            )?;
        }
        Ok(())
    }
}

/// Whether a flight flying for `flown` with `cycles` hub cycles so far (committed or reused)
/// and the hub's heartbeat counters `hub` is overdue a first decision, at heartbeats of
/// `heartbeat` and a decision deadline of `deadline_ms`.
pub fn overdue(
    flown: Duration,
    cycles: u64,
    hub: Option<HubBeatCounters>,
    heartbeat: Duration,
    deadline_ms: u64,
) -> Option<NoFirstDecision> {
    if cycles > 0 || flown < heartbeat * FIRST_DECISION_HEARTBEATS {
        return None;
    }
    Some(NoFirstDecision {
        waited_s: flown.as_secs_f64(),
        hub: hub.unwrap_or_default(),
        deadline_ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const HB: Duration = Duration::from_secs(2);

    #[test]
    fn a_flight_without_a_first_decision_fails_after_its_heartbeats_and_says_why() {
        let late = HubBeatCounters {
            received: 14,
            rejected: 14,
            late: 14,
            ..Default::default()
        };
        // not yet: 14 heartbeats flown
        assert_eq!(overdue(HB * 14, 0, Some(late), HB, 2000), None);
        // a cycle came: never
        assert_eq!(overdue(HB * 100, 1, Some(late), HB, 2000), None);
        let failure = overdue(HB * 15, 0, Some(late), HB, 2000).expect("overdue");
        let text = failure.to_string();
        assert!(
            text.contains("no decision was committed in 30 s")
                && text.contains("of 14 received, 14 came after the 2000 ms deadline")
                && text.contains("does not decide within the heartbeat"),
            "{text}"
        );
        // nothing received at all
        let text = overdue(HB * 15, 0, None, HB, 2000).unwrap().to_string();
        assert!(text.contains("received none from the reasoner"), "{text}");
        // rejected by the gate, not late: no advice about speed
        let invalid = HubBeatCounters {
            received: 15,
            rejected: 15,
            ..Default::default()
        };
        let text = overdue(HB * 15, 0, Some(invalid), HB, 2000)
            .unwrap()
            .to_string();
        assert!(
            text.contains("0 came after") && text.contains("15 more were rejected"),
            "{text}"
        );
        assert!(!text.contains("does not decide within"), "{text}");
    }
}
