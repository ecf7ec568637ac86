//! [`Flight`]: the handle of a supervised flight running on its own thread, and
//! [`FlightBuilder`], which starts one.

use crate::error::FlightError;
use crate::event::{FlightEvent, FlightPhase, FlightStatus, FlightWatcher, StopRule};
use crate::hook::{FnHook, HookError, NoHook, StepContext, StepHook};
use crate::monitor::FlightOutcome;
use crate::overrides::Overrides;
use crate::supervise::{FlightSetup, Shared, StopRequest, supervise};
use aeris_orchestrator::workflow::Workflow;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

/// How often [`Flight::watch`] asks its watcher whether to interrupt the flight.
const WATCH_POLL: Duration = Duration::from_millis(50);

/// Sets up a flight; [`FlightBuilder::start`] starts it.
#[must_use = "a builder does nothing until start()"]
pub struct FlightBuilder<H: StepHook = NoHook> {
    workflow: Workflow,
    name: Option<String>,
    run_dir: Option<PathBuf>,
    autopilot: Option<String>,
    overrides: Overrides,
    stop: StopRule,
    role_executable: Option<PathBuf>,
    record: Option<crate::recording::RecordRequest>,
    offload_check: Option<crate::executors::OffloadCheck>,
    clock: crate::sim_time::FlightClock,
    hook: H,
}

impl<H: StepHook> FlightBuilder<H> {
    /// Flight name: the namespace prefix of every service (default `flight-PID`).
    pub fn name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }

    /// Where role specs, logs and `cycles.jsonl` go (default `$TMPDIR/aeris/NAME`).
    pub fn run_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.run_dir = Some(dir.into());
        self
    }

    /// Fly against this external MAVLink autopilot instead of the built-in vehicle.
    pub fn autopilot(mut self, url: Option<String>) -> Self {
        self.autopilot = url;
        self
    }

    /// Change the workflow for this flight (applied and validated by `start`).
    pub fn overrides(mut self, overrides: Overrides) -> Self {
        self.overrides = overrides;
        self
    }

    /// The clock the flight runs on (default [`crate::FlightClock::Wall`]; `Sim` is refused
    /// by `start` for a flight that cannot follow it, [`crate::sim_time::check_sim_time`]).
    pub fn clock(mut self, clock: crate::sim_time::FlightClock) -> Self {
        self.clock = clock;
        self
    }

    /// When the flight ends (default [`StopRule::Goal`]).
    pub fn stop_when(mut self, rule: StopRule) -> Self {
        self.stop = rule;
        self
    }

    /// Check before any role starts that this build's language-model engine can offload to
    /// the accelerator executors its language-model roles start on (the binary passes
    /// llama.cpp's; without one, each role checks when it loads).
    pub fn language_offload_check(mut self, check: crate::executors::OffloadCheck) -> Self {
        self.offload_check = Some(check);
        self
    }

    /// The executable roles start from, as `EXE role --spec FILE` (default: this one).
    pub fn role_executable(mut self, path: impl Into<PathBuf>) -> Self {
        self.role_executable = Some(path.into());
        self
    }

    /// Record the flight into the MCAP file `path` (see `aeris-record`; a relative path is
    /// taken in the run directory): a recorder role is added to the workflow, and the
    /// summary gains `recording`. An earlier recording at `path` is replaced; a restarted
    /// recorder writes `path.1`, `path.2`, ... Every frame is recorded exactly, so that
    /// the recording can be replayed ([`FlightBuilder::record_exact_frames`]).
    pub fn record(mut self, path: impl Into<PathBuf>) -> Self {
        let mut request = self
            .record
            .take()
            .unwrap_or(crate::recording::RecordRequest {
                exact_frames: true,
                ..Default::default()
            });
        request.path = path.into();
        self.record = Some(request);
        self
    }

    /// Record every `n`-th camera frame's pixels as an image (0: none); with
    /// [`FlightBuilder::record`] (default `aeris_record::DEFAULT_FRAME_EVERY`).
    pub fn record_frame_every(mut self, n: u64) -> Self {
        if let Some(r) = &mut self.record {
            r.frame_every = Some(n);
        }
        self
    }

    /// Record the images as JPEG of quality `q` (1..=100; depth as PNG), or with 0 as raw
    /// pixels (`foxglove.RawImage`); with [`FlightBuilder::record`] (default JPEG at
    /// `aeris_record::codec::DEFAULT_JPEG_QUALITY`).
    pub fn record_jpeg_quality(mut self, q: u8) -> Self {
        if let Some(r) = &mut self.record {
            r.jpeg_quality = Some(q);
        }
        self
    }

    /// Record every camera frame exactly as well (the default), so that `aeris replay` can
    /// replay the recording (LZ4-compressed; see `aeris_record::read`); `false` keeps only
    /// the pictures; with [`FlightBuilder::record`].
    pub fn record_exact_frames(mut self, on: bool) -> Self {
        if let Some(r) = &mut self.record {
            r.exact_frames = on;
        }
        self
    }

    /// Record only `topics` (default: every topic the flight publishes); with
    /// [`FlightBuilder::record`].
    pub fn record_topics(mut self, topics: Vec<String>) -> Self {
        if let Some(r) = &mut self.record {
            r.topics = Some(topics);
        }
        self
    }

    /// Run `step` once every supervisor step (see [`StepHook`]).
    pub fn on_step<F>(self, step: F) -> FlightBuilder<FnHook<F>>
    where
        F: FnMut(&mut StepContext<'_>) -> Result<bool, HookError> + Send + 'static,
    {
        self.step_hook(FnHook(step))
    }

    /// Run `hook` once every supervisor step; [`Flight::wait_with_hook`] hands it back.
    pub fn step_hook<H2: StepHook>(self, hook: H2) -> FlightBuilder<H2> {
        FlightBuilder {
            workflow: self.workflow,
            name: self.name,
            run_dir: self.run_dir,
            autopilot: self.autopilot,
            overrides: self.overrides,
            stop: self.stop,
            role_executable: self.role_executable,
            record: self.record,
            offload_check: self.offload_check,
            clock: self.clock,
            hook,
        }
    }

    /// Start the flight on its own thread (the supervisor's ports and its children's
    /// parent-death signal belong to the thread that creates it). Returns once the roles'
    /// processes are started; start-up failures come back here, later ones from
    /// [`Flight::wait`].
    pub fn start(self) -> Result<Flight<H>, FlightError> {
        let mut workflow = self.workflow;
        self.overrides.apply(&mut workflow)?;
        let role_executable = match self.role_executable {
            Some(p) => p,
            None => std::env::current_exe().map_err(FlightError::RoleExecutable)?,
        };
        let name = self
            .name
            .unwrap_or_else(|| format!("flight-{}", std::process::id()));
        let run_dir = self
            .run_dir
            .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&name));
        let record = match self.record {
            Some(mut request) => {
                request.path = run_dir.join(&request.path);
                let role = crate::recording::add_recorder(&mut workflow, &request)?;
                let path = request.path;
                Some((path, role))
            }
            None => None,
        };
        let shared = Arc::new(Shared::new(&name));
        let (events_tx, events) = mpsc::channel();
        let (started_tx, started_rx) = mpsc::sync_channel(1);
        let setup = FlightSetup {
            workflow,
            name: name.clone(),
            run_dir: run_dir.clone(),
            autopilot: self.autopilot,
            dynamic: self.overrides.dynamic,
            stop: self.stop,
            role_executable,
            record,
            offload_check: self.offload_check,
            clock: self.clock,
        };
        let hook = self.hook;
        let thread_shared = shared.clone();
        let thread = std::thread::Builder::new()
            .name(format!("flight {name}"))
            .spawn(move || {
                let result = supervise(setup, hook, &thread_shared, &events_tx, started_tx);
                thread_shared.set_phase(FlightPhase::Finished);
                result
            })
            .map_err(FlightError::Thread)?;
        let mut flight = Flight {
            name,
            run_dir,
            events,
            shared,
            thread: Some(thread),
        };
        if started_rx.recv().is_err() {
            // the thread ended before the roles were started: its result says why
            return Err(match flight.join() {
                Err(e) => e,
                Ok(_) => FlightError::Panicked,
            });
        }
        Ok(flight)
    }
}

