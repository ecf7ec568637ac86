//! The zenoh sessions of our processes. Hosts find each other only at the endpoints the
//! workflow and the agents name (no multicast scouting: a radio link or a shared LAN must
//! not pull another flight's hosts in). An agent is a zenoh **router** listening on its
//! endpoint; every other process of ours is a **client** of one router: the bridge and the
//! handles on the flight's host connect to the other host's agent, the bridge and roles on
//! that host to their own agent.
//!
//! Every link is mutual TLS ([`LinkSecurity::Tls`], endpoints `tls/ADDRESS:PORT`): each
//! side shows a certificate of the flight's CA ([`crate::keys`]), a client checks that the
//! agent's certificate is valid for the address it dialled, and the agent's router admits a
//! peer only through its access rules ([`crate::access`]). A link whose certificate expires
//! is closed. Plain TCP ([`LinkSecurity::Insecure`], `tcp/`) is only for a user who asks
//! for it by name.

use crate::keys::Identity;
use std::time::Duration;
use zenoh::{Config, Session, Wait};

/// How a session's links are secured.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkSecurity {
    /// Mutual TLS with this host's identity: endpoints `tls/ADDRESS:PORT`.
    Tls(Identity),
    /// Plain TCP: no authentication, no encryption. Endpoints `tcp/ADDRESS:PORT`; only
    /// where a user asked for it (`--insecure`, `insecure = true`).
    Insecure,
}

impl LinkSecurity {
    /// Mutual TLS with the identity in `keys`, or plain TCP without one.
    pub fn from_keys(
        keys: Option<&std::path::Path>,
    ) -> Result<LinkSecurity, crate::keys::IdentityError> {
        match keys {
            Some(dir) => Ok(LinkSecurity::Tls(Identity::load(dir)?)),
            None => Ok(LinkSecurity::Insecure),
        }
    }

    /// The endpoint scheme it takes (`tls`, `tcp`).
    pub fn scheme(&self) -> &'static str {
        match self {
            LinkSecurity::Tls(_) => "tls",
            LinkSecurity::Insecure => "tcp",
        }
    }
}

/// Why a session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// An endpoint is not a zenoh endpoint of ours (`tls/ADDRESS:PORT`, `tcp/ADDRESS:PORT`).
    #[error("`{endpoint}` is not a zenoh endpoint of ours (write tls/ADDRESS:PORT)")]
    Endpoint {
        /// The endpoint as written.
        endpoint: String,
    },
    /// An endpoint's transport is not the session's security: a `tcp/` endpoint without
    /// `insecure`, or a `tls/` endpoint without keys.
    #[error("`{endpoint}` {reason}")]
    Security {
        /// The endpoint as written.
        endpoint: String,
        /// What does not fit.
        reason: &'static str,
    },
    /// zenoh refused the configuration.
    #[error("zenoh refused the session configuration `{key}`: {reason}")]
    Config {
        /// The configuration key.
        key: String,
        /// zenoh's reason.
        reason: String,
    },
    /// The session could not be opened (a router that does not answer, a port in use).
    #[error("cannot open a zenoh session ({what}): {reason}")]
    Open {
        /// Which session (`listening on tcp/0.0.0.0:7447`, `to tcp/10.0.0.2:7447`).
        what: String,
        /// zenoh's reason.
        reason: String,
    },
}

/// Check that `endpoint` is one of ours (`tls/HOST:PORT` or `tcp/HOST:PORT` with a port,
/// [`aeris_orchestrator::workflow::check_endpoint`]) and that its transport is `security`'s.
pub fn check_endpoint(endpoint: &str, security: &LinkSecurity) -> Result<(), SessionError> {
    if !aeris_orchestrator::workflow::check_endpoint(endpoint) {
        return Err(SessionError::Endpoint {
            endpoint: endpoint.to_string(),
        });
    }
    let reason = match (endpoint.split('/').next(), security) {
        (Some("tls"), LinkSecurity::Tls(_)) | (Some("tcp"), LinkSecurity::Insecure) => {
            return Ok(());
        }
        (Some("tls"), LinkSecurity::Insecure) => {
            "is a TLS endpoint: it needs this host's keys (`aeris keys issue`), not an insecure link"
        }
        _ => {
            "is plain TCP (no authentication, no encryption): use a tls/ endpoint with keys, or ask for an insecure link by name"
        }
    };
    Err(SessionError::Security {
        endpoint: endpoint.to_string(),
        reason,
    })
}

fn json_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into())
}

fn path_json(p: &std::path::Path) -> String {
    json_str(&p.display().to_string())
}

/// The TLS settings of a session with `identity`: its CA is the only one trusted for
/// clients (zenoh's server verifier) and added to the web roots for servers, which is why a
/// client also checks the server's name against the address it dialled; mutual
/// authentication; a link closes when its certificate expires.
fn set_tls(c: &mut Config, identity: &Identity, listen: bool) -> Result<(), SessionError> {
    let tls = "transport/link/tls";
    set(
        c,
        &format!("{tls}/root_ca_certificate"),
        &path_json(&identity.ca),
    )?;
    let side = if listen { "listen" } else { "connect" };
    set(
        c,
        &format!("{tls}/{side}_private_key"),
        &path_json(&identity.key),
    )?;
    set(
        c,
        &format!("{tls}/{side}_certificate"),
        &path_json(&identity.cert),
    )?;
    set(c, &format!("{tls}/enable_mtls"), "true")?;
    set(c, &format!("{tls}/verify_name_on_connect"), "true")?;
    set(c, &format!("{tls}/close_link_on_expiration"), "true")?;
    Ok(())
}

