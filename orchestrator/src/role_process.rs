//! Starting one role process the way every AERIS process starter does (the supervisor on
//! the flight's host, the host agent on another): `aeris role --spec FILE --instance N`
//! with its log as stdout and stderr, in its own process group, with
//! `PR_SET_PDEATHSIG(SIGKILL)`, bound to its CPUs, optionally under SCHED_IDLE, in the
//! flight's CPU control group or at its nice value ([`crate::priority`]), inheriting no
//! descriptor of its parent.

use crate::priority::ChildPriority;
use aeris_runtime::affinity::CpuSet;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// Scheduling of a process the supervisor starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoadPolicy {
    /// The normal policy.
    Normal,
    /// SCHED_IDLE until the supervisor restores SCHED_OTHER: the new side of a swap loads
    /// and warms up (seconds of every core for a language model) only on CPU time the
    /// running role leaves idle, and never preempts it. Measured on the 2-core VM: a
    /// running SmolLM2 decision p50/p95 547/612 ms alone, 529/632 ms beside Gemma loading
    /// under SCHED_IDLE, 621/824 ms beside it at nice 19.
    IdleUntilReady,
}

/// Start `exe role --spec SPEC --instance N` with stdout and stderr appended to `log`, in
/// its own process group, killed when this process dies (`PR_SET_PDEATHSIG`), bound to
/// `cpus`, given the flight's `priority`, inheriting no descriptor but its standard streams.
pub fn spawn_role(
    exe: &Path,
    spec: &Path,
    instance: u32,
    log: std::fs::File,
    cpus: Option<&CpuSet>,
    policy: LoadPolicy,
    priority: ChildPriority,
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
    // sched_setaffinity, sched_setscheduler, write, setpriority, close_range/fcntl) and does
    // not allocate: CpuSet::bind_task builds the mask on the stack and
    // io::Error::last_os_error / from_raw_os_error do not allocate; `priority` holds the
    // parent's open cgroup.procs descriptor, which outlives the spawn.
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
            priority.apply_in_child();
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
