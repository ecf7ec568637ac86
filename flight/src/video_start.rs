//! How soon the flight decides on its video once the video starts: from the capture of the
//! first camera frame captured after the flight was up to the publication of the first
//! decision taken on an S_t of a frame at least that recent. For a flight whose eyes are a
//! stream that starts after the roles (an FPV transmitter switched on, `aeris scene video
//! --follow`), this is how long the stack flies blind on telemetry once pictures exist; with a
//! camera that was already streaming it is the age of the first decision on a fresh frame.

use aeris_runtime::bus::{BusError, FlightBus, FrameSubscriber, TypedSubscriber};
use aeris_schemas::{Decision, topics};

/// Watches `camera/rgb` until its first frame and `reasoning/decision` until the first
/// decision on it; both subscriptions end then.
pub(crate) struct FirstDecisionOnVideo {
    frames: Option<FrameSubscriber>,
    decisions: Option<TypedSubscriber<Decision>>,
    /// Frames captured before this (CLOCK_MONOTONIC ns) are not the start of the video.
    since_ns: u64,
    first_frame_ns: Option<u64>,
    latency_ns: Option<u64>,
}

impl FirstDecisionOnVideo {
    /// Watch `bus` for frames captured from `since_ns` on.
    pub(crate) fn new(bus: &FlightBus, since_ns: u64) -> Result<Self, BusError> {
        Ok(Self {
            frames: Some(bus.frame_subscriber::<topics::CameraRgb>()?),
            decisions: Some(bus.subscriber::<topics::ReasoningDecision>()?),
            since_ns,
            first_frame_ns: None,
            latency_ns: None,
        })
    }

    /// Take in what arrived.
    pub(crate) fn poll(&mut self) -> Result<(), BusError> {
        if self.first_frame_ns.is_none()
            && let Some(frames) = &self.frames
        {
            while let Some(f) = frames.next()? {
                let capture = f.user_header().capture_ns;
                if capture >= self.since_ns {
                    self.first_frame_ns = Some(capture);
                    break;
                }
            }
            if self.first_frame_ns.is_some() {
                self.frames = None;
            }
        }
        let Some(decisions) = &self.decisions else {
            return Ok(());
        };
        while let Some(d) = decisions.next()? {
            if let Some(t0) = self.first_frame_ns
                && decided_on_a_frame_since(&d, t0)
            {
                self.latency_ns = Some(d.publish_ns.saturating_sub(t0));
                self.decisions = None;
                break;
            }
        }
        Ok(())
    }

    /// Seconds from the first frame to the first decision on it or a later frame; `None`
    /// before both happened (or when the flight had no video).
    pub(crate) fn seconds(&self) -> Option<f64> {
        self.latency_ns.map(|ns| ns as f64 * 1e-9)
    }
}

/// Whether `d` was decided on an S_t (its cycle starts at the S_t's frame capture, before the
/// S_t was published; a decision on telemetry alone starts and is stamped at its poll) of a
/// frame captured at `t0` or later.
fn decided_on_a_frame_since(d: &Decision, t0: u64) -> bool {
    d.cycle_start_ns >= t0 && d.state_stamp_ns > d.cycle_start_ns
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_decision_on_an_s_t_of_a_recent_frame_counts() {
        let on_state = |capture, published| Decision {
            cycle_start_ns: capture,
            state_stamp_ns: published,
            ..Decision::default()
        };
        assert!(decided_on_a_frame_since(&on_state(100, 150), 100));
        // an S_t of a frame before the video started
        assert!(!decided_on_a_frame_since(&on_state(90, 150), 100));
        // telemetry alone: the cycle starts at the poll, and that is its stamp
        assert!(!decided_on_a_frame_since(&on_state(200, 200), 100));
    }
}
