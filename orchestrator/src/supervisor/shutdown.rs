//! Shutdown: stopping every role in order (reasoning first, controller and vehicle last),
//! SIGKILL for those still running after the grace period, and the report of how each ended.

use super::Supervisor;
use super::role_runtime::RoleState;
use crate::restart::RoleExit;
use aeris_schemas::RoleKind;
use std::time::{Duration, Instant};

/// Pause between checks for exited roles during [`Supervisor::shutdown`].
const SHUTDOWN_POLL: Duration = Duration::from_millis(5);

/// How one role ended at shutdown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShutdownOutcome {
    /// It exited within the grace period after SIGTERM.
    Exited(RoleExit),
    /// It was still running after the grace period and got SIGKILL.
    Killed,
    /// No process was running.
    NotRunning,
}

/// One line of a [`ShutdownReport`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ShutdownEntry {
    /// Role name.
    pub name: String,
    /// How it ended.
    pub outcome: ShutdownOutcome,
}

/// Who exited cleanly at shutdown and who had to be killed, in signalling order.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ShutdownReport {
    /// One entry per role.
    pub roles: Vec<ShutdownEntry>,
}

impl ShutdownReport {
    /// Roles that exited with code 0.
    pub fn clean(&self) -> Vec<&str> {
        self.filter(|o| o == ShutdownOutcome::Exited(RoleExit::Code(0)))
    }
    /// Roles that needed SIGKILL.
    pub fn killed(&self) -> Vec<&str> {
        self.filter(|o| o == ShutdownOutcome::Killed)
    }
    /// `true` when every running role exited with code 0.
    pub fn all_clean(&self) -> bool {
        self.roles.iter().all(|e| {
            matches!(
                e.outcome,
                ShutdownOutcome::Exited(RoleExit::Code(0)) | ShutdownOutcome::NotRunning
            )
        })
    }
    fn filter(&self, f: impl Fn(ShutdownOutcome) -> bool) -> Vec<&str> {
        self.roles
            .iter()
            .filter(|e| f(e.outcome))
            .map(|e| e.name.as_str())
            .collect()
    }
}

impl core::fmt::Display for ShutdownOutcome {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ShutdownOutcome::Exited(RoleExit::Code(0)) => write!(f, "exited cleanly"),
            ShutdownOutcome::Exited(e) => write!(f, "exited ({e})"),
            ShutdownOutcome::Killed => write!(f, "killed after the grace period"),
            ShutdownOutcome::NotRunning => write!(f, "not running"),
        }
    }
}

impl core::fmt::Display for ShutdownReport {
    /// One `name: outcome` item per role, comma-separated, in signalling order.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        for (i, e) in self.roles.iter().enumerate() {
            if i > 0 {
                write!(f, ", ")?;
            }
            write!(f, "{}: {}", e.name, e.outcome)?;
        }
        Ok(())
    }
}

/// Order in which shutdown stops kinds: reasoning first, controller, vehicle and recorder
/// last.
fn shutdown_rank(kind: RoleKind) -> u8 {
    match kind {
        RoleKind::Reasoning => 0,
        RoleKind::Perception | RoleKind::Camera => 1,
        RoleKind::TextReader
        | RoleKind::Detector
        | RoleKind::Cues
        | RoleKind::Occupancy
        | RoleKind::ImageToText
        | RoleKind::Hub
        | RoleKind::Bridge
        | RoleKind::Replay
        | RoleKind::Formation => 2,
        RoleKind::Controller => 3,
        RoleKind::Vehicle => 4,
        // last: it records the flight down to its end
        RoleKind::Recorder => 5,
    }
}

