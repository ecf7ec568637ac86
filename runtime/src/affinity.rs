//! CPU sets: parsing "0-2,5" lists and binding processes (every thread) to them.

use aeris_schemas::FixedText;

/// Why a CPU list cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CpuSetError {
    /// The text is not a CPU list like `0`, `0-3` or `0,2-3`.
    #[error("`{0}` is not a CPU list (expected e.g. `0`, `0-3` or `0,2-3`)")]
    Syntax(String),
    /// A CPU index is beyond what this machine has.
    #[error("CPU {cpu} does not exist on this machine (it has CPUs 0-{last})")]
    NoSuchCpu {
        /// Requested CPU.
        cpu: usize,
        /// Highest CPU index available.
        last: usize,
    },
    /// The list is empty.
    #[error("the CPU list is empty")]
    Empty,
}

/// A parsed set of CPU indices.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CpuSet {
    cpus: Vec<usize>,
}

impl CpuSet {
    /// Parse `"0-2,5"`; does not check that the CPUs exist (see [`CpuSet::check_exists`]).
    pub fn parse(text: &str) -> Result<Self, CpuSetError> {
        let mut cpus = Vec::new();
        let bad = || CpuSetError::Syntax(text.to_string());
        for part in text.split(',').map(str::trim) {
            if part.is_empty() {
                return Err(bad());
            }
            match part.split_once('-') {
                Some((a, b)) => {
                    let a: usize = a.trim().parse().map_err(|_| bad())?;
                    let b: usize = b.trim().parse().map_err(|_| bad())?;
                    if a > b || b >= libc::CPU_SETSIZE as usize {
                        return Err(bad());
                    }
                    cpus.extend(a..=b);
                }
                None => {
                    let a: usize = part.parse().map_err(|_| bad())?;
                    if a >= libc::CPU_SETSIZE as usize {
                        return Err(bad());
                    }
                    cpus.push(a)
                }
            }
        }
        cpus.sort_unstable();
        cpus.dedup();
        if cpus.is_empty() {
            return Err(CpuSetError::Empty);
        }
        Ok(Self { cpus })
    }

    /// All CPUs this process may currently run on.
    pub fn available() -> Self {
        let n = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1);
        Self {
            cpus: (0..n).collect(),
        }
    }

    /// Error unless every CPU exists on this machine.
    pub fn check_exists(&self) -> Result<(), CpuSetError> {
        // SAFETY: sysconf has no memory-safety preconditions.
        let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) };
        let n = if online > 0 { online as usize } else { 1 };
        match self.cpus.iter().find(|c| **c >= n) {
            Some(&cpu) => Err(CpuSetError::NoSuchCpu { cpu, last: n - 1 }),
            None => Ok(()),
        }
    }

    /// The CPU indices, ascending.
    pub fn cpus(&self) -> &[usize] {
        &self.cpus
    }

    fn to_libc(&self) -> libc::cpu_set_t {
        // SAFETY: cpu_set_t is plain data; zero is the empty set.
        let mut set: libc::cpu_set_t = unsafe { core::mem::zeroed() };
        for &c in &self.cpus {
            // SAFETY: c < CPU_SETSIZE was checked at parse time.
            unsafe { libc::CPU_SET(c, &mut set) };
        }
        set
    }

    /// Bind one task (thread id, or a pid for its main thread; 0 = caller) to this set.
    pub fn bind_task(&self, tid: i32) -> std::io::Result<()> {
        let set = self.to_libc();
        // SAFETY: `set` is a valid cpu_set_t of the size passed.
        let rc =
            unsafe { libc::sched_setaffinity(tid, core::mem::size_of::<libc::cpu_set_t>(), &set) };
        if rc == 0 {
            Ok(())
        } else {
            Err(std::io::Error::last_os_error())
        }
    }

    /// Bind every thread of process `pid` (read from /proc/PID/task) to this set.
    pub fn bind_process(&self, pid: i32) -> std::io::Result<usize> {
        let mut moved = 0;
        for entry in std::fs::read_dir(format!("/proc/{pid}/task"))? {
            let Some(tid) = entry?
                .file_name()
                .to_str()
                .and_then(|s| s.parse::<i32>().ok())
            else {
                continue;
            };
            match self.bind_task(tid) {
                Ok(()) => moved += 1,
                // a thread may exit while we iterate
                Err(e) if e.raw_os_error() == Some(libc::ESRCH) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(moved)
    }

    /// The affinity of task `tid` (0 = caller).
    pub fn of_task(tid: i32) -> std::io::Result<Self> {
        // SAFETY: zeroed cpu_set_t is valid; the kernel fills it.
        let mut set: libc::cpu_set_t = unsafe { core::mem::zeroed() };
        // SAFETY: `set` is writable and of the size passed.
        let rc = unsafe {
            libc::sched_getaffinity(tid, core::mem::size_of::<libc::cpu_set_t>(), &mut set)
        };
        if rc != 0 {
            return Err(std::io::Error::last_os_error());
        }
        // SAFETY: reading bits of a valid set.
        let cpus: Vec<usize> = (0..libc::CPU_SETSIZE as usize)
            .filter(|c| unsafe { libc::CPU_ISSET(*c, &set) })
            .collect();
        Ok(Self { cpus })
    }
}

impl core::fmt::Display for CpuSet {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write_cpu_list(self.cpus.iter().copied(), f)
    }
}

