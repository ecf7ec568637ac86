//! What a supervisor step reports: [`SupervisorEvent`] and the live moves behind
//! [`SupervisorEvent::RoleMigrated`], with the one-line text the CLI prints for each.

use crate::ladder::StepDirection;
use crate::restart::RoleExit;

/// How a make-before-break swap handed the role over once its new process was ready.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Handover {
    /// The old process completed one more cycle, `after_ms` after the new one was ready.
    AfterCycle {
        /// Milliseconds from the new process's ready heartbeat to the hand-over.
        after_ms: u64,
    },
    /// The old process completed no cycle within the hand-over wait (one heartbeat and the
    /// decision deadline): the role was handed over without it.
    Waited {
        /// Milliseconds from the new process's ready heartbeat to the hand-over.
        after_ms: u64,
    },
    /// The role's host link was lost: handed over at once, no cycle waited for.
    LinkLost,
    /// There was no old process to wait for (the role was down).
    NoOldProcess,
}

impl core::fmt::Display for Handover {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Handover::AfterCycle { after_ms } => write!(
                f,
                "handed over {after_ms} ms later, after a cycle of the old process; stopping it"
            ),
            Handover::Waited { after_ms } => write!(
                f,
                "handed over {after_ms} ms later: the old process completed no cycle in that \
                 time; stopping it"
            ),
            Handover::LinkLost => write!(f, "handed over at once: the old process's link is lost"),
            Handover::NoOldProcess => write!(f, "handed over: the role had no process"),
        }
    }
}

