//! The flight's roles before outside work on a shared machine (issue 21): every role process
//! the supervisor starts joins one CPU control group of the flight with ten times the
//! default weight, so that busy work outside the flight gets the CPU the roles leave, not
//! the CPU they need; where no control group may be made, the roles run at a raised
//! priority (a negative nice value); where neither is permitted, they run as any process
//! and the flight says so.
//!
//! The group is a child of the supervisor's own, named `aeris-PID-FLIGHT` after the process
//! that made it, so that a later flight removes only the groups of processes that are gone.
//! The supervisor's process joins the group for the flight and returns to its own group
//! after it (see `cgroup_group` for why).
//!
//! Which works where:
//! - **cgroup v2** (`cpu.weight`): the supervisor's group must hand the `cpu` controller to
//!   its children, which the kernel allows a non-root group only while it holds no process
//!   of its own: in practice the supervisor must run in the root group (root on a board's
//!   own image or a VM). In a container or a systemd scope, where it shares a group with
//!   other processes, the kernel refuses (EBUSY) and the roles get a nice value instead;
//! - **cgroup v1** (`cpu.shares`, JetPack 5 and hybrid hosts): needs write access to the
//!   `cpu` hierarchy (root);
//! - **nice** −5: needs `CAP_SYS_NICE` (root has it unless a container dropped it) or an
//!   `RLIMIT_NICE` of at least 25;
//! - otherwise **none**: the roles compete with outside work as equals; the flight flies
//!   and its summary names why.

use std::fs::File;
use std::io::Write;
use std::os::fd::{AsRawFd, RawFd};
use std::path::{Path, PathBuf};

/// The CPU weight of the flight's group under cgroup v2 (the default is 100).
pub const CGROUP_V2_WEIGHT: u32 = 1000;
/// The CPU shares of the flight's group under cgroup v1 (the default is 1024).
pub const CGROUP_V1_SHARES: u64 = 10_240;
/// The nice value of the flight's roles where no group may be made.
pub const ROLE_NICE: i32 = -5;

/// How the workflow asks for the roles' priority (`[scheduling] priority`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PriorityMode {
    /// A CPU control group where permitted, else a nice value, else none (the default).
    #[default]
    Auto,
    /// A nice value only (no control group).
    Nice,
    /// The roles run as any process.
    Off,
}

impl std::str::FromStr for PriorityMode {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "auto" => Ok(PriorityMode::Auto),
            "nice" => Ok(PriorityMode::Nice),
            "off" => Ok(PriorityMode::Off),
            other => Err(format!("`{other}`: use auto, nice or off")),
        }
    }
}

/// How the flight's roles got their priority.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Priority {
    /// A cgroup v2 group with `cpu.weight`.
    CgroupV2 {
        /// The group's folder.
        path: PathBuf,
        /// Its `cpu.weight`.
        weight: u32,
    },
    /// A cgroup v1 `cpu` group with `cpu.shares`.
    CgroupV1 {
        /// The group's folder.
        path: PathBuf,
        /// Its `cpu.shares`.
        shares: u64,
    },
    /// A nice value for every role process.
    Nice {
        /// The value.
        nice: i32,
    },
    /// None: the roles compete with outside work as equals.
    None {
        /// Why (the mode was `off`, or what was not permitted).
        reason: String,
    },
}

impl Priority {
    /// A short name: `cgroup-v2`, `cgroup-v1`, `nice` or `none`.
    pub fn mechanism(&self) -> &'static str {
        match self {
            Priority::CgroupV2 { .. } => "cgroup-v2",
            Priority::CgroupV1 { .. } => "cgroup-v1",
            Priority::Nice { .. } => "nice",
            Priority::None { .. } => "none",
        }
    }
}

impl std::fmt::Display for Priority {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Priority::CgroupV2 { path, weight } => {
                write!(f, "cgroup v2 {} cpu.weight {weight}", path.display())
            }
            Priority::CgroupV1 { path, shares } => {
                write!(f, "cgroup v1 {} cpu.shares {shares}", path.display())
            }
            Priority::Nice { nice } => write!(f, "nice {nice}"),
            Priority::None { reason } => write!(f, "none ({reason})"),
        }
    }
}

/// The flight's priority over outside work, held by whoever starts its role processes; its
/// control group (if any) is removed when it is dropped, once the roles are gone.
#[derive(Debug)]
pub struct FlightPriority {
    priority: Priority,
    /// The group's `cgroup.procs`, open for writing: a starting role writes itself into it.
    procs: Option<File>,
}

