//! A replayed flight (`aeris replay`): the recording is the camera and the vehicle, the
//! roles under test (perception, reasoning, hub, with any variant) run live on it, and
//! every semantic cycle's recorded decision is set beside the replayed one.
//!
//! - The workflow is the recorded flight's ([`aeris_record::read::RecordedFlight`]) with
//!   its vehicle, controllers, camera and recorder replaced by one replay source
//!   ([`aeris_record::replay`]), which publishes the recording's exact frames and telemetry
//!   at their recorded times (scaled by [`ReplayRequest::speed`], the heartbeat with
//!   them).
//! - The replay records its own decisions and hub reports (`replay.mcap` in its run
//!   directory, for Foxglove); after the flight both recordings are read by the same code
//!   ([`compare`]).
//! - A replayed decision pairs with the recorded one whose cycle started at the same frame
//!   capture (moved back onto the recording's clock); a pair is *identical* when the
//!   decision's content (waypoint, yaw, speed, altitude, radius, confidence, step,
//!   action) is equal bit for bit. Stamps, sequence numbers and the publisher's instance
//!   differ by nature and are not compared.
//! - A replay starts at a recorded cycle's frame (the first at or after `from`), so the
//!   reasoner's heartbeat has the recorded phase. Started mid-flight, the roles start
//!   fresh (a planner at step 1, an empty map): compare from the start for determinism.

use crate::FlightWatcher;
use crate::error::FlightError;
use crate::event::StopRule;
use crate::handle::Flight;
use crate::hook::{HookError, StepContext, StepHook};
use crate::monitor::FlightOutcome;
use crate::overrides::{Overrides, VariantChoice};
use aeris_orchestrator::restart::RestartPolicy;
use aeris_orchestrator::workflow::{
    Executor, ExecutorCpus, RoleDecl, SchedulingSpec, Workflow, WorkflowError,
};
use aeris_record::read::{ReadError, RecordedFlight, Recording};
use aeris_schemas::RoleKind;
use aeris_schemas::{Decision, HubReport, LanguageCounters, ReplayCounters, topics};
use serde::Serialize;
use std::path::{Path, PathBuf};

mod compare;
pub use compare::{CompareRow, DecisionView, ReplayCycle, RunFigures, compare, same_content};
use compare::{figures, pair};

/// Variant of the replay source role (kind `replay`).
const SOURCE_VARIANT: &str = "mcap";
/// The replay's own recording, in its run directory.
pub const REPLAY_RECORDING: &str = "replay.mcap";
/// Kinds a replay does not run: the recording stands in for them.
const REPLACED_KINDS: [RoleKind; 5] = [
    RoleKind::Vehicle,
    RoleKind::Controller,
    RoleKind::Camera,
    RoleKind::Recorder,
    RoleKind::Replay,
];

/// What to replay, and how.
#[derive(Debug, Clone)]
pub struct ReplayRequest {
    /// The recording (made with `aeris run --record`).
    pub path: PathBuf,
    /// Start at the first recorded cycle at or after this many seconds into the recording.
    pub from_s: Option<f64>,
    /// End this many seconds into the recording (default: its end).
    pub to_s: Option<f64>,
    /// Time scale: 2 replays twice as fast (the heartbeat and deadline scale with it).
    pub speed: f64,
    /// Roles run with another variant than the recorded one.
    pub variants: Vec<VariantChoice>,
    /// Flight name (default `replay-PID`).
    pub name: Option<String>,
    /// Run directory (default `$TMPDIR/aeris/NAME`).
    pub run_dir: Option<PathBuf>,
    /// The executable the roles run as (default: this one).
    pub role_executable: Option<PathBuf>,
    /// The language-model engine's offload check for the replay's flights
    /// ([`crate::FlightBuilder::language_offload_check`]).
    pub offload_check: Option<crate::executors::OffloadCheck>,
    /// The clock the replay runs on: on simulated time ([`crate::FlightClock::Sim`]) the
    /// roles take their turns at the recorded instants and the replay runs as fast as they
    /// compute (`aeris replay --speed max`; `speed` is then 1).
    pub clock: crate::FlightClock,
}

impl ReplayRequest {
    /// Replay `path` whole, at recorded speed, with the recorded variants.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            from_s: None,
            to_s: None,
            speed: 1.0,
            variants: Vec::new(),
            name: None,
            run_dir: None,
            role_executable: None,
            offload_check: None,
            clock: crate::FlightClock::Wall,
        }
    }
}

