//! The service audit: a service of the flight removed from outside (a `/dev/shm` clean-up)
//! under running roles is rebuilt by killing those roles, whose restarts create it again.
//!
//! Listing the services reads every service of the machine (iceoryx2 has no listing per
//! flight): hundreds of files, and slow while services are being created and removed (a
//! swap, a restart; 260 ms was measured beside a second flight). The listing therefore runs
//! on a thread of its own ([`ServiceLister`]); the supervisor's step only compares the newest
//! listing with the one before, and never waits for one.

use super::events::SupervisorEvent;
use super::role_runtime::RoleRuntime;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often the flight's services are listed to find one removed from outside.
const SERVICE_AUDIT_PERIOD: Duration = Duration::from_millis(500);

/// One listing of the flight's services.
#[derive(Debug)]
struct Listing {
    /// When the listing began: only processes started before it can be in it.
    taken_at: Instant,
    /// Each service (relative to the flight) with the names of the nodes registered at it.
    services: Vec<(String, Vec<String>)>,
}

/// The thread that lists the flight's services every [`SERVICE_AUDIT_PERIOD`], keeping the
/// newest listing for the audit to take. It ends within a period of being dropped.
#[derive(Debug)]
struct ServiceLister {
    newest: Arc<Mutex<Option<Listing>>>,
    stop: Arc<AtomicBool>,
}

impl ServiceLister {
    fn start(flight: &str) -> Self {
        let newest = Arc::new(Mutex::new(None));
        let stop = Arc::new(AtomicBool::new(false));
        let (slot, stopped, flight) = (newest.clone(), stop.clone(), flight.to_string());
        let spawned = std::thread::Builder::new()
            .name("service-audit".into())
            .spawn(move || {
                while !stopped.load(Ordering::Relaxed) {
                    let taken_at = Instant::now();
                    let services = aeris_runtime::bus::flight_service_nodes(&flight);
                    if let Ok(mut s) = slot.lock() {
                        *s = Some(Listing { taken_at, services });
                    }
                    // the audit's period, not a synchronisation
                    std::thread::sleep(SERVICE_AUDIT_PERIOD);
                }
            });
        if spawned.is_err() {
            // no thread (out of resources): the audit sees no listing and does nothing
            stop.store(true, Ordering::Relaxed);
        }
        ServiceLister { newest, stop }
    }

    /// The newest listing not taken yet.
    fn take(&self) -> Option<Listing> {
        self.newest.lock().ok()?.take()
    }
}

impl Drop for ServiceLister {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// What the last audit saw: the flight's services and the roles registered at each.
#[derive(Debug)]
pub(super) struct ServiceAudit {
    /// Lists the flight's services on its own thread.
    lister: ServiceLister,
    /// Each service (relative to the flight) with the roles, and their pids, registered at it.
    known: Vec<(String, Vec<(String, u32)>)>,
}

impl ServiceAudit {
    /// An audit of `flight`'s services, its first listing under way.
    pub(super) fn new(flight: &str) -> Self {
        ServiceAudit {
            lister: ServiceLister::start(flight),
            known: Vec::new(),
        }
    }

    /// With each new listing (every [`SERVICE_AUDIT_PERIOD`]): the flight's services and the
    /// roles registered at each. A service seen before that is gone while a role registered
    /// at it still runs the same process was removed from outside (a `/dev/shm` clean-up):
    /// the processes keep their mappings but nobody new can join it, so a later restart of
    /// any of them would talk into a fresh service nobody else is on. Kill them now; their
    /// restarts create the service again and all join it. Never waits for a listing.
    pub(super) fn check(&mut self, roles: &mut [RoleRuntime], events: &mut Vec<SupervisorEvent>) {
        let Some(Listing {
            taken_at,
            services: current,
        }) = self.lister.take()
        else {
            return;
        };
        let mut lost = Vec::new();
        for (service, attached) in &self.known {
            if current.iter().any(|(s, _)| s == service) {
                continue;
            }
            let victims: Vec<(usize, u32)> = attached
                .iter()
                .filter_map(|(name, pid)| {
                    let i = roles.iter().position(|r| &r.name == name)?;
                    let r = &roles[i];
                    (r.running && r.pid == Some(*pid)).then_some((i, *pid))
                })
                .collect();
            if !victims.is_empty() {
                lost.push((service.clone(), victims));
            }
        }
        self.known = current
            .into_iter()
            .map(|(service, nodes)| {
                let attached = nodes
                    .into_iter()
                    .filter_map(|n| {
                        // a node of the role's current process only if that process ran
                        // when the listing began (a newer one may not be on the service)
                        let r = roles.iter().find(|r| r.name == n)?;
                        r.started_at.filter(|t| *t <= taken_at)?;
                        Some((n, r.pid?))
                    })
                    .collect();
                (service, attached)
            })
            .collect();
        for (service, victims) in lost {
            let mut killed = Vec::new();
            for (i, pid) in victims {
                let role = &mut roles[i];
                if !role.running {
                    continue; // already killed for another lost service
                }
                if let Some(child) = role.child.as_mut() {
                    let _ = child.kill();
                }
                role.running = false;
                killed.push((role.name.clone(), pid));
            }
            if !killed.is_empty() {
                events.push(SupervisorEvent::ServiceLost {
                    service,
                    roles: killed,
                });
            }
        }
    }
}
