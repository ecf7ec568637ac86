//! The formation benchmark, program stage: every variant (the deterministic parser, the
//! language models) writes a program for each of the benchmark instructions
//! ([`BENCHMARK_INSTRUCTIONS`], or the development set); each goes through validation, the simulation and the
//! repair loop. Per instruction: time to write, whether it was valid as written, the outcome
//! (accepted as written, repaired after k attempts, refused), whether its phases are the
//! parser's (the oracle), the closest two vehicles came as planned and as the built-in
//! multirotor model flew it (50 Hz slots with feed-forward), how long the slowest phase
//! took to settle, and how far a vehicle fell behind its slot.

use crate::error::BenchError;
use crate::flights::BusyProcesses;
use aeris_formation::{
    BENCHMARK_INSTRUCTIONS, DEVELOPMENT_INSTRUCTIONS, ParserWriter, PlanOutcome, ProgramWriter,
    Simulation, ground_row, parse_instruction, plan_instruction,
};
use aeris_llm::FormationWriter;
use aeris_models::ModelStore;
use aeris_schemas::{FormationLimits, FormationProgram};
use serde::Serialize;

/// What the program stage is measured with.
#[derive(Debug, Clone)]
pub struct FormationBenchConfig {
    /// Variants: `parser`, `qwen-coder`, `smollm2`, `gemma3`.
    pub variants: Vec<String>,
    /// Vehicles the flight has.
    pub vehicles: u8,
    /// Repairs tried before a program is refused.
    pub max_repairs: usize,
    /// CPU threads a language model evaluates on.
    pub threads: i32,
    /// Busy processes started outside the benchmark (unpinned, normal priority).
    pub outside_load: usize,
    /// The instructions: [`BENCHMARK_INSTRUCTIONS`] (reported) or
    /// [`DEVELOPMENT_INSTRUCTIONS`] (to develop prompts on).
    pub instructions: &'static [&'static str],
}

/// One instruction written by one variant.
#[derive(Debug, Clone, Serialize)]
pub struct ProgramRow {
    /// The variant.
    pub variant: String,
    /// The instruction.
    pub instruction: String,
    /// Time to write the first program (ms).
    pub write_ms: f64,
    /// Tokens the model generated for it, repairs included (language models only).
    pub generated_tokens: Option<usize>,
    /// The program passed validation as first written.
    pub valid_as_written: bool,
    /// `accepted` (as written), `repaired`, `refused`, or `failed` (no program written).
    pub outcome: &'static str,
    /// Repairs made.
    pub repairs: usize,
    /// Time to validate, simulate and repair (ms).
    pub plan_ms: f64,
    /// The first program's phase kinds and shapes are the parser's.
    pub same_phases_as_parser: bool,
    /// Closest two vehicles in the planned transitions of the accepted program (m).
    pub min_separation_m: Option<f32>,
    /// Closest two vehicles as the vehicle model flew the accepted program (m).
    pub flown_min_separation_m: Option<f32>,
    /// The longest any phase took, after its planned end, until every vehicle was within
    /// tolerance of its slot (s; vehicle model).
    pub settle_max_s: Option<f32>,
    /// The furthest a vehicle fell behind its slot while flying (m; vehicle model).
    pub max_tracking_error_m: Option<f32>,
    /// How long the vehicle model took to fly the accepted program (s).
    pub flown_s: Option<f32>,
    /// The last problem (refused) or why nothing was written (failed).
    pub problem: Option<String>,
    /// The first program in its JSON form (as a language model writes it).
    pub program: Option<String>,
}

/// The program stage's figures.
#[derive(Debug, Clone, Serialize)]
pub struct FormationReport {
    /// Vehicles the flight had.
    pub vehicles: u8,
    /// Busy processes outside.
    pub outside_load: usize,
    /// Seconds each language model took to load.
    pub load_s: Vec<(String, f64)>,
    /// One row per variant and instruction.
    pub rows: Vec<ProgramRow>,
    /// The flight stage (`--fly`): one row per instruction flown by real processes.
    pub flights: Vec<crate::flights::FormationFlightRow>,
}

/// The simulation a program goes through before it is accepted: with the built-in
/// multirotor flying it where this build has the simulator (the exact check alone where not).
pub fn simulation() -> Simulation {
    #[cfg(feature = "sim")]
    {
        aeris_sim::formation_vehicle::multirotor_simulation()
    }
    #[cfg(not(feature = "sim"))]
    {
        Simulation::default()
    }
}

/// The instruction sets: the benchmark's, reported, and the development set.
pub const INSTRUCTION_SETS: [(&str, &[&str]); 2] = [
    ("benchmark", &BENCHMARK_INSTRUCTIONS),
    ("development", &DEVELOPMENT_INSTRUCTIONS),
];

