//! # aeris-formation
//!
//! Multi-UAV formations (the paper's formation experiment), as pure functions:
//!
//! - [`slots`]: where each vehicle of a formation program's `assume` phase goes (`[N, E, U]`);
//! - [`assign`]: which vehicle takes which slot, so that their straight-line, synchronised
//!   transitions keep them apart;
//! - [`parse`]: the deterministic parser of formation instructions (`formation/parser`);
//! - [`check`]: a program flown in simulation before it flies: separation, geofence,
//!   altitude, duration, and a diagnosis of the first violation;
//! - [`repair`]: validate, simulate, repair on failure (at most K times), or refuse;
//! - [`writer`]: the formation role's variants ([`ProgramWriter`]; the parser's here, the
//!   language model's in `aeris-llm`) and [`plan_instruction`], instruction to outcome.

#![deny(missing_docs)]

pub mod assign;
pub mod check;
pub mod parse;
pub mod repair;
pub mod slots;
pub mod writer;

pub use assign::{
    AssignError, Assignment, ClosestApproach, assign, closest_approach, min_separation_along,
};
pub use check::{
    CheckError, CheckReport, Diagnosis, Dynamics, Violation, check_program, ground_row,
};
pub use parse::{ParseError, clauses, parse_instruction};
pub use repair::{PlanOutcome, Problem, plan_program, repair_by_rule};
pub use slots::{formation_offsets, slots};
pub use writer::{
    BENCHMARK_INSTRUCTIONS, DEVELOPMENT_INSTRUCTIONS, ParserWriter, PlanInstructionError,
    PlannedInstruction, ProgramWriter, plan_instruction,
};
