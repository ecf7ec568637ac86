//! The handle of a remote role: the process the supervisor starts for a role whose executor
//! is on another host (`aeris role --spec` with `remote` set). It has that host's agent run
//! the role and then stands for it on the flight's host, so the supervisor starts, watches,
//! restarts, swaps and stops it like any role process:
//! - the role's heartbeats name the handle's pid (they cross on the bridge);
//! - the handle ends when the role ends, with its exit code (or 128 + its signal), so the
//!   restart policy applies unchanged;
//! - SIGTERM to the handle stops the role there; the supervisor's death (the handle's
//!   `PR_SET_PDEATHSIG`) or a cut link removes the handle's liveliness token, and the agent
//!   stops the role;
//! - a host whose agent is gone for longer than the link timeout ends the handle with an
//!   error naming the host: the role counts as lost.

use crate::protocol::{
    AgentReply, ExitReport, HostInfo, SchemaMismatch, SchemaStamp, SpawnRequest, Spawned,
    StopRequest, agent_request_key, agent_token_key, check_schema, exit_key, handle_token_key,
};
use crate::session::{LinkSecurity, Reach, SessionError, open_client};
use aeris_orchestrator::restart::EXIT_HOST_UNREACHABLE;
use aeris_runtime::RoleSpec;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::signals;
use std::time::{Duration, Instant};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

/// How often the handle looks at the link, the role's exit and its signals.
const POLL: Duration = Duration::from_millis(20);

/// How long a stopped role has to report its exit before the handle gives up on it.
const STOP_WAIT: Duration = Duration::from_secs(7);
/// The least time the handle gives itself to reach the host's agent before it fails naming
/// the host (the link's timeout when that is longer).
const CONNECT_BUDGET: Duration = Duration::from_secs(5);

/// Why a remote role could not be run or was lost.
#[derive(Debug, thiserror::Error)]
pub enum HandleError {
    /// The spec has no `remote`.
    #[error("role `{0}` has no remote host in its spec")]
    NotRemote(String),
    /// The flight host's identity for the link is unusable.
    #[error("cannot authenticate to host `{host}`")]
    Keys {
        /// The host.
        host: String,
        /// Why.
        #[source]
        source: crate::keys::IdentityError,
    },
    /// The session to the host could not be opened (its agent does not answer).
    #[error("cannot reach the agent of host `{host}` at {endpoint}")]
    Unreachable {
        /// The host.
        host: String,
        /// Its endpoint.
        endpoint: String,
        /// Why.
        #[source]
        source: SessionError,
    },
    /// A request got no answer in time.
    #[error("the agent of host `{host}` did not answer `{op}` within {waited_ms} ms")]
    NoAnswer {
        /// The host.
        host: String,
        /// The request.
        op: String,
        /// How long the handle waited.
        waited_ms: u64,
    },
    /// The agent refused.
    #[error("the agent of host `{host}` refused `{op}`: {reason}")]
    Refused {
        /// The host.
        host: String,
        /// The request.
        op: String,
        /// Its reason.
        reason: String,
    },
    /// The host's build speaks another schema.
    #[error("host `{host}` cannot run role `{role}`")]
    Schema {
        /// The host.
        host: String,
        /// The role.
        role: String,
        /// The mismatch.
        #[source]
        source: SchemaMismatch,
    },
    /// The link to the host was lost while the role ran.
    #[error(
        "lost host `{host}`: its agent was silent for {silent_ms} ms (link timeout {timeout_ms} ms)"
    )]
    LinkLost {
        /// The host.
        host: String,
        /// How long it was silent.
        silent_ms: u64,
        /// The link timeout.
        timeout_ms: u64,
    },
    /// The agent stopped the role because it had not heard this handle for a lease (the
    /// link faded while both ends ran): the link's loss, not the role's end.
    #[error("host `{host}` stopped role `{role}`: {reason}")]
    StoppedThere {
        /// The host.
        host: String,
        /// The role.
        role: String,
        /// The agent's reason.
        reason: String,
    },
    /// A zenoh declaration failed.
    #[error("cannot declare {what} on zenoh: {reason}")]
    Declare {
        /// What.
        what: String,
        /// zenoh's reason.
        reason: String,
    },
}

/// How the remote role ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RemoteExit {
    /// Its exit code there (`None`: a signal).
    pub code: Option<i32>,
    /// The signal that ended it.
    pub signal: Option<i32>,
}

