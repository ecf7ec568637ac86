//! `aeris agent`: the daemon on every host that may run roles for a flight whose supervisor
//! runs on another host. It is a zenoh router listening on the endpoint the workflow names
//! for the host, and it
//! - says what its host is (`info`: schema, CPUs and how busy they are, its clock for the
//!   offset between hosts); the flight's bridge asks every 250 ms, which measures the link;
//! - starts a role process on request (`spawn`), the way the supervisor starts one locally
//!   (own process group, killed with the agent, bound to the executor's CPUs, log file),
//!   after checking that the asker speaks its schema;
//! - stops one on request (`stop`: SIGTERM, SIGKILL after [`STOP_GRACE`]);
//! - reports every exit (code or signal, log tail) to the role's handle;
//! - stops a role whose handle is gone (the flight's host died or the link was cut: the
//!   handle's liveliness token vanished), so no role outlives its flight here either; its exit
//!   report says the agent stopped it, and a handle that still hears that (its session only
//!   lapsed) counts its link lost, not its role ended.

mod handle_watch;

use crate::access::agent_access_control;
use crate::admission::{AgentPolicy, AllowList, LocalLink, OwnParam, Refusal, admit, read_request};
use crate::private_dir::{
    FileMode, PrivateDirError, ensure_private_dir, open_private_file, private_subdir,
};
use crate::protocol::{
    AgentReply, ExitReport, HostInfo, SchemaStamp, Spawned, StopRequest, agent_request_key,
    agent_token_key, exit_key, handle_token_key,
};
use crate::session::{LinkSecurity, SessionError, open_router};
use aeris_orchestrator::executors::{CpuTicks, busy_cores, read_proc_stat};
use aeris_orchestrator::role_process::{LoadPolicy, spawn_role};
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::host_monotonic_ns;
use handle_watch::HandleWatch;
use std::collections::{BTreeMap, HashSet};
use std::io::{Read, Seek, SeekFrom, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::query::{Query, Queryable};
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait};

/// How long a role asked to stop has before SIGKILL.
pub const STOP_GRACE: Duration = Duration::from_secs(5);

/// Bytes of a role's log sent back with its exit.
const LOG_TAIL_BYTES: u64 = 2048;

/// What an agent is started with.
#[derive(Debug, Clone)]
pub struct AgentConfig {
    /// The host's name (what the workflow's `[hosts.NAME]` calls it).
    pub host: String,
    /// Endpoints to listen on (`tls/0.0.0.0:7447`).
    pub listen: Vec<String>,
    /// Where role specs and logs go (`DIR/FLIGHT/roles`, `DIR/FLIGHT/logs`): a private
    /// directory ([`crate::private_dir`]).
    pub run_dir: PathBuf,
    /// The `aeris` executable that runs roles.
    pub exe: PathBuf,
    /// A client silent this long is gone (its roles are stopped).
    pub lease: Duration,
    /// The links' security: this host's identity, or plain TCP where asked for.
    pub security: LinkSecurity,
    /// The certificate names of the hosts whose supervisors may start and stop roles here.
    pub flight_hosts: Vec<String>,
    /// The role kinds and variants it starts.
    pub allow: AllowList,
    /// The parameters it sets itself (model files, pipelines: never the network's).
    pub own_params: Vec<OwnParam>,
}

/// Why the agent could not start.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    /// The host name is unusable in a key expression.
    #[error("host name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    HostName(String),
    /// The zenoh session could not be opened.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The keys given are another host's.
    #[error(
        "the keys in {dir} are host `{theirs}`'s, not host `{host}`'s: give the agent its own (`aeris keys issue STORE {host}`)"
    )]
    WrongIdentity {
        /// The identity directory.
        dir: PathBuf,
        /// The name in its certificate.
        theirs: String,
        /// This host.
        host: String,
    },
    /// No host may command the agent.
    #[error(
        "no host may start roles here: name the flight's host (`--flight-host NAME`, the name in its certificate)"
    )]
    NoFlightHost,
    /// A flight host's name is unusable.
    #[error("flight host name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    FlightHostName(String),
    /// A zenoh declaration failed.
    #[error("cannot declare {what} on zenoh: {reason}")]
    Declare {
        /// What (`the info queryable`).
        what: String,
        /// zenoh's reason.
        reason: String,
    },
    /// The run directory is not a private directory of ours.
    #[error("cannot use the agent's run directory {path}")]
    RunDir {
        /// The directory.
        path: PathBuf,
        /// Why.
        #[source]
        source: PrivateDirError,
    },
}

