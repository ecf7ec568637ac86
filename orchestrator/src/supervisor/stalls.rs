//! Stall detection: a running role that is alive but silent (stopped, blocked, or silent
//! past the hard timeout) is killed, so that its restart policy applies.

use super::events::SupervisorEvent;
use super::role_runtime::{RoleRuntime, RoleState};
use crate::executors::{process_state, process_thread_times};
use crate::workflow::SchedulingSpec;
use std::time::{Duration, Instant};

/// The flight's stall thresholds.
#[derive(Debug, Clone, Copy)]
pub(super) struct StallDetector {
    /// Three idle-heartbeat periods: silence after which a stopped process is stalled.
    quick: Duration,
    /// `stall_timeout_ms`: silence after which a process making no CPU progress is stalled.
    timeout: Duration,
    /// `stall_hard_timeout_ms`: silence after which a process is stalled whatever it does.
    hard: Duration,
}

impl StallDetector {
    /// The thresholds of a flight with idle heartbeats every `idle_heartbeat_ms` and
    /// `scheduling`'s stall timeouts.
    pub(super) fn new(idle_heartbeat_ms: u64, scheduling: &SchedulingSpec) -> Self {
        StallDetector {
            quick: Duration::from_millis(3 * idle_heartbeat_ms),
            timeout: Duration::from_millis(scheduling.stall_timeout_ms),
            hard: Duration::from_millis(scheduling.stall_hard_timeout_ms),
        }
    }

    /// Kill running roles that are alive but silent: stopped (SIGSTOP, state `T`) after
    /// three idle-heartbeat periods of silence (or of life, before a first heartbeat); silent for `stall_timeout_ms` neither running
    /// nor waiting for a CPU (blocked, deadlocked: a role starved by a loaded machine waits in
    /// a run queue and is not stalled); or silent for `stall_hard_timeout_ms` whatever it does.
    /// The exit is reaped by the next step and the restart policy applies.
    pub(super) fn check(&self, roles: &mut [RoleRuntime], events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        let (quick, timeout, hard) = (self.quick, self.timeout, self.hard);
        for role in roles {
            let (Some(pid), true) = (role.pid, role.state == RoleState::Running) else {
                continue;
            };
            if !role.running {
                // before its first heartbeat only a stopped process is certainly stalled (a
                // model loading from disk can be silent, and blocked, for many seconds)
                let up = role
                    .started_at
                    .map_or(Duration::ZERO, |t| now.saturating_duration_since(t));
                if up >= quick
                    && let Some(state @ ('T' | 't')) = process_state(pid)
                {
                    if let Some(child) = role.child.as_mut() {
                        let _ = child.kill();
                    }
                    role.stalls += 1;
                    events.push(SupervisorEvent::RoleStalled {
                        name: role.name.clone(),
                        pid,
                        silent_ms: up.as_millis() as u64,
                        why: format!("stopped (state {state}) before its first heartbeat"),
                    });
                }
                continue;
            }
            // a role on another host falls silent with its link: the link watch decides
            // (its handle here uses no CPU either way)
            if role.link.is_some() {
                continue;
            }
            let Some(heard) = role.heard_at else {
                continue;
            };
            let silent = now.saturating_duration_since(heard);
            if silent < quick {
                continue;
            }
            // time on a CPU plus time runnable in a run queue: grows unless it sleeps
            let times = process_thread_times(pid);
            let probe = role
                .silence_probe
                .get_or_insert_with(|| times.clone().unwrap_or_default());
            let state = process_state(pid);
            let why = if matches!(state, Some('T' | 't')) {
                Some(format!("stopped (state {})", state.unwrap_or('T')))
            } else if silent >= timeout
                && times
                    .as_ref()
                    .is_some_and(|t| t.progress_since(probe) < 1_000_000)
            {
                Some(format!(
                    "neither running nor runnable for {} ms",
                    silent.as_millis()
                ))
            } else if silent >= hard {
                Some("still silent after the hard stall timeout".to_string())
            } else {
                None
            };
            let Some(why) = why else { continue };
            if let Some(child) = role.child.as_mut() {
                // SIGKILL ends a stopped process too; the next reap restarts it
                let _ = child.kill();
            }
            role.stalls += 1;
            role.running = false;
            events.push(SupervisorEvent::RoleStalled {
                name: role.name.clone(),
                pid,
                silent_ms: silent.as_millis() as u64,
                why,
            });
        }
    }
}
