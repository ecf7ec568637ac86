//! Exits and restarts: reaping exited role processes, applying each role's restart policy
//! ([`crate::restart`]: stay down, restart after a backoff, or give up), and starting the
//! restarts that are due.

use super::Supervisor;
use super::error::SupervisorError;
use super::events::SupervisorEvent;
use super::role_runtime::RoleState;
use crate::restart::{
    EXIT_HOST_UNREACHABLE, RestartDecision, RestartPolicy, RoleExit, restart_decision,
};
use std::time::Instant;

impl Supervisor {
    /// Reap every role process that exited: record how, and set the role's state from its
    /// restart policy ([`SupervisorEvent::RoleExited`], [`SupervisorEvent::RoleGaveUp`]).
    pub(super) fn reap(
        &mut self,
        events: &mut Vec<SupervisorEvent>,
    ) -> Result<(), SupervisorError> {
        let now = Instant::now();
        let mut exited = false;
        let mut unreachable = Vec::new();
        for (i, role) in self.roles.iter_mut().enumerate() {
            let Some(child) = role.child.as_mut() else {
                continue;
            };
            let status = match child.try_wait() {
                Ok(Some(status)) => status,
                Ok(None) => continue,
                Err(source) => {
                    return Err(SupervisorError::Wait {
                        role: role.name.clone(),
                        pid: child.id(),
                        source,
                    });
                }
            };
            let exit = RoleExit::from_status(status);
            if let Some(pid) = role.pid.take() {
                role.old_pids.push(pid);
            }
            role.child = None;
            role.last_exit = Some(exit);
            role.incarnation_heartbeats = 0;
            role.new_incarnation();
            exited = true;
            events.push(SupervisorEvent::RoleExited {
                name: role.name.clone(),
                status: exit,
            });
            // its handle could not reach the host: the link is lost, not the role
            if exit == RoleExit::Code(EXIT_HOST_UNREACHABLE)
                && role.link.as_ref().is_some_and(|l| !l.lost)
            {
                role.state = RoleState::Stopped;
                unreachable.push(i);
                continue;
            }
            role.state = match restart_decision(
                role.policy,
                exit,
                role.restarts,
                role.max_restarts,
                role.backoff_ms,
            ) {
                RestartDecision::Stay => RoleState::Stopped,
                RestartDecision::Restart { after } => RoleState::Backoff { until: now + after },
                RestartDecision::GiveUp => {
                    events.push(SupervisorEvent::RoleGaveUp {
                        name: role.name.clone(),
                    });
                    RoleState::GaveUp
                }
            };
        }
        if exited {
            // a dead process cannot remove its own iceoryx2 node and ports: do it now, not
            // only when its replacement starts (a role kept down has none), off the step
            self.services.clean_up_dead_nodes();
        }
        for i in unreachable {
            self.host_unreachable(i, events);
        }
        Ok(())
    }

    /// Restart the roles whose backoff is over; a spawn that fails counts against the
    /// budget and is retried after the next backoff.
    pub(super) fn restart_due(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        for i in 0..self.roles.len() {
            let RoleState::Backoff { until } = self.roles[i].state else {
                continue;
            };
            if now < until {
                continue;
            }
            self.roles[i].restarts += 1;
            let name = self.roles[i].name.clone();
            match self.spawn(i, "restart") {
                Ok(pid) => events.push(SupervisorEvent::RoleRestarted {
                    name,
                    pid,
                    restarts: self.roles[i].restarts,
                }),
                Err(e) => {
                    events.push(SupervisorEvent::RestartFailed {
                        name: name.clone(),
                        reason: aeris_runtime::error_chain::chain(&e).to_string(),
                    });
                    let role = &mut self.roles[i];
                    let exit = role.last_exit.unwrap_or(RoleExit::Code(-1));
                    role.state = match restart_decision(
                        RestartPolicy::Always,
                        exit,
                        role.restarts,
                        role.max_restarts,
                        role.backoff_ms,
                    ) {
                        RestartDecision::Restart { after } => {
                            RoleState::Backoff { until: now + after }
                        }
                        _ => {
                            events.push(SupervisorEvent::RoleGaveUp { name });
                            RoleState::GaveUp
                        }
                    };
                }
            }
        }
    }
}
