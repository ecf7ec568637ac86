//! Workflow files: which roles a flight runs, on which executors, with which message paths.
//!
//! A workflow is a TOML file (format in `workflows/README.md`). [`Workflow::from_toml_str`]
//! parses and validates it in one go; every problem comes back as a [`WorkflowError`] that
//! names the offending role, field, executor or topic and says how to fix it. Parsing never
//! panics, whatever the input.
//!
//! One file per step: the built-in workflows (`builtin.rs`), parsing (`parse.rs`),
//! validation (`validate.rs`), the services graph (`graph.rs`) and the errors (`error.rs`);
//! the types are here.

mod builtin;
mod error;
mod graph;
mod hosts;
mod parse;
mod validate;

pub use builtin::{DEFAULT_WORKFLOW_TOML, FORMATION_WORKFLOW_TOML, MODELS_WORKFLOW_TOML};
pub use error::{WorkflowError, WorkflowFileError};
pub use hosts::{BridgePlan, REMOTE_PARAMS, SUPERVISOR_READS, movable_across_hosts, remote_cpus};
pub use validate::{
    LANGUAGE_MODEL_VARIANTS, ONNX_MODEL_VARIANTS, REQUIRED_KINDS, is_valid_role_name,
    runs_on_accelerator,
};

use crate::restart::RestartPolicy;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::spec::{CameraSpec, MissionSpec, TimingSpec};
use aeris_schemas::RoleKind;

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

/// A named executor: a CPU set roles are bound to, on the flight's host or another, and
/// optionally an accelerator its model roles run their sessions on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Executor {
    /// Executor name (the key under `[executors]`).
    pub name: String,
    /// Its CPUs (on its host: another host's are not checked here).
    pub cpus: ExecutorCpus,
    /// The host it is on (a `[hosts.NAME]`); `None`: the flight's own host.
    pub host: Option<String>,
    /// The accelerator its roles' model sessions run on (`accelerator = "cuda:0"`); the
    /// roles' processes still run on its `cpus`.
    pub accelerator: Option<aeris_runtime::accelerator::Accelerator>,
}

/// Another host roles may run on (`[hosts.NAME]`): an `aeris agent` listens there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Host {
    /// Host name (the key under `[hosts]`).
    pub name: String,
    /// Its agent's zenoh endpoint (`tls/10.0.0.2:7447`).
    pub endpoint: String,
    /// The flight host's identity directory for the mutual-TLS link to it (`keys`: an
    /// `aeris keys issue` directory of the flight's host); required for a `tls/` endpoint.
    pub keys: Option<String>,
    /// The link is plain TCP, unauthenticated and unencrypted (`insecure = true`):
    /// required for a `tcp/` endpoint, refused with keys.
    pub insecure: bool,
    /// The link counts as lost after this long without the host's agent (ms).
    pub link_timeout_ms: u64,
    /// How RGB frames cross to and from it: `jpeg` (the default) or `raw`.
    pub frames: String,
    /// JPEG quality of those frames (1-100).
    pub jpeg_quality: u8,
}

/// Default JPEG quality of frames between hosts.
pub const DEFAULT_JPEG_QUALITY: u8 = 85;

/// Default time without a host's agent before its link counts as lost (ms).
pub const DEFAULT_LINK_TIMEOUT_MS: u64 = 1000;

/// Role kinds that never run on another host: the hub and the controller keep the vehicle
/// flying whatever the link does, and the simulated vehicle and the replay source stand
/// for the vehicle itself.
pub const FLIGHT_HOST_KINDS: &[RoleKind] = &[
    RoleKind::Hub,
    RoleKind::Controller,
    RoleKind::Vehicle,
    RoleKind::Replay,
    RoleKind::Recorder,
];

/// Check that `endpoint` is a zenoh endpoint of ours: `tls/HOST:PORT` (mutual TLS), or
/// `tcp/HOST:PORT` (plain, only on a link declared insecure).
pub fn check_endpoint(endpoint: &str) -> bool {
    let Some(rest) = endpoint
        .strip_prefix("tls/")
        .or_else(|| endpoint.strip_prefix("tcp/"))
    else {
        return false;
    };
    let Some((host, port)) = rest.rsplit_once(':') else {
        return false;
    };
    !host.is_empty() && port.parse::<u16>().is_ok_and(|p| p > 0)
}

