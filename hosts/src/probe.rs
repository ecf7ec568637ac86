//! The link's own measurement: the bridge on the flight's host asks the other host's agent
//! for its `info` every [`LINK_PROBE_PERIOD_MS`] and publishes what the answers say on
//! `hosts/link` ([`HostLinkStatus`]): the round trip (last and smoothed), the probes lost
//! over the last [`LINK_LOSS_WINDOW`], the offset between the two hosts' clocks, how busy
//! the other host's CPUs are, and what encoding a frame for the link costs. A probe is
//! lost when no answer comes within the link timeout, or when it cannot be sent (no
//! session, or the link is down): a cut link shows 100 % loss, not a stale round trip.
//!
//! Probes run beside the flight's topics on the same session, at interactive priority, so
//! their round trip is what a decision's crossing sees.

use crate::protocol::{AgentReply, HostInfo, agent_request_key};
use aeris_runtime::bus::{BusError, RoleBus, TypedPublisher};
use aeris_schemas::kinds;
use aeris_schemas::{FixedText, HostLinkStatus, LINK_LOSS_WINDOW, LINK_PROBE_PERIOD_MS, topics};
use core::time::Duration;
use std::collections::VecDeque;
use zenoh::handlers::FifoChannelHandler;
use zenoh::query::Reply;
use zenoh::{Session, Wait};

/// Probes in flight at most (older ones count as lost when a new one would exceed it).
const MAX_IN_FLIGHT: usize = 8;

/// One probe of the window: answered (with its round trip and clock offset) or lost.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Outcome {
    Answered { rtt_ns: u64, offset_ns: i64 },
    Lost,
}

/// What the probes of one link have measured: pure bookkeeping, no I/O.
#[derive(Debug, Clone)]
pub struct LinkFigures {
    status: HostLinkStatus,
    window: VecDeque<Outcome>,
    /// Frames encoded and the time spent since the last probe.
    coded: (u64, u64),
}

impl LinkFigures {
    /// Figures of the link to `host`, none measured yet.
    pub fn new(host: &str) -> Self {
        LinkFigures {
            status: HostLinkStatus {
                host: FixedText::from_str_truncated(host),
                ..HostLinkStatus::default()
            },
            window: VecDeque::with_capacity(LINK_LOSS_WINDOW),
            coded: (0, 0),
        }
    }

    /// The figures as published.
    pub fn status(&self) -> &HostLinkStatus {
        &self.status
    }

    /// A probe was sent.
    pub fn sent(&mut self) {
        self.status.probes += 1;
    }

    /// A probe sent at `sent_ns` was answered at `now_ns` by an agent whose clock read
    /// `their_ns` (its `info`, when it could be read).
    pub fn answered(&mut self, sent_ns: u64, now_ns: u64, info: Option<&HostInfo>) {
        let rtt_ns = now_ns.saturating_sub(sent_ns);
        let s = &mut self.status;
        s.answered += 1;
        s.rtt_ns = rtt_ns;
        s.rtt_smoothed_ns = if s.answered == 1 {
            rtt_ns
        } else {
            // TCP's srtt: an eighth of the difference per answer
            (s.rtt_smoothed_ns as i128 + (rtt_ns as i128 - s.rtt_smoothed_ns as i128) / 8) as u64
        };
        let mut offset_ns = i64::MIN;
        if let Some(info) = info {
            let mid = (sent_ns as i128 + now_ns as i128) / 2;
            offset_ns = (info.monotonic_ns as i128 - mid)
                .clamp(i64::MIN as i128 + 1, i64::MAX as i128) as i64;
            s.busy_milli = (info.busy_cores * 1000.0)
                .round()
                .clamp(0.0, u32::MAX as f64) as u32;
            s.cpus = info.cpu_count;
        }
        self.push(Outcome::Answered { rtt_ns, offset_ns });
    }

    /// A probe got no answer in time, or could not be sent.
    pub fn lost(&mut self) {
        self.push(Outcome::Lost);
    }

    /// A frame for the link took `ns` to encode.
    pub fn frame_coded(&mut self, ns: u64) {
        self.coded.0 += 1;
        self.coded.1 += ns;
    }

    /// Close the figures for publication at `now_ns` (the link `connected` or not).
    pub fn close(&mut self, now_ns: u64, connected: bool) -> &HostLinkStatus {
        let s = &mut self.status;
        s.stamp_ns = now_ns;
        s.connected = connected as u8;
        if let Some(mean) = self.coded.1.checked_div(self.coded.0) {
            s.frame_coding_ns = mean;
            self.coded = (0, 0);
        }
        &self.status
    }

    fn push(&mut self, outcome: Outcome) {
        if self.window.len() == LINK_LOSS_WINDOW {
            self.window.pop_front();
        }
        self.window.push_back(outcome);
        let lost = self.window.iter().filter(|o| **o == Outcome::Lost).count();
        self.status.loss_permille = (lost * 1000 / self.window.len()) as u16;
        // the offset from the answer with the shortest round trip: the least queueing
        // between the two reads of the clock
        if let Some(offset) = self
            .window
            .iter()
            .filter_map(|o| match *o {
                Outcome::Answered { rtt_ns, offset_ns } if offset_ns != i64::MIN => {
                    Some((rtt_ns, offset_ns))
                }
                _ => None,
            })
            .min_by_key(|(rtt, _)| *rtt)
            .map(|(_, offset)| offset)
        {
            self.status.clock_offset_ns = offset;
        }
    }
}

/// The probe of one link: sends a probe every period, collects the answers, publishes the
/// figures on `hosts/link`.
pub struct LinkProbe {
    key: String,
    timeout_ns: u64,
    figures: LinkFigures,
    publisher: TypedPublisher<HostLinkStatus>,
    in_flight: VecDeque<(u64, FifoChannelHandler<Reply>)>,
    next_ns: u64,
}

