//! The executor registry: the CPU sets roles may be bound to, with their capacity and the
//! load the kernel reports, and the per-process scheduler figures the re-binding policy
//! reads.
//!
//! Executors come from the workflow (`[executors.NAME] cpus = ...`, resolved by the launch
//! plan) and from the machine: one `cpuN` executor per CPU the supervisor may run on that no
//! declared executor already is. Load comes from `/proc/stat` (per-CPU busy time) and
//! `/proc/pressure/cpu` (machine-wide run-queue pressure); a role process's CPU demand and
//! run-queue wait come from `/proc/PID/task/*/schedstat` (every thread summed).

use aeris_runtime::affinity::CpuSet;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// Where an executor came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExecutorOrigin {
    /// Declared in the workflow.
    Declared,
    /// Found on the machine (one per CPU the supervisor may use).
    Discovered,
}

/// One executor: a CPU set with its capacity and current load.
#[derive(Debug, Clone, PartialEq)]
pub struct ExecutorInfo {
    /// Name (`[executors.NAME]`, or `cpuN` for a discovered one).
    pub name: String,
    /// Its CPUs.
    pub cpus: CpuSet,
    /// Declared or discovered.
    pub origin: ExecutorOrigin,
    /// Busy CPU time over the last sampling interval, in cores (0..=capacity).
    pub busy: f64,
}

impl ExecutorInfo {
    /// Capacity in cores: the number of CPUs.
    pub fn capacity(&self) -> f64 {
        self.cpus.cpus().len() as f64
    }
}

/// An accelerator an ONNX Runtime execution provider offers on this machine (a GPU or NPU
/// device). Model roles reach it through that provider, so moving a role onto it means a
/// restart with the provider registered, not a live CPU move.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AcceleratorInfo {
    /// Name: the provider's short name and the device id (`cuda0`, `tensorrt0`, `qnn1`).
    pub name: String,
    /// The execution provider (`CUDAExecutionProvider`).
    pub provider: String,
    /// `gpu`, `npu` or `fpga`.
    pub kind: String,
    /// The vendor ONNX Runtime reports.
    pub vendor: String,
    /// The device id.
    pub device_id: u32,
}

/// The accelerators among execution-provider devices `(provider, kind, vendor, device id)`
/// as ONNX Runtime reports them: every device that is not a CPU (CPUs are the CPU-set
/// executors already), in the order given, without duplicates.
pub fn accelerators_from(devices: &[(String, String, String, u32)]) -> Vec<AcceleratorInfo> {
    let mut out: Vec<AcceleratorInfo> = Vec::new();
    for (provider, kind, vendor, id) in devices {
        if kind.eq_ignore_ascii_case("cpu") {
            continue;
        }
        let short = provider
            .strip_suffix("ExecutionProvider")
            .unwrap_or(provider)
            .to_ascii_lowercase();
        let name = format!("{short}{id}");
        if out.iter().any(|a| a.name == name) {
            continue;
        }
        out.push(AcceleratorInfo {
            name,
            provider: provider.clone(),
            kind: kind.to_ascii_lowercase(),
            vendor: vendor.clone(),
            device_id: *id,
        });
    }
    out
}

/// Busy and total jiffies of one CPU, from `/proc/stat`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CpuTicks {
    /// Ticks spent not idle (user, nice, system, irq, softirq, steal).
    pub busy: u64,
    /// All ticks.
    pub total: u64,
}

/// Parse the per-CPU lines of `/proc/stat` text: CPU index -> ticks.
pub fn parse_proc_stat(text: &str) -> BTreeMap<usize, CpuTicks> {
    let mut out = BTreeMap::new();
    for line in text.lines() {
        let mut fields = line.split_ascii_whitespace();
        let Some(head) = fields.next() else { continue };
        let Some(index) = head
            .strip_prefix("cpu")
            .and_then(|n| n.parse::<usize>().ok())
        else {
            continue;
        };
        let v: Vec<u64> = fields.filter_map(|f| f.parse().ok()).collect();
        if v.len() < 4 {
            continue;
        }
        // user nice system idle iowait irq softirq steal (guest time is already in user)
        let idle = v[3] + v.get(4).copied().unwrap_or(0);
        let total: u64 = v.iter().take(8).sum();
        out.insert(
            index,
            CpuTicks {
                busy: total.saturating_sub(idle),
                total,
            },
        );
    }
    out
}

/// Read `/proc/stat` (empty when unreadable).
pub fn read_proc_stat() -> BTreeMap<usize, CpuTicks> {
    std::fs::read_to_string("/proc/stat")
        .map(|t| parse_proc_stat(&t))
        .unwrap_or_default()
}