/// What a starting role process does to itself between fork and exec (see
/// [`FlightPriority::for_child`]): plain values, no allocation.
#[derive(Debug, Clone, Copy)]
pub struct ChildPriority {
    /// `cgroup.procs` of the flight's group, or -1.
    procs_fd: RawFd,
    /// The nice value to take, if any.
    nice: Option<i32>,
}

impl ChildPriority {
    /// Nothing: the process keeps its parent's group and nice value.
    pub const NONE: ChildPriority = ChildPriority {
        procs_fd: -1,
        nice: None,
    };

    /// Join the group or take the nice value, in the forked child before exec. Best effort:
    /// a failure leaves the role running at normal priority rather than not running.
    ///
    /// # Safety
    /// Call only between fork and exec of a process whose parent holds the
    /// [`FlightPriority`] this came from; it makes only async-signal-safe system calls.
    pub unsafe fn apply_in_child(&self) {
        if self.procs_fd >= 0 {
            // "0" moves the writing process (and the threads it will start)
            // SAFETY: a descriptor the parent keeps open across the fork; a 1-byte buffer.
            unsafe { libc::write(self.procs_fd, b"0".as_ptr().cast(), 1) };
        }
        if let Some(nice) = self.nice {
            // SAFETY: setpriority on the calling process has no memory preconditions.
            unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, nice) };
        }
    }
}

impl FlightPriority {
    /// No priority, for `reason`.
    pub fn none(reason: impl Into<String>) -> Self {
        FlightPriority {
            priority: Priority::None {
                reason: reason.into(),
            },
            procs: None,
        }
    }

    /// Give flight `flight`'s roles priority as `mode` asks and this process is permitted:
    /// a control group `aeris-PID-FLIGHT` under this process's own, else a nice value, else
    /// none. Never fails: what was not permitted is in [`Priority::None`]'s reason.
    pub fn establish(flight: &str, mode: PriorityMode) -> Self {
        let mut refused = Vec::new();
        if mode == PriorityMode::Auto {
            match cgroup_group(flight) {
                Ok(p) => return p,
                Err(why) => refused.push(why),
            }
        }
        if mode != PriorityMode::Off {
            if may_raise_priority(ROLE_NICE) {
                return FlightPriority {
                    priority: Priority::Nice { nice: ROLE_NICE },
                    procs: None,
                };
            }
            refused.push(format!(
                "nice {ROLE_NICE} needs root, CAP_SYS_NICE or RLIMIT_NICE >= {}",
                20 - ROLE_NICE
            ));
        } else {
            refused.push("[scheduling] priority = \"off\"".into());
        }
        FlightPriority::none(refused.join("; "))
    }

    /// How the roles got their priority.
    pub fn priority(&self) -> &Priority {
        &self.priority
    }

    /// What a role process starting now does to itself before exec.
    pub fn for_child(&self) -> ChildPriority {
        match &self.priority {
            Priority::CgroupV1 { .. } | Priority::CgroupV2 { .. } => ChildPriority {
                procs_fd: self.procs.as_ref().map_or(-1, |f| f.as_raw_fd()),
                nice: None,
            },
            Priority::Nice { nice } => ChildPriority {
                procs_fd: -1,
                nice: Some(*nice),
            },
            Priority::None { .. } => ChildPriority::NONE,
        }
    }
}

impl Drop for FlightPriority {
    fn drop(&mut self) {
        self.procs = None;
        if let Priority::CgroupV1 { path, .. } | Priority::CgroupV2 { path, .. } = &self.priority {
            // this process returns to the group it left, the flight group's parent (best
            // effort: where the way back is refused, the group stays until this process is
            // gone and a later flight's sweep removes it)
            if let Some(home) = path.parent() {
                let _ = std::fs::write(home.join("cgroup.procs"), std::process::id().to_string());
            }
            // fails (EBUSY) while a role process lives in it; the supervisor has reaped
            // them by now, and the next flight's sweep removes a group left behind
            let _ = std::fs::remove_dir(path);
        }
    }
}

