//! A new instruction for a formation in flight (`aeris formation say`), and the formation
//! role's answer. Both are flight-wide topics: `formation/say` and `formation/reply`.

use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Longest instruction (bytes of UTF-8).
pub const FORMATION_INSTRUCTION_MAX: usize = 512;

/// Longest answer (bytes of UTF-8).
pub const FORMATION_REPLY_MAX: usize = 384;

/// A new instruction for the formation in flight (`formation/say`).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::FormationCommand@s8")]
#[repr(C)]
pub struct FormationCommand {
    /// Chosen by the sender; the reply carries it back.
    pub id: u64,
    /// The instruction, e.g. "form a circle of radius 8 m, hold 5 s, and land".
    pub text: FixedText<FORMATION_INSTRUCTION_MAX>,
}

/// How a new instruction came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum SayOutcome {
    /// Planned as written; the formation flies it now.
    Accepted = 1,
    /// Planned after repairs; the formation flies the repaired program now.
    Repaired = 2,
    /// Refused (invalid or unsafe, or it does not fit the formation in flight): the
    /// formation flies on as before.
    Refused = 3,
}

impl SayOutcome {
    /// From its wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(Self::Accepted),
            2 => Some(Self::Repaired),
            3 => Some(Self::Refused),
            _ => None,
        }
    }

    /// `accepted`, `repaired`, `refused`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Accepted => "accepted",
            Self::Repaired => "repaired",
            Self::Refused => "refused",
        }
    }
}

/// The formation role's answer to a [`FormationCommand`] (`formation/reply`).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::FormationReply@s8")]
#[repr(C)]
pub struct FormationReply {
    /// The command's id.
    pub id: u64,
    /// [`SayOutcome`] as its wire byte.
    pub outcome: u8,
    /// Reserved, zero.
    pub reserved: [u8; 7],
    /// What was planned, or why it was refused.
    pub text: FixedText<FORMATION_REPLY_MAX>,
}
