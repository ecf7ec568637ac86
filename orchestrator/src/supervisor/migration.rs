//! Live migration: moving a role's running process to another executor (every thread, same
//! pid, checked), by hand (`aeris migrate`) or for the scheduling policy, and the move's line
//! in `RUN_DIR/scheduling.jsonl`.

use super::Supervisor;
use super::error::MigrateError;
use super::events::{Migration, MigrationTrigger, SupervisorEvent};
use super::role_runtime::{RECENT_CYCLES, RoleState};
use crate::executors::process_threads;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::LatencyWindow;
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

impl Supervisor {
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
        let name = self
            .registry
            .by_cpus(&set)
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
}
