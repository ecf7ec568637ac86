//! The links to other hosts. A role on another host is heard through its host's link: when
//! its heartbeats stop for longer than the host's `link_timeout_ms`, the link counts as
//! lost. The role's fallback variant (the workflow's `fallback`, or for a role moved there
//! by hand the role as it ran before the move) starts on the flight's host at once, through
//! the hot-swap path but without waiting for the silent side (it becomes the role with its
//! first heartbeat, and the hub follows its first decision); without a fallback the role is
//! lost with its host: its handle is killed and it stays down (its host's bridge too),
//! never failing the flight. A swap of the role under way when its link goes silent, whose
//! new side is behind the same link, is rolled back at once rather than waiting out its
//! ready timeout (90 s), and the fallback follows. The hub and the controller never wait
//! for any of this: they run on the flight's host.
//!
//! When the link returns (the host's bridge on the flight's host reports its agent
//! connected again), the host's own bridge restarts there, and once the link has held for
//! [`LINK_RETURN_HYSTERESIS`] every role that fell back returns, make-before-break, to the
//! executor and variant it ran there. A link that fades in and out never moves a role
//! twice within the hysteresis.

use super::Supervisor;
use super::events::SupervisorEvent;
use super::replacement::{Placement, ReturnTo};
use super::role_runtime::RoleState;
use super::swap::DEFAULT_SWAP_READY_TIMEOUT;
use crate::restart::RestartPolicy;
use aeris_schemas::BridgeCounters;
use std::time::{Duration, Instant};

/// How long a lost link must be back, continuously, before the roles that fell back return
/// to its host.
pub const LINK_RETURN_HYSTERESIS: Duration = Duration::from_secs(5);

/// The name of the bridge role on the flight's host for `host` (it connects to that host's
/// agent and reports whether it is connected: heartbeat counter 6).
fn bridge_here(host: &str) -> String {
    format!("bridge-to-{host}")
}

/// The name of the bridge role on `host`.
fn bridge_there(host: &str) -> String {
    format!("bridge-on-{host}")
}