/// Why a replay could not run.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The recording could not be read (or another schema version made it).
    #[error("reading the recording")]
    Read(#[from] ReadError),
    /// The recording holds no exact frames.
    #[error(
        "{} holds no exact frames (recorded with --record-no-exact-frames): it cannot be \
         replayed",
        path.display()
    )]
    NotReplayable {
        /// The recording.
        path: PathBuf,
    },
    /// The recording is of a flight of several vehicles (each vehicle's topics under its
    /// scope, `v1/...`): a replay replays one vehicle's perception and reasoning.
    #[error(
        "{} is a flight of {vehicles} vehicles (their topics under v1/ .. v{vehicles}/): \
         aeris replay replays a flight of one vehicle",
        path.display()
    )]
    Fleet {
        /// The recording.
        path: PathBuf,
        /// Vehicles whose telemetry it holds.
        vehicles: u8,
    },
    /// The recording holds no decision in the range asked for.
    #[error("{} holds no recorded decision from {from_s:.1} s to {to_s:.1} s", path.display())]
    NoCycles {
        /// The recording.
        path: PathBuf,
        /// Start of the range (s into the recording).
        from_s: f64,
        /// End of the range (s into the recording).
        to_s: f64,
    },
    /// The speed is not a positive number, or does not divide the flight's periods into
    /// whole milliseconds (a rounded heartbeat would pick other frames).
    #[error(
        "--speed {given}: must be positive and divide the heartbeat ({heartbeat_ms} ms) and \
         the model roles' intervals into whole milliseconds (e.g. 0.5, 2 or 4)"
    )]
    Speed {
        /// The speed given.
        given: f64,
        /// The recorded heartbeat period (ms).
        heartbeat_ms: u64,
    },
    /// The replay's workflow is not valid (a variant its kind does not have, ...).
    #[error("the replay's workflow")]
    Workflow(#[source] WorkflowError),
    /// The replayed flight failed.
    #[error("the replayed flight")]
    Flight(#[from] FlightError),
    /// The replayed flight ended before the recording was replayed.
    #[error("the replayed flight ended early: {why}")]
    Ended {
        /// Why.
        why: String,
    },
}

/// What a replay found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplaySummary {
    /// The recording replayed.
    pub recording: PathBuf,
    /// The replay's own recording.
    pub replay_recording: PathBuf,
    /// The variant of every reasoning and perception role in the replay (`ROLE=VARIANT`).
    pub variants: Vec<String>,
    /// Start of the replayed range (s into the recording).
    pub from_s: f64,
    /// End of it (s).
    pub to_s: f64,
    /// Time scale.
    pub speed: f64,
    /// The clock the replay ran on (`sim`: `aeris replay --speed max`).
    pub clock: crate::FlightClock,
    /// Recorded cycles in the range.
    pub recorded_cycles: usize,
    /// Replayed cycles.
    pub replayed_cycles: usize,
    /// Cycles both decided on the same frame.
    pub paired: usize,
    /// Of those, identical bit for bit.
    pub identical: usize,
    /// Recorded cycles decided on the telemetry alone (no frame to pair them by): listed,
    /// not counted in the agreement.
    pub recorded_without_frame: usize,
    /// `identical / (recorded_cycles - recorded_without_frame)`.
    pub agreement: f64,
    /// Cycles with the same action and step, over the recorded cycles decided on a frame.
    pub action_agreement: f64,
    /// The recording, in the range.
    pub recorded: RunFigures,
    /// The replay.
    pub replayed: RunFigures,
    /// Mean tokens per second of a language-model reasoner (`None` for others).
    pub tokens_per_s: Option<f64>,
    /// Most a replayed message was published after its time (ms).
    pub late_max_ms: f64,
}

/// A replay's cycles and summary, and the replayed flight's own outcome.
#[derive(Debug, Clone)]
pub struct ReplayReport {
    /// Every cycle, in order of capture.
    pub cycles: Vec<ReplayCycle>,
    /// The summary.
    pub summary: ReplaySummary,
    /// The replayed decisions, for comparing variants with each other.
    pub decisions: Vec<(u64, Decision)>,
    /// The replayed flight's outcome.
    pub outcome: FlightOutcome,
}

