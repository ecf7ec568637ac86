//! Stall detection: a running role that is alive but silent (stopped, blocked, or silent
//! past the hard timeout) is killed, so that its restart policy applies. Silence counts
//! only while the supervisor watches: a pause of the supervisor itself (a virtual machine
//! descheduled, a machine starved) is discounted from every role's silence ([`WatchClock`]),
//! so a pause of the whole machine does not read as a stall or a lost link.

use super::cpu_watch::{CpuWatch, UNWATCHED_GAP};
use super::events::SupervisorEvent;
use super::role_runtime::{RoleRuntime, RoleState};
use crate::executors::{process_state, process_thread_times};
use crate::workflow::SchedulingSpec;
use std::time::{Duration, Instant};

/// When the supervisor last stepped, and whether every CPU ran since ([`CpuWatch`]).
#[derive(Debug, Default)]
pub(super) struct WatchClock {
    last_step: Option<Instant>,
    cpus: Option<CpuWatch>,
}

impl WatchClock {
    /// A clock that also watches every CPU the supervisor may run on.
    pub(super) fn watching_cpus() -> Self {
        WatchClock {
            last_step: None,
            cpus: Some(CpuWatch::start()),
        }
    }

    /// Call at the start of every step: after a pause of the supervisor longer than
    /// [`UNWATCHED_GAP`], or of one CPU, every role's last heartbeat moves forward by the
    /// pause (its silence is what the supervisor saw), its CPU probe starts again, and
    /// [`SupervisorEvent::Unwatched`] says so. In a pause of the whole machine the roles made
    /// no progress either, and the heartbeats they send as it ends may not have arrived yet;
    /// in a pause of one CPU the roles waiting to wake on it did not run. Returns whether the
    /// roles' silence may be judged in this step: not while a CPU is paused now (for at most
    /// `hold_at_most`, after which silence is judged whatever the CPUs do).
    pub(super) fn discount(
        &mut self,
        roles: &mut [RoleRuntime],
        events: &mut Vec<SupervisorEvent>,
        hold_at_most: Duration,
    ) -> bool {
        let now = Instant::now();
        let own = self
            .last_step
            .replace(now)
            .map(|last| now.saturating_duration_since(last))
            .filter(|gap| *gap > UNWATCHED_GAP)
            .map(|gap| (gap, None));
        let cpu = self
            .cpus
            .as_ref()
            .and_then(CpuWatch::take_pause)
            .map(|p| (p.gap, Some(p.cpu)));
        // the longer of the two: a pause of the supervisor's own CPU shows in both
        let pause = match (own, cpu) {
            (Some(a), Some(b)) => Some(if b.0 > a.0 { b } else { a }),
            (a, b) => a.or(b),
        };
        if let Some((gap, cpu)) = pause {
            for role in roles {
                if let Some(heard) = role.heard_at.as_mut() {
                    *heard = (*heard + gap).min(now);
                }
                role.silence_probe = None;
            }
            events.push(SupervisorEvent::Unwatched {
                gap_ms: gap.as_millis() as u64,
                cpu,
            });
        }
        self.cpus
            .as_ref()
            .and_then(CpuWatch::frozen_now)
            .is_none_or(|p| p.gap > hold_at_most)
    }
}

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

    /// `stall_hard_timeout_ms`.
    pub(super) fn hard(&self) -> Duration {
        self.hard
    }

    /// Kill running roles that are alive but silent: stopped (SIGSTOP, state `T`) after
    /// three idle-heartbeat periods of silence (or of life, before a first heartbeat); silent for `stall_timeout_ms` neither running
    /// nor waiting for a CPU (blocked, deadlocked: a role starved by a loaded machine waits in
    /// a run queue and is not stalled, nor is one waiting for the disk, state `D`); or silent for `stall_hard_timeout_ms` whatever it does.
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
                // waiting in the kernel for the disk or a page (state D) is the machine's
                // slowness, not a deadlock of the role: the hard timeout decides
                && state != Some('D')
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::supervisor::role_runtime::tests::runtime;

    const HOLD: Duration = Duration::from_secs(60);

    #[test]
    fn a_pause_of_the_supervisor_is_not_the_roles_silence() {
        let now = Instant::now();
        let mut roles = [runtime(), runtime()];
        roles[0].heard_at = Some(now - Duration::from_millis(2_500));
        roles[1].heard_at = None;
        let mut events = Vec::new();
        // the last step 2 s ago: 2 s were not watched
        let mut clock = WatchClock {
            last_step: Some(now - Duration::from_secs(2)),
            cpus: None,
        };
        assert!(clock.discount(&mut roles, &mut events, HOLD));
        let heard = roles[0].heard_at.unwrap();
        let silent = heard.elapsed();
        assert!(
            silent >= Duration::from_millis(500) && silent < Duration::from_millis(1_500),
            "{silent:?}"
        );
        assert_eq!(roles[1].heard_at, None);
        assert!(
            matches!(events[..], [SupervisorEvent::Unwatched { gap_ms, cpu: None }] if gap_ms >= 2_000),
            "{events:?}"
        );
        // the next step follows at once: nothing more is discounted
        events.clear();
        assert!(clock.discount(&mut roles, &mut events, HOLD));
        assert_eq!(roles[0].heard_at, Some(heard));
        assert!(events.is_empty(), "{events:?}");
    }

    #[test]
    fn a_heartbeat_is_never_moved_past_now() {
        let now = Instant::now();
        let mut roles = [runtime()];
        roles[0].heard_at = Some(now - Duration::from_millis(100));
        let mut clock = WatchClock {
            last_step: Some(now - Duration::from_secs(5)),
            cpus: None,
        };
        clock.discount(&mut roles, &mut Vec::new(), HOLD);
        assert!(roles[0].heard_at.unwrap() <= Instant::now());
    }

    #[test]
    fn a_pause_of_one_cpu_is_not_the_roles_silence_and_one_under_way_holds_judgement() {
        let now = Instant::now();
        let mut roles = [runtime()];
        roles[0].heard_at = Some(now - Duration::from_millis(1_200));
        let mut events = Vec::new();
        // CPU 1 did not run for 900 ms, and has run since; the supervisor stepped on time
        let mut clock = WatchClock {
            last_step: Some(now),
            cpus: Some(CpuWatch::stub(
                1,
                Duration::ZERO,
                Duration::from_millis(900),
            )),
        };
        assert!(clock.discount(&mut roles, &mut events, HOLD));
        let silent = roles[0].heard_at.unwrap().elapsed();
        assert!(silent < Duration::from_millis(400), "{silent:?}");
        assert!(
            matches!(
                events[..],
                [SupervisorEvent::Unwatched {
                    gap_ms: 900,
                    cpu: Some(1)
                }]
            ),
            "{events:?}"
        );
        // CPU 1 has not run for 700 ms now: nobody's silence is judged in this step ...
        let mut clock = WatchClock {
            last_step: Some(Instant::now()),
            cpus: Some(CpuWatch::stub(
                1,
                Duration::from_millis(700),
                Duration::ZERO,
            )),
        };
        assert!(!clock.discount(&mut roles, &mut Vec::new(), HOLD));
        // ... unless it has been paused longer than the hold allows
        assert!(clock.discount(&mut roles, &mut Vec::new(), Duration::from_millis(500)));
    }
}
