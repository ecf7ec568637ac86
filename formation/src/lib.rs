//! # aeris-formation
//!
//! Multi-UAV formations (the paper's formation experiment), as pure functions (no simulator:
//! a vehicle model is handed in):
//!
//! - [`slots`]: where each vehicle of a formation program's `assume` phase goes (`[N, E, U]`);
//! - [`assign`]: which vehicle takes which slot, so that their straight-line, synchronised
//!   transitions keep them apart;
//! - [`parse`]: the deterministic parser of formation instructions (`formation/parser`);
//! - [`check`]: a program flown in simulation before it flies: separation, geofence,
//!   altitude, duration, and a diagnosis of the first violation;
//! - [`trajectory`]: a checked program's slots as functions of time, and the executor that
//!   flies them (waiting at each phase's end for every vehicle to reach its slot);
//! - [`flown`]: a checked program flown by a vehicle model (the built-in multirotor's is in
//!   `aeris-sim`), faster than real time: separation, settling and tracking as they fly it;
//! - [`repair`]: validate, simulate, repair on failure (at most K times), or refuse;
//! - [`replan`]: runtime faults (a vehicle lost, or stuck off its slot) planned around: the
//!   rest of the program for the vehicles that remain, or their landing;
//! - [`tracks`]: a formation flight's tracks, the file `aeris plot formation` draws;
//! - [`writer`]: the formation role's variants ([`ProgramWriter`]; the parser's here, the
//!   language model's in `aeris-llm`) and [`plan_instruction`], instruction to outcome.

#![deny(missing_docs)]

pub mod assign;
pub mod check;
pub mod flown;
pub mod parse;
pub mod repair;
pub mod replan;
pub mod slots;
pub mod tracks;
pub mod trajectory;
pub mod writer;

pub use assign::{
    AssignError, Assignment, ClosestApproach, assign, closest_approach, min_separation_along,
};
pub use check::{
    CheckError, CheckReport, Diagnosis, Dynamics, Violation, check_program, ground_row,
    phase_description,
};
pub use flown::{
    Closest, FlownConfig, FlownReport, TrackPoint, VehicleFactory, VehicleModel, flown_diagnosis,
    fly_trajectory,
};
pub use parse::{ParseError, clauses, parse_instruction};
pub use repair::{PlanOutcome, Problem, Simulation, plan_program, repair_by_rule};
pub use replan::{
    FaultDiagnosis, InFlight, ReplanError, Replanned, RuntimeFault, replan_after_fault,
    rest_of_program,
};
pub use slots::{formation_offsets, slots};
pub use tracks::{FORMATION_TRACKS_FILE, FormationTracks, TrackSample};
pub use trajectory::{ExecutorState, FormationExecutor, Segment, Slot, Tolerance, Trajectory};
pub use writer::{
    BENCHMARK_INSTRUCTIONS, DEVELOPMENT_INSTRUCTIONS, ParserWriter, PlanInstructionError,
    PlannedInstruction, ProgramWriter, plan_instruction,
};
