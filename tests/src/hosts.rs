//! Two hosts on one machine for the multi-host tests ([`aeris_hosts::netns`]): two network
//! namespaces joined by a veth pair, every process with a private `/dev/shm`. Needs root.

pub use aeris_hosts::netns::TwoHosts;

/// Two hosts; panics with what failed (these tests need root).
pub fn two_hosts() -> TwoHosts {
    TwoHosts::new().unwrap_or_else(|e| {
        panic!("cannot create two hosts as network namespaces (run the tests as root): {e}")
    })
}
