//! Why a workflow is unusable ([`WorkflowError`]), and why a workflow file could not be
//! loaded ([`WorkflowFileError`]).

use aeris_runtime::affinity::CpuSetError;
use aeris_runtime::spec::MissionError;
use aeris_schemas::RoleKind;
use aeris_schemas::heartbeat::NAME_MAX;

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
    /// An executor's `accelerator` is not one.
    #[error("[executors.{executor}] accelerator is unusable")]
    BadAccelerator {
        /// Executor name.
        executor: String,
        /// Why.
        source: aeris_runtime::accelerator::AcceleratorParseError,
    },
    /// A role that runs no model this accelerator can run is bound to it.
    #[error(
        "role `{role}` ({kind_variant}) is bound to executor `{executor}`, an accelerator ({accelerator}): only model roles can use one ({}); bind it to a CPU executor",
        super::validate::accelerated_variants_text()
    )]
    NotAccelerated {
        /// The role.
        role: String,
        /// Its kind and variant (`camera / sim-render`).
        kind_variant: String,
        /// The executor.
        executor: String,
        /// Its accelerator.
        accelerator: aeris_runtime::accelerator::Accelerator,
    },
    /// An executor names a host that is not declared.
    #[error("[executors.{executor}] host `{host}` is not declared (declared: {known})")]
    UnknownHost {
        /// Executor name.
        executor: String,
        /// The host as written.
        host: String,
        /// Declared hosts, comma-separated (or "none").
        known: String,
    },
    /// A host's endpoint is not a zenoh endpoint of ours.
    #[error(
        "[hosts.{host}] endpoint `{endpoint}` is not a zenoh endpoint of ours (write tls/ADDRESS:PORT)"
    )]
    BadEndpoint {
        /// Host name.
        host: String,
        /// The endpoint as written.
        endpoint: String,
    },
    /// A role on another host has a parameter that names a file, model, pipeline or
    /// endpoint: that host's agent sets those itself.
    #[error(
        "role `{role}` runs on host `{host}`: its param `{param}` is that host's own configuration, never sent over the network (`aeris agent --param KIND.{param}=...` there)"
    )]
    RemoteParam {
        /// Role name.
        role: String,
        /// The parameter.
        param: String,
        /// The host.
        host: String,
    },
    /// A host's link security does not fit its endpoint: a `tls/` endpoint without keys, a
    /// `tcp/` endpoint not declared insecure, keys on an insecure link.
    #[error("[hosts.{host}] endpoint `{endpoint}`: {reason}")]
    LinkSecurity {
        /// Host name.
        host: String,
        /// The endpoint as written.
        endpoint: String,
        /// What does not fit, and how to fix it.
        reason: &'static str,
    },
    /// A host's frame coding is unknown or its JPEG quality out of range.
    #[error(
        "[hosts.{host}] frames = `{frames}`, jpeg_quality = {quality}: use `jpeg` (quality 1-100) or `raw`"
    )]
    BadFrames {
        /// Host name.
        host: String,
        /// The coding as written.
        frames: String,
        /// The quality as written (or the default).
        quality: u8,
    },
    /// A host name is unusable.
    #[error("host name `{host}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    BadHostName {
        /// The name.
        host: String,
    },
    /// A role that must stay on the flight's host is bound to an executor on another.
    #[error(
        "role `{role}` (kind {kind}) must run on the flight's host, but its executor is on host `{host}`"
    )]
    RemoteNotAllowed {
        /// Role name.
        role: String,
        /// Its kind.
        kind: RoleKind,
        /// Its executor's host.
        host: String,
    },
    /// A role's `fallback` is unusable.
    #[error("role `{role}`: fallback {reason}")]
    BadFallback {
        /// Role name.
        role: String,
        /// What is wrong.
        reason: String,
    },
    /// A topic would go from one other host to another: bridges run between the flight's
    /// host and each other host only.
    #[error(
        "topic `{topic}` would go from host `{from}` to host `{to}`: roles on two other hosts cannot talk directly; put one of them on the flight's host"
    )]
    HostToHost {
        /// The topic.
        topic: String,
        /// The publisher's host.
        from: String,
        /// The subscriber's host.
        to: String,
    },
    /// More other hosts than the status board can list.
    #[error("the workflow names {count} other hosts; at most {max} are supported")]
    TooManyHosts {
        /// Hosts declared.
        count: usize,
        /// The limit.
        max: usize,
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
    /// A role's kind is not a role kind (`RoleKind`).
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
        kind: RoleKind,
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
    /// `[flight] vehicles` or `vehicle_spacing_m` is out of range.
    #[error(
        "[flight] vehicles = {vehicles}, vehicle_spacing_m = {spacing_m}: a flight has 1 to {max} vehicles, a positive distance apart",
        max = aeris_schemas::topics::MAX_FLIGHT_VEHICLES
    )]
    BadFleet {
        /// The vehicles asked for.
        vehicles: u8,
        /// The spacing asked for (m).
        spacing_m: f32,
    },
    /// A vehicle or controller of a flight of several vehicles is not declared per vehicle.
    #[error(
        "role `{role}` flies one vehicle of {vehicles}: declare it with per_vehicle = true, so that each vehicle has its own"
    )]
    NotPerVehicle {
        /// The role.
        role: String,
        /// The flight's vehicles.
        vehicles: u8,
    },
    /// A `per_vehicle_params` entry is not one value per vehicle of a `per_vehicle` role.
    #[error(
        "role `{role}`: per_vehicle_params.{key} must be a list of {vehicles} values (one per vehicle) of a role with per_vehicle = true"
    )]
    PerVehicleParam {
        /// The role.
        role: String,
        /// The parameter.
        key: String,
        /// The flight's vehicles.
        vehicles: u8,
    },
    /// A required role kind is missing.
    #[error("the workflow has no role of kind `{kind}`{hint}")]
    MissingRole {
        /// The missing kind.
        kind: RoleKind,
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
