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

use crate::run_cmd::{FlightPlan, StopRule, apply_overrides, fly};
use aeris_flight::FlightMonitor;
use aeris_orchestrator::supervisor::{Supervisor, SupervisorEvent};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::topics;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use serde::Serialize;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;

/// A kind of fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
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

/// Arguments of `aeris bench faults`.
#[derive(Debug, Args)]
pub struct FaultsArgs {
    /// Workflow to fly (default: the built-in default flight, workflows/default.toml).
    #[arg(long)]
    pub workflow: Option<PathBuf>,
    /// Faults to inject, comma-separated (default: all four kinds).
    #[arg(long, value_delimiter = ',')]
    pub faults: Vec<FaultKind>,
    /// Roles to SIGKILL / SIGSTOP, comma-separated (default: every role of the workflow but
    /// standby controllers; a controller row hits the controller holding the lease).
    #[arg(long, value_delimiter = ',')]
    pub roles: Vec<String>,
    /// Give up on a fault's recovery after this many seconds (the row shows no recovery).
    #[arg(long, default_value_t = 30)]
    pub recover_timeout_s: u64,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
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

    fn total(&self, i: usize) -> u64 {
        self.last.values().map(|c| c[i]).sum()
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

/// Vehicle counters: setpoints outside the fence, setpoint ticks missed, rejected.
const VEH_OUTSIDE: usize = 1;
const VEH_MISSED: usize = 4;
const VEH_REJECTED: usize = 5;
/// Reasoner counter: decisions published.
const REASONER_PUBLISHED: usize = 0;

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
            missed: self.vehicle.total(VEH_MISSED),
            invalid: self.vehicle.total(VEH_OUTSIDE) + self.vehicle.total(VEH_REJECTED),
            published: self.reasoner.total(REASONER_PUBLISHED),
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

fn workflow(a: &FaultsArgs) -> Result<Workflow> {
    let mut w = match &a.workflow {
        Some(p) => Workflow::from_path(p).with_context(|| format!("workflow {}", p.display()))?,
        None => Workflow::builtin_default().context("built-in default workflow")?,
    };
    apply_overrides(&mut w, &[], None)?;
    Ok(w)
}

fn plan_faults(a: &FaultsArgs, w: &Workflow) -> Result<Vec<Fault>> {
    let names: Vec<String> = w.roles.iter().map(|r| r.name.clone()).collect();
    for r in &a.roles {
        if !names.contains(r) {
            bail!(
                "--roles: no role `{r}` in the workflow (roles: {})",
                names.join(", ")
            );
        }
    }
    let roles: Vec<String> = if a.roles.is_empty() {
        w.roles
            .iter()
            .filter(|r| !r.is_standby_controller())
            .map(|r| r.name.clone())
            .collect()
    } else {
        a.roles.clone()
    };
    let kinds = if a.faults.is_empty() {
        vec![
            FaultKind::Sigkill,
            FaultKind::Sigstop,
            FaultKind::Garbage,
            FaultKind::ServiceRemoved,
        ]
    } else {
        a.faults.clone()
    };
    let reasoner = w.roles.iter().find(|r| r.kind == "reasoning");
    let mut out = Vec::new();
    for kind in kinds {
        match kind {
            FaultKind::Sigkill | FaultKind::Sigstop => out.extend(roles.iter().map(|r| Fault {
                kind,
                role: r.clone(),
            })),
            FaultKind::Garbage => {
                let Some(r) = reasoner.filter(|r| r.variants.iter().any(|v| v == "garbage")) else {
                    bail!("garbage: the workflow's reasoning role has no `garbage` variant");
                };
                out.push(Fault {
                    kind,
                    role: r.name.clone(),
                });
            }
            FaultKind::ServiceRemoved => {
                let Some(camera) = w.roles.iter().find(|r| r.kind == "camera") else {
                    bail!("service-removed: the workflow has no camera role");
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

/// The controller holding the autopilot lease (heartbeat counter 5 is 1) when `role` is one
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
                .is_some_and(|h| h.counters[5] == 1)
        })
        .cloned()
        .unwrap_or_else(|| role.to_string())
}

fn signal(sup: &Supervisor, role: &str, sig: i32) -> Result<()> {
    let pid = sup
        .role(role)
        .and_then(|r| r.pid())
        .with_context(|| format!("role `{role}` has no running process"))?;
    // SAFETY: kill(2) on the pid of a child the supervisor owns and reports running.
    if unsafe { libc::kill(pid as i32, sig) } != 0 {
        bail!(
            "signalling `{role}` (pid {pid}): {}",
            std::io::Error::last_os_error()
        );
    }
    Ok(())
}

fn ms(from: u64, to: Option<u64>) -> Option<f64> {
    to.map(|t| t.saturating_sub(from) as f64 / 1e6)
}

/// `aeris bench faults`.
pub fn faults(a: FaultsArgs) -> Result<()> {
    let mut w = workflow(&a)?;
    let faults = plan_faults(&a, &w)?;
    let heartbeat_ns = w.timing.heartbeat_period_ms * 1_000_000;
    // every fault takes a few heartbeats: make room for them before the time limit
    w.mission.max_duration_s += faults.len() as f64 * 4.0 * heartbeat_ns as f64 * 1e-9;
    let flight = format!("bench-faults-{}", std::process::id());
    let plan = FlightPlan {
        run_dir: a
            .run_dir
            .clone()
            .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight)),
        flight: flight.clone(),
        autopilot: None,
        stop: StopRule::Hook,
        progress: true,
        // moves are not faults: keep the declared binding so rows compare
        dynamic: Some(false),
    };
    let mut counters = Counters {
        vehicle: PerProcess::default(),
        reasoner: PerProcess::default(),
        vehicle_role: w
            .roles
            .iter()
            .find(|r| r.kind == "vehicle")
            .map(|r| r.name.clone()),
        reasoner_role: w
            .roles
            .iter()
            .find(|r| r.kind == "reasoning")
            .map(|r| r.name.clone()),
    };
    let controllers: Vec<String> = w
        .roles
        .iter()
        .filter(|r| r.kind == "controller")
        .map(|r| r.name.clone())
        .collect();
    let reasoner_variant = w
        .roles
        .iter()
        .find(|r| r.kind == "reasoning")
        .map(|r| r.variant.clone())
        .unwrap_or_default();
    let recover_timeout_ns = a.recover_timeout_s * 1_000_000_000;
    let mut queue = faults.into_iter();
    let mut phase = Phase::Warmup;
    let mut rows: Vec<FaultRow> = Vec::new();
    let mut problem: Option<String> = None;
    // the row whose deltas close when the settle after it ends: (row, snapshot before it)
    let mut pending_close: Option<(usize, Snapshot)> = None;
    let outcome = fly(w, &plan, |sup, monitor, events| {
        let now = monotonic_ns();
        let snap = counters.snapshot(sup, monitor);
        if let (Some((i, before)), Phase::Settle { until_ns }) = (pending_close, &phase)
            && now >= *until_ns
        {
            let r = &mut rows[i];
            r.missed_ticks = snap.missed.saturating_sub(before.missed);
            r.invalid_setpoints = snap.invalid.saturating_sub(before.invalid);
            r.rejected_decisions = snap.rejected.saturating_sub(before.rejected);
            let published = snap.published.saturating_sub(before.published);
            r.lost_decisions =
                published.saturating_sub(snap.received.saturating_sub(before.received));
            pending_close = None;
        }
        match &mut phase {
            Phase::Warmup => {
                let up = sup.roles().iter().all(|r| r.has_heartbeat());
                let flying = monitor.position().is_some_and(|p| p[2] > 5.0);
                if up && flying && monitor.cycles() >= 2 {
                    phase = Phase::Settle { until_ns: now };
                }
            }
            Phase::Settle { until_ns } => {
                if now >= *until_ns {
                    phase = match queue.next() {
                        None => Phase::Done,
                        Some(mut fault) => {
                            if matches!(fault.kind, FaultKind::Sigkill | FaultKind::Sigstop) {
                                fault.role = lease_holder(sup, &controllers, &fault.role);
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
                                deadline_ns: now + recover_timeout_ns,
                            };
                            match fault.kind {
                                FaultKind::Sigkill => signal(sup, &fault.role, libc::SIGKILL)?,
                                FaultKind::Sigstop => signal(sup, &fault.role, libc::SIGSTOP)?,
                                FaultKind::Garbage => {
                                    sup.begin_swap(
                                        &fault.role,
                                        "garbage",
                                        Duration::from_secs(a.recover_timeout_s),
                                    )?;
                                }
                                FaultKind::ServiceRemoved => {
                                    inj.waiting_for.clear();
                                    aeris_runtime::bus::remove_flight_service_files(
                                        sup.flight(),
                                        topics::CAMERA_RGB,
                                    )
                                    .context("removing camera/rgb")?;
                                }
                            }
                            eprintln!("aeris: bench faults: {:?} {}", fault.kind, fault.role);
                            inj.t0_ns = monotonic_ns();
                            Phase::Injected(Box::new(inj))
                        }
                    };
                }
            }
            Phase::Injected(inj) => {
                let role = inj.fault.role.clone();
                for e in events {
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
                            let stamp = sup
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
                            problem = Some(format!("garbage swap failed: {reason}"));
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
                        sup.begin_swap(
                            &role,
                            &reasoner_variant,
                            Duration::from_secs(a.recover_timeout_s),
                        )?;
                        inj.swapped_back_ns = Some(monotonic_ns());
                        inj.committed_at_swap_back = monitor.decisions_received_committed().1;
                    }
                    if inj.swapped_back_ns.is_some()
                        && sup
                            .role(&role)
                            .is_some_and(|r| r.variant() == reasoner_variant)
                        && monitor.decisions_received_committed().1 > inj.committed_at_swap_back
                    {
                        inj.recover_ns.get_or_insert(now);
                    }
                }
                if inj.recover_ns.is_some() || now > inj.deadline_ns {
                    if inj.recover_ns.is_none() {
                        if let Some(r) = sup.role(&role) {
                            eprintln!(
                                "aeris: bench faults: {:?} {role}: no recovery within {} s (state {:?})",
                                inj.fault.kind,
                                a.recover_timeout_s,
                                r.state()
                            );
                        }
                        if inj.fault.kind == FaultKind::Sigstop {
                            let _ = signal(sup, &role, libc::SIGCONT);
                        }
                    }
                    let settle = Phase::Settle {
                        until_ns: now + heartbeat_ns,
                    };
                    let Phase::Injected(inj) = std::mem::replace(&mut phase, settle) else {
                        unreachable!("matched above");
                    };
                    rows.push(FaultRow {
                        fault: inj.fault.kind,
                        role: inj.fault.role.clone(),
                        detect_ms: ms(inj.t0_ns, inj.detect_ns),
                        recover_ms: match inj.fault.kind {
                            FaultKind::Garbage => {
                                ms(inj.swapped_back_ns.unwrap_or(inj.t0_ns), inj.recover_ns)
                            }
                            _ => ms(inj.t0_ns, inj.recover_ns),
                        },
                        // deltas are closed when the settle after the row ends
                        missed_ticks: 0,
                        lost_decisions: 0,
                        invalid_setpoints: 0,
                        rejected_decisions: 0,
                    });
                    pending_close = Some((rows.len() - 1, inj.before));
                }
            }
            Phase::Done => {}
        }
        if let Some(p) = &problem {
            bail!("bench faults: {p}");
        }
        Ok(matches!(phase, Phase::Done) && pending_close.is_none() && monitor.reached_goal())
    })?;
    let summary = &outcome.summary;
    print_table(&rows);
    println!(
        "  flight: goal {} after {:.1} s, {} restarts",
        if summary.reached_goal {
            "reached"
        } else {
            "NOT reached"
        },
        summary.duration_s,
        summary.role_restarts
    );
    if let Some(f) = &outcome.failure {
        println!("  flight ended early: {f}");
    }
    if a.json {
        let report = FaultsReport {
            reached_goal: summary.reached_goal,
            duration_s: summary.duration_s,
            role_restarts: summary.role_restarts,
            rows,
        };
        println!("{}", serde_json::to_string(&report)?);
    }
    if let Some(f) = outcome.failure {
        bail!("bench faults: the flight ended early: {f}");
    }
    Ok(())
}

fn print_table(rows: &[FaultRow]) {
    println!(
        "  {:<16} {:<26} {:>10} {:>11} {:>12} {:>14} {:>17}",
        "fault",
        "role",
        "detect ms",
        "recover ms",
        "missed ticks",
        "lost decisions",
        "invalid setpoints"
    );
    let f = |v: Option<f64>| v.map(|v| format!("{v:.0}")).unwrap_or_else(|| "-".into());
    for r in rows {
        let fault = serde_json::to_value(r.fault)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        println!(
            "  {:<16} {:<26} {:>10} {:>11} {:>12} {:>14} {:>17}",
            fault,
            r.role,
            f(r.detect_ms),
            f(r.recover_ms),
            r.missed_ticks,
            r.lost_decisions,
            r.invalid_setpoints
        );
    }
}
