//! What crosses between hosts besides the flight's topics: the key expressions, the schema
//! stamp every request and message carries, and the agent's requests and replies (JSON).

use aeris_runtime::RoleSpec;
use aeris_schemas::{SCHEMA_LAYOUT_HASH, SCHEMA_VERSION};
use serde::{Deserialize, Serialize};

/// The key of a flight topic on zenoh: `aeris/data/FLIGHT/TOPIC`. The schema version is not
/// in the key but in each message's attachment, so a peer of another schema is heard and
/// refused by name instead of silently never matching.
pub fn data_key(flight: &str, topic: &str) -> String {
    format!("aeris/data/{flight}/{topic}")
}

/// The agent's liveliness token on `host`.
pub fn agent_token_key(host: &str) -> String {
    format!("aeris/host/{host}/agent")
}

/// The agent's request `op` (`info`, `spawn`, `stop`) on `host`.
pub fn agent_request_key(host: &str, op: &str) -> String {
    format!("aeris/host/{host}/{op}")
}

/// Where the agent on `host` reports the exit of a role process it started.
pub fn exit_key(host: &str, flight: &str, role: &str, instance: u32) -> String {
    format!("aeris/host/{host}/exit/{flight}/{role}/{instance}")
}

/// The liveliness token of the handle that stands for a remote role on the flight's host:
/// while it lives the role may run; when it goes (the handle or its host died, or the link
/// was cut) the agent stops the role.
pub fn handle_token_key(host: &str, flight: &str, role: &str, instance: u32) -> String {
    format!("aeris/host/{host}/handle/{flight}/{role}/{instance}")
}

/// The schema a build speaks: what both ends of a link must share.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SchemaStamp {
    /// [`SCHEMA_VERSION`] of the build.
    pub version: u32,
    /// [`SCHEMA_LAYOUT_HASH`] of the build.
    pub layout_hash: u64,
}

impl SchemaStamp {
    /// This build's stamp.
    pub fn current() -> Self {
        SchemaStamp {
            version: SCHEMA_VERSION,
            layout_hash: SCHEMA_LAYOUT_HASH,
        }
    }

    /// The stamp as 12 bytes (version, then layout hash; little-endian).
    pub fn to_bytes(self) -> [u8; 12] {
        let mut b = [0u8; 12];
        b[..4].copy_from_slice(&self.version.to_le_bytes());
        b[4..].copy_from_slice(&self.layout_hash.to_le_bytes());
        b
    }

    /// A stamp read from [`SchemaStamp::to_bytes`]'s bytes.
    pub fn from_bytes(b: &[u8]) -> Option<Self> {
        let version = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
        let layout_hash = u64::from_le_bytes(b.get(4..12)?.try_into().ok()?);
        Some(SchemaStamp {
            version,
            layout_hash,
        })
    }
}

impl core::fmt::Display for SchemaStamp {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "schema s{} (layout {:#018x})",
            self.version, self.layout_hash
        )
    }
}

/// A peer of another schema than this build's.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{peer} speaks {theirs}, this build {ours}: build both from the same AERIS-rs")]
pub struct SchemaMismatch {
    /// Who the peer is (`host ground`, `the bridge of host ground`).
    pub peer: String,
    /// The peer's stamp.
    pub theirs: SchemaStamp,
    /// This build's stamp.
    pub ours: SchemaStamp,
}

/// Check that `theirs` is this build's schema; `peer` names the other side.
pub fn check_schema(peer: &str, theirs: SchemaStamp) -> Result<(), SchemaMismatch> {
    let ours = SchemaStamp::current();
    if theirs == ours {
        Ok(())
    } else {
        Err(SchemaMismatch {
            peer: peer.to_string(),
            theirs,
            ours,
        })
    }
}

/// What an agent says of its host (`info`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HostInfo {
    /// The host's name (the agent's `--host`).
    pub host: String,
    /// The schema its build speaks.
    pub schema: SchemaStamp,
    /// The CPUs its role processes may run on.
    pub cpus: String,
    /// The agent's process id.
    pub agent_pid: u32,
    /// Role processes it runs now.
    pub roles: usize,
    /// Its CLOCK_MONOTONIC when it answered (ns): with the asker's clock at the request and
    /// the reply, the offset between the two hosts' clocks.
    pub monotonic_ns: u64,
    /// Busy cores of its CPUs (`cpus`) over the last [`crate::agent::LOAD_INTERVAL`] or so
    /// (all work there, roles and outside work alike).
    #[serde(default)]
    pub busy_cores: f64,
    /// How many CPUs `cpus` names.
    #[serde(default)]
    pub cpu_count: u32,
}

/// Start a role on the agent's host (`spawn`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpawnRequest {
    /// The asker's schema: the agent refuses another.
    pub schema: SchemaStamp,
    /// The role to run there (its `remote` empty, its `cpus` the executor's CPUs there).
    pub spec: RoleSpec,
    /// The pid the role's heartbeats name: the handle's, on the flight's host.
    pub handle_pid: u32,
}

/// A role process the agent started.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Spawned {
    /// Its pid on the agent's host.
    pub pid: u32,
    /// Its log there.
    pub log: String,
}

/// Stop a role process the agent started (`stop`): SIGTERM, SIGKILL after the grace time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StopRequest {
    /// Its flight.
    pub flight: String,
    /// Its role name.
    pub role: String,
    /// Its instance number.
    pub instance: u32,
}

/// How a role process on the agent's host ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExitReport {
    /// Its pid there.
    pub pid: u32,
    /// Its exit code (`None`: killed by a signal).
    pub code: Option<i32>,
    /// The signal that killed it.
    pub signal: Option<i32>,
    /// The last lines of its log.
    pub log_tail: String,
    /// Why the agent stopped it on its own (its handle's token was gone for a lease), if it
    /// did: a handle that still hears this lost its link, not its role.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped_by_agent: Option<String>,
}

/// An agent's answer: the result, or why it refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AgentReply<T> {
    /// Done.
    Ok(T),
    /// Refused, and why.
    Refused(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stamp_round_trips_its_bytes_and_another_is_refused_by_name() {
        let s = SchemaStamp::current();
        assert_eq!(SchemaStamp::from_bytes(&s.to_bytes()), Some(s));
        assert_eq!(SchemaStamp::from_bytes(&[1, 2, 3]), None);
        assert!(check_schema("host ground", s).is_ok());
        let other = SchemaStamp {
            version: s.version - 1,
            layout_hash: 7,
        };
        let e = check_schema("host ground", other).unwrap_err().to_string();
        assert!(e.starts_with("host ground speaks schema s"), "{e}");
        assert!(
            e.contains(&format!("this build schema s{}", s.version)),
            "{e}"
        );
    }
}
