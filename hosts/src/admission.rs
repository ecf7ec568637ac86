//! What an agent agrees to start (`spawn`), decided before anything touches the disk: pure
//! functions of the request and the agent's own policy.
//!
//! - the flight and role names are plain names (`[a-z0-9_-]`, `[A-Za-z0-9_-]`: no `/`, no
//!   `..`), so the files the agent writes for them stay in its run directory;
//! - the role's kind and variant are on the agent's allow-list ([`AllowList`]; the default
//!   is the model and reasoning roles that make sense on another host);
//! - parameters from the network are values only ([`NETWORK_PARAMS`]): a parameter that
//!   names a file, a directory, a model, a pipeline or a device comes from the agent's own
//!   configuration ([`OwnParam`]), and a request carrying one is refused by name;
//! - a bridge's link (where it connects, with which keys) is the agent's, never the
//!   request's;
//! - the mission, CPUs and accelerator are checked as the role would check them.

use crate::protocol::{SchemaMismatch, SpawnRequest, check_schema};
use aeris_runtime::RoleSpec;
use aeris_runtime::affinity::CpuSet;
use aeris_schemas::RoleKind;
use std::path::{Path, PathBuf};

/// The largest spawn request an agent reads (bytes): a role spec is a few KB.
pub const MAX_REQUEST_BYTES: usize = 256 * 1024;

/// Parameters a spawn request may carry: values that name no file, directory, model,
/// pipeline, device or endpoint (the workflow refuses others on a remote role already).
pub use aeris_orchestrator::workflow::REMOTE_PARAMS as NETWORK_PARAMS;

/// The kinds an agent runs unless told otherwise: the model and reasoning roles.
pub const DEFAULT_ALLOW: &[&str] = &[
    "reasoning/*",
    "perception/*",
    "detector/*",
    "text-reader/*",
    "cues/*",
    "occupancy/*",
    "image-to-text/*",
];

/// The bridge's parameter naming where it connects: the agent's own endpoint.
pub const BRIDGE_CONNECT_PARAM: &str = "connect";
/// The bridge's parameter naming its identity directory: the agent's own keys.
pub const BRIDGE_KEYS_PARAM: &str = "keys";

/// Why an allow-list or an agent parameter is unusable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PolicyError {
    /// An entry names no role kind (`RoleKind`).
    #[error("`{entry}` names no role kind (write KIND/VARIANT or KIND/*; kinds: {known})")]
    UnknownKind {
        /// The entry.
        entry: String,
        /// The kinds there are.
        known: String,
    },
    /// An entry names a variant its kind does not have.
    #[error("`{entry}`: kind {kind} has no variant `{variant}` (it has {known})")]
    UnknownVariant {
        /// The entry.
        entry: String,
        /// The kind.
        kind: RoleKind,
        /// The variant.
        variant: String,
        /// The kind's variants.
        known: String,
    },
    /// An entry names a kind that runs on the flight's host only.
    #[error("`{entry}`: kind {kind} runs on the flight's host only")]
    FlightHostKind {
        /// The entry.
        entry: String,
        /// The kind.
        kind: RoleKind,
    },
    /// An agent parameter is not `KIND[/VARIANT].KEY=VALUE`.
    #[error("`{0}` is not KIND[/VARIANT].KEY=VALUE")]
    Param(String),
}

/// One allowed kind, with one variant or all.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Allowed {
    kind: RoleKind,
    variant: Option<String>,
}

/// The role kinds and variants an agent starts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AllowList {
    entries: Vec<Allowed>,
}

