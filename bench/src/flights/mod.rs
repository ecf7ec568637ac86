//! Benchmarks that fly the pipeline end to end (every role its own process), each a
//! supervised flight of [`aeris_flight`] with a step hook that drives the benchmark:
//!
//! - [`cycle`]: cycle time per stage and EER over N heartbeats;
//! - [`swap`]: hot swaps during the flight: time to ready and done, missed heartbeats,
//!   setpoint gaps;
//! - [`faults`]: the fault-injection table (SIGKILL, SIGSTOP, a garbage reasoner, a removed
//!   service) over one flight of the default workflow;
//! - [`ds`]: dynamic scheduling on and off under a CPU hog;
//! - [`record`]: what recording costs: flights with and without the recorder;
//! - [`formation`]: formation flights of several vehicles (separation, settling, every
//!   controller's missed ticks).
//!
//! Each takes a config and a [`aeris_flight::FlightWatcher`] that gets every event of its
//! flights (the benchmark's own progress lines arrive as [`aeris_flight::FlightEvent::Note`])
//! and may interrupt them, and returns its report.

pub mod cycle;
pub mod ds;
pub mod faults;
pub mod formation;
pub mod record;
pub mod swap;

pub use cycle::{CycleConfig, CycleReport, DecisionCost, RoleLatency};
pub use ds::{DsConfig, DsReport, DsRun};
pub use faults::{FaultError, FaultKind, FaultRow, FaultsConfig, FaultsReport};
pub use formation::{FormationFlightConfig, FormationFlightRow};
pub use record::{RecordBenchConfig, RecordBenchReport, RecordRow};
pub use swap::{SwapConfig, SwapReport, SwapRow};

use aeris_flight::{FlightError, FlightFailure, OverrideError, Overrides, VariantChoice};
use aeris_orchestrator::supervisor::Supervisor;
use aeris_orchestrator::workflow::{Workflow, WorkflowError, WorkflowFileError};
use aeris_runtime::affinity::CpuSet;
use std::path::PathBuf;

/// Settings shared by the flight benchmarks.
#[derive(Debug, Clone, Default)]
pub struct FlightBenchConfig {
    /// Workflow to fly (default: the built-in model flight, workflows/models.toml).
    pub workflow: Option<PathBuf>,
    /// Roles run with another variant.
    pub variants: Vec<VariantChoice>,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    pub run_dir: Option<PathBuf>,
    /// Busy processes started outside the flight (unpinned, normal priority) for the run.
    pub outside_load: usize,
    /// How the roles get priority over outside work (default: the workflow's).
    pub priority: Option<aeris_orchestrator::priority::PriorityMode>,
}

