//! The supervisor's status board, read by `aeris status`.

use crate::heartbeat::NAME_MAX;
use crate::host_link::{HostLinkStatus, MAX_HOSTS};
use crate::text::FixedText;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Maximum number of roles the status board lists.
pub const MAX_ROLES: usize = 16;

/// One role's line on the status board.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct RoleStatusEntry {
    /// Role instance name.
    pub name: FixedText<NAME_MAX>,
    /// Variant.
    pub variant: FixedText<NAME_MAX>,
    /// Executor CPU list.
    pub cpus: FixedText<NAME_MAX>,
    /// Process id (0 = not running).
    pub pid: u32,
    /// Last reported [`crate::RoleStatus`] byte (0 = no heartbeat yet).
    pub status: u8,
    /// Reserved, zero.
    pub reserved: [u8; 3],
    /// CLOCK_MONOTONIC ns of the last heartbeat (0 = none).
    pub last_heartbeat_ns: u64,
    /// Heartbeats received.
    pub heartbeats: u64,
    /// Latency percentiles over the window (ms): p50, p95, p99.
    pub latency_ms: [f32; 3],
    /// Restarts so far.
    pub restarts: u32,
    /// Heartbeat sequence gaps observed.
    pub heartbeat_gaps: u32,
    /// Name of the executor the role is bound to (empty = unbound).
    pub executor: FixedText<NAME_MAX>,
    /// The role's share of the heartbeat budget (ms; 0 = none, never re-bound).
    pub budget_ms: f32,
    /// Live moves between executors so far.
    pub migrations: u32,
    /// Times the role was found alive but silent (stalled) and replaced.
    pub stalls: u32,
    /// Reserved, zero.
    pub reserved2: u32,
    /// Why the role is bound where it is (initial binding, or the move that put it there).
    pub binding: FixedText<BINDING_TEXT_MAX>,
}

/// Longest "why it is bound there" text on the board.
pub const BINDING_TEXT_MAX: usize = 96;

/// The whole board (`aeris/{flight}/supervisor`, a blackboard entry).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::SupervisorStatus@s8")]
#[repr(C)]
pub struct SupervisorStatus {
    /// Board update counter.
    pub seq: u64,
    /// CLOCK_MONOTONIC ns of the update.
    pub stamp_ns: u64,
    /// Supervisor pid.
    pub supervisor_pid: u32,
    /// Number of valid entries in `roles`.
    pub role_count: u32,
    /// Active step (1-based, 0 = unknown).
    pub active_step: u16,
    /// Number of subgoals.
    pub subgoals: u16,
    /// Live migrations of all roles so far.
    pub migrations: u32,
    /// Distance to the goal (m), negative when unknown.
    pub distance_to_goal_m: f32,
    /// Mean cycle time so far (s).
    pub ct_mean_s: f32,
    /// One line per role.
    pub roles: [RoleStatusEntry; MAX_ROLES],
    /// Number of valid entries in `links`.
    pub link_count: u32,
    /// Reserved, zero.
    pub reserved: u32,
    /// The links to the flight's other hosts, as last measured (one per host, in the
    /// workflow's order; `probes` 0 = not measured yet).
    pub links: [HostLinkStatus; MAX_HOSTS],
}

impl Default for SupervisorStatus {
    fn default() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            supervisor_pid: 0,
            role_count: 0,
            active_step: 0,
            subgoals: 0,
            migrations: 0,
            distance_to_goal_m: -1.0,
            ct_mean_s: 0.0,
            roles: [RoleStatusEntry::default(); MAX_ROLES],
            link_count: 0,
            reserved: 0,
            links: [HostLinkStatus::default(); MAX_HOSTS],
        }
    }
}

impl SupervisorStatus {
    /// The valid role entries.
    pub fn roles(&self) -> &[RoleStatusEntry] {
        &self.roles[..(self.role_count as usize).min(MAX_ROLES)]
    }

    /// The valid link entries.
    pub fn links(&self) -> &[HostLinkStatus] {
        &self.links[..(self.link_count as usize).min(MAX_HOSTS)]
    }
}
