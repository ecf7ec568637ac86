//! The restart policy of a role: a pure decision, so it can be tested without processes.

use core::time::Duration;

/// Longest wait between two restarts of one role.
pub const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// When the supervisor restarts a role whose process exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RestartPolicy {
    /// Never restart; the role stays down.
    Never,
    /// Restart after a non-zero exit code or a death by signal (the default).
    #[default]
    OnFailure,
    /// Restart after any exit, clean or not.
    Always,
}

impl RestartPolicy {
    /// Parse the workflow spelling: `never`, `on-failure` or `always`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "never" => Some(RestartPolicy::Never),
            "on-failure" => Some(RestartPolicy::OnFailure),
            "always" => Some(RestartPolicy::Always),
            _ => None,
        }
    }

    /// The workflow spelling.
    pub fn name(self) -> &'static str {
        match self {
            RestartPolicy::Never => "never",
            RestartPolicy::OnFailure => "on-failure",
            RestartPolicy::Always => "always",
        }
    }
}

/// How a role process ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoleExit {
    /// It exited with this code.
    Code(i32),
    /// A signal killed it.
    Signal(i32),
}

impl RoleExit {
    /// From the status `wait` returned.
    pub fn from_status(status: std::process::ExitStatus) -> Self {
        use std::os::unix::process::ExitStatusExt;
        match (status.code(), status.signal()) {
            (Some(code), _) => RoleExit::Code(code),
            (None, Some(sig)) => RoleExit::Signal(sig),
            // Neither (stopped/continued cannot reach us from try_wait): report as failure.
            (None, None) => RoleExit::Code(-1),
        }
    }

    /// `true` for exit code 0.
    pub fn is_success(self) -> bool {
        self == RoleExit::Code(0)
    }
}

impl core::fmt::Display for RoleExit {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RoleExit::Code(c) => write!(f, "exit code {c}"),
            RoleExit::Signal(s) => {
                let name = match *s {
                    libc::SIGKILL => " (SIGKILL)",
                    libc::SIGTERM => " (SIGTERM)",
                    libc::SIGSEGV => " (SIGSEGV)",
                    libc::SIGABRT => " (SIGABRT)",
                    libc::SIGINT => " (SIGINT)",
                    libc::SIGBUS => " (SIGBUS)",
                    _ => "",
                };
                write!(f, "signal {s}{name}")
            }
        }
    }
}

/// Exit code of `aeris role` when it refuses to join a flight of another schema: final,
/// never restarted.
pub const EXIT_SCHEMA_MISMATCH: i32 = 3;

/// Exit code of a remote role's handle that could not reach its host's agent, or lost it
/// while the role ran: the supervisor counts that host's link as lost (the role's fallback
/// starts, or it waits for the link), whichever of the two noticed the silence first.
pub const EXIT_HOST_UNREACHABLE: i32 = 4;

/// What to do about a role that exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RestartDecision {
    /// The policy does not restart after this exit: the role stays down, no failure.
    Stay,
    /// Restart after waiting this long.
    Restart {
        /// Backoff before the new process starts.
        after: Duration,
    },
    /// The policy wanted a restart but the budget is spent: the role stays down.
    GiveUp,
}

/// Backoff before restart number `restarts_so_far + 1`: `backoff_ms * 2^restarts_so_far`,
/// capped at [`MAX_BACKOFF`].
pub fn backoff(backoff_ms: u64, restarts_so_far: u32) -> Duration {
    let cap = MAX_BACKOFF.as_millis() as u64;
    let factor = 1u64
        .checked_shl(restarts_so_far.min(63))
        .unwrap_or(u64::MAX);
    Duration::from_millis(backoff_ms.saturating_mul(factor).min(cap))
}

