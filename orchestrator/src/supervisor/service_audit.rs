//! The service audit: a service of the flight removed from outside (a `/dev/shm` clean-up)
//! under running roles is rebuilt by killing those roles, whose restarts create it again.

use super::events::SupervisorEvent;
use super::role_runtime::RoleRuntime;
use std::time::{Duration, Instant};

/// How often the flight's services are listed to find one removed from outside.
const SERVICE_AUDIT_PERIOD: Duration = Duration::from_millis(500);

/// What the last audit saw: the flight's services and the roles registered at each.
#[derive(Debug)]
pub(super) struct ServiceAudit {
    /// When the next audit is due.
    next: Instant,
    /// Each service (relative to the flight) with the roles, and their pids, registered at it.
    known: Vec<(String, Vec<(String, u32)>)>,
}

impl ServiceAudit {
    /// An audit due at once, that knows no service yet.
    pub(super) fn new() -> Self {
        ServiceAudit {
            next: Instant::now(),
            known: Vec::new(),
        }
    }

    /// Every [`SERVICE_AUDIT_PERIOD`]: list the flight's services and the roles registered
    /// at each. A service seen before that is gone while a role registered at it still runs
    /// the same process was removed from outside (a `/dev/shm` clean-up): the processes keep
    /// their mappings but nobody new can join it, so a later restart of any of them would
    /// talk into a fresh service nobody else is on. Kill them now; their restarts create
    /// the service again and all join it.
    pub(super) fn check(
        &mut self,
        flight: &str,
        roles: &mut [RoleRuntime],
        events: &mut Vec<SupervisorEvent>,
    ) {
        let now = Instant::now();
        if now < self.next {
            return;
        }
        self.next = now + SERVICE_AUDIT_PERIOD;
        let current = aeris_runtime::bus::flight_service_nodes(flight);
        let mut lost = Vec::new();
        for (service, attached) in &self.known {
            if current.iter().any(|(s, _)| s == service) {
                continue;
            }
            let victims: Vec<(usize, u32)> = attached
                .iter()
                .filter_map(|(name, pid)| {
                    let i = roles.iter().position(|r| &r.name == name)?;
                    let r = &roles[i];
                    (r.running && r.pid == Some(*pid)).then_some((i, *pid))
                })
                .collect();
            if !victims.is_empty() {
                lost.push((service.clone(), victims));
            }
        }
        self.known = current
            .into_iter()
            .map(|(service, nodes)| {
                let attached = nodes
                    .into_iter()
                    .filter_map(|n| {
                        let r = roles.iter().find(|r| r.name == n)?;
                        Some((n, r.pid?))
                    })
                    .collect();
                (service, attached)
            })
            .collect();
        for (service, victims) in lost {
            let mut killed = Vec::new();
            for (i, pid) in victims {
                let role = &mut roles[i];
                if !role.running {
                    continue; // already killed for another lost service
                }
                if let Some(child) = role.child.as_mut() {
                    let _ = child.kill();
                }
                role.running = false;
                killed.push((role.name.clone(), pid));
            }
            if !killed.is_empty() {
                events.push(SupervisorEvent::ServiceLost {
                    service,
                    roles: killed,
                });
            }
        }
    }
}