/// One role of the workflow, validated against its kind (`RoleKind::info`).
#[derive(Debug, Clone, PartialEq)]
pub struct RoleDecl {
    /// Unique instance name.
    pub name: String,
    /// Its kind.
    pub kind: RoleKind,
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
    /// Topics it subscribes to (its kind's unless overridden).
    pub subscribes: Vec<String>,
    /// Topics it publishes (its kind's unless overridden; `heartbeat` is implicit).
    pub publishes: Vec<String>,
    /// For a role on another host: the variant that takes over on the flight's host when the
    /// link to that host is lost (`fallback`, `fallback_executor`).
    pub fallback: Option<RoleFallback>,
    /// The vehicle whose scope it runs in (1-based), in a flight of several vehicles: a
    /// role declared `per_vehicle = true`, once per vehicle. `None`: a role of the whole
    /// flight (or of the only vehicle).
    pub vehicle: Option<u8>,
}

/// What replaces a role on another host when the link to that host is lost.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RoleFallback {
    /// The variant started on the flight's host (e.g. the planner for a ground-station
    /// language model).
    pub variant: String,
    /// The flight's executor it runs on (`None`: unbound).
    pub executor: Option<String>,
}

impl RoleDecl {
    /// `true` when this role and `other` can exchange a topic: the same vehicle's scope, or
    /// either of them a role of the whole flight (no vehicle).
    pub fn shares_scope_with(&self, other: &RoleDecl) -> bool {
        match (self.vehicle, other.vehicle) {
            (Some(a), Some(b)) => a == b,
            _ => true,
        }
    }

    /// A role of `kind` running `variant` (its only variant), with the workflow defaults:
    /// no ladder, restarted on failure within the default budget and back-off, the kind's
    /// default latency budget, and the kind's topics.
    pub fn new(
        name: &str,
        kind: RoleKind,
        variant: &str,
        executor: Option<String>,
        params: serde_json::Map<String, serde_json::Value>,
    ) -> Self {
        let topics = |list: &[&str]| list.iter().map(|t| t.to_string()).collect();
        Self {
            name: name.to_string(),
            kind,
            variant: variant.to_string(),
            variants: vec![variant.to_string()],
            ladder: Vec::new(),
            executor,
            restart: RestartPolicy::OnFailure,
            max_restarts: DEFAULT_MAX_RESTARTS,
            backoff_ms: DEFAULT_BACKOFF_MS,
            budget_ms: None,
            params,
            subscribes: topics(kind.info().subscribes),
            publishes: topics(kind.info().publishes),
            fallback: None,
            vehicle: None,
        }
    }

    /// A string parameter.
    pub fn param_str(&self, key: &str) -> Option<&str> {
        self.params.get(key).and_then(|v| v.as_str())
    }

    /// A hot-standby controller (`kind = "controller"`, `params.standby = true`).
    pub fn is_standby_controller(&self) -> bool {
        self.kind == RoleKind::Controller
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
    /// Other hosts roles may run on, sorted by name (`[hosts.NAME]`).
    pub hosts: Vec<Host>,
    /// Roles in declaration order.
    pub roles: Vec<RoleDecl>,
    /// Dynamic scheduling and stall detection (`[scheduling]`).
    pub scheduling: SchedulingSpec,
    /// How many vehicles fly, and where they start (`[flight] vehicles`).
    pub fleet: Fleet,
}

/// The vehicles of a flight (`[flight] vehicles = N`, `vehicle_spacing_m`). With more than
/// one, every role declared `per_vehicle = true` runs once per vehicle, in that vehicle's
/// scope (`{name}-v{K}`, services `FLIGHT/v{K}/{topic}`), and vehicle K starts on the
/// ground in a row along east centred on the mission's start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fleet {
    /// Vehicles, 1..=[`aeris_schemas::topics::MAX_FLIGHT_VEHICLES`].
    pub vehicles: u8,
    /// Distance between neighbours at the start (m).
    pub spacing_m: f32,
}

impl Default for Fleet {
    /// One vehicle; 4 m apart when there are more.
    fn default() -> Self {
        Self {
            vehicles: 1,
            spacing_m: DEFAULT_VEHICLE_SPACING_M,
        }
    }
}

/// Distance between neighbouring vehicles at the start when the workflow gives none (m).
pub const DEFAULT_VEHICLE_SPACING_M: f32 = 4.0;

