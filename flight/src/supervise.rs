//! The flight's thread: start the supervisor, wait for every role, then step it until the
//! stop rule, a failure, the time limit or a stop request; stop every role; write the trace.

use crate::compute_time::ComputeWatch;
use crate::error::FlightError;
use crate::event::{
    FleetProgress, FlightEvent, FlightFailure, FlightPhase, FlightProgress, FlightStatus,
    RoleSnapshot, StopRule,
};
use crate::executors::{accelerator_line, onnx_accelerators};
use crate::hook::{StepContext, StepHook};
use crate::monitor::{CycleTrace, FlightMonitor, FlightOutcome, LinkSummary};
use crate::recording::RecordingSummary;
use crate::sim_time::{FlightClock, FlightTime, check_sim_time};
use aeris_orchestrator::supervisor::{RoleState, Supervisor, SupervisorEvent, SupervisorOptions};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::MissionSpec;
use aeris_runtime::clock::sim::SimClockError;
use aeris_runtime::stats::{mean_std, percentile};
use aeris_schemas::HubBeatCounters;
use aeris_schemas::RoleKind;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::mpsc::{Sender, SyncSender};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// How long every role has to send its first heartbeat.
const READY_TIMEOUT: Duration = Duration::from_secs(60);
/// Pause between supervisor steps.
const STEP_PERIOD: Duration = Duration::from_millis(20);
/// Interval of [`FlightEvent::Progress`].
const PROGRESS_PERIOD: Duration = Duration::from_secs(2);
/// How long the roles have to stop on their own at the end before they are killed.
const SHUTDOWN_GRACE: Duration = Duration::from_secs(3);

/// Everything the thread needs, resolved by the builder.
pub(crate) struct FlightSetup {
    pub workflow: Workflow,
    pub name: String,
    pub run_dir: PathBuf,
    pub autopilot: Option<String>,
    pub dynamic: Option<bool>,
    pub stop: StopRule,
    pub role_executable: PathBuf,
    /// The recording's path and its recorder role's name, when recorded.
    pub record: Option<(PathBuf, String)>,
    /// The language-model engine's offload check, when the caller has one.
    pub offload_check: Option<crate::executors::OffloadCheck>,
    /// The clock the flight runs on.
    pub clock: crate::sim_time::FlightClock,
}

/// Why the flight was asked to end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum StopRequest {
    Stop = 1,
    Interrupt = 2,
}

/// What the handle and the thread share.
pub(crate) struct Shared {
    pub status: Mutex<FlightStatus>,
    /// 0: go on; else a [`StopRequest`].
    stop: AtomicU8,
}

impl Shared {
    pub fn new(name: &str) -> Self {
        Self {
            status: Mutex::new(FlightStatus {
                flight: name.to_string(),
                phase: FlightPhase::Starting,
                progress: None,
                roles: Vec::new(),
            }),
            stop: AtomicU8::new(0),
        }
    }

    pub fn request_stop(&self, why: StopRequest) {
        let _ = self
            .stop
            .compare_exchange(0, why as u8, Ordering::SeqCst, Ordering::SeqCst);
    }

    fn stop_requested(&self) -> Option<FlightFailure> {
        match self.stop.load(Ordering::SeqCst) {
            0 => None,
            r if r == StopRequest::Interrupt as u8 => Some(FlightFailure::Interrupted),
            _ => Some(FlightFailure::Stopped),
        }
    }

    fn update(&self, f: impl FnOnce(&mut FlightStatus)) {
        f(&mut self.status.lock().unwrap_or_else(PoisonError::into_inner));
    }

    pub fn set_phase(&self, phase: FlightPhase) {
        self.update(|s| s.phase = phase);
    }

    fn set_roles(&self, sup: &Supervisor) {
        self.update(|s| {
            s.roles.clear();
            s.roles.extend(sup.roles().iter().map(|r| RoleSnapshot {
                name: r.name().to_string(),
                kind: r.kind(),
                variant: r.variant().to_string(),
                pid: r.pid(),
                state: r.state(),
                restarts: r.restarts(),
                cpus: r.cpus().to_string(),
            }));
        });
    }
}

