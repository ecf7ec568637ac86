//! `aeris status` and `aeris topic ...`: looking at running flights from another process.

use aeris_runtime::bus::{self, FlightBus};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::raw;
use aeris_schemas::{FrameHeader, RoleStatus, topics, with_payload_type};
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

const MIB: f64 = 1024.0 * 1024.0;

/// `aeris status`.
pub fn status(flight: Option<String>, json: bool) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "status")?;
    let board = bus.read_status_board().with_context(|| {
        format!("flight `{flight}` has no supervisor status board (is its supervisor running?)")
    })?;
    let now = monotonic_ns();
    let roles: Vec<serde_json::Value> = board
        .roles()
        .iter()
        .map(|r| {
            let age_ms = (r.last_heartbeat_ns > 0)
                .then(|| now.saturating_sub(r.last_heartbeat_ns) as f64 / 1e6);
            // a role on another host runs on an executor `HOST:EXECUTOR`; its pid is that
            // host's, its memory not readable here
            let executor = r.executor.as_str_lossy();
            let memory = (r.pid != 0 && !executor.contains(':'))
                .then(|| aeris_orchestrator::executors::process_memory(r.pid))
                .flatten();
            serde_json::json!({
                "name": r.name.as_str_lossy(),
                "pid": r.pid,
                "cpus": r.cpus.as_str_lossy(),
                "variant": r.variant.as_str_lossy(),
                "status": RoleStatus::from_u8(r.status).map(|s| s.name()).unwrap_or("no-heartbeat"),
                "heartbeat_age_ms": age_ms,
                "heartbeats": r.heartbeats,
                "latency_p50_ms": r.latency_ms[0],
                "latency_p95_ms": r.latency_ms[1],
                "latency_p99_ms": r.latency_ms[2],
                "restarts": r.restarts,
                "heartbeat_gaps": r.heartbeat_gaps,
                "executor": r.executor.as_str_lossy(),
                "budget_ms": (r.budget_ms > 0.0).then_some(r.budget_ms),
                "migrations": r.migrations,
                "stalls": r.stalls,
                "binding": r.binding.as_str_lossy(),
                "rss_mib": memory.map(|m| m.rss_bytes as f64 / MIB),
                "pss_mib": memory.and_then(|m| m.pss_bytes).map(|b| b as f64 / MIB),
            })
        })
        .collect();
    let links: Vec<serde_json::Value> = board
        .links()
        .iter()
        .map(|l| {
            let measured = l.probes > 0;
            serde_json::json!({
                "host": l.host.as_str_lossy(),
                "connected": measured.then_some(l.connected == 1),
                "rtt_ms": l.rtt_ms(),
                "rtt_last_ms": (l.answered > 0).then(|| l.rtt_ns as f64 / 1e6),
                "loss": measured.then(|| l.loss()),
                "probes": l.probes,
                "answered": l.answered,
                "clock_offset_ms": (l.answered > 0).then(|| l.clock_offset_ns as f64 / 1e6),
                "busy_cores": (l.cpus > 0).then(|| l.busy_cores()),
                "cpus": l.cpus,
                "frame_coding_ms": (l.frame_coding_ns > 0).then(|| l.frame_coding_ns as f64 / 1e6),
            })
        })
        .collect();
    let sum = |key: &str| -> Option<f64> {
        let known: Vec<f64> = roles.iter().filter_map(|r| r[key].as_f64()).collect();
        (!known.is_empty()).then(|| known.iter().sum())
    };
    let (rss_total, pss_total) = (sum("rss_mib"), sum("pss_mib"));
    if json {
        let out = serde_json::json!({
            "memory": {"rss_total_mib": rss_total, "pss_total_mib": pss_total},
            "flight": flight,
            "supervisor_pid": board.supervisor_pid,
            "active_step": board.active_step,
            "subgoals": board.subgoals,
            "distance_to_goal_m": (board.distance_to_goal_m >= 0.0).then_some(board.distance_to_goal_m),
            "ct_mean_s": board.ct_mean_s,
            "migrations": board.migrations,
            "roles": roles,
            "links": links,
        });
        println!("{out}");
        return Ok(());
    }
    println!(
        "flight {flight}  supervisor pid {}  step {}/{}  distance to goal {}  CT mean {:.3} s  migrations {}",
        board.supervisor_pid,
        board.active_step,
        board.subgoals,
        if board.distance_to_goal_m >= 0.0 {
            format!("{:.1} m", board.distance_to_goal_m)
        } else {
            "?".into()
        },
        board.ct_mean_s,
        board.migrations
    );
    // the role column fits the longest name (`controller-standby`)
    let w = roles
        .iter()
        .filter_map(|r| r["name"].as_str().map(str::len))
        .max()
        .unwrap_or(0)
        .max(12);
    println!(
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
    );
    for r in &roles {
        let age = r["heartbeat_age_ms"]
            .as_f64()
            .map(|a| format!("{a:.0} ms"))
            .unwrap_or_else(|| "-".into());
        println!(
            "{:<w$} {:>7} {:<12} {:<6} {:<15} {:<12} {:>9} {:>9.3} {:>9.3} {:>9} {:>8} {:>5} {:>6} {:>7}",
            r["name"].as_str().unwrap_or(""),
            r["pid"],
            r["executor"].as_str().unwrap_or(""),
            r["cpus"].as_str().unwrap_or(""),
            r["variant"].as_str().unwrap_or(""),
            r["status"].as_str().unwrap_or(""),
            age,
            r["latency_p50_ms"].as_f64().unwrap_or(0.0),
            r["latency_p95_ms"].as_f64().unwrap_or(0.0),
            r["budget_ms"]
                .as_f64()
                .map(|b| format!("{b:.0}"))
                .unwrap_or_else(|| "-".into()),
            r["restarts"].as_u64().unwrap_or(0),
            r["migrations"].as_u64().unwrap_or(0),
            r["stalls"].as_u64().unwrap_or(0),
            r["pss_mib"]
                .as_f64()
                .or(r["rss_mib"].as_f64())
                .map(|m| format!("{m:.0}"))
                .unwrap_or_else(|| "-".into())
        );
    }
    if let Some(rss) = rss_total {
        match pss_total {
            Some(pss) => println!(
                "memory of the roles on this host: {pss:.0} MiB (PSS: shared pages divided among them; RSS summed {rss:.0} MiB)"
            ),
            None => println!("memory of the roles on this host: RSS summed {rss:.0} MiB"),
        }
    }
    println!("binding:");
    for r in &roles {
        println!(
            "  {:<w$} {}",
            r["name"].as_str().unwrap_or(""),
            r["binding"].as_str().unwrap_or("")
        );
    }
    if !links.is_empty() {
        print_links(&links);
    }
    Ok(())
}

