//! The autopilot link as the controller sees it (`controller/link`): whom it flies, what it
//! heard, and what the autopilot refused. The flight reads it to end a flight whose
//! autopilot never answered (naming what was heard instead), to report a link lost in
//! flight, and to show a refused command with its MAV_RESULT.

use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Longest autopilot URL carried (longer ones are truncated).
pub const LINK_URL_MAX: usize = 96;
/// Longest description of a refusal or a foreign sender.
pub const LINK_NOTE_MAX: usize = 80;

/// Where the link is ([`AutopilotLinkStatus::state`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum LinkState {
    /// No autopilot heartbeat yet, and the link timeout has not passed.
    Waiting = 1,
    /// The autopilot's heartbeat is fresh.
    Up = 2,
    /// No autopilot heartbeat within the link timeout of the controller's start.
    Silent = 3,
    /// The autopilot was heard, then not for the link timeout.
    Lost = 4,
}

impl LinkState {
    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(LinkState::Waiting),
            2 => Some(LinkState::Up),
            3 => Some(LinkState::Silent),
            4 => Some(LinkState::Lost),
            _ => None,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            LinkState::Waiting => "waiting",
            LinkState::Up => "up",
            LinkState::Silent => "silent",
            LinkState::Lost => "lost",
        }
    }
}

/// The firmware flown ([`AutopilotLinkStatus::autopilot`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum AutopilotKind {
    /// Not bound to an autopilot yet.
    Unknown = 0,
    /// PX4 (offboard).
    Px4 = 1,
    /// ArduPilot Copter (guided).
    ArduPilot = 2,
}

impl AutopilotKind {
    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            0 => Some(AutopilotKind::Unknown),
            1 => Some(AutopilotKind::Px4),
            2 => Some(AutopilotKind::ArduPilot),
            _ => None,
        }
    }

    /// The firmware's name.
    pub fn name(self) -> &'static str {
        match self {
            AutopilotKind::Unknown => "unknown",
            AutopilotKind::Px4 => "PX4",
            AutopilotKind::ArduPilot => "ArduPilot",
        }
    }
}

/// What the lease-holding controller knows of its autopilot link, every control tick.
/// Counters count from the controller process's start.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::AutopilotLinkStatus@s8")]
#[repr(C)]
pub struct AutopilotLinkStatus {
    /// Publisher sequence number.
    pub seq: u64,
    /// The autopilot-lease epoch of the controller that published it: a controller that
    /// takes the lease holds a higher one, so a reader tells the holders' statuses apart
    /// (and drops a former holder's late ones) whatever order they are read in.
    pub lease_epoch: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub stamp_ns: u64,
    /// Frames received and decoded, from anyone.
    pub frames: u64,
    /// Frames from the autopilot flown.
    pub autopilot_frames: u64,
    /// Frames from other systems or components (a GCS, MAVProxy, another vehicle), ignored.
    pub other_frames: u64,
    /// MAVLink 1 frames refused (the controller is configured for MAVLink 2 only).
    pub v1_refused: u64,
    /// Unsigned frames refused (signing is on).
    pub unsigned_refused: u64,
    /// Signed frames whose signature or timestamp did not check, refused.
    pub bad_signature_refused: u64,
    /// Frame-shaped bytes whose CRC did not check, dropped (a run of damage counts once;
    /// not counted on serial links).
    pub crc_failures: u64,
    /// Heartbeats of systems that are not autopilots the controller can fly.
    pub foreign_heartbeats: u64,
    /// Commands the autopilot refused (a COMMAND_ACK with a result other than accepted or
    /// in progress).
    pub commands_refused: u64,
    /// Times the link went from up to lost.
    pub losses: u64,
    /// The link timeout (ms).
    pub timeout_ms: u32,
    /// The last refused command's MAV_CMD.
    pub last_refused_command: u16,
    /// [`LinkState`] as a byte.
    pub state: u8,
    /// [`AutopilotKind`] as a byte.
    pub autopilot: u8,
    /// The autopilot's system id (0 until bound).
    pub system_id: u8,
    /// The autopilot's component id (0 until bound).
    pub component_id: u8,
    /// The MAVLink version of the autopilot's last heartbeat (0: unknown).
    pub heard_version: u8,
    /// The MAVLink version the controller sends (1 or 2).
    pub send_version: u8,
    /// The last refused command's MAV_RESULT.
    pub last_refused_result: u8,
    /// The last other sender's system id (0: none).
    pub other_system_id: u8,
    /// The last other sender's component id.
    pub other_component_id: u8,
    /// The MAV_TYPE of the last foreign heartbeat (0 when none).
    pub foreign_type: u8,
    /// The MAV_AUTOPILOT of the last foreign heartbeat.
    pub foreign_autopilot: u8,
    /// 1 when MAVLink 2 signing is on.
    pub signing: u8,
    /// The autopilot's URL.
    pub url: FixedText<LINK_URL_MAX>,
    /// The last refused command and its result, by name (`MAV_CMD_... : MAV_RESULT_...`).
    pub last_refusal: FixedText<LINK_NOTE_MAX>,
    /// The last foreign heartbeat's sender, by name (`MAV_TYPE_..., MAV_AUTOPILOT_...`).
    pub foreign: FixedText<LINK_NOTE_MAX>,
}

impl Default for AutopilotLinkStatus {
    fn default() -> Self {
        Self {
            seq: 0,
            lease_epoch: 0,
            stamp_ns: 0,
            frames: 0,
            autopilot_frames: 0,
            other_frames: 0,
            v1_refused: 0,
            unsigned_refused: 0,
            bad_signature_refused: 0,
            crc_failures: 0,
            foreign_heartbeats: 0,
            commands_refused: 0,
            losses: 0,
            timeout_ms: 0,
            last_refused_command: 0,
            state: LinkState::Waiting as u8,
            autopilot: AutopilotKind::Unknown as u8,
            system_id: 0,
            component_id: 0,
            heard_version: 0,
            send_version: 2,
            last_refused_result: 0,
            other_system_id: 0,
            other_component_id: 0,
            foreign_type: 0,
            foreign_autopilot: 0,
            signing: 0,
            url: FixedText::new(),
            last_refusal: FixedText::new(),
            foreign: FixedText::new(),
        }
    }
}

impl AutopilotLinkStatus {
    /// The link's state; `None` for a byte that is no [`LinkState`].
    pub fn link_state(&self) -> Option<LinkState> {
        LinkState::from_u8(self.state)
    }
}
