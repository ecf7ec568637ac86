//! The supervisor's dynamic side: live moves between executors, latency-driven re-binding
//! (the initial check and every tick after), and stall detection.

use super::*;
use crate::ladder::{LadderConfig, LadderSample, VariantStep};
use crate::probe::{ProbeFigure, ProbedRole, bind_from_probes};
use std::io::Write as _;

/// Consecutive ticks of figures a role needs before the initial binding is checked.
const INITIAL_PROBE_TICKS: usize = 8;
/// Ticks the initial binding waits, once every role has its samples, for the roles that
/// have not finished a cycle yet (40 ticks: 10 s at the default 250 ms).
const INITIAL_CYCLE_WAIT_TICKS: u32 = 40;
/// Below this much CPU time in a window, a role's slowdown is not measured (ms of run time).
const MIN_RUN_FOR_SLOWDOWN_NS: u64 = 2_000_000;
/// Affinity passes over a process's threads before a move gives up on threads that keep
/// appearing.
const MOVE_PASSES: usize = 4;

/// A role that runs or waits to run less than this (cores) is not probed: its slowdown
/// cannot be measured in a few ticks, and a move would not shorten cycles spent waiting on
/// input.
const MIN_PROBE_DEMAND: f64 = 0.05;

/// The initial binding's probes while they run: each role that does not fit where the
/// workflow put it visits every other executor for `probe_ticks` scheduling ticks.
#[derive(Debug)]
pub(crate) struct InitialProbes {
    roles: Vec<ProbedRole>,
    /// The pid each probed role had when its probes began (a restart ends them).
    pids: Vec<u32>,
    /// Probes still to make, in order: (index into `roles`, executor index).
    queue: VecDeque<(usize, usize)>,
    /// The probe under way: (index into `roles`, executor, worked cycles on arrival).
    current: Option<(usize, usize, u64)>,
    /// Every role's figures at home when the probes began (for the report).
    at_home: Vec<String>,
    /// Probes of `roles[k]` ended early: it is bound where a move by hand sent it, or
    /// where its restart started it, not by its probes.
    ended: Vec<bool>,
}

impl InitialProbes {
    /// Stop probing `roles[k]` (moved by hand, restarted, being swapped).
    fn forget(&mut self, k: usize) {
        self.queue.retain(|&(q, _)| q != k);
        if self.current.is_some_and(|(c, _, _)| c == k) {
            self.current = None;
        }
        self.roles[k].figures.clear();
        if let Some(e) = self.ended.get_mut(k) {
            *e = true;
        }
    }
}

/// Bind every thread of `pid` to `set`; passes repeat until every thread, new ones
/// included, reports it. Returns the threads bound.
fn bind_all_threads(pid: u32, set: &CpuSet) -> Result<usize, String> {
    for _ in 0..MOVE_PASSES {
        set.bind_process(pid as i32).map_err(|e| e.to_string())?;
        // a thread started during the pass inherits the old mask from its creator only
        // if the creator had not moved yet: check every thread
        let tids = process_threads(pid).map_err(|e| e.to_string())?;
        if tids
            .iter()
            .all(|&t| CpuSet::of_task(t).map_or(true, |s| &s == set))
        {
            return Ok(tids.len());
        }
    }
    Err(format!(
        "threads kept appearing with the old affinity after {MOVE_PASSES} passes"
    ))
}

/// A role's latency against its budget, as the initial binding reports it.
fn fits_line(r: &RoleLoad) -> String {
    match (r.latency_ms, r.budget_ms) {
        (Some(l), Some(b)) => format!("{l:.1} of {b:.0} ms"),
        (None, Some(b)) => format!("no cycle yet, budget {b:.0} ms"),
        (_, None) => "no budget".into(),
    }
}

/// How often the flight's services are listed to find one removed from outside.
const SERVICE_AUDIT_PERIOD: Duration = Duration::from_millis(500);

/// The policy settings of a flight's `[scheduling]` table.
pub(super) fn rebind_config(s: &SchedulingSpec) -> RebindConfig {
    let ticks = |ms: u64| (ms / s.interval_ms.max(1)).clamp(1, u32::MAX as u64) as u32;
    RebindConfig {
        trigger_ticks: s.trigger_samples,
        margin: s.margin,
        cooldown_ticks: ticks(s.cooldown_ms),
        max_moves: 3,
    }
}

/// The variant ladder's settings of a flight's `[scheduling]` table.
pub(super) fn ladder_config(s: &SchedulingSpec) -> LadderConfig {
    LadderConfig {
        margin: s.margin,
        ..LadderConfig::default()
    }
}