/// The flight, from start to end. Sends `started` once the roles' processes run.
pub(crate) fn supervise<H: StepHook>(
    setup: FlightSetup,
    mut hook: H,
    shared: &Shared,
    events: &Sender<FlightEvent>,
    started: SyncSender<()>,
) -> Result<(FlightOutcome, H), FlightError> {
    let FlightSetup {
        mut workflow,
        name,
        run_dir,
        autopilot,
        dynamic,
        stop,
        role_executable,
        record,
        offload_check,
        clock,
    } = setup;
    let span = tracing::info_span!("flight", flight = %name, run_dir = %run_dir.display());
    let _in_flight = span.enter();
    let send = |event| {
        // nobody listening is no reason to stop flying
        let _ = events.send(event);
    };
    let mission = workflow.mission.clone();
    let vehicles = workflow.fleet.vehicles;
    let max_duration = Duration::from_secs_f64(mission.max_duration_s);
    let heartbeat = Duration::from_millis(workflow.timing.heartbeat_period_ms);
    let deadline_ms = workflow.timing.decision_deadline_ms;
    // how long simulated time may stand still (a role's work, or its start) before the
    // flight fails: twice the supervisor's hard stall limit, at least the start-up limit
    let sim_stuck_after =
        Duration::from_millis(workflow.scheduling.stall_hard_timeout_ms.saturating_mul(2))
            .max(READY_TIMEOUT);
    crate::executors::check_accelerators(&workflow, offload_check)
        .map_err(|e| FlightError::Accelerator(Box::new(e)))?;
    let mut time = match clock {
        FlightClock::Wall => FlightTime::Wall,
        FlightClock::Sim => {
            check_sim_time(&workflow, autopilot.as_deref()).map_err(FlightError::SimTime)?;
            // a step down the ladder is a hot swap, which simulated time does not do yet
            workflow.scheduling.adapt_variants = false;
            std::fs::create_dir_all(&run_dir).map_err(|source| {
                FlightError::SimClock(SimClockError::Map {
                    path: run_dir.clone(),
                    source,
                })
            })?;
            FlightTime::simulated(&run_dir.join("flight.clock")).map_err(FlightError::SimClock)?
        }
    };
    let mut sup = Supervisor::start(SupervisorOptions {
        workflow,
        flight: name.clone(),
        aeris_exe: role_executable,
        run_dir: run_dir.clone(),
        autopilot,
        sim_clock: time.segment().map(Path::to_path_buf),
    })
    .map_err(|e| FlightError::Start(Box::new(e)))?;
    time.expect(sup.roles().len());
    if let Some(on) = dynamic {
        sup.set_dynamic(on);
    }
    if let Some((providers, accelerators)) = onnx_accelerators() {
        sup.set_accelerators(providers, accelerators);
    }
    send(FlightEvent::Started {
        flight: name.clone(),
        roles: sup.roles().len(),
        logs: run_dir.join("logs"),
        instruction: mission.instruction.clone(),
        accelerators: accelerator_line(sup.registry()),
        priority: sup.priority().to_string(),
    });
    shared.set_roles(&sup);
    shared.set_phase(FlightPhase::WaitingForRoles);
    let _ = started.send(());

    sup.wait_ready(READY_TIMEOUT)
        .map_err(|e| FlightError::NotReady(Box::new(e)))?;
    send(FlightEvent::Ready);
    shared.set_phase(FlightPhase::Flying);
    let start_ns = time.now_ns();
    let mut monitor =
        FlightMonitor::new(sup.bus(), &mission, start_ns).map_err(FlightError::Subscribe)?;
    monitor
        .watch_fleet(sup.bus(), vehicles)
        .map_err(FlightError::Subscribe)?;
    // the flight's time (simulated or wall) since it started flying
    let elapsed = |time: &FlightTime| Duration::from_nanos(time.now_ns().saturating_sub(start_ns));
    let mut last_progress = Instant::now();
    let mut failure: Option<FlightFailure> = None;
    let (mut swaps_done, mut swaps_failed) = (0u64, 0u64);
    let mut memory = crate::memory::MemoryWatch::default();
    let mut compute = ComputeWatch::default();
    let wall_start = Instant::now();
    loop {
        let step_events = sup
            .step()
            .map_err(|e| FlightError::Supervise(Box::new(e)))?;
        for event in &step_events {
            match event {
                SupervisorEvent::SwapDone { .. } => swaps_done += 1,
                SupervisorEvent::SwapFailed { .. } => swaps_failed += 1,
                // a recorder that gave up leaves the flight unrecorded, not failed
                SupervisorEvent::RoleGaveUp { name }
                    if record.as_ref().is_none_or(|(_, role)| role != name) =>
                {
                    failure = Some(FlightFailure::RoleGaveUp { role: name.clone() });
                }
                _ => {}
            }
            send(FlightEvent::Supervisor(event.clone()));
        }
        if !time.step_done() {
            // simulated time still inside the step period (a role is working): the
            // supervisor steps on, and the monitor, the stop rules and the hook wait for
            // the period's end, so that they see the flight at the same instants every run
            if let Some(request) = shared.stop_requested() {
                failure = Some(request);
            }
            // a role that hangs in its turn is killed by the supervisor's stall check, and
            // time moves on; past twice that limit, nothing will move it
            if let Some((stood, pid)) = time.standing_still()
                && stood > sim_stuck_after
            {
                failure = Some(FlightFailure::SimTimeStuck {
                    stood_s: stood.as_secs_f64(),
                    pid,
                });
            }
            if failure.is_some() {
                break;
            }
            time.pass(STEP_PERIOD);
            continue;
        }
        monitor.poll().map_err(FlightError::Telemetry)?;
        compute.observe(monitor.trace(), &sup, deadline_ms.saturating_mul(1_000_000));
        memory.sample(&sup);
        for event in monitor.take_autopilot_events() {
            send(FlightEvent::Autopilot(event));
        }
        if let Some(diagnosis) = monitor.silent_autopilot() {
            failure = Some(FlightFailure::AutopilotSilent { diagnosis });
        }
        if let Some(collision) = monitor.fleet().and_then(|f| f.collision()) {
            failure = Some(FlightFailure::Collision(collision));
        }
        // only before a first cycle: the hub's counters are not looked up on every step after
        if vehicles <= 1
            && monitor.cycles() == 0
            && let Some(overdue) = crate::first_decision::overdue(
                elapsed(&time),
                monitor.cycles(),
                hub_counters(&sup),
                heartbeat,
                deadline_ms,
            )
        {
            failure = Some(FlightFailure::NoFirstDecision(overdue));
        }
        let hook_done = hook
            .step(&mut StepContext {
                supervisor: &mut sup,
                monitor: &monitor,
                events: &step_events,
                now_ns: time.now_ns(),
                events_out: events,
            })
            .map_err(FlightError::Hook)?;
        let progress = progress(&monitor, &mission, elapsed(&time), &sup);
        sup.set_progress(
            progress.step,
            progress.steps,
            progress.distance_to_goal_m.unwrap_or(-1.0),
            progress.ct_mean_s as f32,
        );
        let done = match stop {
            StopRule::Goal => monitor.reached_goal(),
            StopRule::Cycles(n) => monitor.cycles() >= n,
            StopRule::Landed => monitor.landed_after_flight(),
            StopRule::Hook => false,
        };
        if done || hook_done || failure.is_some() {
            break;
        }
        if elapsed(&time) > max_duration {
            failure = Some(FlightFailure::TimeLimit {
                rule: stop,
                limit_s: max_duration.as_secs_f64(),
            });
            break;
        }
        if let Some(request) = shared.stop_requested() {
            failure = Some(request);
            break;
        }
        if last_progress.elapsed() >= PROGRESS_PERIOD {
            last_progress = Instant::now();
            send(FlightEvent::Progress(progress.clone()));
            if monitor.invalid_reports() > 0 {
                send(FlightEvent::InvalidReports(monitor.invalid_reports()));
            }
        }
        // a role's process, state, variant or CPUs change only with an event
        if !step_events.is_empty() {
            shared.set_roles(&sup);
        }
        shared.update(|s| s.progress = Some(progress));
        time.pass(STEP_PERIOD);
    }
    let duration = elapsed(&time).as_secs_f64();
    let _ = monitor.poll();
    compute.observe(monitor.trace(), &sup, deadline_ms.saturating_mul(1_000_000));
    let mut summary = monitor.summary(&name, duration, u64::from(sup.total_restarts()));
    summary.clock = clock;
    summary.wall_s = wall_start.elapsed().as_secs_f64();
    summary.ct_compute_mean_s = mean_std(compute.samples_s()).map_or(0.0, |(mean, _)| mean);
    summary.ct_compute_p95_s = percentile(compute.samples_s(), 95.0).unwrap_or(0.0);
    summary.eer_compute = compute.eer();
    // before a first commit the hub reports no cycle: its counters are in its heartbeats
    if monitor.cycles() == 0
        && let Some(hub) = hub_counters(&sup)
    {
        summary.hub.decisions_received = hub.received;
        summary.hub.decisions_rejected = hub.rejected;
        summary.hub.decisions_late = hub.late;
    }
    summary.migrations = u64::from(sup.total_migrations());
    summary.variant_steps = u64::from(sup.total_variant_steps());
    summary.stalls = sup.roles().iter().map(|r| u64::from(r.stalls())).sum();
    summary.swaps_done = swaps_done;
    summary.swaps_failed = swaps_failed;
    summary.links = sup.status().links().iter().map(LinkSummary::of).collect();
    summary.priority = sup.priority().mechanism().to_string();
    summary.priority_detail = sup.priority().to_string();
    summary.memory = memory.summary();
    if let Some(fleet) = summary.fleet.as_mut() {
        fleet.formation = Some(formation_tally(&sup));
    }
    let recorder_heartbeat = record.as_ref().and_then(|(_, role)| {
        sup.roles()
            .iter()
            .find(|r| r.name() == role)
            .and_then(|r| r.last_heartbeat().copied())
    });
    shared.set_phase(FlightPhase::ShuttingDown);
    let shutdown = sup.shutdown(SHUTDOWN_GRACE);
    // after the shutdown: the recorder has finished its file (or been killed)
    summary.recording = record
        .as_ref()
        .map(|(path, _)| RecordingSummary::new(path, recorder_heartbeat.as_ref()));
    shared.update(|s| {
        for r in &mut s.roles {
            r.pid = None;
            r.state = RoleState::Stopped;
        }
    });
    send(FlightEvent::Finished {
        failure: failure.clone(),
        shutdown,
    });
    let trace_path = run_dir.join("cycles.jsonl");
    write_trace(&trace_path, monitor.trace()).map_err(|source| FlightError::WriteTrace {
        path: trace_path,
        source,
    })?;
    let outcome = FlightOutcome {
        summary,
        failure,
        ct_samples_s: monitor.ct_samples_s().to_vec(),
        ct_compute_samples_s: compute.samples_s().to_vec(),
        compute_misses: compute.misses(),
        trace: monitor.trace().to_vec(),
    };
    Ok((outcome, hook))
}