/// The restart decision for a role that exited with `exit`, having been restarted
/// `restarts_so_far` times already, with a budget of `max_restarts` restarts.
pub fn restart_decision(
    policy: RestartPolicy,
    exit: RoleExit,
    restarts_so_far: u32,
    max_restarts: u32,
    backoff_ms: u64,
) -> RestartDecision {
    let wants = match policy {
        RestartPolicy::Never => false,
        RestartPolicy::OnFailure => !exit.is_success(),
        RestartPolicy::Always => true,
    };
    if !wants {
        RestartDecision::Stay
    } else if exit == RoleExit::Code(EXIT_SCHEMA_MISMATCH) || restarts_so_far >= max_restarts {
        // a role that refused the flight's schema would refuse it again: restarting only
        // burns the budget
        RestartDecision::GiveUp
    } else {
        RestartDecision::Restart {
            after: backoff(backoff_ms, restarts_so_far),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FAIL: RoleExit = RoleExit::Code(1);
    const KILLED: RoleExit = RoleExit::Signal(libc::SIGKILL);
    const CLEAN: RoleExit = RoleExit::Code(0);

    #[test]
    fn never_keeps_every_role_down() {
        for exit in [FAIL, KILLED, CLEAN] {
            assert_eq!(
                restart_decision(RestartPolicy::Never, exit, 0, 5, 100),
                RestartDecision::Stay
            );
        }
    }

    #[test]
    fn on_failure_restarts_failures_and_signals_only() {
        let first = RestartDecision::Restart {
            after: Duration::from_millis(100),
        };
        assert_eq!(
            restart_decision(RestartPolicy::OnFailure, FAIL, 0, 5, 100),
            first
        );
        assert_eq!(
            restart_decision(RestartPolicy::OnFailure, KILLED, 0, 5, 100),
            first
        );
        assert_eq!(
            restart_decision(RestartPolicy::OnFailure, CLEAN, 0, 5, 100),
            RestartDecision::Stay
        );
    }

    #[test]
    fn always_restarts_clean_exits_too() {
        assert_eq!(
            restart_decision(RestartPolicy::Always, CLEAN, 2, 5, 100),
            RestartDecision::Restart {
                after: Duration::from_millis(400)
            }
        );
    }

    #[test]
    fn backoff_doubles_and_caps_at_five_seconds() {
        let ms: Vec<u128> = (0..8).map(|n| backoff(100, n).as_millis()).collect();
        assert_eq!(ms, [100, 200, 400, 800, 1600, 3200, 5000, 5000]);
        assert_eq!(backoff(100, 200), MAX_BACKOFF);
        assert_eq!(backoff(u64::MAX, 3), MAX_BACKOFF);
        assert_eq!(backoff(0, 3), Duration::ZERO);
        assert_eq!(backoff(7000, 0), MAX_BACKOFF);
    }

    #[test]
    fn the_budget_ends_restarts() {
        assert!(matches!(
            restart_decision(RestartPolicy::OnFailure, FAIL, 4, 5, 10),
            RestartDecision::Restart { .. }
        ));
        assert_eq!(
            restart_decision(RestartPolicy::OnFailure, FAIL, 5, 5, 10),
            RestartDecision::GiveUp
        );
        assert_eq!(
            restart_decision(RestartPolicy::Always, CLEAN, 0, 0, 10),
            RestartDecision::GiveUp
        );
        // A clean exit under on-failure is not a failure even with the budget spent.
        assert_eq!(
            restart_decision(RestartPolicy::OnFailure, CLEAN, 5, 5, 10),
            RestartDecision::Stay
        );
    }

    #[test]
    fn policy_names_round_trip() {
        for p in [
            RestartPolicy::Never,
            RestartPolicy::OnFailure,
            RestartPolicy::Always,
        ] {
            assert_eq!(RestartPolicy::from_name(p.name()), Some(p));
        }
        assert_eq!(RestartPolicy::from_name("sometimes"), None);
    }

    #[test]
    fn exits_print_readably() {
        assert_eq!(RoleExit::Code(3).to_string(), "exit code 3");
        assert_eq!(
            restart_decision(
                RestartPolicy::Always,
                RoleExit::Code(EXIT_SCHEMA_MISMATCH),
                0,
                5,
                100
            ),
            RestartDecision::GiveUp,
            "a schema mismatch is final"
        );
        assert_eq!(
            RoleExit::Signal(libc::SIGKILL).to_string(),
            "signal 9 (SIGKILL)"
        );
    }
}
