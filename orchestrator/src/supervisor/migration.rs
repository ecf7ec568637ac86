//! Live migration: moving a role's running process to another executor (every thread, same
//! pid, checked), by hand (`aeris migrate`) or for the scheduling policy, and the move's line
//! in `RUN_DIR/scheduling.jsonl`; and moving a role to another host and back
//! ([`Supervisor::move_role`]), make-before-break through the hot-swap path.

use super::Supervisor;
use super::error::MigrateError;
use super::events::{Migration, MigrationTrigger, SupervisorEvent};
use super::links::flight_host_place;
use super::recent_cycles::RecentCycles;
use super::replacement::Placement;
use super::role_runtime::RoleState;
use super::swap::DEFAULT_SWAP_READY_TIMEOUT;
use crate::executors::process_threads;
use crate::launch::PlannedFallback;
use crate::workflow::movable_across_hosts;
use aeris_runtime::accelerator::Accelerator;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::spec::RemoteSpec;
use aeris_schemas::topics;
use std::fs::OpenOptions;
use std::io::Write as _;
use std::time::Instant;

/// Affinity passes over a process's threads before a move gives up on threads that keep
/// appearing.
const MOVE_PASSES: usize = 4;

/// Bind every thread of `pid` to `set`; passes repeat until every thread, new ones
/// included, reports it. Returns the threads bound.
pub(super) fn bind_all_threads(pid: u32, set: &CpuSet) -> Result<usize, String> {
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

/// How a move asked for goes ([`Supervisor::move_role`]).
#[derive(Debug, Clone, PartialEq)]
pub enum RoleMove {
    /// Moved live between executors of the flight's host: same pid, done.
    Live(Migration),
    /// Moving to another host or back, make-before-break: the new process (`new_pid`, on
    /// the flight's host the role's handle when the role goes to another host) is starting
    /// at `place`; [`SupervisorEvent::SwapReady`] and [`SupervisorEvent::SwapDone`] (or
    /// [`SupervisorEvent::SwapFailed`], the role staying where it was) follow.
    Started {
        /// The new process.
        new_pid: u32,
        /// Where it runs.
        place: String,
    },
}

impl Supervisor {
    /// Move role `role` to `target`, by hand (`aeris migrate`):
    /// - an executor or CPU list of the flight's host, for a role there: live, same pid
    ///   ([`Supervisor::migrate`]);
    /// - `HOST:EXECUTOR` (or the name of an executor on another host): make-before-break
    ///   through the hot-swap path: the same variant starts there, becomes the role with its
    ///   first heartbeat (the hub follows its first decision), and the old process stops.
    ///   If the link to that host is lost later, the workflow's `fallback` takes over on the
    ///   flight's host, or else the role as it ran before the move;
    /// - an executor or CPU list of the flight's host, for a role on another host: back,
    ///   make-before-break too.
    pub fn move_role(&mut self, role: &str, target: &str) -> Result<RoleMove, MigrateError> {
        self.move_role_for(role, target, None)
    }

    /// [`Supervisor::move_role`], for the figures in `trigger` (the scheduling policy) or
    /// by hand (`None`): the role's binding says which.
    pub(super) fn move_role_for(
        &mut self,
        role: &str,
        target: &str,
        trigger: Option<MigrationTrigger>,
    ) -> Result<RoleMove, MigrateError> {
        let Some(i) = self.roles.iter().position(|r| r.name == role) else {
            return Err(MigrateError::UnknownRole {
                role: role.to_string(),
                known: self.role_names(),
            });
        };
        let remote = self.resolve_remote(target)?;
        // onto or off an accelerator: a restart with the other execution provider
        let accelerator = match &remote {
            Some((executor, _)) => self.accelerator_of(executor),
            // a CPU list is CPUs, whichever executor has them
            None => self.accelerator_of(target),
        };
        self.check_accelerator_move(i, target, accelerator, remote.is_some())?;
        let r = &self.roles[i];
        if remote.is_none() && r.link.is_none() && accelerator == r.accelerator {
            let moved = self.migrate(role, target).map(RoleMove::Live)?;
            // sent by hand: it no longer waits to return where a lost link took it from
            self.roles[i].returns_to = None;
            return Ok(moved);
        }
        if r.swap.is_some() {
            return Err(MigrateError::SwapInProgress {
                role: r.name.clone(),
            });
        }
        if r.pid.is_none() || r.state != super::role_runtime::RoleState::Running {
            return Err(MigrateError::NotRunning {
                role: r.name.clone(),
                state: r.describe_state(),
            });
        }
        let placement = match remote {
            Some((executor, spec)) => self.remote_placement(i, executor, spec)?,
            None => {
                let (executor, set) = self.resolve_target(target)?;
                let r = &self.roles[i];
                let from = r.link.as_ref().map(|l| l.host.clone()).unwrap_or_default();
                let executor = if self.registry.by_name(&executor).is_some() {
                    executor
                } else {
                    String::new()
                };
                Placement {
                    place: flight_host_place(&executor, accelerator),
                    cpus: Some(set),
                    accelerator,
                    executor,
                    remote: None,
                    link_fallback: None,
                    why: if from.is_empty() {
                        "moved by hand".to_string()
                    } else {
                        format!("moved by hand from host `{from}`")
                    },
                    policy: None,
                    returning: None,
                }
            }
        };
        let mut placement = placement;
        if trigger.is_some() {
            let from = self.roles[i].host_label();
            placement.why = self.binding_why(trigger.as_ref(), &from);
        }
        let place = placement.place.clone();
        let variant = self.roles[i].variant.clone();
        // loaded at the normal policy: under outside load an idle load got no CPU (measured:
        // 15 s to ready beside two busy threads, 47 ms without them)
        let new_pid = self
            .start_swap(
                role,
                &variant,
                DEFAULT_SWAP_READY_TIMEOUT,
                false,
                Some(placement),
            )
            .map_err(|source| MigrateError::Start {
                role: role.to_string(),
                source,
            })?;
        // sent by hand: it no longer waits to return where a lost link took it from
        self.roles[i].returns_to = None;
        Ok(RoleMove::Started { new_pid, place })
    }

    /// The accelerator executor `executor` names, if any.
    pub(super) fn accelerator_of(&self, executor: &str) -> Option<Accelerator> {
        self.executor_accelerators
            .iter()
            .find(|(name, _)| name == executor)
            .map(|(_, a)| *a)
    }

    /// Whether role `i` may go to `target`, whose accelerator is `accelerator`: only a model
    /// role goes onto one (language models onto CUDA only), an ONNX one only if this host's
    /// ONNX Runtime offers its execution provider (a target `on_other_host` is checked there,
    /// when the role loads).
    /// A refusal leaves the role where it runs.
    fn check_accelerator_move(
        &self,
        i: usize,
        target: &str,
        accelerator: Option<Accelerator>,
        on_other_host: bool,
    ) -> Result<(), MigrateError> {
        let r = &self.roles[i];
        let Some(a) = accelerator else {
            return Ok(());
        };
        if !crate::workflow::runs_on_accelerator(r.kind, &r.variant, a) {
            return Err(MigrateError::NotAccelerated {
                role: r.name.clone(),
                target: target.to_string(),
                accelerator: a,
            });
        }
        // a language model's offload is checked by its new process when it loads (a build
        // without offload, or no device, fails that start and the role stays where it runs)
        let language =
            crate::workflow::LANGUAGE_MODEL_VARIANTS.contains(&(r.kind, r.variant.as_str()));
        if on_other_host || language {
            return Ok(());
        }
        let provider = a.kind.provider();
        match self.registry.providers() {
            Some(offered) if offered.iter().any(|p| p == provider) => Ok(()),
            Some(offered) => Err(MigrateError::AcceleratorUnavailable {
                role: r.name.clone(),
                target: target.to_string(),
                accelerator: a,
                offered: offered.join(", "),
            }),
            None => Err(MigrateError::AcceleratorUnchecked {
                role: r.name.clone(),
                target: target.to_string(),
                accelerator: a,
            }),
        }
    }

    /// Why a role moved from `from` (its binding): the figures of `trigger`, or by hand.
    fn binding_why(&self, trigger: Option<&MigrationTrigger>, from: &str) -> String {
        match trigger {
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
        }
    }

    /// The executor on another host that `target` names (`HOST:EXECUTOR`, or an executor
    /// name that is on another host); `None` when `target` is of the flight's host.
    fn resolve_remote(&self, target: &str) -> Result<Option<(String, RemoteSpec)>, MigrateError> {
        let found = match target.split_once(':') {
            Some((host, executor)) => self
                .remote_executors
                .iter()
                .find(|(name, spec)| name == executor && spec.host == host),
            None => {
                return Ok(self
                    .remote_executors
                    .iter()
                    .find(|(name, _)| name == target)
                    .cloned());
            }
        };
        match found {
            Some(f) => Ok(Some(f.clone())),
            None => Err(MigrateError::UnknownRemoteExecutor {
                target: target.to_string(),
                known: if self.remote_executors.is_empty() {
                    "none".to_string()
                } else {
                    self.remote_executors
                        .iter()
                        .map(|(name, spec)| format!("{}:{name}", spec.host))
                        .collect::<Vec<_>>()
                        .join(", ")
                },
            }),
        }
    }

    /// Where role `i` runs on `executor` of another host, checked: a kind that may move,
    /// not there already, no topic with a role on a third host.
    pub(super) fn remote_placement(
        &self,
        i: usize,
        executor: String,
        spec: RemoteSpec,
    ) -> Result<Placement, MigrateError> {
        let r = &self.roles[i];
        if !movable_across_hosts(r.kind) {
            return Err(MigrateError::NotMovable {
                role: r.name.clone(),
                kind: r.kind,
            });
        }
        let place = format!("host `{}` (executor {executor})", spec.host);
        if r.link.as_ref().is_some_and(|l| l.host == spec.host) && r.executor == executor {
            return Err(MigrateError::AlreadyThere {
                role: r.name.clone(),
                place,
            });
        }
        let k = r.kind.info();
        for o in &self.roles {
            let Some(other_host) = o.link.as_ref().map(|l| &l.host) else {
                continue;
            };
            if o.name == r.name || *other_host == spec.host {
                continue;
            }
            let ok = o.kind.info();
            let shared = k
                .publishes
                .iter()
                .filter(|t| ok.subscribes.contains(t))
                .chain(k.subscribes.iter().filter(|t| ok.publishes.contains(t)))
                .find(|t| **t != topics::HEARTBEAT);
            if let Some(topic) = shared {
                return Err(MigrateError::HostToHost {
                    role: r.name.clone(),
                    host: spec.host.clone(),
                    topic: topic.to_string(),
                    other: o.name.clone(),
                    other_host: other_host.clone(),
                });
            }
        }
        // lost link: the workflow's fallback, else the role as it runs here now
        let link_fallback = r.declared_fallback.clone().or_else(|| match &r.link {
            Some(l) => l.fallback.clone(),
            None => Some(PlannedFallback {
                variant: r.variant.clone(),
                executor: (!r.executor.is_empty()).then(|| r.executor.clone()),
                cpus: r.cpu_set.clone(),
            }),
        });
        let from = r.host_label();
        Ok(Placement {
            cpus: None,
            accelerator: self.accelerator_of(&executor),
            executor,
            why: format!("moved by hand from {from}"),
            place,
            remote: Some(spec),
            link_fallback,
            policy: None,
            returning: None,
        })
    }

    /// Move role `role`'s running process, live, to `target`: an executor name or a CPU
    /// list. Every thread is bound (passes repeat until every thread, new ones included,
    /// reports the new affinity); the pid stays, nothing restarts, no port closes. Later
    /// restarts of the role start on the new CPUs.
    pub fn migrate(&mut self, role: &str, target: &str) -> Result<Migration, MigrateError> {
        self.migrate_with(role, target, None)
    }

    /// The executor named `target`, or the CPU list `target` (named after the executor
    /// with those CPUs, if any).
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
        // named after a CPU executor with those CPUs: an accelerator executor's CPUs are not
        // its accelerator
        let name = self
            .registry
            .executors()
            .iter()
            .find(|e| e.cpus == set && self.accelerator_of(&e.name).is_none())
            .map(|e| e.name.clone())
            .unwrap_or_else(|| format!("cpus {set}"));
        Ok((name, set))
    }

    /// [`Supervisor::migrate`], for a reason: `None` by hand, else the figures of the
    /// policy's move.
    pub(super) fn migrate_with(
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
        if self.accelerator_of(&to_name) != self.roles[i].accelerator {
            return Err(MigrateError::AcceleratorNeedsRestart {
                role: role.to_string(),
                target: target.to_string(),
            });
        }
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
            && let Some(p) = self.initial.probes.as_mut()
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
        let binding = self.binding_why(trigger.as_ref(), &from);
        let r = &mut self.roles[i];
        r.binding = binding;
        // the spec a restart reads names the new CPUs too
        if let Ok(mut spec) = aeris_runtime::RoleSpec::load(&r.spec_path) {
            spec.cpus = r.cpus.clone();
            if let Ok(json) = serde_json::to_string_pretty(&spec) {
                let _ = std::fs::write(&r.spec_path, json);
            }
        }
        // its figures were measured elsewhere
        r.sched.clear();
        r.recent = RecentCycles::default();
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
}
