//! Why a flight could not start or ended with an error ([`FlightError`]).

use crate::hook::HookError;
use crate::overrides::OverrideError;
use aeris_orchestrator::supervisor::SupervisorError;
use aeris_runtime::bus::BusError;
use std::path::PathBuf;

/// Why a flight could not start or ended with an error.
#[derive(Debug, thiserror::Error)]
pub enum FlightError {
    /// The executable roles start from could not be found (by default this one).
    #[error("locating the role executable")]
    RoleExecutable(#[source] std::io::Error),
    /// The overrides do not fit the workflow.
    #[error("workflow overrides")]
    Overrides(#[from] OverrideError),
    /// The flight's thread could not be started.
    #[error("starting the flight's thread")]
    Thread(#[source] std::io::Error),
    /// The flight cannot run on simulated time.
    #[error("cannot fly on simulated time")]
    SimTime(#[source] crate::sim_time::SimTimeRefusal),
    /// The flight's simulated clock could not be made.
    #[error("making the flight's simulated clock")]
    SimClock(#[source] aeris_runtime::clock::sim::SimClockError),
    /// An accelerator executor names an accelerator this host's ONNX Runtime cannot run.
    #[error(transparent)]
    Accelerator(Box<crate::executors::AcceleratorError>),
    /// The supervisor could not start the roles.
    #[error("starting the supervisor")]
    Start(#[source] Box<SupervisorError>),
    /// A role sent no first heartbeat in time, or stopped for good while starting.
    #[error("waiting for every role's first heartbeat")]
    NotReady(#[source] Box<SupervisorError>),
    /// The flight's hub reports, setpoints or telemetry could not be subscribed to.
    #[error("subscribing to the flight")]
    Subscribe(#[source] BusError),
    /// A supervisor step failed.
    #[error("supervising")]
    Supervise(#[source] Box<SupervisorError>),
    /// Reading the flight's hub reports, setpoints or telemetry failed.
    #[error("reading flight telemetry")]
    Telemetry(#[source] BusError),
    /// The step hook failed; its own error says how.
    #[error(transparent)]
    Hook(HookError),
    /// The flight could not be set up for recording.
    #[error(transparent)]
    Record(#[from] crate::recording::RecordError),
    /// The cycle trace could not be written into the run directory.
    #[error("writing {}", path.display())]
    WriteTrace {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The flight's thread panicked (in a step hook: the library's own code does not).
    #[error("the flight's thread panicked")]
    Panicked,
}
