//! The scheduling tick and the re-binding policy hook: every `interval_ms` the supervisor
//! samples executor load and every role's scheduler time, builds the policy's view of the
//! flight ([`RoleLoad`], [`ExecutorLoad`]), and makes the moves the policy plans
//! ([`crate::rebind`]); the initial binding and the variant ladder are checked from the same
//! tick. Executors on other hosts are part of that view (their host's load and their
//! link's round trip, from `hosts/link`); a move to or from one is make-before-break
//! ([`Supervisor::move_role`]), a move on the flight's host is live.

use super::Supervisor;
use super::error::MigrateError;
use super::events::{MigrationTrigger, SupervisorEvent};
use super::role_runtime::{RoleState, SCHED_SAMPLES};
use crate::executors::{process_sched_time, shares};
use crate::rebind::{ExecutorLoad, RebindConfig, RebindPlan, RoleLoad, link_cost};
use crate::workflow::SchedulingSpec;
use crate::workflow::movable_across_hosts;
use aeris_runtime::affinity::CpuSet;
use aeris_schemas::topics;
use std::time::{Duration, Instant};

/// A link losing this share of its probes or more takes no role (a fading radio link).
const MAX_LOSS_TO_PLACE: f64 = 0.2;

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

impl Supervisor {
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
        if !self.initial.done {
            self.check_initial_binding(&roles, &executors, events);
            return;
        }
        if let Some(plan) = self.policy.tick(&roles, &executors) {
            self.apply_plan(&plan, &roles, &executors, false, events);
            events.append(&mut self.pending);
        }
        // after re-binding: a role just moved is settled and judged on its new executor
        self.step_variants(&roles, events);
    }

    /// Make the moves of `plan`; a move the kernel refuses is reported and the role stays.
    /// Returns `true` when at least one role moved.
    pub(super) fn apply_plan(
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
            let to = &executors[m.to];
            let from = executors.get(m.from);
            let across = to.host.is_some() || from.is_some_and(|e| e.host.is_some());
            // onto, off or between accelerators: a restart with the other provider
            let restarts = to.accelerator != from.and_then(|e| e.accelerator);
            let result = if restarts && !across {
                let at = self.pending.len();
                self.move_role_for(&role.name, &to.name, Some(trigger.clone()))
                    .map(|_| {
                        let why = SupervisorEvent::MoveAccelerator {
                            name: role.name.clone(),
                            executor: to.name.clone(),
                            accelerator: to.accelerator,
                            trigger,
                            probe: plan.probe,
                        };
                        self.pending.insert(at.min(self.pending.len()), why);
                    })
            } else if across {
                // to or from another host: make-before-break through the hot-swap path
                let target = match &to.host {
                    Some(host) => format!("{host}:{}", to.name),
                    None => to.name.clone(),
                };
                // why, before the move's own events
                let at = self.pending.len();
                self.move_role_for(&role.name, &target, Some(trigger.clone()))
                    .map(|_| {
                        let why = SupervisorEvent::MoveAcrossHosts {
                            name: role.name.clone(),
                            place: target,
                            trigger,
                        };
                        self.pending.insert(at.min(self.pending.len()), why);
                    })
            } else {
                self.migrate_with(&role.name, &to.name, Some(trigger))
                    .map(|_| ())
            };
            match result {
                Ok(()) => moved = true,
                Err(e) => {
                    // refused for the accelerator itself (no provider for it on this host):
                    // not tried again; a passing refusal (a swap under way) may be
                    let refused_there = matches!(
                        e,
                        MigrateError::NotAccelerated { .. }
                            | MigrateError::AcceleratorUnavailable { .. }
                            | MigrateError::AcceleratorUnchecked { .. }
                    );
                    if refused_there
                        && !across
                        && let Some(r) = self.roles.iter_mut().find(|r| r.name == role.name)
                    {
                        r.ruled_out_on(&to.name);
                    }
                    events.push(SupervisorEvent::MigrationFailed {
                        name: role.name.clone(),
                        reason: format!("re-binding to {}: {e}", to.name),
                    })
                }
            }
        }
        moved
    }

    /// The executors on other hosts as the policy sees them: their CPUs, their host's load
    /// and the link's cost, from the link's last measurement.
    fn remote_executor_loads(&self) -> Vec<ExecutorLoad> {
        self.remote_executors
            .iter()
            // as on the flight's host: accelerators are no CPU set to predict on
            .filter(|(name, _)| self.accelerator_of(name).is_none())
            .map(|(name, spec)| {
                let link = self.host_links.get(&spec.host);
                let host_cpus = link.map_or(0, |l| l.cpus) as f64;
                let capacity = match CpuSet::parse(&spec.cpus) {
                    Ok(set) if !spec.cpus.is_empty() => set.cpus().len() as f64,
                    _ => host_cpus,
                };
                // the agent measures its host's role CPUs as a whole: an executor's share
                let busy = link.map_or(0.0, |l| {
                    l.busy_cores() * capacity / host_cpus.max(capacity).max(1.0)
                });
                let lost = self.roles.iter().any(|r| {
                    r.link
                        .as_ref()
                        .is_some_and(|k| k.lost && k.host == spec.host)
                });
                ExecutorLoad {
                    name: name.clone(),
                    capacity: capacity.max(1.0),
                    busy,
                    host: Some(spec.host.clone()),
                    link_ms: link.and_then(|l| l.rtt_ms()).unwrap_or(0.0),
                    frame_ms: link.map_or(0.0, |l| l.frame_coding_ns as f64 / 1e6),
                    accelerator: None,
                    reachable: !lost
                        && link.is_some_and(|l| {
                            l.connected == 1 && l.rtt_ms().is_some() && l.loss() < MAX_LOSS_TO_PLACE
                        }),
                }
            })
            .collect()
    }

    /// The policy's view of the flight now.
    fn observe(&mut self) -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        // executors of the same CPUs are one place to run (two names of "auto" on a
        // one-CPU host): listed twice, each would look free while the other is loaded
        // (an accelerator executor is a place of its own, whatever CPUs it shares)
        let mut local_sets: Vec<Option<CpuSet>> = Vec::new();
        let mut executors: Vec<ExecutorLoad> = Vec::new();
        for e in self.registry.executors() {
            let accelerator = self.accelerator_of(&e.name);
            if accelerator.is_none() && local_sets.iter().any(|s| s.as_ref() == Some(&e.cpus)) {
                continue;
            }
            local_sets.push(accelerator.is_none().then(|| e.cpus.clone()));
            executors.push(ExecutorLoad {
                accelerator,
                ..ExecutorLoad::local(&e.name, e.capacity(), e.busy)
            });
        }
        let local = executors.len();
        executors.extend(self.remote_executor_loads());
        // in the order remote_executor_loads lists them
        let remote: Vec<(String, String)> = self
            .remote_executors
            .iter()
            .filter(|(name, _)| self.accelerator_of(name).is_none())
            .map(|(name, spec)| (name.clone(), spec.host.clone()))
            .collect();
        let roles =
            self.roles
                .iter_mut()
                .map(|r| {
                    let executor = match &r.link {
                        // on another host: the executor it runs on there
                        Some(link) => remote
                            .iter()
                            .position(|(name, host)| *name == r.executor && *host == link.host)
                            .map(|j| local + j),
                        // on an accelerator: that executor, by name
                        None if r.accelerator.is_some() => executors[..local]
                            .iter()
                            .position(|e| e.accelerator.is_some() && e.name == r.executor),
                        None => r.cpu_set.as_ref().and_then(|set| {
                            local_sets.iter().position(|s| s.as_ref() == Some(set))
                        }),
                    }
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
                    let mut load = RoleLoad {
                        name: r.name.clone(),
                        executor,
                        budget_ms: r.budget_ms,
                        latency_ms: None,
                        slowdown: fast_s,
                        demand,
                        waiting,
                        // a role that fell back with its link returns there by itself
                        movable: executor != usize::MAX
                            && r.state == RoleState::Running
                            && r.swap.is_none()
                            && r.returns_to.is_none()
                            && !r.link.as_ref().is_some_and(|l| l.lost),
                        crosses_hosts: movable_across_hosts(r.kind),
                        reads_frames: r.kind.info().subscribes.contains(&topics::CAMERA_RGB),
                        // a language model starts with no more threads than it had CPUs (and a
                        // live move keeps them): at most the CPUs it runs on now
                        threads: r.threads.min(
                            r.cpu_set
                                .as_ref()
                                .map_or(r.threads, |s| s.cpus().len().max(1)),
                        ),
                        kind_variant: (r.kind, r.variant.clone()),
                        accelerator_ms: Vec::new(),
                        cpu_base_ms: None,
                    };
                    // on another host its heartbeats give its own cycle: the link comes on top
                    let paid = executors.get(executor).map_or(0.0, |e| link_cost(&load, e));
                    // a slowdown that just grew stretches the cycles that are still running:
                    // the signal does not wait for them to finish late. Only one that holds
                    // over the whole window (2 s) too: a hog stays, while the bursts of our
                    // own roles' work beside a reasoner pass (in `bench ds` they moved it,
                    // at 1.1-1.5x its budget for half a second, before any hog came)
                    load.latency_ms = r.recent.expected_ms(fast_s.min(slow_s)).map(|ms| ms + paid);
                    // remember what it measured where it runs: its latency on an accelerator,
                    // its own cycle on CPUs (what a later move there or back is predicted from)
                    if let (Some(latency), Some(ex)) = (load.latency_ms, executors.get(executor))
                        && r.swap.is_none()
                    {
                        if ex.accelerator.is_some() {
                            match r.accelerator_ms.iter_mut().find(|(n, _)| *n == ex.name) {
                                Some(m) => m.1 = latency,
                                None => r.accelerator_ms.push((ex.name.clone(), latency)),
                            }
                        } else {
                            r.cpu_base_ms = Some((latency - paid).max(0.0) / fast_s.max(1.0));
                        }
                    }
                    load.cpu_base_ms = r.cpu_base_ms;
                    load.accelerator_ms = r
                        .accelerator_ms
                        .iter()
                        .filter_map(|(name, ms)| {
                            let e = executors[..local]
                                .iter()
                                .position(|e| e.accelerator.is_some() && e.name == *name)?;
                            Some((e, *ms))
                        })
                        .collect();
                    load
                })
                .collect();
        (roles, executors)
    }
}