/// Machine-wide CPU pressure: the share of the last 10 s in which some runnable task waited
/// for a CPU (`/proc/pressure/cpu`, "some avg10", as a fraction). `None` without PSI.
pub fn cpu_pressure() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/pressure/cpu").ok()?;
    let line = text.lines().find(|l| l.starts_with("some"))?;
    let avg10 = line
        .split_ascii_whitespace()
        .find_map(|f| f.strip_prefix("avg10="))?;
    avg10.parse::<f64>().ok().map(|p| p / 100.0)
}

/// Scheduler time of one process, every thread summed (`/proc/PID/task/*/schedstat`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SchedTime {
    /// Time on a CPU (ns).
    pub run_ns: u64,
    /// Time runnable but waiting in a run queue (ns).
    pub wait_ns: u64,
}

/// Below this much CPU time in a window, a role's slowdown is not measured (ms of run time).
const MIN_RUN_FOR_SLOWDOWN_NS: u64 = 2_000_000;

/// Slowdown `(run + wait) / run` and the run and wait shares of wall time between two
/// scheduler samples.
pub(crate) fn shares(
    a: &(Instant, SchedTime),
    b: &(Instant, SchedTime),
) -> Option<(f64, f64, f64)> {
    let wall = b.0.checked_duration_since(a.0)?.as_nanos() as f64;
    if wall <= 0.0 {
        return None;
    }
    let run = b.1.run_ns.checked_sub(a.1.run_ns)?;
    let wait = b.1.wait_ns.checked_sub(a.1.wait_ns)?;
    let slowdown = if run >= MIN_RUN_FOR_SLOWDOWN_NS {
        (run + wait) as f64 / run as f64
    } else {
        1.0
    };
    Some((slowdown, run as f64 / wall, wait as f64 / wall))
}

/// Parse one `schedstat` line: "run_ns wait_ns timeslices".
pub fn parse_schedstat(text: &str) -> Option<SchedTime> {
    let mut f = text.split_ascii_whitespace();
    Some(SchedTime {
        run_ns: f.next()?.parse().ok()?,
        wait_ns: f.next()?.parse().ok()?,
    })
}

/// Call `f` with each live thread of process `pid` and its scheduler time
/// (`/proc/PID/task/TID/schedstat`); `false` when the process is gone or no thread's
/// schedstat could be read.
fn for_each_thread_schedstat(pid: u32, mut f: impl FnMut(u32, SchedTime)) -> bool {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return false;
    };
    let mut any = false;
    for task in tasks.flatten() {
        let Some(tid) = task
            .file_name()
            .to_str()
            .and_then(|t| t.parse::<u32>().ok())
        else {
            continue;
        };
        // a thread may exit between the listing and the read
        if let Some(t) = std::fs::read_to_string(task.path().join("schedstat"))
            .ok()
            .and_then(|s| parse_schedstat(&s))
        {
            f(tid, t);
            any = true;
        }
    }
    any
}

/// The scheduler time of process `pid`, its live threads summed; `None` when the process
/// is gone or the kernel keeps no schedstat. A thread that exits takes its time with it, so
/// the sum may go down between two samples: compare samples with checked differences.
pub fn process_sched_time(pid: u32) -> Option<SchedTime> {
    let mut sum = SchedTime::default();
    for_each_thread_schedstat(pid, |_, t| {
        sum.run_ns += t.run_ns;
        sum.wait_ns += t.wait_ns;
    })
    .then_some(sum)
}

/// Each live thread of process `pid` with its scheduler time (time on a CPU plus time
/// runnable in a run queue, ns), for [`ThreadTimes::progress_since`]; `None` when the
/// process is gone or the kernel keeps no schedstat.
pub fn process_thread_times(pid: u32) -> Option<ThreadTimes> {
    let mut threads = Vec::new();
    for_each_thread_schedstat(pid, |tid, t| threads.push((tid, t.run_ns + t.wait_ns)))
        .then_some(ThreadTimes { threads })
}

/// The scheduler time of each live thread of a process at one instant.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ThreadTimes {
    /// `(thread id, run + wait ns)`.
    pub threads: Vec<(u32, u64)>,
}

impl ThreadTimes {
    /// Scheduler time the process's threads gained since `earlier` (ns): each thread's
    /// growth, a thread born since counted whole. Unlike the difference of two sums, a
    /// thread that exited in between does not hide the others' progress: llama.cpp starts
    /// and joins a worker thread per graph it computes, and the summed time of a reasoner
    /// busy deciding once went down, which read as a stalled process and killed it.
    pub fn progress_since(&self, earlier: &ThreadTimes) -> u64 {
        self.threads
            .iter()
            .map(|&(tid, now)| {
                let before = earlier
                    .threads
                    .iter()
                    .find(|(t, _)| *t == tid)
                    .map_or(0, |&(_, ns)| ns);
                now.saturating_sub(before)
            })
            .sum()
    }
}

