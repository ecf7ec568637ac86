//! When the agent stops a role on its own: its handle (the process on the flight's host that
//! asked for it) is gone.

use std::time::Duration;

/// What the agent knows of a role's handle (the liveliness token of the process on the
/// flight's host that started it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct HandleWatch {
    /// Its token was seen alive since the role started.
    pub(super) seen: bool,
    /// Its token is alive now.
    pub(super) alive: bool,
    /// How long the role has run.
    pub(super) running_for: Duration,
}

impl HandleWatch {
    /// Why the role is to be stopped, if it is: its handle's token, seen before, is gone, or
    /// it never showed within two leases of the start (the token is declared before the role
    /// is asked for). A handle whose session only lapsed hears the reason in the role's exit
    /// report and counts its link lost, so the role is started again when the link is back;
    /// keeping the role instead would leave it running beside its replacement when the link
    /// returns.
    pub(super) fn verdict(self, lease: Duration) -> Option<String> {
        if self.seen && !self.alive {
            return Some("its handle is gone".into());
        }
        (!self.seen && self.running_for > lease * 2).then(|| {
            format!(
                "its handle never showed within {} ms",
                (lease * 2).as_millis()
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LEASE: Duration = Duration::from_millis(1000);

    fn watch(seen: bool, alive: bool, running_ms: u64) -> HandleWatch {
        HandleWatch {
            seen,
            alive,
            running_for: Duration::from_millis(running_ms),
        }
    }

    #[test]
    fn a_role_whose_handle_is_gone_or_never_showed_is_stopped_and_says_why() {
        assert_eq!(watch(true, true, 60_000).verdict(LEASE), None);
        assert_eq!(
            watch(true, false, 4000).verdict(LEASE).as_deref(),
            Some("its handle is gone")
        );
        assert_eq!(watch(false, false, 2000).verdict(LEASE), None);
        assert_eq!(
            watch(false, false, 2001).verdict(LEASE).as_deref(),
            Some("its handle never showed within 2000 ms")
        );
    }
}