/// What the agent did, for its log.
#[derive(Debug, Clone, PartialEq)]
pub enum AgentEvent {
    /// It started a role process.
    Spawned {
        /// `FLIGHT/ROLE#INSTANCE`.
        role: String,
        /// Its pid.
        pid: u32,
        /// Its CPUs ("" = unbound).
        cpus: String,
    },
    /// It refused a request.
    Refused {
        /// The request (`spawn FLIGHT/ROLE#N`).
        request: String,
        /// Why.
        reason: String,
    },
    /// A role process ended.
    Exited {
        /// `FLIGHT/ROLE#INSTANCE`.
        role: String,
        /// How (`exit code 0`, `signal 9`).
        how: String,
    },
    /// A role's handle went away (its host died or the link was cut): the role is stopped.
    HandleGone {
        /// `FLIGHT/ROLE#INSTANCE`.
        role: String,
        /// Why, as the role's exit report says it.
        why: String,
    },
}

impl core::fmt::Display for AgentEvent {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            AgentEvent::Spawned { role, pid, cpus } => {
                let on = if cpus.is_empty() { "unbound" } else { cpus };
                write!(f, "started {role} as pid {pid} (CPUs {on})")
            }
            AgentEvent::Refused { request, reason } => write!(f, "refused {request}: {reason}"),
            AgentEvent::Exited { role, how } => write!(f, "{role} ended: {how}"),
            AgentEvent::HandleGone { role, why } => {
                write!(f, "{role}: {why} (host or link lost): stopping it")
            }
        }
    }
}

/// One role process the agent runs.
struct RoleProcess {
    flight: String,
    role: String,
    instance: u32,
    child: Child,
    log: PathBuf,
    /// SIGTERM sent at (SIGKILL after [`STOP_GRACE`]).
    stopping: Option<Instant>,
    /// The key of its handle's liveliness token (made once: the agent looks it up every
    /// step).
    handle_key: String,
    /// Its handle's token was seen alive.
    handle_seen: bool,
    /// Why the agent stopped it on its own, for its exit report.
    stopped_by_agent: Option<String>,
    started: Instant,
}

impl RoleProcess {
    fn label(&self) -> String {
        format!("{}/{}#{}", self.flight, self.role, self.instance)
    }
    fn terminate(&mut self) {
        if self.stopping.is_none() {
            // SAFETY: kill on the pid of a child not yet reaped (it cannot be reused).
            unsafe { libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM) };
            self.stopping = Some(Instant::now());
        }
    }
}

/// The least time between two load samples of the host's CPUs (`info` asked more often
/// answers the last figure).
pub const LOAD_INTERVAL: Duration = Duration::from_millis(200);

/// The load of the host's CPUs, sampled when `info` is asked.
struct HostLoad {
    /// The last `/proc/stat` sample and when it was taken.
    ticks: BTreeMap<usize, CpuTicks>,
    at: Instant,
    /// Busy cores between the last two samples.
    busy: f64,
}

impl HostLoad {
    fn new() -> Self {
        HostLoad {
            ticks: read_proc_stat(),
            at: Instant::now(),
            busy: 0.0,
        }
    }

    /// Busy cores of `cpus`, sampled again when the last sample is older than
    /// [`LOAD_INTERVAL`].
    fn busy(&mut self, cpus: &CpuSet) -> f64 {
        if self.at.elapsed() >= LOAD_INTERVAL {
            let now = read_proc_stat();
            self.busy = busy_cores(&self.ticks, &now, cpus.cpus());
            self.ticks = now;
            self.at = Instant::now();
        }
        self.busy
    }
}

/// What `info` answers, shared with the queryable's callback: `info` is answered at once
/// on zenoh's thread, not at the agent's next step, so the link's probes measure the link
/// and not the agent's step period.
struct HostState {
    host: String,
    online: CpuSet,
    load: Mutex<HostLoad>,
    /// Role processes running now.
    roles: AtomicUsize,
}