impl Fleet {
    /// Where vehicle `k` (1-based) starts, given the mission's start: a row along east
    /// centred on it, `spacing_m` apart. One vehicle starts at the mission's start.
    pub fn start(&self, k: u8, mission_start: [f32; 3]) -> [f32; 3] {
        let middle = (f32::from(self.vehicles) - 1.0) / 2.0;
        let offset = (f32::from(k) - 1.0 - middle) * self.spacing_m;
        [
            mission_start[0],
            mission_start[1] + offset,
            mission_start[2],
        ]
    }

    /// Every vehicle's start, vehicle 1 first.
    pub fn starts(&self, mission_start: [f32; 3]) -> Vec<[f32; 3]> {
        (1..=self.vehicles)
            .map(|k| self.start(k, mission_start))
            .collect()
    }
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
    /// How the roles get priority over outside work on a shared machine: `auto` (a CPU
    /// control group where permitted, else a nice value), `nice`, or `off`.
    pub priority: crate::priority::PriorityMode,
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
            priority: crate::priority::PriorityMode::Auto,
        }
    }
}

impl Workflow {
    /// The latency budget of `role` (ms): its `budget_ms`, else its kind's share of the
    /// heartbeat — half for reasoning, a quarter for each perception kind, one period for the
    /// periodic camera, hub and controller; `None` for the simulated vehicle (part of the
    /// world, not of the stack), which is never re-bound for its own latency.
    pub fn role_budget_ms(&self, role: &RoleDecl) -> Option<f64> {
        if role.budget_ms.is_some() {
            return role.budget_ms;
        }
        let hb = self.timing.heartbeat_period_ms as f64;
        match role.kind {
            RoleKind::Reasoning => Some(hb * 0.5),
            RoleKind::Camera => Some(1000.0 / self.camera.fps.max(1.0)),
            RoleKind::Hub | RoleKind::Controller => Some(1000.0 / self.timing.control_rate_hz),
            // off the critical path: no budget, so the scheduler never moves roles for it
            RoleKind::Vehicle | RoleKind::Recorder | RoleKind::Bridge => None,
            RoleKind::Perception
            | RoleKind::TextReader
            | RoleKind::Detector
            | RoleKind::Cues
            | RoleKind::Occupancy
            | RoleKind::ImageToText
            | RoleKind::Replay
            | RoleKind::Formation => Some(hb * 0.25),
        }
    }

    /// Fit every recorder role (kind `recorder`) to what the flight publishes: its
    /// `subscribes` become every topic another role publishes, `heartbeat`, and
    /// `hosts/link` when the flight names other hosts (its bridges measure them), in the
    /// order of [`topics::ALL`](aeris_schemas::topics::ALL).
    pub fn fit_recorders(&mut self) {
        let published: Vec<String> = aeris_schemas::topics::ALL
            .iter()
            .filter(|t| {
                **t == aeris_schemas::topics::HEARTBEAT
                    || (**t == aeris_schemas::topics::HOSTS_LINK && !self.hosts.is_empty())
                    || self.roles.iter().any(|r| {
                        r.kind != RoleKind::Recorder && r.publishes.iter().any(|p| p == *t)
                    })
            })
            .map(|t| t.to_string())
            .collect();
        for r in self
            .roles
            .iter_mut()
            .filter(|r| r.kind == RoleKind::Recorder)
        {
            r.subscribes = published.clone();
        }
    }

    /// `true` when the built-in simulated vehicle is needed: some controller's autopilot is
    /// `auto` (or unset).
    pub fn needs_builtin_vehicle(&self) -> bool {
        self.roles
            .iter()
            .filter(|r| r.kind == RoleKind::Controller)
            .any(|r| r.param_str("autopilot").is_none_or(|a| a == "auto"))
    }

    /// The role named `name`.
    pub fn role(&self, name: &str) -> Option<&RoleDecl> {
        self.roles.iter().find(|r| r.name == name)
    }

    /// The executor named `name`.
    pub fn executor(&self, name: &str) -> Option<&Executor> {
        self.executors.iter().find(|e| e.name == name)
    }

    /// The other host role `role` runs on (`None`: the flight's host).
    pub fn role_host(&self, role: &RoleDecl) -> Option<&Host> {
        let ex = self.executor(role.executor.as_deref()?)?;
        let host = ex.host.as_deref()?;
        self.hosts.iter().find(|h| h.name == host)
    }
}