/// The phase kinds and shapes of `p`, in order.
fn skeleton(p: &FormationProgram) -> Vec<(u8, u8)> {
    p.phases().iter().map(|ph| (ph.kind, ph.shape)).collect()
}

/// Run every instruction through `writer`.
fn rows_of<W: ProgramWriter>(
    writer: &mut W,
    instructions: &[&str],
    limits: &FormationLimits,
    max_repairs: usize,
    tokens: impl Fn(&W) -> Option<usize>,
) -> Vec<ProgramRow> {
    let starts = ground_row(
        limits.vehicles as usize,
        (2.0 * limits.min_separation_m).max(4.0),
    );
    instructions
        .iter()
        .map(|text| {
            let oracle = parse_instruction(text, limits).ok();
            let tokens_before = tokens(writer);
            let planned =
                plan_instruction(writer, text, &starts, limits, &simulation(), max_repairs);
            let mut row = ProgramRow {
                variant: writer.name().to_string(),
                instruction: text.to_string(),
                write_ms: 0.0,
                generated_tokens: tokens(writer).zip(tokens_before).map(|(a, b)| a - b),
                valid_as_written: false,
                outcome: "failed",
                repairs: 0,
                plan_ms: 0.0,
                same_phases_as_parser: false,
                min_separation_m: None,
                flown_min_separation_m: None,
                settle_max_s: None,
                max_tracking_error_m: None,
                flown_s: None,
                problem: None,
                program: None,
            };
            let planned = match planned {
                Ok(p) => p,
                Err(e) => {
                    row.problem = Some(aeris_runtime::error_chain::chain(&e).to_string());
                    return row;
                }
            };
            row.write_ms = planned.write_time.as_secs_f64() * 1e3;
            row.plan_ms = planned.plan_time.as_secs_f64() * 1e3;
            row.valid_as_written = planned.written.validate(limits).is_ok();
            row.program = aeris_llm::program_to_json(&planned.written);
            row.same_phases_as_parser =
                oracle.is_some_and(|o| skeleton(&o) == skeleton(&planned.written));
            match planned.outcome {
                PlanOutcome::Accepted {
                    report,
                    flown,
                    repaired,
                    ..
                } => {
                    if let Some(flown) = flown {
                        row.flown_min_separation_m = flown.closest.map(|c| c.distance_m);
                        row.settle_max_s = flown.settled_after_s.iter().copied().reduce(f32::max);
                        row.max_tracking_error_m = Some(flown.max_tracking_error_m);
                        row.flown_s = Some(flown.duration_s);
                    }
                    row.outcome = if repaired.is_empty() {
                        "accepted"
                    } else {
                        "repaired"
                    };
                    row.repairs = repaired.len();
                    row.min_separation_m = Some(report.min_separation_m);
                }
                PlanOutcome::Refused { problem, repaired } => {
                    row.outcome = "refused";
                    row.repairs = repaired.len();
                    row.problem = Some(problem.to_string());
                }
            }
            row
        })
        .collect()
}

/// Measure the program stage for every variant of `config`.
pub fn bench_programs(
    config: &FormationBenchConfig,
    store: &ModelStore,
) -> Result<FormationReport, BenchError> {
    let limits = FormationLimits {
        vehicles: config.vehicles,
        ..FormationLimits::default()
    };
    if !limits.is_coherent() {
        return Err(BenchError::Config(format!(
            "{} vehicles: a formation has 1 to 8",
            config.vehicles
        )));
    }
    let _load = BusyProcesses::start(None, config.outside_load)?;
    let mut report = FormationReport {
        vehicles: config.vehicles,
        outside_load: config.outside_load,
        load_s: Vec::new(),
        rows: Vec::new(),
        flights: Vec::new(),
    };
    for variant in &config.variants {
        if variant == "parser" {
            report.rows.extend(rows_of(
                &mut ParserWriter,
                config.instructions,
                &limits,
                config.max_repairs,
                |_| None,
            ));
            continue;
        }
        let file = aeris_llm::variant_model(variant).ok_or_else(|| {
            BenchError::Config(format!(
                "variant `{variant}`: the formation variants are parser, qwen-coder, smollm2 and gemma3"
            ))
        })?;
        let mut writer = FormationWriter::load(store, variant, file, config.threads)?;
        report.load_s.push((variant.clone(), writer.load_s()));
        let rows = rows_of(
            &mut writer,
            config.instructions,
            &limits,
            config.max_repairs,
            |w| Some(w.tokens_generated()),
        );
        report.rows.extend(rows);
    }
    Ok(report)
}
