//! # aeris-hosts
//!
//! Roles on other hosts. A workflow may put an executor on another host
//! (`[hosts.ground] endpoint = "tcp/10.0.0.2:7447"`, `[executors.gs] host = "ground"`); a
//! role bound there runs on that host, started by its agent, and talks to the rest of the
//! flight through a bridge on each host. Everything crosses on zenoh.
//! - [`protocol`]: key expressions, the schema stamp, the agent's requests and replies;
//! - [`keys`]: the flight's CA and its hosts' certificates (`aeris keys`);
//! - [`access`]: who may do what on an agent's router (zenoh access control by
//!   certificate name);
//! - [`admission`]: what an agent agrees to start (names, allow-list, parameters), pure;
//! - [`private_dir`]: owner-only directories and files, never through a link;
//! - [`session`]: zenoh sessions of our processes (no multicast scouting: a host is reached
//!   at the endpoint the workflow names);
//! - [`agent`]: `aeris agent`, the daemon on every host that runs role processes for the
//!   supervisor on another, reports their exits and stops them when their handle goes;
//! - [`handle`]: the process that stands for a remote role on the flight's host: the
//!   supervisor starts, watches, restarts and stops it like any role process;
//! - [`bridge`]: the role (kind `bridge`, variant `zenoh`) that carries a flight's topics
//!   between iceoryx2 on its host and zenoh, exact bytes, schema checked per message;
//! - [`frames`]: how frames cross (JPEG or raw);
//! - [`probe`]: the link's round trip, loss, clock offset and the other host's load, as
//!   the bridge on the flight's host measures them (`hosts/link`);
//! - [`netns`]: two hosts on one machine (network namespaces, private `/dev/shm`), for the
//!   tests and `aeris bench hosts`.

#![deny(missing_docs)]

pub mod access;
pub mod admission;
pub mod agent;
pub mod bridge;
pub mod frames;
pub mod handle;
pub mod keys;
pub mod netns;
pub mod private_dir;
pub mod probe;
pub mod protocol;
pub mod session;
pub mod testing;