/// A supervised flight running on its own thread: watch it ([`Flight::events`],
/// [`Flight::status`]), end it ([`Flight::stop`]), collect it ([`Flight::wait`]).
/// Dropping it stops it and waits for every role to be stopped.
pub struct Flight<H: StepHook = NoHook> {
    name: String,
    run_dir: PathBuf,
    events: Receiver<FlightEvent>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<Result<(FlightOutcome, H), FlightError>>>,
}

impl Flight {
    /// Set up a flight of `workflow` (start it with [`FlightBuilder::start`]).
    pub fn builder(workflow: Workflow) -> FlightBuilder {
        FlightBuilder {
            workflow,
            name: None,
            run_dir: None,
            autopilot: None,
            overrides: Overrides::default(),
            stop: StopRule::Goal,
            role_executable: None,
            record: None,
            offload_check: None,
            clock: Default::default(),
            hook: NoHook,
        }
    }
}

impl<H: StepHook> Flight<H> {
    /// Flight name (the namespace prefix of its services).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Where its role specs, logs and `cycles.jsonl` are.
    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    /// Its events, in order; the channel closes when the flight's thread ends.
    pub fn events(&self) -> &Receiver<FlightEvent> {
        &self.events
    }

    /// Where the flight is now.
    pub fn status(&self) -> FlightStatus {
        self.shared
            .status
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Ask the flight to end (at its next step; it fails with [`FlightFailure::Stopped`]).
    /// Idempotent: the first request's reason stays.
    pub fn stop(&self) {
        self.shared.request_stop(StopRequest::Stop);
    }

    /// [`Flight::stop`] because the process was asked to terminate (Ctrl-C): the flight
    /// fails with [`FlightFailure::Interrupted`].
    pub fn interrupt(&self) {
        self.shared.request_stop(StopRequest::Interrupt);
    }

    /// Wait for the flight to end.
    pub fn wait(self) -> Result<FlightOutcome, FlightError> {
        self.wait_with_hook().map(|(outcome, _)| outcome)
    }

    /// Wait for the flight to end; also hands back the step hook with what it gathered.
    pub fn wait_with_hook(mut self) -> Result<(FlightOutcome, H), FlightError> {
        self.join()
    }

    /// Hand every event to `watcher` as it comes, and [`Flight::interrupt`] the flight
    /// once the watcher says so, until the flight ends; then [`Flight::wait_with_hook`].
    pub fn watch(self, watcher: &mut dyn FlightWatcher) -> Result<(FlightOutcome, H), FlightError> {
        loop {
            match self.events.recv_timeout(WATCH_POLL) {
                Ok(event) => watcher.event(&event),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            if watcher.interrupted() {
                self.interrupt();
            }
        }
        self.wait_with_hook()
    }

    /// Join the flight's thread (once: `wait*` consume the handle, `Drop` joins only a
    /// thread not joined yet).
    fn join(&mut self) -> Result<(FlightOutcome, H), FlightError> {
        let thread = self.thread.take().ok_or(FlightError::Panicked)?;
        thread.join().map_err(|_| FlightError::Panicked)?
    }
}

impl<H: StepHook> Drop for Flight<H> {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.stop();
            let _ = self.join();
        }
    }
}
