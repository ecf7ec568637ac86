//! What the supervisor knows about one role ([`RoleRuntime`]): its process and restarts, its
//! binding, and its heartbeat statistics (sequence gaps, the latency window and its
//! percentiles, the recent cycles the scheduling policy and the variant ladder read).

use super::recent_cycles::RecentCycles;
use super::replacement::{ReturnTo, SwapInProgress};
use crate::executors::SchedTime;
use crate::launch::{PlannedFallback, PlannedRole};
use crate::restart::{RestartPolicy, RoleExit};
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::stats::LatencyWindow;
use aeris_schemas::RoleKind;
use aeris_schemas::{RoleHeartbeat, RoleStatus};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::{Duration, Instant};

/// Heartbeats per role kept for the latency percentiles.
pub const LATENCY_WINDOW: usize = 256;

/// Scheduler samples kept per role (the demand window).
pub(super) const SCHED_SAMPLES: usize = 9;

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

/// A role on another host: the link it depends on.
#[derive(Debug, Clone)]
pub(super) struct RemoteLink {
    /// The host.
    pub(super) host: String,
    /// Silent this long: the link counts as lost.
    pub(super) timeout: Duration,
    /// What takes over on the flight's host when it is lost.
    pub(super) fallback: Option<PlannedFallback>,
    /// The link was lost (counted once; the fallback is under way or failed).
    pub(super) lost: bool,
    /// The role's restart policy, held while its link is lost and no fallback runs (a
    /// bridge on that host), back in force when the link returns.
    pub(super) held_policy: Option<crate::restart::RestartPolicy>,
}

/// What the supervisor knows about one role.
#[derive(Debug)]
pub struct RoleRuntime {
    /// Role name.
    pub(super) name: String,
    /// Role kind.
    pub(super) kind: RoleKind,
    /// Variant it runs.
    pub(super) variant: String,
    /// CPU list it is bound to ("" = unbound).
    pub(super) cpus: String,
    /// The CPUs its processes are bound to (`None`: unbound).
    pub(super) cpu_set: Option<CpuSet>,
    /// The spec its processes start from.
    pub(super) spec_path: PathBuf,
    /// The log of its running process.
    pub(super) log_path: PathBuf,
    /// When an exit is restarted.
    pub(super) policy: RestartPolicy,
    /// The restart budget.
    pub(super) max_restarts: u32,
    /// The first restart's backoff (it doubles).
    pub(super) backoff_ms: u64,
    /// Its running process.
    pub(super) child: Option<Child>,
    /// Its pid.
    pub(super) pid: Option<u32>,
    /// Pids of its processes that exited or were replaced (their late heartbeats are dropped).
    pub(super) old_pids: Vec<u32>,
    /// Where it is in its life.
    pub(super) state: RoleState,
    /// Restarts so far.
    pub(super) restarts: u32,
    /// How its last process ended.
    pub(super) last_exit: Option<RoleExit>,
    /// The last valid heartbeat.
    pub(super) last_heartbeat: Option<RoleHeartbeat>,
    /// Heartbeats from all its processes.
    pub(super) heartbeats: u64,
    /// Heartbeats from its running process.
    pub(super) incarnation_heartbeats: u64,
    /// Heartbeat sequence gaps.
    pub(super) heartbeat_gaps: u64,
    /// Latencies of its last [`LATENCY_WINDOW`] worked cycles.
    pub(super) window: LatencyWindow,
    /// p50, p95, p99 of `window` (ms).
    pub(super) latency_ms: Option<[f64; 3]>,
    /// Variants it may be swapped to.
    pub(super) pool: Vec<String>,
    /// Instance number of its running process.
    pub(super) instance: u32,
    /// The new side of a swap under way.
    pub(super) swap: Option<SwapInProgress>,
    /// Its executor's name (empty: unbound).
    pub(super) executor: String,
    /// The accelerator its model sessions run on (its executor's), if any.
    pub(super) accelerator: Option<aeris_runtime::accelerator::Accelerator>,
    /// Its latency budget (ms).
    pub(super) budget_ms: Option<f64>,
    /// Live moves so far.
    pub(super) migrations: u32,
    /// Stalls detected so far.
    pub(super) stalls: u32,
    /// Why it is bound where it is.
    pub(super) binding: String,
    /// A `Running` heartbeat came from the current process (stall detection starts then).
    pub(super) running: bool,
    /// When the last heartbeat of the current process arrived.
    pub(super) heard_at: Option<Instant>,
    /// When the current process was started (or took over).
    pub(super) started_at: Option<Instant>,
    /// Run + run-queue wait time of each thread of the process when its silence was first
    /// noticed.
    pub(super) silence_probe: Option<crate::executors::ThreadTimes>,
    /// Scheduler time samples, one per scheduling tick (newest last).
    pub(super) sched: VecDeque<(Instant, SchedTime)>,
    /// The last few worked cycles (the DS signal).
    pub(super) recent: RecentCycles,
    /// Its variant ladder, most capable first (empty: none).
    pub(super) ladder: Vec<String>,
    /// Worked cycles reported by any of its processes (the ladder's cycle count).
    pub(super) worked_cycles: u64,
    /// Latency (ms) of the newest worked cycle.
    pub(super) last_cycle_ms: Option<f64>,
    /// On another host: the link it depends on (`None`: it runs on the flight's host).
    pub(super) link: Option<RemoteLink>,
    /// The workflow's fallback for it (`fallback`), for whenever it runs on another host.
    pub(super) declared_fallback: Option<PlannedFallback>,
    /// Running its fallback since its link was lost: where it returns when the link is back.
    pub(super) returns_to: Option<ReturnTo>,
    /// Its worker threads as asked: its `threads` parameter, else 2 for a reasoner (a
    /// language model's default) and 1 for the others (the policy takes at most the CPUs it
    /// runs on: a language model starts with no more); never moved live onto fewer CPUs.
    pub(super) threads: usize,
    /// Its latency (ms) as last measured on each accelerator executor it ran on (by name).
    pub(super) accelerator_ms: Vec<(String, f64)>,
    /// Its own cycle (ms, without slowdown or link) as last measured on a CPU executor.
    pub(super) cpu_base_ms: Option<f64>,
}

