//! The status board: the `supervisor` blackboard (`SupervisorStatus`) that `aeris status`
//! reads, rewritten every step with each role's process, heartbeats, latency and binding,
//! and the mission progress the caller reports.

use super::role_runtime::RoleRuntime;
use aeris_runtime::bus::StatusBoardWriter;
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::{
    FixedText, HostLinkStatus, MAX_HOSTS, MAX_ROLES, RoleStatusEntry, SupervisorStatus,
};
use std::io::Write as _;

/// The flight's status board and the last status written to it.
pub(super) struct StatusBoard {
    /// The `supervisor` blackboard.
    writer: StatusBoardWriter,
    /// The last status written.
    status: SupervisorStatus,
}

impl StatusBoard {
    /// A board of this supervisor's process for a mission of `subgoals` steps.
    pub(super) fn new(writer: StatusBoardWriter, subgoals: usize) -> Self {
        StatusBoard {
            writer,
            status: SupervisorStatus {
                supervisor_pid: std::process::id(),
                subgoals: subgoals.min(u16::MAX as usize) as u16,
                ..SupervisorStatus::default()
            },
        }
    }

    /// The last status written.
    pub(super) fn status(&self) -> &SupervisorStatus {
        &self.status
    }

    /// Write the status of `roles`, the flight's `migrations` so far and its `links` to
    /// other hosts.
    pub(super) fn publish(
        &mut self,
        roles: &[RoleRuntime],
        migrations: u32,
        links: &[HostLinkStatus],
    ) {
        let s = &mut self.status;
        s.seq += 1;
        s.stamp_ns = monotonic_ns();
        s.role_count = roles.len().min(MAX_ROLES) as u32;
        for (entry, role) in s.roles.iter_mut().zip(roles.iter()) {
            let hb = role.last_heartbeat.as_ref();
            // a role on another host shows it: `HOST:EXECUTOR` (no allocation per publish)
            let mut place = [0u8; 96];
            let executor = match &role.link {
                Some(link) => {
                    let mut out = std::io::Cursor::new(&mut place[..]);
                    let _ = if role.executor.is_empty() {
                        write!(out, "{}", link.host)
                    } else {
                        write!(out, "{}:{}", link.host, role.executor)
                    };
                    let n = out.position() as usize;
                    core::str::from_utf8(&place[..n]).unwrap_or(&role.executor)
                }
                None => role.executor.as_str(),
            };
            let lat = role.latency_ms.unwrap_or([0.0; 3]);
            *entry = RoleStatusEntry {
                name: FixedText::from_str_truncated(&role.name),
                variant: FixedText::from_str_truncated(&role.variant),
                cpus: FixedText::from_str_truncated(&role.cpus),
                pid: role.pid.unwrap_or(0),
                status: hb.map(|h| h.status).unwrap_or(0),
                reserved: [0; 3],
                last_heartbeat_ns: hb.map(|h| h.stamp_ns).unwrap_or(0),
                heartbeats: role.heartbeats,
                latency_ms: [lat[0] as f32, lat[1] as f32, lat[2] as f32],
                restarts: role.restarts,
                heartbeat_gaps: role.heartbeat_gaps.min(u32::MAX as u64) as u32,
                executor: FixedText::from_str_truncated(executor),
                budget_ms: role.budget_ms.unwrap_or(0.0) as f32,
                migrations: role.migrations,
                stalls: role.stalls,
                reserved2: 0,
                binding: FixedText::from_str_truncated(&role.binding),
            };
        }
        s.migrations = migrations;
        s.link_count = links.len().min(MAX_HOSTS) as u32;
        for (entry, link) in s.links.iter_mut().zip(links) {
            *entry = *link;
        }
        self.writer.update(&self.status);
    }

    /// Copy mission progress into the status (written with the next [`StatusBoard::publish`]).
    pub(super) fn set_progress(
        &mut self,
        active_step: u16,
        subgoals: u16,
        distance_to_goal_m: f32,
        ct_mean_s: f32,
    ) {
        self.status.active_step = active_step;
        self.status.subgoals = subgoals;
        self.status.distance_to_goal_m = distance_to_goal_m;
        self.status.ct_mean_s = ct_mean_s;
    }
}
