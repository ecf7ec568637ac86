//! Hot swap, make-before-break: the new process of a role loads and warms up beside the
//! running one (under SCHED_IDLE where the supervisor may restore SCHED_OTHER); once it
//! is ready (its first heartbeat after warm-up) and the old process has completed one more
//! cycle (at most [`handover_wait`]), it becomes the role and the old process retires
//! (SIGTERM, SIGKILL after [`RETIRE_GRACE`]); a new process that exits or stays silent is
//! rolled back.

use super::Supervisor;
use super::error::SwapError;
use super::events::{Handover, SupervisorEvent};
use super::logs::{log_tail, open_log, quote_tail};
use super::replacement::{Placement, SwapInProgress};
use super::role_runtime::{LATENCY_WINDOW, RemoteLink, RoleRuntime, RoleState};
use super::spawn::{LoadPolicy, may_leave_idle, set_normal_policy};
use super::warm_up_gate::WarmUpGate;
use crate::restart::RoleExit;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::LatencyWindow;
use aeris_schemas::RoleKind;
use std::path::Path;
use std::process::Child;
use std::time::{Duration, Instant};

/// How long a swapped-in process may take, by default, to load, warm up and report its
/// first heartbeat before the swap is rolled back.
pub const DEFAULT_SWAP_READY_TIMEOUT: Duration = Duration::from_secs(90);
/// How long a replaced process has to exit after SIGTERM before it gets SIGKILL.
pub const RETIRE_GRACE: Duration = Duration::from_secs(5);
/// Lines of a failed swap's log quoted in its reply (the error a role prints is its last).
const SWAP_LOG_LINES: usize = 4;

/// How long a ready swap waits, at most, for the replaced process to complete one more
/// cycle before it commits: one heartbeat and the decision deadline, the longest a
/// reasoner's cycle may take. Committing right after the replaced process's cycle leaves
/// the new one a whole cycle for its first: a reasoner stopped mid-heartbeat, with its next
/// decision not made, cost the flight a heartbeat without a decision while the new one
/// waited for a fresh S_t (measured: one in every few swaps under two busy threads).
pub(super) fn handover_wait(timing: &aeris_runtime::spec::TimingSpec) -> Duration {
    Duration::from_millis(
        timing
            .heartbeat_period_ms
            .saturating_add(timing.decision_deadline_ms),
    )
}

/// A replaced process, asked to stop, until it exits.
#[derive(Debug)]
struct Retiring {
    /// The role.
    name: String,
    /// The variant it was swapped to.
    variant: String,
    /// Where the new process runs, when it moved.
    place: Option<String>,
    /// The replaced process's pid.
    pid: u32,
    /// The replaced process.
    child: Child,
    /// When it was asked to stop.
    since: Instant,
}

/// The replaced processes of committed swaps, asked to stop, until they exit.
#[derive(Debug, Default)]
pub(super) struct RetiringProcesses {
    /// The processes, in the order they were asked to stop.
    processes: Vec<Retiring>,
}

impl RetiringProcesses {
    /// Ask `old`, the process role `name` ran before its swap to `variant`, to stop
    /// (SIGTERM) at `now`, and watch it until it exits: the swap is done then
    /// ([`SupervisorEvent::SwapDone`]).
    pub(super) fn retire(
        &mut self,
        name: &str,
        variant: String,
        place: Option<String>,
        mut old: Child,
        now: Instant,
        events: &mut Vec<SupervisorEvent>,
    ) {
        let pid = old.id();
        if let Ok(raw) = libc::pid_t::try_from(pid) {
            // SAFETY: kill has no memory-safety preconditions; the pid is our unreaped
            // child, so it cannot have been reused.
            unsafe { libc::kill(raw, libc::SIGTERM) };
        }
        match old.try_wait() {
            Ok(None) => self.processes.push(Retiring {
                name: name.to_string(),
                variant,
                place,
                pid,
                child: old,
                since: now,
            }),
            exited => events.push(SupervisorEvent::SwapDone {
                name: name.to_string(),
                variant,
                old_pid: Some(pid),
                exit: exited.ok().flatten().map(RoleExit::from_status),
                place,
            }),
        }
    }

