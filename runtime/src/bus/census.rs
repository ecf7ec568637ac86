//! What exists on this host: the flights, their services and the nodes registered at
//! them, and the clean-up after processes that died without closing theirs.

use super::{Ipc, iceoryx_config};
use aeris_schemas::SCHEMA_VERSION;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;

/// Services of `flight` that currently exist (names relative to the flight prefix).
pub fn list_flight_services(flight: &str) -> Vec<String> {
    let prefix = format!("aeris/s{SCHEMA_VERSION}/{flight}/");
    let mut out = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix(&prefix) {
            out.push(rest.to_string());
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup();
    out
}

/// Services of `flight` with the names of the nodes registered at each (node names relative
/// to the flight: role names, `supervisor`, ...). A service whose dynamic part cannot be
/// read lists no nodes.
pub fn flight_service_nodes(flight: &str) -> Vec<(String, Vec<String>)> {
    let prefix = format!("aeris/s{SCHEMA_VERSION}/{flight}/");
    let node_prefix = format!("{flight}/");
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix(&prefix) {
            let mut nodes: Vec<String> = s
                .dynamic_details
                .iter()
                .flat_map(|d| d.nodes.iter())
                .filter_map(|n| {
                    let details = match n {
                        NodeState::Alive(v) => v.details().as_ref(),
                        NodeState::Dead(v) => v.details().as_ref(),
                        _ => None,
                    }?;
                    details
                        .name()
                        .as_str()
                        .strip_prefix(&node_prefix)
                        .map(str::to_string)
                })
                .collect();
            nodes.sort();
            nodes.dedup();
            out.push((rest.to_string(), nodes));
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup_by(|a, b| a.0 == b.0);
    out
}

/// Delete the files of `flight`'s service `topic` the way an outside tool would (a `/dev/shm`
/// clean-up, systemd's `RemoveIPC`): its static config and every shared-memory file named
/// after its hash. Processes that mapped them keep their mappings; nobody new can open the
/// service. Fault injection for `aeris bench faults`; returns the files removed.
pub fn remove_flight_service_files(flight: &str, topic: &str) -> std::io::Result<usize> {
    let full = format!("aeris/s{SCHEMA_VERSION}/{flight}/{topic}");
    let mut hash = None;
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        if s.static_details.name().as_str() == full {
            hash = Some(s.static_details.service_hash().as_str().to_string());
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    let Some(hash) = hash else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("no service `{topic}` in flight `{flight}`"),
        ));
    };
    let global = &iceoryx_config().global;
    let root = std::path::PathBuf::from(global.root_path().to_string());
    let dirs = [
        root.join(global.service.directory.to_string()),
        std::path::PathBuf::from("/dev/shm"),
    ];
    let mut removed = 0;
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().contains(&hash) {
                std::fs::remove_file(e.path())?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// Flights that have a manifest on this host.
pub fn list_flights() -> Vec<String> {
    let mut out = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix("aeris/")
            && let Some(flight) = rest.strip_suffix("/manifest")
        {
            out.push(flight.to_string());
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup();
    out
}

/// Whether a live process of `flight` has the node `node` (relative to the flight: a role
/// name, `supervisor`). A tool that follows a flight asks it of `supervisor` to learn that
/// the flight ended (the manifest outlives it while any process still holds it).
pub fn flight_node_alive(flight: &str, node: &str) -> bool {
    let full = format!("{flight}/{node}");
    let mut alive = false;
    let _ = Node::<Ipc>::list(iceoryx_config(), |state| {
        if let NodeState::Alive(v) = &state
            && v.details()
                .as_ref()
                .is_some_and(|d| d.name().as_str() == full)
        {
            alive = true;
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    alive
}

/// iceoryx2 nodes of `flight`: (alive, dead) counts. A dead node is one whose process died
/// without cleaning up.
pub fn flight_node_census(flight: &str) -> (usize, usize) {
    let prefix = format!("{flight}/");
    let (mut alive, mut dead) = (0, 0);
    let _ = Node::<Ipc>::list(iceoryx_config(), |state| {
        let of_flight = |d: &Option<iceoryx2::node::NodeDetails>| {
            d.as_ref()
                .is_some_and(|d| d.name().as_str().starts_with(&prefix))
        };
        match &state {
            NodeState::Alive(v) if of_flight(v.details()) => alive += 1,
            NodeState::Dead(v) if of_flight(v.details()) => dead += 1,
            _ => {}
        }
        CallbackProgression::Continue
    });
    (alive, dead)
}

/// Remove the iceoryx2 resources of every dead process on this host; returns how many dead
/// nodes were cleaned up.
pub fn cleanup_dead_nodes() -> u64 {
    match NodeBuilder::new()
        .config(iceoryx_config())
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Ipc>()
    {
        Ok(node) => node.try_cleanup_dead_nodes().cleanups,
        Err(_) => 0,
    }
}
