//! `aeris bench faults`: a fault-injection table over one flight of the default workflow.
//! Each fault is injected once the previous one has recovered and the flight has settled
//! for a heartbeat: SIGKILL of every role in turn, SIGSTOP of every role in turn, a
//! garbage-emitting reasoner (hot swap to the `garbage` variant and back), and a
//! shared-memory service removed under its subscriber (`camera/rgb`'s files deleted).
//!
//! Per row: when the supervisor (or, for garbage, the hub) noticed; when the role was back
//! and publishing (first heartbeat of its new process; for garbage, the first decision
//! committed after the swap back); controller ticks whose setpoint never reached the
//! autopilot (counted by the vehicle at the MAVLink boundary); decisions the reasoner
//! published that the hub never received; setpoints the autopilot got outside the fence or
//! unusable. The flight then goes on to its goal.
//!
//! Controllers: with a hot standby (a second controller role, `params.standby = true`), the
//! SIGKILL and SIGSTOP rows of the controller hit whichever controller holds the autopilot
//! lease at that moment (heartbeat counter 5), and the row names it; standby controllers get
//! no rows of their own by default.

use super::{FlightBenchError, no_role};
use aeris_flight::{
    Flight, FlightMonitor, FlightWatcher, HookError, Overrides, StepContext, StepHook, StopRule,
};
use aeris_orchestrator::supervisor::{Supervisor, SupervisorEvent, SwapError};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::RoleKind;
use aeris_schemas::{ControllerCounters, VehicleCounters, reasoner_decisions, topics};
use serde::Serialize;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;

/// A kind of fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FaultKind {
    /// SIGKILL the role's process.
    Sigkill,
    /// SIGSTOP the role's process (alive, silent).
    Sigstop,
    /// Hot-swap the reasoner to its `garbage` variant, then back.
    Garbage,
    /// Delete the files of the `camera/rgb` service under its subscriber.
    ServiceRemoved,
}

impl FaultKind {
    /// Its name in the table and the JSON (`sigkill`, `service-removed`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::Sigkill => "sigkill",
            FaultKind::Sigstop => "sigstop",
            FaultKind::Garbage => "garbage",
            FaultKind::ServiceRemoved => "service-removed",
        }
    }
}

/// Settings of `aeris bench faults`.
#[derive(Debug, Clone)]
pub struct FaultsConfig {
    /// Workflow to fly (default: the built-in default flight, workflows/default.toml).
    pub workflow: Option<PathBuf>,
    /// Faults to inject (empty: all four kinds).
    pub faults: Vec<FaultKind>,
    /// Roles to SIGKILL / SIGSTOP (empty: every role of the workflow but standby
    /// controllers; a controller row hits the controller holding the lease).
    pub roles: Vec<String>,
    /// Give up on a fault's recovery after this many seconds (the row shows no recovery).
    pub recover_timeout_s: u64,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    pub run_dir: Option<PathBuf>,
}

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct FaultRow {
    /// The fault.
    pub fault: FaultKind,
    /// The role it hit (`camera/rgb` rows name the publisher and its subscribers).
    pub role: String,
    /// From the injection to the supervisor's (hub's) notice (ms).
    pub detect_ms: Option<f64>,
    /// From the injection to the role back and publishing (ms); for garbage, from the swap
    /// back to the first committed decision.
    pub recover_ms: Option<f64>,
    /// Controller ticks whose setpoint never reached the autopilot.
    pub missed_ticks: u64,
    /// Decisions the reasoner published that the hub never received.
    pub lost_decisions: u64,
    /// Setpoints the autopilot received outside the fence or unusable.
    pub invalid_setpoints: u64,
    /// Decisions the hub rejected in the row (garbage rows: the garbage caught).
    pub rejected_decisions: u64,
}

