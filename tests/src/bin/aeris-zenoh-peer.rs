//! A zenoh peer that speaks AERIS-rs's host protocol as a build of **another schema** would:
//! the conformance peer of the multi-host tests. It writes the protocol from its
//! description (key expressions, JSON requests, the 24-byte attachment), not with the
//! library's code, so it checks the wire and not the library against itself.
//!
//! - `aeris-zenoh-peer agent LISTEN HOST`: a router on LISTEN answering `info` for HOST as
//!   an agent of schema version N-1 would, until killed;
//! - `aeris-zenoh-peer spawn CONNECT HOST FLIGHT`: asks HOST's agent to start a role, stamped
//!   with schema N-1, and prints the answer;
//! - `aeris-zenoh-peer publish CONNECT FLIGHT TOPIC`: publishes messages stamped with schema
//!   N-1 on TOPIC every 50 ms, until killed.
//!
//! With `AERIS_PEER_KEYS=DIR` (an identity directory: `ca.pem`, `cert.pem`, `key.pem`) its
//! links are mutual TLS with that identity, configured from zenoh's documented keys.

use std::time::Duration;
use zenoh::{Config, Wait};

/// The schema this peer claims: the version before this build's, another layout.
fn old_stamp() -> (u32, u64) {
    (aeris_schemas::SCHEMA_VERSION - 1, 0x0123_4567_89ab_cdef)
}

fn config(mode: &str, key: &str, endpoint: &str) -> Config {
    let mut c = Config::default();
    c.insert_json5("mode", &format!("\"{mode}\"")).unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    c.insert_json5(key, &format!("[\"{endpoint}\"]")).unwrap();
    if let Some(dir) = std::env::var_os("AERIS_PEER_KEYS") {
        let dir = std::path::PathBuf::from(dir);
        let file = |f: &str| format!("\"{}\"", dir.join(f).display());
        let side = if mode == "router" {
            "listen"
        } else {
            "connect"
        };
        let tls = "transport/link/tls";
        c.insert_json5(&format!("{tls}/root_ca_certificate"), &file("ca.pem"))
            .unwrap();
        c.insert_json5(&format!("{tls}/{side}_certificate"), &file("cert.pem"))
            .unwrap();
        c.insert_json5(&format!("{tls}/{side}_private_key"), &file("key.pem"))
            .unwrap();
        c.insert_json5(&format!("{tls}/enable_mtls"), "true")
            .unwrap();
    }
    c
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (version, hash) = old_stamp();
    match args
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>()
        .as_slice()
    {
        ["agent", listen, host] => {
            let session = zenoh::open(config("router", "listen/endpoints", listen))
                .wait()
                .expect("open");
            let _token = session
                .liveliness()
                .declare_token(format!("aeris/host/{host}/agent"))
                .wait()
                .unwrap();
            let info = session
                .declare_queryable(format!("aeris/host/{host}/info"))
                .wait()
                .unwrap();
            println!("peer agent of host `{host}` listening (schema s{version})");
            while let Ok(q) = info.recv() {
                let answer = serde_json::json!({"ok": {
                    "host": host, "schema": {"version": version, "layout_hash": hash},
                    "cpus": "0", "agent_pid": std::process::id(), "roles": 0,
                    "monotonic_ns": 0u64,
                }});
                q.reply(q.key_expr().clone(), answer.to_string())
                    .wait()
                    .unwrap();
            }
        }
        ["spawn", connect, host, flight] => {
            let session = zenoh::open(config("client", "connect/endpoints", connect))
                .wait()
                .expect("open");
            let request = serde_json::json!({
                "schema": {"version": version, "layout_hash": hash},
                "spec": {"flight": flight, "name": "reasoning", "kind": "reasoning",
                         "variant": "planner", "mission": {"instruction": "x", "subgoals": []}},
                "handle_pid": std::process::id(),
            });
            let replies = session
                .get(format!("aeris/host/{host}/spawn"))
                .payload(request.to_string())
                .timeout(Duration::from_secs(5))
                .wait()
                .unwrap();
            match replies.recv() {
                Ok(r) => match r.result() {
                    Ok(s) => println!("{}", String::from_utf8_lossy(&s.payload().to_bytes())),
                    Err(e) => println!("error reply: {e:?}"),
                },
                Err(_) => println!("no answer"),
            }
        }
        ["publish", connect, flight, topic] => {
            let session = zenoh::open(config("client", "connect/endpoints", connect))
                .wait()
                .expect("open");
            let publisher = session
                .declare_publisher(format!("aeris/data/{flight}/{topic}"))
                .wait()
                .unwrap();
            let mut seq = 0u64;
            loop {
                seq += 1;
                let mut att = Vec::with_capacity(24);
                att.extend_from_slice(&version.to_le_bytes());
                att.extend_from_slice(&hash.to_le_bytes());
                att.extend_from_slice(&seq.to_le_bytes());
                att.extend_from_slice(&64u32.to_le_bytes());
                publisher.put(vec![0u8; 64]).attachment(att).wait().unwrap();
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        _ => {
            eprintln!(
                "usage: aeris-zenoh-peer agent LISTEN HOST | spawn CONNECT HOST FLIGHT | publish CONNECT FLIGHT TOPIC"
            );
            std::process::exit(2);
        }
    }
}
