//! Workflow files: which roles a flight runs, on which executors, with which message paths.
//!
//! A workflow is a TOML file (format in `workflows/README.md`). [`Workflow::from_toml_str`]
//! parses and validates it in one go; every problem comes back as a [`WorkflowError`] that
//! names the offending role, field, executor or topic and says how to fix it. Parsing never
//! panics, whatever the input.

use crate::restart::RestartPolicy;
use aeris_runtime::affinity::{CpuSet, CpuSetError};
use aeris_runtime::catalog::{ROLE_KINDS, role_kind};
use aeris_runtime::spec::{CameraSpec, MissionError, MissionSpec, TimingSpec};
use aeris_schemas::heartbeat::NAME_MAX;
use aeris_schemas::{MAX_ROLES, topics};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The built-in default flight (`workflows/default.toml`).
pub const DEFAULT_WORKFLOW_TOML: &str = include_str!("../../workflows/default.toml");

/// The model flight (`workflows/models.toml`): a real model in every perception and
/// reasoning role; what `aeris bench cycle` and `aeris bench swap` fly.
pub const MODELS_WORKFLOW_TOML: &str = include_str!("../../workflows/models.toml");

/// Role kinds every workflow must have (plus `vehicle` while the controller's autopilot is
/// `auto`). S_t may come from one `perception` role or from the perception pipeline
/// (`image-to-text` composing the blocks): the topic check requires a publisher of
/// `perception/state` either way.
pub const REQUIRED_KINDS: [&str; 4] = ["hub", "reasoning", "controller", "camera"];

/// Default restart budget of a role.
pub const DEFAULT_MAX_RESTARTS: u32 = 5;
/// Default first backoff of a role (ms).
pub const DEFAULT_BACKOFF_MS: u64 = 100;

/// Where an executor's CPUs come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ExecutorCpus {
    /// One CPU chosen by the supervisor (auto executors are spread round-robin).
    Auto,
    /// Every CPU the supervisor may run on.
    All,
    /// This explicit set.
    Set(CpuSet),
}

impl core::fmt::Display for ExecutorCpus {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ExecutorCpus::Auto => write!(f, "auto"),
            ExecutorCpus::All => write!(f, "all"),
            ExecutorCpus::Set(s) => write!(f, "{s}"),
        }
    }
}

/// A named executor: a CPU set roles are bound to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Executor {
    /// Executor name (the key under `[executors]`).
    pub name: String,
    /// Its CPUs.
    pub cpus: ExecutorCpus,
}

/// One role of the workflow, validated against the catalog.
#[derive(Debug, Clone, PartialEq)]
pub struct RoleDecl {
    /// Unique instance name.
    pub name: String,
    /// Kind from [`ROLE_KINDS`].
    pub kind: String,
    /// The variant to start.
    pub variant: String,
    /// Variants this role may be switched to (contains `variant`).
    pub variants: Vec<String>,
    /// Its variant ladder, most capable first, lightest last (empty: none): the supervisor
    /// steps it along the ladder when a variant keeps missing its budget
    /// ([`crate::ladder`]). Every entry is in `variants`, and `variant` is on it.
    pub ladder: Vec<String>,
    /// Executor name, if bound.
    pub executor: Option<String>,
    /// Restart policy.
    pub restart: RestartPolicy,
    /// Restart budget.
    pub max_restarts: u32,
    /// First restart backoff (ms), doubling up to 5 s.
    pub backoff_ms: u64,
    /// Latency budget (ms) as written; `None` takes the kind's default
    /// ([`Workflow::role_budget_ms`]).
    pub budget_ms: Option<f64>,
    /// Free-form parameters handed to the role.
    pub params: serde_json::Map<String, serde_json::Value>,
    /// Topics it subscribes to (the catalog's unless overridden).
    pub subscribes: Vec<String>,
    /// Topics it publishes (the catalog's unless overridden; `heartbeat` is implicit).
    pub publishes: Vec<String>,
}

impl RoleDecl {
    /// A string parameter.
    pub fn param_str(&self, key: &str) -> Option<&str> {
        self.params.get(key).and_then(|v| v.as_str())
    }

    /// A hot-standby controller (`kind = "controller"`, `params.standby = true`).
    pub fn is_standby_controller(&self) -> bool {
        self.kind == "controller"
            && self.params.get("standby").and_then(|v| v.as_bool()) == Some(true)
    }
}

/// A validated workflow.
///
/// The fields are public so that tools can adjust a workflow (e.g. pick another variant);
/// call [`Workflow::validate`] after changing one. The supervisor validates again at start.
#[derive(Debug, Clone, PartialEq)]
pub struct Workflow {
    /// Flight timing.
    pub timing: TimingSpec,
    /// Topics allowed to close a loop (edges through them are not service dependencies).
    pub feedback: Vec<String>,
    /// Camera geometry.
    pub camera: CameraSpec,
    /// The mission.
    pub mission: MissionSpec,
    /// Executors, sorted by name.
    pub executors: Vec<Executor>,
    /// Roles in declaration order.
    pub roles: Vec<RoleDecl>,
    /// Dynamic scheduling and stall detection (`[scheduling]`).
    pub scheduling: SchedulingSpec,
}

