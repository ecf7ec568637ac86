//! Who may do what on an agent's router: zenoh's own access control, by the common name of
//! the certificate a peer authenticated with (mutual TLS). Everything not allowed here is
//! denied by zenoh before any request reaches our code.
//!
//! | peer (certificate name) | may send to the agent (ingress) |
//! |---|---|
//! | a flight's host (`--flight-host NAME`) | `info`, `spawn`, `stop` queries; its handles' liveliness tokens; subscriptions to the exit reports and the agent's token; the flight's data (`aeris/data/**`: put, subscribe) |
//! | this host (its own bridge) | the flight's data (put, subscribe) |
//! | anyone else, with a certificate of the flight's CA | nothing |
//!
//! What the agent's router sends out (egress) goes only to those two kinds of peers.

use crate::protocol::{agent_request_key, agent_token_key};
use serde_json::{Value, json};

/// The zenoh `access_control` configuration of the agent of `host` that obeys the flight
/// hosts `flight_hosts` (certificate names).
pub fn agent_access_control(host: &str, flight_hosts: &[String]) -> Value {
    let h = |rest: &str| format!("aeris/host/{host}/{rest}");
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [
            {
                "id": "command",
                "messages": ["query"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [
                    agent_request_key(host, "info"),
                    agent_request_key(host, "spawn"),
                    agent_request_key(host, "stop"),
                ],
            },
            {
                "id": "handles",
                "messages": ["liveliness_token"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [h("handle/**")],
            },
            {
                "id": "exits",
                "messages": ["declare_subscriber"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [h("exit/**")],
            },
            {
                "id": "agent_token",
                "messages": ["declare_liveliness_subscriber", "liveliness_query"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": [agent_token_key(host)],
            },
            {
                "id": "data",
                "messages": ["put", "declare_subscriber"],
                "flows": ["ingress"],
                "permission": "allow",
                "key_exprs": ["aeris/data/**"],
            },
            {
                "id": "to_members",
                "messages": [
                    "put", "delete", "declare_subscriber", "query", "declare_queryable",
                    "reply", "liveliness_token", "declare_liveliness_subscriber",
                    "liveliness_query",
                ],
                "flows": ["egress"],
                "permission": "allow",
                "key_exprs": ["aeris/**"],
            },
        ],
        "subjects": [
            { "id": "flight_hosts", "cert_common_names": flight_hosts },
            { "id": "this_host", "cert_common_names": [host] },
        ],
        "policies": [
            {
                "rules": ["command", "handles", "exits", "agent_token", "data", "to_members"],
                "subjects": ["flight_hosts"],
            },
            { "rules": ["data", "to_members"], "subjects": ["this_host"] },
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenoh_takes_the_rules_and_only_named_hosts_are_subjects() {
        let acl = agent_access_control("ground", &["vehicle".into()]);
        let mut c = zenoh::Config::default();
        c.insert_json5("access_control", &acl.to_string())
            .expect("zenoh's access control configuration");
        assert_eq!(acl["default_permission"], "deny");
        assert_eq!(acl["subjects"][0]["cert_common_names"], json!(["vehicle"]));
        assert_eq!(acl["subjects"][1]["cert_common_names"], json!(["ground"]));
    }
}
