//! `aeris status` and `aeris topic ...`: looking at running flights from another process.

use aeris_orchestrator::control::{MigrateReport, SwapReport};
use aeris_runtime::bus::{self, FlightBus};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::raw;
use aeris_schemas::{FrameHeader, topics, with_payload_type};
use anyhow::{Context, Result, bail};
use core::time::Duration;

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

/// `aeris status`.
pub fn status(flight: Option<String>, json: bool) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "status")?;
    let report = aeris_flight::status_report::FlightStatusReport::read(&bus, &flight)?;
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{report}");
    }
    Ok(())
}

fn type_of(topic: &str) -> &'static str {
    match topics::info(topic) {
        Some(info) if info.payload == Some(topics::Payload::Frame) => "[u8] + FrameHeader",
        Some(info) => info.message_type(),
        None if topic == "supervisor" => "SupervisorStatus (blackboard)",
        None => "?",
    }
}

/// `aeris topic list`.
pub fn topic_list(flight: Option<String>) -> Result<()> {
    let flights = match flight {
        Some(f) => vec![f],
        None => {
            bus::cleanup_dead_nodes();
            bus::list_flights()
        }
    };
    if flights.is_empty() {
        bail!("no flight is running on this host (start one with `aeris run`)");
    }
    for f in flights {
        for t in bus::list_flight_services(&f) {
            println!("{:<60} {}", bus::service_name(&f, &t), type_of(&t));
        }
    }
    Ok(())
}

/// Calls `on_sample` for every sample of `topic` until `count` samples or `seconds` passed.
fn each_sample(
    bus: &FlightBus,
    topic: &str,
    count: Option<u64>,
    seconds: f64,
    mut on_sample: impl FnMut(String),
) -> Result<u64> {
    if topics::payload_of(topic).is_none() {
        bail!(
            "unknown topic `{topic}`; known topics: {} (in a flight of several vehicles, \
             vehicle K's are vK/TOPIC)",
            topics::ALL.join(", ")
        );
    }
    // `v2/vehicle/telemetry`: vehicle 2's telemetry in a flight of several vehicles
    let sub = raw::raw_subscriber(bus, topic)?;
    let payload = topics::payload_of(topic);
    let next = || -> Result<Option<String>> {
        let mut text = None;
        sub.next_raw(&mut |bytes, pixels, _| {
            text = Some(match payload {
                Some(topics::Payload::Frame) => match raw::read::<FrameHeader>(bytes) {
                    Some(h) => format!("{h:?} bytes={}", pixels.len()),
                    None => format!("{} bytes", bytes.len()),
                },
                Some(p) => with_payload_type!(p, T => match raw::read::<T>(bytes) {
                    Some(v) => format!("{v:?}"),
                    None => format!("{} bytes", bytes.len()),
                }),
                None => format!("{} bytes", bytes.len()),
            });
        })?;
        Ok(text)
    };
    let end = monotonic_ns().saturating_add((seconds.max(0.0) * 1e9) as u64);
    let mut n = 0;
    while monotonic_ns() < end && count.is_none_or(|c| n < c) {
        match next()? {
            Some(s) => {
                n += 1;
                on_sample(s);
            }
            None => std::thread::sleep(Duration::from_millis(2)),
        }
    }
    Ok(n)
}

/// `aeris topic echo`.
pub fn topic_echo(
    flight: Option<String>,
    topic: &str,
    count: Option<u64>,
    seconds: f64,
) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "echo")?;
    let n = each_sample(&bus, topic, count, seconds, |s| println!("{s}"))?;
    if n == 0 {
        eprintln!("no sample on `{topic}` within {seconds} s");
    }
    Ok(())
}

/// `aeris topic hz`.
pub fn topic_hz(flight: Option<String>, topic: &str, seconds: f64) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "hz")?;
    let start = monotonic_ns();
    let mut window_start = start;
    let mut in_window = 0u64;
    let total = each_sample(&bus, topic, None, seconds, |_| {
        in_window += 1;
        let now = monotonic_ns();
        if now - window_start >= 1_000_000_000 {
            let dt = (now - window_start) as f64 * 1e-9;
            println!(
                "{topic}: {:.2} Hz ({in_window} samples in {dt:.2} s)",
                in_window as f64 / dt
            );
            window_start = now;
            in_window = 0;
        }
    })?;
    let dt = (monotonic_ns() - start) as f64 * 1e-9;
    println!(
        "{topic}: average {:.2} Hz over {dt:.1} s ({total} samples)",
        total as f64 / dt
    );
    Ok(())
}

/// `aeris swap ROLE VARIANT`: hot-swap a role of a running flight, make-before-break, and
/// print each step as the supervisor reports it.
pub fn swap(
    flight: Option<String>,
    role: &str,
    variant: &str,
    timeout_s: Option<f64>,
    json: bool,
) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "swap")?;
    let timeout = match timeout_s {
        Some(s) if s.is_finite() && s > 0.0 => Duration::from_secs_f64(s),
        Some(s) => bail!("--timeout must be a positive number of seconds, got {s}"),
        None => Duration::ZERO,
    };
    let mut replies = Vec::new();
    let outcome = aeris_orchestrator::control::request_swap(&bus, role, variant, timeout, |r| {
        // a refusal or rollback is the error printed below
        if !json && r.stage() != Some(aeris_schemas::ReplyStage::Failed) {
            eprintln!("[{:>6} ms] {}", r.elapsed_ms, r.message.as_str_lossy());
        }
        replies.push(*r);
    });
    let report = SwapReport::new(&flight, role, variant, &replies, &outcome);
    if json {
        println!("{}", serde_json::to_string(&report)?);
    }
    outcome.with_context(|| {
        format!("swap of role `{role}` to `{variant}` in flight `{flight}` failed")
    })?;
    if !json {
        println!("{report}");
    }
    Ok(())
}

/// `aeris migrate ROLE TARGET`: live on the flight's host, make-before-break between hosts
/// (each stage printed as it comes).
pub fn migrate(flight: Option<String>, role: &str, target: &str, json: bool) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "migrate")?;
    let mut replies = Vec::new();
    let outcome = aeris_orchestrator::control::request_migrate(&bus, role, target, |r| {
        // the final reply is printed below; a refusal is the error
        if !json
            && !matches!(
                r.stage(),
                Some(aeris_schemas::ReplyStage::Failed | aeris_schemas::ReplyStage::Done)
            )
        {
            eprintln!("[{:>6} ms] {}", r.elapsed_ms, r.message.as_str_lossy());
        }
        replies.push(*r);
    });
    let report = MigrateReport::new(&flight, role, target, &replies, &outcome);
    if json {
        println!("{}", serde_json::to_string(&report)?);
    }
    outcome.with_context(|| {
        format!("moving role `{role}` to `{target}` in flight `{flight}` failed")
    })?;
    if !json {
        println!("{report}");
    }
    Ok(())
}
