//! # aeris-orchestrator
//!
//! The supervisor side of AERIS-rs (MISSION §5):
//! - [`workflow`]: TOML workflow files -> a validated [`Workflow`] (roles, variants,
//!   executors, message paths, mission, timing);
//! - [`launch`]: a workflow -> one role spec per role in start order, executors resolved to
//!   CPU sets, the built-in vehicle linked to the controller;
//! - [`restart`]: the restart policy as a pure function;
//! - [`role_process`]: starting one role process (shared by the supervisor and the host
//!   agent);
//! - [`supervisor`]: starts every role as its own process bound to its executor's CPUs,
//!   watches heartbeats (latency percentiles, sequence gaps), restarts failed roles with
//!   backoff, keeps the status board, and hot-swaps role variants make-before-break;
//! - [`executors`]: the executor registry (declared and discovered CPU sets, load from
//!   /proc) and per-process scheduler figures;
//! - [`rebind`]: the latency-driven re-binding policy (fewest moves, hysteresis) as pure
//!   functions;
//! - [`ladder`]: the role-adaptive variant policy (step a role down its ladder of model
//!   variants when it keeps missing its budget, back up when the heavier one fits again);
//! - [`control`]: asking a running flight's supervisor for a hot swap (`aeris swap`) or a
//!   live move (`aeris migrate`).

#![deny(missing_docs)]

pub mod control;
pub mod executors;
pub mod ladder;
pub mod launch;
pub mod priority;
pub mod probe;
pub mod rebind;
pub mod restart;
pub mod role_process;
pub mod supervisor;
pub mod workflow;

pub use launch::{LaunchPlan, PlanError, PlannedRole, plan_launch};
pub use restart::{RestartDecision, RestartPolicy, RoleExit, restart_decision};
pub use supervisor::{
    Handover, RoleRuntime, RoleState, ShutdownEntry, ShutdownOutcome, ShutdownReport, SilentRole,
    Supervisor, SupervisorError, SupervisorEvent, SupervisorOptions, SwapError,
};
pub use workflow::{
    Executor, ExecutorCpus, RoleDecl, SchedulingSpec, Workflow, WorkflowError, WorkflowFileError,
};