/// Something that happened to a role during a [`Supervisor::step`](super::Supervisor::step).
#[derive(Debug, Clone, PartialEq)]
pub enum SupervisorEvent {
    /// The role process was started for the first time.
    RoleStarted {
        /// Role name.
        name: String,
        /// Its pid.
        pid: u32,
    },
    /// The role process exited.
    RoleExited {
        /// Role name.
        name: String,
        /// How.
        status: RoleExit,
    },
    /// The role process was started again after an exit.
    RoleRestarted {
        /// Role name.
        name: String,
        /// The new pid.
        pid: u32,
        /// Restarts of this role so far, this one included.
        restarts: u32,
    },
    /// A restart could not spawn the process; it counts against the budget.
    RestartFailed {
        /// Role name.
        name: String,
        /// Why.
        reason: String,
    },
    /// The restart budget is spent: the role stays down.
    RoleGaveUp {
        /// Role name.
        name: String,
    },
    /// The first heartbeat of the role's current process arrived.
    FirstHeartbeat {
        /// Role name.
        name: String,
    },
    /// The role's heartbeat says it is degraded (working, but something is wrong: a camera
    /// whose stream failed or stalled, a recorder that cannot write); its log says what.
    RoleDegraded {
        /// Role name.
        name: String,
    },
    /// A degraded role's heartbeat says it is running normally again.
    RoleRecovered {
        /// Role name.
        name: String,
    },
    /// The supervisor itself did not run for a while (the machine paused or starved it): the
    /// roles' silence in that time is not counted against them (stalls, lost links).
    Unwatched {
        /// Milliseconds not watched: between two steps of the supervisor, or of one CPU's
        /// pause.
        gap_ms: u64,
        /// The CPU that ran no ordinary thread (paused, or held by real-time work); `None`:
        /// the supervisor itself did not run.
        cpu: Option<usize>,
    },
    /// A hot swap started the new process; the old one keeps running.
    SwapStarted {
        /// Role name.
        name: String,
        /// The variant being brought up.
        variant: String,
        /// The running process.
        old_pid: Option<u32>,
        /// The new process.
        new_pid: u32,
        /// Its instance number.
        instance: u32,
        /// Where it runs, when it moves the role to another host or back (`None`: a hot
        /// swap where the role runs).
        place: Option<String>,
    },
    /// The new process loaded, warmed up and sent its first heartbeat: it is the role now
    /// (its normal scheduling restored), and the old one was asked to stop.
    SwapReady {
        /// Role name.
        name: String,
        /// The variant now running.
        variant: String,
        /// The process being stopped.
        old_pid: Option<u32>,
        /// The new process.
        new_pid: u32,
        /// Its instance number.
        instance: u32,
        /// Milliseconds from the start of the swap to the new process's first heartbeat.
        ready_ms: u64,
        /// How the role was handed over once the new process was ready.
        handover: Handover,
        /// Where it runs, when it moved the role to another host or back.
        place: Option<String>,
    },
    /// The old process of a swap exited: the swap is complete.
    SwapDone {
        /// Role name.
        name: String,
        /// The variant now running.
        variant: String,
        /// The process that was replaced.
        old_pid: Option<u32>,
        /// How it ended (`None`: there was none).
        exit: Option<RoleExit>,
        /// Where the role runs now, when it moved to another host or back.
        place: Option<String>,
    },
    /// The new process failed to come up; it was stopped and the old one keeps running.
    SwapFailed {
        /// Role name.
        name: String,
        /// The variant that failed.
        variant: String,
        /// Why, with the tail of the new process's log.
        reason: String,
        /// Where it was going, when it was a move to another host or back.
        place: Option<String>,
    },
    /// A role's process was moved, live, to another executor: every thread, same pid.
    RoleMigrated(Migration),
    /// The variant ladder stepped a role to another variant: a hot swap to it started
    /// (its `SwapStarted` .. `SwapDone`/`SwapFailed` follow).
    VariantStepped {
        /// Role name.
        name: String,
        /// The variant it ran.
        from: String,
        /// The variant it is swapped to.
        to: String,
        /// Down (lighter, the current one misses its budget) or up (heavier, fits again).
        direction: StepDirection,
        /// The last cycle's latency (ms) when the ladder stepped.
        latency_ms: f64,
        /// The role's budget (ms).
        budget_ms: f64,
        /// The latency (ms) predicted for `to` from its earlier cycles, if it ran before.
        predicted_ms: Option<f64>,
    },
    /// A running role was alive but silent: it was killed, and its restart policy applies.
    RoleStalled {
        /// Role name.
        name: String,
        /// The stalled process.
        pid: u32,
        /// Milliseconds since its last heartbeat.
        silent_ms: u64,
        /// What gave it away ("stopped (state T)", "no CPU time", "silent").
        why: String,
    },
    /// A role on another host fell silent for longer than its host's link timeout: the link
    /// counts as lost. Its fallback (if the workflow names one) starts on the flight's host
    /// at once; otherwise its handle is stopped and it stays down.
    LinkLost {
        /// Role name.
        name: String,
        /// The host.
        host: String,
        /// Milliseconds since its last heartbeat.
        silent_ms: u64,
        /// The fallback variant started, if any.
        fallback: Option<String>,
    },
    /// A role's handle could not reach its host's agent (at the start or a restart): the
    /// link counts as lost; the fallback starts in its place, or it waits for the link.
    HostUnreachable {
        /// Role name.
        name: String,
        /// The host.
        host: String,
        /// The fallback variant started, if any.
        fallback: Option<String>,
    },
    /// A lost link to another host is back: a role lost with it starts there again
    /// (`variant: None`), or a role that fell back returns there, make-before-break
    /// (`variant: Some`; its `SwapStarted` .. `SwapDone` follow).
    LinkBack {
        /// The host.
        host: String,
        /// Role name.
        name: String,
        /// Its new process (on the flight's host: its handle).
        pid: Option<u32>,
        /// The variant it returns with.
        variant: Option<String>,
    },
    /// A service of the flight disappeared from under running roles (its files were
    /// removed from outside); the roles registered at it were killed so that their restarts
    /// create a fresh service and join it.
    ServiceLost {
        /// The service (relative to the flight).
        service: String,
        /// The roles killed, with the pids they had.
        roles: Vec<(String, u32)>,
    },
    /// The scheduling policy moved a role to or from another host (make-before-break: its
    /// `SwapStarted` .. `SwapDone`/`SwapFailed` follow), for the figures in `trigger`.
    MoveAcrossHosts {
        /// Role name.
        name: String,
        /// Where it goes (`HOST:EXECUTOR`, or an executor of the flight's host).
        place: String,
        /// The latency that triggered it and the one predicted there (the link included).
        trigger: MigrationTrigger,
    },
    /// The scheduling policy moved a model role onto or off an accelerator executor
    /// (make-before-break, a restart with the other execution provider: its `SwapStarted`
    /// .. `SwapDone`/`SwapFailed` follow).
    MoveAccelerator {
        /// Role name.
        name: String,
        /// The executor it goes to.
        executor: String,
        /// That executor's accelerator (`None`: back to CPUs).
        accelerator: Option<aeris_runtime::accelerator::Accelerator>,
        /// The latency that triggered it and the one predicted there.
        trigger: MigrationTrigger,
        /// A probe: never measured there, so nothing is predicted; the move measures it.
        probe: bool,
    },
    /// An automatic move could not be made; the role stays where it was.
    MigrationFailed {
        /// Role name.
        name: String,
        /// Why.
        reason: String,
    },
    /// The initial binding measured a role, moved live, on another executor (a probe).
    BindingProbed {
        /// Role name.
        name: String,
        /// Executor probed.
        executor: String,
        /// Slowdown `(run + wait) / run` measured there.
        slowdown: f64,
        /// Latency the probe predicts there (ms).
        predicted_ms: f64,
        /// `true` when a whole cycle finished there (the prediction is that cycle).
        measured_cycle: bool,
    },
    /// The initial binding was checked against the budgets (kept, or re-bound).
    InitialBinding {
        /// `true` when roles were moved.
        rebound: bool,
        /// One line per role: where it runs and why.
        reasons: Vec<String>,
    },
}