/// The `[scheduling]` table: latency-driven re-binding and stall detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchedulingSpec {
    /// Re-bind roles between executors when their latency exceeds their budget (DS).
    pub dynamic: bool,
    /// How often the supervisor samples load and evaluates the binding (ms).
    pub interval_ms: u64,
    /// Consecutive over-budget samples before roles move.
    pub trigger_samples: u32,
    /// A moved role stays put this long; after a failed search, the wait before the next (ms).
    pub cooldown_ms: u64,
    /// Roles over budget must fit this fraction below it after a move (0..0.9).
    pub margin: f64,
    /// A running role silent this long while stopped or making no CPU progress is stalled
    /// and replaced (ms; default half the heartbeat period).
    pub stall_timeout_ms: u64,
    /// A running role silent this long is stalled whatever its state (ms).
    pub stall_hard_timeout_ms: u64,
    /// Step roles with a `ladder` between their variants on measured latency (the
    /// role-adaptive model stack); `false` keeps every role on its declared variant.
    pub adapt_variants: bool,
    /// Scheduling ticks the initial binding spends on each other executor, measuring a role
    /// that does not fit its budget where the workflow put it; 0 judges every executor
    /// from its load instead of probing.
    pub probe_ticks: u32,
}

impl SchedulingSpec {
    /// The defaults for a flight with `timing`.
    pub fn defaults(timing: &TimingSpec) -> Self {
        Self {
            dynamic: true,
            interval_ms: 250,
            trigger_samples: 2,
            cooldown_ms: 10_000,
            margin: 0.2,
            stall_timeout_ms: (timing.heartbeat_period_ms / 2).max(3 * timing.idle_heartbeat_ms),
            // a role busy in one long cycle (a language model's first prefill on a crowded
            // CPU takes over 10 s) is working, not stalled: only a very long silence counts
            stall_hard_timeout_ms: timing.heartbeat_period_ms.saturating_mul(30).max(60_000),
            adapt_variants: true,
            probe_ticks: 4,
        }
    }
}

