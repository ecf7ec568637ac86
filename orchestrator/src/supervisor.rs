//! The supervisor: starts every role of a workflow as its own process, watches heartbeats,
//! restarts failed roles with backoff, and keeps the status board `aeris status` reads.
//!
//! The caller drives it: [`Supervisor::start`], then [`Supervisor::step`] every ~20 ms
//! (non-blocking), then [`Supervisor::shutdown`].
//!
//! With dynamic scheduling on (`[scheduling] dynamic`, the default), every
//! `interval_ms` the supervisor samples executor load and each role's scheduler time, checks
//! the initial binding once every role has figures, and re-binds the fewest roles that
//! restore the latency budget ([`crate::rebind`]); a move is live ([`Supervisor::migrate`]:
//! every thread of the process, same pid). A running role that falls silent while stopped
//! or making no CPU progress is stalled: it is killed and its restart policy applies.
//!
//! Role processes get `prctl(PR_SET_PDEATHSIG, SIGKILL)`, so they never outlive the
//! supervisor. Linux delivers that signal when the **thread** that forked them ends, so
//! drive a supervisor from one long-lived thread (the one that calls `start` and `step`).
//! Each role runs in its own process group: a Ctrl-C in the terminal reaches only the
//! supervisor, which then stops the roles in order.

use crate::executors::{
    ExecutorRegistry, SchedTime, process_sched_time, process_state, process_threads,
};
use crate::ladder::{StepDirection, VariantLadder};
use crate::launch::{PlanError, PlannedRole, plan_launch};
use crate::rebind::{
    ExecutorLoad, RebindConfig, RebindPlan, RebindPolicy, RoleLoad, plan_fewest_moves,
};
use crate::restart::{RestartDecision, RestartPolicy, RoleExit, restart_decision};
use crate::workflow::{SchedulingSpec, Workflow};
use std::collections::VecDeque;

mod dynamic;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::bus::{
    BusError, ControlRequest, ControlServer, FlightBus, StatusBoardWriter, TypedSubscriber,
};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::LatencyWindow;
use aeris_schemas::{
    CommandKind, FixedText, MAX_ROLES, ReplyStage, RoleHeartbeat, RoleStatus, RoleStatusEntry,
    SupervisorReply, SupervisorStatus, topics,
};
use dynamic::{InitialProbes, ladder_config, rebind_config};
use std::fs::OpenOptions;
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Heartbeats per role kept for the latency percentiles.
pub const LATENCY_WINDOW: usize = 256;
/// Lines of a role's log quoted in errors.
pub const LOG_TAIL_LINES: usize = 8;
/// Lines of a failed swap's log quoted in its reply (the error a role prints is its last).
const SWAP_LOG_LINES: usize = 4;
/// Pause between steps inside [`Supervisor::wait_ready`].
const POLL: Duration = Duration::from_millis(20);
/// Pause between checks for exited roles during [`Supervisor::shutdown`].
const SHUTDOWN_POLL: Duration = Duration::from_millis(5);
/// How long a swapped-in process may take, by default, to load, warm up and report its
/// first heartbeat before the swap is rolled back.
pub const DEFAULT_SWAP_READY_TIMEOUT: Duration = Duration::from_secs(90);
/// How long a replaced process has to exit after SIGTERM before it gets SIGKILL.
pub const RETIRE_GRACE: Duration = Duration::from_secs(5);
/// Scheduling of a process the supervisor starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum LoadPolicy {
    /// The normal policy.
    Normal,
    /// SCHED_IDLE until the supervisor restores SCHED_OTHER: the new side of a swap loads
    /// and warms up (seconds of every core for a language model) only on CPU time the
    /// running role leaves idle, and never preempts it. Measured on the 2-core VM: a
    /// running SmolLM2 decision p50/p95 547/612 ms alone, 529/632 ms beside Gemma loading
    /// under SCHED_IDLE, 621/824 ms beside it at nice 19.
    IdleUntilReady,
}

/// What the supervisor needs to start a flight.
#[derive(Debug, Clone)]
pub struct SupervisorOptions {
    /// The validated workflow.
    pub workflow: Workflow,
    /// Flight name: the namespace of every service (`[a-z0-9_-]{1,48}`).
    pub flight: String,
    /// The `aeris` executable; roles start as `aeris_exe role --spec FILE`.
    pub aeris_exe: PathBuf,
    /// Directory for `roles/NAME.json` specs and `logs/NAME.log` logs (created if missing).
    pub run_dir: PathBuf,
    /// External autopilot MAVLink URL: drop the vehicle role and give this URL to the
    /// controller. `None` flies the built-in vehicle.
    pub autopilot: Option<String>,
}

/// Why the supervisor failed.
#[derive(Debug, thiserror::Error)]
pub enum SupervisorError {
    /// The flight could not be planned (flight name, workflow, vehicle link).
    #[error("cannot plan flight `{flight}`: {source}")]
    Plan {
        /// Flight name.
        flight: String,
        /// Why.
        source: PlanError,
    },
    /// The supervisor's iceoryx2 node, heartbeat subscriber or status board failed. A
    /// status board that already exists means another supervisor runs this flight.
    #[error(
        "supervisor of flight `{flight}`: {source} (is another supervisor running this flight? pick another flight name)"
    )]
    Bus {
        /// Flight name.
        flight: String,
        /// Why.
        source: BusError,
    },
    /// The run directory could not be prepared.
    #[error("cannot create run directory {path}: {source} (pass a writable --run-dir)")]
    RunDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A role spec could not be written.
    #[error("cannot write the spec of role `{role}` to {path}: {source}")]
    WriteSpec {
        /// Role name.
        role: String,
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A role's log could not be opened.
    #[error("cannot open the log of role `{role}` at {path}: {source}")]
    OpenLog {
        /// Role name.
        role: String,
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A role process could not be started.
    #[error(
        "cannot start role `{role}` as `{exe} role --spec {spec}`{cpus}: {source} (build the binary with `cargo build --bin aeris`)"
    )]
    Spawn {
        /// Role name.
        role: String,
        /// The executable.
        exe: PathBuf,
        /// The spec file.
        spec: PathBuf,
        /// " on CPUs X" when it was bound, else empty.
        cpus: String,
        /// Why.
        source: std::io::Error,
    },
    /// Waiting on a role process failed.
    #[error("cannot wait on role `{role}` (pid {pid}): {source}")]
    Wait {
        /// Role name.
        role: String,
        /// Its pid.
        pid: u32,
        /// Why.
        source: std::io::Error,
    },
    /// Some roles sent no heartbeat in time.
    #[error("{}", not_ready_text(.timeout, .silent))]
    NotReady {
        /// How long was waited.
        timeout: Duration,
        /// The silent roles with the tail of their logs.
        silent: Vec<SilentRole>,
    },
    /// While waiting for readiness, a role stopped for good (gave up, or exited under a
    /// policy that keeps it down).
    #[error("{}", role_down_text(.role, .state, .log_path, .log_tail))]
    RoleDown {
        /// Role name.
        role: String,
        /// What happened ("gave up after 5 restarts, last exit code 1").
        state: String,
        /// Its log.
        log_path: PathBuf,
        /// The last lines of its log.
        log_tail: Vec<String>,
    },
}

/// A role that stayed silent, for [`SupervisorError::NotReady`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SilentRole {
    /// Role name.
    pub name: String,
    /// Its state ("running pid 123", "restarting", ...).
    pub state: String,
    /// Its log file.
    pub log_path: PathBuf,
    /// The last lines of its log.
    pub log_tail: Vec<String>,
}

