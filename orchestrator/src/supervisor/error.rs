//! Why the supervisor failed ([`SupervisorError`]), or refused a hot swap ([`SwapError`]) or a
//! live move ([`MigrateError`]).

use super::logs::quote_tail;
use crate::launch::PlanError;
use aeris_runtime::bus::BusError;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Why the supervisor failed.
#[derive(Debug, thiserror::Error)]
pub enum SupervisorError {
    /// The flight could not be planned (flight name, workflow, vehicle link).
    #[error("cannot plan flight `{flight}`")]
    Plan {
        /// Flight name.
        flight: String,
        /// Why.
        source: PlanError,
    },
    /// The supervisor's iceoryx2 node, heartbeat subscriber or status board failed. A
    /// status board that already exists means another supervisor runs this flight.
    #[error(
        "the supervisor of flight `{flight}` cannot open its services (is another supervisor running this flight? pick another flight name)"
    )]
    Bus {
        /// Flight name.
        flight: String,
        /// Why.
        source: BusError,
    },
    /// The run directory could not be prepared.
    #[error("cannot create run directory {path} (pass a writable --run-dir)")]
    RunDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A role spec could not be written.
    #[error("cannot write the spec of role `{role}` to {path}")]
    WriteSpec {
        /// Role name.
        role: String,
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A role's log could not be opened.
    #[error("cannot open the log of role `{role}` at {path}")]
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
        "cannot start role `{role}` as `{exe} role --spec {spec}`{cpus} (build the binary with `cargo build --bin aeris`)"
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
    #[error("cannot wait on role `{role}` (pid {pid})")]
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
        kind: aeris_schemas::RoleKind,
        /// Why (its kind's `swap_refusal`).
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
    /// The flight runs on simulated time, where a second process of a role would be one
    /// more participant every instant waits for (not supported yet).
    #[error(
        "role `{role}` cannot be hot-swapped in a flight on simulated time (fly it with --clock wall)"
    )]
    SimulatedTime {
        /// Role name.
        role: String,
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
    /// The target is an accelerator executor and the role runs no model it can run (ONNX
    /// models on any accelerator, language models on CUDA).
    #[error(
        "role `{role}` cannot go to `{target}`: its accelerator ({accelerator}) runs ONNX models (and, on CUDA, language models), and the role runs none; it stays where it runs"
    )]
    NotAccelerated {
        /// Role name.
        role: String,
        /// The target as given.
        target: String,
        /// The target's accelerator.
        accelerator: aeris_runtime::accelerator::Accelerator,
    },
    /// The target's accelerator needs an execution provider this host's ONNX Runtime lacks.
    #[error(
        "role `{role}` cannot go to `{target}`: its accelerator {accelerator} needs ONNX Runtime's {}, which this host's does not offer (offered: {offered}); it stays where it runs",
        accelerator.kind.provider()
    )]
    AcceleratorUnavailable {
        /// Role name.
        role: String,
        /// The target as given.
        target: String,
        /// The target's accelerator.
        accelerator: aeris_runtime::accelerator::Accelerator,
        /// The providers offered.
        offered: String,
    },
    /// The target's accelerator cannot be checked: no ONNX Runtime could be loaded here.
    #[error(
        "role `{role}` cannot go to `{target}`: no ONNX Runtime could be loaded on this host to check that it offers {}, which its accelerator {accelerator} needs; it stays where it runs",
        accelerator.kind.provider()
    )]
    AcceleratorUnchecked {
        /// Role name.
        role: String,
        /// The target as given.
        target: String,
        /// The target's accelerator.
        accelerator: aeris_runtime::accelerator::Accelerator,
    },
    /// A live move (same process) would change the role's accelerator, which needs a restart.
    #[error(
        "role `{role}` cannot move to `{target}` live: it changes the accelerator its models run on, which restarts it (`aeris migrate` does, make-before-break)"
    )]
    AcceleratorNeedsRestart {
        /// Role name.
        role: String,
        /// The target as given.
        target: String,
    },
    /// A hot swap of the role is under way.
    #[error("role `{role}` is being swapped; move it once the swap is done")]
    SwapInProgress {
        /// Role name.
        role: String,
    },
    /// `HOST:EXECUTOR` names a host the workflow does not declare, or an executor not on it.
    #[error("`{target}` is not an executor on another host (declared: {known})")]
    UnknownRemoteExecutor {
        /// The target as given.
        target: String,
        /// The executors on other hosts, as `HOST:EXECUTOR`, comma-separated.
        known: String,
    },
    /// The role's kind must stay on the flight's host (or cannot run twice for a moment,
    /// which a make-before-break move needs).
    #[error(
        "role `{role}` (kind {kind}) cannot move to another host: it runs on the flight's host"
    )]
    NotMovable {
        /// Role name.
        role: String,
        /// Its kind.
        kind: aeris_schemas::RoleKind,
    },
    /// The role already runs there.
    #[error("role `{role}` already runs on {place}")]
    AlreadyThere {
        /// Role name.
        role: String,
        /// Where it runs.
        place: String,
    },
    /// There, the role would exchange a topic with a role on a third host: topics cross
    /// only between the flight's host and one other.
    #[error(
        "role `{role}` cannot move to host `{host}`: it would exchange `{topic}` with role `{other}` on host `{other_host}` (topics cross only between the flight's host and one other)"
    )]
    HostToHost {
        /// Role name.
        role: String,
        /// The target host.
        host: String,
        /// The topic.
        topic: String,
        /// The role on the third host.
        other: String,
        /// The third host.
        other_host: String,
    },
    /// The new process of a move between hosts could not be started (the source names the
    /// role).
    #[error("the move could not start")]
    Start {
        /// Role name.
        role: String,
        /// Why.
        #[source]
        source: SwapError,
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