/// The memory of one process.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ProcessMemory {
    /// Resident set size (bytes): its pages in RAM, shared ones counted whole.
    pub rss_bytes: u64,
    /// Proportional set size (bytes): shared pages divided among the processes mapping
    /// them, so that the PSS of several processes adds up to what they hold together
    /// (`None` where the kernel has no `smaps_rollup`).
    pub pss_bytes: Option<u64>,
}

/// Parse `/proc/PID/smaps_rollup` (its `Rss:` and `Pss:` lines, in kB).
pub fn parse_smaps_rollup(text: &str) -> Option<ProcessMemory> {
    let field = |name: &str| {
        text.lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map(|kib| kib * 1024)
    };
    Some(ProcessMemory {
        rss_bytes: field("Rss:")?,
        pss_bytes: field("Pss:"),
    })
}

/// The memory of process `pid` (`/proc/PID/smaps_rollup`, else the resident pages of
/// `/proc/PID/statm`); `None` when it is gone or not readable.
pub fn process_memory(pid: u32) -> Option<ProcessMemory> {
    if let Some(m) = std::fs::read_to_string(format!("/proc/{pid}/smaps_rollup"))
        .ok()
        .and_then(|t| parse_smaps_rollup(&t))
    {
        return Some(m);
    }
    let statm = std::fs::read_to_string(format!("/proc/{pid}/statm")).ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) }.max(4096) as u64;
    Some(ProcessMemory {
        rss_bytes: pages * page,
        pss_bytes: None,
    })
}

/// The state letter of process `pid` from `/proc/PID/stat` (`R`, `S`, `D`, `T` stopped,
/// `t` traced, `Z` zombie...); `None` when it is gone.
pub fn process_state(pid: u32) -> Option<char> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    parse_stat_state(&text)
}

/// The state letter of a `/proc/PID/stat` line (after the parenthesised command name, which
/// may itself contain spaces and parentheses).
pub fn parse_stat_state(text: &str) -> Option<char> {
    let after = &text[text.rfind(')')? + 1..];
    after.trim_start().chars().next()
}

/// The thread ids of process `pid`.
pub fn process_threads(pid: u32) -> std::io::Result<Vec<i32>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(Path::new("/proc").join(pid.to_string()).join("task"))? {
        if let Some(tid) = entry?.file_name().to_str().and_then(|s| s.parse().ok()) {
            out.push(tid);
        }
    }
    Ok(out)
}

/// Busy cores of `cpus` between two `/proc/stat` samples ([`read_proc_stat`]); a CPU
/// missing from either sample counts as idle.
pub fn busy_cores(
    before: &BTreeMap<usize, CpuTicks>,
    after: &BTreeMap<usize, CpuTicks>,
    cpus: &[usize],
) -> f64 {
    cpus.iter()
        .filter_map(|c| {
            let (a, b) = (before.get(c)?, after.get(c)?);
            let total = b.total.checked_sub(a.total)?;
            let busy = b.busy.checked_sub(a.busy)?;
            (total > 0).then(|| busy as f64 / total as f64)
        })
        .sum()
}

/// Executors and their load.
#[derive(Debug, Clone)]
pub struct ExecutorRegistry {
    executors: Vec<ExecutorInfo>,
    accelerators: Vec<AcceleratorInfo>,
    providers: Option<Vec<String>>,
    last: BTreeMap<usize, CpuTicks>,
    pressure: Option<f64>,
}

impl ExecutorRegistry {
    /// The declared executors (name, resolved CPU set) plus one `cpuN` executor per CPU of
    /// `online` that no declared executor is exactly.
    pub fn discover(declared: &[(String, CpuSet)], online: &CpuSet) -> Self {
        let mut executors: Vec<ExecutorInfo> = declared
            .iter()
            .map(|(name, cpus)| ExecutorInfo {
                name: name.clone(),
                cpus: cpus.clone(),
                origin: ExecutorOrigin::Declared,
                busy: 0.0,
            })
            .collect();
        for &cpu in online.cpus() {
            let Ok(set) = CpuSet::parse(&cpu.to_string()) else {
                continue;
            };
            if executors.iter().any(|e| e.cpus == set) {
                continue;
            }
            executors.push(ExecutorInfo {
                name: format!("cpu{cpu}"),
                cpus: set,
                origin: ExecutorOrigin::Discovered,
                busy: 0.0,
            });
        }
        Self {
            executors,
            accelerators: Vec::new(),
            providers: None,
            last: read_proc_stat(),
            pressure: cpu_pressure(),
        }
    }

