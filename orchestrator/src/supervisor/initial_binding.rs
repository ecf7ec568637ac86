//! The initial binding (pi_0): once every role has figures, the declared binding is checked
//! against the latency budgets (less the margin); a role that does not fit is probed, live,
//! on every other executor and bound where its probes say, or, without probes, the fewest
//! moves that fit are made.

use super::Supervisor;
use super::events::{MigrationTrigger, SupervisorEvent};
use super::migration::bind_all_threads;
use super::role_runtime::RoleState;
use crate::executors::shares;
use crate::probe::{ProbeFigure, ProbedRole, bind_from_probes};
use crate::rebind::{ExecutorLoad, RoleLoad, plan_fewest_moves};
use std::collections::VecDeque;

/// Consecutive ticks of figures a role needs before the initial binding is checked.
const INITIAL_PROBE_TICKS: usize = 8;
/// Ticks the initial binding waits, once every role has its samples, for the roles that
/// have not finished a cycle yet (40 ticks: 10 s at the default 250 ms).
const INITIAL_CYCLE_WAIT_TICKS: u32 = 40;

/// A role that runs or waits to run less than this (cores) is not probed: its slowdown
/// cannot be measured in a few ticks, and a move would not shorten cycles spent waiting on
/// input.
const MIN_PROBE_DEMAND: f64 = 0.05;

/// Where the initial binding check stands.
#[derive(Debug, Default)]
pub(super) struct InitialCheck {
    /// `true` once the initial binding was checked (kept, probed or re-bound).
    pub(super) done: bool,
    /// Scheduling ticks the check has waited for roles' first cycles.
    pub(super) wait_ticks: u32,
    /// The initial binding's probes, while they run.
    pub(super) probes: Option<InitialProbes>,
}

/// The initial binding's probes while they run: each role that does not fit where the
/// workflow put it visits every other executor for `probe_ticks` scheduling ticks.
#[derive(Debug)]
pub(super) struct InitialProbes {
    pub(super) roles: Vec<ProbedRole>,
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
    pub(super) fn forget(&mut self, k: usize) {
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

/// A role's latency against its budget, as the initial binding reports it.
fn fits_line(r: &RoleLoad) -> String {
    match (r.latency_ms, r.budget_ms) {
        (Some(l), Some(b)) => format!("{l:.1} of {b:.0} ms"),
        (None, Some(b)) => format!("no cycle yet, budget {b:.0} ms"),
        (_, None) => "no budget".into(),
    }
}

impl Supervisor {
    /// One scheduling tick before the initial binding is settled: step the probes under
    /// way, or, once every role has its samples and a finished cycle (or waited long
    /// enough for one), start probing or judge the binding from load.
    pub(super) fn check_initial_binding(
        &mut self,
        roles: &[RoleLoad],
        executors: &[ExecutorLoad],
        events: &mut Vec<SupervisorEvent>,
    ) {
        if self.initial.probes.is_some() {
            self.step_probes(executors, events);
            return;
        }
        let sampled =
            self.roles.iter().all(|r| {
                r.budget_ms.is_none() || !r.running || r.sched.len() >= INITIAL_PROBE_TICKS
            }) && self
                .roles
                .iter()
                .any(|r| r.sched.len() >= INITIAL_PROBE_TICKS);
        // a role without a finished cycle cannot be judged: wait for one (a language
        // model's first decision takes seconds, and a role still loading its models
        // has not even said it runs), but not for ever
        let cycled = self
            .roles
            .iter()
            .all(|r| r.budget_ms.is_none() || r.state != RoleState::Running || r.worked_cycles > 0);
        if sampled {
            self.initial.wait_ticks += 1;
        }
        let ready = sampled && (cycled || self.initial.wait_ticks > INITIAL_CYCLE_WAIT_TICKS);
        if ready && !self.start_probes(roles, executors, events) {
            self.initial.done = true;
            self.initial_binding(roles, executors, events);
        }
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
            // (a role on an accelerator moves only by a restart: the policy's, later)
            if !r.movable
                || executors
                    .get(r.executor)
                    .is_some_and(|e| e.accelerator.is_some())
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
                // probes move live: the CPU executors of the flight's host (one on another
                // host is judged by the re-binding policy from its load and its link, an
                // accelerator by a probe of the policy's)
                (0..executors.len())
                    .filter(move |&e| {
                        e != p.home
                            && executors[e].host.is_none()
                            && executors[e].accelerator.is_none()
                            && executors[e].capacity >= roles[p.role].threads as f64
                    })
                    .map(move |e| (k, e))
            })
            .collect();
        self.initial.probes = Some(InitialProbes {
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
        let Some(mut p) = self.initial.probes.take() else {
            return;
        };
        let ticks = self.scheduling.probe_ticks as usize;
        if let Some((k, e, cycles_then)) = p.current {
            let i = p.roles[k].role;
            let r = &self.roles[i];
            if r.pid != Some(p.pids[k]) || r.state != RoleState::Running || r.swap.is_some() {
                // restarted (on its home CPUs, from its spec), or being swapped: no probes
                self.restore_home(i, executors, p.roles[k].home);
                p.forget(k);
            } else if r.sched.len() < ticks {
                self.initial.probes = Some(p);
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
                    if let Err(reason) = self.probe_move(i, executors, home) {
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
            match self.probe_move(i, executors, e) {
                Ok(()) => {
                    p.current = Some((k, e, self.roles[i].worked_cycles));
                    self.initial.probes = Some(p);
                    return;
                }
                Err(reason) => {
                    events.push(SupervisorEvent::MigrationFailed {
                        name: self.roles[i].name.clone(),
                        reason: format!("initial binding probe: {reason}"),
                    });
                    // the next candidate, or home when there is none
                    if !p.queue.iter().any(|&(q, _)| q == k) {
                        let _ = self.probe_move(i, executors, p.roles[k].home);
                    }
                }
            }
        }
        self.finish_probes(p, executors, events);
    }

    /// A probe's move: the role's threads to executor `e`, nothing counted as a migration
    /// (the role's spec, which a restart reads, keeps its home).
    fn probe_move(&mut self, i: usize, executors: &[ExecutorLoad], e: usize) -> Result<(), String> {
        let Some(x) = executors
            .get(e)
            .and_then(|x| self.registry.by_name(&x.name))
        else {
            return Err(format!("no executor #{e} on the flight's host"));
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
    fn restore_home(&mut self, i: usize, executors: &[ExecutorLoad], home: usize) {
        if let Some(x) = executors
            .get(home)
            .and_then(|x| self.registry.by_name(&x.name))
        {
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
        self.initial.done = true;
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