/// Why a hot swap was refused (the running process was not touched).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SwapError {
    /// No role of that name.
    #[error("the flight has no role `{role}` (roles: {known})")]
    UnknownRole {
        /// The name asked for.
        role: String,
        /// The flight's roles, comma-separated.
        known: String,
    },
    /// The role's kind cannot run twice at once.
    #[error("role `{role}` (kind `{kind}`) cannot be hot-swapped: {why}")]
    NotSwappable {
        /// Role name.
        role: String,
        /// Its kind.
        kind: String,
        /// Why (from the catalog).
        why: &'static str,
    },
    /// The variant is not in the role's pool.
    #[error(
        "role `{role}` has no variant `{variant}` in its pool [{pool}]; list it in the role's `variants` in the workflow"
    )]
    NotInPool {
        /// Role name.
        role: String,
        /// The variant asked for.
        variant: String,
        /// The pool, comma-separated.
        pool: String,
    },
    /// A swap of this role is already under way.
    #[error("role `{role}` is already being swapped to `{variant}`")]
    InProgress {
        /// Role name.
        role: String,
        /// The variant being brought up.
        variant: String,
    },
    /// The role has no running process to replace.
    #[error("role `{role}` is not running ({state}); a swap replaces a running process")]
    NotRunning {
        /// Role name.
        role: String,
        /// Its state.
        state: String,
    },
    /// The new process's spec or log could not be written.
    #[error("cannot prepare variant `{variant}` of role `{role}`: {reason}")]
    Prepare {
        /// Role name.
        role: String,
        /// The variant.
        variant: String,
        /// Why.
        reason: String,
    },
}

fn quote_tail(out: &mut String, tail: &[String]) {
    if tail.is_empty() {
        out.push_str("\n    (log is empty)");
    }
    for line in tail {
        out.push_str("\n    | ");
        out.push_str(line);
    }
}

fn not_ready_text(timeout: &Duration, silent: &[SilentRole]) -> String {
    let names: Vec<&str> = silent.iter().map(|s| s.name.as_str()).collect();
    let mut out = format!(
        "no heartbeat within {:.1} s from role(s) {}",
        timeout.as_secs_f64(),
        names.join(", ")
    );
    for s in silent {
        out.push_str(&format!(
            "\n  role `{}` ({}), log {}:",
            s.name,
            s.state,
            s.log_path.display()
        ));
        quote_tail(&mut out, &s.log_tail);
    }
    out
}

fn role_down_text(role: &str, state: &str, log_path: &Path, tail: &[String]) -> String {
    let mut out = format!(
        "role `{role}` {state}; it stays down, so the flight cannot start; log {}:",
        log_path.display()
    );
    quote_tail(&mut out, tail);
    out
}