/// `aeris bench faults --json`.
#[derive(Debug, Serialize)]
pub struct FaultsReport {
    /// One row per fault.
    pub rows: Vec<FaultRow>,
    /// The flight reached its goal after every fault.
    pub reached_goal: bool,
    /// Flight duration (s).
    pub duration_s: f64,
    /// Restarts over the flight.
    pub role_restarts: u64,
}

/// The table, and why the flight ended early if it did (the rows up to then are kept).
#[derive(Debug)]
pub struct FaultsOutcome {
    /// The table.
    pub report: FaultsReport,
    /// Why the flight ended before its goal, if it did.
    pub failure: Option<aeris_flight::FlightFailure>,
}

/// Why a fault could not be injected.
#[derive(Debug, thiserror::Error)]
pub enum FaultError {
    /// The role to signal has no process.
    #[error("role `{role}` has no running process")]
    NoProcess {
        /// The role.
        role: String,
    },
    /// kill(2) failed.
    #[error("signalling `{role}` (pid {pid})")]
    Signal {
        /// The role.
        role: String,
        /// Its pid.
        pid: u32,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The swap to or from the garbage variant could not start (the error names both).
    #[error(transparent)]
    Swap(Box<SwapError>),
    /// The swap to the garbage variant failed.
    #[error("bench faults: garbage swap failed: {reason}")]
    GarbageSwapFailed {
        /// The supervisor's reason.
        reason: String,
    },
    /// The files of `camera/rgb` could not be removed.
    #[error("removing camera/rgb")]
    RemoveService(#[source] std::io::Error),
}

/// One fault to inject.
#[derive(Debug, Clone)]
struct Fault {
    kind: FaultKind,
    role: String,
}

/// Counters summed over every process of a role (a restarted process counts from 0).
#[derive(Debug, Default)]
struct PerProcess {
    last: HashMap<u32, [u64; 8]>,
}

impl PerProcess {
    fn update(&mut self, sup: &Supervisor, role: &str) {
        if let Some(hb) = sup.role(role).and_then(|r| r.last_heartbeat()) {
            self.last.insert(hb.pid, hb.counters);
        }
    }

    /// `counter` of each process's last heartbeat, summed.
    fn total(&self, counter: impl Fn(&[u64; 8]) -> u64) -> u64 {
        self.last.values().map(counter).sum()
    }
}

/// What the row deltas are taken from.
#[derive(Debug, Clone, Copy, Default)]
struct Snapshot {
    missed: u64,
    invalid: u64,
    published: u64,
    received: u64,
    rejected: u64,
}

/// How long after a row's settling a decision the reasoner counts as published may still be
/// on its way to the hub's report (the reasoner's heartbeat can count it a hub cycle before
/// the hub's report does) before it counts as lost.
const IN_FLIGHT_GRACE_NS: u64 = 500_000_000;

struct Counters {
    vehicle: PerProcess,
    reasoner: PerProcess,
    vehicle_role: Option<String>,
    reasoner_role: Option<String>,
}

impl Counters {
    fn snapshot(&mut self, sup: &Supervisor, monitor: &FlightMonitor) -> Snapshot {
        if let Some(v) = &self.vehicle_role {
            self.vehicle.update(sup, v);
        }
        if let Some(r) = &self.reasoner_role {
            self.reasoner.update(sup, r);
        }
        let (received, _) = monitor.decisions_received_committed();
        Snapshot {
            missed: self
                .vehicle
                .total(|c| VehicleCounters::from_heartbeat(c).setpoint_ticks_missed),
            invalid: self.vehicle.total(|c| {
                let v = VehicleCounters::from_heartbeat(c);
                v.outside_fence + v.rejected
            }),
            published: self.reasoner.total(reasoner_decisions),
            received,
            rejected: monitor.rejected(),
        }
    }
}

/// Where the injection of the current fault stands.
#[derive(Debug)]
enum Phase {
    /// Waiting for the vehicle to be up and flying.
    Warmup,
    /// Letting the flight settle before the next fault (or finishing the last row).
    Settle { until_ns: u64 },
    /// A fault is in effect.
    Injected(Box<Injection>),
    /// Every fault done: fly to the goal.
    Done,
}

#[derive(Debug)]
struct Injection {
    fault: Fault,
    t0_ns: u64,
    before: Snapshot,
    detect_ns: Option<u64>,
    recover_ns: Option<u64>,
    /// Roles whose fresh heartbeat ends the fault.
    waiting_for: Vec<String>,
    /// Garbage: the swap back started at this time.
    swapped_back_ns: Option<u64>,
    committed_at_swap_back: u64,
    deadline_ns: u64,
}

fn plan_faults(config: &FaultsConfig, w: &Workflow) -> Result<Vec<Fault>, FlightBenchError> {
    if let Some(r) = config
        .roles
        .iter()
        .find(|r| !w.roles.iter().any(|d| d.name == **r))
    {
        return Err(no_role(w, r));
    }
    let roles: Vec<String> = if config.roles.is_empty() {
        w.roles
            .iter()
            .filter(|r| !r.is_standby_controller())
            .map(|r| r.name.clone())
            .collect()
    } else {
        config.roles.clone()
    };
    let kinds = if config.faults.is_empty() {
        vec![
            FaultKind::Sigkill,
            FaultKind::Sigstop,
            FaultKind::Garbage,
            FaultKind::ServiceRemoved,
        ]
    } else {
        config.faults.clone()
    };
    let reasoner = w.roles.iter().find(|r| r.kind == RoleKind::Reasoning);
    let mut out = Vec::new();
    for kind in kinds {
        match kind {
            FaultKind::Sigkill | FaultKind::Sigstop => out.extend(roles.iter().map(|r| Fault {
                kind,
                role: r.clone(),
            })),
            FaultKind::Garbage => {
                let Some(r) = reasoner.filter(|r| r.variants.iter().any(|v| v == "garbage")) else {
                    return Err(FlightBenchError::NoGarbageVariant);
                };
                out.push(Fault {
                    kind,
                    role: r.name.clone(),
                });
            }
            FaultKind::ServiceRemoved => {
                let Some(camera) = w.roles.iter().find(|r| r.kind == RoleKind::Camera) else {
                    return Err(FlightBenchError::NoCamera);
                };
                out.push(Fault {
                    kind,
                    role: camera.name.clone(),
                });
            }
        }
    }
    Ok(out)
}

/// The controller holding the autopilot lease (its heartbeat says so) when `role` is one
/// of `controllers`; otherwise `role`.
fn lease_holder(sup: &Supervisor, controllers: &[String], role: &str) -> String {
    if !controllers.iter().any(|c| c == role) {
        return role.to_string();
    }
    controllers
        .iter()
        .find(|c| {
            sup.role(c)
                .and_then(|r| r.last_heartbeat())
                .is_some_and(|h| ControllerCounters::from_heartbeat(&h.counters).lease_held == 1)
        })
        .cloned()
        .unwrap_or_else(|| role.to_string())
}

fn signal(sup: &Supervisor, role: &str, sig: i32) -> Result<(), FaultError> {
    let pid = sup
        .role(role)
        .and_then(|r| r.pid())
        .ok_or_else(|| FaultError::NoProcess {
            role: role.to_string(),
        })?;
    // SAFETY: kill(2) on the pid of a child the supervisor owns and reports running.
    if unsafe { libc::kill(pid as i32, sig) } != 0 {
        return Err(FaultError::Signal {
            role: role.to_string(),
            pid,
            source: std::io::Error::last_os_error(),
        });
    }
    Ok(())
}

fn ms(from: u64, to: Option<u64>) -> Option<f64> {
    to.map(|t| t.saturating_sub(from) as f64 / 1e6)
}

/// The step hook: injects the faults in turn and fills the table.
struct FaultInjector {
    queue: std::vec::IntoIter<Fault>,
    phase: Phase,
    rows: Vec<FaultRow>,
    counters: Counters,
    controllers: Vec<String>,
    reasoner_variant: String,
    recover_timeout_s: u64,
    heartbeat_ns: u64,
    /// The row whose deltas close when the settle after it ends: (row, snapshot before it).
    pending_close: Option<(usize, Snapshot)>,
}

impl FaultInjector {
    fn swap(
        sup: &mut Supervisor,
        role: &str,
        variant: &str,
        timeout_s: u64,
    ) -> Result<(), FaultError> {
        sup.begin_swap(role, variant, Duration::from_secs(timeout_s))
            .map(|_| ())
            .map_err(|e| FaultError::Swap(Box::new(e)))
    }

    /// Inject the next fault, or finish.
    fn inject_next(
        &mut self,
        ctx: &mut StepContext<'_>,
        now: u64,
        snap: Snapshot,
    ) -> Result<Phase, FaultError> {
        let Some(mut fault) = self.queue.next() else {
            return Ok(Phase::Done);
        };
        let sup = &mut *ctx.supervisor;
        if matches!(fault.kind, FaultKind::Sigkill | FaultKind::Sigstop) {
            fault.role = lease_holder(sup, &self.controllers, &fault.role);
        }
        let mut inj = Injection {
            fault: fault.clone(),
            t0_ns: now,
            before: snap,
            detect_ns: None,
            recover_ns: None,
            waiting_for: vec![fault.role.clone()],
            swapped_back_ns: None,
            committed_at_swap_back: 0,
            deadline_ns: now + self.recover_timeout_s * 1_000_000_000,
        };
        match fault.kind {
            FaultKind::Sigkill => signal(sup, &fault.role, libc::SIGKILL)?,
            FaultKind::Sigstop => signal(sup, &fault.role, libc::SIGSTOP)?,
            FaultKind::Garbage => {
                Self::swap(sup, &fault.role, "garbage", self.recover_timeout_s)?;
            }
            FaultKind::ServiceRemoved => {
                inj.waiting_for.clear();
                aeris_runtime::bus::remove_flight_service_files(sup.flight(), topics::CAMERA_RGB)
                    .map_err(FaultError::RemoveService)?;
            }
        }
        ctx.note(format!("bench faults: {:?} {}", fault.kind, fault.role));
        inj.t0_ns = monotonic_ns();
        Ok(Phase::Injected(Box::new(inj)))
    }

    /// Follow the fault in effect; the next phase.
    fn follow(
        &mut self,
        ctx: &mut StepContext<'_>,
        mut inj: Box<Injection>,
        now: u64,
        snap: Snapshot,
    ) -> Result<Phase, FaultError> {
        let monitor = ctx.monitor;
        let role = inj.fault.role.clone();
        for e in ctx.events {
            match (inj.fault.kind, e) {
                (FaultKind::Sigkill, SupervisorEvent::RoleExited { name, .. })
                | (FaultKind::Sigstop, SupervisorEvent::RoleStalled { name, .. })
                    if *name == role =>
                {
                    inj.detect_ns.get_or_insert(now);
                }
                (FaultKind::ServiceRemoved, SupervisorEvent::ServiceLost { roles, .. }) => {
                    inj.detect_ns.get_or_insert(now);
                    inj.waiting_for
                        .extend(roles.iter().map(|(name, _)| name.clone()));
                    inj.fault.role = inj
                        .waiting_for
                        .iter()
                        .map(String::as_str)
                        .collect::<Vec<_>>()
                        .join("+");
                }
                (
                    FaultKind::Sigkill | FaultKind::Sigstop | FaultKind::ServiceRemoved,
                    SupervisorEvent::FirstHeartbeat { name },
                ) if inj.detect_ns.is_some() => {
                    // the new process's own stamp: when it published, not when we looked
                    let stamp = ctx
                        .supervisor
                        .role(name)
                        .and_then(|r| r.last_heartbeat())
                        .map(|h| h.stamp_ns)
                        .filter(|&s| s >= inj.t0_ns)
                        .unwrap_or(now);
                    inj.waiting_for.retain(|w| w != name);
                    if inj.waiting_for.is_empty() {
                        inj.recover_ns = Some(stamp);
                    }
                }
                (FaultKind::Garbage, SupervisorEvent::SwapFailed { reason, .. }) => {
                    return Err(FaultError::GarbageSwapFailed {
                        reason: reason.clone(),
                    });
                }
                _ => {}
            }
        }
        if inj.fault.kind == FaultKind::Garbage {
            let rejected = snap.rejected - inj.before.rejected;
            if rejected > 0 {
                inj.detect_ns.get_or_insert(now);
            }
            // two garbage decisions caught: put the real reasoner back
            if rejected >= 2 && inj.swapped_back_ns.is_none() {
                Self::swap(
                    ctx.supervisor,
                    &role,
                    &self.reasoner_variant,
                    self.recover_timeout_s,
                )?;
                inj.swapped_back_ns = Some(monotonic_ns());
                inj.committed_at_swap_back = monitor.decisions_received_committed().1;
            }
            if inj.swapped_back_ns.is_some()
                && ctx
                    .supervisor
                    .role(&role)
                    .is_some_and(|r| r.variant() == self.reasoner_variant)
                && monitor.decisions_received_committed().1 > inj.committed_at_swap_back
            {
                inj.recover_ns.get_or_insert(now);
            }
        }
        if inj.recover_ns.is_none() && now <= inj.deadline_ns {
            return Ok(Phase::Injected(inj));
        }
        if inj.recover_ns.is_none() {
            if let Some(r) = ctx.supervisor.role(&role) {
                ctx.note(format!(
                    "bench faults: {:?} {role}: no recovery within {} s (state {:?})",
                    inj.fault.kind,
                    self.recover_timeout_s,
                    r.state()
                ));
            }
            if inj.fault.kind == FaultKind::Sigstop {
                let _ = signal(ctx.supervisor, &role, libc::SIGCONT);
            }
        }
        self.rows.push(FaultRow {
            fault: inj.fault.kind,
            role: inj.fault.role.clone(),
            detect_ms: ms(inj.t0_ns, inj.detect_ns),
            recover_ms: match inj.fault.kind {
                FaultKind::Garbage => ms(inj.swapped_back_ns.unwrap_or(inj.t0_ns), inj.recover_ns),
                _ => ms(inj.t0_ns, inj.recover_ns),
            },
            // deltas are closed when the settle after the row ends
            missed_ticks: 0,
            lost_decisions: 0,
            invalid_setpoints: 0,
            rejected_decisions: 0,
        });
        self.pending_close = Some((self.rows.len() - 1, inj.before));
        Ok(Phase::Settle {
            until_ns: now + self.heartbeat_ns,
        })
    }
}

impl StepHook for FaultInjector {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        let now = monotonic_ns();
        let monitor = ctx.monitor;
        let snap = self.counters.snapshot(ctx.supervisor, monitor);
        let in_flight = |until_ns: u64, before: &Snapshot| {
            let published = snap.published.saturating_sub(before.published);
            let received = snap.received.saturating_sub(before.received);
            published > received && now < until_ns.saturating_add(IN_FLIGHT_GRACE_NS)
        };
        if let (Some((i, before)), Phase::Settle { until_ns }) = (self.pending_close, &self.phase)
            && now >= *until_ns
            && !in_flight(*until_ns, &before)
            && let Some(r) = self.rows.get_mut(i)
        {
            r.missed_ticks = snap.missed.saturating_sub(before.missed);
            r.invalid_setpoints = snap.invalid.saturating_sub(before.invalid);
            r.rejected_decisions = snap.rejected.saturating_sub(before.rejected);
            let published = snap.published.saturating_sub(before.published);
            r.lost_decisions =
                published.saturating_sub(snap.received.saturating_sub(before.received));
            self.pending_close = None;
        }
        self.phase = match std::mem::replace(&mut self.phase, Phase::Done) {
            Phase::Warmup => {
                let up = ctx.supervisor.roles().iter().all(|r| r.has_heartbeat());
                let flying = monitor.position().is_some_and(|p| p[2] > 5.0);
                if up && flying && monitor.cycles() >= 2 {
                    Phase::Settle { until_ns: now }
                } else {
                    Phase::Warmup
                }
            }
            Phase::Settle { until_ns } if now >= until_ns && self.pending_close.is_none() => {
                self.inject_next(ctx, now, snap)?
            }
            Phase::Injected(inj) => self.follow(ctx, inj, now, snap)?,
            other => other,
        };
        Ok(matches!(self.phase, Phase::Done)
            && self.pending_close.is_none()
            && monitor.reached_goal())
    }
}

/// Fly the table; `watcher` gets every event of the flight (each fault's line as
/// [`aeris_flight::FlightEvent::Note`]). A flight that ends early still returns its rows, with the reason.
pub fn run(
    config: &FaultsConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<FaultsOutcome, FlightBenchError> {
    let mut w = match &config.workflow {
        Some(p) => Workflow::from_path(p)?,
        None => Workflow::builtin_default().map_err(FlightBenchError::BuiltinWorkflow)?,
    };
    Overrides::default().apply(&mut w)?;
    let faults = plan_faults(config, &w)?;
    let heartbeat_ns = w.timing.heartbeat_period_ms * 1_000_000;
    // every fault takes a few heartbeats: make room for them before the time limit
    w.mission.max_duration_s += faults.len() as f64 * 4.0 * heartbeat_ns as f64 * 1e-9;
    let role_of_kind = |kind: RoleKind| {
        w.roles
            .iter()
            .find(|r| r.kind == kind)
            .map(|r| (r.name.clone(), r.variant.clone()))
    };
    let reasoner = role_of_kind(RoleKind::Reasoning);
    let injector = FaultInjector {
        queue: faults.into_iter(),
        phase: Phase::Warmup,
        rows: Vec::new(),
        counters: Counters {
            vehicle: PerProcess::default(),
            reasoner: PerProcess::default(),
            vehicle_role: role_of_kind(RoleKind::Vehicle).map(|(name, _)| name),
            reasoner_role: reasoner.as_ref().map(|(name, _)| name.clone()),
        },
        controllers: w
            .roles
            .iter()
            .filter(|r| r.kind == RoleKind::Controller)
            .map(|r| r.name.clone())
            .collect(),
        reasoner_variant: reasoner.map(|(_, variant)| variant).unwrap_or_default(),
        recover_timeout_s: config.recover_timeout_s,
        heartbeat_ns,
        pending_close: None,
    };
    let (name, run_dir) = super::flight_name_and_dir("faults", config.run_dir.clone());
    let (outcome, injector) = Flight::builder(w)
        .name(name)
        .language_offload_check(aeris_llm::offload_check)
        .run_dir(run_dir)
        .stop_when(StopRule::Hook)
        // moves are not faults: keep the declared binding so rows compare
        .overrides(Overrides {
            dynamic: Some(false),
            ..Overrides::default()
        })
        .step_hook(injector)
        .start()?
        .watch(watcher)?;
    let summary = &outcome.summary;
    Ok(FaultsOutcome {
        report: FaultsReport {
            reached_goal: summary.reached_goal,
            duration_s: summary.duration_s,
            role_restarts: summary.role_restarts,
            rows: injector.rows,
        },
        failure: outcome.failure,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_kind_is_named_as_in_the_json() {
        for kind in [
            FaultKind::Sigkill,
            FaultKind::Sigstop,
            FaultKind::Garbage,
            FaultKind::ServiceRemoved,
        ] {
            assert_eq!(
                serde_json::to_value(kind).unwrap(),
                serde_json::Value::from(kind.as_str())
            );
        }
    }
}
