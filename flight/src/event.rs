//! What a running flight tells its watchers: events as they happen, a status snapshot on
//! demand, and why it ended.

use aeris_orchestrator::supervisor::{RoleState, ShutdownReport, SupervisorEvent};
use aeris_schemas::RoleKind;
use std::path::PathBuf;

/// When a flight ends (besides a failure, the time limit or [`crate::Flight::stop`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopRule {
    /// When the vehicle reached the goal (the main job).
    Goal,
    /// After this many semantic cycles (benchmarks: heartbeats, goal or not).
    Cycles(u64),
    /// When the vehicle is on the ground after having flown, wherever that is (VLN
    /// episodes: the agent stopped).
    Landed,
    /// Only when the step hook says so (benchmarks that inject faults and then fly on).
    Hook,
}

/// Why a flight ended before its stop rule held.
#[derive(Debug, Clone, PartialEq)]
pub enum FlightFailure {
    /// A role spent its restart budget.
    RoleGaveUp {
        /// The role.
        role: String,
    },
    /// The mission's time limit passed before the stop rule held.
    TimeLimit {
        /// The rule that did not hold.
        rule: StopRule,
        /// The limit (s).
        limit_s: f64,
    },
    /// [`crate::Flight::stop`] ended it.
    Stopped,
    /// [`crate::Flight::interrupt`] ended it (a termination signal reached the process).
    Interrupted,
    /// The controller heard no autopilot HEARTBEAT within its link timeout.
    AutopilotSilent {
        /// The URL, the timeout and what was heard instead.
        diagnosis: String,
    },
    /// Two vehicles of the flight collided ([`crate::fleet::COLLISION_DISTANCE_M`]).
    Collision(crate::fleet::Collision),
    /// The hub committed no decision in the flight's first
    /// [`crate::first_decision::FIRST_DECISION_HEARTBEATS`] heartbeats.
    NoFirstDecision(crate::first_decision::NoFirstDecision),
    /// On simulated time, the flight's time stood still longer than any role may work or
    /// start (the supervisor's stall limit, twice): a turn that never ends.
    SimTimeStuck {
        /// Wall-clock seconds the time stood still.
        stood_s: f64,
        /// The role process holding the turn (or starting), when one does.
        pid: Option<u32>,
    },
}

impl core::fmt::Display for FlightFailure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FlightFailure::RoleGaveUp { role } => {
                write!(f, "role `{role}` exhausted its restart budget")
            }
            FlightFailure::TimeLimit { rule, limit_s } => match rule {
                StopRule::Goal => write!(f, "the goal was not reached within {limit_s:.0} s"),
                StopRule::Cycles(n) => {
                    write!(f, "{n} cycles did not complete within {limit_s:.0} s")
                }
                StopRule::Landed => write!(f, "the vehicle did not land within {limit_s:.0} s"),
                StopRule::Hook => {
                    write!(f, "the benchmark did not finish within {limit_s:.0} s")
                }
            },
            FlightFailure::Stopped => f.write_str("stopped"),
            FlightFailure::Interrupted => f.write_str("interrupted"),
            FlightFailure::AutopilotSilent { diagnosis } => f.write_str(diagnosis),
            FlightFailure::NoFirstDecision(why) => write!(f, "{why}"),
            FlightFailure::SimTimeStuck { stood_s, pid } => {
                write!(
                    f,
                    "the flight's simulated time stood still for {stood_s:.0} s of wall time"
                )?;
                match pid {
                    Some(pid) => write!(f, " (role process {pid} held its turn)"),
                    None => f.write_str(" (no role process held the turn)"),
                }
            }
            FlightFailure::Collision(c) => write!(
                f,
                "vehicles {} and {} collided: {:.2} m apart at [{:.1}, {:.1}, {:.1}] (under {} m)",
                c.vehicles.0,
                c.vehicles.1,
                c.distance_m,
                c.position[0],
                c.position[1],
                c.position[2],
                crate::fleet::COLLISION_DISTANCE_M
            ),
        }
    }
}

