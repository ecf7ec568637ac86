//! # aeris-flight
//!
//! A supervised flight as a library: start one, watch it, stop it, collect its summary.
//!
//! ```no_run
//! use aeris_flight::{Flight, FlightEvent, StopRule};
//! use aeris_orchestrator::Workflow;
//!
//! let flight = Flight::builder(Workflow::builtin_default()?)
//!     .name("flight-123")
//!     .stop_when(StopRule::Goal)
//!     .start()?;
//! for event in flight.events().iter() {
//!     if let FlightEvent::Progress(p) = event {
//!         println!("step {}/{}", p.step, p.steps);
//!     }
//! }
//! let outcome = flight.wait()?;
//! println!("reached the goal: {}", outcome.summary.reached_goal);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! It is its own crate because it is the composition layer over the supervisor: the flight
//! loop (supervisor steps, the [`FlightMonitor`] that turns hub reports and telemetry into
//! progress and the [`FlightSummary`], the [`StopRule`]s, the time limit, the cycle trace)
//! is what `aeris run`, the flight benchmarks, the VLN evaluation and the coming record /
//! replay, remote-host agents and formations share. Keeping it here keeps
//! `aeris-orchestrator` free of models (the accelerator query) and of flight-level policy
//! (when a flight has succeeded or failed), and keeps the `aeris` binary to parsing and
//! printing.
//!
//! - [`Flight`] / [`FlightBuilder`]: the handle of a flight running on its own thread
//!   (iceoryx2 ports are not `Send`, and a role's parent-death signal belongs to the thread
//!   that started it), its [`FlightEvent`]s, [`FlightStatus`], [`FlightOutcome`];
//! - [`StepHook`]: code run in sync with every supervisor step (fault injection, hot swaps,
//!   collision checks);
//! - [`monitor`]: the [`FlightMonitor`], the [`FlightSummary`] and the [`CycleTrace`];
//! - [`Overrides`]: a flight's changes to its workflow;
//! - [`recording`]: a recorded flight ([`FlightBuilder::record`]: the `aeris-record` role);
//! - [`replay`]: a recorded flight replayed with live roles, decision by decision against
//!   the recording, and variants compared on it;
//! - [`executors`]: the executor registry a workflow would start with, and the
//!   accelerators ONNX Runtime offers;
//! - [`sim_time`]: the clock a flight runs on ([`FlightClock`]): the wall clock, or
//!   simulated time in lockstep, as fast as the roles compute;
//! - [`status_report`]: a running flight seen from another process (`aeris status`), as a
//!   typed value whose `Serialize` is `--json` and whose `Display` is the table.

#![deny(missing_docs)]

pub mod autopilot_link;
mod compute_time;
mod error;
pub mod event;
pub mod executors;
pub mod first_decision;
pub mod fleet;
pub mod formation_say;
mod handle;
pub mod hook;
pub mod memory;
pub mod monitor;
mod outcome_text;
pub mod overrides;
pub mod recording;
pub mod replay;
pub mod sim_time;
pub mod status_report;
mod supervise;
mod telemetry;
mod video_start;
pub mod workflow_check;

pub use autopilot_link::{AutopilotEvent, silent_diagnosis};
pub use error::FlightError;
pub use event::{
    FleetProgress, FlightEvent, FlightFailure, FlightPhase, FlightProgress, FlightStatus,
    FlightWatcher, RoleSnapshot, StopRule,
};
pub use fleet::{
    COLLISION_DISTANCE_M, Collision, FleetMonitor, FleetSummary, FormationTally, VehicleSummary,
};
pub use formation_say::{SayAnswer, SayError, say};
pub use handle::{Flight, FlightBuilder};
pub use hook::{FnHook, HookError, NoHook, StepContext, StepHook};
pub use memory::{MemorySummary, RoleMemory};
pub use monitor::{
    CycleTrace, FlightMonitor, FlightOutcome, FlightSummary, LinkSummary, StageMeans,
};
pub use overrides::{OverrideError, Overrides, VariantChoice};
pub use recording::{RecordError, RecordingSummary};
pub use sim_time::{FlightClock, SimTimeRefusal};