/// Write ascending CPU indices as a list with ranges (`0-2,5`).
fn write_cpu_list(
    cpus: impl Iterator<Item = usize>,
    out: &mut impl core::fmt::Write,
) -> core::fmt::Result {
    let mut cpus = cpus.peekable();
    let mut separator = "";
    while let Some(start) = cpus.next() {
        let mut end = start;
        while cpus.next_if_eq(&(end + 1)).is_some() {
            end += 1;
        }
        out.write_str(separator)?;
        separator = ",";
        if start == end {
            write!(out, "{start}")?;
        } else {
            write!(out, "{start}-{end}")?;
        }
    }
    Ok(())
}

/// Replace `label` with the affinity of task `tid` (0 = caller) as a CPU list (`0-1`), the
/// way a role reports where it runs after the supervisor moved it. Never allocates; on an
/// error `label` is left as it was.
///
/// # Errors
/// The `sched_getaffinity` error, or [`std::io::ErrorKind::InvalidData`] when the list does
/// not fit in `N` bytes.
pub fn write_task_affinity<const N: usize>(
    tid: i32,
    label: &mut FixedText<N>,
) -> std::io::Result<()> {
    // SAFETY: zeroed cpu_set_t is valid; the kernel fills it.
    let mut set: libc::cpu_set_t = unsafe { core::mem::zeroed() };
    // SAFETY: `set` is writable and of the size passed.
    let rc =
        unsafe { libc::sched_getaffinity(tid, core::mem::size_of::<libc::cpu_set_t>(), &mut set) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    let mut text = FixedText::<N>::new();
    // SAFETY: reading bits of a valid set.
    let cpus = (0..libc::CPU_SETSIZE as usize).filter(|c| unsafe { libc::CPU_ISSET(*c, &set) });
    write_cpu_list(cpus, &mut text).map_err(|_| std::io::ErrorKind::InvalidData)?;
    *label = text;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_prints_lists() {
        let s = CpuSet::parse("3,0-1,1").unwrap();
        assert_eq!(s.cpus(), &[0, 1, 3]);
        assert_eq!(s.to_string(), "0-1,3");
        for bad in ["", "a", "2-1", "1,,2", "-1", "99999"] {
            assert!(CpuSet::parse(bad).is_err(), "{bad:?}");
        }
        assert!(CpuSet::parse("0").unwrap().check_exists().is_ok());
        assert!(matches!(
            CpuSet::parse("1000").unwrap().check_exists(),
            Err(CpuSetError::NoSuchCpu { .. })
        ));
    }

    #[test]
    fn binds_the_calling_thread() {
        let before = CpuSet::of_task(0).unwrap();
        let one = CpuSet::parse("0").unwrap();
        one.bind_task(0).unwrap();
        assert_eq!(CpuSet::of_task(0).unwrap(), one);
        before.bind_task(0).unwrap();
    }

    #[test]
    fn a_task_reports_its_affinity_as_a_cpu_list() {
        let before = CpuSet::of_task(0).unwrap();
        let mut label = FixedText::<32>::from_str_truncated("stale");
        write_task_affinity(0, &mut label).unwrap();
        assert_eq!(label.as_str(), Some(before.to_string().as_str()));
        let one = CpuSet::parse("0").unwrap();
        one.bind_task(0).unwrap();
        write_task_affinity(0, &mut label).unwrap();
        before.bind_task(0).unwrap();
        assert_eq!(label.as_str(), Some("0"));
        // a list that does not fit leaves the label as it was
        let mut short = FixedText::<0>::new();
        assert!(write_task_affinity(0, &mut short).is_err());
    }

    #[test]
    fn lists_group_consecutive_cpus() {
        let list = |cpus: &[usize]| {
            let mut t = FixedText::<32>::new();
            write_cpu_list(cpus.iter().copied(), &mut t).unwrap();
            t.as_str().unwrap().to_string()
        };
        assert_eq!(list(&[]), "");
        assert_eq!(list(&[4]), "4");
        assert_eq!(list(&[0, 1, 2, 5, 7, 8]), "0-2,5,7-8");
        assert_eq!(list(&[0, 2, 4]), "0,2,4");
    }
}
