//! `aeris formation`: formation programs from instructions (the library is
//! `aeris-formation`; this parses arguments and prints).

use aeris_formation::{ParserWriter, PlanOutcome, ProgramWriter, ground_row, plan_instruction};
use aeris_llm::FormationWriter;
use aeris_schemas::{FormationLimits, FormationPhase, FormationProgram, PhaseKind, ShapeKind};
use anyhow::Context;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `aeris formation`.
#[derive(Debug, clap::Args)]
pub struct FormationArgs {
    #[command(subcommand)]
    command: FormationCommand,
}

/// `aeris formation` subcommands.
#[derive(Debug, Subcommand)]
pub enum FormationCommand {
    /// Turn an instruction into a formation program (the deterministic parser, or a language
    /// model decoding under the program's grammar: --variant), check it in simulation (every
    /// transition exactly: separation, geofence, altitude, duration; then flown by the
    /// built-in multirotor model at 50 Hz: separation as flown, every vehicle reaching every
    /// slot) and repair it on failure; print the program and the outcome (accepted, repaired
    /// after k attempts, or refused with the diagnosis: exit status 1). The vehicles start on
    /// the ground in a row along east, centred on the origin.
    Plan(PlanArgs),
    /// Fly a formation: built-in simulated vehicles (each its own vehicle and controller
    /// process, MAVLink system ids 1..N, services under FLIGHT/v1 .. FLIGHT/vN) and the
    /// formation role, which writes the program (--variant), checks and repairs it, then
    /// flies every vehicle's slot at 50 Hz through its controller, waiting at each phase's
    /// end until all are within 0.5 m; a vehicle lost in flight (link silent 1 s) or stuck
    /// off its slot is planned around. Ends when every vehicle has landed (exit status 0),
    /// on a collision (two vehicles under 1 m) or when the program is refused (1).
    #[cfg(feature = "sim")]
    Fly(crate::formation_fly::FlyArgs),
    /// Give the formation in flight a new instruction ("form a circle of radius 8 m, hold
    /// 5 s, and land"): its formation role writes it for the vehicles in the air (a
    /// take-off to their height put first when it has none), checks and repairs it, and
    /// flies it at once without landing; prints the answer (accepted, repaired: what is
    /// flown now; refused: why, and the formation flies on as before: exit status 1).
    Say(SayArgs),
}

