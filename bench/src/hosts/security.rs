//! `aeris bench hosts --tls`: what mutual TLS costs on the link, beside plain TCP. The same
//! flights on each link: the reasoner and the perception role on the ground host (every
//! frame and every decision crosses), then the link cut under the reasoner and restored; and
//! the link alone, without a flight ([`super::ping`]).

use super::ping::{PingFigures, ping_pong};
use super::{
    Flight, HostsBenchConfig, HostsBenchError, LinkKind, bridge_sent, cut_on, flight_name, setting,
};
use serde::Serialize;
use std::path::Path;

/// One link's figures.
#[derive(Debug, Clone, Serialize)]
pub struct SecurityRow {
    /// The link.
    pub link: LinkKind,
    /// The flight reached its goal.
    pub reached_goal: bool,
    /// The link's round trip as the vehicle's bridge measured it (`info` queries, ms).
    pub rtt_ms: Option<f64>,
    /// Cycle time mean (s).
    pub ct_mean_s: Option<f64>,
    /// Cycle time p95 (s).
    pub ct_p95_s: Option<f64>,
    /// The decision's path across the link: D_t published on the ground host → received
    /// by the hub on the vehicle (mean, ms).
    pub decision_path_ms: Option<f64>,
    /// A frame's path: captured on the vehicle → S_t published on the ground host (its
    /// crossing and the perception there; mean, ms).
    pub frame_to_state_ms: Option<f64>,
    /// Time to encode a frame for the link (JPEG; ms).
    pub frame_coding_ms: Option<f64>,
    /// Bytes per frame on the link.
    pub bytes_per_frame: Option<f64>,
    /// CPU of the vehicle's bridge process (% of one core over its life).
    pub bridge_cpu_vehicle_pct: Option<f64>,
    /// CPU of the ground host's bridge process (%).
    pub bridge_cpu_ground_pct: Option<f64>,
    /// From the link restored to the supervisor hearing the ground host's bridge again (the
    /// new link's handshake included; ms).
    pub restored_to_link_ms: u64,
    /// From the link restored to the reasoner deciding on the ground host again (5 s
    /// hysteresis included; ms).
    pub restored_to_reasoner_ms: u64,
    /// The link alone (loopback, through a router, no flight): round trips of a
    /// decision-sized and a frame-sized message ([`PING_SIZES`]).
    pub ping: Vec<PingFigures>,
}

/// The ping-pong's message sizes: a decision (88 B and its attachment) and a JPEG frame
/// (its header and ~8.6 kB of pixels at quality 85).
pub const PING_SIZES: [usize; 2] = [112, 8_800];
/// Round trips per size.
pub const PING_ROUND_TRIPS: usize = 2_000;

/// Both links.
#[derive(Debug, Clone, Serialize)]
pub struct SecurityReport {
    /// Busy processes outside the flight.
    pub outside_load: usize,
    /// TCP, then TLS.
    pub rows: Vec<SecurityRow>,
}

/// `bridge: used S s of CPU over W s (P% of one core...` in a bridge's log: P.
fn bridge_cpu_pct(log: &Path) -> Option<f64> {
    let text = std::fs::read_to_string(log).ok()?;
    let line = text
        .lines()
        .rev()
        .find(|l| l.starts_with("bridge: used "))?;
    let pct = line.split('(').nth(1)?.split('%').next()?;
    pct.trim().parse().ok()
}

fn row(config: &HostsBenchConfig, kind: LinkKind) -> Result<SecurityRow, HostsBenchError> {
    let tag = match kind {
        LinkKind::Tls => "security-tls",
        LinkKind::Tcp => "security-tcp",
    };
    let s = setting(config, tag, &["reasoning", "perception"], false, kind)?;
    let name = flight_name(tag);
    let flight: Flight = s.fly(config, &name)?;
    let (summary, run_dir) = flight.finish()?;
    let ms = |stage: &str| summary["stages_mean_s"][stage].as_f64().map(|v| v * 1e3);
    let bytes_per_frame = bridge_sent(&run_dir, "bridge-to-ground", "camera/rgb")
        .and_then(|(frames, bytes)| (frames > 0).then(|| bytes as f64 / frames as f64));
    let ground_log = s
        .dir
        .join("agent")
        .join(&name)
        .join("logs")
        .join("bridge-on-ground.log");
    // the cut flight's own figures are the default benchmark's; here, its restore
    let (cut, restored_to_link_ms) = cut_on(config, kind)?;
    let ping = ping_pong(kind, &s.dir, &PING_SIZES, PING_ROUND_TRIPS)?;
    Ok(SecurityRow {
        link: kind,
        reached_goal: summary["reached_goal"] == true,
        rtt_ms: summary["links"][0]["rtt_ms"].as_f64(),
        ct_mean_s: summary["ct_mean_s"].as_f64(),
        ct_p95_s: summary["ct_p95_s"].as_f64(),
        decision_path_ms: ms("routing"),
        frame_to_state_ms: ms("perception"),
        frame_coding_ms: summary["links"][0]["frame_coding_ms"].as_f64(),
        bytes_per_frame,
        bridge_cpu_vehicle_pct: bridge_cpu_pct(&run_dir.join("logs").join("bridge-to-ground.log")),
        bridge_cpu_ground_pct: bridge_cpu_pct(&ground_log),
        restored_to_link_ms,
        restored_to_reasoner_ms: cut.returned_ms,
        ping,
    })
}

/// Fly both links; `progress` hears what starts.
pub fn compare_links(
    config: &HostsBenchConfig,
    progress: &mut dyn FnMut(&str),
) -> Result<SecurityReport, HostsBenchError> {
    let _load = crate::flights::BusyProcesses::start(None, config.outside_load)?;
    let mut rows = Vec::new();
    for (k, kind) in [LinkKind::Tcp, LinkKind::Tls].into_iter().enumerate() {
        progress(&format!(
            "[{}/2] {}: the reasoner and the perception role on the ground host, then the link cut and restored",
            k + 1,
            match kind {
                LinkKind::Tls => "mutual TLS",
                LinkKind::Tcp => "plain TCP",
            }
        ));
        rows.push(row(config, kind)?);
    }
    Ok(SecurityReport {
        outside_load: config.outside_load,
        rows,
    })
}
