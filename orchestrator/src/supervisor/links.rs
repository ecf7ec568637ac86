//! The links to other hosts. A role on another host is heard through its host's link: when
//! its heartbeats stop for longer than the host's `link_timeout_ms`, the link counts as
//! lost. The role's fallback variant, when the workflow names one, starts on the flight's
//! host at once, through the hot-swap path but without waiting for the silent side (it
//! becomes the role with its first heartbeat, and the hub follows its first decision);
//! without a fallback the role is lost with its host: its handle is killed and it stays
//! down (its host's bridge too), never failing the flight. The hub
//! and the controller never wait for any of this: they run on the flight's host.

use super::Supervisor;
use super::events::SupervisorEvent;
use super::role_runtime::RoleState;
use super::swap::{DEFAULT_SWAP_READY_TIMEOUT, Placement};
use crate::restart::RestartPolicy;
use std::time::Instant;

impl Supervisor {
    /// Count the links whose roles fell silent as lost, and start their fallbacks.
    pub(super) fn watch_links(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        for i in 0..self.roles.len() {
            let r = &mut self.roles[i];
            let Some(link) = r.link.as_mut() else {
                continue;
            };
            // only a role that has worked is judged: one still starting is the handle's
            // and the agent's business (they fail with the host's name)
            if link.lost || r.state != RoleState::Running || r.swap.is_some() || !r.running {
                continue;
            }
            let Some(heard) = r.heard_at else { continue };
            let silent = now.saturating_duration_since(heard);
            if silent < link.timeout {
                continue;
            }
            link.lost = true;
            let (name, host) = (r.name.clone(), link.host.clone());
            let fallback = link.fallback.clone();
            // not restarted behind a lost link: its handle may exit before the fallback is
            // ready (the fallback restores the policy when it takes over)
            let policy = core::mem::replace(&mut r.policy, RestartPolicy::Never);
            let silent_ms = silent.as_millis() as u64;
            let started = fallback.as_ref().and_then(|fb| {
                let executor = fb.executor.clone().unwrap_or_default();
                let placement = Placement {
                    cpus: fb.cpus.clone(),
                    place: flight_host_place(&executor),
                    executor,
                    remote: None,
                    link_fallback: None,
                    why: format!("fallback: the link to host `{host}` was lost"),
                    policy: Some(policy),
                };
                match self.start_swap(
                    &name,
                    &fb.variant,
                    DEFAULT_SWAP_READY_TIMEOUT,
                    false,
                    Some(placement),
                ) {
                    Ok(_) => Some(fb.variant.clone()),
                    Err(e) => {
                        events.push(SupervisorEvent::SwapFailed {
                            name: name.clone(),
                            variant: fb.variant.clone(),
                            reason: aeris_runtime::error_chain::chain(&e).to_string(),
                        });
                        None
                    }
                }
            });
            if started.is_none() {
                // no fallback: the role is lost with its host and stays down (its handle
                // is stopped); a role reachable only over the link never fails the flight
                if let Some(child) = self.roles[i].child.as_mut() {
                    let _ = child.kill();
                }
            }
            events.push(SupervisorEvent::LinkLost {
                name,
                host,
                silent_ms,
                fallback: started,
            });
        }
    }
}

/// The flight's host, and the executor there, for messages.
pub(super) fn flight_host_place(executor: &str) -> String {
    if executor.is_empty() {
        "the flight's host".to_string()
    } else {
        format!("the flight's host (executor {executor})")
    }
}
