//! The heartbeat intake: every role's heartbeats, validated and routed to the role's running
//! process (its statistics), to the new side of its swap (readiness), or dropped as late.

use super::events::SupervisorEvent;
use super::role_runtime::RoleRuntime;
use aeris_runtime::bus::{BusError, TypedSubscriber};
use aeris_schemas::{RoleHeartbeat, RoleStatus};

/// The supervisor's subscription to `heartbeat`, with the count of what it could not use.
pub(super) struct HeartbeatIntake {
    /// The `heartbeat` subscriber.
    subscriber: TypedSubscriber<RoleHeartbeat>,
    /// Heartbeats that failed validation.
    invalid: u64,
    /// Valid heartbeats from a role name that is not in this flight.
    unknown: u64,
}

impl HeartbeatIntake {
    /// Take heartbeats from `subscriber`.
    pub(super) fn new(subscriber: TypedSubscriber<RoleHeartbeat>) -> Self {
        HeartbeatIntake {
            subscriber,
            invalid: 0,
            unknown: 0,
        }
    }

    /// Heartbeats that failed validation.
    pub(super) fn invalid(&self) -> u64 {
        self.invalid
    }

    /// Valid heartbeats from a role name that is not in this flight.
    pub(super) fn unknown(&self) -> u64 {
        self.unknown
    }

    /// Take every waiting heartbeat: a working one from the new side of a swap makes it
    /// ready, one from a process that already exited is dropped, the others feed their
    /// role's statistics ([`SupervisorEvent::FirstHeartbeat`] for a process's first).
    pub(super) fn drain(
        &mut self,
        roles: &mut [RoleRuntime],
        events: &mut Vec<SupervisorEvent>,
    ) -> Result<(), BusError> {
        loop {
            let Some(hb) = self.subscriber.next()? else {
                return Ok(());
            };
            let Ok(status) = hb.validate() else {
                self.invalid += 1;
                continue;
            };
            let name = hb.role.as_str().unwrap_or("");
            let Some(role) = roles.iter_mut().find(|r| r.name == name) else {
                self.unknown += 1;
                continue;
            };
            if let Some(swap) = role.swap.as_mut()
                && swap.pid == hb.pid
            {
                // the new side of a swap is ready with its first heartbeat after loading
                // and warming up (`Starting` is sent before the role is built)
                if matches!(status, RoleStatus::Running | RoleStatus::Degraded)
                    && swap.ready.is_none()
                {
                    swap.ready = Some((hb, std::time::Instant::now()));
                }
                continue;
            }
            // the replaced process completed a cycle after the new one was ready: hand over
            if let Some(swap) = role.swap.as_mut()
                && role.pid == Some(hb.pid)
                && hb.worked == 1
                && swap.ready.is_some_and(|(r, _)| hb.stamp_ns > r.stamp_ns)
            {
                swap.handover = true;
            }
            if role.old_pids.contains(&hb.pid) {
                continue; // late heartbeat of a process that already exited
            }
            // a process that turns degraded, or back: an event each way
            let was_degraded = role
                .last_heartbeat
                .filter(|l| l.pid == hb.pid)
                .is_some_and(|l| l.status == RoleStatus::Degraded as u8);
            match status {
                RoleStatus::Degraded if !was_degraded => {
                    events.push(SupervisorEvent::RoleDegraded {
                        name: role.name.clone(),
                    });
                }
                RoleStatus::Running if was_degraded => {
                    events.push(SupervisorEvent::RoleRecovered {
                        name: role.name.clone(),
                    });
                }
                _ => {}
            }
            if role.record(&hb, status) {
                events.push(SupervisorEvent::FirstHeartbeat {
                    name: role.name.clone(),
                });
            }
        }
    }
}