/// The hub's last heartbeat counters (a flight of one vehicle has one hub).
fn hub_counters(sup: &Supervisor) -> Option<HubBeatCounters> {
    sup.roles()
        .iter()
        .find(|r| r.kind() == RoleKind::Hub)
        .and_then(|r| r.last_heartbeat())
        .map(|hb| HubBeatCounters::from_heartbeat(&hb.counters))
}

/// The formation role's last heartbeat counters, read.
fn formation_tally(sup: &Supervisor) -> crate::fleet::FormationTally {
    let counters = sup
        .roles()
        .iter()
        .find(|r| r.kind() == RoleKind::Formation)
        .and_then(|r| r.last_heartbeat())
        .map_or([0; 8], |h| h.counters);
    crate::fleet::FormationTally::from_counters(counters)
}

/// Where the flight is now.
fn progress(
    monitor: &FlightMonitor,
    mission: &MissionSpec,
    elapsed: Duration,
    sup: &Supervisor,
) -> FlightProgress {
    let restarts = sup.total_restarts();
    let (step, steps) = monitor.active_step();
    let fleet = monitor.fleet().map(|fleet| FleetProgress {
        positions: fleet.positions(),
        closest_m: fleet.summary().min_separation_m,
        formation: formation_tally(sup),
    });
    FlightProgress {
        elapsed_s: elapsed.as_secs_f64(),
        step,
        steps,
        step_text: usize::from(step)
            .checked_sub(1)
            .and_then(|i| mission.subgoals.get(i))
            .map(|s| s.text.clone()),
        distance_to_goal_m: monitor.distance_to_goal(),
        position: monitor.position(),
        ct_mean_s: monitor.ct_mean_s(),
        eer: monitor.eer(),
        rejected: monitor.rejected(),
        restarts,
        fleet,
    }
}

/// Write a flight's cycle trace, one JSON object per line.
fn write_trace(path: &Path, trace: &[CycleTrace]) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for c in trace {
        serde_json::to_writer(&mut out, c)?;
        out.write_all(b"\n")?;
    }
    out.flush()
}