impl AllowList {
    /// Read `KIND/VARIANT`, `KIND/*` or `KIND` entries (comma-separated, or one per item).
    pub fn parse<S: AsRef<str>>(items: &[S]) -> Result<AllowList, PolicyError> {
        let mut entries = Vec::new();
        for item in items {
            for entry in item
                .as_ref()
                .split(',')
                .map(str::trim)
                .filter(|e| !e.is_empty())
            {
                let (kind, variant) = match entry.split_once('/') {
                    Some((k, "*")) => (k, None),
                    Some((k, v)) => (k, Some(v)),
                    None => (entry, None),
                };
                let Some(kind) = RoleKind::from_name(kind) else {
                    return Err(PolicyError::UnknownKind {
                        entry: entry.to_string(),
                        known: RoleKind::known_names(),
                    });
                };
                if aeris_orchestrator::workflow::FLIGHT_HOST_KINDS.contains(&kind) {
                    return Err(PolicyError::FlightHostKind {
                        entry: entry.to_string(),
                        kind,
                    });
                }
                if let Some(v) = variant
                    && !kind.info().variants.contains(&v)
                {
                    return Err(PolicyError::UnknownVariant {
                        entry: entry.to_string(),
                        kind,
                        variant: v.to_string(),
                        known: kind.info().variants.join(", "),
                    });
                }
                entries.push(Allowed {
                    kind,
                    variant: variant.map(str::to_string),
                });
            }
        }
        Ok(AllowList { entries })
    }

    /// [`DEFAULT_ALLOW`].
    pub fn default_remote() -> AllowList {
        AllowList::parse(DEFAULT_ALLOW).unwrap_or(AllowList {
            entries: Vec::new(),
        })
    }

    /// `true` when `kind`/`variant` may run here. The bridge always may: it is the
    /// agent's own link, configured by the agent.
    pub fn allows(&self, kind: RoleKind, variant: &str) -> bool {
        (kind == RoleKind::Bridge && variant == "zenoh")
            || self
                .entries
                .iter()
                .any(|a| a.kind == kind && a.variant.as_deref().is_none_or(|v| v == variant))
    }
}

impl core::fmt::Display for AllowList {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let items: Vec<String> = self
            .entries
            .iter()
            .map(|a| format!("{}/{}", a.kind, a.variant.as_deref().unwrap_or("*")))
            .collect();
        write!(f, "{}", items.join(", "))
    }
}

/// A parameter the agent sets itself for the roles of a kind (and variant): the model
/// files, the models' directory, a pipeline — what must never come from the network.
#[derive(Debug, Clone, PartialEq)]
pub struct OwnParam {
    /// The kind it is for.
    pub kind: String,
    /// The variant it is for (`None`: every variant of the kind).
    pub variant: Option<String>,
    /// The parameter.
    pub key: String,
    /// Its value (JSON: a number or `true` as written, else the text).
    pub value: serde_json::Value,
}

impl OwnParam {
    /// Read `KIND[/VARIANT].KEY=VALUE`.
    pub fn parse(text: &str) -> Result<OwnParam, PolicyError> {
        let bad = || PolicyError::Param(text.to_string());
        let (target, value) = text.split_once('=').ok_or_else(bad)?;
        let (who, key) = target.rsplit_once('.').ok_or_else(bad)?;
        let (kind, variant) = match who.split_once('/') {
            Some((k, v)) => (k, Some(v.to_string())),
            None => (who, None),
        };
        if kind.is_empty() || key.is_empty() || variant.as_deref() == Some("") {
            return Err(bad());
        }
        let value = serde_json::from_str(value)
            .ok()
            .filter(|v: &serde_json::Value| !v.is_string())
            .unwrap_or_else(|| serde_json::Value::String(value.to_string()));
        Ok(OwnParam {
            kind: kind.to_string(),
            variant,
            key: key.to_string(),
            value,
        })
    }

    fn applies_to(&self, kind: RoleKind, variant: &str) -> bool {
        self.kind == kind.name() && self.variant.as_deref().is_none_or(|v| v == variant)
    }
}

/// What the agent's bridge connects to: its own router, with its own keys.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LocalLink {
    /// The endpoint of the agent's router as its own host reaches it.
    pub connect: String,
    /// The host's identity directory (`None` on an insecure link).
    pub keys: Option<PathBuf>,
}

