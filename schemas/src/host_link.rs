//! A link to another host as the flight's host measures it (`hosts/link`): the bridge on the
//! flight's host asks the other host's agent for its `info` every [`LINK_PROBE_PERIOD_MS`]
//! and publishes what the answers (and the silences) say. The supervisor shows it in
//! `aeris status` and adds its round trip to the predicted cycle of a role placed there.

use crate::heartbeat::NAME_MAX;
use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// How often the link is probed (ms).
pub const LINK_PROBE_PERIOD_MS: u64 = 250;
/// The probes [`HostLinkStatus::loss_permille`] is taken over (the last this many).
pub const LINK_LOSS_WINDOW: usize = 20;
/// Maximum number of other hosts a flight names (and the status board lists).
pub const MAX_HOSTS: usize = 4;

/// One link's figures (`hosts/link`, one sample per probe answered or lost).
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::HostLinkStatus@s8")]
#[repr(C)]
pub struct HostLinkStatus {
    /// The other host's name (`[hosts.NAME]`).
    pub host: FixedText<NAME_MAX>,
    /// Probes sent so far.
    pub probes: u64,
    /// Probes answered within the link timeout so far.
    pub answered: u64,
    /// CLOCK_MONOTONIC ns (this host) of publication.
    pub stamp_ns: u64,
    /// Round trip of the last probe answered (ns; 0 = none yet).
    pub rtt_ns: u64,
    /// Smoothed round trip (ns): `srtt += (rtt - srtt) / 8` per answer, as TCP's.
    pub rtt_smoothed_ns: u64,
    /// The other host's CLOCK_MONOTONIC minus this host's (ns), from the probe with the
    /// shortest round trip of the last [`LINK_LOSS_WINDOW`] (their clock read at the
    /// midpoint of ours). Stamps are not rewritten with it; it is shown.
    pub clock_offset_ns: i64,
    /// Mean time to encode one frame for this link (ns) over the last probe period; 0 when
    /// frames cross raw or none was encoded yet.
    pub frame_coding_ns: u64,
    /// Busy cores of the other host's role CPUs, thousandths, as its agent measured them.
    pub busy_milli: u32,
    /// The other host's role CPUs (0 = not heard yet).
    pub cpus: u32,
    /// Probes of the last [`LINK_LOSS_WINDOW`] that got no answer within the link timeout,
    /// in thousandths of those sent.
    pub loss_permille: u16,
    /// 1 while the other host's router is connected.
    pub connected: u8,
    /// Reserved, zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: [u8; 5],
}

impl HostLinkStatus {
    /// The smoothed round trip in ms, `None` before the first answer.
    pub fn rtt_ms(&self) -> Option<f64> {
        (self.answered > 0).then(|| self.rtt_smoothed_ns as f64 / 1e6)
    }

    /// The loss over the window as a fraction (0..1).
    pub fn loss(&self) -> f64 {
        f64::from(self.loss_permille) / 1000.0
    }

    /// Busy cores of the other host's role CPUs.
    pub fn busy_cores(&self) -> f64 {
        f64::from(self.busy_milli) / 1000.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_read_in_their_units() {
        let mut s = HostLinkStatus::default();
        assert_eq!(s.rtt_ms(), None);
        s.answered = 3;
        s.rtt_smoothed_ns = 1_500_000;
        s.loss_permille = 50;
        s.busy_milli = 1250;
        assert_eq!(s.rtt_ms(), Some(1.5));
        assert!((s.loss() - 0.05).abs() < 1e-12);
        assert!((s.busy_cores() - 1.25).abs() < 1e-12);
    }
}
