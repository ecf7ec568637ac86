//! The service audit: a service of the flight removed from outside (a `/dev/shm` clean-up)
//! under running roles is rebuilt by killing those roles, whose restarts create it again.
//!
//! Listing the services reads every service of the machine (iceoryx2 has no listing per
//! flight): hundreds of files, and slow while services are being created and removed (a
//! swap, a restart; 260 ms of one step was measured beside a second flight). Cleaning up
//! after dead processes walks every node of the machine likewise. Both run on a thread of
//! their own ([`BusWorker`]); the supervisor's step only compares the newest listing with the
//! one before and asks for clean-ups, and never waits for either.

use super::events::SupervisorEvent;
use super::role_runtime::RoleRuntime;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
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

/// The thread that does the bus's machine-wide work for the supervisor: it lists the
/// flight's services every [`SERVICE_AUDIT_PERIOD`], keeping the newest listing for the
/// audit to take, and cleans up after dead processes when asked. It ends when dropped (after
/// the listing or clean-up under way).
#[derive(Debug)]
struct BusWorker {
    newest: Arc<Mutex<Option<Listing>>>,
    /// Clean-up requests; dropping it ends the thread.
    cleanup: Option<Sender<()>>,
}

impl BusWorker {
    fn start(flight: &str) -> Self {
        let newest = Arc::new(Mutex::new(None));
        let (tx, rx) = std::sync::mpsc::channel();
        let (slot, flight) = (newest.clone(), flight.to_string());
        let spawned = std::thread::Builder::new()
            .name("bus-worker".into())
            .spawn(move || work(&flight, &slot, &rx));
        BusWorker {
            newest,
            // no thread (out of resources): no listing, no clean-up but the new processes'
            // own (every role cleans up after dead processes as it starts)
            cleanup: spawned.is_ok().then_some(tx),
        }
    }

    /// The newest listing not taken yet.
    fn take(&self) -> Option<Listing> {
        self.newest.lock().ok()?.take()
    }

    /// Ask for a clean-up after dead processes (done at once, on the worker's thread).
    fn clean_up_dead_nodes(&self) {
        if let Some(tx) = &self.cleanup {
            let _ = tx.send(());
        }
    }
}

/// The worker's loop: clean-ups as they are asked for, a listing whenever one is due.
fn work(flight: &str, newest: &Mutex<Option<Listing>>, requests: &Receiver<()>) {
    let mut next_listing = Instant::now();
    loop {
        match requests.recv_timeout(next_listing.saturating_duration_since(Instant::now())) {
            Ok(()) => {
                // one clean-up for every request waiting
                while requests.try_recv().is_ok() {}
                aeris_runtime::bus::cleanup_dead_nodes();
            }
            Err(RecvTimeoutError::Timeout) => {
                let taken_at = Instant::now();
                let services = aeris_runtime::bus::flight_service_nodes(flight);
                if let Ok(mut slot) = newest.lock() {
                    *slot = Some(Listing { taken_at, services });
                }
                next_listing = Instant::now() + SERVICE_AUDIT_PERIOD;
            }
            Err(RecvTimeoutError::Disconnected) => return,
        }
    }
}

/// What the last audit saw: the flight's services and the roles registered at each.
#[derive(Debug)]
pub(super) struct ServiceAudit {
    /// Lists the flight's services (and cleans up) on its own thread.
    worker: BusWorker,
    /// Each service (relative to the flight) with the roles, and their pids, registered at it.
    known: Vec<(String, Vec<(String, u32)>)>,
}

impl ServiceAudit {
    /// Clean up after dead processes (their iceoryx2 nodes and ports: a dead process cannot
    /// remove its own), on the worker's thread: the step does not wait for it.
    pub(super) fn clean_up_dead_nodes(&self) {
        self.worker.clean_up_dead_nodes();
    }

    /// An audit of `flight`'s services, its first listing under way.
    pub(super) fn new(flight: &str) -> Self {
        ServiceAudit {
            worker: BusWorker::start(flight),
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
        }) = self.worker.take()
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