impl HostState {
    fn info(&self) -> HostInfo {
        let busy_cores = match self.load.lock() {
            Ok(mut load) => load.busy(&self.online),
            Err(poisoned) => poisoned.into_inner().busy(&self.online),
        };
        HostInfo {
            host: self.host.clone(),
            schema: SchemaStamp::current(),
            cpus: self.online.to_string(),
            agent_pid: std::process::id(),
            roles: self.roles.load(Ordering::Relaxed),
            monotonic_ns: host_monotonic_ns(),
            busy_cores,
            cpu_count: self.online.cpus().len() as u32,
        }
    }
}

/// The agent of one host.
pub struct Agent {
    config: AgentConfig,
    session: Session,
    _token: LivelinessToken,
    _info: Queryable<()>,
    state: Arc<HostState>,
    spawn: Queryable<FifoChannelHandler<Query>>,
    stop: Queryable<FifoChannelHandler<Query>>,
    handles: zenoh::pubsub::Subscriber<FifoChannelHandler<Sample>>,
    alive_handles: HashSet<String>,
    roles: Vec<RoleProcess>,
    /// What it starts, with which parameters.
    policy: AgentPolicy,
    /// The run directory, absolute.
    run_dir: PathBuf,
    /// The priority of the roles it runs over this host's other work.
    priority: aeris_orchestrator::priority::FlightPriority,
}

fn declare_error(what: &str) -> impl Fn(zenoh::Error) -> AgentError + '_ {
    move |e| AgentError::Declare {
        what: what.to_string(),
        reason: e.to_string(),
    }
}

impl Agent {
    /// Listen, declare the agent's requests and its liveliness token.
    pub fn start(config: AgentConfig) -> Result<Agent, AgentError> {
        if !aeris_schemas::topics::is_valid_flight_name(&config.host) {
            return Err(AgentError::HostName(config.host.clone()));
        }
        if let Some(bad) = config
            .flight_hosts
            .iter()
            .find(|h| !aeris_schemas::topics::is_valid_flight_name(h))
        {
            return Err(AgentError::FlightHostName(bad.clone()));
        }
        let access = match &config.security {
            LinkSecurity::Tls(identity) => {
                if identity.name != config.host {
                    return Err(AgentError::WrongIdentity {
                        dir: identity.dir.clone(),
                        theirs: identity.name.clone(),
                        host: config.host.clone(),
                    });
                }
                if config.flight_hosts.is_empty() {
                    return Err(AgentError::NoFlightHost);
                }
                Some(agent_access_control(&config.host, &config.flight_hosts))
            }
            LinkSecurity::Insecure => None,
        };
        for e in &config.listen {
            crate::session::check_endpoint(e, &config.security)?;
        }
        let run_dir = ensure_private_dir(&config.run_dir).map_err(|source| AgentError::RunDir {
            path: config.run_dir.clone(),
            source,
        })?;
        let session = open_router(
            &config.listen,
            config.lease,
            &config.security,
            access.as_ref(),
        )?;
        let host = config.host.clone();
        let queryable = |op: &str| {
            session
                .declare_queryable(agent_request_key(&host, op))
                .wait()
                .map_err(declare_error(&format!("the `{op}` request")))
        };
        let online = CpuSet::available();
        let state = Arc::new(HostState {
            host: host.clone(),
            online: online.clone(),
            load: Mutex::new(HostLoad::new()),
            roles: AtomicUsize::new(0),
        });
        let answering = state.clone();
        let info = session
            .declare_queryable(agent_request_key(&host, "info"))
            .callback(move |q| reply(&q, &AgentReply::Ok(answering.info())))
            .wait()
            .map_err(declare_error("the `info` request"))?;
        let spawn = queryable("spawn")?;
        let stop = queryable("stop")?;
        let handles = session
            .liveliness()
            .declare_subscriber(format!("aeris/host/{host}/handle/**"))
            .history(true)
            .wait()
            .map_err(declare_error("the handles' liveliness subscriber"))?;
        let token = session
            .liveliness()
            .declare_token(agent_token_key(&host))
            .wait()
            .map_err(declare_error("the agent's liveliness token"))?;
        let config_host = config.host.clone();
        let policy = AgentPolicy {
            host: config.host.clone(),
            allow: config.allow.clone(),
            own_params: config.own_params.clone(),
            link: LocalLink {
                connect: local_endpoint(config.listen.first().map(String::as_str).unwrap_or("")),
                keys: match &config.security {
                    LinkSecurity::Tls(identity) => Some(identity.dir.clone()),
                    LinkSecurity::Insecure => None,
                },
            },
            online: online.clone(),
        };
        Ok(Agent {
            config,
            session,
            _token: token,
            _info: info,
            state,
            spawn,
            stop,
            handles,
            alive_handles: HashSet::new(),
            roles: Vec::new(),
            policy,
            run_dir,
            priority: aeris_orchestrator::priority::FlightPriority::establish(
                &format!("agent-{}", config_host),
                aeris_orchestrator::priority::PriorityMode::Auto,
            ),
        })
    }

