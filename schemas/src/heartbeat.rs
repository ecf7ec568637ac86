//! Role heartbeats: every role publishes one per cycle on `heartbeat`.

use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Maximum number of stage timings in one heartbeat.
pub const MAX_STAGES: usize = 4;
/// Maximum bytes of a role, variant or executor name.
pub const NAME_MAX: usize = 32;

/// Health a role reports about itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum RoleStatus {
    /// Loading / warming up; not yet producing output.
    Starting = 1,
    /// Producing output normally.
    Running = 2,
    /// Producing output but something is wrong (e.g. missing input).
    Degraded = 3,
    /// Shutting down after a termination request.
    Stopping = 4,
}

impl RoleStatus {
    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(RoleStatus::Starting),
            2 => Some(RoleStatus::Running),
            3 => Some(RoleStatus::Degraded),
            4 => Some(RoleStatus::Stopping),
            _ => None,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            RoleStatus::Starting => "starting",
            RoleStatus::Running => "running",
            RoleStatus::Degraded => "degraded",
            RoleStatus::Stopping => "stopping",
        }
    }
}

/// Duration of one named stage of a role's cycle.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct StageTiming {
    /// Stage name (empty = unused slot).
    pub name: FixedText<16>,
    /// Duration in ns.
    pub ns: u64,
}

/// A role's heartbeat (`heartbeat`).
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::RoleHeartbeat@s8")]
#[repr(C)]
pub struct RoleHeartbeat {
    /// Role instance name (unique in the flight).
    pub role: FixedText<NAME_MAX>,
    /// Variant the role runs.
    pub variant: FixedText<NAME_MAX>,
    /// CPUs the role's main thread may run on (a CPU list such as "0-1"), read from the
    /// kernel for every heartbeat, so a live move shows in the next one.
    pub executor: FixedText<NAME_MAX>,
    /// OS process id.
    pub pid: u32,
    /// Role status as [`RoleStatus`] wire byte.
    pub status: u8,
    /// 1 when this heartbeat closes a cycle that did work (its latency and stages are new);
    /// 0 for a liveness heartbeat of an idle role (figures repeat the last working cycle).
    pub worked: u8,
    /// Reserved, zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: [u8; 2],
    /// Heartbeat sequence number (from 1, +1 per cycle).
    pub seq: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub stamp_ns: u64,
    /// Duration of the last cycle's work in ns.
    pub cycle_latency_ns: u64,
    /// Per-stage breakdown of the last cycle.
    pub stages: [StageTiming; MAX_STAGES],
    /// Role-specific counters (meaning documented per role).
    pub counters: [u64; 8],
}

impl Default for RoleHeartbeat {
    fn default() -> Self {
        Self {
            role: FixedText::new(),
            variant: FixedText::new(),
            executor: FixedText::new(),
            pid: 0,
            status: RoleStatus::Starting as u8,
            worked: 0,
            reserved: [0; 2],
            seq: 0,
            stamp_ns: 0,
            cycle_latency_ns: 0,
            stages: [StageTiming::default(); MAX_STAGES],
            counters: [0; 8],
        }
    }
}

/// Why a heartbeat is unusable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum HeartbeatError {
    /// A name is empty, not UTF-8 or its length is out of range.
    #[error("heartbeat field `{0}` is empty or corrupt")]
    BadName(&'static str),
    /// Unknown status byte.
    #[error("unknown role status {0}")]
    UnknownStatus(u8),
    /// Sequence 0 is never sent.
    #[error("heartbeat sequence 0")]
    ZeroSequence,
}

impl RoleHeartbeat {
    /// Deterministic validation.
    pub fn validate(&self) -> Result<RoleStatus, HeartbeatError> {
        if self.role.is_empty() || !self.role.is_valid() {
            return Err(HeartbeatError::BadName("role"));
        }
        if !self.variant.is_valid() {
            return Err(HeartbeatError::BadName("variant"));
        }
        if !self.executor.is_valid() {
            return Err(HeartbeatError::BadName("executor"));
        }
        if self.stages.iter().any(|s| !s.name.is_valid()) {
            return Err(HeartbeatError::BadName("stages.name"));
        }
        if self.seq == 0 {
            return Err(HeartbeatError::ZeroSequence);
        }
        RoleStatus::from_u8(self.status).ok_or(HeartbeatError::UnknownStatus(self.status))
    }

    /// Stage duration by name, if reported.
    pub fn stage_ns(&self, name: &str) -> Option<u64> {
        self.stages
            .iter()
            .find(|s| s.name.as_str() == Some(name))
            .map(|s| s.ns)
    }
}