fn set(config: &mut Config, key: &str, value: &str) -> Result<(), SessionError> {
    config
        .insert_json5(key, value)
        .map_err(|e| SessionError::Config {
            key: key.to_string(),
            reason: e.to_string(),
        })
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).unwrap_or_else(|_| "[]".into())
}

/// The settings every session of ours shares: no multicast scouting, and a link lease of
/// `lease` (a peer silent that long is gone; keep-alives go four times a lease).
fn base(mode: &str, lease: Duration) -> Result<Config, SessionError> {
    let mut c = Config::default();
    set(&mut c, "mode", &format!("\"{mode}\""))?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    let lease_ms = lease.as_millis().clamp(500, 60_000);
    set(&mut c, "transport/link/tx/lease", &lease_ms.to_string())?;
    Ok(c)
}

/// An agent's session: a router listening on `listen`, admitting peers by `access` (zenoh
/// access control, JSON; `None` only on an insecure link, where no peer has a name).
pub fn open_router(
    listen: &[String],
    lease: Duration,
    security: &LinkSecurity,
    access: Option<&serde_json::Value>,
) -> Result<Session, SessionError> {
    for e in listen {
        check_endpoint(e, security)?;
    }
    let mut c = base("router", lease)?;
    set(&mut c, "listen/endpoints", &json_list(listen))?;
    if let LinkSecurity::Tls(identity) = security {
        set_tls(&mut c, identity, true)?;
    }
    if let Some(rules) = access {
        set(&mut c, "access_control", &rules.to_string())?;
    }
    // a router of ours never dials out: the flight's host connects to it
    set(&mut c, "connect/endpoints", "[]")?;
    zenoh::open(c).wait().map_err(|e| SessionError::Open {
        what: format!("listening on {}", listen.join(", ")),
        reason: e.to_string(),
    })
}

/// How a client session treats a router it cannot reach.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reach {
    /// Fail when the router does not answer within this time (a handle asking for a role).
    Within(Duration),
    /// Do not wait for the router: try once, at once, and keep retrying the link in the
    /// background once it was made (a bridge: the flight never waits for a link). zenoh
    /// cannot open a client session while no router answers at all: the bridge retries
    /// that itself.
    Eventually,
}

/// A client session of the router at `endpoint`.
pub fn open_client(
    endpoint: &str,
    reach: Reach,
    lease: Duration,
    security: &LinkSecurity,
) -> Result<Session, SessionError> {
    check_endpoint(endpoint, security)?;
    let mut c = base("client", lease)?;
    if let LinkSecurity::Tls(identity) = security {
        set_tls(&mut c, identity, false)?;
    }
    set(
        &mut c,
        "connect/endpoints",
        &json_list(&[endpoint.to_string()]),
    )?;
    match reach {
        Reach::Within(t) => {
            set(
                &mut c,
                "connect/timeout_ms",
                &t.as_millis().max(1).to_string(),
            )?;
            set(&mut c, "connect/exit_on_failure", "true")?;
        }
        Reach::Eventually => {
            set(&mut c, "connect/timeout_ms", "0")?;
            set(&mut c, "connect/exit_on_failure", "false")?;
            set(
                &mut c,
                "connect/retry",
                "{ period_init_ms: 250, period_max_ms: 1000, period_increase_factor: 2 }",
            )?;
        }
    }
    zenoh::open(c).wait().map_err(|e| SessionError::Open {
        what: format!("to {endpoint}"),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_tls_and_tcp_endpoints_with_a_port_are_ours_and_tcp_only_when_insecure() {
        let t = tempfile::tempdir().unwrap();
        crate::keys::init(t.path(), 1).unwrap();
        let issued = crate::keys::issue(t.path(), "ground", &[], 1, false).unwrap();
        let tls = LinkSecurity::Tls(Identity::load(&issued.dir).unwrap());
        let insecure = LinkSecurity::Insecure;
        assert!(check_endpoint("tls/10.0.0.2:7447", &tls).is_ok());
        assert!(check_endpoint("tcp/[::1]:7447", &insecure).is_ok());
        for bad in [
            "udp/10.0.0.2:7447",
            "tls/10.0.0.2",
            "tcp/:7447",
            "10.0.0.2:7447",
        ] {
            let e = check_endpoint(bad, &tls).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
        let e = check_endpoint("tcp/10.0.0.2:7447", &tls)
            .unwrap_err()
            .to_string();
        assert!(e.contains("is plain TCP"), "{e}");
        let e = check_endpoint("tls/10.0.0.2:7447", &insecure)
            .unwrap_err()
            .to_string();
        assert!(e.contains("needs this host's keys"), "{e}");
    }
}