/// Arguments of `aeris formation say`.
#[derive(Debug, Args)]
pub struct SayArgs {
    /// The new instruction.
    pub instruction: String,
    /// The flight (default: the only one running).
    #[arg(long)]
    pub flight: Option<String>,
    /// How long to wait for the answer (s).
    #[arg(long, value_name = "SECONDS", default_value_t = 60.0)]
    pub timeout: f64,
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
    /// Who writes the program: `parser` (deterministic; repairs by rule), or a provisioned
    /// language model, `qwen-coder` (Qwen2.5-Coder 0.5B), `smollm2` or `gemma3` (repairs by
    /// rewriting the program from the problem's text).
    #[arg(long, default_value = "parser")]
    pub variant: String,
    /// Model cache (default: $AERIS_MODELS or ~/.cache/aeris/models).
    #[arg(long, value_name = "DIR")]
    pub models_dir: Option<PathBuf>,
    /// CPU threads a language model evaluates on.
    #[arg(long, default_value_t = 2)]
    pub threads: i32,
    /// Write the simulated flight of the accepted program to DIR/formation.json (draw it
    /// with `aeris plot formation --run DIR`).
    #[arg(long, value_name = "DIR")]
    pub run: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Run an `aeris formation` command.
pub fn run(command: FormationCommand) -> anyhow::Result<ExitCode> {
    match command {
        FormationCommand::Plan(args) => plan(args),
        #[cfg(feature = "sim")]
        FormationCommand::Fly(args) => crate::formation_fly::fly(args),
        FormationCommand::Say(args) => say(args),
    }
}

fn say(a: SayArgs) -> anyhow::Result<ExitCode> {
    if !(a.timeout.is_finite() && a.timeout > 0.0) {
        anyhow::bail!("--timeout {}: give a positive number of seconds", a.timeout);
    }
    let flight = crate::inspect::resolve_flight(a.flight)?;
    let answer = aeris_flight::say(
        &flight,
        &a.instruction,
        std::time::Duration::from_secs_f64(a.timeout),
    )?;
    println!("formation {flight}: {}", answer.text);
    Ok(match answer.outcome {
        aeris_schemas::SayOutcome::Refused => ExitCode::FAILURE,
        _ => ExitCode::SUCCESS,
    })
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
    if a.variant == "parser" {
        return plan_with(&mut ParserWriter, &a, &limits);
    }
    let file = aeris_llm::variant_model(&a.variant).with_context(|| {
        format!(
            "--variant {}: the formation variants are parser, qwen-coder, smollm2 and gemma3",
            a.variant
        )
    })?;
    let store = aeris_models::ModelStore::open(a.models_dir.as_deref())?;
    eprintln!("formation: loading {} ({file})", a.variant);
    let mut writer = FormationWriter::load(&store, &a.variant, file, a.threads)
        .with_context(|| format!("loading the `{}` formation variant", a.variant))?;
    plan_with(&mut writer, &a, &limits)
}

/// Plan `a.instruction` with `writer` and print the program and its outcome.
fn plan_with<W: ProgramWriter>(
    writer: &mut W,
    a: &PlanArgs,
    limits: &FormationLimits,
) -> anyhow::Result<ExitCode> {
    let spacing = a.start_spacing.unwrap_or((2.0 * a.min_separation).max(4.0));
    let starts = ground_row(a.vehicles as usize, spacing);
    let planned = plan_instruction(
        writer,
        &a.instruction,
        &starts,
        limits,
        &aeris_bench::formation::simulation(),
        a.max_repairs,
    )?;
    let write_ms = planned.write_time.as_secs_f64() * 1e3;
    let plan_ms = planned.plan_time.as_secs_f64() * 1e3;
    let outcome = &planned.outcome;
    let (flown, accepted) = match outcome {
        PlanOutcome::Accepted {
            program,
            report,
            flown,
            ..
        } => (Some((**program, report.clone(), flown.clone())), true),
        PlanOutcome::Refused { .. } => (None, false),
    };
    let repaired = match outcome {
        PlanOutcome::Accepted { repaired, .. } | PlanOutcome::Refused { repaired, .. } => {
            repaired.iter().map(|p| p.to_string()).collect::<Vec<_>>()
        }
    };
    let program = planned.written;
    if a.json {
        let json = serde_json::json!({
            "instruction": a.instruction,
            "variant": writer.name(),
            "outcome": match outcome {
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
            "flown": flown.as_ref().and_then(|f| f.2.as_ref()).map(|f| serde_json::json!({
                "duration_s": f.duration_s,
                "min_separation_m": f.closest.map(|c| c.distance_m),
                "max_tracking_error_m": f.max_tracking_error_m,
                "settled_after_s": f.settled_after_s,
            })),
            "write_ms": write_ms,
            "plan_ms": plan_ms,
        });
        println!("{json}");
    } else {
        let shown = flown.as_ref().map_or(program, |f| f.0);
        println!(
            "formation program ({}): {} vehicles, {} phases",
            writer.name(),
            shown.vehicles,
            shown.phase_count
        );
        for (i, p) in shown.phases().iter().enumerate() {
            println!("  {:>2} {}", i + 1, describe(p));
        }
        println!("outcome: {}", outcome.summary());
        for (k, r) in repaired.iter().enumerate() {
            println!("  problem {} (repaired): {r}", k + 1);
        }
        if let Some((_, report, _)) = &flown {
            println!(
                "planned: {:.1} s, closest two vehicles {:.2} m (minimum {:.1} m)",
                report.duration_s, report.min_separation_m, limits.min_separation_m
            );
        }
        if let Some(flown) = flown.as_ref().and_then(|f| f.2.as_ref()) {
            let settle = flown.settled_after_s.iter().fold(0.0f32, |a, b| a.max(*b));
            println!(
                "flown by the vehicle model: {:.1} s, closest two vehicles {:.2} m, furthest \
                 from a slot {:.2} m, slowest phase settled {:.1} s after its end",
                flown.duration_s,
                flown.closest.map_or(f32::INFINITY, |c| c.distance_m),
                flown.max_tracking_error_m,
                settle
            );
        }
        println!("write {write_ms:.1} ms, simulate and repair {plan_ms:.1} ms");
    }
    if let Some(dir) = &a.run {
        match flown.as_ref().and_then(|f| Some((f.0, f.2.as_deref()?))) {
            Some((program, tracks)) => {
                let path = write_tracks(dir, &a.instruction, &program, tracks)?;
                if !a.json {
                    println!("tracks: {}", path.display());
                }
            }
            None => eprintln!("aeris: no flight to write to {}", dir.display()),
        }
    }
    if accepted {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!("aeris: formation {}", outcome.summary());
        Ok(ExitCode::FAILURE)
    }
}

/// Write the simulated flight `flown` of `program` to DIR/formation.json.
#[cfg(feature = "sim")]
fn write_tracks(
    dir: &std::path::Path,
    instruction: &str,
    program: &FormationProgram,
    flown: &aeris_formation::FlownReport,
) -> anyhow::Result<PathBuf> {
    use aeris_eval::formation_plot::{FORMATION_TRACKS_FILE, FormationTracks, TrackSample};
    let n = program.vehicles as usize;
    let tracks = FormationTracks {
        instruction: instruction.to_string(),
        vehicles: n,
        phases: program
            .phases()
            .iter()
            .map(aeris_formation::phase_description)
            .collect(),
        source: "the built-in multirotor model at 50 Hz, by aeris formation plan".into(),
        points: flown
            .tracks
            .iter()
            .map(|p| TrackSample {
                t_s: p.t_s,
                phase: p.phase,
                positions: p.positions[..n].to_vec(),
                slots: p.slots[..n].to_vec(),
            })
            .collect(),
    };
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(FORMATION_TRACKS_FILE);
    std::fs::write(&path, serde_json::to_string(&tracks)?)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// A build without the simulator has no flight to write.
#[cfg(not(feature = "sim"))]
fn write_tracks(
    _dir: &std::path::Path,
    _instruction: &str,
    _program: &FormationProgram,
    _flown: &aeris_formation::FlownReport,
) -> anyhow::Result<PathBuf> {
    anyhow::bail!("--run: this build has no simulator (build with the default `sim` feature)")
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

impl crate::command::Execute for FormationArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self.command)
    }
}
