//! Joining a running flight from another process (`aeris status`, `topic`, `swap`,
//! `migrate`, `record`): which flight, and a bus node of the tool on it.

use aeris_runtime::bus::{self, FlightBus};
use anyhow::{Context, Result, bail};

/// The flight to inspect: the one named, or the only one running.
pub fn resolve_flight(flight: Option<String>) -> Result<String> {
    bus::cleanup_dead_nodes();
    if let Some(f) = flight {
        return Ok(f);
    }
    let flights = bus::list_flights();
    match flights.as_slice() {
        [] => bail!("no flight is running on this host (start one with `aeris run`)"),
        [one] => Ok(one.clone()),
        many => bail!(
            "several flights are running ({}); choose one with --flight NAME",
            many.join(", ")
        ),
    }
}

/// A bus node of the tool `tool` on `flight`.
pub fn tool_bus(flight: &str, tool: &str) -> Result<FlightBus> {
    FlightBus::builder(flight)
        .node_name(&format!("cli-{tool}-{}", std::process::id()))
        .create()
        .with_context(|| format!("cannot join flight `{flight}`"))
}
