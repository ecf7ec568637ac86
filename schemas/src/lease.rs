//! The autopilot lease (`controller/lease`): which of a flight's controllers may command the
//! autopilot.
//!
//! A flight may run a hot-standby controller beside the primary one. Both track the hub's
//! setpoints; only the holder of the lease writes to the autopilot, and it publishes a
//! [`ControllerLease`] at every poll. A controller that hears no lease for a few control
//! periods claims it with a higher epoch, so a dead or stopped holder is replaced long before
//! the autopilot gives up on its setpoints (PX4's offboard loss timeout is 1 s by default).

use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// [`ControllerLease::flags`]: `reference` holds the holder's position reference.
pub const LEASE_HAS_REFERENCE: u8 = 1;
/// [`ControllerLease::flags`]: `hold` and `hold_yaw` hold a latched hold position.
pub const LEASE_HAS_HOLD: u8 = 2;
/// [`ControllerLease::flags`]: the flight's autopilot has been heard (by this holder or one
/// before it), so a new holder whose own link hears nothing reports the link lost, not
/// silent from the start.
pub const LEASE_LINK_HEARD: u8 = 4;

/// One poll's claim of the autopilot by its holder, with the tracking state a standby needs
/// to go on from exactly where the holder was.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::ControllerLease@s8")]
#[repr(C)]
pub struct ControllerLease {
    /// Term of this holder: one more than the highest epoch its claimant had seen.
    pub epoch: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub stamp_ns: u64,
    /// Setpoints the holder has written to the autopilot in this term.
    pub sent: u64,
    /// Process id of the holder.
    pub holder_pid: u32,
    /// The holder's position reference ("carrot") `[N, E, U]` (m).
    pub reference: [f32; 3],
    /// Where the holder's current in-place mode began `[N, E, U]` (m).
    pub anchor: [f32; 3],
    /// The holder's latched hold position `[N, E, U]` (m).
    pub hold: [f32; 3],
    /// Yaw of the latched hold (rad).
    pub hold_yaw: f32,
    /// 1 for a primary controller, 0 for a standby: breaks a tie between two claims of one
    /// epoch in the primary's favour.
    pub rank: u8,
    /// Wire value of the `ActionMode` `anchor` belongs to; 0: no anchor.
    pub anchor_mode: u8,
    /// [`LEASE_HAS_REFERENCE`] | [`LEASE_HAS_HOLD`] | [`LEASE_LINK_HEARD`].
    pub flags: u8,
    /// Zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: u8,
}

impl ControllerLease {
    /// The order between claims: a higher epoch wins, then the primary, then the higher
    /// pid. Two different processes never compare equal.
    pub fn key(&self) -> (u64, u8, u32) {
        (self.epoch, self.rank, self.holder_pid)
    }
}