/// An agent's own policy.
#[derive(Debug, Clone, PartialEq)]
pub struct AgentPolicy {
    /// The host's name.
    pub host: String,
    /// What it starts.
    pub allow: AllowList,
    /// The parameters it sets itself.
    pub own_params: Vec<OwnParam>,
    /// Its bridge's link.
    pub link: LocalLink,
    /// The CPUs its roles may run on.
    pub online: CpuSet,
}

/// Why a spawn request is refused (the reply, and the agent's log line).
#[derive(Debug, thiserror::Error)]
pub enum Refusal {
    /// The request is not a spawn request.
    #[error("unreadable request: {0}")]
    Unreadable(String),
    /// The request is larger than [`MAX_REQUEST_BYTES`].
    #[error("a request of {0} bytes is over the {MAX_REQUEST_BYTES} bytes an agent reads")]
    TooLarge(usize),
    /// The asker speaks another schema.
    #[error(transparent)]
    Schema(#[from] SchemaMismatch),
    /// The flight's name is not a plain name.
    #[error("flight name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    FlightName(String),
    /// The role's name is not a plain name.
    #[error("role name `{0}` is invalid: use letters, digits, `_` and `-`")]
    RoleName(String),
    /// The kind/variant is not on the allow-list.
    #[error(
        "role kind {kind}/{variant} is not allowed on this host (it runs: {allowed}; `aeris agent --allow`)"
    )]
    NotAllowed {
        /// The kind.
        kind: RoleKind,
        /// The variant.
        variant: String,
        /// The allow-list.
        allowed: String,
    },
    /// A parameter the network may not set.
    #[error(
        "param `{key}` is not taken from the network (a file, model, pipeline or endpoint is this host's own configuration: `aeris agent --param {kind}.{key}=...`)"
    )]
    Param {
        /// The kind.
        kind: RoleKind,
        /// The parameter.
        key: String,
    },
    /// A bridge's link parameter: the agent links its bridge itself.
    #[error(
        "param `{0}` is not taken from the network: a bridge's link is this agent's own (its endpoint and keys)"
    )]
    BridgeLink(String),
    /// The CPUs are not all online here.
    #[error("CPUs `{cpus}` are not all online on host {host} (online: {online})")]
    Cpus {
        /// As asked.
        cpus: String,
        /// This host.
        host: String,
        /// Online CPUs.
        online: String,
    },
    /// The accelerator is not one.
    #[error("accelerator `{0}` is not one (cuda:N, tensorrt:N, rocm:N)")]
    Accelerator(String),
    /// The mission is not one a role runs.
    #[error("the role's mission is unusable")]
    Mission(#[source] aeris_runtime::spec::MissionError),
}

/// A request the agent will run: the spec as it will be written, and where.
#[derive(Debug, Clone, PartialEq)]
pub struct Admission {
    /// The spec the role process reads (its params the allowed ones and the agent's own,
    /// `remote` none, its heartbeats naming the handle).
    pub spec: RoleSpec,
    /// The CPUs to bind it to.
    pub cpus: Option<CpuSet>,
    /// The flight's directory name under the run directory.
    pub flight_dir: String,
    /// The spec's file name in `FLIGHT/roles`.
    pub spec_file: String,
    /// The log's file name in `FLIGHT/logs`.
    pub log_file: String,
}

impl Admission {
    /// The spec's path under `run_dir`.
    pub fn spec_path(&self, run_dir: &Path) -> PathBuf {
        run_dir
            .join(&self.flight_dir)
            .join("roles")
            .join(&self.spec_file)
    }

    /// The log's path under `run_dir`.
    pub fn log_path(&self, run_dir: &Path) -> PathBuf {
        run_dir
            .join(&self.flight_dir)
            .join("logs")
            .join(&self.log_file)
    }
}

/// `true` for a role name the agent takes: `[A-Za-z0-9_-]`, 1 to
/// [`aeris_schemas::heartbeat::NAME_MAX`] bytes.
pub fn is_valid_role_name(name: &str) -> bool {
    aeris_orchestrator::workflow::is_valid_role_name(name)
}

