//! The formation role's variants: what turns an instruction into a [`FormationProgram`] and
//! repairs one from a [`Problem`].
//!
//! [`ParserWriter`] is the deterministic variant (`formation/parser`: [`parse_instruction`]
//! and [`repair_by_rule`]); the language-model variant lives in `aeris-llm`.
//! [`plan_instruction`] runs one instruction through write, validate, simulate and repair.

use crate::check::CheckError;
use crate::parse::{ParseError, parse_instruction};
use crate::repair::{PlanOutcome, Problem, Simulation, plan_program, repair_by_rule};
use aeris_schemas::{FormationLimits, FormationProgram};
use std::time::{Duration, Instant};

/// A formation role's variant: writes a program for an instruction and repairs one.
pub trait ProgramWriter {
    /// Why a program could not be written.
    type Error: std::error::Error + Send + Sync + 'static;

    /// The variant's name (`parser`, `smollm2`, ...).
    fn name(&self) -> &str;

    /// A program for `instruction` under `limits` (not yet validated).
    fn write(
        &mut self,
        instruction: &str,
        limits: &FormationLimits,
    ) -> Result<FormationProgram, Self::Error>;

    /// `program`, written for `instruction`, mended for `problem`; `None` when the variant
    /// cannot mend it (the program is then refused).
    fn repair(
        &mut self,
        instruction: &str,
        program: &FormationProgram,
        problem: &Problem,
        limits: &FormationLimits,
    ) -> Option<FormationProgram>;
}

/// The deterministic variant: [`parse_instruction`] and [`repair_by_rule`].
#[derive(Debug, Clone, Copy, Default)]
pub struct ParserWriter;

impl ProgramWriter for ParserWriter {
    type Error = ParseError;

    fn name(&self) -> &str {
        "parser"
    }

    fn write(
        &mut self,
        instruction: &str,
        limits: &FormationLimits,
    ) -> Result<FormationProgram, ParseError> {
        parse_instruction(instruction, limits)
    }

    fn repair(
        &mut self,
        _instruction: &str,
        program: &FormationProgram,
        problem: &Problem,
        limits: &FormationLimits,
    ) -> Option<FormationProgram> {
        repair_by_rule(program, problem, limits)
    }
}

/// Why an instruction could not be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanInstructionError<E: std::error::Error + 'static> {
    /// The variant wrote no program.
    #[error("the `{variant}` variant wrote no program")]
    Write {
        /// The variant.
        variant: String,
        /// Why.
        #[source]
        source: E,
    },
    /// The simulation could not run (see [`CheckError`]).
    #[error("checking the program in simulation")]
    Check(#[source] CheckError),
}

/// One instruction planned: the program as first written, the outcome, and the time each
/// stage took.
#[derive(Debug, Clone)]
pub struct PlannedInstruction {
    /// The program as the variant first wrote it (before any repair).
    pub written: FormationProgram,
    /// Accepted (as written or repaired) or refused.
    pub outcome: PlanOutcome,
    /// Time to write the first program.
    pub write_time: Duration,
    /// Time to validate, simulate and repair (repairs by the variant included).
    pub plan_time: Duration,
}

/// Write a program for `instruction` with `writer`, then validate it, fly it in simulation
/// from `starts` and let `writer` repair it, at most `max_repairs` times.
pub fn plan_instruction<W: ProgramWriter>(
    writer: &mut W,
    instruction: &str,
    starts: &[[f32; 3]],
    limits: &FormationLimits,
    simulation: &Simulation,
    max_repairs: usize,
) -> Result<PlannedInstruction, PlanInstructionError<W::Error>> {
    let t = Instant::now();
    let written =
        writer
            .write(instruction, limits)
            .map_err(|source| PlanInstructionError::Write {
                variant: writer.name().to_string(),
                source,
            })?;
    let write_time = t.elapsed();
    let t = Instant::now();
    let outcome = plan_program(
        &written,
        starts,
        limits,
        simulation,
        max_repairs,
        |program, problem| writer.repair(instruction, program, problem, limits),
    )
    .map_err(PlanInstructionError::Check)?;
    Ok(PlannedInstruction {
        written,
        outcome,
        write_time,
        plan_time: t.elapsed(),
    })
}

/// The formation benchmark's instructions (`aeris bench formation`), also the language-model
/// variant's test instructions. Prompts are developed on [`DEVELOPMENT_INSTRUCTIONS`]; the
/// examples in the language-model variant's API context are none of these.
pub const BENCHMARK_INSTRUCTIONS: [&str; 5] = [
    "four drones take off to 5 m in a line 3 m apart, then form a V heading north, hold 10 s, \
     then a circle of radius 6 m, and land",
    "take off to 6 m, form a column 4 m apart heading east, move 20 m north at 3 m/s, and land",
    "three drones take off to 8 m, form a circle of radius 5 m, hold 15 s, and land",
    "take off to 4 m, form a grid 3 m apart, hold 5 s, then a line 4 m apart heading west, \
     and land",
    "two drones take off to 10 m in a column 6 m apart, move 15 m east at 2 m/s, hold 8 s, \
     and land",
];

/// Instructions to develop a variant's prompt on (`aeris bench formation --instructions
/// development`), kept apart from [`BENCHMARK_INSTRUCTIONS`], which are reported.
pub const DEVELOPMENT_INSTRUCTIONS: [&str; 5] = [
    "three drones take off to 6 m, form a line 5 m apart heading east, hold 12 s, and land",
    "take off to 9 m, a wedge 3 m apart heading south-west, move 25 m south at 4 m/s, then a \
     column 3 m apart, and land",
    "four drones take off to 5 m, form a grid 4 m apart, then a circle of radius 7 m, hold 6 s, \
     and land",
    "take off to 12 m in a circle of radius 4 m, move 10 m west at 1 m/s, hold 30 s, and land",
    "two drones take off to 3 m, a line 2.5 m apart heading north-east, hold 4 s, then a column \
     5 m apart heading west, and land",
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::ground_row;

    #[test]
    fn the_parser_variant_plans_every_listed_instruction_as_asked() {
        let limits = FormationLimits::default();
        let starts = ground_row(4, 4.0);
        for text in BENCHMARK_INSTRUCTIONS
            .iter()
            .chain(&DEVELOPMENT_INSTRUCTIONS)
        {
            let planned = plan_instruction(
                &mut ParserWriter,
                text,
                &starts,
                &limits,
                &Simulation::default(),
                3,
            )
            .unwrap();
            assert_eq!(planned.outcome.summary(), "accepted", "{text}");
        }
    }
}