/// Something that happened to a role during a [`Supervisor::step`].
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
    },
    /// The new process failed to come up; it was stopped and the old one keeps running.
    SwapFailed {
        /// Role name.
        name: String,
        /// The variant that failed.
        variant: String,
        /// Why, with the tail of the new process's log.
        reason: String,
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
    /// A service of the flight disappeared from under running roles (its files were
    /// removed from outside); the roles registered at it were killed so that their restarts
    /// create a fresh service and join it.
    ServiceLost {
        /// The service (relative to the flight).
        service: String,
        /// The roles killed, with the pids they had.
        roles: Vec<(String, u32)>,
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

/// Why a live move was refused (nothing was moved).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MigrateError {
    /// No role of that name.
    #[error("the flight has no role `{role}` (roles: {known})")]
    UnknownRole {
        /// The name asked for.
        role: String,
        /// The flight's roles, comma-separated.
        known: String,
    },
    /// The target is neither an executor nor a CPU list of this machine.
    #[error("`{target}` is neither an executor ({executors}) nor a usable CPU list: {reason}")]
    BadTarget {
        /// The target as given.
        target: String,
        /// Known executors, comma-separated.
        executors: String,
        /// Why the CPU list is unusable.
        reason: String,
    },
    /// The role has no running process.
    #[error("role `{role}` is not running ({state})")]
    NotRunning {
        /// Role name.
        role: String,
        /// Its state.
        state: String,
    },
    /// A hot swap of the role is under way.
    #[error("role `{role}` is being swapped; move it once the swap is done")]
    SwapInProgress {
        /// Role name.
        role: String,
    },
    /// The kernel refused the affinity (CPUs outside the supervisor's cpuset, no permission).
    #[error("cannot move role `{role}` (pid {pid}) to CPUs {cpus}: {reason}")]
    Affinity {
        /// Role name.
        role: String,
        /// Its pid.
        pid: u32,
        /// The CPUs.
        cpus: String,
        /// The kernel's answer.
        reason: String,
    },
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
            SupervisorEvent::SwapStarted {
                name,
                variant,
                new_pid,
                instance,
                ..
            } => write!(
                f,
                "role `{name}`: swap to `{variant}` started (pid {new_pid}, instance {instance})"
            ),
            SupervisorEvent::SwapReady {
                name,
                variant,
                new_pid,
                ready_ms,
                ..
            } => write!(
                f,
                "role `{name}`: `{variant}` (pid {new_pid}) is ready after {ready_ms} ms; stopping the old process"
            ),
            SupervisorEvent::SwapDone {
                name,
                variant,
                old_pid,
                exit,
            } => match (old_pid, exit) {
                (Some(pid), Some(e)) => write!(
                    f,
                    "role `{name}`: swap to `{variant}` done (old pid {pid} {e})"
                ),
                _ => write!(f, "role `{name}`: swap to `{variant}` done"),
            },
            SupervisorEvent::SwapFailed {
                name,
                variant,
                reason,
            } => write!(
                f,
                "role `{name}`: swap to `{variant}` rolled back, the old process keeps running: {reason}"
            ),
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

/// Where a role is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoleState {
    /// Its process runs.
    Running,
    /// Its process exited; it restarts at this instant.
    Backoff {
        /// When the restart is due.
        until: Instant,
    },
    /// Its process exited and the policy keeps it down (no failure).
    Stopped,
    /// Its restart budget is spent.
    GaveUp,
}

/// What the supervisor knows about one role.
#[derive(Debug)]
pub struct RoleRuntime {
    name: String,
    kind: String,
    variant: String,
    cpus: String,
    cpu_set: Option<CpuSet>,
    spec_path: PathBuf,
    log_path: PathBuf,
    policy: RestartPolicy,
    max_restarts: u32,
    backoff_ms: u64,
    child: Option<Child>,
    pid: Option<u32>,
    old_pids: Vec<u32>,
    state: RoleState,
    restarts: u32,
    last_exit: Option<RoleExit>,
    last_heartbeat: Option<RoleHeartbeat>,
    heartbeats: u64,
    incarnation_heartbeats: u64,
    heartbeat_gaps: u64,
    window: LatencyWindow,
    latency_ms: Option<[f64; 3]>,
    pool: Vec<String>,
    instance: u32,
    swap: Option<SwapInProgress>,
    executor: String,
    budget_ms: Option<f64>,
    migrations: u32,
    stalls: u32,
    binding: String,
    /// A `Running` heartbeat came from the current process (stall detection starts then).
    running: bool,
    /// When the last heartbeat of the current process arrived.
    heard_at: Option<Instant>,
    /// When the current process was started (or took over).
    started_at: Option<Instant>,
    /// Run + run-queue wait time of the process when its silence was first noticed.
    silence_probe: Option<u64>,
    /// Scheduler time samples, one per scheduling tick (newest last).
    sched: VecDeque<(Instant, SchedTime)>,
    /// Latencies of the last few worked cycles (the DS signal).
    recent: LatencyWindow,
    /// Its variant ladder, most capable first (empty: none).
    ladder: Vec<String>,
    /// Worked cycles reported by any of its processes (the ladder's cycle count).
    worked_cycles: u64,
    /// Latency (ms) of the newest worked cycle.
    last_cycle_ms: Option<f64>,
}

/// Worked cycles in a role's recent-latency window (the DS signal).
const RECENT_CYCLES: usize = 8;
/// Scheduler samples kept per role (the demand window).
const SCHED_SAMPLES: usize = 9;

/// The new side of a make-before-break swap, until its first heartbeat after warm-up.
#[derive(Debug)]
struct SwapInProgress {
    variant: String,
    spec_path: PathBuf,
    log_path: PathBuf,
    child: Child,
    pid: u32,
    instance: u32,
    started: Instant,
    deadline: Instant,
    ready: Option<RoleHeartbeat>,
}

/// A replaced process, asked to stop, until it exits.
#[derive(Debug)]
struct Retiring {
    name: String,
    variant: String,
    pid: u32,
    child: Child,
    since: Instant,
}

impl RoleRuntime {
    /// Role name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Role kind.
    pub fn kind(&self) -> &str {
        &self.kind
    }
    /// Variant it runs.
    pub fn variant(&self) -> &str {
        &self.variant
    }
    /// CPU list it is bound to ("" = unbound).
    pub fn cpus(&self) -> &str {
        &self.cpus
    }
    /// Pid of its running process.
    pub fn pid(&self) -> Option<u32> {
        self.pid
    }
    /// Its state.
    pub fn state(&self) -> RoleState {
        self.state
    }
    /// Restarts so far.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }
    /// How its last process ended.
    pub fn last_exit(&self) -> Option<RoleExit> {
        self.last_exit
    }
    /// The last valid heartbeat (with its counters).
    pub fn last_heartbeat(&self) -> Option<&RoleHeartbeat> {
        self.last_heartbeat.as_ref()
    }
    /// Heartbeats received from all its processes.
    pub fn heartbeats(&self) -> u64 {
        self.heartbeats
    }
    /// `true` once its running process sent a heartbeat (false while it is down).
    pub fn has_heartbeat(&self) -> bool {
        self.incarnation_heartbeats > 0
    }
    /// Heartbeat sequence gaps observed (one per discontinuity).
    pub fn heartbeat_gaps(&self) -> u64 {
        self.heartbeat_gaps
    }
    /// Cycle latency p50, p95, p99 (ms) over the last [`LATENCY_WINDOW`] cycles.
    pub fn latency_ms(&self) -> Option<[f64; 3]> {
        self.latency_ms
    }
    /// Cycles in the latency window.
    pub fn latency_samples(&self) -> usize {
        self.window.len()
    }
    /// Its spec file.
    pub fn spec_path(&self) -> &Path {
        &self.spec_path
    }
    /// Its log file.
    pub fn log_path(&self) -> &Path {
        &self.log_path
    }
    /// Variants it may be swapped to.
    pub fn pool(&self) -> &[String] {
        &self.pool
    }
    /// Instance number of its current process (0 before the first start).
    pub fn instance(&self) -> u32 {
        self.instance
    }
    /// The variant a swap is bringing up, if one is under way.
    pub fn swapping_to(&self) -> Option<&str> {
        self.swap.as_ref().map(|s| s.variant.as_str())
    }
    /// Name of its executor (empty = unbound).
    pub fn executor(&self) -> &str {
        &self.executor
    }
    /// Its latency budget (ms).
    pub fn budget_ms(&self) -> Option<f64> {
        self.budget_ms
    }
    /// Live moves so far.
    pub fn migrations(&self) -> u32 {
        self.migrations
    }
    /// Stalls detected so far.
    pub fn stalls(&self) -> u32 {
        self.stalls
    }
    /// Why it is bound where it is.
    pub fn binding(&self) -> &str {
        &self.binding
    }

    fn describe_state(&self) -> String {
        match (self.state, self.pid) {
            (RoleState::Running, Some(pid)) => format!("running, pid {pid}"),
            (RoleState::Running, None) => "running".into(),
            (RoleState::Backoff { .. }, _) => self.with_exit("waiting to restart"),
            (RoleState::Stopped, _) => self.with_exit("stopped"),
            (RoleState::GaveUp, _) => {
                self.with_exit(&format!("gave up after {} restart(s)", self.restarts))
            }
        }
    }

    fn with_exit(&self, what: &str) -> String {
        match self.last_exit {
            Some(e) => format!("{what}, last {e}"),
            None => what.to_string(),
        }
    }

    /// Forget what belonged to the previous process (a new one starts or took over).
    fn new_incarnation(&mut self) {
        self.running = false;
        self.heard_at = None;
        self.started_at = Some(Instant::now());
        self.silence_probe = None;
        self.sched.clear();
        self.recent = LatencyWindow::new(RECENT_CYCLES);
    }

    /// Record a heartbeat; returns `true` when it is the first of the current process.
    fn record(&mut self, hb: &RoleHeartbeat, status: RoleStatus) -> bool {
        let first = self.incarnation_heartbeats == 0;
        let same_process = self.last_heartbeat.is_some_and(|l| l.pid == hb.pid);
        if let Some(last) = &self.last_heartbeat
            && same_process
            && hb.seq > last.seq + 1
        {
            self.heartbeat_gaps += 1;
        }
        // Only a heartbeat that closes a working cycle carries new figures; a liveness
        // heartbeat repeats the last ones and must not be counted twice.
        let working = matches!(status, RoleStatus::Running | RoleStatus::Degraded);
        if working && hb.worked == 1 {
            let ms = hb.cycle_latency_ns as f64 / 1e6;
            self.window.push(ms);
            self.recent.push(ms);
            self.worked_cycles += 1;
            self.last_cycle_ms = Some(ms);
            self.latency_ms = self.window.percentiles([50.0, 95.0, 99.0]);
        }
        self.running |= working;
        self.heard_at = Some(Instant::now());
        self.silence_probe = None;
        self.last_heartbeat = Some(*hb);
        self.heartbeats += 1;
        self.incarnation_heartbeats += 1;
        first
    }
}

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

/// Order in which shutdown stops kinds: reasoning first, controller and vehicle last.
fn shutdown_rank(kind: &str) -> u8 {
    match kind {
        "reasoning" => 0,
        "perception" | "camera" => 1,
        "controller" => 3,
        "vehicle" => 4,
        _ => 2,
    }
}

/// The supervisor of one flight.
pub struct Supervisor {
    roles: Vec<RoleRuntime>,
    flight: String,
    aeris_exe: PathBuf,
    run_dir: PathBuf,
    heartbeats: TypedSubscriber<RoleHeartbeat>,
    board: StatusBoardWriter,
    status: SupervisorStatus,
    pending: Vec<SupervisorEvent>,
    invalid_heartbeats: u64,
    unknown_heartbeats: u64,
    next_instance: u32,
    retiring: Vec<Retiring>,
    control: ControlServer,
    requests: Vec<(String, ControlRequest, Instant)>,
    bus: FlightBus,
    registry: ExecutorRegistry,
    scheduling: SchedulingSpec,
    idle_heartbeat_ms: u64,
    policy: RebindPolicy,
    ladder: VariantLadder,
    variant_steps: u32,
    next_tick: Instant,
    initial_checked: bool,
    /// Scheduling ticks the initial check has waited for roles' first cycles.
    initial_wait_ticks: u32,
    /// The initial binding's probes, while they run.
    probes: Option<InitialProbes>,
    migrations: u32,
    next_audit: Instant,
    known_services: Vec<(String, Vec<(String, u32)>)>,
}

impl core::fmt::Debug for Supervisor {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Supervisor")
            .field("flight", &self.flight)
            .field("roles", &self.roles)
            .finish()
    }
}

/// Open (append) a role's log and write `header` to it.
fn open_log(log: &Path, header: &str) -> std::io::Result<std::fs::File> {
    let mut file = OpenOptions::new().create(true).append(true).open(log)?;
    writeln!(file, "{header}")?;
    Ok(file)
}

/// Start `exe role --spec SPEC --instance N` with stdout and stderr appended to `log`.
fn spawn_role(
    exe: &Path,
    spec: &Path,
    instance: u32,
    log: std::fs::File,
    cpus: Option<&CpuSet>,
    policy: LoadPolicy,
) -> std::io::Result<Child> {
    let file = log;
    let err = file.try_clone()?;
    let mut cmd = Command::new(exe);
    cmd.arg("role")
        .arg("--spec")
        .arg(spec)
        .arg("--instance")
        .arg(instance.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::from(file))
        .stderr(Stdio::from(err))
        .process_group(0);
    // SAFETY: getpid has no preconditions.
    let parent = unsafe { libc::getpid() };
    let cpus = cpus.cloned();
    // SAFETY: the closure only makes async-signal-safe system calls (prctl, getppid,
    // sched_setaffinity, sched_setscheduler, close_range/fcntl) and does not allocate: CpuSet::bind_task builds the mask on the
    // stack and io::Error::last_os_error / from_raw_os_error do not allocate.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(
                libc::PR_SET_PDEATHSIG,
                libc::SIGKILL as libc::c_ulong,
                0 as libc::c_ulong,
                0 as libc::c_ulong,
                0 as libc::c_ulong,
            ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            // The supervisor died between fork and prctl: do not run orphaned.
            if libc::getppid() != parent {
                return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
            }
            if let Some(set) = &cpus {
                set.bind_task(0)?;
            }
            // the policy is per thread on Linux; threads the role starts inherit it
            if policy == LoadPolicy::IdleUntilReady {
                let param = libc::sched_param { sched_priority: 0 };
                if libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
            }
            close_inherited_fds();
            Ok(())
        });
    }
    cmd.spawn()
}

