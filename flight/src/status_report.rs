//! A running flight seen from another process (`aeris status`): its supervisor's status
//! board, each role's memory on this host, and the links to other hosts, as one typed value.
//! `--json` is its `Serialize`, the table its `Display`.

use aeris_orchestrator::executors::process_memory;
use aeris_runtime::bus::{BusError, FlightBus};
use aeris_runtime::clock::monotonic_ns;
use aeris_schemas::{HostLinkStatus, RoleStatus, RoleStatusEntry};
use serde::Serialize;
use std::fmt;

const MIB: f64 = 1024.0 * 1024.0;

/// What `aeris status` reports of a running flight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FlightStatusReport {
    /// Flight name.
    pub flight: String,
    /// The supervisor's process.
    pub supervisor_pid: u32,
    /// The hub's active step of the mission (1-based; 0 before the first).
    pub active_step: u16,
    /// Steps of the mission.
    pub subgoals: u16,
    /// Distance to the goal (m), when known.
    pub distance_to_goal_m: Option<f32>,
    /// Mean cycle time so far (s).
    pub ct_mean_s: f32,
    /// Live moves so far.
    pub migrations: u32,
    /// The memory of the roles on this host, summed.
    pub memory: MemoryTotals,
    /// Every role.
    pub roles: Vec<RoleStatusRow>,
    /// The links to other hosts.
    pub links: Vec<LinkStatusRow>,
}

/// The memory of a flight's roles on this host, summed over those whose memory could be read.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MemoryTotals {
    /// Resident set sizes summed (MiB; shared pages counted in every process).
    pub rss_total_mib: Option<f64>,
    /// Proportional set sizes summed (MiB; what the roles hold together).
    pub pss_total_mib: Option<f64>,
}

/// One role of a running flight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RoleStatusRow {
    /// Role name.
    pub name: String,
    /// Its process (0: none).
    pub pid: u32,
    /// The CPUs it is bound to ("": unbound).
    pub cpus: String,
    /// The variant it runs.
    pub variant: String,
    /// Its last heartbeat's status (`no-heartbeat` before the first).
    pub status: &'static str,
    /// Age of its last heartbeat (ms), once it sent one.
    pub heartbeat_age_ms: Option<f64>,
    /// Heartbeats received.
    pub heartbeats: u64,
    /// Latency percentiles of its cycles (ms).
    pub latency_p50_ms: f32,
    /// 95th percentile (ms).
    pub latency_p95_ms: f32,
    /// 99th percentile (ms).
    pub latency_p99_ms: f32,
    /// Restarts so far.
    pub restarts: u32,
    /// Heartbeat gaps so far.
    pub heartbeat_gaps: u32,
    /// Its executor (`HOST:EXECUTOR` on another host).
    pub executor: String,
    /// Its latency budget (ms), if it has one.
    pub budget_ms: Option<f32>,
    /// Live moves of this role.
    pub migrations: u32,
    /// Stalls found.
    pub stalls: u32,
    /// Why it is bound where it is.
    pub binding: String,
    /// Resident set size (MiB), when readable here.
    pub rss_mib: Option<f64>,
    /// Proportional set size (MiB), when the kernel has it.
    pub pss_mib: Option<f64>,
}

/// One link to another host, as the bridge on the flight's host measures it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LinkStatusRow {
    /// The other host.
    pub host: String,
    /// Whether the link is up, once probed.
    pub connected: Option<bool>,
    /// Smoothed round-trip time (ms).
    pub rtt_ms: Option<f64>,
    /// Last round-trip time (ms).
    pub rtt_last_ms: Option<f64>,
    /// Probes lost (fraction), once probed.
    pub loss: Option<f64>,
    /// Probes sent.
    pub probes: u64,
    /// Probes answered.
    pub answered: u64,
    /// The other host's clock offset (ms).
    pub clock_offset_ms: Option<f64>,
    /// Busy cores there.
    pub busy_cores: Option<f64>,
    /// Its cores.
    pub cpus: u32,
    /// Time to code a frame for the link (ms).
    pub frame_coding_ms: Option<f64>,
}

/// Why a flight's status could not be read.
#[derive(Debug, thiserror::Error)]
#[error("flight `{flight}` has no supervisor status board (is its supervisor running?)")]
pub struct StatusReadError {
    /// The flight.
    pub flight: String,
    /// What the bus said.
    #[source]
    pub source: BusError,
}

impl FlightStatusReport {
    /// Read the status of `flight` through `bus` (a node of that flight).
    pub fn read(bus: &FlightBus, flight: &str) -> Result<Self, StatusReadError> {
        let board = bus.read_status_board().map_err(|source| StatusReadError {
            flight: flight.to_string(),
            source,
        })?;
        let now = monotonic_ns();
        let roles: Vec<RoleStatusRow> = board.roles().iter().map(|r| role_row(r, now)).collect();
        let sum = |of: fn(&RoleStatusRow) -> Option<f64>| {
            let known: Vec<f64> = roles.iter().filter_map(of).collect();
            (!known.is_empty()).then(|| known.iter().sum())
        };
        let memory = MemoryTotals {
            rss_total_mib: sum(|r| r.rss_mib),
            pss_total_mib: sum(|r| r.pss_mib),
        };
        Ok(Self {
            flight: flight.to_string(),
            supervisor_pid: board.supervisor_pid,
            active_step: board.active_step,
            subgoals: board.subgoals,
            distance_to_goal_m: (board.distance_to_goal_m >= 0.0)
                .then_some(board.distance_to_goal_m),
            ct_mean_s: board.ct_mean_s,
            migrations: board.migrations,
            memory,
            roles,
            links: board.links().iter().map(link_row).collect(),
        })
    }
}

