//! Starting role processes: `aeris role --spec FILE --instance N` with its log as stdout and
//! stderr, in its own process group, with `PR_SET_PDEATHSIG(SIGKILL)`, bound to its CPUs,
//! optionally under SCHED_IDLE (the new side of a swap), inheriting no descriptor of the
//! supervisor; and writing the role specs those processes read.

use super::error::SupervisorError;
use super::logs::open_log;
use super::role_runtime::{RoleRuntime, RoleState};
use aeris_runtime::RoleSpec;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// Scheduling of a process the supervisor starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LoadPolicy {
    /// The normal policy.
    Normal,
    /// SCHED_IDLE until the supervisor restores SCHED_OTHER: the new side of a swap loads
    /// and warms up (seconds of every core for a language model) only on CPU time the
    /// running role leaves idle, and never preempts it. Measured on the 2-core VM: a
    /// running SmolLM2 decision p50/p95 547/612 ms alone, 529/632 ms beside Gemma loading
    /// under SCHED_IDLE, 621/824 ms beside it at nice 19.
    IdleUntilReady,
}

/// Starts the flight's role processes and numbers them: every process it starts, restarts
/// and swaps included, gets the next instance number.
#[derive(Debug)]
pub(super) struct Launcher {
    /// The `aeris` executable.
    exe: PathBuf,
    /// Instance number of the next process.
    next_instance: u32,
}

impl Launcher {
    /// A launcher of `exe role ...` processes, numbering them from 1.
    pub(super) fn new(exe: PathBuf) -> Self {
        Launcher {
            exe,
            next_instance: 1,
        }
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
        let child = spawn_role(&self.exe, spec, self.next_instance, log, cpus, policy)?;
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