/// The links to other hosts (`aeris status`).
fn print_links(links: &[serde_json::Value]) {
    let ms = |v: &serde_json::Value, digits: usize| {
        v.as_f64()
            .map(|x| format!("{x:.digits$}"))
            .unwrap_or_else(|| "-".into())
    };
    println!(
        "{:<12} {:<9} {:>8} {:>8} {:>6} {:>13} {:>11} {:>12}",
        "LINK",
        "CONNECTED",
        "RTT ms",
        "LAST ms",
        "LOSS",
        "CLOCK OFF ms",
        "BUSY CORES",
        "FRAME ENC ms"
    );
    for l in links {
        let connected = match l["connected"].as_bool() {
            Some(true) => "yes",
            Some(false) => "no",
            None => "-",
        };
        let loss = l["loss"]
            .as_f64()
            .map(|x| format!("{:.0} %", x * 100.0))
            .unwrap_or_else(|| "-".into());
        let busy = match (l["busy_cores"].as_f64(), l["cpus"].as_u64()) {
            (Some(b), Some(c)) => format!("{b:.2}/{c}"),
            _ => "-".into(),
        };
        println!(
            "{:<12} {:<9} {:>8} {:>8} {:>6} {:>13} {:>11} {:>12}",
            l["host"].as_str().unwrap_or(""),
            connected,
            ms(&l["rtt_ms"], 3),
            ms(&l["rtt_last_ms"], 3),
            loss,
            ms(&l["clock_offset_ms"], 3),
            busy,
            ms(&l["frame_coding_ms"], 2),
        );
    }
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
    let stage_name = |r: &aeris_schemas::SupervisorReply| match r.stage() {
        Some(aeris_schemas::ReplyStage::Started) => "started",
        Some(aeris_schemas::ReplyStage::Ready) => "ready",
        Some(aeris_schemas::ReplyStage::Done) => "done",
        Some(aeris_schemas::ReplyStage::Failed) => "failed",
        None => "unknown",
    };
    if json {
        let steps: Vec<serde_json::Value> = replies
            .iter()
            .map(|r| {
                serde_json::json!({
                    "stage": stage_name(r),
                    "elapsed_ms": r.elapsed_ms,
                    "old_pid": r.old_pid,
                    "new_pid": r.new_pid,
                    "new_instance": r.new_instance,
                    "message": r.message.as_str_lossy(),
                })
            })
            .collect();
        let (ok, error) = match &outcome {
            Ok(_) => (true, None),
            Err(e) => (false, Some(e.to_string())),
        };
        println!(
            "{}",
            serde_json::json!({
                "flight": flight, "role": role, "variant": variant,
                "ok": ok, "error": error, "steps": steps,
            })
        );
    }
    let done = outcome.with_context(|| {
        format!("swap of role `{role}` to `{variant}` in flight `{flight}` failed")
    })?;
    if !json {
        println!(
            "role `{role}` now runs `{variant}` as pid {} (instance {}), old pid {} stopped, {} ms",
            done.new_pid, done.new_instance, done.old_pid, done.elapsed_ms
        );
    }
    Ok(())
}