/// Slowdown `(run + wait) / run` and the run and wait shares of wall time between two
/// scheduler samples.
fn shares(a: &(Instant, SchedTime), b: &(Instant, SchedTime)) -> Option<(f64, f64, f64)> {
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

impl Supervisor {
    /// The executor registry (declared and discovered CPU sets with their last load).
    pub fn registry(&self) -> &ExecutorRegistry {
        &self.registry
    }

    /// Record the accelerators ONNX Runtime reported in the executor registry (see
    /// [`crate::executors::accelerators_from`]).
    pub fn set_accelerators(
        &mut self,
        providers: Vec<String>,
        accelerators: Vec<crate::executors::AcceleratorInfo>,
    ) {
        self.registry.set_accelerators(providers, accelerators);
    }

    /// The flight's scheduling settings.
    pub fn scheduling(&self) -> &SchedulingSpec {
        &self.scheduling
    }

    /// Turn latency-driven re-binding on or off (stall detection stays on).
    pub fn set_dynamic(&mut self, on: bool) {
        self.scheduling.dynamic = on;
    }

    /// Live moves of all roles so far.
    pub fn total_migrations(&self) -> u32 {
        self.migrations
    }

    /// Steps the variant ladder started so far.
    pub fn total_variant_steps(&self) -> u32 {
        self.variant_steps
    }

    /// Move role `role`'s running process, live, to `target`: an executor name or a CPU
    /// list. Every thread is bound (passes repeat until every thread, new ones included,
    /// reports the new affinity); the pid stays, nothing restarts, no port closes. Later
    /// restarts of the role start on the new CPUs.
    pub fn migrate(&mut self, role: &str, target: &str) -> Result<Migration, MigrateError> {
        self.migrate_with(role, target, None)
    }

    fn resolve_target(&self, target: &str) -> Result<(String, CpuSet), MigrateError> {
        if let Some(e) = self.registry.by_name(target) {
            return Ok((e.name.clone(), e.cpus.clone()));
        }
        let bad = |reason: String| MigrateError::BadTarget {
            target: target.to_string(),
            executors: self
                .registry
                .executors()
                .iter()
                .map(|e| format!("{} = CPUs {}", e.name, e.cpus))
                .collect::<Vec<_>>()
                .join(", "),
            reason,
        };
        let set = CpuSet::parse(target).map_err(|e| bad(e.to_string()))?;
        set.check_exists().map_err(|e| bad(e.to_string()))?;
        let name = self
            .registry
            .by_cpus(&set)
            .map(|e| e.name.clone())
            .unwrap_or_else(|| format!("cpus {set}"));
        Ok((name, set))
    }

    fn migrate_with(
        &mut self,
        role: &str,
        target: &str,
        trigger: Option<MigrationTrigger>,
    ) -> Result<Migration, MigrateError> {
        let Some(i) = self.roles.iter().position(|r| r.name == role) else {
            return Err(MigrateError::UnknownRole {
                role: role.to_string(),
                known: self.role_names(),
            });
        };
        let (to_name, set) = self.resolve_target(target)?;
        let r = &mut self.roles[i];
        if r.swap.is_some() {
            return Err(MigrateError::SwapInProgress {
                role: r.name.clone(),
            });
        }
        let (Some(pid), true) = (r.pid, r.state == RoleState::Running) else {
            return Err(MigrateError::NotRunning {
                role: r.name.clone(),
                state: r.describe_state(),
            });
        };
        let started = Instant::now();
        let affinity = |reason: String| MigrateError::Affinity {
            role: role.to_string(),
            pid,
            cpus: set.to_string(),
            reason,
        };
        let threads = bind_all_threads(pid, &set).map_err(affinity)?;
        // a move by hand ends the role's probes: it stays where it was sent
        if trigger.is_none()
            && let Some(p) = self.probes.as_mut()
            && let Some(k) = p.roles.iter().position(|x| x.role == i)
        {
            p.forget(k);
        }
        let r = &mut self.roles[i];
        let from = if r.executor.is_empty() {
            format!("cpus {}", r.cpus)
        } else {
            r.executor.clone()
        };
        r.cpus = set.to_string();
        r.cpu_set = Some(set.clone());
        r.executor = to_name.clone();
        r.migrations += 1;
        r.binding = match &trigger {
            Some(t) if t.initial => format!(
                "initial binding: {:.0} ms on {from} > {:.0}% of {:.0} ms budget, {:.0} ms predicted",
                t.latency_ms,
                100.0 * (1.0 - self.scheduling.margin),
                t.budget_ms,
                t.predicted_ms
            ),
            Some(t) => format!(
                "moved from {from}: {:.0} ms > {:.0} ms budget, {:.0} ms predicted",
                t.latency_ms, t.budget_ms, t.predicted_ms
            ),
            None => format!("moved by hand from {from}"),
        };
        // the spec a restart reads names the new CPUs too
        if let Ok(mut spec) = aeris_runtime::RoleSpec::load(&r.spec_path) {
            spec.cpus = r.cpus.clone();
            if let Ok(json) = serde_json::to_string_pretty(&spec) {
                let _ = std::fs::write(&r.spec_path, json);
            }
        }
        // its figures were measured elsewhere
        r.sched.clear();
        r.recent = LatencyWindow::new(RECENT_CYCLES);
        self.policy.settle(i);
        // a move predicted to cure the role gets its chance before the ladder judges it
        // again; a relief move (still predicted over budget) does not: the dense VLN episode
        // moved a 5 s Gemma-3 reasoner 15 times and every move reset the ladder's streak,
        // so it never stepped down and 80 % of the deadlines were missed
        if trigger
            .as_ref()
            .is_none_or(|t| t.predicted_ms <= t.budget_ms)
        {
            self.ladder.settle(i);
        }
        self.migrations += 1;
        let m = Migration {
            role: role.to_string(),
            pid,
            from,
            to: to_name,
            cpus: set.to_string(),
            threads,
            took_us: started.elapsed().as_micros() as u64,
            trigger,
            done_ns: monotonic_ns(),
        };
        self.log_scheduling(&m);
        self.pending.push(SupervisorEvent::RoleMigrated(m.clone()));
        Ok(m)
    }

    /// Append a move to `RUN_DIR/scheduling.jsonl`.
    fn log_scheduling(&self, m: &Migration) {
        let line = serde_json::json!({
            "t_ns": m.done_ns,
            "role": m.role,
            "pid": m.pid,
            "from": m.from,
            "to": m.to,
            "cpus": m.cpus,
            "threads": m.threads,
            "took_us": m.took_us,
            "trigger_latency_ms": m.trigger.as_ref().map(|t| t.latency_ms),
            "budget_ms": m.trigger.as_ref().map(|t| t.budget_ms),
            "predicted_ms": m.trigger.as_ref().map(|t| t.predicted_ms),
            "initial": m.trigger.as_ref().is_some_and(|t| t.initial),
        });
        if let Ok(mut f) = OpenOptions::new()
            .create(true)
            .append(true)
            .open(self.run_dir.join("scheduling.jsonl"))
        {
            let _ = writeln!(f, "{line}");
        }
    }

    /// Kill running roles that are alive but silent: stopped (SIGSTOP, state `T`) after
    /// three idle-heartbeat periods of silence (or of life, before a first heartbeat); silent for `stall_timeout_ms` neither running
    /// nor waiting for a CPU (blocked, deadlocked: a role starved by a loaded machine waits in
    /// a run queue and is not stalled); or silent for `stall_hard_timeout_ms` whatever it does.
    /// The exit is reaped by the next step and the restart policy applies.
    pub(super) fn detect_stalls(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        let quick = Duration::from_millis(3 * self.idle_heartbeat_ms);
        let timeout = Duration::from_millis(self.scheduling.stall_timeout_ms);
        let hard = Duration::from_millis(self.scheduling.stall_hard_timeout_ms);
        for role in &mut self.roles {
            let (Some(pid), true) = (role.pid, role.state == RoleState::Running) else {
                continue;
            };
            if !role.running {
                // before its first heartbeat only a stopped process is certainly stalled (a
                // model loading from disk can be silent, and blocked, for many seconds)
                let up = role
                    .started_at
                    .map_or(Duration::ZERO, |t| now.saturating_duration_since(t));
                if up >= quick
                    && let Some(state @ ('T' | 't')) = process_state(pid)
                {
                    if let Some(child) = role.child.as_mut() {
                        let _ = child.kill();
                    }
                    role.stalls += 1;
                    events.push(SupervisorEvent::RoleStalled {
                        name: role.name.clone(),
                        pid,
                        silent_ms: up.as_millis() as u64,
                        why: format!("stopped (state {state}) before its first heartbeat"),
                    });
                }
                continue;
            }
            let Some(heard) = role.heard_at else {
                continue;
            };
            let silent = now.saturating_duration_since(heard);
            if silent < quick {
                continue;
            }
            // time on a CPU plus time runnable in a run queue: grows unless it sleeps
            let run_ns = process_sched_time(pid).map(|t| t.run_ns + t.wait_ns);
            let probe = *role.silence_probe.get_or_insert(run_ns.unwrap_or(0));
            let state = process_state(pid);
            let why = if matches!(state, Some('T' | 't')) {
                Some(format!("stopped (state {})", state.unwrap_or('T')))
            } else if silent >= timeout
                && run_ns.is_some_and(|r| r.saturating_sub(probe) < 1_000_000)
            {
                Some(format!(
                    "neither running nor runnable for {} ms",
                    silent.as_millis()
                ))
            } else if silent >= hard {
                Some("still silent after the hard stall timeout".to_string())
            } else {
                None
            };
            let Some(why) = why else { continue };
            if let Some(child) = role.child.as_mut() {
                // SIGKILL ends a stopped process too; the next reap restarts it
                let _ = child.kill();
            }
            role.stalls += 1;
            role.running = false;
            events.push(SupervisorEvent::RoleStalled {
                name: role.name.clone(),
                pid,
                silent_ms: silent.as_millis() as u64,
                why,
            });
        }
    }

    /// Every [`SERVICE_AUDIT_PERIOD`]: list the flight's services and the roles registered
    /// at each. A service seen before that is gone while a role registered at it still runs
    /// the same process was removed from outside (a `/dev/shm` clean-up): the processes keep
    /// their mappings but nobody new can join it, so a later restart of any of them would
    /// talk into a fresh service nobody else is on. Kill them now; their restarts create
    /// the service again and all join it.
    pub(super) fn audit_services(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        if now < self.next_audit {
            return;
        }
        self.next_audit = now + SERVICE_AUDIT_PERIOD;
        let current = aeris_runtime::bus::flight_service_nodes(&self.flight);
        let mut lost = Vec::new();
        for (service, attached) in &self.known_services {
            if current.iter().any(|(s, _)| s == service) {
                continue;
            }
            let victims: Vec<(usize, u32)> = attached
                .iter()
                .filter_map(|(name, pid)| {
                    let i = self.roles.iter().position(|r| &r.name == name)?;
                    let r = &self.roles[i];
                    (r.running && r.pid == Some(*pid)).then_some((i, *pid))
                })
                .collect();
            if !victims.is_empty() {
                lost.push((service.clone(), victims));
            }
        }
        self.known_services = current
            .into_iter()
            .map(|(service, nodes)| {
                let attached = nodes
                    .into_iter()
                    .filter_map(|n| {
                        let r = self.roles.iter().find(|r| r.name == n)?;
                        Some((n, r.pid?))
                    })
                    .collect();
                (service, attached)
            })
            .collect();
        for (service, victims) in lost {
            let mut roles = Vec::new();
            for (i, pid) in victims {
                let role = &mut self.roles[i];
                if !role.running {
                    continue; // already killed for another lost service
                }
                if let Some(child) = role.child.as_mut() {
                    let _ = child.kill();
                }
                role.running = false;
                roles.push((role.name.clone(), pid));
            }
            if !roles.is_empty() {
                events.push(SupervisorEvent::ServiceLost { service, roles });
            }
        }
    }

    /// One scheduling tick when due: sample the executors and every role's scheduler time;
    /// with dynamic scheduling on, check the initial binding once every role has figures,
    /// then let the policy re-bind.
    pub(super) fn schedule(&mut self, events: &mut Vec<SupervisorEvent>) {
        let now = Instant::now();
        if now < self.next_tick {
            return;
        }
        self.next_tick = now + Duration::from_millis(self.scheduling.interval_ms);
        self.registry.sample();
        for role in &mut self.roles {
            let Some(t) = role.pid.and_then(process_sched_time) else {
                continue;
            };
            if role.sched.len() == SCHED_SAMPLES {
                role.sched.pop_front();
            }
            role.sched.push_back((now, t));
        }
        if !self.scheduling.dynamic && !self.scheduling.adapt_variants {
            return;
        }
        let (roles, executors) = self.observe();
        if !self.scheduling.dynamic {
            self.step_variants(&roles, events);
            return;
        }
        if !self.initial_checked {
            if self.probes.is_some() {
                self.step_probes(&executors, events);
                return;
            }
            let sampled = self.roles.iter().all(|r| {
                r.budget_ms.is_none() || !r.running || r.sched.len() >= INITIAL_PROBE_TICKS
            }) && self
                .roles
                .iter()
                .any(|r| r.sched.len() >= INITIAL_PROBE_TICKS);
            // a role without a finished cycle cannot be judged: wait for one (a language
            // model's first decision takes seconds, and a role still loading its models
            // has not even said it runs), but not for ever
            let cycled = self.roles.iter().all(|r| {
                r.budget_ms.is_none() || r.state != RoleState::Running || r.worked_cycles > 0
            });
            if sampled {
                self.initial_wait_ticks += 1;
            }
            let ready = sampled && (cycled || self.initial_wait_ticks > INITIAL_CYCLE_WAIT_TICKS);
            if ready && !self.start_probes(&roles, &executors, events) {
                self.initial_checked = true;
                self.initial_binding(&roles, &executors, events);
            }
            return;
        }
        if let Some(plan) = self.policy.tick(&roles, &executors) {
            self.apply_plan(&plan, &roles, &executors, false, events);
            events.append(&mut self.pending);
        }
        // after re-binding: a role just moved is settled and judged on its new executor
        self.step_variants(&roles, events);
    }

    /// One tick of the variant ladder; its steps start hot swaps.
    fn step_variants(&mut self, roles: &[RoleLoad], events: &mut Vec<SupervisorEvent>) {
        if !self.scheduling.adapt_variants {
            return;
        }
        let samples: Vec<LadderSample> = self
            .roles
            .iter()
            .zip(roles)
            .map(|(r, load)| LadderSample {
                cycle_ms: r.last_cycle_ms,
                cycles: r.worked_cycles,
                budget_ms: r.budget_ms,
                slowdown: load.slowdown,
                ready: r.state == RoleState::Running && r.running && r.swap.is_none(),
            })
            .collect();
        let mut steps: Vec<VariantStep> = Vec::new();
        self.ladder.tick(&samples, &mut steps);
        for step in steps {
            let role = &self.roles[step.role];
            let (Some(from), Some(to)) = (role.ladder.get(step.from), role.ladder.get(step.to))
            else {
                self.ladder.failed(step.role);
                continue;
            };
            let (name, from, to) = (role.name.clone(), from.clone(), to.clone());
            // down: the running variant already misses its budget on saturated CPUs, where
            // an idle load would never finish; up: the role fits, load on idle time only
            let load_idle = step.direction == StepDirection::Up;
            match self.start_swap(&name, &to, DEFAULT_SWAP_READY_TIMEOUT, load_idle) {
                Ok(_) => {
                    self.variant_steps += 1;
                    self.log_variant_step(&name, &from, &to, &step);
                    events.push(SupervisorEvent::VariantStepped {
                        name,
                        from,
                        to,
                        direction: step.direction,
                        latency_ms: step.latency_ms,
                        budget_ms: step.budget_ms,
                        predicted_ms: step.predicted_ms,
                    });
                    events.append(&mut self.pending);
                }
                Err(e) => {
                    self.ladder.failed(step.role);
                    events.push(SupervisorEvent::SwapFailed {
                        name,
                        variant: to,
                        reason: format!("variant ladder: {e}"),
                    });
                }
            }
        }
    }

    /// The ladder learns where swaps landed: a committed swap (by the ladder or by hand)
    /// sets the role's rung, a rolled-back one marks the ladder's target unusable.
    pub(super) fn ladder_follow_swaps(&mut self, events: &[SupervisorEvent]) {
        for e in events {
            match e {
                SupervisorEvent::SwapReady { name, variant, .. } => {
                    if let Some(i) = self.roles.iter().position(|r| &r.name == name) {
                        let rung = self.roles[i].ladder.iter().position(|v| v == variant);
                        self.ladder.landed(i, rung);
                    }
                }
                SupervisorEvent::SwapFailed { name, .. } => {
                    if let Some(i) = self.roles.iter().position(|r| &r.name == name) {
                        self.ladder.failed(i);
                    }
                }
                _ => {}
            }
        }
    }

    /// A ladder step goes into the role's log beside the swap's own lines.
    fn log_variant_step(&self, name: &str, from: &str, to: &str, step: &VariantStep) {
        let Some(role) = self.roles.iter().find(|r| r.name == name) else {
            return;
        };
        if let Ok(mut f) = OpenOptions::new().append(true).open(&role.log_path) {
            let _ = writeln!(
                f,
                "=== aeris supervisor: variant ladder {:?} `{from}` -> `{to}`: last cycle {:.1} ms, budget {:.1} ms, predicted {} ===",
                step.direction,
                step.latency_ms,
                step.budget_ms,
                step.predicted_ms
                    .map_or("unmeasured".to_string(), |p| format!("{p:.1} ms"))
            );
        }
    }

    /// Make the moves of `plan`; a move the kernel refuses is reported and the role stays.
    /// Returns `true` when at least one role moved.
    fn apply_plan(
        &mut self,
        plan: &RebindPlan,
        roles: &[RoleLoad],
        executors: &[ExecutorLoad],
        initial: bool,
        events: &mut Vec<SupervisorEvent>,
    ) -> bool {
        let mut moved = false;
        for m in &plan.moves {
            let role = &roles[m.role];
            let trigger = MigrationTrigger {
                latency_ms: role.latency_ms.unwrap_or(0.0),
                budget_ms: role.budget_ms.unwrap_or(0.0),
                predicted_ms: plan.predicted_ms[m.role].unwrap_or(0.0),
                initial,
            };
            let to = &executors[m.to].name;
            match self.migrate_with(&role.name, to, Some(trigger)) {
                Ok(_) => moved = true,
                Err(e) => events.push(SupervisorEvent::MigrationFailed {
                    name: role.name.clone(),
                    reason: format!("re-binding to {to}: {e}"),
                }),
            }
        }
        moved
    }

    /// The policy's view of the flight now.
    fn observe(&mut self) -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        let registry = &self.registry;
        let executors: Vec<ExecutorLoad> = self
            .registry
            .executors()
            .iter()
            .map(|e| ExecutorLoad {
                name: e.name.clone(),
                capacity: e.capacity(),
                busy: e.busy,
            })
            .collect();
        let roles = self
            .roles
            .iter_mut()
            .map(|r| {
                let executor = r
                    .cpu_set
                    .as_ref()
                    .and_then(|set| registry.executors().iter().position(|e| &e.cpus == set))
                    .unwrap_or(usize::MAX);
                let n = r.sched.len();
                // the whole window for demand, the last two samples for slowdown and wait
                let slow = (n >= 2)
                    .then(|| shares(&r.sched[0], &r.sched[n - 1]))
                    .flatten();
                let fast = (n >= 3)
                    .then(|| shares(&r.sched[n - 3], &r.sched[n - 1]))
                    .flatten();
                let (slow_s, demand, _) = slow.unwrap_or((1.0, 0.0, 0.0));
                let (fast_s, _, waiting) = fast.or(slow).unwrap_or((1.0, 0.0, 0.0));
                let percentiles = r.recent.percentiles([50.0, 95.0]);
                // a slowdown that just grew stretches the cycles that are still running:
                // the signal does not wait for them to finish
                let latency_ms = percentiles
                    .map(|[p50, p95]| p95.max(p50 * (fast_s / slow_s.max(1.0)).max(1.0)));
                RoleLoad {
                    name: r.name.clone(),
                    executor,
                    budget_ms: r.budget_ms,
                    latency_ms,
                    slowdown: fast_s,
                    demand,
                    waiting,
                    movable: executor != usize::MAX
                        && r.state == RoleState::Running
                        && r.swap.is_none(),
                }
            })
            .collect();
        (roles, executors)
    }

    /// pi_0: the declared binding measured over the probe window; roles that do not fit
    /// their budget with the margin are re-bound with the fewest moves.
    fn initial_binding(
        &mut self,
        roles: &[RoleLoad],
        executors: &[ExecutorLoad],
        events: &mut Vec<SupervisorEvent>,
    ) {
        let margin = self.scheduling.margin;
        // against the budget less the margin: a binding must fit with room to spare
        let tight: Vec<RoleLoad> = roles
            .iter()
            .map(|r| RoleLoad {
                budget_ms: r.budget_ms.map(|b| b * (1.0 - margin)),
                ..r.clone()
            })
            .collect();
        let plan = plan_fewest_moves(&tight, executors, 0.0, 3, &[]);
        let mut reasons = Vec::new();
        let rebound = plan
            .as_ref()
            .is_some_and(|p| self.apply_plan(p, roles, executors, true, events));
        for (i, r) in roles.iter().enumerate() {
            let runtime = &mut self.roles[i];
            let fits = fits_line(r);
            if runtime.migrations == 0 {
                runtime.binding = format!(
                    "{}; initial check: {fits}",
                    runtime.binding.split(';').next().unwrap_or("")
                );
            }
            reasons.push(format!(
                "{} on {} ({fits})",
                runtime.name,
                if runtime.executor.is_empty() {
                    "unbound"
                } else {
                    &runtime.executor
                }
            ));
        }
        events.append(&mut self.pending);
        events.push(SupervisorEvent::InitialBinding { rebound, reasons });
    }

    /// pi_0's probes: when a role with a budget does not fit it (less the margin) where
    /// the workflow put it, and uses enough CPU for a slowdown to be measured, start moving
    /// it, live, to each other executor in turn. `false` when there is nothing to probe
    /// (probes off, one executor, every role fits): the binding is then judged from load.
    fn start_probes(
        &mut self,
        roles: &[RoleLoad],
        executors: &[ExecutorLoad],
        events: &mut Vec<SupervisorEvent>,
    ) -> bool {
        if self.scheduling.probe_ticks == 0 || executors.len() < 2 {
            return false;
        }
        let margin = self.scheduling.margin;
        let mut probed = Vec::new();
        let mut pids = Vec::new();
        for (i, r) in roles.iter().enumerate() {
            let (Some(latency_ms), Some(budget_ms), Some(pid)) =
                (r.latency_ms, r.budget_ms, self.roles[i].pid)
            else {
                continue;
            };
            // CPU-bound: running or runnable (a starved role waits in a run queue)
            let wants_cpu = r.demand + r.waiting;
            if !r.movable
                || wants_cpu < MIN_PROBE_DEMAND
                || latency_ms <= budget_ms * (1.0 - margin)
            {
                continue;
            }
            // the slowdown over the whole window at home, as a probe measures it elsewhere
            let sched = &self.roles[i].sched;
            let slowdown = (sched.len() >= 2)
                .then(|| shares(&sched[0], &sched[sched.len() - 1]))
                .flatten()
                .map_or(r.slowdown, |s| s.0);
            probed.push(ProbedRole {
                role: i,
                home: r.executor,
                latency_ms,
                slowdown,
                demand: r.demand,
                budget_ms,
                figures: Vec::new(),
            });
            pids.push(pid);
        }
        if probed.is_empty() {
            return false;
        }
        let n = probed.len();
        let queue = probed
            .iter()
            .enumerate()
            .flat_map(|(k, p)| {
                (0..executors.len())
                    .filter(move |&e| e != p.home)
                    .map(move |e| (k, e))
            })
            .collect();
        self.probes = Some(InitialProbes {
            roles: probed,
            pids,
            queue,
            current: None,
            at_home: roles.iter().map(fits_line).collect(),
            ended: vec![false; n],
        });
        self.step_probes(executors, events);
        true
    }

    /// One scheduling tick of the probes: finish the one under way once it has its
    /// samples, start the next, or, when none is left, bind from what they measured.
    fn step_probes(&mut self, executors: &[ExecutorLoad], events: &mut Vec<SupervisorEvent>) {
        let Some(mut p) = self.probes.take() else {
            return;
        };
        let ticks = self.scheduling.probe_ticks as usize;
        if let Some((k, e, cycles_then)) = p.current {
            let i = p.roles[k].role;
            let r = &self.roles[i];
            if r.pid != Some(p.pids[k]) || r.state != RoleState::Running || r.swap.is_some() {
                // restarted (on its home CPUs, from its spec), or being swapped: no probes
                self.restore_home(i, p.roles[k].home);
                p.forget(k);
            } else if r.sched.len() < ticks {
                self.probes = Some(p);
                return;
            } else {
                let n = r.sched.len();
                let slowdown = shares(&r.sched[0], &r.sched[n - 1]).map_or(1.0, |s| s.0);
                // a cycle that both began and ended here: the second one to finish
                let cycle_ms = (r.worked_cycles >= cycles_then + 2)
                    .then_some(r.last_cycle_ms)
                    .flatten();
                let figure = ProbeFigure {
                    executor: e,
                    slowdown,
                    cycle_ms,
                };
                events.push(SupervisorEvent::BindingProbed {
                    name: r.name.clone(),
                    executor: executors.get(e).map_or(String::new(), |x| x.name.clone()),
                    slowdown,
                    predicted_ms: p.roles[k].predicted_ms(&figure),
                    measured_cycle: cycle_ms.is_some(),
                });
                p.roles[k].figures.push(figure);
                p.current = None;
                // its last probe: back home before the next role is measured
                if !p.queue.iter().any(|&(q, _)| q == k) {
                    let home = p.roles[k].home;
                    if let Err(reason) = self.probe_move(i, home) {
                        events.push(SupervisorEvent::MigrationFailed {
                            name: self.roles[i].name.clone(),
                            reason: format!("back from the initial binding's probes: {reason}"),
                        });
                        p.forget(k);
                    }
                }
            }
        }
        while let Some((k, e)) = p.queue.pop_front() {
            let i = p.roles[k].role;
            match self.probe_move(i, e) {
                Ok(()) => {
                    p.current = Some((k, e, self.roles[i].worked_cycles));
                    self.probes = Some(p);
                    return;
                }
                Err(reason) => {
                    events.push(SupervisorEvent::MigrationFailed {
                        name: self.roles[i].name.clone(),
                        reason: format!("initial binding probe: {reason}"),
                    });
                    // the next candidate, or home when there is none
                    if !p.queue.iter().any(|&(q, _)| q == k) {
                        let _ = self.probe_move(i, p.roles[k].home);
                    }
                }
            }
        }
        self.finish_probes(p, executors, events);
    }

    /// A probe's move: the role's threads to executor `e`, nothing counted as a migration
    /// (the role's spec, which a restart reads, keeps its home).
    fn probe_move(&mut self, i: usize, e: usize) -> Result<(), String> {
        let Some(x) = self.registry.executors().get(e) else {
            return Err(format!("no executor #{e}"));
        };
        let (name, set) = (x.name.clone(), x.cpus.clone());
        let r = &mut self.roles[i];
        let pid = r
            .pid
            .ok_or_else(|| format!("`{}` is not running", r.name))?;
        bind_all_threads(pid, &set)?;
        r.cpus = set.to_string();
        r.cpu_set = Some(set);
        r.executor = name;
        r.binding = format!("initial binding: probing on {}", r.executor);
        // its scheduler figures from here on are the probe's
        r.sched.clear();
        Ok(())
    }

    /// Record role `i` on its home executor again (its process was restarted there).
    fn restore_home(&mut self, i: usize, home: usize) {
        if let Some(x) = self.registry.executors().get(home) {
            let (name, set) = (x.name.clone(), x.cpus.clone());
            let r = &mut self.roles[i];
            r.cpus = set.to_string();
            r.cpu_set = Some(set);
            r.executor = name;
            r.sched.clear();
        }
    }

    /// Bind each probed role where its probes say (a live move counted as a migration
    /// when that is not its home) and report the initial binding with the figures.
    fn finish_probes(
        &mut self,
        p: InitialProbes,
        executors: &[ExecutorLoad],
        events: &mut Vec<SupervisorEvent>,
    ) {
        self.initial_checked = true;
        let name_of = |e: usize| executors.get(e).map_or("?", |x| x.name.as_str());
        let kept: Vec<ProbedRole> = p
            .roles
            .iter()
            .zip(&p.ended)
            .filter(|(_, ended)| !**ended)
            .map(|(r, _)| r.clone())
            .collect();
        let choices = bind_from_probes(&kept, executors, self.scheduling.margin);
        let mut rebound = false;
        let mut probed_lines = Vec::new();
        for c in &choices {
            let Some(r) = p.roles.iter().find(|r| r.role == c.role) else {
                continue;
            };
            let mut figures = vec![format!(
                "{:.0} ms on {} (declared)",
                r.latency_ms,
                name_of(r.home)
            )];
            figures.extend(
                r.figures
                    .iter()
                    .map(|f| format!("{:.0} ms on {}", r.predicted_ms(f), name_of(f.executor))),
            );
            let name = self.roles[c.role].name.clone();
            let verdict = if c.to == c.from {
                format!("kept on {}", name_of(c.from))
            } else {
                let trigger = MigrationTrigger {
                    latency_ms: r.latency_ms,
                    budget_ms: r.budget_ms,
                    predicted_ms: c.predicted_ms,
                    initial: true,
                };
                match self.migrate_with(&name, name_of(c.to), Some(trigger)) {
                    Ok(_) => {
                        rebound = true;
                        format!("bound to {}", name_of(c.to))
                    }
                    Err(e) => {
                        events.push(SupervisorEvent::MigrationFailed {
                            name: name.clone(),
                            reason: format!("initial binding to {}: {e}", name_of(c.to)),
                        });
                        format!("kept on {} (the move failed)", name_of(c.from))
                    }
                }
            };
            let line = format!(
                "probed {}; {verdict}, {:.0} ms predicted of {:.0} ms budget",
                figures.join(", "),
                c.predicted_ms,
                r.budget_ms
            );
            self.roles[c.role].binding = format!("initial binding: {line}");
            probed_lines.push((c.role, line));
        }
        let mut reasons = Vec::new();
        for (i, r) in self.roles.iter_mut().enumerate() {
            let ended = p.roles.iter().zip(&p.ended).any(|(r, e)| r.role == i && *e);
            let line = match probed_lines.iter().find(|(role, _)| *role == i) {
                Some((_, line)) => line.clone(),
                None if ended => "probes ended early: moved by hand or restarted".into(),
                None => {
                    let fits = p.at_home.get(i).cloned().unwrap_or_default();
                    if r.migrations == 0 {
                        r.binding = format!(
                            "{}; initial check: {fits}",
                            r.binding.split(';').next().unwrap_or("")
                        );
                    }
                    fits
                }
            };
            let on = if r.executor.is_empty() {
                "unbound"
            } else {
                &r.executor
            };
            reasons.push(format!("{} on {on} ({line})", r.name));
        }
        events.append(&mut self.pending);
        events.push(SupervisorEvent::InitialBinding { rebound, reasons });
    }
}
