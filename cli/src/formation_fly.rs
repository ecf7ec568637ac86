//! `aeris formation fly`: a flight of several built-in vehicles flown in formation by the
//! formation role (the flight is `aeris-flight`'s; this parses arguments and prints).

use crate::flight_print::FlightPrinter;
use aeris_flight::{Flight, FlightSummary, StopRule};
use aeris_orchestrator::workflow::{FORMATION_WORKFLOW_TOML, Workflow};
use anyhow::Context;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `aeris formation fly`.
#[derive(Debug, Args)]
pub struct FlyArgs {
    /// The instruction (default: the built-in one, "Four drones take off to 5 m in a line 3
    /// m apart, then form a V heading north, hold 10 s, then a circle of radius 6 m, and
    /// land.").
    pub instruction: Option<String>,
    /// Vehicles (1-7: each has a vehicle and a controller process, and a flight has at
    /// most 16 roles).
    #[arg(long, default_value_t = 4)]
    pub vehicles: u8,
    /// Who writes the program: `parser`, `qwen-coder`, `smollm2` or `gemma3`.
    #[arg(long, default_value = "parser")]
    pub variant: String,
    /// Flight name (default: generated).
    #[arg(long)]
    pub flight: Option<String>,
    /// Run directory: role specs, logs (default: a new directory under the system's
    /// temporary directory).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Record the flight into this MCAP file (default: RUN_DIR/flight.mcap): every
    /// vehicle's telemetry, setpoints, controller lease and link as `vK/TOPIC`, and every
    /// role's heartbeats. Its FILE is optional: give the instruction before it.
    #[arg(long, value_name = "FILE", num_args = 0..=1)]
    #[allow(clippy::option_option)]
    pub record: Option<Option<PathBuf>>,
    /// Print the flight's summary as one JSON line.
    #[arg(long)]
    pub json: bool,
}

/// Fly the formation; exit status 1 when it did not land every vehicle without collision.
pub fn fly(a: FlyArgs) -> anyhow::Result<ExitCode> {
    let workflow = Workflow::builtin_formation_with(a.vehicles, a.instruction.as_deref(), &a.variant)
        .with_context(|| {
            format!(
                "the formation flight with --vehicles {} --variant {} (workflows/formation.toml, {} bytes)",
                a.vehicles,
                a.variant,
                FORMATION_WORKFLOW_TOML.len()
            )
        })?;
    let mut flight = Flight::builder(workflow)
        .stop_when(StopRule::Landed)
        .language_offload_check(aeris_llm::offload_check);
    if let Some(name) = &a.flight {
        flight = flight.name(name);
    }
    if let Some(dir) = &a.run_dir {
        flight = flight.run_dir(dir);
    }
    if let Some(file) = &a.record {
        flight = flight.record(crate::run_cmd::record_path(file.as_deref())?);
    }
    let mut printer = FlightPrinter::new(true, "")?;
    let flight = flight.start()?;
    let name = flight.name().to_string();
    let logs = flight.run_dir().join("logs");
    let (outcome, _) = flight.watch(&mut printer)?;
    let summary = &outcome.summary;
    let landed = outcome.failure.is_none();
    if a.json {
        println!("{}", serde_json::to_string(summary)?);
    } else {
        print_summary(
            &name,
            summary,
            outcome.failure.as_ref().map(|f| f.to_string()),
        );
        println!(
            "  the program and every replan: {}",
            logs.join("formation.log").display()
        );
    }
    Ok(if landed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn print_summary(name: &str, summary: &FlightSummary, failure: Option<String>) {
    println!(
        "formation flight {name}: {} after {:.1} s",
        if failure.is_none() {
            "every vehicle landed"
        } else {
            "FAILED"
        },
        summary.duration_s
    );
    if let Some(f) = failure {
        println!("  reason: {f}");
    }
    if let Some(r) = &summary.recording {
        println!("{r}");
    }
    let Some(fleet) = &summary.fleet else {
        return;
    };
    match (fleet.min_separation_m, fleet.closest_pair) {
        (Some(d), Some((a, b))) => {
            println!("  closest two vehicles: {d:.2} m (vehicles {a} and {b}), by their telemetry")
        }
        _ => println!("  closest two vehicles: no telemetry"),
    }
    if let Some(t) = &fleet.formation {
        println!(
            "  formation: phase {} {}, {} vehicles in it ({} left, each replanned around), longest wait at a phase's end {:.1} s, {} setpoints ({} slots refused by the gate)",
            t.phase,
            t.state,
            t.in_formation,
            t.replans,
            t.settle_max_ms as f64 / 1e3,
            t.setpoints,
            t.refused_slots
        );
    }
    for v in &fleet.vehicles {
        println!(
            "  vehicle {}: controller ticks {} missed {}, setpoints refused {}, hold ticks {}, {}{}",
            v.vehicle,
            v.controller_ticks,
            v.controller_missed_ticks,
            v.setpoints_refused,
            v.hold_ticks,
            v.final_position.map_or_else(
                || "never heard".to_string(),
                |p| format!("last at [{:.1}, {:.1}, {:.1}]", p[0], p[1], p[2])
            ),
            if v.link_lost {
                ", link lost"
            } else if v.landed_after_flight {
                ", landed"
            } else {
                ""
            }
        );
    }
}