/// A lost link, and what its bridge on the flight's host said since: the link is back only
/// on evidence newer than the loss. Right after a cut, the bridge's zenoh session still
/// reports the other host connected until its own lease runs out (a run over TLS counted
/// the link back 10 ms after the loss and restarted the bridge there into a cut link).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct LostLink {
    host: String,
    /// Probes its bridge had seen answered when the link was lost.
    answered_at_loss: u64,
    /// Its bridge reported the host disconnected (or was not running) since the loss.
    seen_down: bool,
}

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
            if link.lost || r.state != RoleState::Running || !r.running {
                continue;
            }
            let Some(heard) = r.heard_at else { continue };
            let silent = now.saturating_duration_since(heard);
            if silent < link.timeout {
                continue;
            }
            if let Some(swap) = r.swap.as_mut() {
                // a swap under way whose new side is behind the same link cannot finish
                // either: it ends now (rolled back), and the fallback takes over next step
                let behind_link = swap
                    .placement
                    .as_ref()
                    .is_none_or(|p| p.remote.as_ref().is_some_and(|s| s.host == link.host));
                if behind_link && swap.abort.is_none() {
                    swap.abort = Some(format!(
                        "the link to host `{}` was lost (the role silent for {} ms)",
                        link.host,
                        silent.as_millis()
                    ));
                }
                continue;
            }
            link.lost = true;
            let (name, host) = (r.name.clone(), link.host.clone());
            let fallback = link.fallback.clone();
            // not restarted behind a lost link: its handle may exit before the fallback is
            // ready (the fallback restores the policy when it takes over)
            let policy = core::mem::replace(&mut r.policy, RestartPolicy::Never);
            let returns = return_to(&self.remote_executors, r, &host);
            let silent_ms = silent.as_millis() as u64;
            let started = fallback.as_ref().and_then(|fb| {
                let executor = fb.executor.clone().unwrap_or_default();
                let accelerator = self.accelerator_of(&executor);
                let place = flight_host_place(&executor, accelerator);
                let placement = Placement {
                    cpus: fb.cpus.clone(),
                    place: place.clone(),
                    accelerator,
                    executor,
                    remote: None,
                    link_fallback: None,
                    why: format!("fallback: the link to host `{host}` was lost"),
                    policy: Some(policy),
                    returning: None,
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
                            place: Some(place),
                        });
                        None
                    }
                }
            });
            let r = &mut self.roles[i];
            if started.is_some() {
                r.returns_to = returns;
            } else {
                // no fallback: the role is lost with its host and stays down (its handle
                // is stopped) until the link returns; a role reachable only over the link
                // never fails the flight
                if let Some(link) = r.link.as_mut() {
                    link.held_policy = Some(policy);
                }
                if let Some(child) = r.child.as_mut() {
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
        self.watch_returns(now, events);
    }

    /// Role `i`'s handle could not reach its host (at the start, or at a restart): its
    /// link counts as lost. Its fallback starts in its place on the flight's host (as a
    /// start, not a swap: nothing runs to swap with), to return when the link is back;
    /// without one the role waits for the link, down, and the flight goes on without it.
    pub(super) fn host_unreachable(&mut self, i: usize, events: &mut Vec<SupervisorEvent>) {
        let r = &mut self.roles[i];
        let Some(link) = r.link.as_mut() else { return };
        link.lost = true;
        let host = link.host.clone();
        let fallback = link.fallback.clone();
        let policy = core::mem::replace(&mut r.policy, RestartPolicy::Never);
        let name = r.name.clone();
        let Some(fb) = fallback else {
            link.held_policy = Some(policy);
            events.push(SupervisorEvent::HostUnreachable {
                name,
                host,
                fallback: None,
            });
            return;
        };
        let returns = return_to(&self.remote_executors, r, &host);
        let cpus = fb.cpus.as_ref().map(|c| c.to_string()).unwrap_or_default();
        // the role's spec from now on: the fallback, on the flight's host
        if let Ok(mut spec) = aeris_runtime::RoleSpec::load(&r.spec_path) {
            spec.remote = None;
            spec.variant = fb.variant.clone();
            spec.cpus = cpus.clone();
            if let Ok(json) = serde_json::to_string_pretty(&spec) {
                let _ = std::fs::write(&r.spec_path, json);
            }
        }
        r.variant = fb.variant.clone();
        r.cpus = cpus;
        r.cpu_set = fb.cpus.clone();
        r.executor = fb.executor.clone().unwrap_or_default();
        r.binding = format!("fallback: host `{host}` unreachable");
        r.policy = policy;
        r.link = None;
        r.returns_to = returns;
        events.push(SupervisorEvent::HostUnreachable {
            name: name.clone(),
            host,
            fallback: Some(fb.variant.clone()),
        });
        match self.spawn(i, "fallback (its host unreachable): start") {
            Ok(pid) => events.push(SupervisorEvent::RoleStarted { name, pid }),
            Err(e) => events.push(SupervisorEvent::RestartFailed {
                name,
                reason: aeris_runtime::error_chain::chain(&e).to_string(),
            }),
        }
    }

    /// Whether the lost link to `host` is back: its bridge on the flight's host runs and
    /// reports the host's agent connected, and that is news since the loss (the bridge
    /// saw the host go, or a probe was answered since).
    fn link_back(&self, host: &str) -> bool {
        let Some(lost) = self.links_lost.iter().find(|l| l.host == host) else {
            return self.link_connected(host);
        };
        let answered = self.host_links.get(host).map_or(0, |l| l.answered);
        self.link_connected(host) && (lost.seen_down || answered > lost.answered_at_loss)
    }

    /// Whether the bridge on the flight's host for `host` runs and reports that host's
    /// agent connected.
    fn link_connected(&self, host: &str) -> bool {
        let name = bridge_here(host);
        self.roles.iter().any(|r| {
            r.name == name
                && r.state == RoleState::Running
                && r.last_heartbeat
                    .is_some_and(|hb| BridgeCounters::from_heartbeat(&hb.counters).connected == 1)
        })
    }

    /// Bring back what a lost link took: the host's bridge there as soon as the link is
    /// back, then, after [`LINK_RETURN_HYSTERESIS`], the roles that fell back.
    fn watch_returns(&mut self, now: Instant, events: &mut Vec<SupervisorEvent>) {
        let mut hosts: Vec<String> = Vec::new();
        for r in &self.roles {
            let waiting = r
                .returns_to
                .as_ref()
                .map(|t| t.spec.host.clone())
                .or_else(|| {
                    r.link
                        .as_ref()
                        .filter(|l| l.lost && l.held_policy.is_some())
                        .map(|l| l.host.clone())
                });
            if let Some(h) = waiting
                && !hosts.contains(&h)
            {
                hosts.push(h);
            }
        }
        self.links_up_since.retain(|(h, _)| hosts.contains(h));
        self.links_lost.retain(|l| hosts.contains(&l.host));
        for host in &hosts {
            let connected = self.link_connected(host);
            match self.links_lost.iter_mut().find(|l| &l.host == host) {
                Some(l) => l.seen_down |= !connected,
                None => {
                    let answered = self.host_links.get(host).map_or(0, |l| l.answered);
                    self.links_lost.push(LostLink {
                        host: host.clone(),
                        answered_at_loss: answered,
                        seen_down: !connected,
                    });
                }
            }
        }
        for host in hosts {
            if !self.link_back(&host) {
                self.links_up_since.retain(|(h, _)| *h != host);
                continue;
            }
            let since = match self.links_up_since.iter().find(|(h, _)| *h == host) {
                Some((_, t)) => *t,
                None => {
                    self.links_up_since.push((host.clone(), now));
                    now
                }
            };
            // roles lost with the host (its bridge there first) start again at once
            self.restart_lost_with(&host, events);
            let there = bridge_there(&host);
            let bridge_ready = self
                .roles
                .iter()
                .find(|r| r.name == there)
                .is_none_or(|r| r.state == RoleState::Running && r.running);
            if !bridge_ready || now.saturating_duration_since(since) < LINK_RETURN_HYSTERESIS {
                continue;
            }
            self.return_roles(&host, now.saturating_duration_since(since), events);
        }
    }

    /// Start again the roles that stayed down with `host`'s link (no fallback: its bridge).
    fn restart_lost_with(&mut self, host: &str, events: &mut Vec<SupervisorEvent>) {
        for i in 0..self.roles.len() {
            let r = &mut self.roles[i];
            let Some(link) = r.link.as_mut() else {
                continue;
            };
            if link.host != host || !link.lost || r.child.is_some() {
                continue;
            }
            let Some(policy) = link.held_policy.take() else {
                continue;
            };
            link.lost = false;
            r.policy = policy;
            r.heard_at = None;
            let name = r.name.clone();
            match self.spawn(i, "link back: restart") {
                Ok(pid) => events.push(SupervisorEvent::LinkBack {
                    host: host.to_string(),
                    name,
                    pid: Some(pid),
                    variant: None,
                }),
                Err(e) => events.push(SupervisorEvent::RestartFailed {
                    name,
                    reason: aeris_runtime::error_chain::chain(&e).to_string(),
                }),
            }
        }
    }

    /// Move every role that fell back from `host` back there, make-before-break.
    fn return_roles(&mut self, host: &str, up: Duration, events: &mut Vec<SupervisorEvent>) {
        for i in 0..self.roles.len() {
            let r = &self.roles[i];
            let Some(to) = r.returns_to.clone().filter(|t| t.spec.host == host) else {
                continue;
            };
            if r.state != RoleState::Running || r.swap.is_some() {
                continue;
            }
            self.roles[i].returns_to = None;
            let name = self.roles[i].name.clone();
            let returning = to.clone();
            let started = self
                .remote_placement(i, to.executor, to.spec)
                .map_err(|e| aeris_runtime::error_chain::chain(&e).to_string())
                .and_then(|mut placement| {
                    placement.why = format!(
                        "back on host `{host}`: its link held for {} ms",
                        up.as_millis()
                    );
                    placement.returning = Some(returning);
                    self.start_swap(
                        &name,
                        &to.variant,
                        DEFAULT_SWAP_READY_TIMEOUT,
                        false,
                        Some(placement),
                    )
                    .map_err(|e| aeris_runtime::error_chain::chain(&e).to_string())
                });
            match started {
                Ok(pid) => events.push(SupervisorEvent::LinkBack {
                    host: host.to_string(),
                    name,
                    pid: Some(pid),
                    variant: Some(to.variant),
                }),
                Err(reason) => events.push(SupervisorEvent::SwapFailed {
                    name,
                    variant: to.variant,
                    reason,
                    place: Some(format!("host `{host}`")),
                }),
            }
        }
    }
}

/// Where role `r`, running on `host`, returns when that host's lost link is back: its
/// executor there and its variant.
fn return_to(
    remote_executors: &[(String, aeris_runtime::spec::RemoteSpec)],
    r: &super::role_runtime::RoleRuntime,
    host: &str,
) -> Option<ReturnTo> {
    remote_executors
        .iter()
        .find(|(ex, spec)| *ex == r.executor && spec.host == host)
        .map(|(ex, spec)| ReturnTo {
            executor: ex.clone(),
            spec: spec.clone(),
            variant: r.variant.clone(),
        })
}

/// The flight's host, and the executor there with its accelerator, for messages.
pub(super) fn flight_host_place(
    executor: &str,
    accelerator: Option<aeris_runtime::accelerator::Accelerator>,
) -> String {
    match (executor.is_empty(), accelerator) {
        (true, _) => "the flight's host".to_string(),
        (false, None) => format!("the flight's host (executor {executor})"),
        (false, Some(a)) => format!("the flight's host (executor {executor}, {a})"),
    }
}