    /// How the roles this agent runs got priority over the host's other work.
    pub fn priority(&self) -> &aeris_orchestrator::priority::Priority {
        self.priority.priority()
    }

    /// The host's name.
    pub fn host(&self) -> &str {
        &self.config.host
    }

    /// Where role specs and logs go (absolute).
    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    /// Where its own bridge connects: its router, as this host reaches it.
    pub fn local_endpoint(&self) -> &str {
        &self.policy.link.connect
    }

    /// The role kinds and variants it starts.
    pub fn allow_list(&self) -> &AllowList {
        &self.policy.allow
    }

    /// Role processes running now.
    pub fn running(&self) -> usize {
        self.roles.len()
    }

    /// Answer requests, follow the handles, reap exits, escalate stops; call every few ms.
    pub fn step(&mut self) -> Vec<AgentEvent> {
        let mut events = Vec::new();
        while let Ok(Some(q)) = self.spawn.try_recv() {
            let answer = self.spawn_role(&q, &mut events);
            reply(&q, &answer);
        }
        while let Ok(Some(q)) = self.stop.try_recv() {
            let answer =
                match parse::<StopRequest>(&q) {
                    Ok(r) => match self.roles.iter_mut().find(|p| {
                        p.flight == r.flight && p.role == r.role && p.instance == r.instance
                    }) {
                        Some(p) => {
                            p.terminate();
                            AgentReply::Ok(p.child.id())
                        }
                        None => AgentReply::Refused(format!(
                            "no role {}/{}#{} runs here",
                            r.flight, r.role, r.instance
                        )),
                    },
                    Err(e) => AgentReply::Refused(e),
                };
            reply(&q, &answer);
        }
        self.follow_handles(&mut events);
        self.reap(&mut events);
        self.state.roles.store(self.roles.len(), Ordering::Relaxed);
        events
    }