/// Why a workflow is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorkflowError {
    /// The text is not valid TOML.
    #[error("TOML syntax error at line {line}, column {column}: {message}")]
    Syntax {
        /// 1-based line.
        line: usize,
        /// 1-based column (characters).
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// Valid TOML but not a workflow: an unknown or missing field, or a wrong type.
    #[error(
        "line {line}, column {column}: {message} (see workflows/README.md for the workflow format)"
    )]
    Structure {
        /// 1-based line (0 when unknown).
        line: usize,
        /// 1-based column (0 when unknown).
        column: usize,
        /// The message, naming the field.
        message: String,
    },
    /// A `[flight]` timing value is out of range.
    #[error("[flight] {field} = {value}: {reason}")]
    Timing {
        /// The field.
        field: &'static str,
        /// The value as written.
        value: String,
        /// What range it must be in.
        reason: &'static str,
    },
    /// A `[camera]` value is out of range.
    #[error("[camera] {field} = {value}: {reason}")]
    Camera {
        /// The field.
        field: &'static str,
        /// The value as written.
        value: String,
        /// What range it must be in.
        reason: &'static str,
    },
    /// The mission is not flyable.
    #[error("[mission] is invalid: {0}")]
    Mission(MissionError),
    /// An executor's `cpus` is not a usable CPU list.
    #[error("[executors.{executor}] cpus is unusable (write a CPU list, \"all\" or \"auto\")")]
    BadCpuSet {
        /// Executor name.
        executor: String,
        /// The text as written.
        cpus: String,
        /// Why it is unusable.
        source: CpuSetError,
    },
    /// More roles than the status board can list.
    #[error("the workflow has {count} roles; at most {max} are supported")]
    TooManyRoles {
        /// Roles declared.
        count: usize,
        /// The limit.
        max: usize,
    },
    /// A role name is empty, too long or has characters other than `A-Z a-z 0-9 _ -`.
    #[error(
        "role name `{name}` is invalid: use 1-{NAME_MAX} characters of A-Z, a-z, 0-9, `_`, `-`"
    )]
    BadRoleName {
        /// The name.
        name: String,
    },
    /// Two roles share a name.
    #[error("two roles are named `{name}`: role names must be unique")]
    DuplicateRole {
        /// The name.
        name: String,
    },
    /// A role's kind is not in the catalog.
    #[error("role `{role}`: unknown kind `{kind}` (known kinds: {known})")]
    UnknownKind {
        /// Role name.
        role: String,
        /// The kind as written.
        kind: String,
        /// Known kinds, comma-separated.
        known: String,
    },
    /// A role's variant (or one of its pool) is not a variant of its kind.
    #[error("role `{role}`: kind `{kind}` has no variant `{variant}` (known variants: {known})")]
    UnknownVariant {
        /// Role name.
        role: String,
        /// Its kind.
        kind: String,
        /// The variant as written.
        variant: String,
        /// Known variants, comma-separated.
        known: String,
    },
    /// The role's `variant` is not in its `variants` pool.
    #[error("role `{role}`: variant `{variant}` is not in its variants pool [{pool}]; add it")]
    VariantNotInPool {
        /// Role name.
        role: String,
        /// The variant.
        variant: String,
        /// The pool, comma-separated.
        pool: String,
    },
    /// A role's `ladder` is unusable.
    #[error("role `{role}`: ladder [{ladder}]: {reason}")]
    BadLadder {
        /// Role name.
        role: String,
        /// The ladder, comma-separated.
        ladder: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The restart policy is not `never`, `on-failure` or `always`.
    #[error("role `{role}`: restart = \"{value}\" is unknown (use never, on-failure or always)")]
    BadRestart {
        /// Role name.
        role: String,
        /// The value as written.
        value: String,
    },
    /// A `[scheduling]` value is out of range.
    #[error("[scheduling] {field} = {value}: {reason}")]
    Scheduling {
        /// The field.
        field: &'static str,
        /// The value as written.
        value: String,
        /// What it must be.
        reason: &'static str,
    },
    /// A role's `budget_ms` is not a positive number.
    #[error("role `{role}`: budget_ms = {value} must be a positive number of milliseconds")]
    BadBudget {
        /// Role name.
        role: String,
        /// The value.
        value: String,
    },
    /// A role names an executor that is not declared.
    #[error("role `{role}`: executor `{executor}` is not declared (declared: {known})")]
    UnknownExecutor {
        /// Role name.
        role: String,
        /// The executor as written.
        executor: String,
        /// Declared executors, comma-separated (or "none").
        known: String,
    },
    /// A role parameter has the wrong type.
    #[error("role `{role}`: params.{param} {reason}")]
    BadParam {
        /// Role name.
        role: String,
        /// Parameter name.
        param: &'static str,
        /// What is wrong.
        reason: &'static str,
    },
    /// A role names a topic that does not exist.
    #[error("role `{role}`: unknown topic `{topic}` in {list} (known topics: {known})")]
    UnknownTopic {
        /// Role name.
        role: String,
        /// The topic as written.
        topic: String,
        /// `subscribes` or `publishes`.
        list: &'static str,
        /// Known topics, comma-separated.
        known: String,
    },
    /// A `[flight] feedback` entry is not a topic.
    #[error("[flight] feedback: unknown topic `{topic}` (known topics: {known})")]
    UnknownFeedbackTopic {
        /// The topic as written.
        topic: String,
        /// Known topics, comma-separated.
        known: String,
    },
    /// A required role kind is missing.
    #[error("the workflow has no role of kind `{kind}`{hint}")]
    MissingRole {
        /// The missing kind.
        kind: &'static str,
        /// Why it is needed / how to fix, may be empty.
        hint: &'static str,
    },
    /// A role subscribes to a topic nobody publishes.
    #[error("role `{role}` subscribes to `{topic}`, but no role publishes it")]
    Unpublished {
        /// Role name.
        role: String,
        /// The topic.
        topic: String,
    },
    /// The services graph has a cycle that no feedback topic breaks.
    #[error(
        "the services graph has a cycle: {} (list the topic that closes the loop in [flight] feedback, or change the roles' subscribes)",
        cycle_text(.path, .topics)
    )]
    Cycle {
        /// Roles on the cycle; the first is repeated at the end.
        path: Vec<String>,
        /// The topic of each edge (`topics[i]` goes from `path[i]` to `path[i + 1]`).
        topics: Vec<String>,
    },
}

fn cycle_text(path: &[String], topics: &[String]) -> String {
    let mut out = String::new();
    for (i, role) in path.iter().enumerate() {
        out.push_str(role);
        if let Some(t) = topics.get(i) {
            out.push_str(" -[");
            out.push_str(t);
            out.push_str("]-> ");
        }
    }
    out
}

/// Why a workflow file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum WorkflowFileError {
    /// The file could not be read.
    #[error("cannot read workflow file {path}")]
    Read {
        /// The path.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The file was read but is not a valid workflow.
    #[error("workflow file {path} is invalid")]
    Invalid {
        /// The path.
        path: String,
        /// What is wrong.
        source: WorkflowError,
    },
}