fn role_row(r: &RoleStatusEntry, now: u64) -> RoleStatusRow {
    let heartbeat_age_ms =
        (r.last_heartbeat_ns > 0).then(|| now.saturating_sub(r.last_heartbeat_ns) as f64 / 1e6);
    // a role on another host runs on an executor `HOST:EXECUTOR`; its pid is that host's,
    // its memory not readable here
    let executor = r.executor.as_str_lossy().to_string();
    let memory = (r.pid != 0 && !executor.contains(':'))
        .then(|| process_memory(r.pid))
        .flatten();
    RoleStatusRow {
        name: r.name.as_str_lossy().to_string(),
        pid: r.pid,
        cpus: r.cpus.as_str_lossy().to_string(),
        variant: r.variant.as_str_lossy().to_string(),
        status: RoleStatus::from_u8(r.status).map_or("no-heartbeat", |s| s.name()),
        heartbeat_age_ms,
        heartbeats: r.heartbeats,
        latency_p50_ms: r.latency_ms[0],
        latency_p95_ms: r.latency_ms[1],
        latency_p99_ms: r.latency_ms[2],
        restarts: r.restarts,
        heartbeat_gaps: r.heartbeat_gaps,
        executor,
        budget_ms: (r.budget_ms > 0.0).then_some(r.budget_ms),
        migrations: r.migrations,
        stalls: r.stalls,
        binding: r.binding.as_str_lossy().to_string(),
        rss_mib: memory.map(|m| m.rss_bytes as f64 / MIB),
        pss_mib: memory.and_then(|m| m.pss_bytes).map(|b| b as f64 / MIB),
    }
}

fn link_row(l: &HostLinkStatus) -> LinkStatusRow {
    let measured = l.probes > 0;
    let answered = l.answered > 0;
    LinkStatusRow {
        host: l.host.as_str_lossy().to_string(),
        connected: measured.then_some(l.connected == 1),
        rtt_ms: l.rtt_ms(),
        rtt_last_ms: answered.then(|| l.rtt_ns as f64 / 1e6),
        loss: measured.then(|| l.loss()),
        probes: l.probes,
        answered: l.answered,
        clock_offset_ms: answered.then(|| l.clock_offset_ns as f64 / 1e6),
        busy_cores: (l.cpus > 0).then(|| l.busy_cores()),
        cpus: l.cpus,
        frame_coding_ms: (l.frame_coding_ns > 0).then(|| l.frame_coding_ns as f64 / 1e6),
    }
}

/// `x` with `digits` decimals, or `-`.
fn or_dash(x: Option<f64>, digits: usize) -> String {
    x.map_or_else(|| "-".into(), |x| format!("{x:.digits$}"))
}

impl fmt::Display for FlightStatusReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let distance = self
            .distance_to_goal_m
            .map_or_else(|| "?".into(), |d| format!("{d:.1} m"));
        writeln!(
            f,
            "flight {}  supervisor pid {}  step {}/{}  distance to goal {distance}  CT mean {:.3} s  migrations {}",
            self.flight,
            self.supervisor_pid,
            self.active_step,
            self.subgoals,
            self.ct_mean_s,
            self.migrations
        )?;
        // the role column fits the longest name (`controller-standby`)
        let w = self
            .roles
            .iter()
            .map(|r| r.name.len())
            .max()
            .unwrap_or(0)
            .max(12);
        writeln!(
            f,
            "{:<w$} {:>7} {:<12} {:<6} {:<15} {:<12} {:>9} {:>9} {:>9} {:>9} {:>8} {:>5} {:>6} {:>7}",
            "ROLE",
            "PID",
            "EXECUTOR",
            "CPUS",
            "VARIANT",
            "STATUS",
            "HB AGE",
            "P50 ms",
            "P95 ms",
            "BUDGET ms",
            "RESTARTS",
            "MOVES",
            "STALLS",
            "MEM MiB"
        )?;
        for r in &self.roles {
            let age = r
                .heartbeat_age_ms
                .map_or_else(|| "-".into(), |a| format!("{a:.0} ms"));
            writeln!(
                f,
                "{:<w$} {:>7} {:<12} {:<6} {:<15} {:<12} {:>9} {:>9.3} {:>9.3} {:>9} {:>8} {:>5} {:>6} {:>7}",
                r.name,
                r.pid,
                r.executor,
                r.cpus,
                r.variant,
                r.status,
                age,
                r.latency_p50_ms,
                r.latency_p95_ms,
                or_dash(r.budget_ms.map(f64::from), 0),
                r.restarts,
                r.migrations,
                r.stalls,
                or_dash(r.pss_mib.or(r.rss_mib), 0)
            )?;
        }
        if let Some(rss) = self.memory.rss_total_mib {
            match self.memory.pss_total_mib {
                Some(pss) => writeln!(
                    f,
                    "memory of the roles on this host: {pss:.0} MiB (PSS: shared pages divided among them; RSS summed {rss:.0} MiB)"
                )?,
                None => writeln!(
                    f,
                    "memory of the roles on this host: RSS summed {rss:.0} MiB"
                )?,
            }
        }
        writeln!(f, "binding:")?;
        for r in &self.roles {
            writeln!(f, "  {:<w$} {}", r.name, r.binding)?;
        }
        if !self.links.is_empty() {
            write_links(f, &self.links)?;
        }
        Ok(())
    }
}