    fn spawn_role(&mut self, q: &Query, events: &mut Vec<AgentEvent>) -> AgentReply<Spawned> {
        let bytes = q
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        let mut label = "spawn".to_string();
        let admitted = read_request(&bytes).and_then(|req| {
            // the names as asked, escaped: a name is not trusted before it is checked
            label = format!(
                "spawn {}/{}#{}",
                req.spec.flight.escape_debug(),
                req.spec.name.escape_debug(),
                req.spec.instance
            );
            admit(req, &self.policy)
        });
        let refuse = |events: &mut Vec<AgentEvent>, request: String, reason: String| {
            events.push(AgentEvent::Refused {
                request,
                reason: reason.clone(),
            });
            AgentReply::Refused(reason)
        };
        let admission = match admitted {
            Ok(a) => a,
            Err(e) => {
                let reason = match &e {
                    Refusal::Schema(m) => m.to_string(),
                    other => aeris_runtime::error_chain::chain(other).to_string(),
                };
                return refuse(events, label, reason);
            }
        };
        let spec = &admission.spec;
        let (spec_path, log_path) = match write_role_files(&self.run_dir, &admission) {
            Ok(paths) => paths,
            Err(e) => {
                return refuse(
                    events,
                    label,
                    aeris_runtime::error_chain::chain(&e).to_string(),
                );
            }
        };
        let log = match open_private_file(
            log_path.parent().unwrap_or(&self.run_dir),
            &admission.log_file,
            FileMode::Append,
            0o600,
        ) {
            Ok(l) => l,
            Err(e) => {
                return refuse(
                    events,
                    label,
                    aeris_runtime::error_chain::chain(&e).to_string(),
                );
            }
        };
        let role = format!("{}/{}#{}", spec.flight, spec.name, spec.instance);
        match spawn_role(
            &self.config.exe,
            &spec_path,
            spec.instance,
            log,
            admission.cpus.as_ref(),
            LoadPolicy::Normal,
            self.priority.for_child(),
        ) {
            Ok(child) => {
                let pid = child.id();
                events.push(AgentEvent::Spawned {
                    role,
                    pid,
                    cpus: spec.cpus.clone(),
                });
                self.roles.push(RoleProcess {
                    flight: spec.flight.clone(),
                    role: spec.name.clone(),
                    instance: spec.instance,
                    child,
                    log: log_path.clone(),
                    stopping: None,
                    handle_key: handle_token_key(
                        &self.config.host,
                        &spec.flight,
                        &spec.name,
                        spec.instance,
                    ),
                    handle_seen: false,
                    stopped_by_agent: None,
                    started: Instant::now(),
                });
                AgentReply::Ok(Spawned {
                    pid,
                    log: log_path.display().to_string(),
                })
            }
            Err(e) => refuse(
                events,
                label,
                format!("cannot start {}: {e}", self.config.exe.display()),
            ),
        }
    }

    /// Stop the roles whose handle's token went away (or never came within two leases).
    fn follow_handles(&mut self, events: &mut Vec<AgentEvent>) {
        while let Ok(Some(s)) = self.handles.try_recv() {
            let key = s.key_expr().as_str().to_string();
            match s.kind() {
                SampleKind::Put => {
                    self.alive_handles.insert(key);
                }
                SampleKind::Delete => {
                    self.alive_handles.remove(&key);
                }
            }
        }
        let lease = self.config.lease;
        let now = Instant::now();
        for p in self.roles.iter_mut().filter(|p| p.stopping.is_none()) {
            let alive = self.alive_handles.contains(&p.handle_key);
            p.handle_seen |= alive;
            let watch = HandleWatch {
                seen: p.handle_seen,
                alive,
                running_for: now.saturating_duration_since(p.started),
            };
            if let Some(why) = watch.verdict(lease) {
                events.push(AgentEvent::HandleGone {
                    role: p.label(),
                    why: why.clone(),
                });
                p.stopped_by_agent = Some(why);
                p.terminate();
            }
        }
    }

    /// Reap exited roles (reporting each to its handle) and SIGKILL the ones past their grace.
    fn reap(&mut self, events: &mut Vec<AgentEvent>) {
        let mut i = 0;
        while i < self.roles.len() {
            let p = &mut self.roles[i];
            match p.child.try_wait() {
                Ok(Some(status)) => {
                    let report = ExitReport {
                        pid: p.child.id(),
                        code: status.code(),
                        signal: status.signal(),
                        log_tail: log_tail(&p.log),
                        stopped_by_agent: p.stopped_by_agent.clone(),
                    };
                    let how = match (report.code, report.signal) {
                        (Some(c), _) => format!("exit code {c}"),
                        (None, Some(s)) => format!("signal {s}"),
                        _ => "unknown".into(),
                    };
                    events.push(AgentEvent::Exited {
                        role: p.label(),
                        how,
                    });
                    let key = exit_key(&self.config.host, &p.flight, &p.role, p.instance);
                    if let Ok(json) = serde_json::to_vec(&report) {
                        let _ = self.session.put(key, json).wait();
                    }
                    let flight = p.flight.clone();
                    self.roles.remove(i);
                    if !self.roles.iter().any(|r| r.flight == flight) {
                        // the flight's last role here: remove what dead processes left
                        aeris_runtime::bus::cleanup_dead_nodes();
                    }
                }
                Ok(None) => {
                    if p.stopping.is_some_and(|t| t.elapsed() > STOP_GRACE) {
                        let _ = p.child.kill();
                    }
                    i += 1;
                }
                Err(_) => i += 1,
            }
        }
    }

