//! Parsing a workflow: TOML text -> the raw file shape -> a [`Workflow`] with every default
//! filled in, then validated. Syntax and structure errors carry their line and column.

use super::{
    DEFAULT_BACKOFF_MS, DEFAULT_JPEG_QUALITY, DEFAULT_LINK_TIMEOUT_MS, DEFAULT_MAX_RESTARTS,
    Executor, ExecutorCpus, Host, RoleDecl, RoleFallback, SchedulingSpec, Workflow, WorkflowError,
    WorkflowFileError,
};
use crate::restart::RestartPolicy;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::spec::{CameraSpec, MissionSpec, TimingSpec};
use aeris_schemas::{RoleKind, topics};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

// ---------------------------------------------------------------- raw TOML shape

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorkflow {
    #[serde(default)]
    flight: RawFlight,
    #[serde(default)]
    camera: CameraSpec,
    mission: MissionSpec,
    #[serde(default)]
    executors: BTreeMap<String, RawExecutor>,
    #[serde(default)]
    hosts: BTreeMap<String, RawHost>,
    #[serde(default)]
    roles: Vec<RawRole>,
    #[serde(default)]
    scheduling: RawScheduling,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScheduling {
    dynamic: Option<bool>,
    interval_ms: Option<u64>,
    trigger_samples: Option<u32>,
    cooldown_ms: Option<u64>,
    margin: Option<f64>,
    stall_timeout_ms: Option<u64>,
    stall_hard_timeout_ms: Option<u64>,
    adapt_variants: Option<bool>,
    probe_ticks: Option<u32>,
    priority: Option<crate::priority::PriorityMode>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFlight {
    heartbeat_period_ms: Option<u64>,
    decision_deadline_ms: Option<u64>,
    control_rate_hz: Option<f64>,
    setpoint_timeout_ms: Option<u64>,
    idle_heartbeat_ms: Option<u64>,
    feedback: Option<Vec<String>>,
    vehicles: Option<u8>,
    vehicle_spacing_m: Option<f32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawExecutor {
    #[serde(default = "auto")]
    cpus: String,
    host: Option<String>,
    accelerator: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHost {
    endpoint: String,
    keys: Option<String>,
    insecure: Option<bool>,
    link_timeout_ms: Option<u64>,
    frames: Option<String>,
    jpeg_quality: Option<u8>,
}

fn auto() -> String {
    "auto".into()
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRole {
    name: String,
    kind: String,
    variant: String,
    variants: Option<Vec<String>>,
    ladder: Option<Vec<String>>,
    executor: Option<String>,
    restart: Option<String>,
    max_restarts: Option<u32>,
    backoff_ms: Option<u64>,
    budget_ms: Option<f64>,
    #[serde(default)]
    params: serde_json::Map<String, serde_json::Value>,
    subscribes: Option<Vec<String>>,
    publishes: Option<Vec<String>>,
    fallback: Option<String>,
    fallback_executor: Option<String>,
    #[serde(default)]
    per_vehicle: bool,
    #[serde(default)]
    per_vehicle_params: serde_json::Map<String, serde_json::Value>,
}

/// 1-based (line, column) of byte offset `at` in `text`, without slicing `text`.
fn line_column(text: &str, at: usize) -> (usize, usize) {
    let bytes = text.as_bytes();
    let at = at.min(bytes.len());
    let before = &bytes[..at];
    let line = before.iter().filter(|b| **b == b'\n').count() + 1;
    let line_start = before
        .iter()
        .rposition(|b| *b == b'\n')
        .map(|p| p + 1)
        .unwrap_or(0);
    // count characters: bytes that are not UTF-8 continuation bytes
    let column = before[line_start..]
        .iter()
        .filter(|b| (**b & 0xC0) != 0x80)
        .count()
        + 1;
    (line, column)
}

fn located(text: &str, e: &toml::de::Error) -> (usize, usize) {
    match e.span() {
        Some(span) => line_column(text, span.start),
        None => (0, 0),
    }
}

impl Workflow {
    /// Parse and validate a workflow from TOML text.
    pub fn from_toml_str(text: &str) -> Result<Self, WorkflowError> {
        // Grammar first, so that syntax errors are told apart from schema errors.
        if let Err(e) = text.parse::<toml::Table>() {
            let (line, column) = located(text, &e);
            return Err(WorkflowError::Syntax {
                line,
                column,
                message: e.message().trim().to_string(),
            });
        }
        let raw: RawWorkflow = toml::from_str(text).map_err(|e| {
            let (line, column) = located(text, &e);
            WorkflowError::Structure {
                line,
                column,
                message: e.message().trim().to_string(),
            }
        })?;
        let workflow = Self::from_raw(raw)?;
        workflow.validate()?;
        Ok(workflow)
    }

    /// Read, parse and validate a workflow file.
    pub fn from_path(path: &Path) -> Result<Self, WorkflowFileError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| WorkflowFileError::Read {
            path: p.clone(),
            source,
        })?;
        Self::from_toml_str(&text).map_err(|source| WorkflowFileError::Invalid { path: p, source })
    }

    fn from_raw(raw: RawWorkflow) -> Result<Self, WorkflowError> {
        let defaults = TimingSpec::default();
        let period = raw
            .flight
            .heartbeat_period_ms
            .unwrap_or(defaults.heartbeat_period_ms);
        let timing = TimingSpec {
            heartbeat_period_ms: period,
            decision_deadline_ms: raw.flight.decision_deadline_ms.unwrap_or(period),
            control_rate_hz: raw
                .flight
                .control_rate_hz
                .unwrap_or(defaults.control_rate_hz),
            setpoint_timeout_ms: raw
                .flight
                .setpoint_timeout_ms
                .unwrap_or(defaults.setpoint_timeout_ms),
            idle_heartbeat_ms: raw
                .flight
                .idle_heartbeat_ms
                .unwrap_or(defaults.idle_heartbeat_ms),
        };
        let feedback = raw
            .flight
            .feedback
            .unwrap_or_else(|| vec![topics::VEHICLE_TELEMETRY.to_string()]);

        let mut executors = Vec::with_capacity(raw.executors.len());
        for (name, ex) in raw.executors {
            let cpus = match ex.cpus.trim() {
                "auto" => ExecutorCpus::Auto,
                "all" => ExecutorCpus::All,
                list => {
                    // another host's CPUs are its agent's to check
                    let set = CpuSet::parse(list)
                        .and_then(|s| match ex.host {
                            Some(_) => Ok(s),
                            None => s.check_exists().map(|()| s),
                        })
                        .map_err(|source| WorkflowError::BadCpuSet {
                            executor: name.clone(),
                            cpus: ex.cpus.clone(),
                            source,
                        })?;
                    ExecutorCpus::Set(set)
                }
            };
            let accelerator = ex
                .accelerator
                .as_deref()
                .map(str::parse)
                .transpose()
                .map_err(|source| WorkflowError::BadAccelerator {
                    executor: name.clone(),
                    source,
                })?;
            executors.push(Executor {
                name,
                cpus,
                host: ex.host,
                accelerator,
            });
        }

        let fleet = super::Fleet {
            vehicles: raw.flight.vehicles.unwrap_or(1),
            spacing_m: raw
                .flight
                .vehicle_spacing_m
                .unwrap_or(super::DEFAULT_VEHICLE_SPACING_M),
        };
        let fleet_ok = (1..=topics::MAX_FLIGHT_VEHICLES).contains(&fleet.vehicles)
            && fleet.spacing_m.is_finite()
            && fleet.spacing_m > 0.0;
        if !fleet_ok {
            return Err(WorkflowError::BadFleet {
                vehicles: fleet.vehicles,
                spacing_m: fleet.spacing_m,
            });
        }
        let mut roles = Vec::with_capacity(raw.roles.len());
        let mut fit_recorders = false;
        for r in raw.roles {
            // one per vehicle, each in its vehicle's scope, when there are several
            let scopes: Vec<Option<u8>> = if r.per_vehicle && fleet.vehicles > 1 {
                (1..=fleet.vehicles).map(Some).collect()
            } else {
                vec![None]
            };
            let restart = match &r.restart {
                None => RestartPolicy::default(),
                Some(v) => {
                    RestartPolicy::from_name(v).ok_or_else(|| WorkflowError::BadRestart {
                        role: r.name.clone(),
                        value: v.clone(),
                    })?
                }
            };
            let kind = RoleKind::from_name(&r.kind).ok_or_else(|| WorkflowError::UnknownKind {
                role: r.name.clone(),
                kind: r.kind.clone(),
                known: RoleKind::known_names(),
            })?;
            // topics default to the kind's
            let declared = |topics: &[&str]| topics.iter().map(|t| t.to_string()).collect();
            fit_recorders |= kind == RoleKind::Recorder && r.subscribes.is_none();
            let subscribes = r
                .subscribes
                .unwrap_or_else(|| declared(kind.info().subscribes));
            let publishes = r
                .publishes
                .unwrap_or_else(|| declared(kind.info().publishes));
            let fallback = r.fallback.map(|variant| RoleFallback {
                variant,
                executor: r.fallback_executor,
            });
            let role = RoleDecl {
                fallback,
                variants: r.variants.unwrap_or_else(|| vec![r.variant.clone()]),
                ladder: r.ladder.unwrap_or_default(),
                name: r.name,
                kind,
                variant: r.variant,
                executor: r.executor,
                restart,
                max_restarts: r.max_restarts.unwrap_or(DEFAULT_MAX_RESTARTS),
                backoff_ms: r.backoff_ms.unwrap_or(DEFAULT_BACKOFF_MS),
                budget_ms: r.budget_ms,
                params: r.params,
                subscribes,
                publishes,
                vehicle: None,
            };
            for (key, values) in &r.per_vehicle_params {
                let fits = values
                    .as_array()
                    .is_some_and(|v| v.len() == usize::from(fleet.vehicles));
                if !(r.per_vehicle && fits) {
                    return Err(WorkflowError::PerVehicleParam {
                        role: role.name.clone(),
                        key: key.clone(),
                        vehicles: fleet.vehicles,
                    });
                }
            }
            for vehicle in scopes {
                let mut role = role.clone();
                if let Some(k) = vehicle {
                    role.name = format!("{}-v{k}", role.name);
                    role.vehicle = Some(k);
                }
                // vehicle K's own value of each per-vehicle parameter (one vehicle: the first)
                let index = usize::from(vehicle.unwrap_or(1)) - 1;
                for (key, values) in &r.per_vehicle_params {
                    if let Some(v) = values.as_array().and_then(|a| a.get(index)) {
                        role.params.insert(key.clone(), v.clone());
                    }
                }
                roles.push(role);
            }
        }
        let d = SchedulingSpec::defaults(&timing);
        let rs = raw.scheduling;
        let scheduling = SchedulingSpec {
            dynamic: rs.dynamic.unwrap_or(d.dynamic),
            interval_ms: rs.interval_ms.unwrap_or(d.interval_ms),
            trigger_samples: rs.trigger_samples.unwrap_or(d.trigger_samples),
            cooldown_ms: rs.cooldown_ms.unwrap_or(d.cooldown_ms),
            margin: rs.margin.unwrap_or(d.margin),
            stall_timeout_ms: rs.stall_timeout_ms.unwrap_or(d.stall_timeout_ms),
            stall_hard_timeout_ms: rs.stall_hard_timeout_ms.unwrap_or(d.stall_hard_timeout_ms),
            adapt_variants: rs.adapt_variants.unwrap_or(d.adapt_variants),
            probe_ticks: rs.probe_ticks.unwrap_or(d.probe_ticks),
            priority: rs.priority.unwrap_or(d.priority),
        };
        let hosts = raw
            .hosts
            .into_iter()
            .map(|(name, h)| Host {
                name,
                endpoint: h.endpoint,
                keys: h.keys,
                insecure: h.insecure.unwrap_or(false),
                link_timeout_ms: h.link_timeout_ms.unwrap_or(DEFAULT_LINK_TIMEOUT_MS),
                frames: h.frames.unwrap_or_else(|| "jpeg".to_string()),
                jpeg_quality: h.jpeg_quality.unwrap_or(DEFAULT_JPEG_QUALITY),
            })
            .collect();
        let mut workflow = Workflow {
            hosts,
            timing,
            feedback,
            camera: raw.camera,
            mission: raw.mission,
            executors,
            roles,
            scheduling,
            fleet,
        };
        if fit_recorders {
            // a recorder records what this flight publishes, not every topic there is
            workflow.fit_recorders();
        }
        Ok(workflow)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workflow::DEFAULT_WORKFLOW_TOML;

    #[test]
    fn line_and_column_count_characters() {
        assert_eq!(line_column("ab\ncd", 4), (2, 2));
        assert_eq!(line_column("é=\nx", 2), (1, 2));
        assert_eq!(line_column("abc", 100), (1, 4));
    }

    #[test]
    fn probe_ticks_parse_and_one_tick_is_refused() {
        let w = Workflow::builtin_default().unwrap();
        assert_eq!(w.scheduling.probe_ticks, 4);
        let text = |n: u32| format!("{DEFAULT_WORKFLOW_TOML}\n[scheduling]\nprobe_ticks = {n}\n");
        let w = Workflow::from_toml_str(&text(0)).unwrap();
        assert_eq!(w.scheduling.probe_ticks, 0);
        for n in [1, 41] {
            let err = Workflow::from_toml_str(&text(n)).unwrap_err().to_string();
            assert!(err.contains("probe_ticks"), "{n}: {err}");
        }
    }
}