/// The links to other hosts, as a table.
fn write_links(f: &mut fmt::Formatter<'_>, links: &[LinkStatusRow]) -> fmt::Result {
    writeln!(
        f,
        "{:<12} {:<9} {:>8} {:>8} {:>6} {:>13} {:>11} {:>12}",
        "LINK",
        "CONNECTED",
        "RTT ms",
        "LAST ms",
        "LOSS",
        "CLOCK OFF ms",
        "BUSY CORES",
        "FRAME ENC ms"
    )?;
    for l in links {
        let connected = match l.connected {
            Some(true) => "yes",
            Some(false) => "no",
            None => "-",
        };
        let loss = l
            .loss
            .map_or_else(|| "-".into(), |x| format!("{:.0} %", x * 100.0));
        let busy = l
            .busy_cores
            .map_or_else(|| "-".into(), |b| format!("{b:.2}/{}", l.cpus));
        writeln!(
            f,
            "{:<12} {:<9} {:>8} {:>8} {:>6} {:>13} {:>11} {:>12}",
            l.host,
            connected,
            or_dash(l.rtt_ms, 3),
            or_dash(l.rtt_last_ms, 3),
            loss,
            or_dash(l.clock_offset_ms, 3),
            busy,
            or_dash(l.frame_coding_ms, 2),
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> FlightStatusReport {
        FlightStatusReport {
            flight: "f1".into(),
            supervisor_pid: 42,
            active_step: 1,
            subgoals: 2,
            distance_to_goal_m: None,
            ct_mean_s: 0.5,
            migrations: 0,
            memory: MemoryTotals {
                rss_total_mib: Some(10.0),
                pss_total_mib: None,
            },
            roles: vec![RoleStatusRow {
                name: "controller-standby".into(),
                pid: 7,
                cpus: "0".into(),
                variant: "mavlink".into(),
                status: "running",
                heartbeat_age_ms: None,
                heartbeats: 3,
                latency_p50_ms: 0.25,
                latency_p95_ms: 0.5,
                latency_p99_ms: 1.0,
                restarts: 0,
                heartbeat_gaps: 0,
                executor: "control".into(),
                budget_ms: Some(20.0),
                migrations: 0,
                stalls: 0,
                binding: "declared".into(),
                rss_mib: Some(10.0),
                pss_mib: None,
            }],
            links: vec![LinkStatusRow {
                host: "ground".into(),
                connected: None,
                rtt_ms: None,
                rtt_last_ms: None,
                loss: Some(0.5),
                probes: 2,
                answered: 1,
                clock_offset_ms: None,
                busy_cores: Some(0.5),
                cpus: 2,
                frame_coding_ms: None,
            }],
        }
    }

    /// `--json` keeps the keys scripts read (`roles[].name`, `memory.rss_total_mib`, a
    /// link's `loss`), an unknown value as null.
    #[test]
    fn the_json_form_has_the_keys_scripts_read_and_null_for_what_is_unknown() {
        let v = serde_json::to_value(report()).expect("serialises");
        assert_eq!(v["roles"][0]["name"], "controller-standby");
        assert_eq!(v["memory"]["rss_total_mib"], 10.0);
        assert!(v["memory"]["pss_total_mib"].is_null());
        assert!(v["distance_to_goal_m"].is_null());
        assert_eq!(v["links"][0]["loss"], 0.5);
        assert!(v["roles"][0]["heartbeat_age_ms"].is_null());
    }

    /// The table says what is unknown with `-` or `?` and sizes the role column to the
    /// longest name.
    #[test]
    fn the_table_marks_unknowns_and_fits_the_longest_role_name() {
        let text = report().to_string();
        assert!(text.contains("distance to goal ?"), "{text}");
        let row = text
            .lines()
            .find(|l| l.starts_with("controller-standby "))
            .expect("the role's row");
        assert!(row.contains(" - "), "{row}");
        assert!(text.contains("memory of the roles on this host: RSS summed 10 MiB"));
        assert!(text.contains("ground       -"), "{text}");
        assert!(text.contains("50 %") && text.contains("0.50/2"), "{text}");
    }
}
