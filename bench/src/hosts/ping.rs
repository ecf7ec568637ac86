//! The link alone, without a flight: a round trip through an agent's router, on this
//! machine's loopback, over mutual TLS (with the agent's access rules) or plain TCP. Two
//! client sessions, the flight's host and the other host, as a flight's bridges connect:
//! the first publishes a message, the second sends it straight back, with the bridges'
//! publisher settings (a decision-sized message express at interactive priority, a
//! frame-sized one at data priority). Each way crosses two links (client → router →
//! client), as a decision or a frame between two hosts does.

use super::{HostsBenchError, LinkKind};
use aeris_hosts::access::agent_access_control;
use aeris_hosts::keys::Identity;
use aeris_hosts::session::{LinkSecurity, Reach, open_client, open_router};
use serde::Serialize;
use std::path::Path;
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::qos::{CongestionControl, Priority};

/// Round trips of one message size on one link.
#[derive(Debug, Clone, Serialize)]
pub struct PingFigures {
    /// The message's size (bytes).
    pub bytes: usize,
    /// Round trips measured.
    pub round_trips: usize,
    /// Median round trip (µs).
    pub p50_us: f64,
    /// 95th percentile (µs).
    pub p95_us: f64,
    /// Mean (µs).
    pub mean_us: f64,
}

/// How long one round trip may take before the ping-pong fails.
const ROUND_TRIP_BOUND: Duration = Duration::from_secs(5);
/// Round trips before measuring (the links' and sessions' first messages).
const WARM_UP: usize = 50;

fn failed(what: impl std::fmt::Display) -> HostsBenchError {
    HostsBenchError::Flight(format!("the link ping-pong: {what}"))
}

/// The securities of the router (ground), the flight host's client and the other host's
/// client on `kind`, keys made in `dir`.
fn securities(
    kind: LinkKind,
    dir: &Path,
) -> Result<(LinkSecurity, LinkSecurity, LinkSecurity), HostsBenchError> {
    match kind {
        LinkKind::Tcp => Ok((
            LinkSecurity::Insecure,
            LinkSecurity::Insecure,
            LinkSecurity::Insecure,
        )),
        LinkKind::Tls => {
            let store = dir.join("ping-keys");
            aeris_hosts::keys::init(&store, 1)?;
            let id = |host: &str| -> Result<LinkSecurity, HostsBenchError> {
                let issued = aeris_hosts::keys::issue(&store, host, &[], 1, false)?;
                Ok(LinkSecurity::Tls(
                    Identity::load(&issued.dir).map_err(failed)?,
                ))
            };
            let ground = id("ground")?;
            Ok((ground.clone(), id("vehicle")?, ground))
        }
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// `round_trips` round trips of each of `sizes` (bytes) on a link of `kind`.
pub(super) fn ping_pong(
    kind: LinkKind,
    dir: &Path,
    sizes: &[usize],
    round_trips: usize,
) -> Result<Vec<PingFigures>, HostsBenchError> {
    let (router_security, here, there) = securities(kind, dir)?;
    let port = std::net::TcpListener::bind(("127.0.0.1", 0))
        .and_then(|l| l.local_addr())
        .map_err(failed)?
        .port();
    let scheme = match kind {
        LinkKind::Tls => "tls",
        LinkKind::Tcp => "tcp",
    };
    let endpoint = format!("{scheme}/127.0.0.1:{port}");
    let access = match kind {
        LinkKind::Tls => Some(agent_access_control("ground", &["vehicle".to_string()])),
        LinkKind::Tcp => None,
    };
    let lease = Duration::from_secs(1);
    let _router = open_router(
        std::slice::from_ref(&endpoint),
        lease,
        &router_security,
        access.as_ref(),
    )
    .map_err(failed)?;
    let reach = Reach::Within(Duration::from_secs(5));
    let vehicle = open_client(&endpoint, reach, lease, &here).map_err(failed)?;
    let ground = open_client(&endpoint, reach, lease, &there).map_err(failed)?;
    let mut out = Vec::new();
    for (k, &bytes) in sizes.iter().enumerate() {
        let (priority, express) = if bytes > 1024 {
            (Priority::Data, false)
        } else {
            (Priority::InteractiveHigh, true)
        };
        let ping_key = format!("aeris/data/ping-pong/ping{k}");
        let pong_key = format!("aeris/data/ping-pong/pong{k}");
        let pong = ground
            .declare_publisher(pong_key.clone())
            .congestion_control(CongestionControl::Block)
            .priority(priority)
            .express(express)
            .wait()
            .map_err(failed)?;
        let _echo = ground
            .declare_subscriber(ping_key.clone())
            .callback(move |s| {
                let _ = pong.put(s.payload().clone()).wait();
            })
            .wait()
            .map_err(failed)?;
        let pongs = vehicle
            .declare_subscriber(pong_key)
            .wait()
            .map_err(failed)?;
        let ping = vehicle
            .declare_publisher(ping_key)
            .congestion_control(CongestionControl::Block)
            .priority(priority)
            .express(express)
            .wait()
            .map_err(failed)?;
        let payload = vec![0x5au8; bytes];
        // the echo's subscription reaches the router asynchronously: ping until answered
        let started = Instant::now();
        loop {
            ping.put(payload.clone()).wait().map_err(failed)?;
            if pongs
                .recv_timeout(Duration::from_millis(100))
                .map_err(failed)?
                .is_some()
            {
                break;
            }
            if started.elapsed() > ROUND_TRIP_BOUND {
                return Err(failed(format!("no answer over {endpoint}")));
            }
        }
        while pongs.try_recv().map_err(failed)?.is_some() {}
        let mut rtts = Vec::with_capacity(round_trips);
        for i in 0..WARM_UP + round_trips {
            let t0 = Instant::now();
            ping.put(payload.clone()).wait().map_err(failed)?;
            pongs
                .recv_timeout(ROUND_TRIP_BOUND)
                .map_err(failed)?
                .ok_or_else(|| failed(format!("a round trip over {endpoint} took over 5 s")))?;
            if i >= WARM_UP {
                rtts.push(t0.elapsed().as_secs_f64() * 1e6);
            }
        }
        let mean_us = rtts.iter().sum::<f64>() / rtts.len().max(1) as f64;
        rtts.sort_by(f64::total_cmp);
        out.push(PingFigures {
            bytes,
            round_trips,
            p50_us: percentile(&rtts, 0.5),
            p95_us: percentile(&rtts, 0.95),
            mean_us,
        });
    }
    Ok(out)
}
