//! The formation benchmark, flight stage: each instruction flown by real processes (the
//! built-in formation flight, `workflows/formation.toml`: a vehicle and a controller process
//! per vehicle, the formation role writing the program with one variant), as many vehicles
//! as the parser's program for the instruction flies. Per flight: whether every vehicle
//! landed, its time, the longest wait at a phase's end until every vehicle was within
//! tolerance of its slot, the closest two vehicles came by their telemetry, and each
//! controller's ticks, missed ticks and refused setpoints.

use super::{BusyProcesses, FlightBenchError, flight_name_and_dir};
use aeris_flight::{Flight, FlightWatcher, StopRule};
use aeris_formation::parse_instruction;
use aeris_orchestrator::workflow::Workflow;
use aeris_schemas::FormationLimits;
use serde::Serialize;

/// What the flight stage flies.
#[derive(Debug, Clone)]
pub struct FormationFlightConfig {
    /// The instructions, each flown once.
    pub instructions: Vec<String>,
    /// Who writes the program in flight: `parser`, `qwen-coder`, `smollm2`, `gemma3`.
    pub variant: String,
    /// Most vehicles a flight has; each flies as many as the parser reads in its
    /// instruction (at least 2).
    pub vehicles: u8,
    /// Busy processes started outside the flights (unpinned, normal priority).
    pub outside_load: usize,
}

/// One instruction flown.
#[derive(Debug, Clone, Serialize)]
pub struct FormationFlightRow {
    /// The instruction.
    pub instruction: String,
    /// Vehicles flown.
    pub vehicles: u8,
    /// Every vehicle landed, no collision.
    pub landed: bool,
    /// Why not, when not.
    pub failure: Option<String>,
    /// Wall time of the flight, from every role up (s): the program's writing and check
    /// included.
    pub duration_s: f64,
    /// The formation role's time to write, check and repair the program (s).
    pub program_s: f64,
    /// Phases of the program flown (the last one reached).
    pub phases: u64,
    /// Runtime replans.
    pub replans: u64,
    /// The longest wait at a phase's end until every vehicle was within 0.5 m of its slot
    /// (s).
    pub settle_max_s: f64,
    /// The closest two vehicles came, by their telemetry (m).
    pub min_separation_m: Option<f32>,
    /// Each controller's ticks (vehicle 1 first).
    pub controller_ticks: Vec<u64>,
    /// Each controller's ticks that missed their deadline.
    pub missed_ticks: Vec<u64>,
    /// Setpoints each controller refused.
    pub setpoints_refused: Vec<u64>,
}

/// Fly every instruction of `config`; `watcher` gets every flight's events.
pub fn run(
    config: &FormationFlightConfig,
    watcher: &mut dyn FlightWatcher,
) -> Result<Vec<FormationFlightRow>, FlightBenchError> {
    let limits = FormationLimits {
        vehicles: config.vehicles,
        ..FormationLimits::default()
    };
    if !(2..=aeris_schemas::topics::MAX_FLIGHT_VEHICLES).contains(&config.vehicles) {
        return Err(FlightBenchError::Settings(format!(
            "{} vehicles: a formation flight has 2 to {}",
            config.vehicles,
            aeris_schemas::topics::MAX_FLIGHT_VEHICLES
        )));
    }
    let _load = BusyProcesses::start(None, config.outside_load)?;
    let mut rows = Vec::with_capacity(config.instructions.len());
    for (i, instruction) in config.instructions.iter().enumerate() {
        let vehicles = parse_instruction(instruction, &limits)
            .map_or(config.vehicles, |p| p.vehicles)
            .clamp(2, config.vehicles);
        let workflow =
            Workflow::builtin_formation_with(vehicles, Some(instruction), &config.variant)
                .map_err(FlightBenchError::BuiltinWorkflow)?;
        let (name, run_dir) = flight_name_and_dir(&format!("formation-{}", i + 1), None);
        let (outcome, _) = Flight::builder(workflow)
            .name(name)
            .language_offload_check(aeris_llm::offload_check)
            .run_dir(run_dir)
            .stop_when(StopRule::Landed)
            .start()?
            .watch(watcher)?;
        let s = &outcome.summary;
        let fleet = s.fleet.as_ref();
        let each = |f: fn(&aeris_flight::VehicleSummary) -> u64| -> Vec<u64> {
            fleet.map_or_else(Vec::new, |fl| fl.vehicles.iter().map(f).collect())
        };
        let formation = fleet.and_then(|f| f.formation);
        rows.push(FormationFlightRow {
            instruction: instruction.clone(),
            vehicles,
            landed: outcome.failure.is_none(),
            failure: outcome.failure.as_ref().map(|f| f.to_string()),
            duration_s: s.duration_s,
            program_s: formation.map_or(0.0, |f| f.program_ms as f64 / 1e3),
            phases: formation.map_or(0, |f| f.phase),
            replans: formation.map_or(0, |f| f.replans),
            settle_max_s: formation.map_or(0.0, |f| f.settle_max_ms as f64 / 1e3),
            min_separation_m: fleet.and_then(|f| f.min_separation_m),
            controller_ticks: each(|v| v.controller_ticks),
            missed_ticks: each(|v| v.controller_missed_ticks),
            setpoints_refused: each(|v| v.setpoints_refused),
        });
    }
    Ok(rows)
}