/// The `cpu` controller's hierarchy this process is in: (v2?, mount point, own path).
fn cpu_hierarchy() -> Result<(bool, PathBuf, String), String> {
    let mountinfo = std::fs::read_to_string("/proc/self/mountinfo")
        .map_err(|e| format!("/proc/self/mountinfo: {e}"))?;
    let cgroups = std::fs::read_to_string("/proc/self/cgroup")
        .map_err(|e| format!("/proc/self/cgroup: {e}"))?;
    let (mut v2, mut v1) = (None, None);
    for line in mountinfo.lines() {
        let Some((left, right)) = line.split_once(" - ") else {
            continue;
        };
        let mut fields = left.split(' ');
        // the hierarchy's folder mounted there (`/` unless only part of it is, as in a
        // container that sees its own group as the root)
        let root = fields.nth(3).unwrap_or("/");
        let mount = fields.next().unwrap_or_default();
        let mut r = right.split(' ');
        let fstype = r.next().unwrap_or_default();
        let options = r.nth(1).unwrap_or_default();
        if fstype == "cgroup2" && v2.is_none() {
            let controllers = std::fs::read_to_string(Path::new(mount).join("cgroup.controllers"))
                .unwrap_or_default();
            if controllers.split_whitespace().any(|c| c == "cpu") {
                v2 = Some((PathBuf::from(mount), root.to_string()));
            }
        } else if fstype == "cgroup" && options.split(',').any(|o| o == "cpu") && v1.is_none() {
            v1 = Some((PathBuf::from(mount), root.to_string()));
        }
    }
    for line in cgroups.lines() {
        let mut f = line.splitn(3, ':');
        let (_, controllers, path) = (f.next(), f.next().unwrap_or(""), f.next().unwrap_or(""));
        // the process's path is in the whole hierarchy; below the mount's root it is there
        let under = |root: &str| {
            let rest = path
                .strip_prefix(root.trim_end_matches('/'))
                .unwrap_or(path);
            rest.to_string()
        };
        if let Some((mount, root)) = &v2
            && controllers.is_empty()
        {
            return Ok((true, mount.clone(), under(root)));
        }
        if let Some((mount, root)) = &v1
            && controllers.split(',').any(|c| c == "cpu")
        {
            return Ok((false, mount.clone(), under(root)));
        }
    }
    Err("no cgroup hierarchy with the cpu controller".into())
}

/// Make the flight's group under this process's own and open its `cgroup.procs`.
fn cgroup_group(flight: &str) -> Result<FlightPriority, String> {
    let (v2, mount, own) = cpu_hierarchy()?;
    // a flight's group is made beside this process's other flights' groups, never inside
    // one it joined (several flights of one process: tests, an agent)
    let own = match own.rsplit_once('/') {
        Some((up, last)) if last.starts_with(&format!("aeris-{}-", std::process::id())) => up,
        _ => own.as_str(),
    };
    let parent = mount.join(own.trim_start_matches('/'));
    sweep_stale_groups(&parent);
    let dir = parent.join(format!("aeris-{}-{flight}", std::process::id()));
    let denied = |what: &str, e: std::io::Error| {
        format!("cgroup {}: {what}: {e}", if v2 { "v2" } else { "v1" })
    };
    if v2 {
        // children get the cpu controller only if the parent hands it down
        let subtree = parent.join("cgroup.subtree_control");
        let enabled = std::fs::read_to_string(&subtree).unwrap_or_default();
        if !enabled.split_whitespace().any(|c| c == "cpu") {
            std::fs::write(&subtree, "+cpu")
                .map_err(|e| denied(&format!("enable cpu in {}", subtree.display()), e))?;
        }
    }
    match std::fs::create_dir(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(denied(&format!("create {}", dir.display()), e)),
    }
    let remove = |msg: String| {
        let _ = std::fs::remove_dir(&dir);
        msg
    };
    let (file, value) = if v2 {
        ("cpu.weight", CGROUP_V2_WEIGHT.to_string())
    } else {
        ("cpu.shares", CGROUP_V1_SHARES.to_string())
    };
    std::fs::File::options()
        .write(true)
        .open(dir.join(file))
        .and_then(|mut f| f.write_all(value.as_bytes()))
        .map_err(|e| remove(denied(&format!("write {file}"), e)))?;
    let mut procs = std::fs::File::options()
        .write(true)
        .open(dir.join("cgroup.procs"))
        .map_err(|e| remove(denied("open cgroup.procs", e)))?;
    // The supervisor joins its roles' group. Left outside, it competes with the whole group
    // as one task against one heavy entity, and on Linux 6.x (EEVDF) a busy group starves
    // the tasks beside it for seconds even at nice -20: measured on a 2-core VM during
    // SmolLM2 decisions, the supervisor's step and its CPU watchers waited up to 4.8 s
    // (`perf sched`), and the stall and link watch read the roles as silent. In the group it
    // is one more task among the roles, as with a nice value. Its whole process moves (a
    // cgroup v2 group holds processes, not threads): load a benchmark puts beside the flight
    // runs in processes of its own.
    procs
        .write_all(std::process::id().to_string().as_bytes())
        .map_err(|e| remove(denied("move the supervisor into the group", e)))?;
    let priority = if v2 {
        Priority::CgroupV2 {
            path: dir,
            weight: CGROUP_V2_WEIGHT,
        }
    } else {
        Priority::CgroupV1 {
            path: dir,
            shares: CGROUP_V1_SHARES,
        }
    };
    Ok(FlightPriority {
        priority,
        procs: Some(procs),
    })
}