/// Where the flight is, every 2 s of flight (and in [`FlightStatus`] at every step).
#[derive(Debug, Clone, PartialEq)]
pub struct FlightProgress {
    /// Seconds since every role was up.
    pub elapsed_s: f64,
    /// The hub's active step (1-based; 0 before the first decision).
    pub step: u16,
    /// Steps of the mission.
    pub steps: u16,
    /// The active step's instruction; `None` before the first decision.
    pub step_text: Option<String>,
    /// Distance to the goal (m), when the goal and the position are known.
    pub distance_to_goal_m: Option<f32>,
    /// The vehicle's position `[N, E, U]` (m), once telemetry arrived.
    pub position: Option<[f32; 3]>,
    /// Mean cycle time so far (s).
    pub ct_mean_s: f64,
    /// Execution error rate so far (reused cycles over all).
    pub eer: f64,
    /// Decisions the hub rejected so far.
    pub rejected: u64,
    /// Role restarts so far.
    pub restarts: u32,
    /// A flight of several vehicles: where they are and how the formation goes.
    pub fleet: Option<FleetProgress>,
}

/// Where the vehicles of a formation flight are.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetProgress {
    /// Each vehicle's position `[N, E, U]` (vehicle 1 first; `None` before its telemetry).
    pub positions: Vec<Option<[f32; 3]>>,
    /// The closest two vehicles with live links came so far (m).
    pub closest_m: Option<f32>,
    /// The formation role's last report.
    pub formation: crate::fleet::FormationTally,
}

/// Something that happened to a flight, in order.
#[derive(Debug, Clone)]
pub enum FlightEvent {
    /// The supervisor started every role's process (their first heartbeats are awaited).
    Started {
        /// Flight name.
        flight: String,
        /// Roles started.
        roles: usize,
        /// Where the roles' logs are.
        logs: PathBuf,
        /// The mission's instruction.
        instruction: String,
        /// The accelerators the flight may use, as one line.
        accelerators: String,
        /// How the roles got priority over outside work, as one line.
        priority: String,
    },
    /// Every role sent its first heartbeat: the flight is on, its time limit runs.
    Ready,
    /// The supervisor reported this (restarts, swaps, moves, stalls, ...).
    Supervisor(SupervisorEvent),
    /// Where the flight is (every 2 s).
    Progress(FlightProgress),
    /// Hub reports failed validation and were not counted (total so far; sent after a
    /// progress event while there are any).
    InvalidReports(u64),
    /// Something happened on the autopilot link (bound, lost, back, a refused command).
    Autopilot(crate::AutopilotEvent),
    /// A line from the step hook (a benchmark's fault injected, a swap measured).
    Note(String),
    /// The flight ended and every role was stopped.
    Finished {
        /// Why it ended early, if it did.
        failure: Option<FlightFailure>,
        /// How each role stopped.
        shutdown: ShutdownReport,
    },
}

/// Where a flight is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightPhase {
    /// Starting the roles.
    Starting,
    /// Waiting for every role's first heartbeat.
    WaitingForRoles,
    /// Flying.
    Flying,
    /// Stopping the roles.
    ShuttingDown,
    /// Ended (with or without an error).
    Finished,
}

/// One role as the flight last saw it.
#[derive(Debug, Clone, PartialEq)]
pub struct RoleSnapshot {
    /// Role name.
    pub name: String,
    /// Role kind.
    pub kind: RoleKind,
    /// Variant running.
    pub variant: String,
    /// Its process, when one runs.
    pub pid: Option<u32>,
    /// Where it is in its life.
    pub state: RoleState,
    /// Restarts so far.
    pub restarts: u32,
    /// CPUs it runs on.
    pub cpus: String,
}

/// A snapshot of a flight ([`crate::Flight::status`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FlightStatus {
    /// Flight name.
    pub flight: String,
    /// Where it is in its life.
    pub phase: FlightPhase,
    /// Where the flight is, once it flies.
    pub progress: Option<FlightProgress>,
    /// Every role, once started.
    pub roles: Vec<RoleSnapshot>,
}

/// Who watches a flight ([`crate::Flight::watch`]): gets its events as they come, and may
/// ask it to end. A closure over `&FlightEvent` is a watcher that never interrupts.
pub trait FlightWatcher {
    /// One event.
    fn event(&mut self, event: &FlightEvent);

    /// `true` ends the flight as [`FlightFailure::Interrupted`] (asked between events, at
    /// least every 50 ms; e.g. once a termination signal arrived).
    fn interrupted(&self) -> bool {
        false
    }
}

impl<F: FnMut(&FlightEvent)> FlightWatcher for F {
    fn event(&mut self, event: &FlightEvent) {
        self(event)
    }
}