impl Supervisor {
    /// Stop every role: SIGTERM in order (reasoning first; controller and vehicle only once
    /// the others exited or half of `grace` passed), wait up to `grace` in all, SIGKILL the
    /// stragglers and reap everything.
    pub fn shutdown(mut self, grace: Duration) -> ShutdownReport {
        let start = Instant::now();
        self.stop_swaps();
        let mut order: Vec<usize> = (0..self.roles.len()).collect();
        order.sort_by_key(|&i| shutdown_rank(self.roles[i].kind));
        let mut outcomes: Vec<Option<ShutdownOutcome>> = vec![None; self.roles.len()];
        for &i in &order {
            let role = &mut self.roles[i];
            if role.child.is_none() {
                outcomes[i] = Some(ShutdownOutcome::NotRunning);
            }
            role.state = RoleState::Stopped;
        }
        // phase 1: everything but the control roles; phase 2: controller, vehicle
        let phases = [(0u8..3, grace / 2), (3u8..u8::MAX, grace)];
        for (ranks, until) in phases {
            let in_phase = |rank: u8| ranks.contains(&rank);
            for &i in &order {
                let role = &self.roles[i];
                if in_phase(shutdown_rank(role.kind))
                    && let Some(child) = &role.child
                    && let Ok(pid) = libc::pid_t::try_from(child.id())
                {
                    // SAFETY: kill has no memory-safety preconditions; the pid is our
                    // unreaped child, so it cannot have been reused.
                    unsafe { libc::kill(pid, libc::SIGTERM) };
                }
            }
            loop {
                self.collect_exits(&mut outcomes);
                let waiting = order
                    .iter()
                    .any(|&i| outcomes[i].is_none() && in_phase(shutdown_rank(self.roles[i].kind)));
                if !waiting || start.elapsed() >= until {
                    break;
                }
                std::thread::sleep(SHUTDOWN_POLL);
            }
        }
        for (i, role) in self.roles.iter_mut().enumerate() {
            if let Some(mut child) = role.child.take() {
                let _ = child.kill();
                let _ = child.wait();
                outcomes[i] = Some(ShutdownOutcome::Killed);
                if let Some(pid) = role.pid.take() {
                    role.old_pids.push(pid);
                }
            }
        }
        // drain what the roles said while stopping, then show everyone down
        let mut ignored = Vec::new();
        let _ = self.heartbeats.drain(&mut self.roles, &mut ignored);
        self.publish_board();
        ShutdownReport {
            roles: order
                .iter()
                .map(|&i| ShutdownEntry {
                    name: self.roles[i].name.clone(),
                    outcome: outcomes[i].unwrap_or(ShutdownOutcome::NotRunning),
                })
                .collect(),
        }
    }

    fn collect_exits(&mut self, outcomes: &mut [Option<ShutdownOutcome>]) {
        for (i, role) in self.roles.iter_mut().enumerate() {
            let Some(child) = role.child.as_mut() else {
                continue;
            };
            if let Ok(Some(status)) = child.try_wait() {
                let exit = RoleExit::from_status(status);
                role.last_exit = Some(exit);
                role.child = None;
                if let Some(pid) = role.pid.take() {
                    role.old_pids.push(pid);
                }
                outcomes[i] = Some(ShutdownOutcome::Exited(exit));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shutdown_reports_print_one_item_per_role() {
        let report = ShutdownReport {
            roles: vec![
                ShutdownEntry {
                    name: "reasoning".into(),
                    outcome: ShutdownOutcome::Exited(RoleExit::Code(0)),
                },
                ShutdownEntry {
                    name: "vehicle".into(),
                    outcome: ShutdownOutcome::Killed,
                },
            ],
        };
        assert_eq!(
            report.to_string(),
            "reasoning: exited cleanly, vehicle: killed after the grace period"
        );
        assert_eq!(report.clean(), ["reasoning"]);
        assert_eq!(report.killed(), ["vehicle"]);
        assert!(!report.all_clean());
    }

    #[test]
    fn shutdown_ranks_put_reasoning_first_and_vehicle_last() {
        let mut kinds = [
            RoleKind::Vehicle,
            RoleKind::Controller,
            RoleKind::Hub,
            RoleKind::Camera,
            RoleKind::Reasoning,
            RoleKind::Perception,
        ];
        kinds.sort_by_key(|k| shutdown_rank(*k));
        assert_eq!(kinds[0], RoleKind::Reasoning);
        assert_eq!(kinds[4], RoleKind::Controller);
        assert_eq!(kinds[5], RoleKind::Vehicle);
    }
}
