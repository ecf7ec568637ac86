//! Starting role processes: `aeris role --spec FILE --instance N` with its log as stdout and
//! stderr, in its own process group, with `PR_SET_PDEATHSIG(SIGKILL)`, bound to its CPUs,
//! optionally under SCHED_IDLE (the new side of a swap), inheriting no descriptor of the
//! supervisor; and writing the role specs those processes read.

use super::error::SupervisorError;
use super::logs::open_log;
use super::role_runtime::{RoleRuntime, RoleState};
use crate::priority::FlightPriority;
pub(super) use crate::role_process::{LoadPolicy, spawn_role};
use aeris_runtime::RoleSpec;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use std::path::{Path, PathBuf};
use std::process::Child;

/// Starts the flight's role processes and numbers them: every process it starts, restarts
/// and swaps included, gets the next instance number.
#[derive(Debug)]
pub(super) struct Launcher {
    /// The `aeris` executable.
    exe: PathBuf,
    /// Instance number of the next process.
    next_instance: u32,
    /// The roles' priority over outside work (their CPU control group or nice value).
    priority: FlightPriority,
}

impl Launcher {
    /// A launcher of `exe role ...` processes, numbering them from 1, each given `priority`.
    pub(super) fn new(exe: PathBuf, priority: FlightPriority) -> Self {
        Launcher {
            exe,
            next_instance: 1,
            priority,
        }
    }

    /// The roles' priority over outside work.
    pub(super) fn priority(&self) -> &FlightPriority {
        &self.priority
    }

    /// The `aeris` executable.
    pub(super) fn exe(&self) -> &Path {
        &self.exe
    }

    /// The instance number the next process will get.
    pub(super) fn next_instance(&self) -> u32 {
        self.next_instance
    }

    /// Start `exe role --spec SPEC` as instance [`Launcher::next_instance`], which is then
    /// used up.
    pub(super) fn spawn(
        &mut self,
        spec: &Path,
        log: std::fs::File,
        cpus: Option<&CpuSet>,
        policy: LoadPolicy,
    ) -> std::io::Result<Child> {
        let child = spawn_role(
            &self.exe,
            spec,
            self.next_instance,
            log,
            cpus,
            policy,
            self.priority.for_child(),
        )?;
        self.next_instance += 1;
        Ok(child)
    }

    /// Start `role`'s process from its spec (`why`: "start", "restart", for its log's
    /// header); it becomes the role's running process. Returns its pid.
    pub(super) fn start(
        &mut self,
        role: &mut RoleRuntime,
        why: &str,
    ) -> Result<u32, SupervisorError> {
        let instance = self.next_instance;
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
        match self.spawn(
            &role.spec_path,
            log,
            role.cpu_set.as_ref(),
            LoadPolicy::Normal,
        ) {
            Ok(child) => {
                let pid = child.id();
                role.instance = instance;
                role.child = Some(child);
                role.pid = Some(pid);
                role.state = RoleState::Running;
                role.incarnation_heartbeats = 0;
                role.new_incarnation();
                Ok(pid)
            }
            Err(source) => Err(SupervisorError::Spawn {
                role: role.name.clone(),
                exe: self.exe.clone(),
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
}

/// Write `spec` as pretty JSON to `path`, where the role's processes read it.
pub(super) fn write_spec(spec: &RoleSpec, path: &Path) -> Result<(), SupervisorError> {
    let json = serde_json::to_string_pretty(spec).map_err(|e| SupervisorError::WriteSpec {
        role: spec.name.clone(),
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    std::fs::write(path, json).map_err(|source| SupervisorError::WriteSpec {
        role: spec.name.clone(),
        path: path.to_path_buf(),
        source,
    })
}

/// `true` when this process may move a thread from SCHED_IDLE back to SCHED_OTHER (root,
/// or an RLIMIT_NICE that allows nice 0): only then does a swap start its new process idle.
pub(super) fn may_leave_idle() -> bool {
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
pub(super) fn set_normal_policy(pid: u32) {
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