/// One live move of a role between executors.
#[derive(Debug, Clone, PartialEq)]
pub struct Migration {
    /// Role name.
    pub role: String,
    /// Its pid (unchanged by the move).
    pub pid: u32,
    /// Executor it left (name, or the CPU list when unnamed).
    pub from: String,
    /// Executor it went to.
    pub to: String,
    /// CPUs it runs on now.
    pub cpus: String,
    /// Threads moved.
    pub threads: usize,
    /// Time the move took (µs), affinity checked on every thread.
    pub took_us: u64,
    /// Why: `None` by hand (`aeris migrate`), else the latency that triggered it.
    pub trigger: Option<MigrationTrigger>,
    /// CLOCK_MONOTONIC ns when the move completed.
    pub done_ns: u64,
}

/// The figures behind an automatic move.
#[derive(Debug, Clone, PartialEq)]
pub struct MigrationTrigger {
    /// The role's latency signal (ms) when the policy acted.
    pub latency_ms: f64,
    /// Its budget (ms).
    pub budget_ms: f64,
    /// The latency predicted after the move (ms).
    pub predicted_ms: f64,
    /// `true` when it was part of the initial binding.
    pub initial: bool,
}

impl core::fmt::Display for SupervisorEvent {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SupervisorEvent::RoleStarted { name, pid } => {
                write!(f, "role `{name}` started (pid {pid})")
            }
            SupervisorEvent::RoleExited { name, status } => {
                write!(f, "role `{name}` exited ({status})")
            }
            SupervisorEvent::RoleRestarted {
                name,
                pid,
                restarts,
            } => write!(f, "role `{name}` restarted (pid {pid}, restart {restarts})"),
            SupervisorEvent::RestartFailed { name, reason } => {
                write!(f, "role `{name}` could not be restarted: {reason}")
            }
            SupervisorEvent::RoleGaveUp { name } => {
                write!(f, "role `{name}` spent its restart budget and stays down")
            }
            SupervisorEvent::FirstHeartbeat { name } => {
                write!(f, "role `{name}` is alive (first heartbeat)")
            }
            SupervisorEvent::RoleDegraded { name } => {
                write!(f, "role `{name}` is degraded (its log says why)")
            }
            SupervisorEvent::RoleRecovered { name } => {
                write!(f, "role `{name}` runs normally again")
            }
            SupervisorEvent::Unwatched { gap_ms, cpu: None } => write!(
                f,
                "the supervisor did not run for {gap_ms} ms (the machine paused or starved it): the roles' silence in that time is not held against them"
            ),
            SupervisorEvent::Unwatched {
                gap_ms,
                cpu: Some(cpu),
            } => write!(
                f,
                "CPU {cpu} ran no ordinary thread for {gap_ms} ms (the machine paused it, or real-time work held it): the roles' silence in that time is not held against them"
            ),
            SupervisorEvent::SwapStarted {
                name,
                variant,
                new_pid,
                instance,
                place,
                ..
            } => match place {
                Some(place) => write!(
                    f,
                    "role `{name}`: moving `{variant}` to {place} (pid {new_pid}, instance {instance})"
                ),
                None => write!(
                    f,
                    "role `{name}`: swap to `{variant}` started (pid {new_pid}, instance {instance})"
                ),
            },
            SupervisorEvent::SwapReady {
                name,
                variant,
                new_pid,
                ready_ms,
                handover,
                place,
                ..
            } => {
                write!(f, "role `{name}`: `{variant}` (pid {new_pid}) ")?;
                if let Some(place) = place {
                    write!(f, "on {place} ")?;
                }
                write!(f, "was ready after {ready_ms} ms; {handover}")
            }
            SupervisorEvent::SwapDone {
                name,
                variant,
                old_pid,
                exit,
                place,
            } => {
                match place {
                    Some(place) => write!(f, "role `{name}`: move of `{variant}` to {place} done")?,
                    None => write!(f, "role `{name}`: swap to `{variant}` done")?,
                }
                match (old_pid, exit) {
                    (Some(pid), Some(e)) => write!(f, " (old pid {pid} {e})"),
                    _ => Ok(()),
                }
            }
            SupervisorEvent::SwapFailed {
                name,
                variant,
                reason,
                place,
            } => match place {
                Some(place) => write!(
                    f,
                    "role `{name}`: move of `{variant}` to {place} failed, the role stays where it was: {reason}"
                ),
                None => write!(
                    f,
                    "role `{name}`: swap to `{variant}` rolled back, the old process keeps running: {reason}"
                ),
            },
            SupervisorEvent::RoleMigrated(m) => {
                write!(
                    f,
                    "role `{}` (pid {}) moved from {} to {} (CPUs {}, {} threads, {} µs)",
                    m.role, m.pid, m.from, m.to, m.cpus, m.threads, m.took_us
                )?;
                match &m.trigger {
                    Some(t) => write!(
                        f,
                        ": {}latency {:.1} ms over its {:.1} ms budget, {:.1} ms predicted there",
                        if t.initial { "initial binding, " } else { "" },
                        t.latency_ms,
                        t.budget_ms,
                        t.predicted_ms
                    ),
                    None => write!(f, " by hand"),
                }
            }
            SupervisorEvent::RoleStalled {
                name,
                pid,
                silent_ms,
                why,
            } => write!(
                f,
                "role `{name}` (pid {pid}) stalled: no heartbeat for {silent_ms} ms, {why}; killed"
            ),
            SupervisorEvent::HostUnreachable {
                name,
                host,
                fallback,
            } => match fallback {
                Some(v) => write!(
                    f,
                    "host `{host}` unreachable (role `{name}` could not reach its agent): fallback `{v}` starting on the flight's host"
                ),
                None => write!(
                    f,
                    "host `{host}` unreachable (role `{name}` could not reach its agent): it waits for the link"
                ),
            },
            SupervisorEvent::LinkBack {
                host,
                name,
                pid,
                variant,
            } => {
                match variant {
                    Some(v) => write!(
                        f,
                        "link to host `{host}` back: role `{name}` returns there as `{v}`"
                    )?,
                    None => write!(f, "link to host `{host}` back: role `{name}` restarted")?,
                }
                match pid {
                    Some(pid) => write!(f, " (pid {pid})"),
                    None => Ok(()),
                }
            }
            SupervisorEvent::LinkLost {
                name,
                host,
                silent_ms,
                fallback,
            } => match fallback {
                Some(v) => write!(
                    f,
                    "link to host `{host}` lost (role `{name}` silent for {silent_ms} ms): fallback `{v}` starting on the flight's host"
                ),
                None => write!(
                    f,
                    "link to host `{host}` lost (role `{name}` silent for {silent_ms} ms): no fallback, it stays down"
                ),
            },
            SupervisorEvent::MoveAcrossHosts {
                name,
                place,
                trigger,
            } => {
                write!(
                    f,
                    "{} moves `{name}` to {place}: {:.0} ms against its budget of {:.0} ms, {:.0} ms predicted there (the link included)",
                    if trigger.initial {
                        "initial binding"
                    } else {
                        "re-binding"
                    },
                    trigger.latency_ms,
                    trigger.budget_ms,
                    trigger.predicted_ms
                )
            }
            SupervisorEvent::MoveAccelerator {
                name,
                executor,
                accelerator,
                trigger,
                probe,
            } => {
                let place = match accelerator {
                    Some(a) => format!("{executor} ({a})"),
                    None => format!("{executor} (CPUs)"),
                };
                write!(
                    f,
                    "re-binding moves `{name}` to {place}, make-before-break: {:.0} ms against its budget of {:.0} ms, ",
                    trigger.latency_ms, trigger.budget_ms
                )?;
                if *probe {
                    write!(f, "a probe (never measured there)")
                } else {
                    write!(f, "{:.0} ms predicted there", trigger.predicted_ms)
                }
            }
            SupervisorEvent::MigrationFailed { name, reason } => {
                write!(f, "role `{name}` could not be moved: {reason}")
            }
            SupervisorEvent::VariantStepped {
                name,
                from,
                to,
                direction,
                latency_ms,
                budget_ms,
                predicted_ms,
            } => {
                let way = match direction {
                    StepDirection::Down => "down",
                    StepDirection::Up => "up",
                };
                write!(
                    f,
                    "role `{name}`: variant ladder steps {way} from `{from}` to `{to}`: last cycle {latency_ms:.1} ms, budget {budget_ms:.1} ms"
                )?;
                match predicted_ms {
                    Some(p) => write!(f, ", `{to}` predicted at {p:.1} ms"),
                    None => write!(f, ", `{to}` not measured yet"),
                }
            }
            SupervisorEvent::ServiceLost { service, roles } => {
                write!(f, "service `{service}` was removed under ")?;
                for (i, (name, pid)) in roles.iter().enumerate() {
                    let sep = if i == 0 { "" } else { ", " };
                    write!(f, "{sep}`{name}` (pid {pid})")?;
                }
                write!(f, "; killed them to rebuild it")
            }
            SupervisorEvent::BindingProbed {
                name,
                executor,
                slowdown,
                predicted_ms,
                measured_cycle,
            } => write!(
                f,
                "initial binding probe: `{name}` on {executor}: slowdown {slowdown:.2}, {predicted_ms:.0} ms {}",
                if *measured_cycle {
                    "(a cycle measured there)"
                } else {
                    "predicted"
                }
            ),
            SupervisorEvent::InitialBinding { rebound, reasons } => write!(
                f,
                "initial binding {}: {}",
                if *rebound { "re-bound" } else { "kept" },
                reasons.join("; ")
            ),
        }
    }
}
