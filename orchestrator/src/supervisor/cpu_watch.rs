//! Whether every CPU ran: one thread pinned to each CPU the supervisor may use wakes every
//! [`TICK`] and notes the time. A CPU can run no ordinary thread for seconds while the others
//! run: measured on CI's 2-CPU VM during the suite, a nice -20 thread pinned to one CPU went
//! unscheduled for 0.25-6 s at a time, while a SCHED_FIFO 99 thread pinned to the same CPU
//! woke on time (so the CPU ran, real-time work or the kernel held it; what exactly was not
//! identified). A role on that CPU does not run and its heartbeat is late: silence the
//! supervisor must not hold against the role, which it would otherwise kill as stalled, or
//! count as a lost link. [`CpuWatch::frozen_now`] says a CPU is held now (judge no silence),
//! [`CpuWatch::take_pause`] how long the longest hold since the last look lasted (discount
//! it, as a pause of the supervisor itself).

use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

/// A pause between two supervisor steps (called every ~20 ms) longer than this is time the
/// supervisor did not watch.
pub(super) const UNWATCHED_GAP: Duration = Duration::from_millis(300);

/// How often each CPU's watcher wakes.
const TICK: Duration = Duration::from_millis(20);

/// Nice value of a watcher: the highest an ordinary thread can have, so that it runs whenever
/// an ordinary thread of high weight (a role) could, and wakes late only when its CPU did not
/// run ordinary threads at all. (A SCHED_FIFO watcher would miss a CPU taken by real-time
/// work: on CI's VM a nice -20 thread went unscheduled for 4.2 s while a SCHED_FIFO 99 one on
/// the same CPU ran on time.) It wakes for microseconds per tick.
const WATCHER_NICE: libc::c_int = -20;

/// One CPU's watcher state, shared with its thread.
#[derive(Debug)]
struct CpuTicks {
    cpu: usize,
    /// When the watcher last woke (monotonic ns).
    last_ns: AtomicU64,
    /// The longest gap between two wake-ups over [`UNWATCHED_GAP`] since the last
    /// [`CpuWatch::take_pause`] (ns); 0 for none.
    pause_ns: AtomicU64,
}

/// The per-CPU watchers of a supervisor; they stop when it is dropped.
#[derive(Debug)]
pub(super) struct CpuWatch {
    cpus: Arc<[CpuTicks]>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// A pause of one CPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct CpuPause {
    /// The CPU.
    pub cpu: usize,
    /// How long it did not run (so far, for one paused now).
    pub gap: Duration,
}

impl CpuWatch {
    /// Start a watcher on each CPU the calling thread may run on. A watcher that cannot be
    /// pinned or started is left out (its CPU is then not watched, as before).
    pub(super) fn start() -> Self {
        let mine = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
        let now = monotonic_ns();
        let cpus: Arc<[CpuTicks]> = mine
            .cpus()
            .iter()
            .map(|&cpu| CpuTicks {
                cpu,
                last_ns: AtomicU64::new(now),
                pause_ns: AtomicU64::new(0),
            })
            .collect();
        let stop = Arc::new(AtomicBool::new(false));
        let mut threads = Vec::with_capacity(cpus.len());
        for i in 0..cpus.len() {
            let (shared, stop) = (Arc::clone(&cpus), Arc::clone(&stop));
            let spawned = std::thread::Builder::new()
                .name(format!("cpu-watch-{}", cpus[i].cpu))
                .spawn(move || watch(&shared[i], &stop));
            if let Ok(t) = spawned {
                threads.push(t);
            }
        }
        CpuWatch {
            cpus,
            stop,
            threads,
        }
    }

    /// The CPU paused longest right now, if one has not run for over [`UNWATCHED_GAP`].
    pub(super) fn frozen_now(&self) -> Option<CpuPause> {
        let now = monotonic_ns();
        self.cpus
            .iter()
            .map(|c| CpuPause {
                cpu: c.cpu,
                gap: Duration::from_nanos(now.saturating_sub(c.last_ns.load(Ordering::Acquire))),
            })
            .filter(|p| p.gap > UNWATCHED_GAP)
            .max_by_key(|p| p.gap)
    }

