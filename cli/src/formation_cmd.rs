//! `aeris formation`: formation programs from instructions (the library is
//! `aeris-formation`; this parses arguments and prints).

use aeris_formation::{
    Dynamics, PlanOutcome, ground_row, parse_instruction, plan_program, repair_by_rule,
};
use aeris_schemas::{FormationLimits, FormationPhase, FormationProgram, PhaseKind, ShapeKind};
use anyhow::Context;
use clap::{Args, Subcommand};
use std::process::ExitCode;
use std::time::Instant;

/// `aeris formation` subcommands.
#[derive(Debug, Subcommand)]
pub enum FormationCommand {
    /// Turn an instruction into a formation program with the deterministic parser, fly it
    /// in simulation (every vehicle, every transition: separation, geofence, altitude,
    /// duration) and repair it on failure; print the program and the outcome (accepted,
    /// repaired after k attempts, or refused with the diagnosis: exit status 1). The
    /// vehicles start on the ground in a row along east, centred on the origin.
    Plan(PlanArgs),
}

/// Arguments of `aeris formation plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// The instruction, e.g. "four drones take off to 5 m in a line 3 m apart, then form a
    /// V heading north, hold 10 s, then a circle of radius 6 m, and land".
    pub instruction: String,
    /// Vehicles the flight has (1-8).
    #[arg(long, default_value_t = 4)]
    pub vehicles: u8,
    /// The closest two vehicles may come (m).
    #[arg(long, value_name = "M", default_value_t = 2.0)]
    pub min_separation: f32,
    /// Distance between the vehicles on the ground at the start (m; default: twice the
    /// minimum separation, at least 4 m).
    #[arg(long, value_name = "M")]
    pub start_spacing: Option<f32>,
    /// Repairs tried before the program is refused.
    #[arg(long, value_name = "K", default_value_t = 3)]
    pub max_repairs: usize,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Run an `aeris formation` command.
pub fn run(command: FormationCommand) -> anyhow::Result<ExitCode> {
    match command {
        FormationCommand::Plan(args) => plan(args),
    }
}

fn plan(a: PlanArgs) -> anyhow::Result<ExitCode> {
    let limits = FormationLimits {
        vehicles: a.vehicles,
        min_separation_m: a.min_separation,
        ..FormationLimits::default()
    };
    if !limits.is_coherent() {
        anyhow::bail!(
            "--vehicles {} --min-separation {}: vehicles must be 1-8 and the separation a positive number up to {} m",
            a.vehicles,
            a.min_separation,
            limits.max_spacing_m
        );
    }
    let t = Instant::now();
    let program = parse_instruction(&a.instruction, &limits).context("parsing the instruction")?;
    let parse_us = t.elapsed().as_secs_f64() * 1e6;
    let spacing = a.start_spacing.unwrap_or((2.0 * a.min_separation).max(4.0));
    let starts = ground_row(program.vehicles.max(a.vehicles) as usize, spacing);
    let t = Instant::now();
    let outcome = plan_program(
        &program,
        &starts,
        &limits,
        &Dynamics::default(),
        a.max_repairs,
        |p, problem| repair_by_rule(p, problem, &limits),
    )
    .context("checking the program in simulation")?;
    let plan_us = t.elapsed().as_secs_f64() * 1e6;
    let (flown, accepted) = match &outcome {
        PlanOutcome::Accepted {
            program, report, ..
        } => (Some((**program, report.clone())), true),
        PlanOutcome::Refused { .. } => (None, false),
    };
    let repaired = match &outcome {
        PlanOutcome::Accepted { repaired, .. } | PlanOutcome::Refused { repaired, .. } => {
            repaired.iter().map(|p| p.to_string()).collect::<Vec<_>>()
        }
    };
    if a.json {
        let json = serde_json::json!({
            "instruction": a.instruction,
            "outcome": match &outcome {
                PlanOutcome::Accepted { repaired, .. } if repaired.is_empty() => "accepted",
                PlanOutcome::Accepted { .. } => "repaired",
                PlanOutcome::Refused { .. } => "refused",
            },
            "summary": outcome.summary(),
            "repaired": repaired,
            "vehicles": flown.as_ref().map_or(program.vehicles, |f| f.0.vehicles),
            "phases": flown.as_ref().map_or_else(|| phases_json(&program), |f| phases_json(&f.0)),
            "duration_s": flown.as_ref().map(|f| f.1.duration_s),
            "min_separation_m": flown.as_ref().map(|f| f.1.min_separation_m),
            "parse_us": parse_us,
            "plan_us": plan_us,
        });
        println!("{json}");
    } else {
        let shown = flown.as_ref().map_or(program, |f| f.0);
        println!(
            "formation program: {} vehicles, {} phases",
            shown.vehicles, shown.phase_count
        );
        for (i, p) in shown.phases().iter().enumerate() {
            println!("  {:>2} {}", i + 1, describe(p));
        }
        println!("outcome: {}", outcome.summary());
        for (k, r) in repaired.iter().enumerate() {
            println!("  problem {} (repaired): {r}", k + 1);
        }
        if let Some((_, report)) = &flown {
            println!(
                "simulated: {:.1} s, closest two vehicles {:.2} m (minimum {:.1} m)",
                report.duration_s, report.min_separation_m, limits.min_separation_m
            );
        }
        println!("parse {parse_us:.0} µs, simulate and repair {plan_us:.0} µs");
    }
    if accepted {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("aeris: formation {}", outcome.summary());
        Ok(ExitCode::FAILURE)
    }
}

/// One phase in words.
fn describe(p: &FormationPhase) -> String {
    let kind = PhaseKind::from_u8(p.kind);
    match kind {
        Some(PhaseKind::TakeOff) => format!("take off to {:.1} m", p.height_m),
        Some(PhaseKind::Assume) => format!(
            "{} {:.1} m {}, heading {:.0}°, centre N {:.1} E {:.1}, at {:.1} m",
            ShapeKind::from_u8(p.shape).map_or("?", ShapeKind::name),
            p.spacing_m,
            if p.shape == ShapeKind::Circle as u8 {
                "radius"
            } else {
                "apart"
            },
            p.heading_rad.to_degrees(),
            p.centre[0],
            p.centre[1],
            p.height_m
        ),
        Some(PhaseKind::Hold) => format!("hold {:.1} s", p.hold_s),
        Some(PhaseKind::Move) => format!(
            "move the centre to N {:.1} E {:.1} at {:.1} m/s",
            p.centre[0], p.centre[1], p.speed_mps
        ),
        Some(PhaseKind::Land) => "land".into(),
        None => format!("unknown phase kind {}", p.kind),
    }
}

fn phases_json(program: &FormationProgram) -> serde_json::Value {
    program
        .phases()
        .iter()
        .map(|p| {
            serde_json::json!({
                "kind": PhaseKind::from_u8(p.kind).map_or("?", PhaseKind::name),
                "shape": ShapeKind::from_u8(p.shape).map(ShapeKind::name),
                "height_m": p.height_m,
                "spacing_m": p.spacing_m,
                "heading_deg": p.heading_rad.to_degrees(),
                "hold_s": p.hold_s,
                "speed_mps": p.speed_mps,
                "centre": p.centre,
            })
        })
        .collect()
}