    /// Reap replaced processes; SIGKILL those still running after [`RETIRE_GRACE`].
    pub(super) fn reap(&mut self, events: &mut Vec<SupervisorEvent>) {
        let mut i = 0;
        while i < self.processes.len() {
            let r = &mut self.processes[i];
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
                    let r = self.processes.swap_remove(i);
                    events.push(SupervisorEvent::SwapDone {
                        name: r.name,
                        variant: r.variant,
                        old_pid: Some(r.pid),
                        exit: Some(exit),
                        place: r.place,
                    });
                }
            }
        }
    }

    /// Kill every replaced process still exiting.
    pub(super) fn kill_all(&mut self) {
        for mut r in self.processes.drain(..) {
            let _ = r.child.kill();
            let _ = r.child.wait();
        }
    }
}

impl RoleRuntime {
    /// Commit `swap`: its process, ready since `now`, becomes the role's running process,
    /// with a fresh latency window (a new model's latency is a new distribution). Returns
    /// the replaced process.
    fn take_over(&mut self, swap: SwapInProgress, now: Instant) -> (Option<u32>, Option<Child>) {
        let swap_placement = swap.placement;
        let old_pid = self.pid.take();
        let old_child = self.child.take();
        self.variant = swap.variant;
        self.child = Some(swap.child);
        self.pid = Some(swap.pid);
        self.instance = swap.instance;
        self.spec_path = swap.spec_path;
        self.log_path = swap.log_path;
        self.state = RoleState::Running;
        self.last_heartbeat = swap.ready.map(|(hb, _)| hb);
        self.heartbeats += 1;
        self.incarnation_heartbeats = 1;
        self.new_incarnation();
        self.running = true;
        self.heard_at = Some(now);
        self.window = LatencyWindow::new(LATENCY_WINDOW);
        self.latency_ms = None;
        if let Some(p) = swap_placement {
            // it now runs there: behind that host's link, or on the flight's host
            self.cpus = match &p.remote {
                Some(r) => r.cpus.clone(),
                None => p.cpus.as_ref().map(|c| c.to_string()).unwrap_or_default(),
            };
            self.cpu_set = p.cpus;
            self.executor = p.executor;
            self.accelerator = p.accelerator;
            self.binding = p.why;
            if let Some(policy) = p.policy {
                self.policy = policy;
            }
            self.link = p.remote.map(|r| RemoteLink {
                host: r.host,
                timeout: Duration::from_millis(r.link_timeout_ms),
                fallback: p.link_fallback,
                lost: false,
                held_policy: None,
            });
            self.migrations += 1;
        }
        (old_pid, old_child)
    }
}

impl Supervisor {
    /// Start replacing role `role` by `variant`, make-before-break: a new process (a new
    /// instance number) loads and warms up beside the running one, under SCHED_IDLE so it
    /// takes only idle CPU; with its first heartbeat, right after the old process's next
    /// completed cycle, it becomes the role (normal policy restored) and the old process
    /// is stopped ([`SupervisorEvent::SwapReady`], then
    /// [`SupervisorEvent::SwapDone`]). If it exits
    /// first, or sends no heartbeat within `ready_timeout`, it is stopped and the old process
    /// keeps running ([`SupervisorEvent::SwapFailed`]). Returns the new pid.
    pub fn begin_swap(
        &mut self,
        role: &str,
        variant: &str,
        ready_timeout: Duration,
    ) -> Result<u32, SwapError> {
        self.start_swap(role, variant, ready_timeout, true, None)
    }