impl WorkflowFileError {
    /// The validation error, when the file was read.
    pub fn workflow_error(&self) -> Option<&WorkflowError> {
        match self {
            WorkflowFileError::Read { .. } => None,
            WorkflowFileError::Invalid { source, .. } => Some(source),
        }
    }
}

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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawExecutor {
    #[serde(default = "auto")]
    cpus: String,
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

fn known_topics() -> String {
    topics::ALL.join(", ")
}

fn is_valid_role_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= NAME_MAX
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
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

    /// The built-in default flight (`workflows/default.toml`).
    pub fn builtin_default() -> Result<Self, WorkflowError> {
        Self::from_toml_str(DEFAULT_WORKFLOW_TOML)
    }

    /// The built-in model flight ([`MODELS_WORKFLOW_TOML`]).
    pub fn builtin_models() -> Result<Self, WorkflowError> {
        Self::from_toml_str(MODELS_WORKFLOW_TOML)
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
                    let set = CpuSet::parse(list)
                        .and_then(|s| s.check_exists().map(|()| s))
                        .map_err(|source| WorkflowError::BadCpuSet {
                            executor: name.clone(),
                            cpus: ex.cpus.clone(),
                            source,
                        })?;
                    ExecutorCpus::Set(set)
                }
            };
            executors.push(Executor { name, cpus });
        }

        let mut roles = Vec::with_capacity(raw.roles.len());
        for r in raw.roles {
            let restart = match &r.restart {
                None => RestartPolicy::default(),
                Some(v) => {
                    RestartPolicy::from_name(v).ok_or_else(|| WorkflowError::BadRestart {
                        role: r.name.clone(),
                        value: v.clone(),
                    })?
                }
            };
            // Topics default to the catalog's; an unknown kind is reported by validate().
            let entry = role_kind(&r.kind);
            let catalog = |f: fn(&aeris_runtime::catalog::RoleKind) -> &'static [&'static str]| {
                entry
                    .map(|k| f(k).iter().map(|t| t.to_string()).collect())
                    .unwrap_or_default()
            };
            let subscribes = r.subscribes.unwrap_or_else(|| catalog(|k| k.subscribes));
            let publishes = r.publishes.unwrap_or_else(|| catalog(|k| k.publishes));
            roles.push(RoleDecl {
                variants: r.variants.unwrap_or_else(|| vec![r.variant.clone()]),
                ladder: r.ladder.unwrap_or_default(),
                name: r.name,
                kind: r.kind,
                variant: r.variant,
                executor: r.executor,
                restart,
                max_restarts: r.max_restarts.unwrap_or(DEFAULT_MAX_RESTARTS),
                backoff_ms: r.backoff_ms.unwrap_or(DEFAULT_BACKOFF_MS),
                budget_ms: r.budget_ms,
                params: r.params,
                subscribes,
                publishes,
            });
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
        };
        Ok(Workflow {
            timing,
            feedback,
            camera: raw.camera,
            mission: raw.mission,
            executors,
            roles,
            scheduling,
        })
    }

    /// Check everything: timing, camera, mission, executors, roles against the catalog,
    /// required kinds, topics, and that the services graph has no cycle.
    pub fn validate(&self) -> Result<(), WorkflowError> {
        self.validate_timing()?;
        self.validate_scheduling()?;
        self.validate_camera()?;
        self.mission.validate().map_err(WorkflowError::Mission)?;
        for ex in &self.executors {
            if let ExecutorCpus::Set(set) = &ex.cpus {
                set.check_exists()
                    .map_err(|source| WorkflowError::BadCpuSet {
                        executor: ex.name.clone(),
                        cpus: set.to_string(),
                        source,
                    })?;
            }
        }
        self.validate_roles()?;
        self.validate_required()?;
        self.validate_topics()?;
        if let Some((path, topics)) = self.find_cycle() {
            return Err(WorkflowError::Cycle { path, topics });
        }
        Ok(())
    }

    /// The latency budget of `role` (ms): its `budget_ms`, else its kind's share of the
    /// heartbeat — half for reasoning, a quarter for each perception kind, one period for the
    /// periodic camera, hub and controller; `None` for the simulated vehicle (part of the
    /// world, not of the stack), which is never re-bound for its own latency.
    pub fn role_budget_ms(&self, role: &RoleDecl) -> Option<f64> {
        if role.budget_ms.is_some() {
            return role.budget_ms;
        }
        let hb = self.timing.heartbeat_period_ms as f64;
        match role.kind.as_str() {
            "reasoning" => Some(hb * 0.5),
            "camera" => Some(1000.0 / self.camera.fps.max(1.0)),
            "hub" | "controller" => Some(1000.0 / self.timing.control_rate_hz),
            "vehicle" => None,
            _ => Some(hb * 0.25),
        }
    }

    fn validate_scheduling(&self) -> Result<(), WorkflowError> {
        let s = &self.scheduling;
        let bad = |field, value: String, reason| WorkflowError::Scheduling {
            field,
            value,
            reason,
        };
        if s.interval_ms < 20 {
            return Err(bad(
                "interval_ms",
                s.interval_ms.to_string(),
                "must be at least 20 ms",
            ));
        }
        if s.trigger_samples == 0 {
            return Err(bad("trigger_samples", "0".into(), "must be at least 1"));
        }
        if s.probe_ticks == 1 || s.probe_ticks > 40 {
            return Err(bad(
                "probe_ticks",
                s.probe_ticks.to_string(),
                "must be 0 (no probes) or 2..=40 (a slowdown needs two samples on the executor)",
            ));
        }
        if !(s.margin.is_finite() && (0.0..=0.9).contains(&s.margin)) {
            return Err(bad("margin", s.margin.to_string(), "must be in 0..=0.9"));
        }
        if s.stall_timeout_ms < 2 * self.timing.idle_heartbeat_ms {
            return Err(bad(
                "stall_timeout_ms",
                s.stall_timeout_ms.to_string(),
                "must be at least twice idle_heartbeat_ms (a live idle role would look stalled)",
            ));
        }
        if s.stall_hard_timeout_ms < s.stall_timeout_ms {
            return Err(bad(
                "stall_hard_timeout_ms",
                s.stall_hard_timeout_ms.to_string(),
                "must be at least stall_timeout_ms",
            ));
        }
        for r in &self.roles {
            if let Some(b) = r.budget_ms
                && !(b.is_finite() && b > 0.0)
            {
                return Err(WorkflowError::BadBudget {
                    role: r.name.clone(),
                    value: b.to_string(),
                });
            }
        }
        Ok(())
    }

    fn validate_timing(&self) -> Result<(), WorkflowError> {
        let t = &self.timing;
        let bad = |field, value: String, reason| WorkflowError::Timing {
            field,
            value,
            reason,
        };
        for (field, v) in [
            ("heartbeat_period_ms", t.heartbeat_period_ms),
            ("decision_deadline_ms", t.decision_deadline_ms),
            ("setpoint_timeout_ms", t.setpoint_timeout_ms),
            ("idle_heartbeat_ms", t.idle_heartbeat_ms),
        ] {
            if v == 0 {
                return Err(bad(field, v.to_string(), "must be at least 1 ms"));
            }
        }
        if t.decision_deadline_ms > t.heartbeat_period_ms.saturating_mul(10) {
            return Err(bad(
                "decision_deadline_ms",
                t.decision_deadline_ms.to_string(),
                "must be at most 10 times heartbeat_period_ms",
            ));
        }
        if !(t.control_rate_hz.is_finite() && (1.0..=1000.0).contains(&t.control_rate_hz)) {
            return Err(bad(
                "control_rate_hz",
                t.control_rate_hz.to_string(),
                "must be a finite rate in 1..=1000 Hz",
            ));
        }
        Ok(())
    }

    fn validate_camera(&self) -> Result<(), WorkflowError> {
        let c = &self.camera;
        let bad = |field, value: String, reason| WorkflowError::Camera {
            field,
            value,
            reason,
        };
        if !(1..=4096).contains(&c.width) {
            return Err(bad("width", c.width.to_string(), "must be in 1..=4096"));
        }
        if !(1..=4096).contains(&c.height) {
            return Err(bad("height", c.height.to_string(), "must be in 1..=4096"));
        }
        if !(c.fps.is_finite() && c.fps > 0.0 && c.fps <= 1000.0) {
            return Err(bad("fps", c.fps.to_string(), "must be in (0, 1000]"));
        }
        if !(c.hfov_deg.is_finite() && c.hfov_deg > 0.0 && c.hfov_deg < 180.0) {
            return Err(bad(
                "hfov_deg",
                c.hfov_deg.to_string(),
                "must be in (0, 180) degrees",
            ));
        }
        Ok(())
    }

    fn validate_roles(&self) -> Result<(), WorkflowError> {
        if self.roles.len() > MAX_ROLES {
            return Err(WorkflowError::TooManyRoles {
                count: self.roles.len(),
                max: MAX_ROLES,
            });
        }
        let known_kinds = || {
            ROLE_KINDS
                .iter()
                .map(|k| k.kind)
                .collect::<Vec<_>>()
                .join(", ")
        };
        for (i, r) in self.roles.iter().enumerate() {
            if !is_valid_role_name(&r.name) {
                return Err(WorkflowError::BadRoleName {
                    name: r.name.clone(),
                });
            }
            if self.roles[..i].iter().any(|o| o.name == r.name) {
                return Err(WorkflowError::DuplicateRole {
                    name: r.name.clone(),
                });
            }
            let Some(kind) = role_kind(&r.kind) else {
                return Err(WorkflowError::UnknownKind {
                    role: r.name.clone(),
                    kind: r.kind.clone(),
                    known: known_kinds(),
                });
            };
            for v in core::iter::once(&r.variant).chain(r.variants.iter()) {
                if !kind.variants.contains(&v.as_str()) {
                    return Err(WorkflowError::UnknownVariant {
                        role: r.name.clone(),
                        kind: r.kind.clone(),
                        variant: v.clone(),
                        known: kind.variants.join(", "),
                    });
                }
            }
            if !r.variants.contains(&r.variant) {
                return Err(WorkflowError::VariantNotInPool {
                    role: r.name.clone(),
                    variant: r.variant.clone(),
                    pool: r.variants.join(", "),
                });
            }
            if !r.ladder.is_empty() {
                let bad = |reason: String| WorkflowError::BadLadder {
                    role: r.name.clone(),
                    ladder: r.ladder.join(", "),
                    reason,
                };
                if r.ladder.len() < 2 {
                    return Err(bad("a ladder needs at least two variants".into()));
                }
                if let Some(v) = r.ladder.iter().find(|v| !r.variants.contains(v)) {
                    return Err(bad(format!(
                        "`{v}` is not in the variants pool [{}]",
                        r.variants.join(", ")
                    )));
                }
                if let Some((i, v)) = r
                    .ladder
                    .iter()
                    .enumerate()
                    .find(|(i, v)| r.ladder[..*i].contains(v))
                {
                    return Err(bad(format!("`{v}` is on it twice (again at rung {i})")));
                }
                if !r.ladder.contains(&r.variant) {
                    return Err(bad(format!(
                        "the declared variant `{}` is not on it (the role starts there)",
                        r.variant
                    )));
                }
            }
            if let Some(ex) = &r.executor
                && !self.executors.iter().any(|e| &e.name == ex)
            {
                let known = if self.executors.is_empty() {
                    "none".to_string()
                } else {
                    self.executors
                        .iter()
                        .map(|e| e.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                return Err(WorkflowError::UnknownExecutor {
                    role: r.name.clone(),
                    executor: ex.clone(),
                    known,
                });
            }
            let string_param = |param: &'static str| match r.params.get(param) {
                Some(v) if !v.is_string() => Err(WorkflowError::BadParam {
                    role: r.name.clone(),
                    param,
                    reason: "must be a string (\"auto\" or a MAVLink URL such as \"udpout:127.0.0.1:14540\")",
                }),
                _ => Ok(()),
            };
            match r.kind.as_str() {
                "controller" => {
                    string_param("autopilot")?;
                    if r.params.get("standby").is_some_and(|v| !v.is_boolean()) {
                        return Err(WorkflowError::BadParam {
                            role: r.name.clone(),
                            param: "standby",
                            reason: "must be true or false",
                        });
                    }
                }
                "vehicle" => string_param("listen")?,
                _ => {}
            }
            for (list, topics_of) in [("subscribes", &r.subscribes), ("publishes", &r.publishes)] {
                if let Some(t) = topics_of.iter().find(|t| !topics::is_known_topic(t)) {
                    return Err(WorkflowError::UnknownTopic {
                        role: r.name.clone(),
                        topic: t.clone(),
                        list,
                        known: known_topics(),
                    });
                }
            }
        }
        if let Some(t) = self.feedback.iter().find(|t| !topics::is_known_topic(t)) {
            return Err(WorkflowError::UnknownFeedbackTopic {
                topic: t.clone(),
                known: known_topics(),
            });
        }
        Ok(())
    }

    /// `true` when the built-in simulated vehicle is needed: some controller's autopilot is
    /// `auto` (or unset).
    pub fn needs_builtin_vehicle(&self) -> bool {
        self.roles
            .iter()
            .filter(|r| r.kind == "controller")
            .any(|r| r.param_str("autopilot").is_none_or(|a| a == "auto"))
    }

    fn validate_required(&self) -> Result<(), WorkflowError> {
        let has = |kind: &str| self.roles.iter().any(|r| r.kind == kind);
        for kind in REQUIRED_KINDS {
            if !has(kind) {
                return Err(WorkflowError::MissingRole { kind, hint: "" });
            }
        }
        if self.needs_builtin_vehicle() && !has("vehicle") {
            return Err(WorkflowError::MissingRole {
                kind: "vehicle",
                hint: " (the controller's autopilot is \"auto\", which flies the built-in vehicle; \
                       add a vehicle role or set the controller's params.autopilot to a MAVLink URL)",
            });
        }
        Ok(())
    }

    fn validate_topics(&self) -> Result<(), WorkflowError> {
        let published = |topic: &str| {
            topic == topics::HEARTBEAT
                || self
                    .roles
                    .iter()
                    .any(|r| r.publishes.iter().any(|t| t == topic))
        };
        for r in &self.roles {
            if let Some(t) = r.subscribes.iter().find(|t| !published(t)) {
                return Err(WorkflowError::Unpublished {
                    role: r.name.clone(),
                    topic: t.clone(),
                });
            }
        }
        Ok(())
    }

    /// Service dependency edges `(from, to, topic)`: role `to` subscribes to `topic` that role
    /// `from` publishes. Feedback topics and `heartbeat` make no edges, nor does a topic
    /// that `to` publishes itself: peers exchanging one topic (the controllers'
    /// `controller/lease`) have no order between them.
    pub fn service_edges(&self) -> Vec<(usize, usize, String)> {
        let mut edges = Vec::new();
        for (from, a) in self.roles.iter().enumerate() {
            for topic in &a.publishes {
                if topic == topics::HEARTBEAT || self.feedback.contains(topic) {
                    continue;
                }
                for (to, b) in self.roles.iter().enumerate() {
                    if b.subscribes.contains(topic)
                        && !b.publishes.contains(topic)
                        && !edges.iter().any(|(f, t, _)| *f == from && *t == to)
                    {
                        edges.push((from, to, topic.clone()));
                    }
                }
            }
        }
        edges
    }

    /// A cycle of the services graph as (roles with the first repeated, edge topics).
    fn find_cycle(&self) -> Option<(Vec<String>, Vec<String>)> {
        let n = self.roles.len();
        let edges = self.service_edges();
        let mut adj: Vec<Vec<(usize, &str)>> = vec![Vec::new(); n];
        for (f, t, topic) in &edges {
            adj[*f].push((*t, topic.as_str()));
        }
        // 0 = unvisited, 1 = on the stack, 2 = done. Iterative DFS.
        let mut color = vec![0u8; n];
        for root in 0..n {
            if color[root] != 0 {
                continue;
            }
            // stack of (node, next edge index); `via[k]` is the topic into stack[k]
            let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
            let mut via: Vec<&str> = vec![""];
            color[root] = 1;
            while let Some(&mut (node, ref mut next)) = stack.last_mut() {
                if let Some(&(to, topic)) = adj[node].get(*next) {
                    *next += 1;
                    match color[to] {
                        0 => {
                            color[to] = 1;
                            stack.push((to, 0));
                            via.push(topic);
                        }
                        1 => {
                            let start = stack.iter().position(|(v, _)| *v == to).unwrap_or(0);
                            let mut path: Vec<String> = stack[start..]
                                .iter()
                                .map(|(v, _)| self.roles[*v].name.clone())
                                .collect();
                            path.push(self.roles[to].name.clone());
                            let mut topics: Vec<String> =
                                via[start + 1..].iter().map(|t| t.to_string()).collect();
                            topics.push(topic.to_string());
                            return Some((path, topics));
                        }
                        _ => {}
                    }
                } else {
                    color[node] = 2;
                    stack.pop();
                    via.pop();
                }
            }
        }
        None
    }

    /// Role indices in start order: publishers before their subscribers (feedback edges
    /// ignored), ties in declaration order. On a cyclic graph (which [`Workflow::validate`]
    /// rejects) the roles left on cycles follow in declaration order.
    pub fn start_order(&self) -> Vec<usize> {
        let n = self.roles.len();
        let edges = self.service_edges();
        let mut indegree = vec![0usize; n];
        for (_, t, _) in &edges {
            indegree[*t] += 1;
        }
        let mut done = vec![false; n];
        let mut order = Vec::with_capacity(n);
        while order.len() < n {
            let next = (0..n)
                .find(|&i| !done[i] && indegree[i] == 0)
                .or_else(|| (0..n).find(|&i| !done[i]));
            let Some(i) = next else { break };
            done[i] = true;
            order.push(i);
            for (f, t, _) in &edges {
                if *f == i && !done[*t] {
                    indegree[*t] = indegree[*t].saturating_sub(1);
                }
            }
        }
        order
    }

    /// The role named `name`.
    pub fn role(&self, name: &str) -> Option<&RoleDecl> {
        self.roles.iter().find(|r| r.name == name)
    }

    /// The executor named `name`.
    pub fn executor(&self, name: &str) -> Option<&Executor> {
        self.executors.iter().find(|e| e.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_builtin_default_is_valid_and_complete() {
        let w = Workflow::builtin_default().unwrap();
        let names: Vec<&str> = w.roles.iter().map(|r| r.name.as_str()).collect();
        for n in [
            "vehicle",
            "controller",
            "camera",
            "perception",
            "hub",
            "reasoning",
        ] {
            assert!(names.contains(&n), "{n} missing from {names:?}");
        }
        assert_eq!(w.mission.subgoals.len(), 4);
        assert_eq!(w.mission.world, "village");
        assert_eq!(w.timing, TimingSpec::default());
        assert_eq!(w.feedback, vec![topics::VEHICLE_TELEMETRY.to_string()]);
        assert_eq!(
            w.role("reasoning").unwrap().variants,
            vec!["planner".to_string(), "garbage".to_string()]
        );
        assert!(w.executors.iter().all(|e| e.cpus == ExecutorCpus::Auto));
        assert!(w.needs_builtin_vehicle());
    }

    #[test]
    fn start_order_puts_publishers_first() {
        let w = Workflow::builtin_default().unwrap();
        let order: Vec<&str> = w
            .start_order()
            .into_iter()
            .map(|i| w.roles[i].name.as_str())
            .collect();
        let pos = |n: &str| order.iter().position(|o| *o == n).unwrap();
        assert_eq!(order.len(), w.roles.len());
        assert!(pos("camera") < pos("perception"));
        assert!(pos("perception") < pos("reasoning"));
        assert!(pos("reasoning") < pos("hub"));
        assert!(pos("hub") < pos("controller"));
    }

    #[test]
    fn without_feedback_the_control_loop_is_a_cycle() {
        let text =
            DEFAULT_WORKFLOW_TOML.replace("feedback = [\"vehicle/telemetry\"]", "feedback = []");
        assert_ne!(text, DEFAULT_WORKFLOW_TOML, "default.toml lists feedback");
        match Workflow::from_toml_str(&text) {
            Err(WorkflowError::Cycle { path, topics }) => {
                assert_eq!(path.first(), path.last());
                assert_eq!(topics.len() + 1, path.len());
                assert!(topics.contains(&topics::VEHICLE_TELEMETRY.to_string()));
                assert!(path.contains(&"controller".to_string()));
            }
            other => panic!("expected a cycle, got {other:?}"),
        }
    }

    #[test]
    fn line_and_column_count_characters() {
        assert_eq!(line_column("ab\ncd", 4), (2, 2));
        assert_eq!(line_column("é=\nx", 2), (1, 2));
        assert_eq!(line_column("abc", 100), (1, 4));
    }

    #[test]
    fn an_altitude_band_that_misses_the_geofence_is_refused() {
        let mut w = Workflow::builtin_default().unwrap();
        // h_max below the fence's floor: no altitude is allowed by both (the controller's
        // tracker once panicked on such limits)
        w.mission.limits.h_max = 5.0;
        w.mission.limits.geofence_min[2] = 10.0;
        let err = w.validate().unwrap_err();
        assert!(
            matches!(err, WorkflowError::Mission(MissionError::BadLimits)),
            "{err}"
        );
        assert!(err.to_string().contains("meets the geofence"), "{err}");
    }

    #[test]
    fn the_model_flight_declares_its_reasoner_ladder_and_bad_ladders_are_refused() {
        let w = Workflow::builtin_models().unwrap();
        let r = w.role("reasoning").unwrap();
        assert_eq!(r.ladder, ["gemma3", "smollm2", "planner"]);
        assert!(w.scheduling.adapt_variants);
        let ladder_error = |ladder: &[&str], variant: &str| {
            let mut w = Workflow::builtin_models().unwrap();
            let r = w.roles.iter_mut().find(|r| r.kind == "reasoning").unwrap();
            r.ladder = ladder.iter().map(|v| v.to_string()).collect();
            r.variant = variant.into();
            match w.validate() {
                Err(e @ WorkflowError::BadLadder { .. }) => e.to_string(),
                other => panic!("{ladder:?} from {variant}: expected BadLadder, got {other:?}"),
            }
        };
        assert!(ladder_error(&["smollm2"], "smollm2").contains("at least two"));
        assert!(ladder_error(&["smollm2", "random"], "smollm2").contains("`random` is not in"));
        assert!(ladder_error(&["smollm2", "planner", "smollm2"], "smollm2").contains("twice"));
        assert!(ladder_error(&["gemma3", "planner"], "smollm2").contains("declared variant"));
        // `adapt_variants` parses, and an empty ladder is none
        let text = MODELS_WORKFLOW_TOML.replace(
            "ladder = [\"gemma3\", \"smollm2\", \"planner\"]",
            "ladder = []",
        ) + "\n[scheduling]\nadapt_variants = false\n";
        let w = Workflow::from_toml_str(&text).unwrap();
        assert!(!w.scheduling.adapt_variants);
        assert!(w.role("reasoning").unwrap().ladder.is_empty());
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

    #[test]
    fn timing_limits_are_enforced() {
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.decision_deadline_ms = w.timing.heartbeat_period_ms * 10 + 1;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "decision_deadline_ms",
                ..
            })
        ));
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.control_rate_hz = f64::NAN;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "control_rate_hz",
                ..
            })
        ));
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.heartbeat_period_ms = 0;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "heartbeat_period_ms",
                ..
            })
        ));
    }

    #[test]
    fn an_external_autopilot_makes_the_vehicle_optional() {
        let mut w = Workflow::builtin_default().unwrap();
        w.roles.retain(|r| r.kind != "vehicle");
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::MissingRole {
                kind: "vehicle",
                ..
            })
        ));
        for r in w.roles.iter_mut().filter(|r| r.kind == "controller") {
            r.params
                .insert("autopilot".into(), "udpout:127.0.0.1:14540".into());
        }
        w.validate().unwrap();
    }
}