/// Mark every descriptor above stderr close-on-exec, so a role does not inherit the
/// supervisor's iceoryx2 node locks and shared-memory handles (which would keep a dead
/// supervisor's node looking alive). Closing is left to exec: std's error-report pipe must
/// stay open until then. Runs between fork and exec: async-signal-safe, no allocation.
fn close_inherited_fds() {
    // SAFETY: close_range only changes descriptor flags of this (forked) process.
    let rc = unsafe {
        libc::syscall(
            libc::SYS_close_range,
            3 as libc::c_uint,
            libc::c_uint::MAX,
            libc::CLOSE_RANGE_CLOEXEC,
        )
    };
    if rc == 0 {
        return;
    }
    // Kernels before 5.11: one by one, up to the descriptor limit.
    // SAFETY: a zeroed rlimit is valid; getrlimit fills it.
    let mut lim: libc::rlimit = unsafe { core::mem::zeroed() };
    // SAFETY: `lim` is writable.
    let max = if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } == 0 {
        lim.rlim_cur.min(65_536) as libc::c_int
    } else {
        1024
    };
    for fd in 3..max {
        // SAFETY: fcntl on a descriptor number that may or may not be open is harmless.
        unsafe {
            let flags = libc::fcntl(fd, libc::F_GETFD);
            if flags >= 0 && flags & libc::FD_CLOEXEC == 0 {
                libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC);
            }
        }
    }
}

/// `true` when this process may move a thread from SCHED_IDLE back to SCHED_OTHER (root,
/// or an RLIMIT_NICE that allows nice 0): only then does a swap start its new process idle.
fn may_leave_idle() -> bool {
    // SAFETY: geteuid has no preconditions.
    if unsafe { libc::geteuid() } == 0 {
        return true;
    }
    // SAFETY: a zeroed rlimit is valid; getrlimit fills it.
    let mut lim: libc::rlimit = unsafe { core::mem::zeroed() };
    // SAFETY: `lim` is writable. RLIMIT_NICE 20 allows nice 0 (the limit is 20 - nice).
    unsafe { libc::getrlimit(libc::RLIMIT_NICE, &mut lim) == 0 && lim.rlim_cur >= 20 }
}

/// Put every thread of `pid` under SCHED_OTHER (the policy is per thread on Linux). Best
/// effort: a thread that exits meanwhile, or a refusal, leaves the others as they are.
fn set_normal_policy(pid: u32) {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return;
    };
    let param = libc::sched_param { sched_priority: 0 };
    for task in tasks.flatten() {
        if let Some(tid) = task
            .file_name()
            .to_str()
            .and_then(|t| t.parse::<libc::pid_t>().ok())
        {
            // SAFETY: `param` is valid; a thread id that vanished only makes this fail.
            unsafe { libc::sched_setscheduler(tid, libc::SCHED_OTHER, &param) };
        }
    }
}