/// Kinds whose roles keep the first frame of every `interval_ms` of the clock
/// (`aeris_roles::vision::FrameStride`).
const STRIDED_KINDS: [RoleKind; 3] = [
    RoleKind::TextReader,
    RoleKind::Detector,
    RoleKind::Occupancy,
];
/// Their default interval (ms), `aeris_roles::vision::DEFAULT_INTERVAL_MS`.
const DEFAULT_INTERVAL_MS: u64 = 2000;

/// The frame intervals (ms) of `flight`'s strided roles (the variants that run no model
/// keep every frame, but an interval does them no harm).
fn frame_intervals_ms(flight: &RecordedFlight) -> Vec<u64> {
    flight
        .roles
        .iter()
        .filter(|r| RoleKind::from_name(&r.kind).is_some_and(|k| STRIDED_KINDS.contains(&k)))
        .map(|r| frame_interval_ms(&r.params))
        .collect()
}

/// A strided role's frame interval (ms) from its parameters.
fn frame_interval_ms(params: &serde_json::Map<String, serde_json::Value>) -> u64 {
    params
        .get("interval_ms")
        .and_then(|v| v.as_f64())
        .map_or(DEFAULT_INTERVAL_MS, |v| v.max(1.0) as u64)
}

/// `ms / speed` when it is a whole number of milliseconds.
fn scaled_ms(ms: u64, speed: f64) -> Option<u64> {
    let v = ms as f64 / speed;
    (v >= 1.0 && (v - v.round()).abs() < 1e-6).then(|| v.round() as u64)
}

/// The alignment of the replay's start (ns, recording clock): the least common multiple of
/// the strided roles' intervals, so each keeps the frames it kept in flight; 0 for none.
fn start_alignment_ns(flight: &RecordedFlight) -> u64 {
    let gcd = |mut a: u64, mut b: u64| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    frame_intervals_ms(flight)
        .into_iter()
        .fold(0u64, |l, i| if l == 0 { i } else { l / gcd(l, i) * i })
        .saturating_mul(1_000_000)
}

/// The workflow that replays `flight` from the recording at `path`: its roles minus the
/// vehicle, controllers, camera and recorder, plus the replay source; its heartbeat,
/// deadline and frame intervals divided by `speed` (which must leave them whole
/// milliseconds: [`ReplayError::Speed`] from [`replay`]).
pub fn replay_workflow(
    flight: &RecordedFlight,
    path: &Path,
    from_ns: u64,
    to_ns: u64,
    speed: f64,
) -> Result<Workflow, WorkflowError> {
    let mut timing = flight.timing.clone();
    let scale = |ms: u64| scaled_ms(ms, speed).unwrap_or(((ms as f64 / speed) as u64).max(1));
    timing.heartbeat_period_ms = scale(timing.heartbeat_period_ms);
    timing.decision_deadline_ms = scale(timing.decision_deadline_ms);
    let mut executors: Vec<Executor> = flight
        .executors
        .iter()
        .map(|name| Executor {
            name: name.clone(),
            cpus: ExecutorCpus::Auto,
            host: None,
            accelerator: None,
        })
        .collect();
    if executors.is_empty() {
        executors.push(Executor {
            name: "replay".into(),
            cpus: ExecutorCpus::Auto,
            host: None,
            accelerator: None,
        });
    }
    executors.sort_by(|a, b| a.name.cmp(&b.name));
    let mut source_params = serde_json::Map::new();
    source_params.insert("path".into(), path.to_string_lossy().into_owned().into());
    source_params.insert("from_ns".into(), from_ns.into());
    source_params.insert("to_ns".into(), to_ns.into());
    source_params.insert("speed".into(), speed.into());
    // the vehicle's state at the first frame's capture: a heartbeat of telemetry before it
    source_params.insert(
        "lead_ns".into(),
        flight
            .timing
            .heartbeat_period_ms
            .saturating_mul(1_000_000)
            .into(),
    );
    source_params.insert("align_ns".into(), start_alignment_ns(flight).into());
    let mut source = RoleDecl::new(
        "replay",
        RoleKind::Replay,
        SOURCE_VARIANT,
        Some(executors[0].name.clone()),
        source_params,
    );
    // a restarted source would replay from the start on another offset: the replay fails
    // instead ([`ReplayHook`])
    source.restart = RestartPolicy::Never;
    let mut roles = vec![source];
    for r in &flight.roles {
        let kind = RoleKind::from_name(&r.kind).ok_or_else(|| WorkflowError::UnknownKind {
            role: r.name.clone(),
            kind: r.kind.clone(),
            known: RoleKind::known_names(),
        })?;
        if REPLACED_KINDS.contains(&kind) {
            continue;
        }
        let mut params = r.params.clone();
        if STRIDED_KINDS.contains(&kind) {
            let interval = frame_interval_ms(&r.params);
            params.insert("interval_ms".into(), scale(interval).into());
        }
        let executor = r
            .executor
            .clone()
            .filter(|e| executors.iter().any(|x| &x.name == e));
        let mut role = RoleDecl::new(&r.name, kind, &r.variant, executor, params);
        role.variants = r.variants.clone();
        roles.push(role);
    }
    let workflow = Workflow {
        scheduling: SchedulingSpec::defaults(&timing),
        timing,
        feedback: Vec::new(),
        camera: flight.camera.clone(),
        mission: flight.mission.clone(),
        executors,
        hosts: Vec::new(),
        roles,
        fleet: Default::default(),
    };
    workflow.validate()?;
    Ok(workflow)
}

