//! The step hook: code that runs on the flight's thread once every supervisor step, in
//! sync with it (benchmarks inject faults and start swaps from it, the VLN evaluation
//! watches for collisions).

use crate::event::FlightEvent;
use crate::monitor::FlightMonitor;
use aeris_orchestrator::supervisor::{Supervisor, SupervisorEvent};
use std::sync::mpsc::Sender;

/// What a step hook's error is: anything the hook's own code returns.
pub type HookError = Box<dyn std::error::Error + Send + Sync>;

/// What a step hook sees.
pub struct StepContext<'a> {
    /// The flight's supervisor (signal a role, begin a swap, read heartbeats).
    pub supervisor: &'a mut Supervisor,
    /// The flight's monitor, polled this step.
    pub monitor: &'a FlightMonitor,
    /// What the supervisor reported this step.
    pub events: &'a [SupervisorEvent],
    /// The flight's time now (ns): simulated on simulated time, where a hook runs at the
    /// end of each step period.
    pub now_ns: u64,
    pub(crate) events_out: &'a Sender<FlightEvent>,
}

impl StepContext<'_> {
    /// Send a line to the flight's watchers ([`FlightEvent::Note`]).
    pub fn note(&self, line: impl Into<String>) {
        // nobody listening is not the hook's problem
        let _ = self.events_out.send(FlightEvent::Note(line.into()));
    }
}

/// Code run once every supervisor step; `Ok(true)` ends the flight (no failure), an error
/// ends it with that error. It runs on the flight's thread, hence `Send + 'static`; the
/// flight hands it back at the end ([`crate::Flight::wait_with_hook`]), with whatever it
/// gathered.
pub trait StepHook: Send + 'static {
    /// One step.
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError>;
}

/// No hook: the stop rule alone ends the flight.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoHook;

impl StepHook for NoHook {
    fn step(&mut self, _: &mut StepContext<'_>) -> Result<bool, HookError> {
        Ok(false)
    }
}

/// A closure as a step hook ([`crate::FlightBuilder::on_step`]).
pub struct FnHook<F>(pub F);

impl<F> StepHook for FnHook<F>
where
    F: FnMut(&mut StepContext<'_>) -> Result<bool, HookError> + Send + 'static,
{
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        (self.0)(ctx)
    }
}