impl RemoteExit {
    /// The handle's own exit code: the role's, or 128 + its signal. A role's own code
    /// [`EXIT_HOST_UNREACHABLE`] reads as 1: that code is the handle's, for a host it
    /// could not reach, and the supervisor answers it with the role's fallback.
    pub fn exit_code(&self) -> u8 {
        match (self.code, self.signal) {
            (Some(EXIT_HOST_UNREACHABLE), _) => 1,
            (Some(c), _) => c.clamp(0, 255) as u8,
            (None, Some(s)) => (128 + s).clamp(0, 255) as u8,
            _ => 1,
        }
    }
}

/// Answers asked of the agent to measure the offset between the two hosts' clocks.
const CLOCK_PROBES: usize = 5;

/// The other host's clock minus ours (ns): its reading `theirs_ns`, taken between our
/// readings `t0_ns` and `t1_ns`, against our clock at their midpoint.
pub fn clock_offset_ns(t0_ns: u64, t1_ns: u64, theirs_ns: u64) -> i64 {
    let mid = (t0_ns as i128 + t1_ns as i128) / 2;
    (theirs_ns as i128 - mid).clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// Ask `host`'s agent for `op` with `payload`; the typed answer.
fn ask<T: serde::de::DeserializeOwned>(
    session: &Session,
    host: &str,
    op: &str,
    payload: Vec<u8>,
    timeout: Duration,
) -> Result<T, HandleError> {
    let no_answer = || HandleError::NoAnswer {
        host: host.to_string(),
        op: op.to_string(),
        waited_ms: timeout.as_millis() as u64,
    };
    let replies = session
        .get(agent_request_key(host, op))
        .payload(payload)
        .timeout(timeout)
        .wait()
        .map_err(|_| no_answer())?;
    while let Ok(reply) = replies.recv() {
        let Ok(sample) = reply.result() else {
            continue;
        };
        let bytes = sample.payload().to_bytes();
        return match serde_json::from_slice::<AgentReply<T>>(&bytes) {
            Ok(AgentReply::Ok(v)) => Ok(v),
            Ok(AgentReply::Refused(reason)) => Err(HandleError::Refused {
                host: host.to_string(),
                op: op.to_string(),
                reason,
            }),
            Err(e) => Err(HandleError::Refused {
                host: host.to_string(),
                op: op.to_string(),
                reason: format!("unreadable answer: {e}"),
            }),
        };
    }
    Err(no_answer())
}

/// Run role `spec` on its remote host until it ends, this process is asked to stop, or the
/// link is lost. Prints what it does (the role log on the flight's host).
pub fn run_remote(spec: RoleSpec) -> Result<RemoteExit, HandleError> {
    let remote = spec
        .remote
        .clone()
        .ok_or_else(|| HandleError::NotRemote(spec.name.clone()))?;
    let host = remote.host.clone();
    let timeout = Duration::from_millis(remote.link_timeout_ms.max(100));
    let _ = signals::install_termination_handlers();
    // reaching the agent (TCP and zenoh's handshake) is given more than the link's timeout:
    // on a loaded machine a debug build took over a second
    let reach = Reach::Within(timeout.max(CONNECT_BUDGET));
    let security = LinkSecurity::from_keys(remote.keys.as_deref().map(std::path::Path::new))
        .map_err(|source| HandleError::Keys {
            host: host.clone(),
            source,
        })?;
    let session = open_client(&remote.endpoint, reach, timeout, &security).map_err(|source| {
        HandleError::Unreachable {
            host: host.clone(),
            endpoint: remote.endpoint.clone(),
            source,
        }
    })?;
    let declare = |what: &str| {
        let what = what.to_string();
        move |e: zenoh::Error| HandleError::Declare {
            what: what.clone(),
            reason: e.to_string(),
        }
    };
    // the offset between the two hosts' clocks from the fastest of a few answers (the
    // least time between the agent's read of its clock and ours)
    let mut best: Option<(u64, i64, HostInfo)> = None;
    for _ in 0..CLOCK_PROBES {
        let t0 = monotonic_ns();
        let info: HostInfo = ask(&session, &host, "info", Vec::new(), timeout)?;
        let t1 = monotonic_ns();
        check_schema(&format!("host `{host}`"), info.schema).map_err(|source| {
            HandleError::Schema {
                host: host.clone(),
                role: spec.name.clone(),
                source,
            }
        })?;
        let rtt = t1.saturating_sub(t0);
        if best.as_ref().is_none_or(|b| rtt < b.0) {
            best = Some((rtt, clock_offset_ns(t0, t1, info.monotonic_ns), info));
        }
    }
    let Some((rtt, offset, info)) = best else {
        return Err(HandleError::NoAnswer {
            host,
            op: "info".into(),
            waited_ms: timeout.as_millis() as u64,
        });
    };
    println!(
        "host `{host}` answers in {:.1} ms (agent pid {}, CPUs {}, its clock {:+.6} s from ours: the role stamps in ours)",
        rtt as f64 / 1e6,
        info.agent_pid,
        info.cpus,
        offset as f64 / 1e9
    );
    let exits = session
        .declare_subscriber(exit_key(&host, &spec.flight, &spec.name, spec.instance))
        .wait()
        .map_err(declare("the exit subscriber"))?;
    let agent_alive = session
        .liveliness()
        .declare_subscriber(agent_token_key(&host))
        .history(true)
        .wait()
        .map_err(declare("the agent's liveliness subscriber"))?;
    let _token = session
        .liveliness()
        .declare_token(handle_token_key(
            &host,
            &spec.flight,
            &spec.name,
            spec.instance,
        ))
        .wait()
        .map_err(declare("the handle's liveliness token"))?;
    let mut remote_spec = spec.clone();
    remote_spec.cpus = remote.cpus.clone();
    remote_spec.remote = None;
    // there, the role reads the flight's clock: its host's, less the offset
    remote_spec.flight_clock_offset_ns = offset.saturating_neg();
    let request = SpawnRequest {
        schema: SchemaStamp::current(),
        spec: remote_spec,
        handle_pid: std::process::id(),
    };
    let payload = serde_json::to_vec(&request).unwrap_or_default();
    let spawned: Spawned = ask(&session, &host, "spawn", payload, timeout)?;
    println!(
        "role `{}` runs on host `{host}` as pid {} (log there: {})",
        spec.name, spawned.pid, spawned.log
    );

    let mut agent_gone_at: Option<Instant> = None;
    let mut stop_sent: Option<Instant> = None;
    loop {
        if let Ok(Some(sample)) = exits.try_recv() {
            let bytes = sample.payload().to_bytes();
            if let Ok(report) = serde_json::from_slice::<ExitReport>(&bytes) {
                print!("{}", report.log_tail);
                println!(
                    "role `{}` on host `{host}` ended ({})",
                    spec.name,
                    match (report.code, report.signal) {
                        (Some(c), _) => format!("exit code {c}"),
                        (_, Some(s)) => format!("signal {s}"),
                        _ => "unknown".into(),
                    }
                );
                if let Some(reason) = report.stopped_by_agent {
                    return Err(HandleError::StoppedThere {
                        host,
                        role: spec.name.clone(),
                        reason,
                    });
                }
                return Ok(RemoteExit {
                    code: report.code,
                    signal: report.signal,
                });
            }
        }
        while let Ok(Some(s)) = agent_alive.try_recv() {
            agent_gone_at = match s.kind() {
                SampleKind::Put => None,
                SampleKind::Delete => Some(agent_gone_at.unwrap_or_else(Instant::now)),
            };
        }
        if let Some(at) = agent_gone_at
            && at.elapsed() >= timeout
        {
            return Err(HandleError::LinkLost {
                host,
                silent_ms: at.elapsed().as_millis() as u64,
                timeout_ms: timeout.as_millis() as u64,
            });
        }
        if signals::termination_requested() {
            match stop_sent {
                None => {
                    let stop = StopRequest {
                        flight: spec.flight.clone(),
                        role: spec.name.clone(),
                        instance: spec.instance,
                    };
                    let payload = serde_json::to_vec(&stop).unwrap_or_default();
                    // a role already gone there is refused: its exit report is on its way
                    let _ = ask::<u32>(&session, &host, "stop", payload, timeout);
                    stop_sent = Some(Instant::now());
                }
                Some(t) if t.elapsed() > STOP_WAIT || agent_gone_at.is_some() => {
                    // the token goes with this process: the agent stops the role anyway
                    return Ok(RemoteExit {
                        code: None,
                        signal: Some(signals::last_signal()),
                    });
                }
                Some(_) => {}
            }
        }
        std::thread::sleep(POLL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_handle_exits_as_its_role_did_but_never_as_an_unreachable_host() {
        let exit = |code, signal| RemoteExit { code, signal }.exit_code();
        assert_eq!(exit(Some(0), None), 0);
        assert_eq!(exit(Some(3), None), 3);
        assert_eq!(exit(None, Some(9)), 137);
        assert_eq!(exit(Some(EXIT_HOST_UNREACHABLE), None), 1);
        assert_eq!(exit(None, None), 1);
    }

    #[test]
    fn the_clock_offset_is_theirs_against_our_midpoint() {
        assert_eq!(clock_offset_ns(100, 300, 1_200), 1_000);
        assert_eq!(clock_offset_ns(1_000, 1_000, 0), -1_000);
    }
}