    /// [`Supervisor::begin_swap`], with the new process loading idle (`load_idle`) or at
    /// the normal policy. The variant ladder loads a lighter variant at the normal policy:
    /// the role it replaces already misses its budget, so the CPUs are saturated, and an
    /// idle load gets no CPU at all (measured: SmolLM2 stepping in for Gemma-3 on 2 busy
    /// CPUs was not ready within 90 s and the step was rolled back). With `placement` the
    /// new process runs there (another host, or the flight's host for a role behind a
    /// link), whatever the role's pool.
    pub(super) fn start_swap(
        &mut self,
        role: &str,
        variant: &str,
        ready_timeout: Duration,
        load_idle: bool,
        placement: Option<Placement>,
    ) -> Result<u32, SwapError> {
        let Some(i) = self.roles.iter().position(|r| r.name == role) else {
            return Err(SwapError::UnknownRole {
                role: role.to_string(),
                known: self.role_names(),
            });
        };
        if self.on_sim_clock {
            return Err(SwapError::SimulatedTime {
                role: role.to_string(),
            });
        }
        let instance = self.launcher.next_instance();
        let exe = self.launcher.exe().to_path_buf();
        let r = &mut self.roles[i];
        if let Some(why) = r.kind.info().swap_refusal {
            return Err(SwapError::NotSwappable {
                role: r.name.clone(),
                kind: r.kind,
                why,
            });
        }
        if placement.is_none() && !r.pool.iter().any(|v| v == variant) {
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
        let mut spec = aeris_runtime::RoleSpec::load(&r.spec_path)
            .map_err(|e| prepare(aeris_runtime::error_chain::chain(&e).to_string()))?;
        spec.variant = variant.to_string();
        if let Some(p) = &placement {
            spec.remote = p.remote.clone();
            spec.cpus = p.cpus.as_ref().map(|c| c.to_string()).unwrap_or_default();
            spec.accelerator = p.accelerator.map(|a| a.to_string());
        }
        let cpus = placement
            .as_ref()
            .map_or(r.cpu_set.clone(), |p| p.cpus.clone());
        let dir = r.spec_path.parent().unwrap_or(Path::new("."));
        let spec_path = dir.join(format!("{}.i{instance}.json", r.name));
        let json = serde_json::to_string_pretty(&spec).map_err(|e| prepare(e.to_string()))?;
        std::fs::write(&spec_path, json)
            .map_err(|e| prepare(format!("{}: {e}", spec_path.display())))?;
        let log_dir = r.log_path.parent().unwrap_or(Path::new("."));
        let log_path = log_dir.join(format!("{}.i{instance}.log", r.name));
        let what = placement.as_ref().map_or_else(
            || "hot swap".to_string(),
            |p| format!("{} to {}", p.why, p.place),
        );
        let header = format!(
            "=== aeris supervisor: {what} of role `{}` from `{}` to `{variant}`, instance {instance} on CPUs [{}], monotonic {} ns ===",
            r.name,
            r.variant,
            cpus.as_ref().map(|c| c.to_string()).unwrap_or_default(),
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
        let child = self
            .launcher
            .spawn(&spec_path, log, cpus.as_ref(), policy)
            .map_err(|e| cleanup(format!("cannot start `{}`: {e}", exe.display())))?;
        let pid = child.id();
        let now = Instant::now();
        let place = placement.as_ref().map(|p| p.place.clone());
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
            handover: false,
            handover_wait: handover_wait(&spec.timing),
            placement,
            abort: None,
            // on this host only: a move to another host starts a handle here, which relays
            gate: (policy == LoadPolicy::IdleUntilReady
                && r.kind == RoleKind::Reasoning
                && spec.remote.is_none())
            .then(|| WarmUpGate::new(spec.timing.heartbeat_period_ms.saturating_mul(1_000_000))),
        });
        self.pending.push(SupervisorEvent::SwapStarted {
            name: r.name.clone(),
            variant: variant.to_string(),
            old_pid: r.pid,
            new_pid: pid,
            instance,
            place,
        });
        Ok(pid)
    }