/// Ends the replayed flight once the source has published the whole range and one more
/// heartbeat (and deadline) has passed for the last decision; keeps the source's clock
/// offset and the reasoner's token rate.
struct ReplayHook {
    /// The replay's heartbeat plus its deadline (ns): how long the last decision may take.
    last_wait_ns: u64,
    /// When the hook saw that the source had replayed everything (the flight's clock,
    /// simulated or wall).
    done_at: Option<u64>,
    offset: Option<(u64, i64)>,
    late_max_us: u64,
    /// The source could not read the recording to its end.
    source_failed: bool,
    reasoner: Option<String>,
    last_decisions: u64,
    tokens_per_s: Vec<f64>,
}

impl StepHook for ReplayHook {
    fn step(&mut self, ctx: &mut StepContext<'_>) -> Result<bool, HookError> {
        let source = ctx.supervisor.role("replay");
        if self.done_at.is_none()
            && source.is_some_and(|r| {
                matches!(
                    r.state(),
                    aeris_orchestrator::supervisor::RoleState::Stopped
                        | aeris_orchestrator::supervisor::RoleState::GaveUp
                )
            })
        {
            return Err(
                "the replay source stopped before the end of the recording (see its log)".into(),
            );
        }
        if let Some(hb) = source.and_then(|r| r.last_heartbeat()) {
            let c = ReplayCounters::from_heartbeat(&hb.counters);
            if c.started == 1 {
                self.offset = Some((c.start, c.offset as i64));
            }
            self.late_max_us = self.late_max_us.max(c.late_max_us);
            self.source_failed |= hb.status == aeris_schemas::RoleStatus::Degraded as u8;
            if c.done == 1 && self.done_at.is_none() {
                self.done_at = Some(ctx.now_ns);
                ctx.note("replay: the recording is replayed; waiting one heartbeat for the last decision");
            }
        }
        if let Some(c) = self
            .reasoner
            .as_deref()
            .and_then(|name| ctx.supervisor.role(name))
            .filter(|r| {
                aeris_orchestrator::workflow::LANGUAGE_MODEL_VARIANTS
                    .contains(&(RoleKind::Reasoning, r.variant()))
            })
            .and_then(|r| r.last_heartbeat())
            .map(|hb| LanguageCounters::from_heartbeat(&hb.counters))
            && c.decisions != self.last_decisions
        {
            self.last_decisions = c.decisions;
            if c.tokens_per_s_x100 > 0 {
                self.tokens_per_s.push(c.tokens_per_s_x100 as f64 / 100.0);
            }
        }
        Ok(self
            .done_at
            .is_some_and(|t| ctx.now_ns.saturating_sub(t) >= self.last_wait_ns))
    }
}