    /// The longest pause of a CPU that ended since the last call, if any.
    pub(super) fn take_pause(&self) -> Option<CpuPause> {
        self.cpus
            .iter()
            .map(|c| CpuPause {
                cpu: c.cpu,
                gap: Duration::from_nanos(c.pause_ns.swap(0, Ordering::AcqRel)),
            })
            .filter(|p| !p.gap.is_zero())
            .max_by_key(|p| p.gap)
    }
}

#[cfg(test)]
impl CpuWatch {
    /// A watch of one CPU with no thread: last seen `since` ago, with a pause of `pause`
    /// recorded (zero: none).
    pub(super) fn stub(cpu: usize, since: Duration, pause: Duration) -> Self {
        CpuWatch {
            cpus: Arc::from(vec![CpuTicks {
                cpu,
                last_ns: AtomicU64::new(monotonic_ns().saturating_sub(since.as_nanos() as u64)),
                pause_ns: AtomicU64::new(pause.as_nanos() as u64),
            }]),
            stop: Arc::new(AtomicBool::new(true)),
            threads: Vec::new(),
        }
    }
}

impl Drop for CpuWatch {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// A watcher's loop: pinned to its CPU, wakes every [`TICK`], records gaps.
fn watch(ticks: &CpuTicks, stop: &AtomicBool) {
    let Ok(only) = CpuSet::parse(&ticks.cpu.to_string()) else {
        return;
    };
    if only.bind_task(0).is_err() {
        // not pinned, it would watch whichever CPU it ran on: say nothing rather than wrong
        ticks.last_ns.store(u64::MAX, Ordering::Release);
        return;
    }
    // best effort: without the permission it keeps the supervisor's nice value
    // SAFETY: setpriority on the calling thread's id has no memory-safety preconditions.
    unsafe {
        let tid = libc::syscall(libc::SYS_gettid) as libc::id_t;
        libc::setpriority(libc::PRIO_PROCESS, tid, WATCHER_NICE);
    }
    let mut last = monotonic_ns();
    ticks.last_ns.store(last, Ordering::Release);
    while !stop.load(Ordering::Acquire) {
        std::thread::sleep(TICK);
        let now = monotonic_ns();
        let gap = now.saturating_sub(last);
        if gap > UNWATCHED_GAP.as_nanos() as u64 {
            ticks.pause_ns.fetch_max(gap, Ordering::AcqRel);
        }
        ticks.last_ns.store(now, Ordering::Release);
        last = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cpu_is_watched_and_none_is_paused_while_they_run() {
        let watch = CpuWatch::start();
        let mine = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
        assert_eq!(watch.cpus.len(), mine.cpus().len());
        // a watcher's first tick has been stored before it can be looked at
        assert!(
            watch
                .cpus
                .iter()
                .all(|c| c.last_ns.load(Ordering::Acquire) > 0)
        );
    }

    #[test]
    fn a_pause_is_reported_once_and_a_cpu_silent_now_is_frozen() {
        let watch = CpuWatch::start();
        // as a watcher records a pause of its CPU (its thread cannot be paused from here)
        watch.cpus[0]
            .pause_ns
            .fetch_max(700_000_000, Ordering::AcqRel);
        let pause = watch.take_pause().expect("the pause");
        assert_eq!(
            (pause.cpu, pause.gap),
            (watch.cpus[0].cpu, Duration::from_millis(700))
        );
        assert_eq!(watch.take_pause(), None);
        // a watcher whose last tick is a second old: its CPU is paused now
        let stopped = CpuWatch::stub(7, Duration::from_secs(1), Duration::ZERO);
        let frozen = stopped.frozen_now().expect("frozen");
        assert_eq!(frozen.cpu, 7);
        assert!(frozen.gap >= Duration::from_secs(1), "{frozen:?}");
    }
}