/// Remove the groups of flights whose process is gone without removing its group (a killed
/// supervisor): `aeris-PID-...` with no process PID. A group still holding processes is
/// left alone (the kernel refuses); a live process's group, empty or not, is never touched.
fn sweep_stale_groups(parent: &Path) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = name
            .strip_prefix("aeris-")
            .and_then(|rest| rest.split('-').next())
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_dir(e.path());
        }
    }
}

/// The capability bit that permits raising a priority (linux/capability.h).
const CAP_SYS_NICE: u32 = 23;

/// Whether this process may give its children a nice value of `nice` (< 0): with
/// `CAP_SYS_NICE` (root has it unless a container dropped it), or within `RLIMIT_NICE`.
pub fn may_raise_priority(nice: i32) -> bool {
    let cap_sys_nice = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("CapEff:"))
                .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        })
        .is_some_and(|caps| caps & (1 << CAP_SYS_NICE) != 0);
    if cap_sys_nice {
        return true;
    }
    // SAFETY: a zeroed rlimit is valid; getrlimit fills it.
    let mut lim: libc::rlimit = unsafe { core::mem::zeroed() };
    // SAFETY: `lim` is writable.
    let got = unsafe { libc::getrlimit(libc::RLIMIT_NICE, &mut lim) } == 0;
    got && lim.rlim_cur >= (20 - nice) as libc::rlim_t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_parse_and_a_bad_one_is_named() {
        assert_eq!("auto".parse(), Ok(PriorityMode::Auto));
        assert_eq!("nice".parse(), Ok(PriorityMode::Nice));
        assert_eq!("off".parse(), Ok(PriorityMode::Off));
        let err = "fifo".parse::<PriorityMode>().unwrap_err();
        assert!(err.contains("`fifo`"), "{err}");
    }

    #[test]
    fn off_gives_none_and_says_why() {
        let p = FlightPriority::establish("unit-off", PriorityMode::Off);
        assert_eq!(p.priority().mechanism(), "none");
        assert!(p.priority().to_string().contains("off"), "{}", p.priority());
        assert_eq!(p.for_child().procs_fd, -1);
        assert_eq!(p.for_child().nice, None);
    }

    #[test]
    fn auto_makes_a_group_that_a_child_joins_or_says_why_not() {
        let p =
            FlightPriority::establish(&format!("unit-{}", std::process::id()), PriorityMode::Auto);
        match p.priority().clone() {
            Priority::CgroupV1 { path, .. } | Priority::CgroupV2 { path, .. } => {
                let child = p.for_child();
                let mut cmd = std::process::Command::new("cat");
                cmd.arg("/proc/self/cgroup");
                // SAFETY: apply_in_child makes only async-signal-safe calls.
                unsafe {
                    use std::os::unix::process::CommandExt;
                    cmd.pre_exec(move || {
                        child.apply_in_child();
                        Ok(())
                    });
                }
                let out = cmd.output().unwrap();
                let text = String::from_utf8_lossy(&out.stdout);
                let name = path.file_name().unwrap().to_string_lossy().into_owned();
                assert!(text.contains(&name), "{text}");
                // the supervisor's own process is in the group with its roles
                let own = std::fs::read_to_string("/proc/self/cgroup").unwrap();
                assert!(own.contains(&name), "{own}");
                // a later flight's sweep removes the group of a process that is gone, and
                // never a live one's (this one's, empty now)
                let parent = path.parent().unwrap();
                let mut gone = std::process::Command::new("true").spawn().unwrap();
                let dead = gone.id();
                gone.wait().unwrap();
                let stale = parent.join(format!("aeris-{dead}-unit"));
                std::fs::create_dir(&stale).unwrap();
                sweep_stale_groups(parent);
                assert!(!stale.exists(), "{}", stale.display());
                assert!(path.exists(), "{}", path.display());
                drop(p);
                assert!(!path.exists(), "{}", path.display());
                let own = std::fs::read_to_string("/proc/self/cgroup").unwrap();
                assert!(!own.contains(&name), "{own}");
            }
            Priority::Nice { nice } => assert_eq!(nice, ROLE_NICE),
            Priority::None { reason } => assert!(reason.contains("cgroup"), "{reason}"),
        }
    }
}
