//! The links to the flight's other hosts as their bridges measure them (`hosts/link`): the
//! latest figures per host, for the status board and for placing roles there (the link's
//! round trip is part of the cycle of a role on another host).

use aeris_runtime::bus::{BusError, FlightBus, TypedSubscriber};
use aeris_schemas::{FixedText, HostLinkStatus, MAX_HOSTS, topics};

/// The latest figures of every link, one entry per other host in the workflow's order.
pub(super) struct HostLinks {
    /// The `hosts/link` subscriber (`None` for a flight on one host).
    subscriber: Option<TypedSubscriber<HostLinkStatus>>,
    /// One entry per host (`probes` 0 until its bridge measured it).
    links: Vec<HostLinkStatus>,
}

impl HostLinks {
    /// The links to `hosts` (at most [`MAX_HOSTS`], as the workflow checked).
    pub(super) fn new(bus: &FlightBus, hosts: &[String]) -> Result<Self, BusError> {
        let subscriber = if hosts.is_empty() {
            None
        } else {
            Some(bus.subscriber::<topics::HostsLink>()?)
        };
        let links = hosts
            .iter()
            .take(MAX_HOSTS)
            .map(|h| HostLinkStatus {
                host: FixedText::from_str_truncated(h),
                ..HostLinkStatus::default()
            })
            .collect();
        Ok(HostLinks { subscriber, links })
    }

    /// Take every waiting sample; one of a host the flight does not name is ignored.
    pub(super) fn drain(&mut self) -> Result<(), BusError> {
        let Some(sub) = self.subscriber.as_ref() else {
            return Ok(());
        };
        while let Some(s) = sub.next()? {
            if let Some(l) = self.links.iter_mut().find(|l| l.host == s.host) {
                *l = s;
            }
        }
        Ok(())
    }

    /// Every link, in the workflow's order.
    pub(super) fn all(&self) -> &[HostLinkStatus] {
        &self.links
    }

    /// The link to `host`, once measured.
    pub(super) fn get(&self, host: &str) -> Option<&HostLinkStatus> {
        self.links
            .iter()
            .find(|l| l.host.as_str() == Some(host) && l.probes > 0)
    }
}