    /// Commit swaps whose new process works, roll back those whose new process died or
    /// timed out.
    pub(super) fn advance_swaps(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        let mut returns_failed = Vec::new();
        for role in &mut self.roles {
            let Some(swap) = role.swap.as_mut() else {
                continue;
            };
            if let Some(gate) = swap.gate.as_mut() {
                // the running process's latest heartbeat (not a copy per role and step)
                if let Some(hb) = role
                    .last_heartbeat
                    .as_ref()
                    .filter(|hb| Some(hb.pid) == role.pid)
                {
                    gate.observe(hb);
                }
                gate.apply(swap.pid, monotonic_ns(), swap.ready.is_some());
            }
            let failure = match swap.child.try_wait() {
                _ if swap.abort.is_some() => swap.abort.take(),
                Ok(Some(status)) => Some(format!(
                    "the new process exited ({}) before it was ready",
                    RoleExit::from_status(status)
                )),
                Err(e) => Some(format!("cannot wait on the new process: {e}")),
                Ok(None) => match swap.ready.map(|(_, at)| at) {
                    // a role whose link is lost sends no heartbeat: its fallback takes over
                    Some(_) if role.link.as_ref().is_some_and(|l| l.lost) => None,
                    Some(at) if swap.handover || now >= at + swap.handover_wait => None,
                    Some(_) => continue,
                    None if now >= swap.deadline => Some(format!(
                        "not ready (loaded, warmed up, first heartbeat) within {:.0} s",
                        (swap.deadline - swap.started).as_secs_f64()
                    )),
                    None => continue,
                },
            };
            let Some(swap) = role.swap.take() else {
                continue;
            };
            if let Some(why) = failure {
                let place = swap.placement.as_ref().map(|p| p.place.clone());
                let mut child = swap.child;
                let _ = child.kill();
                let _ = child.wait();
                if let Some(p) = swap.placement {
                    if p.accelerator.is_some() && p.remote.is_none() {
                        // it cannot run there (no device, no offload, out of memory): the
                        // policy predicts it never fits there, and probes it no more
                        role.ruled_out_on(&p.executor);
                    }
                    if let Some(policy) = p.policy {
                        // a fallback that never took over: the role waits, down, for its
                        // link (restarted when it is back, its policy restored then)
                        if let Some(link) = role.link.as_mut() {
                            link.held_policy = Some(policy);
                        }
                        if let Some(old) = role.child.as_mut() {
                            let _ = old.kill();
                        }
                        role.returns_to = None;
                    }
                    if let Some(back) = p.returning {
                        // a return that failed: tried again after another hysteresis
                        returns_failed.push(back.spec.host.clone());
                        role.returns_to = Some(back);
                    }
                }
                role.old_pids.push(swap.pid);
                let _ = std::fs::remove_file(&swap.spec_path);
                let mut reason = format!("{why}; its log {}:", swap.log_path.display());
                quote_tail(&mut reason, &log_tail(&swap.log_path, SWAP_LOG_LINES));
                events.push(SupervisorEvent::SwapFailed {
                    name: role.name.clone(),
                    variant: swap.variant,
                    reason,
                    place,
                });
                continue;
            }
            // commit: the new process is the role (normal policy back, on every thread)
            set_normal_policy(swap.pid);
            let (variant, new_pid, instance) = (swap.variant.clone(), swap.pid, swap.instance);
            let place = swap.placement.as_ref().map(|p| p.place.clone());
            let ready_at = swap.ready.map_or(now, |(_, at)| at);
            let ready_ms = ready_at.saturating_duration_since(swap.started).as_millis() as u64;
            let after_ms = now.saturating_duration_since(ready_at).as_millis() as u64;
            let handover = if role.child.is_none() {
                Handover::NoOldProcess
            } else if swap.handover {
                Handover::AfterCycle { after_ms }
            } else if role.link.as_ref().is_some_and(|l| l.lost) {
                Handover::LinkLost
            } else {
                Handover::Waited { after_ms }
            };
            let (old_pid, old_child) = role.take_over(swap, now);
            events.push(SupervisorEvent::SwapReady {
                name: role.name.clone(),
                variant: variant.clone(),
                old_pid,
                new_pid,
                instance,
                ready_ms,
                handover,
                place: place.clone(),
            });
            // then stop the old one; the swap is done when it has exited
            let Some(old) = old_child else {
                events.push(SupervisorEvent::SwapDone {
                    name: role.name.clone(),
                    variant,
                    old_pid: None,
                    exit: None,
                    place,
                });
                continue;
            };
            role.old_pids.push(old.id());
            self.retiring
                .retire(&role.name, variant, place, old, now, events);
        }
        self.links_up_since
            .retain(|(host, _)| !returns_failed.contains(host));
    }

    /// Kill the new sides of unfinished swaps and the replaced processes still exiting.
    pub(super) fn stop_swaps(&mut self) {
        for role in &mut self.roles {
            if let Some(mut swap) = role.swap.take() {
                let _ = swap.child.kill();
                let _ = swap.child.wait();
            }
        }
        self.retiring.kill_all();
    }
}