    /// Every executor.
    pub fn executors(&self) -> &[ExecutorInfo] {
        &self.executors
    }

    /// Record what ONNX Runtime reported: its execution providers and the accelerators they
    /// found ([`accelerators_from`]).
    pub fn set_accelerators(&mut self, providers: Vec<String>, accelerators: Vec<AcceleratorInfo>) {
        self.providers = Some(providers);
        self.accelerators = accelerators;
    }

    /// The accelerators ONNX Runtime reported (empty when none, or not asked).
    pub fn accelerators(&self) -> &[AcceleratorInfo] {
        &self.accelerators
    }

    /// The execution providers ONNX Runtime reported; `None` when it was not asked (no
    /// provisioned runtime).
    pub fn providers(&self) -> Option<&[String]> {
        self.providers.as_deref()
    }

    /// The executor named `name`.
    pub fn by_name(&self, name: &str) -> Option<&ExecutorInfo> {
        self.executors.iter().find(|e| e.name == name)
    }

    /// The executor whose CPU set is exactly `cpus`.
    pub fn by_cpus(&self, cpus: &CpuSet) -> Option<&ExecutorInfo> {
        self.executors.iter().find(|e| &e.cpus == cpus)
    }

    /// Machine-wide CPU pressure at the last sample (see [`cpu_pressure`]).
    pub fn pressure(&self) -> Option<f64> {
        self.pressure
    }

    /// Read `/proc/stat` again and set every executor's busy cores over the interval since
    /// the last sample.
    pub fn sample(&mut self) {
        let now = read_proc_stat();
        self.apply(&now);
        self.last = now;
        self.pressure = cpu_pressure();
    }