impl LinkProbe {
    /// A probe of `host`'s agent; a probe unanswered after `timeout` is lost.
    pub fn new(
        bus: &RoleBus<kinds::Bridge>,
        host: &str,
        timeout: Duration,
    ) -> Result<Self, BusError> {
        Ok(LinkProbe {
            key: agent_request_key(host, "info"),
            timeout_ns: timeout.as_nanos() as u64,
            figures: LinkFigures::new(host),
            publisher: bus.publisher::<topics::HostsLink>()?,
            in_flight: VecDeque::with_capacity(MAX_IN_FLIGHT),
            next_ns: 0,
        })
    }

    /// A frame for the link took `ns` to encode.
    pub fn frame_coded(&mut self, ns: u64) {
        self.figures.frame_coded(ns);
    }

    /// Collect answers, count the late as lost, send the next probe when due, and publish
    /// when a probe was settled. `session` is `None` while the other host was never
    /// reached; `connected` is whether its router is connected now.
    pub fn step(&mut self, session: Option<&Session>, connected: bool, now_ns: u64) {
        let mut settled = false;
        while let Some((sent_ns, replies)) = self.in_flight.front() {
            let sent_ns = *sent_ns;
            match replies.try_recv() {
                Ok(Some(reply)) => {
                    let info =
                        reply.result().ok().and_then(|sample| {
                            match serde_json::from_slice::<AgentReply<HostInfo>>(
                                &sample.payload().to_bytes(),
                            ) {
                                Ok(AgentReply::Ok(info)) => Some(info),
                                _ => None,
                            }
                        });
                    self.figures.answered(sent_ns, now_ns, info.as_ref());
                }
                // still waiting
                Ok(None) if now_ns.saturating_sub(sent_ns) < self.timeout_ns => break,
                // late, or the query ended without an answer
                _ => self.figures.lost(),
            }
            self.in_flight.pop_front();
            settled = true;
        }
        if now_ns >= self.next_ns {
            self.next_ns = now_ns + LINK_PROBE_PERIOD_MS * 1_000_000;
            if self.in_flight.len() == MAX_IN_FLIGHT {
                self.in_flight.pop_front();
                self.figures.lost();
                settled = true;
            }
            self.figures.sent();
            let asked = session.filter(|_| connected).and_then(|s| {
                s.get(&self.key)
                    .timeout(Duration::from_nanos(self.timeout_ns))
                    .wait()
                    .ok()
            });
            match asked {
                Some(replies) => self.in_flight.push_back((now_ns, replies)),
                None => {
                    self.figures.lost();
                    settled = true;
                }
            }
        }
        if settled {
            let status = *self.figures.close(now_ns, connected);
            // a full buffer drops the oldest; nothing here can fail the bridge
            let _ = self.publisher.publish(&status);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(their_ns: u64, busy: f64) -> HostInfo {
        HostInfo {
            host: "ground".into(),
            schema: crate::protocol::SchemaStamp::current(),
            cpus: "0-1".into(),
            agent_pid: 1,
            roles: 0,
            monotonic_ns: their_ns,
            busy_cores: busy,
            cpu_count: 2,
        }
    }

    #[test]
    fn round_trip_smooths_and_the_offset_comes_from_the_fastest_answer() {
        let mut f = LinkFigures::new("ground");
        f.sent();
        // 2 ms round trip, their clock 1 s ahead at the midpoint
        f.answered(10_000_000, 12_000_000, Some(&info(1_011_000_000, 0.5)));
        let s = *f.close(12_000_000, true);
        assert_eq!((s.rtt_ns, s.rtt_smoothed_ns), (2_000_000, 2_000_000));
        assert_eq!(s.clock_offset_ns, 1_000_000_000);
        assert_eq!((s.busy_milli, s.cpus, s.connected), (500, 2, 1));
        assert_eq!(s.host.as_str_lossy(), "ground");
        // a slow answer moves the smoothed round trip by an eighth, not the offset
        f.sent();
        f.answered(20_000_000, 30_000_000, Some(&info(1_026_000_000, 0.5)));
        let s = *f.close(30_000_000, true);
        assert_eq!(s.rtt_ns, 10_000_000);
        assert_eq!(s.rtt_smoothed_ns, 3_000_000);
        assert_eq!(s.clock_offset_ns, 1_000_000_000);
        assert_eq!(s.loss_permille, 0);
    }

    #[test]
    fn loss_is_over_the_last_window_and_a_cut_link_reaches_all_of_it() {
        let mut f = LinkFigures::new("ground");
        for i in 0..LINK_LOSS_WINDOW as u64 {
            f.sent();
            if i % 4 == 0 {
                f.lost();
            } else {
                f.answered(i, i + 1000, None);
            }
        }
        assert_eq!(f.close(0, true).loss_permille, 250);
        for _ in 0..LINK_LOSS_WINDOW {
            f.sent();
            f.lost();
        }
        let s = *f.close(0, false);
        assert_eq!((s.loss_permille, s.connected), (1000, 0));
        assert_eq!(s.probes, 2 * LINK_LOSS_WINDOW as u64);
    }

    #[test]
    fn frame_coding_is_the_mean_since_the_last_publication() {
        let mut f = LinkFigures::new("ground");
        f.frame_coded(2_000_000);
        f.frame_coded(4_000_000);
        assert_eq!(f.close(0, true).frame_coding_ns, 3_000_000);
        // nothing coded since: the last figure stays
        assert_eq!(f.close(0, true).frame_coding_ns, 3_000_000);
    }
}
