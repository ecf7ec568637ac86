//! Commands to a running flight's supervisor (`aeris swap ...`, `aeris migrate ...`) and its
//! replies, over the
//! iceoryx2 request-response service [`crate::topics::SUPERVISOR_CONTROL`].
//!
//! One request gets a stream of replies: started, ready, done (or failed at any point). The
//! last reply of a request is always [`ReplyStage::Done`] or [`ReplyStage::Failed`].

use crate::heartbeat::NAME_MAX;
use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Longest reply message (bytes).
pub const REPLY_MESSAGE_MAX: usize = 4096;

/// What a command asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum CommandKind {
    /// Replace a running role by another variant of its pool, make-before-break.
    Swap = 1,
    /// Move a running role's process (every thread) to another CPU set, live.
    Migrate = 2,
}

impl CommandKind {
    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(CommandKind::Swap),
            2 => Some(CommandKind::Migrate),
            _ => None,
        }
    }
}

/// A command to the supervisor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("aeris::SupervisorCommand@s8")]
#[repr(C)]
pub struct SupervisorCommand {
    /// [`CommandKind`] wire byte.
    pub kind: u8,
    /// Reserved, zero.
    pub reserved: [u8; 3],
    /// How long the new process may take to load, warm up and send its first
    /// heartbeat before the swap is rolled back (ms; 0 = the supervisor's default).
    pub ready_timeout_ms: u32,
    /// Role name (as in the workflow).
    pub role: FixedText<NAME_MAX>,
    /// Where the command takes the role: the variant to run (swap) or the CPU list or
    /// executor name to move it to (migrate).
    pub target: FixedText<NAME_MAX>,
}

impl SupervisorCommand {
    /// A swap of `role` to `variant`.
    pub fn swap(role: &str, variant: &str, ready_timeout_ms: u32) -> Self {
        Self {
            kind: CommandKind::Swap as u8,
            reserved: [0; 3],
            ready_timeout_ms,
            role: FixedText::from_str_truncated(role),
            target: FixedText::from_str_truncated(variant),
        }
    }

    /// A live move of `role` to `cpus` (a CPU list such as `0-1`, or an executor name).
    pub fn migrate(role: &str, cpus: &str) -> Self {
        Self {
            kind: CommandKind::Migrate as u8,
            reserved: [0; 3],
            ready_timeout_ms: 0,
            role: FixedText::from_str_truncated(role),
            target: FixedText::from_str_truncated(cpus),
        }
    }
}

/// How far a command got.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ReplyStage {
    /// The supervisor took the command and started the new process (`new_pid`).
    Started = 1,
    /// The new process loaded, warmed up and published its first heartbeat; the
    /// old one is being stopped.
    Ready = 2,
    /// Done: the new process runs, the old one exited.
    Done = 3,
    /// Refused or rolled back; the old process keeps running. `message` says why.
    Failed = 4,
}

impl ReplyStage {
    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        [
            ReplyStage::Started,
            ReplyStage::Ready,
            ReplyStage::Done,
            ReplyStage::Failed,
        ]
        .into_iter()
        .find(|s| *s as u8 == v)
    }

    /// `true` for the last reply of a request.
    pub fn is_final(self) -> bool {
        matches!(self, ReplyStage::Done | ReplyStage::Failed)
    }
}

/// One reply of the supervisor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("aeris::SupervisorReply@s8")]
#[repr(C)]
pub struct SupervisorReply {
    /// [`ReplyStage`] wire byte.
    pub stage: u8,
    /// Reserved, zero.
    pub reserved: [u8; 3],
    /// pid of the process being replaced (0 = none).
    pub old_pid: u32,
    /// pid of the new process (0 = not started).
    pub new_pid: u32,
    /// Instance number of the new process.
    pub new_instance: u32,
    /// Milliseconds since the supervisor accepted the command.
    pub elapsed_ms: u64,
    /// What happened, for people.
    pub message: FixedText<REPLY_MESSAGE_MAX>,
}

impl SupervisorReply {
    /// A reply at `stage` saying `message`.
    pub fn new(stage: ReplyStage, message: &str) -> Self {
        Self {
            stage: stage as u8,
            reserved: [0; 3],
            old_pid: 0,
            new_pid: 0,
            new_instance: 0,
            elapsed_ms: 0,
            message: FixedText::from_str_truncated(message),
        }
    }

    /// The stage, if the byte is known.
    pub fn stage(&self) -> Option<ReplyStage> {
        ReplyStage::from_u8(self.stage)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_round_trip_and_only_done_and_failed_are_final() {
        for v in 0..=8u8 {
            if let Some(s) = ReplyStage::from_u8(v) {
                assert_eq!(s as u8, v);
                assert_eq!(s.is_final(), v >= 3);
            } else {
                assert!(v == 0 || v > 4);
            }
        }
        let c = SupervisorCommand::swap("reasoning", "gemma3", 0);
        assert_eq!(CommandKind::from_u8(c.kind), Some(CommandKind::Swap));
        assert_eq!(c.target.as_str(), Some("gemma3"));
        let m = SupervisorCommand::migrate("hub", "0-1");
        assert_eq!(CommandKind::from_u8(m.kind), Some(CommandKind::Migrate));
        assert_eq!(m.target.as_str(), Some("0-1"));
        assert_eq!(CommandKind::from_u8(3), None);
    }
}