    fn apply(&mut self, now: &BTreeMap<usize, CpuTicks>) {
        for e in &mut self.executors {
            e.busy = busy_cores(&self.last, now, e.cpus.cpus());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accelerators_are_the_non_cpu_devices_named_by_provider_and_id() {
        let d =
            |p: &str, k: &str, v: &str, id: u32| (p.to_string(), k.to_string(), v.to_string(), id);
        let devices = [
            d("CPUExecutionProvider", "cpu", "AMD", 0),
            d("CUDAExecutionProvider", "gpu", "NVIDIA", 0),
            d("CUDAExecutionProvider", "gpu", "NVIDIA", 1),
            d("CUDAExecutionProvider", "gpu", "NVIDIA", 1),
            d("QNNExecutionProvider", "NPU", "Qualcomm", 0),
        ];
        let a = accelerators_from(&devices);
        let names: Vec<&str> = a.iter().map(|a| a.name.as_str()).collect();
        assert_eq!(names, ["cuda0", "cuda1", "qnn0"]);
        assert_eq!(a[2].kind, "npu");
        assert_eq!(a[0].provider, "CUDAExecutionProvider");
        assert!(
            accelerators_from(&devices[..1]).is_empty(),
            "a CPU is no accelerator"
        );
        let mut r = ExecutorRegistry::discover(&[], &CpuSet::parse("0").unwrap());
        assert_eq!(r.providers(), None);
        r.set_accelerators(vec!["CPUExecutionProvider".into()], a.clone());
        assert_eq!(r.accelerators(), &a[..]);
        assert_eq!(r.providers().unwrap(), ["CPUExecutionProvider"]);
    }

    const STAT: &str = "cpu  10 0 10 80 0 0 0 0 0 0\n\
                        cpu0 5 0 5 40 0 0 0 0 0 0\n\
                        cpu1 5 0 5 40 0 0 0 0 0 0\n\
                        intr 1 2 3\n";

    #[test]
    fn proc_stat_gives_busy_and_total_ticks_per_cpu() {
        let t = parse_proc_stat(STAT);
        assert_eq!(t.len(), 2);
        assert_eq!(
            t[&1],
            CpuTicks {
                busy: 10,
                total: 50
            }
        );
    }

    #[test]
    fn executors_get_busy_cores_from_two_samples() {
        let zero = CpuSet::parse("0").unwrap();
        let online = CpuSet::parse("0-1").unwrap();
        let mut reg = ExecutorRegistry::discover(&[("control".into(), zero)], &online);
        // cpu0 is declared as `control`; cpu1 is discovered
        let names: Vec<&str> = reg.executors().iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["control", "cpu1"]);
        reg.last = parse_proc_stat(STAT);
        // cpu0: 50 more ticks, 50 busy; cpu1: 100 more ticks, 25 busy
        let later = "cpu0 30 0 30 40 0 0 0 0\ncpu1 20 0 15 115 0 0 0 0\n";
        reg.apply(&parse_proc_stat(later));
        assert!((reg.executors()[0].busy - 1.0).abs() < 1e-9);
        assert!((reg.executors()[1].busy - 0.25).abs() < 1e-9);
        assert_eq!(reg.by_name("cpu1").unwrap().capacity(), 1.0);
    }

    #[test]
    fn stat_lines_and_schedstat_parse() {
        assert_eq!(parse_stat_state("123 (aeris role) T 1 2"), Some('T'));
        assert_eq!(parse_stat_state("123 (a (b) c) S 1 2"), Some('S'));
        assert_eq!(parse_stat_state("garbage"), None);
        assert_eq!(
            parse_schedstat("100 20 3\n"),
            Some(SchedTime {
                run_ns: 100,
                wait_ns: 20
            })
        );
        assert_eq!(parse_schedstat("x"), None);
    }

    #[test]
    fn smaps_rollup_parses_and_this_process_has_memory() {
        let text = "55d0-7ffe ---p 00000000 00:00 0  [rollup]\nRss:    2048 kB\nPss:    1024 kB\nPss_Anon: 512 kB\n";
        assert_eq!(
            parse_smaps_rollup(text),
            Some(ProcessMemory {
                rss_bytes: 2048 * 1024,
                pss_bytes: Some(1024 * 1024)
            })
        );
        assert_eq!(parse_smaps_rollup("Pss: 1 kB"), None);
        let own = process_memory(std::process::id()).unwrap();
        assert!(own.rss_bytes > 0);
        assert!(own.pss_bytes.is_none_or(|p| p > 0 && p <= own.rss_bytes));
    }

    #[test]
    fn this_process_has_threads_a_state_and_sched_time() {
        let pid = std::process::id();
        assert!(process_threads(pid).unwrap().contains(&(pid as i32)));
        // a child waiting on its input (a process's own /proc/self/stat is emulated under
        // qemu-user, where the aarch64 build's tests run)
        let mut child = std::process::Command::new("cat")
            .stdin(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let state = process_state(child.id());
        drop(child.stdin.take());
        child.wait().unwrap();
        // one of the kernel's states (just spawned on a busy machine it may still be
        // running, or in disk sleep while exec reads `cat`, before it waits on its input)
        assert!(state.is_some_and(|c| "RSDTtWXZIP".contains(c)), "{state:?}");
        // CONFIG_SCHED_INFO kernels keep schedstat; where they do, the process's figure
        // holds at least this thread's time (the test harness's other threads come and go,
        // so the sum itself may drop between two samples)
        if let Some(own) = std::fs::read_to_string("/proc/thread-self/schedstat")
            .ok()
            .and_then(|s| parse_schedstat(&s))
        {
            let mut x = 0u64;
            for i in 0..200_000u64 {
                x = x.wrapping_add(std::hint::black_box(i));
            }
            std::hint::black_box(x);
            let whole = process_sched_time(pid).unwrap();
            assert!(whole.run_ns >= own.run_ns);
            assert!(own.run_ns > 0);
        }
    }

    #[test]
    fn a_thread_that_exits_does_not_hide_the_others_progress() {
        // a reasoner mid-decision: its main thread 10 computed 300 ms more, its worker 11
        // (1.2 s) was joined and worker 12 started: the summed time went down
        let before = ThreadTimes {
            threads: vec![(10, 2_000_000_000), (11, 1_200_000_000)],
        };
        let after = ThreadTimes {
            threads: vec![(10, 2_300_000_000), (12, 50_000_000)],
        };
        let sum = |t: &ThreadTimes| t.threads.iter().map(|x| x.1).sum::<u64>();
        assert!(sum(&after) < sum(&before));
        assert_eq!(after.progress_since(&before), 350_000_000);
        // a blocked process: the same threads, no time gained
        assert_eq!(before.progress_since(&before), 0);
        // this process, read twice around some work: it progressed
        let pid = std::process::id();
        let first = process_thread_times(pid).unwrap();
        let mut x = 0u64;
        for i in 0..2_000_000u64 {
            x = x.wrapping_add(std::hint::black_box(i));
        }
        std::hint::black_box(x);
        assert!(process_thread_times(pid).unwrap().progress_since(&first) > 0);
        assert!(process_thread_times(u32::MAX).is_none());
    }
}
