//! The zenoh sessions of our processes. Hosts find each other only at the endpoints the
//! workflow and the agents name (no multicast scouting: a radio link or a shared LAN must
//! not pull another flight's hosts in). An agent is a zenoh **router** listening on its
//! endpoint; every other process of ours is a **client** of one router: the bridge and the
//! handles on the flight's host connect to the other host's agent, the bridge and roles on
//! that host to their own agent.

use std::time::Duration;
use zenoh::{Config, Session, Wait};

/// Why a session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// An endpoint is not a zenoh endpoint of the TCP transport (`tcp/ADDRESS:PORT`).
    #[error("`{endpoint}` is not a zenoh TCP endpoint (write tcp/ADDRESS:PORT)")]
    Endpoint {
        /// The endpoint as written.
        endpoint: String,
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

/// Check that `endpoint` is one of ours: `tcp/HOST:PORT` with a port
/// ([`aeris_orchestrator::workflow::check_endpoint`]).
pub fn check_endpoint(endpoint: &str) -> Result<(), SessionError> {
    if aeris_orchestrator::workflow::check_endpoint(endpoint) {
        Ok(())
    } else {
        Err(SessionError::Endpoint {
            endpoint: endpoint.to_string(),
        })
    }
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

/// An agent's session: a router listening on `listen`.
pub fn open_router(listen: &[String], lease: Duration) -> Result<Session, SessionError> {
    for e in listen {
        check_endpoint(e)?;
    }
    let mut c = base("router", lease)?;
    set(&mut c, "listen/endpoints", &json_list(listen))?;
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
pub fn open_client(endpoint: &str, reach: Reach, lease: Duration) -> Result<Session, SessionError> {
    check_endpoint(endpoint)?;
    let mut c = base("client", lease)?;
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
    fn only_tcp_endpoints_with_a_port_are_ours() {
        assert!(check_endpoint("tcp/10.0.0.2:7447").is_ok());
        assert!(check_endpoint("tcp/[::1]:7447").is_ok());
        for bad in [
            "udp/10.0.0.2:7447",
            "tcp/10.0.0.2",
            "tcp/:7447",
            "10.0.0.2:7447",
        ] {
            let e = check_endpoint(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