/// `aeris migrate ROLE TARGET`: live on the flight's host, make-before-break between hosts
/// (each stage printed as it comes).
pub fn migrate(flight: Option<String>, role: &str, target: &str, json: bool) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "migrate")?;
    let mut steps = Vec::new();
    let outcome = aeris_orchestrator::control::request_migrate(&bus, role, target, |r| {
        let stage = r.stage();
        // the final reply is printed below; a refusal is the error
        if !json
            && !matches!(
                stage,
                Some(aeris_schemas::ReplyStage::Failed | aeris_schemas::ReplyStage::Done)
            )
        {
            eprintln!("[{:>6} ms] {}", r.elapsed_ms, r.message.as_str_lossy());
        }
        steps.push(serde_json::json!({
            "elapsed_ms": r.elapsed_ms,
            "old_pid": r.old_pid,
            "new_pid": r.new_pid,
            "message": r.message.as_str_lossy(),
        }));
    });
    if json {
        let (ok, error, message, pid, elapsed_ms) = match &outcome {
            Ok(r) => (
                true,
                None,
                r.message.as_str_lossy().to_string(),
                r.new_pid,
                r.elapsed_ms,
            ),
            Err(e) => (false, Some(e.to_string()), String::new(), 0, 0),
        };
        println!(
            "{}",
            serde_json::json!({
                "flight": flight, "role": role, "target": target, "ok": ok, "error": error,
                "pid": pid, "elapsed_ms": elapsed_ms, "message": message, "steps": steps,
            })
        );
    }
    let done = outcome.with_context(|| {
        format!("moving role `{role}` to `{target}` in flight `{flight}` failed")
    })?;
    if !json {
        println!("{} [{} ms]", done.message.as_str_lossy(), done.elapsed_ms);
    }
    Ok(())
}