/// Why a flight benchmark could not run to the end.
#[derive(Debug, thiserror::Error)]
pub enum FlightBenchError {
    /// The settings cannot be measured (e.g. zero heartbeats).
    #[error("invalid benchmark settings: {0}")]
    Settings(String),
    /// The workflow file could not be read or is not valid.
    #[error(transparent)]
    Workflow(#[from] WorkflowFileError),
    /// A built-in workflow is not valid (a build defect).
    #[error("built-in workflow")]
    BuiltinWorkflow(#[source] WorkflowError),
    /// The variant choices do not fit the workflow.
    #[error("variant overrides")]
    Overrides(#[from] OverrideError),
    /// A role named in the settings is not in the workflow.
    #[error("the workflow has no role `{role}` (roles: {roles})")]
    NoRole {
        /// The role named.
        role: String,
        /// The workflow's roles, comma-separated.
        roles: String,
    },
    /// The role to swap has no variant but the one it runs, and none was named.
    #[error("role `{role}` has no other variant to swap to; name the variants to swap to")]
    NothingToSwap {
        /// The role.
        role: String,
    },
    /// The garbage fault needs a reasoning role with a `garbage` variant.
    #[error("garbage: the workflow's reasoning role has no `garbage` variant")]
    NoGarbageVariant,
    /// The service-removed fault needs a camera role.
    #[error("service-removed: the workflow has no camera role")]
    NoCamera,
    /// The flight could not start, or ended with an error.
    #[error(transparent)]
    Flight(#[from] FlightError),
    /// The outside load could not be started.
    #[error(transparent)]
    OutsideLoad(#[from] OutsideLoadError),
    /// The flight ended before the benchmark had its figures.
    #[error("{bench}: the flight ended early: {failure}")]
    EndedEarly {
        /// The benchmark (and run).
        bench: String,
        /// Why it ended.
        failure: FlightFailure,
    },
    /// Fewer swaps than asked were made before the flight ended.
    #[error("bench swap: the flight ended after {made} of {asked} swaps: {}", reason_text(.failure))]
    SwapsCut {
        /// Swaps made.
        made: usize,
        /// Swaps asked for.
        asked: u32,
        /// Why the flight ended, when it failed.
        failure: Option<FlightFailure>,
    },
    /// The CPU hog of `bench ds` never landed.
    #[error("bench ds ({run}): the hog never landed (no role had latency figures)")]
    HogNeverLanded {
        /// `ds-on` or `ds-off`.
        run: &'static str,
    },
}

fn reason_text(failure: &Option<FlightFailure>) -> String {
    failure
        .as_ref()
        .map_or_else(|| "no reason given".into(), FlightFailure::to_string)
}

/// Busy processes outside the flight (pinned to a CPU set, or unpinned at normal priority)
/// until dropped: the CPU hog of `bench ds`, the outside load of `bench record`, `cycle`,
/// `swap` and `models`. Processes, not threads of this one: the supervisor's process joins
/// the flight's CPU control group ([`aeris_orchestrator::priority`]), and load started in it
/// would join the flight with it.
pub struct BusyProcesses {
    children: Vec<std::process::Child>,
}

/// Outside load could not be started.
#[derive(Debug, thiserror::Error)]
#[error("outside load: start a busy `sh` loop")]
pub struct OutsideLoadError(#[source] std::io::Error);

impl BusyProcesses {
    /// Start `n` busy processes (`sh` running an empty loop), bound to `cpus` when given.
    pub fn start(cpus: Option<&CpuSet>, n: usize) -> Result<Self, OutsideLoadError> {
        use std::os::unix::process::CommandExt;
        let mut load = Self {
            children: Vec::with_capacity(n),
        };
        for _ in 0..n {
            let mut cmd = std::process::Command::new("sh");
            cmd.args(["-c", "while :; do :; done"])
                .stdin(std::process::Stdio::null())
                .stdout(std::process::Stdio::null());
            if let Some(set) = cpus.cloned() {
                // SAFETY: binding the forked child to CPUs is one sched_setaffinity call,
                // async-signal-safe, no allocation.
                unsafe { cmd.pre_exec(move || set.bind_task(0)) };
            }
            // a child that failed to start leaves those started to Drop
            load.children.push(cmd.spawn().map_err(OutsideLoadError)?);
        }
        Ok(load)
    }
}

impl Drop for BusyProcesses {
    fn drop(&mut self) {
        for child in &mut self.children {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// The workflow a flight benchmark flies: the file, or the built-in model flight.
fn load_workflow(config: &FlightBenchConfig) -> Result<Workflow, FlightBenchError> {
    match &config.workflow {
        Some(p) => Ok(Workflow::from_path(p)?),
        None => Workflow::builtin_models().map_err(FlightBenchError::BuiltinWorkflow),
    }
}

/// The flight name and run directory of a benchmark flight tagged `tag`.
fn flight_name_and_dir(tag: &str, run_dir: Option<PathBuf>) -> (String, PathBuf) {
    let flight = format!("bench-{tag}-{}", std::process::id());
    let dir = run_dir.unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight));
    (flight, dir)
}

/// One role's latency over the flight, from its heartbeats.
fn role_latencies(sup: &Supervisor) -> Vec<RoleLatency> {
    sup.roles()
        .iter()
        .filter_map(|r| {
            r.latency_ms().map(|l| RoleLatency {
                role: r.name().to_string(),
                variant: r.variant().to_string(),
                p50_ms: l[0],
                p95_ms: l[1],
            })
        })
        .collect()
}

/// [`FlightBenchError::NoRole`] for `role` of `workflow`.
fn no_role(workflow: &Workflow, role: &str) -> FlightBenchError {
    FlightBenchError::NoRole {
        role: role.to_string(),
        roles: workflow
            .roles
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// `workflow` with the benchmark's variant choices, and the variant ladder off: the
/// benchmark's figures are the declared variants' (and it makes its own swaps).
fn with_variants(
    workflow: Workflow,
    config: &FlightBenchConfig,
) -> Result<Workflow, FlightBenchError> {
    with_variants_and_ladder(workflow, config, false)
}

/// `workflow` with the benchmark's variant choices; the variant ladder as the workflow
/// says when `ladder`, else off.
fn with_variants_and_ladder(
    mut workflow: Workflow,
    config: &FlightBenchConfig,
    ladder: bool,
) -> Result<Workflow, FlightBenchError> {
    Overrides {
        variants: config.variants.clone(),
        fixed_variants: !ladder,
        ..Overrides::default()
    }
    .apply(&mut workflow)?;
    Ok(workflow)
}