impl RoleRuntime {
    /// Role name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Role kind.
    pub fn kind(&self) -> RoleKind {
        self.kind
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
    /// The accelerator its model sessions run on (`cuda:0`), if any.
    pub fn accelerator(&self) -> Option<aeris_runtime::accelerator::Accelerator> {
        self.accelerator
    }
    /// Why it is bound where it is.
    pub fn binding(&self) -> &str {
        &self.binding
    }
    /// The other host its process runs on (`None`: the flight's host, its fallback's
    /// included while the link is lost).
    pub fn host(&self) -> Option<&str> {
        self.link
            .as_ref()
            .filter(|l| !l.lost)
            .map(|l| l.host.as_str())
    }

    /// A role as planned, not started yet: its spec is at `spec_path`, its log goes to
    /// `log_path`.
    pub(super) fn planned(planned: PlannedRole, spec_path: PathBuf, log_path: PathBuf) -> Self {
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
            fallback,
        } = planned;
        let link = spec.remote.as_ref().map(|r| RemoteLink {
            host: r.host.clone(),
            timeout: Duration::from_millis(r.link_timeout_ms),
            fallback: fallback.clone(),
            lost: false,
            held_policy: None,
        });
        let accelerator = spec.accelerator.as_deref().and_then(|a| a.parse().ok());
        let threads = spec.param_f64("threads").map_or(
            if spec.kind == RoleKind::Reasoning {
                2
            } else {
                1
            },
            |t| t.clamp(1.0, 64.0) as usize,
        );
        RoleRuntime {
            threads,
            accelerator,
            link,
            returns_to: None,
            accelerator_ms: Vec::new(),
            cpu_base_ms: None,
            declared_fallback: fallback,
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
            recent: RecentCycles::default(),
            ladder,
            worked_cycles: 0,
            last_cycle_ms: None,
        }
    }

    /// The host it runs on, for messages: `host `NAME`` or `the flight's host`.
    pub(super) fn host_label(&self) -> String {
        match &self.link {
            Some(l) => format!("host `{}`", l.host),
            None => "the flight's host".to_string(),
        }
    }

    /// Its state in words, for errors ("running, pid 123", "stopped, last exit code 1").
    pub(super) fn describe_state(&self) -> String {
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
    pub(super) fn new_incarnation(&mut self) {
        self.running = false;
        self.heard_at = None;
        self.started_at = Some(Instant::now());
        self.silence_probe = None;
        self.sched.clear();
        self.recent = RecentCycles::default();
    }

    /// It failed to start on accelerator executor `executor`: its latency there is taken
    /// as unbounded, so the re-binding policy neither predicts it fits there nor probes it.
    pub(super) fn ruled_out_on(&mut self, executor: &str) {
        match self.accelerator_ms.iter_mut().find(|(n, _)| n == executor) {
            Some(m) => m.1 = f64::INFINITY,
            None => self
                .accelerator_ms
                .push((executor.to_string(), f64::INFINITY)),
        }
    }

    /// Record a heartbeat; returns `true` when it is the first of the current process.
    pub(super) fn record(&mut self, hb: &RoleHeartbeat, status: RoleStatus) -> bool {
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
        let now = Instant::now();
        if working && hb.worked == 1 {
            let ms = hb.cycle_latency_ns as f64 / 1e6;
            self.window.push(ms);
            self.recent.push(ms, now, &self.sched);
            self.worked_cycles += 1;
            self.last_cycle_ms = Some(ms);
            self.latency_ms = self.window.percentiles([50.0, 95.0, 99.0]);
        }
        self.running |= working;
        self.heard_at = Some(now);
        self.silence_probe = None;
        self.last_heartbeat = Some(*hb);
        self.heartbeats += 1;
        self.incarnation_heartbeats += 1;
        first
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

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

    /// A role that never ran (for the supervisor's unit tests).
    pub(in crate::supervisor) fn runtime() -> RoleRuntime {
        RoleRuntime {
            threads: 1,
            accelerator: None,
            link: None,
            returns_to: None,
            accelerator_ms: Vec::new(),
            cpu_base_ms: None,
            declared_fallback: None,
            name: "r".into(),
            kind: RoleKind::Hub,
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
            recent: RecentCycles::default(),
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