/// Read a spawn request's bytes.
pub fn read_request(bytes: &[u8]) -> Result<SpawnRequest, Refusal> {
    if bytes.len() > MAX_REQUEST_BYTES {
        return Err(Refusal::TooLarge(bytes.len()));
    }
    serde_json::from_slice(bytes).map_err(|e| Refusal::Unreadable(e.to_string()))
}

/// Decide `req` under `policy`.
pub fn admit(req: SpawnRequest, policy: &AgentPolicy) -> Result<Admission, Refusal> {
    let mut spec = req.spec;
    check_schema(
        &format!("the supervisor of flight `{}`", spec.flight),
        req.schema,
    )?;
    if !aeris_schemas::topics::is_valid_flight_name(&spec.flight) {
        return Err(Refusal::FlightName(spec.flight));
    }
    if !is_valid_role_name(&spec.name) {
        return Err(Refusal::RoleName(spec.name));
    }
    if !policy.allow.allows(spec.kind, &spec.variant) {
        return Err(Refusal::NotAllowed {
            kind: spec.kind,
            variant: spec.variant,
            allowed: policy.allow.to_string(),
        });
    }
    if let Some(key) = spec
        .params
        .keys()
        .find(|k| !NETWORK_PARAMS.contains(&k.as_str()))
    {
        if spec.kind == RoleKind::Bridge
            && (key == BRIDGE_CONNECT_PARAM || key == BRIDGE_KEYS_PARAM)
        {
            return Err(Refusal::BridgeLink(key.clone()));
        }
        return Err(Refusal::Param {
            kind: spec.kind,
            key: key.clone(),
        });
    }
    let cpus = if spec.cpus.is_empty() {
        None
    } else {
        match CpuSet::parse(&spec.cpus) {
            Ok(set) if set.cpus().iter().all(|c| policy.online.cpus().contains(c)) => Some(set),
            _ => {
                return Err(Refusal::Cpus {
                    cpus: spec.cpus,
                    host: policy.host.clone(),
                    online: policy.online.to_string(),
                });
            }
        }
    };
    if let Some(a) = &spec.accelerator
        && a.parse::<aeris_runtime::accelerator::Accelerator>()
            .is_err()
    {
        return Err(Refusal::Accelerator(a.clone()));
    }
    spec.mission.validate().map_err(Refusal::Mission)?;
    for p in &policy.own_params {
        if p.applies_to(spec.kind, &spec.variant) {
            spec.params.insert(p.key.clone(), p.value.clone());
        }
    }
    if spec.kind == RoleKind::Bridge {
        spec.params.insert(
            BRIDGE_CONNECT_PARAM.into(),
            policy.link.connect.clone().into(),
        );
        match &policy.link.keys {
            Some(k) => {
                spec.params
                    .insert(BRIDGE_KEYS_PARAM.into(), k.display().to_string().into());
            }
            None => {
                spec.params.remove(BRIDGE_KEYS_PARAM);
            }
        }
    }
    spec.heartbeat_pid = Some(req.handle_pid);
    spec.remote = None;
    Ok(Admission {
        flight_dir: spec.flight.clone(),
        spec_file: format!("{}-{}.json", spec.name, spec.instance),
        log_file: format!("{}.log", spec.name),
        cpus,
        spec,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::SchemaStamp;

    pub(crate) fn policy() -> AgentPolicy {
        AgentPolicy {
            host: "ground".into(),
            allow: AllowList::default_remote(),
            own_params: vec![OwnParam::parse("reasoning/smollm2.model=/opt/m.gguf").unwrap()],
            link: LocalLink {
                connect: "tls/127.0.0.1:7447".into(),
                keys: Some("/etc/aeris/keys".into()),
            },
            online: CpuSet::parse("0-1").unwrap(),
        }
    }

    fn request(json: serde_json::Value) -> SpawnRequest {
        let mut spec = serde_json::json!({
            "flight": "f1", "name": "reasoning", "kind": "reasoning", "variant": "planner",
            "mission": {"instruction": "take off, then land",
                        "subgoals": [{"text": "take off", "action": "takeoff"},
                                     {"text": "land", "action": "land"}]},
        });
        for (k, v) in json.as_object().unwrap() {
            spec[k] = v.clone();
        }
        SpawnRequest {
            schema: SchemaStamp::current(),
            spec: serde_json::from_value(spec).unwrap(),
            handle_pid: 42,
        }
    }

    #[test]
    fn a_plain_request_is_admitted_with_its_files_under_the_run_dir() {
        let a = admit(request(serde_json::json!({})), &policy()).unwrap();
        assert_eq!(
            a.spec_path(Path::new("/run/a")),
            Path::new("/run/a/f1/roles/reasoning-0.json")
        );
        assert_eq!(a.spec.heartbeat_pid, Some(42));
    }

    #[test]
    fn traversal_names_disallowed_kinds_and_file_params_are_refused_by_name() {
        let e = admit(
            request(serde_json::json!({"name": "../../../../tmp/x"})),
            &policy(),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "role name `../../../../tmp/x` is invalid: use letters, digits, `_` and `-`"
        );
        let e = admit(request(serde_json::json!({"flight": ".."})), &policy()).unwrap_err();
        assert!(matches!(e, Refusal::FlightName(_)), "{e}");
        let e = admit(
            request(serde_json::json!({"kind": "camera", "variant": "gstreamer"})),
            &policy(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("role kind camera/gstreamer is not allowed on this host (it runs: reasoning/*, perception/*"),
            "{e}"
        );
        for key in ["model", "models_dir", "pipeline", "connect", "keys", "path"] {
            let e = admit(
                request(serde_json::json!({"params": {key: "/etc/shadow"}})),
                &policy(),
            )
            .unwrap_err()
            .to_string();
            assert!(e.starts_with(&format!("param `{key}` is not taken")), "{e}");
        }
    }

    #[test]
    fn the_agent_sets_its_own_params_and_its_bridge_link() {
        let a = admit(
            request(serde_json::json!({"variant": "smollm2", "params": {"threads": 2}})),
            &policy(),
        )
        .unwrap();
        assert_eq!(a.spec.params["model"], "/opt/m.gguf");
        assert_eq!(a.spec.params["threads"], 2);
        let a = admit(
            request(
                serde_json::json!({"name": "bridge-on-ground", "kind": "bridge",
                "variant": "zenoh", "params": {"import": [], "export": []}}),
            ),
            &policy(),
        )
        .unwrap();
        assert_eq!(a.spec.params["connect"], "tls/127.0.0.1:7447");
        assert_eq!(a.spec.params["keys"], "/etc/aeris/keys");
    }

    #[test]
    fn allow_lists_name_known_kinds_and_variants_only() {
        let l = AllowList::parse(&["reasoning/planner, detector"]).unwrap();
        assert!(
            l.allows(RoleKind::Reasoning, "planner") && !l.allows(RoleKind::Reasoning, "smollm2")
        );
        assert!(l.allows(RoleKind::Detector, "yolov8") && l.allows(RoleKind::Bridge, "zenoh"));
        assert!(matches!(
            AllowList::parse(&["hub/gate"]),
            Err(PolicyError::FlightHostKind { .. })
        ));
        assert!(matches!(
            AllowList::parse(&["reasoning/gpt9"]),
            Err(PolicyError::UnknownVariant { .. })
        ));
        assert!(matches!(
            AllowList::parse(&["teleport"]),
            Err(PolicyError::UnknownKind { .. })
        ));
        assert_eq!(
            OwnParam::parse("detector.min_score=0.4").unwrap().value,
            serde_json::json!(0.4)
        );
        assert!(OwnParam::parse("detector=0.4").is_err());
    }
}