/// Replay `request.path` (see the module docs), `watcher` seeing the replayed flight's
/// events.
pub fn replay(
    request: &ReplayRequest,
    watcher: &mut dyn FlightWatcher,
) -> Result<ReplayReport, ReplayError> {
    let mut recording = Recording::open(&request.path)?;
    let flight = recording.flight().clone();
    // a flight of several vehicles has each vehicle's topics in its scope (`v1/...`)
    let vehicles = (1..=topics::MAX_FLIGHT_VEHICLES)
        .filter(|k| recording.message_count(&topics::in_vehicle(*k, topics::VEHICLE_TELEMETRY)) > 0)
        .count() as u8;
    if vehicles > 0 {
        return Err(ReplayError::Fleet {
            path: request.path.clone(),
            vehicles,
        });
    }
    let speed = request.speed;
    let periods = [
        flight.timing.heartbeat_period_ms,
        flight.timing.decision_deadline_ms,
    ];
    let whole = periods
        .iter()
        .chain(&frame_intervals_ms(&flight))
        .all(|ms| scaled_ms(*ms, speed).is_some());
    if !(speed.is_finite() && speed > 0.0 && whole) {
        return Err(ReplayError::Speed {
            given: speed,
            heartbeat_ms: flight.timing.heartbeat_period_ms,
        });
    }
    if !flight.exact_frames || recording.message_count("camera/rgb/frame") == 0 {
        return Err(ReplayError::NotReplayable {
            path: request.path.clone(),
        });
    }
    let (start, end) = recording.time_range().unwrap_or((0, 0));
    let at = |s: Option<f64>, default: u64| {
        s.map_or(default, |s| start.saturating_add((s.max(0.0) * 1e9) as u64))
    };
    let (from_ns, to_ns) = (at(request.from_s, start), at(request.to_s, end + 1));
    let recorded: Vec<Decision> = recording.typed(topics::REASONING_DECISION)?;
    // the first recorded cycle at or after `from`, started on a frame
    let frames: Vec<u64> = {
        let mut captures = Vec::new();
        recording.for_each(
            &["camera/rgb/frame"],
            Some(from_ns),
            Some(to_ns),
            |_, t, _| {
                captures.push(t);
                true
            },
        )?;
        captures
    };
    let first = recorded
        .iter()
        .map(|d| d.cycle_start_ns)
        .filter(|t| *t >= from_ns && *t < to_ns && frames.binary_search(t).is_ok())
        .min()
        .ok_or_else(|| ReplayError::NoCycles {
            path: request.path.clone(),
            from_s: from_ns.saturating_sub(start) as f64 * 1e-9,
            to_s: to_ns.min(end).saturating_sub(start) as f64 * 1e-9,
        })?;
    let workflow = replay_workflow(&flight, &request.path, first, to_ns, request.speed)
        .map_err(ReplayError::Workflow)?;
    let reasoner = workflow
        .roles
        .iter()
        .find(|r| r.kind == RoleKind::Reasoning)
        .map(|r| r.name.clone());
    let span_s = to_ns.min(end).saturating_sub(first) as f64 * 1e-9 / request.speed;
    let overrides = Overrides {
        variants: request.variants.clone(),
        max_duration_s: Some(span_s + 60.0),
        dynamic: None,
        // an A/B comparison keeps each role on the variant it was given
        fixed_variants: true,
    };
    let name = request
        .name
        .clone()
        .unwrap_or_else(|| format!("replay-{}", std::process::id()));
    let mut builder = Flight::builder(workflow)
        .name(name)
        .overrides(overrides)
        .stop_when(StopRule::Hook)
        .clock(request.clock)
        .record(REPLAY_RECORDING)
        .record_frame_every(0)
        .record_exact_frames(false)
        .record_topics(vec![
            topics::REASONING_DECISION.into(),
            topics::HUB_REPORT.into(),
            topics::HUB_SETPOINT.into(),
            topics::PERCEPTION_STATE.into(),
            topics::HEARTBEAT.into(),
        ]);
    if let Some(dir) = &request.run_dir {
        builder = builder.run_dir(dir.clone());
    }
    if let Some(check) = request.offload_check {
        builder = builder.language_offload_check(check);
    }
    if let Some(exe) = &request.role_executable {
        builder = builder.role_executable(exe.clone());
    }
    let hook = ReplayHook {
        last_wait_ns: (scaled_ms(flight.timing.heartbeat_period_ms, speed).unwrap_or(1)
            + scaled_ms(flight.timing.decision_deadline_ms, speed).unwrap_or(1))
            * 1_000_000,
        done_at: None,
        offset: None,
        late_max_us: 0,
        source_failed: false,
        reasoner,
        last_decisions: 0,
        tokens_per_s: Vec::new(),
    };
    let started = builder.step_hook(hook).start()?;
    let run_dir = started.run_dir().to_path_buf();
    let variants = started
        .status()
        .roles
        .iter()
        .filter(|r| !matches!(r.kind, RoleKind::Replay | RoleKind::Recorder))
        .map(|r| format!("{}={}", r.name, r.variant))
        .collect();
    let (outcome, hook) = started.watch(watcher)?;
    if let Some(f) = &outcome.failure
        && hook.done_at.is_none()
    {
        return Err(ReplayError::Ended { why: f.to_string() });
    }
    if hook.source_failed {
        return Err(ReplayError::Ended {
            why: format!(
                "the recording could not be read to its end (see {})",
                run_dir.join("logs/replay.log").display()
            ),
        });
    }
    let Some((t0_rec, offset)) = hook.offset else {
        return Err(ReplayError::Ended {
            why: "the replay source never started".into(),
        });
    };
    let replay_path = run_dir.join(REPLAY_RECORDING);
    let mut replayed_rec = Recording::open(&replay_path)?;
    let replayed: Vec<Decision> = replayed_rec.typed(topics::REASONING_DECISION)?;
    let replayed_reports: Vec<HubReport> = replayed_rec.typed(topics::HUB_REPORT)?;
    let recorded_reports: Vec<HubReport> = recording.typed(topics::HUB_REPORT)?;
    // the replay's clock back onto the recording's
    let t0_wall = (t0_rec as i64).wrapping_sub(offset) as u64;
    let to_recording =
        |t: u64| t0_rec.saturating_add((t.saturating_sub(t0_wall) as f64 * speed) as u64);
    let recorded_in: Vec<(u64, Decision)> = recorded
        .iter()
        .filter(|d| d.cycle_start_ns >= first && d.cycle_start_ns < to_ns)
        .map(|d| (d.cycle_start_ns, *d))
        .collect();
    // cycles decided on the telemetry alone start at the reasoner's poll, not at a frame:
    // nothing to pair them by
    let without_frame = recorded_in
        .iter()
        .filter(|(t, _)| frames.binary_search(t).is_err())
        .count();
    // decisions after the range are the reasoner's on telemetry alone, once the frames
    // stopped: not part of the replay
    let replayed_in: Vec<(u64, Decision)> = replayed
        .iter()
        .map(|d| (to_recording(d.cycle_start_ns), *d))
        .filter(|(t, _)| *t >= first && *t < to_ns.min(end + 1))
        .collect();
    let cycles = pair(&recorded_in, &replayed_in, start);
    let paired = cycles
        .iter()
        .filter(|c| c.recorded.is_some() && c.replayed.is_some())
        .count();
    let identical = cycles.iter().filter(|c| c.identical).count();
    let same_action = cycles
        .iter()
        .filter(|c| match (&c.recorded, &c.replayed) {
            (Some(a), Some(b)) => a.action == b.action && a.step == b.step,
            _ => false,
        })
        .count();
    let share = |n: usize| match recorded_in.len() - without_frame {
        0 => 0.0,
        total => n as f64 / total as f64,
    };
    // both runs' reports over the same range of the recording
    let recorded_reports: Vec<HubReport> = recorded_reports
        .into_iter()
        .filter(|r| r.publish_ns >= first && r.publish_ns < to_ns)
        .collect();
    let replayed_reports: Vec<HubReport> = replayed_reports
        .into_iter()
        .filter(|r| {
            let t = to_recording(r.publish_ns);
            t >= first && t < to_ns
        })
        .collect();
    let summary = ReplaySummary {
        recording: request.path.clone(),
        replay_recording: replay_path,
        variants,
        from_s: first.saturating_sub(start) as f64 * 1e-9,
        to_s: to_ns.min(end).saturating_sub(start) as f64 * 1e-9,
        speed,
        clock: request.clock,
        recorded_cycles: recorded_in.len(),
        replayed_cycles: replayed_in.len(),
        recorded_without_frame: without_frame,
        paired,
        identical,
        agreement: share(identical),
        action_agreement: share(same_action),
        recorded: figures(recorded_in.len(), &recorded_reports),
        replayed: figures(replayed_in.len(), &replayed_reports),
        tokens_per_s: (!hook.tokens_per_s.is_empty())
            .then(|| hook.tokens_per_s.iter().sum::<f64>() / hook.tokens_per_s.len() as f64),
        late_max_ms: hook.late_max_us as f64 / 1000.0,
    };
    Ok(ReplayReport {
        cycles,
        summary,
        decisions: replayed_in,
        outcome,
    })
}