    /// Stop every role (SIGTERM, SIGKILL after the grace) and wait for them.
    pub fn shutdown(mut self) -> Vec<AgentEvent> {
        let mut events = Vec::new();
        for p in &mut self.roles {
            p.terminate();
        }
        let until = Instant::now() + STOP_GRACE + Duration::from_secs(1);
        while !self.roles.is_empty() && Instant::now() < until {
            self.reap(&mut events);
            std::thread::sleep(Duration::from_millis(20));
        }
        events
    }
}

fn parse<T: serde::de::DeserializeOwned>(q: &Query) -> Result<T, String> {
    let bytes = q
        .payload()
        .map(|p| p.to_bytes().into_owned())
        .unwrap_or_default();
    serde_json::from_slice(&bytes).map_err(|e| format!("unreadable request: {e}"))
}

fn reply<T: serde::Serialize>(q: &Query, answer: &AgentReply<T>) {
    if let Ok(json) = serde_json::to_vec(answer) {
        let _ = q.reply(q.key_expr().clone(), json).wait();
    }
}

/// Write an admitted role's spec under the private run directory `run_dir` (absolute):
/// `FLIGHT/roles/NAME-INSTANCE.json` beside `FLIGHT/logs`, private directories, no link
/// followed, and the written file checked to resolve under `run_dir`. Its spec and log
/// paths.
pub fn write_role_files(
    run_dir: &Path,
    a: &crate::admission::Admission,
) -> Result<(PathBuf, PathBuf), WriteError> {
    let flight = private_subdir(run_dir, &a.flight_dir)?;
    let roles = private_subdir(&flight, "roles")?;
    private_subdir(&flight, "logs")?;
    let json = serde_json::to_vec_pretty(&a.spec).map_err(WriteError::Encode)?;
    let spec_path = a.spec_path(run_dir);
    let mut f = open_private_file(&roles, &a.spec_file, FileMode::Replace, 0o600)?;
    f.write_all(&json).map_err(|source| WriteError::Write {
        path: spec_path.clone(),
        source,
    })?;
    let resolved = std::fs::canonicalize(&spec_path).map_err(|source| WriteError::Write {
        path: spec_path.clone(),
        source,
    })?;
    let root = std::fs::canonicalize(run_dir).map_err(|source| WriteError::Write {
        path: run_dir.to_path_buf(),
        source,
    })?;
    if !resolved.starts_with(&root) {
        let _ = std::fs::remove_file(&spec_path);
        return Err(WriteError::Outside {
            path: resolved,
            run_dir: root,
        });
    }
    Ok((spec_path, a.log_path(run_dir)))
}

/// Why an admitted role's files could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// A directory or file was refused or could not be made.
    #[error(transparent)]
    Private(#[from] PrivateDirError),
    /// The spec could not be encoded.
    #[error("cannot encode the role's spec")]
    Encode(#[source] serde_json::Error),
    /// The spec could not be written.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The spec resolved outside the run directory.
    #[error("{path} lies outside the run directory {run_dir}")]
    Outside {
        /// Where it resolved.
        path: PathBuf,
        /// The run directory.
        run_dir: PathBuf,
    },
}

/// The endpoint of a router listening on `listen`, as its own host reaches it: the
/// loopback address when it listens on every address.
pub fn local_endpoint(listen: &str) -> String {
    let Some((scheme, rest)) = listen.split_once('/') else {
        return listen.to_string();
    };
    let Some((addr, port)) = rest.rsplit_once(':') else {
        return listen.to_string();
    };
    let addr = match addr {
        "0.0.0.0" => "127.0.0.1",
        "[::]" => "[::1]",
        other => other,
    };
    format!("{scheme}/{addr}:{port}")
}

/// The last [`LOG_TAIL_BYTES`] of `path` (lossy UTF-8).
fn log_tail(path: &Path) -> String {
    let Ok(mut f) = std::fs::File::open(path) else {
        return String::new();
    };
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    let _ = f.seek(SeekFrom::Start(len.saturating_sub(LOG_TAIL_BYTES)));
    let mut buf = Vec::new();
    let _ = f.read_to_end(&mut buf);
    String::from_utf8_lossy(&buf).into_owned()
}
