//! When the agent stops a role on its own: its handle (the process on the flight's host that
//! asked for it) is gone.

use std::time::Duration;

/// What the agent knows of a role's handle (the liveliness token of the process on the
/// flight's host that started it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct HandleWatch {
    /// Its token was seen alive since the role started.
    pub(super) seen: bool,
    /// How long the token, seen before, has been gone (`None`: alive, or never seen).
    pub(super) gone_for: Option<Duration>,
    /// How long the role has run.
    pub(super) running_for: Duration,
}

impl HandleWatch {
    /// Why the role is to be stopped, if it is: its handle's token gone for a whole `lease`
    /// (a token's loss alone is no proof: a session whose lease lapsed on a loaded host
    /// declares it again when it reconnects, a moment later), or never seen within two
    /// leases of the start (the token is declared before the role is asked for).
    pub(super) fn verdict(self, lease: Duration) -> Option<String> {
        match self.gone_for {
            Some(gone) if gone >= lease => Some(format!(
                "its handle has been gone for {} ms",
                gone.as_millis()
            )),
            Some(_) => None,
            None if !self.seen && self.running_for > lease * 2 => Some(format!(
                "its handle never showed within {} ms",
                (lease * 2).as_millis()
            )),
            None => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LEASE: Duration = Duration::from_millis(1000);

    fn watch(seen: bool, gone_ms: Option<u64>, running_ms: u64) -> HandleWatch {
        HandleWatch {
            seen,
            gone_for: gone_ms.map(Duration::from_millis),
            running_for: Duration::from_millis(running_ms),
        }
    }

    #[test]
    fn a_handle_gone_for_less_than_a_lease_keeps_its_role() {
        // a session whose lease lapsed declares its token again when it reconnects: the
        // role ran on through that (a CI run stopped a bridge whose handle was alive)
        assert_eq!(watch(true, Some(0), 4000).verdict(LEASE), None);
        assert_eq!(watch(true, Some(999), 4000).verdict(LEASE), None);
        assert_eq!(watch(true, None, 60_000).verdict(LEASE), None);
    }

    #[test]
    fn a_handle_gone_for_a_lease_or_never_seen_in_two_stops_its_role_and_says_why() {
        assert_eq!(
            watch(true, Some(1000), 4000).verdict(LEASE).as_deref(),
            Some("its handle has been gone for 1000 ms")
        );
        assert_eq!(watch(false, None, 2000).verdict(LEASE), None);
        assert_eq!(
            watch(false, None, 2001).verdict(LEASE).as_deref(),
            Some("its handle never showed within 2000 ms")
        );
    }
}