/// The last `lines` lines of a file (reads at most its last 16 KiB); empty when unreadable.
pub fn log_tail(path: &Path, lines: usize) -> Vec<String> {
    let Ok(mut f) = std::fs::File::open(path) else {
        return Vec::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let start = len.saturating_sub(16 * 1024);
    if f.seek(SeekFrom::Start(start)).is_err() {
        return Vec::new();
    }
    let mut buf = Vec::new();
    if f.read_to_end(&mut buf).is_err() {
        return Vec::new();
    }
    let text = String::from_utf8_lossy(&buf);
    let all: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    // the first line may be cut when we did not read from the start
    let skip_first = usize::from(start > 0 && all.len() > lines);
    let from = all.len().saturating_sub(lines).max(skip_first);
    all[from..].iter().map(|l| l.to_string()).collect()
}

fn supervisor_pid() -> u32 {
    std::process::id()
}

impl Supervisor {
    /// Plan the flight, open the bus (publishing the flight manifest), the status board and
    /// the heartbeat subscriber, write every role's spec and start every role in dependency
    /// order. On error, roles already started are killed.
    pub fn start(options: SupervisorOptions) -> Result<Supervisor, SupervisorError> {
        let SupervisorOptions {
            workflow,
            flight,
            aeris_exe,
            run_dir,
            autopilot,
        } = options;
        let online = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
        let scheduling = workflow.scheduling;
        let idle_heartbeat_ms = workflow.timing.idle_heartbeat_ms;
        let plan = plan_launch(
            &workflow,
            &flight,
            autopilot.as_deref(),
            &online,
            crate::launch::free_udp_port,
        )
        .map_err(|source| SupervisorError::Plan {
            flight: flight.clone(),
            source,
        })?;
        let mut plan = plan;
        // A restarted simulated vehicle resumes from its last checkpoint instead of
        // teleporting back to the start.
        for r in plan.roles.iter_mut().filter(|r| r.spec.kind == "vehicle") {
            if !r.spec.params.contains_key("state_file") {
                let path = run_dir.join(format!("{}.state", r.spec.name));
                r.spec
                    .params
                    .insert("state_file".into(), path.display().to_string().into());
            }
        }
        // each role's ladder length and starting rung (its declared variant)
        let ladders: Vec<(usize, usize)> = plan
            .roles
            .iter()
            .map(|r| {
                let start = r.ladder.iter().position(|v| *v == r.spec.variant);
                (r.ladder.len(), start.unwrap_or(usize::MAX))
            })
            .collect();
        let bus_err = |source| SupervisorError::Bus {
            flight: flight.clone(),
            source,
        };
        let bus = FlightBus::builder(&flight)
            .node_name("supervisor")
            .create()
            .map_err(bus_err)?;
        let heartbeats = bus
            .subscriber::<RoleHeartbeat>(topics::HEARTBEAT)
            .map_err(bus_err)?;
        let board = bus.create_status_board().map_err(bus_err)?;
        let control = bus.control_server().map_err(bus_err)?;

        let roles_dir = run_dir.join("roles");
        let logs_dir = run_dir.join("logs");
        for dir in [&roles_dir, &logs_dir] {
            std::fs::create_dir_all(dir).map_err(|source| SupervisorError::RunDir {
                path: dir.clone(),
                source,
            })?;
        }

        let mut sup = Supervisor {
            roles: Vec::with_capacity(plan.roles.len()),
            flight: flight.clone(),
            aeris_exe,
            run_dir,
            heartbeats,
            board,
            status: SupervisorStatus {
                supervisor_pid: supervisor_pid(),
                subgoals: workflow.mission.subgoals.len().min(u16::MAX as usize) as u16,
                ..SupervisorStatus::default()
            },
            pending: Vec::new(),
            invalid_heartbeats: 0,
            unknown_heartbeats: 0,
            next_instance: 1,
            retiring: Vec::new(),
            control,
            requests: Vec::new(),
            bus,
            registry: ExecutorRegistry::discover(&plan.executors, &online),
            policy: RebindPolicy::new(rebind_config(&scheduling), plan.roles.len()),
            ladder: VariantLadder::new(ladder_config(&scheduling), &ladders),
            variant_steps: 0,
            scheduling,
            idle_heartbeat_ms,
            next_tick: Instant::now(),
            initial_checked: false,
            initial_wait_ticks: 0,
            probes: None,
            migrations: 0,
            next_audit: Instant::now(),
            known_services: Vec::new(),
        };
        for planned in plan.roles {
            sup.add_role(planned, &roles_dir, &logs_dir)?;
        }
        for i in 0..sup.roles.len() {
            let pid = sup.spawn(i, "start")?;
            sup.pending.push(SupervisorEvent::RoleStarted {
                name: sup.roles[i].name.clone(),
                pid,
            });
        }
        sup.publish_board();
        Ok(sup)
    }

    fn add_role(
        &mut self,
        planned: PlannedRole,
        roles_dir: &Path,
        logs_dir: &Path,
    ) -> Result<(), SupervisorError> {
        let PlannedRole {
            spec,
            cpus,
            executor,
            budget_ms,
            restart,
            max_restarts,
            backoff_ms,
            pool,
            ladder,
        } = planned;
        let spec_path = roles_dir.join(format!("{}.json", spec.name));
        let log_path = logs_dir.join(format!("{}.log", spec.name));
        let json = serde_json::to_string_pretty(&spec).map_err(|e| SupervisorError::WriteSpec {
            role: spec.name.clone(),
            path: spec_path.clone(),
            source: std::io::Error::other(e),
        })?;
        std::fs::write(&spec_path, json).map_err(|source| SupervisorError::WriteSpec {
            role: spec.name.clone(),
            path: spec_path.clone(),
            source,
        })?;
        self.roles.push(RoleRuntime {
            name: spec.name,
            kind: spec.kind,
            variant: spec.variant,
            cpus: spec.cpus,
            cpu_set: cpus,
            spec_path,
            log_path,
            policy: restart,
            max_restarts,
            backoff_ms,
            child: None,
            pid: None,
            old_pids: Vec::new(),
            state: RoleState::Stopped,
            restarts: 0,
            last_exit: None,
            last_heartbeat: None,
            heartbeats: 0,
            incarnation_heartbeats: 0,
            heartbeat_gaps: 0,
            window: LatencyWindow::new(LATENCY_WINDOW),
            latency_ms: None,
            pool,
            instance: 0,
            swap: None,
            binding: match &executor {
                Some(e) => format!("declared: executor `{e}`"),
                None => "unbound: the supervisor's CPUs".into(),
            },
            executor: executor.unwrap_or_default(),
            budget_ms,
            migrations: 0,
            stalls: 0,
            running: false,
            heard_at: None,
            started_at: None,
            silence_probe: None,
            sched: VecDeque::with_capacity(SCHED_SAMPLES),
            recent: LatencyWindow::new(RECENT_CYCLES),
            ladder,
            worked_cycles: 0,
            last_cycle_ms: None,
        });
        Ok(())
    }

    /// Start role `i`'s process; returns its pid.
    fn spawn(&mut self, i: usize, why: &str) -> Result<u32, SupervisorError> {
        let exe = self.aeris_exe.clone();
        let instance = self.next_instance;
        let Some(role) = self.roles.get_mut(i) else {
            return Err(SupervisorError::Spawn {
                role: format!("#{i}"),
                exe,
                spec: PathBuf::new(),
                cpus: String::new(),
                source: std::io::Error::other("no such role"),
            });
        };
        let header = format!(
            "=== aeris supervisor: {why} role `{}` ({} / {}) instance {instance} on CPUs [{}], monotonic {} ns ===",
            role.name,
            role.kind,
            role.variant,
            role.cpus,
            monotonic_ns()
        );
        let log = open_log(&role.log_path, &header).map_err(|source| SupervisorError::OpenLog {
            role: role.name.clone(),
            path: role.log_path.clone(),
            source,
        })?;
        match spawn_role(
            &exe,
            &role.spec_path,
            instance,
            log,
            role.cpu_set.as_ref(),
            LoadPolicy::Normal,
        ) {
            Ok(child) => {
                self.next_instance += 1;
                let pid = child.id();
                role.instance = instance;
                role.child = Some(child);
                role.pid = Some(pid);
                role.state = RoleState::Running;
                role.incarnation_heartbeats = 0;
                role.new_incarnation();
                // a new process: its first cycles load and warm up
                self.ladder.settle(i);
                Ok(pid)
            }
            Err(source) => Err(SupervisorError::Spawn {
                role: role.name.clone(),
                exe,
                spec: role.spec_path.clone(),
                cpus: if role.cpus.is_empty() {
                    String::new()
                } else {
                    format!(" on CPUs {}", role.cpus)
                },
                source,
            }),
        }
    }

    /// One non-blocking round: drain heartbeats, reap exited roles and apply their restart
    /// policy, start due restarts, update the status board. Call it every ~20 ms.
    pub fn step(&mut self) -> Result<Vec<SupervisorEvent>, SupervisorError> {
        let mut events = core::mem::take(&mut self.pending);
        self.serve_control(&mut events)?;
        self.drain_heartbeats(&mut events)?;
        self.reap(&mut events)?;
        self.detect_stalls(&mut events);
        let before = events.len();
        self.advance_swaps(&mut events);
        self.ladder_follow_swaps(&events[before..]);
        self.reap_retiring(&mut events);
        self.restart_due(&mut events);
        self.schedule(&mut events);
        self.audit_services(&mut events);
        self.answer_requests(&events);
        self.publish_board();
        Ok(events)
    }

    fn drain_heartbeats(
        &mut self,
        events: &mut Vec<SupervisorEvent>,
    ) -> Result<(), SupervisorError> {
        loop {
            let hb = match self.heartbeats.next() {
                Ok(Some(hb)) => hb,
                Ok(None) => return Ok(()),
                Err(source) => return Err(self.bus_error(source)),
            };
            let Ok(status) = hb.validate() else {
                self.invalid_heartbeats += 1;
                continue;
            };
            let name = hb.role.as_str().unwrap_or("");
            let Some(role) = self.roles.iter_mut().find(|r| r.name == name) else {
                self.unknown_heartbeats += 1;
                continue;
            };
            if let Some(swap) = role.swap.as_mut()
                && swap.pid == hb.pid
            {
                // the new side of a swap is ready with its first heartbeat after loading
                // and warming up (`Starting` is sent before the role is built)
                if matches!(status, RoleStatus::Running | RoleStatus::Degraded)
                    && swap.ready.is_none()
                {
                    swap.ready = Some(hb);
                }
                continue;
            }
            if role.old_pids.contains(&hb.pid) {
                continue; // late heartbeat of a process that already exited
            }
            if role.record(&hb, status) {
                events.push(SupervisorEvent::FirstHeartbeat {
                    name: role.name.clone(),
                });
            }
        }
    }

    fn reap(&mut self, events: &mut Vec<SupervisorEvent>) -> Result<(), SupervisorError> {
        let now = Instant::now();
        let mut exited = false;
        for role in &mut self.roles {
            let Some(child) = role.child.as_mut() else {
                continue;
            };
            let status = match child.try_wait() {
                Ok(Some(status)) => status,
                Ok(None) => continue,
                Err(source) => {
                    return Err(SupervisorError::Wait {
                        role: role.name.clone(),
                        pid: child.id(),
                        source,
                    });
                }
            };
            let exit = RoleExit::from_status(status);
            if let Some(pid) = role.pid.take() {
                role.old_pids.push(pid);
            }
            role.child = None;
            role.last_exit = Some(exit);
            role.incarnation_heartbeats = 0;
            role.new_incarnation();
            exited = true;
            events.push(SupervisorEvent::RoleExited {
                name: role.name.clone(),
                status: exit,
            });
            role.state = match restart_decision(
                role.policy,
                exit,
                role.restarts,
                role.max_restarts,
                role.backoff_ms,
            ) {
                RestartDecision::Stay => RoleState::Stopped,
                RestartDecision::Restart { after } => RoleState::Backoff { until: now + after },
                RestartDecision::GiveUp => {
                    events.push(SupervisorEvent::RoleGaveUp {
                        name: role.name.clone(),
                    });
                    RoleState::GaveUp
                }
            };
        }
        if exited {
            // a dead process cannot remove its own iceoryx2 node and ports: do it now, not
            // only when its replacement starts (a role kept down has none)
            aeris_runtime::bus::cleanup_dead_nodes();
        }
        Ok(())
    }

    fn restart_due(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        for i in 0..self.roles.len() {
            let RoleState::Backoff { until } = self.roles[i].state else {
                continue;
            };
            if now < until {
                continue;
            }
            self.roles[i].restarts += 1;
            let name = self.roles[i].name.clone();
            match self.spawn(i, "restart") {
                Ok(pid) => events.push(SupervisorEvent::RoleRestarted {
                    name,
                    pid,
                    restarts: self.roles[i].restarts,
                }),
                Err(e) => {
                    events.push(SupervisorEvent::RestartFailed {
                        name: name.clone(),
                        reason: e.to_string(),
                    });
                    let role = &mut self.roles[i];
                    let exit = role.last_exit.unwrap_or(RoleExit::Code(-1));
                    role.state = match restart_decision(
                        RestartPolicy::Always,
                        exit,
                        role.restarts,
                        role.max_restarts,
                        role.backoff_ms,
                    ) {
                        RestartDecision::Restart { after } => {
                            RoleState::Backoff { until: now + after }
                        }
                        _ => {
                            events.push(SupervisorEvent::RoleGaveUp { name });
                            RoleState::GaveUp
                        }
                    };
                }
            }
        }
    }

    fn publish_board(&mut self) {
        let s = &mut self.status;
        s.seq += 1;
        s.stamp_ns = monotonic_ns();
        s.role_count = self.roles.len().min(MAX_ROLES) as u32;
        for (entry, role) in s.roles.iter_mut().zip(self.roles.iter()) {
            let hb = role.last_heartbeat.as_ref();
            let lat = role.latency_ms.unwrap_or([0.0; 3]);
            *entry = RoleStatusEntry {
                name: FixedText::from_str_truncated(&role.name),
                variant: FixedText::from_str_truncated(&role.variant),
                cpus: FixedText::from_str_truncated(&role.cpus),
                pid: role.pid.unwrap_or(0),
                status: hb.map(|h| h.status).unwrap_or(0),
                reserved: [0; 3],
                last_heartbeat_ns: hb.map(|h| h.stamp_ns).unwrap_or(0),
                heartbeats: role.heartbeats,
                latency_ms: [lat[0] as f32, lat[1] as f32, lat[2] as f32],
                restarts: role.restarts,
                heartbeat_gaps: role.heartbeat_gaps.min(u32::MAX as u64) as u32,
                executor: FixedText::from_str_truncated(&role.executor),
                budget_ms: role.budget_ms.unwrap_or(0.0) as f32,
                migrations: role.migrations,
                stalls: role.stalls,
                reserved2: 0,
                binding: FixedText::from_str_truncated(&role.binding),
            };
        }
        s.migrations = self.migrations;
        self.board.update(&self.status);
    }

    /// Step until every role has sent a heartbeat from its current process. Events seen
    /// meanwhile are returned by the next [`Supervisor::step`]. Fails at once when a role
    /// stops for good, and after `timeout` naming the silent roles with their log tails.
    pub fn wait_ready(&mut self, timeout: Duration) -> Result<(), SupervisorError> {
        let deadline = Instant::now() + timeout;
        loop {
            let events = self.step()?;
            self.pending.extend(events);
            if let Some(role) = self.roles.iter().find(|r| {
                !r.has_heartbeat() && matches!(r.state, RoleState::GaveUp | RoleState::Stopped)
            }) {
                return Err(SupervisorError::RoleDown {
                    role: role.name.clone(),
                    state: role.describe_state(),
                    log_path: role.log_path.clone(),
                    log_tail: log_tail(&role.log_path, LOG_TAIL_LINES),
                });
            }
            if self.roles.iter().all(RoleRuntime::has_heartbeat) {
                return Ok(());
            }
            if Instant::now() >= deadline {
                let silent = self
                    .roles
                    .iter()
                    .filter(|r| !r.has_heartbeat())
                    .map(|r| SilentRole {
                        name: r.name.clone(),
                        state: r.describe_state(),
                        log_path: r.log_path.clone(),
                        log_tail: log_tail(&r.log_path, LOG_TAIL_LINES),
                    })
                    .collect();
                return Err(SupervisorError::NotReady { timeout, silent });
            }
            std::thread::sleep(POLL);
        }
    }

    /// Start replacing role `role` by `variant`, make-before-break: a new process (a new
    /// instance number) loads and warms up beside the running one, under SCHED_IDLE so it
    /// takes only idle CPU; with its first heartbeat it becomes the role (normal policy
    /// restored) and the
    /// old process is stopped
    /// ([`SupervisorEvent::SwapReady`], then [`SupervisorEvent::SwapDone`]). If it exits
    /// first, or sends no heartbeat within `ready_timeout`, it is stopped and the old process
    /// keeps running ([`SupervisorEvent::SwapFailed`]). Returns the new pid.
    pub fn begin_swap(
        &mut self,
        role: &str,
        variant: &str,
        ready_timeout: Duration,
    ) -> Result<u32, SwapError> {
        self.start_swap(role, variant, ready_timeout, true)
    }

    /// [`Supervisor::begin_swap`], with the new process loading idle (`load_idle`) or at
    /// the normal policy. The variant ladder loads a lighter variant at the normal policy:
    /// the role it replaces already misses its budget, so the CPUs are saturated, and an
    /// idle load gets no CPU at all (measured: SmolLM2 stepping in for Gemma-3 on 2 busy
    /// CPUs was not ready within 90 s and the step was rolled back).
    pub(crate) fn start_swap(
        &mut self,
        role: &str,
        variant: &str,
        ready_timeout: Duration,
        load_idle: bool,
    ) -> Result<u32, SwapError> {
        let Some(i) = self.roles.iter().position(|r| r.name == role) else {
            return Err(SwapError::UnknownRole {
                role: role.to_string(),
                known: self.role_names(),
            });
        };
        let instance = self.next_instance;
        let exe = self.aeris_exe.clone();
        let r = &mut self.roles[i];
        let refusal = aeris_runtime::catalog::role_kind(&r.kind)
            .map_or(Some("unknown kind"), |k| k.swap_refusal);
        if let Some(why) = refusal {
            return Err(SwapError::NotSwappable {
                role: r.name.clone(),
                kind: r.kind.clone(),
                why,
            });
        }
        if !r.pool.iter().any(|v| v == variant) {
            return Err(SwapError::NotInPool {
                role: r.name.clone(),
                variant: variant.to_string(),
                pool: r.pool.join(", "),
            });
        }
        if let Some(s) = &r.swap {
            return Err(SwapError::InProgress {
                role: r.name.clone(),
                variant: s.variant.clone(),
            });
        }
        if r.state != RoleState::Running || r.child.is_none() {
            return Err(SwapError::NotRunning {
                role: r.name.clone(),
                state: r.describe_state(),
            });
        }
        let prepare = |reason: String| SwapError::Prepare {
            role: role.to_string(),
            variant: variant.to_string(),
            reason,
        };
        let mut spec =
            aeris_runtime::RoleSpec::load(&r.spec_path).map_err(|e| prepare(e.to_string()))?;
        spec.variant = variant.to_string();
        let dir = r.spec_path.parent().unwrap_or(Path::new("."));
        let spec_path = dir.join(format!("{}.i{instance}.json", r.name));
        let json = serde_json::to_string_pretty(&spec).map_err(|e| prepare(e.to_string()))?;
        std::fs::write(&spec_path, json)
            .map_err(|e| prepare(format!("{}: {e}", spec_path.display())))?;
        let log_dir = r.log_path.parent().unwrap_or(Path::new("."));
        let log_path = log_dir.join(format!("{}.i{instance}.log", r.name));
        let header = format!(
            "=== aeris supervisor: hot swap of role `{}` from `{}` to `{variant}`, instance {instance} on CPUs [{}], monotonic {} ns ===",
            r.name,
            r.variant,
            r.cpus,
            monotonic_ns()
        );
        let cleanup = |e: String| {
            let _ = std::fs::remove_file(&spec_path);
            prepare(e)
        };
        let log = open_log(&log_path, &header)
            .map_err(|e| cleanup(format!("{}: {e}", log_path.display())))?;
        let policy = if load_idle && may_leave_idle() {
            LoadPolicy::IdleUntilReady
        } else {
            LoadPolicy::Normal
        };
        let child = spawn_role(&exe, &spec_path, instance, log, r.cpu_set.as_ref(), policy)
            .map_err(|e| cleanup(format!("cannot start `{}`: {e}", exe.display())))?;
        self.next_instance += 1;
        let pid = child.id();
        let now = Instant::now();
        r.swap = Some(SwapInProgress {
            variant: variant.to_string(),
            spec_path,
            log_path,
            child,
            pid,
            instance,
            started: now,
            deadline: now + ready_timeout,
            ready: None,
        });
        self.pending.push(SupervisorEvent::SwapStarted {
            name: r.name.clone(),
            variant: variant.to_string(),
            old_pid: r.pid,
            new_pid: pid,
            instance,
        });
        Ok(pid)
    }

    /// Commit swaps whose new process works, roll back those whose new process died or
    /// timed out.
    fn advance_swaps(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        for role in &mut self.roles {
            let Some(swap) = role.swap.as_mut() else {
                continue;
            };
            let failure = match swap.child.try_wait() {
                Ok(Some(status)) => Some(format!(
                    "the new process exited ({}) before it was ready",
                    RoleExit::from_status(status)
                )),
                Err(e) => Some(format!("cannot wait on the new process: {e}")),
                Ok(None) if swap.ready.is_some() => None,
                Ok(None) if now >= swap.deadline => Some(format!(
                    "not ready (loaded, warmed up, first heartbeat) within {:.0} s",
                    (swap.deadline - swap.started).as_secs_f64()
                )),
                Ok(None) => continue,
            };
            let Some(swap) = role.swap.take() else {
                continue;
            };
            if let Some(why) = failure {
                let mut child = swap.child;
                let _ = child.kill();
                let _ = child.wait();
                role.old_pids.push(swap.pid);
                let _ = std::fs::remove_file(&swap.spec_path);
                let mut reason = format!("{why}; its log {}:", swap.log_path.display());
                quote_tail(&mut reason, &log_tail(&swap.log_path, SWAP_LOG_LINES));
                events.push(SupervisorEvent::SwapFailed {
                    name: role.name.clone(),
                    variant: swap.variant,
                    reason,
                });
                continue;
            }
            // commit: the new process is the role (normal policy back, on every thread)
            set_normal_policy(swap.pid);
            let old_pid = role.pid.take();
            let old_child = role.child.take();
            role.variant = swap.variant.clone();
            role.child = Some(swap.child);
            role.pid = Some(swap.pid);
            role.instance = swap.instance;
            role.spec_path = swap.spec_path;
            role.log_path = swap.log_path;
            role.state = RoleState::Running;
            role.last_heartbeat = swap.ready;
            role.heartbeats += 1;
            role.incarnation_heartbeats = 1;
            role.new_incarnation();
            role.running = true;
            role.heard_at = Some(now);
            // a new model: its latency is a new distribution
            role.window = LatencyWindow::new(LATENCY_WINDOW);
            role.latency_ms = None;
            events.push(SupervisorEvent::SwapReady {
                name: role.name.clone(),
                variant: swap.variant.clone(),
                old_pid,
                new_pid: swap.pid,
                instance: swap.instance,
                ready_ms: swap.started.elapsed().as_millis() as u64,
            });
            // then stop the old one; the swap is done when it has exited
            let Some(mut old) = old_child else {
                events.push(SupervisorEvent::SwapDone {
                    name: role.name.clone(),
                    variant: swap.variant,
                    old_pid: None,
                    exit: None,
                });
                continue;
            };
            let pid = old.id();
            role.old_pids.push(pid);
            if let Ok(raw) = libc::pid_t::try_from(pid) {
                // SAFETY: kill has no memory-safety preconditions; the pid is our unreaped
                // child, so it cannot have been reused.
                unsafe { libc::kill(raw, libc::SIGTERM) };
            }
            match old.try_wait() {
                Ok(None) => self.retiring.push(Retiring {
                    name: role.name.clone(),
                    variant: swap.variant,
                    pid,
                    child: old,
                    since: now,
                }),
                exited => events.push(SupervisorEvent::SwapDone {
                    name: role.name.clone(),
                    variant: swap.variant,
                    old_pid: Some(pid),
                    exit: exited.ok().flatten().map(RoleExit::from_status),
                }),
            }
        }
    }

    /// Reap replaced processes; SIGKILL those still running after [`RETIRE_GRACE`].
    fn reap_retiring(&mut self, events: &mut Vec<SupervisorEvent>) {
        let mut i = 0;
        while i < self.retiring.len() {
            let r = &mut self.retiring[i];
            let exit = match r.child.try_wait() {
                Ok(Some(status)) => Some(RoleExit::from_status(status)),
                Ok(None) if r.since.elapsed() < RETIRE_GRACE => None,
                _ => {
                    let _ = r.child.kill();
                    r.child.wait().ok().map(RoleExit::from_status)
                }
            };
            match exit {
                None => i += 1,
                Some(exit) => {
                    let r = self.retiring.swap_remove(i);
                    events.push(SupervisorEvent::SwapDone {
                        name: r.name,
                        variant: r.variant,
                        old_pid: Some(r.pid),
                        exit: Some(exit),
                    });
                }
            }
        }
    }

    /// A transport failure of this supervisor's node.
    fn bus_error(&self, source: BusError) -> SupervisorError {
        SupervisorError::Bus {
            flight: self.flight.clone(),
            source,
        }
    }

    /// Take the commands waiting on `supervisor/control`.
    fn serve_control(&mut self, events: &mut Vec<SupervisorEvent>) -> Result<(), SupervisorError> {
        loop {
            let request = match self.control.receive() {
                Ok(Some(r)) => r,
                Ok(None) => return Ok(()),
                Err(source) => return Err(self.bus_error(source)),
            };
            let command = *request.payload();
            let role = command.role.as_str_lossy().to_string();
            let variant = command.target.as_str_lossy().to_string();
            let reply = match CommandKind::from_u8(command.kind) {
                None => SupervisorReply::new(
                    ReplyStage::Failed,
                    &format!("unknown command kind {}", command.kind),
                ),
                Some(CommandKind::Swap) => {
                    let timeout = match command.ready_timeout_ms {
                        0 => DEFAULT_SWAP_READY_TIMEOUT,
                        ms => Duration::from_millis(ms as u64),
                    };
                    match self.begin_swap(&role, &variant, timeout) {
                        Ok(_) => {
                            // the SwapStarted event answers it below
                            events.append(&mut self.pending);
                            self.requests.push((role, request, Instant::now()));
                            continue;
                        }
                        Err(e) => SupervisorReply::new(ReplyStage::Failed, &e.to_string()),
                    }
                }
                Some(CommandKind::Migrate) => match self.migrate(&role, &variant) {
                    Ok(m) => {
                        let mut r = SupervisorReply::new(
                            ReplyStage::Done,
                            &SupervisorEvent::RoleMigrated(m.clone()).to_string(),
                        );
                        r.old_pid = m.pid;
                        r.new_pid = m.pid;
                        r.elapsed_ms = m.took_us / 1000;
                        events.append(&mut self.pending);
                        r
                    }
                    Err(e) => SupervisorReply::new(ReplyStage::Failed, &e.to_string()),
                },
            };
            let _ = self.control.reply(&request, &reply);
        }
    }

    /// Forward swap events to the clients that asked for the swap; a final reply ends the
    /// request.
    fn answer_requests(&mut self, events: &[SupervisorEvent]) {
        for event in events {
            let (name, stage, mut reply) = match event {
                SupervisorEvent::SwapStarted {
                    name,
                    variant,
                    old_pid,
                    new_pid,
                    instance,
                } => {
                    let mut r = SupervisorReply::new(
                        ReplyStage::Started,
                        &format!("started `{variant}` as pid {new_pid}; loading and warming up"),
                    );
                    r.old_pid = old_pid.unwrap_or(0);
                    r.new_pid = *new_pid;
                    r.new_instance = *instance;
                    (name, ReplyStage::Started, r)
                }
                SupervisorEvent::SwapReady {
                    name,
                    old_pid,
                    new_pid,
                    instance,
                    ..
                } => {
                    let mut r = SupervisorReply::new(ReplyStage::Ready, &event.to_string());
                    r.old_pid = old_pid.unwrap_or(0);
                    r.new_pid = *new_pid;
                    r.new_instance = *instance;
                    (name, ReplyStage::Ready, r)
                }
                SupervisorEvent::SwapDone { name, old_pid, .. } => {
                    let mut r = SupervisorReply::new(ReplyStage::Done, &event.to_string());
                    r.old_pid = old_pid.unwrap_or(0);
                    (name, ReplyStage::Done, r)
                }
                SupervisorEvent::SwapFailed { name, .. } => (
                    name,
                    ReplyStage::Failed,
                    SupervisorReply::new(ReplyStage::Failed, &event.to_string()),
                ),
                _ => continue,
            };
            let Some(k) = self.requests.iter().position(|(r, _, _)| r == name) else {
                continue;
            };
            let role = &self.roles.iter().find(|r| &r.name == name);
            if reply.new_pid == 0 {
                reply.new_pid = role.and_then(|r| r.pid).unwrap_or(0);
                reply.new_instance = role.map_or(0, |r| r.instance);
            }
            reply.elapsed_ms = self.requests[k].2.elapsed().as_millis() as u64;
            let _ = self.control.reply(&self.requests[k].1, &reply);
            if stage.is_final() {
                self.requests.swap_remove(k);
            }
        }
    }

    /// The flight's role names, comma-separated (for errors).
    fn role_names(&self) -> String {
        self.roles
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Every role, in start order.
    pub fn roles(&self) -> &[RoleRuntime] {
        &self.roles
    }

    /// The role named `name`.
    pub fn role(&self, name: &str) -> Option<&RoleRuntime> {
        self.roles.iter().find(|r| r.name == name)
    }

    /// Restarts of all roles together.
    pub fn total_restarts(&self) -> u32 {
        self.roles.iter().map(|r| r.restarts).sum()
    }

    /// Heartbeats that failed validation.
    pub fn invalid_heartbeats(&self) -> u64 {
        self.invalid_heartbeats
    }

    /// Valid heartbeats from a role name that is not in this flight.
    pub fn unknown_heartbeats(&self) -> u64 {
        self.unknown_heartbeats
    }

    /// The flight name.
    pub fn flight(&self) -> &str {
        &self.flight
    }

    /// The supervisor's node in the flight.
    pub fn bus(&self) -> &FlightBus {
        &self.bus
    }

    /// The run directory (specs under `roles/`, logs under `logs/`).
    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    /// The last status board written.
    pub fn status(&self) -> &SupervisorStatus {
        &self.status
    }

    /// Mission progress copied onto the status board (written at once).
    pub fn set_progress(
        &mut self,
        active_step: u16,
        subgoals: u16,
        distance_to_goal_m: f32,
        ct_mean_s: f32,
    ) {
        self.status.active_step = active_step;
        self.status.subgoals = subgoals;
        self.status.distance_to_goal_m = distance_to_goal_m;
        self.status.ct_mean_s = ct_mean_s;
        self.publish_board();
    }

    /// Stop every role: SIGTERM in order (reasoning first; controller and vehicle only once
    /// the others exited or half of `grace` passed), wait up to `grace` in all, SIGKILL the
    /// stragglers and reap everything.
    pub fn shutdown(mut self, grace: Duration) -> ShutdownReport {
        let start = Instant::now();
        self.stop_swaps();
        let mut order: Vec<usize> = (0..self.roles.len()).collect();
        order.sort_by_key(|&i| shutdown_rank(&self.roles[i].kind));
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
                if in_phase(shutdown_rank(&role.kind))
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
                let waiting = order.iter().any(|&i| {
                    outcomes[i].is_none() && in_phase(shutdown_rank(&self.roles[i].kind))
                });
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
        let _ = self.drain_heartbeats(&mut ignored);
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

impl Supervisor {
    /// Kill the new sides of unfinished swaps and the replaced processes still exiting.
    fn stop_swaps(&mut self) {
        for role in &mut self.roles {
            if let Some(mut swap) = role.swap.take() {
                let _ = swap.child.kill();
                let _ = swap.child.wait();
            }
        }
        for mut r in self.retiring.drain(..) {
            let _ = r.child.kill();
            let _ = r.child.wait();
        }
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        self.stop_swaps();
        for role in &mut self.roles {
            if let Some(mut child) = role.child.take() {
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_tail_keeps_the_last_lines() {
        let dir = std::env::temp_dir().join(format!("aeris-orch-tail-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.log");
        let text: String = (0..20).map(|i| format!("line {i}\n")).collect();
        std::fs::write(&p, text).unwrap();
        assert_eq!(log_tail(&p, 2), vec!["line 18", "line 19"]);
        assert!(log_tail(&dir.join("missing.log"), 3).is_empty());
        // a long log: only whole lines from the end
        let long: String = (0..5000).map(|i| format!("entry {i:05}\n")).collect();
        std::fs::write(&p, long).unwrap();
        assert_eq!(log_tail(&p, 1), vec!["entry 04999"]);
        let _ = std::fs::remove_dir_all(&dir);
    }

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
            "vehicle",
            "controller",
            "hub",
            "camera",
            "reasoning",
            "perception",
        ];
        kinds.sort_by_key(|k| shutdown_rank(k));
        assert_eq!(kinds[0], "reasoning");
        assert_eq!(kinds[4], "controller");
        assert_eq!(kinds[5], "vehicle");
    }

    fn hb(pid: u32, seq: u64, latency_ns: u64) -> RoleHeartbeat {
        let mut h = RoleHeartbeat::default();
        h.role.set("r");
        h.pid = pid;
        h.seq = seq;
        h.status = RoleStatus::Running as u8;
        h.cycle_latency_ns = latency_ns;
        h.worked = 1;
        h
    }

    fn liveness(pid: u32, seq: u64, latency_ns: u64) -> RoleHeartbeat {
        RoleHeartbeat {
            worked: 0,
            ..hb(pid, seq, latency_ns)
        }
    }

    fn runtime() -> RoleRuntime {
        RoleRuntime {
            name: "r".into(),
            kind: "hub".into(),
            variant: "gate".into(),
            cpus: String::new(),
            cpu_set: None,
            spec_path: PathBuf::new(),
            log_path: PathBuf::new(),
            policy: RestartPolicy::OnFailure,
            max_restarts: 1,
            backoff_ms: 1,
            child: None,
            pid: None,
            old_pids: Vec::new(),
            state: RoleState::Running,
            restarts: 0,
            last_exit: None,
            last_heartbeat: None,
            heartbeats: 0,
            incarnation_heartbeats: 0,
            heartbeat_gaps: 0,
            window: LatencyWindow::new(LATENCY_WINDOW),
            latency_ms: None,
            pool: vec!["gate".into()],
            instance: 1,
            swap: None,
            executor: String::new(),
            budget_ms: None,
            migrations: 0,
            stalls: 0,
            binding: String::new(),
            running: false,
            heard_at: None,
            started_at: None,
            silence_probe: None,
            sched: VecDeque::new(),
            recent: LatencyWindow::new(RECENT_CYCLES),
            ladder: Vec::new(),
            worked_cycles: 0,
            last_cycle_ms: None,
        }
    }

    #[test]
    fn heartbeats_feed_gaps_and_percentiles() {
        let mut r = runtime();
        assert!(r.record(&hb(10, 1, 1_000_000), RoleStatus::Running));
        assert!(!r.record(&hb(10, 2, 2_000_000), RoleStatus::Running));
        // a liveness repeat of the same figures is not a new cycle
        assert!(!r.record(&liveness(10, 3, 2_000_000), RoleStatus::Running));
        assert_eq!(r.latency_samples(), 2);
        // the ladder's cycle count and newest latency: worked cycles only
        assert_eq!((r.worked_cycles, r.last_cycle_ms), (2, Some(2.0)));
        // seq 4 and 5 lost
        r.record(&hb(10, 6, 3_000_000), RoleStatus::Running);
        assert_eq!(r.heartbeat_gaps(), 1);
        assert_eq!(r.latency_ms(), Some([2.0, 3.0, 3.0]));
        // a new process restarts at seq 1: not a gap
        r.incarnation_heartbeats = 0;
        assert!(r.record(&hb(11, 1, 0), RoleStatus::Starting));
        assert_eq!(r.heartbeat_gaps(), 1);
        assert_eq!(r.heartbeats(), 5);
        assert_eq!(r.latency_samples(), 3);
    }
}
