//! What `aeris validate` says of a workflow file: its roles, hosts, bridges, the executors a
//! flight of it would start with and their accelerators, as one value ([`WorkflowCheck`]):
//! `Display` is the command's text, `Serialize` its `--json`.

use crate::executors::{accelerator_line, planned_registry};
use aeris_orchestrator::executors::ExecutorOrigin;
use aeris_orchestrator::launch::PlanError;
use aeris_orchestrator::workflow::Workflow;
use aeris_schemas::RoleKind;
use serde::Serialize;
use std::fmt;

/// A checked workflow and what a flight of it would start.
#[derive(Debug, Clone, Serialize)]
pub struct WorkflowCheck {
    /// The workflow file.
    pub workflow: String,
    /// Its mission's subgoals.
    pub subgoals: usize,
    /// Its roles.
    pub roles: Vec<RoleLine>,
    /// Its other hosts (an `aeris agent` runs on each).
    pub hosts: Vec<HostLine>,
    /// The bridge to each other host and what it carries.
    pub bridges: Vec<BridgeLine>,
    /// The executors on other hosts.
    pub remote_executors: Vec<ExecutorLine>,
    /// The executor registry a flight would start with on this machine.
    pub executors: Vec<ExecutorLine>,
    /// What ONNX Runtime reports of this machine's accelerators, as one line.
    pub accelerators: String,
    /// The executors that run their model roles on an accelerator, and which.
    pub executor_accelerators: Vec<(String, String)>,
}

/// One role of the workflow.
#[derive(Debug, Clone, Serialize)]
pub struct RoleLine {
    /// Role name.
    pub name: String,
    /// Its kind.
    pub kind: RoleKind,
    /// Its variant.
    pub variant: String,
    /// Its declared executor (`None`: the supervisor binds it).
    pub executor: Option<String>,
    /// The other host it runs on (`None`: this one).
    pub host: Option<String>,
}

/// One other host.
#[derive(Debug, Clone, Serialize)]
pub struct HostLine {
    /// Host name.
    pub name: String,
    /// Its agent's endpoint.
    pub endpoint: String,
    /// The identity directory of the mutual-TLS link (`None`: insecure plain TCP).
    pub keys: Option<String>,
    /// The link counts as lost after this long without the agent (ms).
    pub link_timeout_ms: u64,
}

/// The bridge to one other host.
#[derive(Debug, Clone, Serialize)]
pub struct BridgeLine {
    /// The other host.
    pub host: String,
    /// Topics sent there.
    pub sends: Vec<String>,
    /// Topics received from there.
    pub receives: Vec<String>,
}

/// One executor.
#[derive(Debug, Clone, Serialize)]
pub struct ExecutorLine {
    /// Executor name.
    pub name: String,
    /// Its CPUs.
    pub cpus: String,
    /// `declared`, `discovered`, or the other host it is on.
    pub origin: String,
}

impl WorkflowCheck {
    /// What a flight of `workflow` (read from `file`) would start on this machine; an error
    /// when its executors do not resolve here. (Whether its accelerators are usable is
    /// [`crate::executors::check_accelerators`].)
    pub fn of(file: &str, workflow: &Workflow) -> Result<Self, PlanError> {
        let w = workflow;
        let registry = planned_registry(w)?;
        Ok(WorkflowCheck {
            workflow: file.to_string(),
            subgoals: w.mission.subgoals.len(),
            roles: w
                .roles
                .iter()
                .map(|r| RoleLine {
                    name: r.name.clone(),
                    kind: r.kind,
                    variant: r.variant.clone(),
                    executor: r.executor.clone(),
                    host: w.role_host(r).map(|h| h.name.clone()),
                })
                .collect(),
            hosts: w
                .hosts
                .iter()
                .map(|h| HostLine {
                    name: h.name.clone(),
                    endpoint: h.endpoint.clone(),
                    keys: h.keys.clone(),
                    link_timeout_ms: h.link_timeout_ms,
                })
                .collect(),
            bridges: w
                .bridge_plans()
                .into_iter()
                .map(|b| BridgeLine {
                    host: b.host.name,
                    sends: b.to_host,
                    receives: b.from_host,
                })
                .collect(),
            remote_executors: w
                .executors
                .iter()
                .filter_map(|e| {
                    e.host.as_ref().map(|h| ExecutorLine {
                        name: e.name.clone(),
                        cpus: e.cpus.to_string(),
                        origin: h.clone(),
                    })
                })
                .collect(),
            executors: registry
                .executors()
                .iter()
                .map(|e| ExecutorLine {
                    name: e.name.clone(),
                    cpus: e.cpus.to_string(),
                    origin: match e.origin {
                        ExecutorOrigin::Declared => "declared",
                        ExecutorOrigin::Discovered => "discovered",
                    }
                    .to_string(),
                })
                .collect(),
            accelerators: accelerator_line(&registry),
            executor_accelerators: w
                .executors
                .iter()
                .filter_map(|e| e.accelerator.map(|a| (e.name.clone(), a.to_string())))
                .collect(),
        })
    }
}

impl fmt::Display for WorkflowCheck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: ok — {} roles, {} subgoals",
            self.workflow,
            self.roles.len(),
            self.subgoals
        )?;
        for r in &self.roles {
            let host = r
                .host
                .as_ref()
                .map(|h| format!(" on host {h}"))
                .unwrap_or_default();
            writeln!(
                f,
                "  {:<18} {:<10} {:<15} executor {}{host}",
                r.name,
                r.kind,
                r.variant,
                r.executor.as_deref().unwrap_or("-")
            )?;
        }
        if !self.hosts.is_empty() {
            writeln!(f, "hosts (an `aeris agent` runs on each):")?;
            for h in &self.hosts {
                let link = match &h.keys {
                    Some(k) => format!("mutual TLS, keys {k}"),
                    None => "INSECURE plain TCP".to_string(),
                };
                writeln!(
                    f,
                    "  {:<18} {:<22} {link}, link timeout {} ms",
                    h.name, h.endpoint, h.link_timeout_ms
                )?;
            }
            for b in &self.bridges {
                writeln!(
                    f,
                    "  bridge to {}: sends {}; receives {}",
                    b.host,
                    b.sends.join(", "),
                    b.receives.join(", ")
                )?;
            }
            for e in &self.remote_executors {
                writeln!(
                    f,
                    "  executor {:<9} CPUs {:<8} on host {}",
                    e.name, e.cpus, e.origin
                )?;
            }
        }
        writeln!(f, "executors:")?;
        for e in &self.executors {
            writeln!(f, "  {:<18} CPUs {:<8} {}", e.name, e.cpus, e.origin)?;
        }
        writeln!(f, "{}", self.accelerators)?;
        for (executor, accelerator) in &self.executor_accelerators {
            writeln!(
                f,
                "  executor {executor} runs its model roles on {accelerator}"
            )?;
        }
        Ok(())
    }
}
