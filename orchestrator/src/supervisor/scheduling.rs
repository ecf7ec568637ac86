//! The scheduling tick and the re-binding policy hook: every `interval_ms` the supervisor
//! samples executor load and every role's scheduler time, builds the policy's view of the
//! flight ([`RoleLoad`], [`ExecutorLoad`]), and makes the moves the policy plans
//! ([`crate::rebind`]); the initial binding and the variant ladder are checked from the same
//! tick.

use super::Supervisor;
use super::events::{MigrationTrigger, SupervisorEvent};
use super::role_runtime::{RoleState, SCHED_SAMPLES};
use crate::executors::{SchedTime, process_sched_time};
use crate::rebind::{ExecutorLoad, RebindConfig, RebindPlan, RoleLoad};
use crate::workflow::SchedulingSpec;
use std::time::{Duration, Instant};

/// Below this much CPU time in a window, a role's slowdown is not measured (ms of run time).
const MIN_RUN_FOR_SLOWDOWN_NS: u64 = 2_000_000;

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

/// Slowdown `(run + wait) / run` and the run and wait shares of wall time between two
/// scheduler samples.
pub(super) fn shares(
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
}
