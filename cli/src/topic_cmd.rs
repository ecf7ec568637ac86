//! `aeris topic ...`: the topics of a running flight (like `ros2 topic`).

use crate::command::Execute;
use crate::inspect::{resolve_flight, tool_bus};
use aeris_runtime::bus::{self, FlightBus};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::raw;
use aeris_schemas::{FrameHeader, topics, with_payload_type};
use anyhow::{Result, bail};
use clap::{Args, Subcommand};
use core::time::Duration;
use std::process::ExitCode;

/// Arguments of `aeris topic`.
#[derive(Debug, Args)]
pub struct TopicArgs {
    #[command(subcommand)]
    command: TopicCommand,
}

#[derive(Debug, Subcommand)]
enum TopicCommand {
    /// List the services of running flights with their message types.
    List {
        /// Only this flight.
        #[arg(long)]
        flight: Option<String>,
    },
    /// Print the messages published on a topic.
    Echo {
        /// Topic, e.g. hub/setpoint (see `aeris topic list`).
        topic: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Stop after this many messages.
        #[arg(long, short = 'n')]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
    },
    /// Measure the publication rate of a topic.
    Hz {
        /// Topic, e.g. vehicle/telemetry.
        topic: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Measure for this many seconds.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
    },
}

impl Execute for TopicArgs {
    fn execute(self) -> Result<ExitCode> {
        match self.command {
            TopicCommand::List { flight } => topic_list(flight),
            TopicCommand::Echo {
                topic,
                flight,
                count,
                seconds,
            } => topic_echo(flight, &topic, count, seconds),
            TopicCommand::Hz {
                topic,
                flight,
                seconds,
            } => topic_hz(flight, &topic, seconds),
        }?;
        Ok(ExitCode::SUCCESS)
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
fn topic_list(flight: Option<String>) -> Result<()> {
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
fn topic_echo(flight: Option<String>, topic: &str, count: Option<u64>, seconds: f64) -> Result<()> {
    let flight = resolve_flight(flight)?;
    let bus = tool_bus(&flight, "echo")?;
    let n = each_sample(&bus, topic, count, seconds, |s| println!("{s}"))?;
    if n == 0 {
        eprintln!("no sample on `{topic}` within {seconds} s");
    }
    Ok(())
}

/// `aeris topic hz`.
fn topic_hz(flight: Option<String>, topic: &str, seconds: f64) -> Result<()> {
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
