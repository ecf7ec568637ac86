//! The supervisor: starts every role of a workflow as its own process, watches heartbeats,
//! restarts failed roles with backoff, and keeps the status board `aeris status` reads.
//!
//! The caller drives it: [`Supervisor::start`], then [`Supervisor::step`] every ~20 ms
//! (non-blocking), then [`Supervisor::shutdown`].
//!
//! With dynamic scheduling on (`[scheduling] dynamic`, the default), every
//! `interval_ms` the supervisor samples executor load and each role's scheduler time, checks
//! the initial binding once every role has figures, and re-binds the fewest roles that
//! restore the latency budget ([`crate::rebind`]); a move is live ([`Supervisor::migrate`]:
//! every thread of the process, same pid). A running role that falls silent while stopped
//! or making no CPU progress is stalled: it is killed and its restart policy applies.
//!
//! Role processes get `prctl(PR_SET_PDEATHSIG, SIGKILL)`, so they never outlive the
//! supervisor. Linux delivers that signal when the **thread** that forked them ends, so
//! drive a supervisor from one long-lived thread (the one that calls `start` and `step`).
//! Each role runs in its own process group: a Ctrl-C in the terminal reaches only the
//! supervisor, which then stops the roles in order.
//!
//! One file per concern; [`Supervisor`] (here) owns the roles and composes the parts, and
//! [`Supervisor::step`] runs them in turn:
//! - `role_runtime`: what it knows about one role ([`RoleRuntime`]: process, restarts,
//!   binding, heartbeat statistics and latency windows);
//! - `spawn`: starting role processes (`Launcher`: log, process group, pdeathsig, affinity,
//!   SCHED_IDLE, no inherited descriptors) and writing their specs;
//! - `heartbeats`: the heartbeat intake (`HeartbeatIntake`);
//! - `exits`: reaping exited roles, restart policies and backoff;
//! - `stalls`: stall detection (`StallDetector`);
//! - `service_audit`: services removed from under running roles (`ServiceAudit`);
//! - `swap`: hot swap make-before-break and the replaced processes (`RetiringProcesses`);
//! - `migration`: live moves between executors;
//! - `scheduling`: the scheduling tick and the re-binding policy hook;
//! - `initial_binding`: the initial binding check and its probes (`InitialCheck`);
//! - `variants`: the variant ladder hook;
//! - `control_service`: the `supervisor/control` service (`ControlService`);
//! - `board`: the status board (`StatusBoard`);
//! - `shutdown`: shutdown order and its report;
//! - `events`, `error`, `logs`: what a step reports, why things fail, role log tails.

mod board;
mod control_service;
mod cpu_watch;
mod error;
mod events;
mod exits;
mod heartbeats;
mod host_links;
mod initial_binding;
mod links;
mod logs;
mod migration;
mod recent_cycles;
mod replacement;
mod role_runtime;
mod scheduling;
mod service_audit;
mod shutdown;
mod spawn;
mod stalls;
mod swap;
mod variants;
mod warm_up_gate;

pub use error::{MigrateError, SilentRole, SupervisorError, SwapError};
pub use events::{Handover, Migration, MigrationTrigger, SupervisorEvent};
pub use logs::{LOG_TAIL_LINES, log_tail};
pub use migration::RoleMove;
pub use role_runtime::{LATENCY_WINDOW, RoleRuntime, RoleState};
pub use shutdown::{ShutdownEntry, ShutdownOutcome, ShutdownReport};
pub use swap::{DEFAULT_SWAP_READY_TIMEOUT, RETIRE_GRACE};

use crate::executors::ExecutorRegistry;
use crate::ladder::VariantLadder;
use crate::launch::{PlannedRole, plan_launch};
use crate::priority::{FlightPriority, Priority};
use crate::rebind::RebindPolicy;
use crate::workflow::{SchedulingSpec, Workflow};
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::bus::{BusError, FlightBus};
use aeris_schemas::RoleKind;
use aeris_schemas::{SupervisorStatus, topics};
use board::StatusBoard;
use control_service::ControlService;
use heartbeats::HeartbeatIntake;
use host_links::HostLinks;
use initial_binding::InitialCheck;
use scheduling::rebind_config;
use service_audit::ServiceAudit;
use spawn::{Launcher, write_spec};
use stalls::{StallDetector, WatchClock};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use swap::RetiringProcesses;
use variants::ladder_config;

/// Pause between steps inside [`Supervisor::wait_ready`].
const POLL: Duration = Duration::from_millis(20);

/// What the supervisor needs to start a flight.
#[derive(Debug, Clone)]
pub struct SupervisorOptions {
    /// The validated workflow.
    pub workflow: Workflow,
    /// Flight name: the namespace of every service (`[a-z0-9_-]{1,48}`).
    pub flight: String,
    /// The `aeris` executable; roles start as `aeris_exe role --spec FILE`.
    pub aeris_exe: PathBuf,
    /// Directory for `roles/NAME.json` specs and `logs/NAME.log` logs (created if missing).
    pub run_dir: PathBuf,
    /// External autopilot MAVLink URL: drop the vehicle role and give this URL to the
    /// controller. `None` flies the built-in vehicle.
    pub autopilot: Option<String>,
    /// The flight's simulated clock ([`aeris_runtime::clock::sim`]), whose segment every
    /// role joins; `None` flies on the wall clock.
    pub sim_clock: Option<PathBuf>,
}

/// The supervisor of one flight: its roles, and one part per concern (launching processes,
/// the heartbeat intake, exits and restarts, stalls, hot swaps, live moves and the
/// scheduling policy, the control service, the status board), which [`Supervisor::step`]
/// runs in turn.
pub struct Supervisor {
    /// Every role, in start order.
    roles: Vec<RoleRuntime>,
    /// The flight name.
    flight: String,
    /// Starts and numbers role processes.
    launcher: Launcher,
    /// Specs under `roles/`, logs under `logs/`, `scheduling.jsonl`.
    run_dir: PathBuf,
    /// Every role's heartbeats.
    heartbeats: HeartbeatIntake,
    /// The `supervisor` blackboard.
    board: StatusBoard,
    /// Events of calls between steps (swaps and moves begun), returned by the next step.
    pending: Vec<SupervisorEvent>,
    /// Processes replaced by swaps, until they exit.
    retiring: RetiringProcesses,
    /// The `supervisor/control` service.
    control: ControlService,
    /// The supervisor's node in the flight.
    bus: FlightBus,
    /// The executors and their load.
    registry: ExecutorRegistry,
    /// The flight's `[scheduling]` settings.
    scheduling: SchedulingSpec,
    /// Stall thresholds.
    stalls: StallDetector,
    /// When the supervisor last stepped (its own absences are not the roles' silence).
    watch_clock: WatchClock,
    /// The re-binding policy.
    policy: RebindPolicy,
    /// The variant ladder.
    ladder: VariantLadder,
    /// Steps the variant ladder started.
    variant_steps: u32,
    /// When the next scheduling tick is due.
    next_tick: Instant,
    /// The initial binding check.
    initial: InitialCheck,
    /// Live moves of all roles.
    migrations: u32,
    /// The audit of the flight's services.
    services: ServiceAudit,
    /// The executors on other hosts (where `aeris migrate ROLE HOST:EXECUTOR` sends a role).
    remote_executors: Vec<(String, aeris_runtime::spec::RemoteSpec)>,
    /// The executors that name an accelerator, with it.
    executor_accelerators: Vec<(String, aeris_runtime::accelerator::Accelerator)>,
    /// Lost links that are back, and since when (roles return after the hysteresis).
    links_up_since: Vec<(String, Instant)>,
    /// What a lost link's bridge had said when the link was lost ([`links::LostLink`]): it
    /// is back only on evidence newer than the loss.
    links_lost: Vec<links::LostLink>,
    /// The links to the other hosts as their bridges measure them.
    host_links: HostLinks,
    /// The flight runs on simulated time (its roles take turns; no hot swaps yet).
    on_sim_clock: bool,
}

impl core::fmt::Debug for Supervisor {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Supervisor")
            .field("flight", &self.flight)
            .field("roles", &self.roles)
            .finish()
    }
}

impl Supervisor {
    /// Plan the flight, open the bus (publishing the flight manifest), the status board and
    /// the heartbeat subscriber, write every role's spec and start every role in dependency
    /// order. On error, roles already started are killed.
    pub fn start(options: SupervisorOptions) -> Result<Supervisor, SupervisorError> {
        let SupervisorOptions {
            workflow,
            flight,
            aeris_exe,
            run_dir,
            autopilot,
            sim_clock,
        } = options;
        let online = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
        let scheduling = workflow.scheduling;
        let idle_heartbeat_ms = workflow.timing.idle_heartbeat_ms;
        let plan = plan_launch(
            &workflow,
            &flight,
            autopilot.as_deref(),
            &online,
            crate::launch::free_udp_port,
        )
        .map_err(|source| SupervisorError::Plan {
            flight: flight.clone(),
            source,
        })?;
        let mut plan = plan;
        // A restarted simulated vehicle resumes from its last checkpoint instead of
        // teleporting back to the start.
        for r in plan
            .roles
            .iter_mut()
            .filter(|r| r.spec.kind == RoleKind::Vehicle)
        {
            if !r.spec.params.contains_key("state_file") {
                let path = run_dir.join(format!("{}.state", r.spec.name));
                r.spec
                    .params
                    .insert("state_file".into(), path.display().to_string().into());
            }
        }
        // the formation role writes its vehicles' tracks to the run folder (`aeris plot
        // formation --run RUN_DIR` draws them)
        for r in plan
            .roles
            .iter_mut()
            .filter(|r| r.spec.kind == RoleKind::Formation)
        {
            if !r.spec.params.contains_key("tracks_file") {
                let path = run_dir.join("formation.json");
                r.spec
                    .params
                    .insert("tracks_file".into(), path.display().to_string().into());
            }
        }
        // on simulated time every role takes its turn at an instant in the pipeline's order
        // (its kind's), roles of one kind in the workflow's order
        if let Some(segment) = &sim_clock {
            for (index, r) in plan.roles.iter_mut().enumerate() {
                r.spec.clock = aeris_runtime::ClockSpec::Sim {
                    segment: segment.clone(),
                    rank: sim_rank(r.spec.kind, index),
                };
            }
        }
        // each role's ladder length and starting rung (its declared variant)
        let ladders: Vec<(usize, usize)> = plan
            .roles
            .iter()
            .map(|r| {
                let start = r.ladder.iter().position(|v| *v == r.spec.variant);
                (r.ladder.len(), start.unwrap_or(usize::MAX))
            })
            .collect();
        let bus_err = |source| SupervisorError::Bus {
            flight: flight.clone(),
            source,
        };
        let bus = FlightBus::builder(&flight)
            .node_name("supervisor")
            .create()
            .map_err(bus_err)?;
        let heartbeats = bus.subscriber::<topics::Heartbeat>().map_err(bus_err)?;
        let board = bus.create_status_board().map_err(bus_err)?;
        let hosts: Vec<String> = workflow.hosts.iter().map(|h| h.name.clone()).collect();
        let host_links = HostLinks::new(&bus, &hosts).map_err(bus_err)?;
        let control = bus.control_server().map_err(bus_err)?;

        let roles_dir = run_dir.join("roles");
        let logs_dir = run_dir.join("logs");
        for dir in [&roles_dir, &logs_dir] {
            std::fs::create_dir_all(dir).map_err(|source| SupervisorError::RunDir {
                path: dir.clone(),
                source,
            })?;
        }

        let mut sup = Supervisor {
            roles: Vec::with_capacity(plan.roles.len()),
            flight: flight.clone(),
            launcher: Launcher::new(
                aeris_exe,
                FlightPriority::establish(&flight, scheduling.priority),
            ),
            run_dir,
            heartbeats: HeartbeatIntake::new(heartbeats),
            board: StatusBoard::new(board, workflow.mission.subgoals.len()),
            pending: Vec::new(),
            retiring: RetiringProcesses::default(),
            control: ControlService::new(control),
            bus,
            registry: ExecutorRegistry::discover(&plan.executors, &online),
            policy: RebindPolicy::new(rebind_config(&scheduling), plan.roles.len()),
            ladder: VariantLadder::new(ladder_config(&scheduling), &ladders),
            variant_steps: 0,
            stalls: StallDetector::new(idle_heartbeat_ms, &scheduling),
            watch_clock: WatchClock::watching_cpus(),
            scheduling,
            next_tick: Instant::now(),
            initial: InitialCheck::default(),
            migrations: 0,
            services: ServiceAudit::new(&flight),
            remote_executors: plan.remote_executors,
            executor_accelerators: plan.accelerators,
            links_up_since: Vec::new(),
            links_lost: Vec::new(),
            host_links,
            on_sim_clock: sim_clock.is_some(),
        };
        for planned in plan.roles {
            sup.add_role(planned, &roles_dir, &logs_dir)?;
        }
        for i in 0..sup.roles.len() {
            let pid = sup.spawn(i, "start")?;
            sup.pending.push(SupervisorEvent::RoleStarted {
                name: sup.roles[i].name.clone(),
                pid,
            });
        }
        sup.publish_board();
        Ok(sup)
    }

    /// Write `planned`'s spec under `roles_dir` and add the role, not started yet, with its
    /// log under `logs_dir`.
    fn add_role(
        &mut self,
        planned: PlannedRole,
        roles_dir: &Path,
        logs_dir: &Path,
    ) -> Result<(), SupervisorError> {
        let spec_path = roles_dir.join(format!("{}.json", planned.spec.name));
        let log_path = logs_dir.join(format!("{}.log", planned.spec.name));
        write_spec(&planned.spec, &spec_path)?;
        self.roles
            .push(RoleRuntime::planned(planned, spec_path, log_path));
        Ok(())
    }

    /// Start role `i`'s process; returns its pid.
    fn spawn(&mut self, i: usize, why: &str) -> Result<u32, SupervisorError> {
        let Some(role) = self.roles.get_mut(i) else {
            return Err(SupervisorError::Spawn {
                role: format!("#{i}"),
                exe: self.launcher.exe().to_path_buf(),
                spec: PathBuf::new(),
                cpus: String::new(),
                source: std::io::Error::other("no such role"),
            });
        };
        let pid = self.launcher.start(role, why)?;
        // a new process: its first cycles load and warm up
        self.ladder.settle(i);
        Ok(pid)
    }

    /// One non-blocking round: drain heartbeats, reap exited roles and apply their restart
    /// policy, start due restarts, update the status board. Call it every ~20 ms.
    pub fn step(&mut self) -> Result<Vec<SupervisorEvent>, SupervisorError> {
        let mut events = core::mem::take(&mut self.pending);
        let judge_silence =
            self.watch_clock
                .discount(&mut self.roles, &mut events, self.stalls.hard());
        self.serve_control(&mut events)?;
        self.drain_heartbeats(&mut events)?;
        self.reap(&mut events)?;
        if judge_silence {
            self.stalls.check(&mut self.roles, &mut events);
            self.watch_links(&mut events);
        }
        let before = events.len();
        self.advance_swaps(&mut events);
        self.ladder_follow_swaps(&events[before..]);
        self.retiring.reap(&mut events);
        self.restart_due(&mut events);
        self.schedule(&mut events);
        self.services.check(&mut self.roles, &mut events);
        self.control.answer(&events, &self.roles);
        self.publish_board();
        Ok(events)
    }

    /// Take the waiting heartbeats ([`HeartbeatIntake::drain`]).
    fn drain_heartbeats(
        &mut self,
        events: &mut Vec<SupervisorEvent>,
    ) -> Result<(), SupervisorError> {
        self.heartbeats
            .drain(&mut self.roles, events)
            .map_err(|source| self.bus_error(source))?;
        self.host_links
            .drain()
            .map_err(|source| self.bus_error(source))
    }

    /// Write the status board.
    fn publish_board(&mut self) {
        self.board
            .publish(&self.roles, self.migrations, self.host_links.all());
    }

    /// Step until every role has sent a heartbeat from its current process. Events seen
    /// meanwhile are returned by the next [`Supervisor::step`]. Fails at once when a role
    /// stops for good, and after `timeout` naming the silent roles with their log tails.
    pub fn wait_ready(&mut self, timeout: Duration) -> Result<(), SupervisorError> {
        let deadline = Instant::now() + timeout;
        loop {
            let events = self.step()?;
            self.pending.extend(events);
            // a role waiting for its host's link never holds the flight back
            let waits_for_link = |r: &RoleRuntime| r.link.as_ref().is_some_and(|l| l.lost);
            if let Some(role) = self.roles.iter().find(|r| {
                !r.has_heartbeat()
                    && !waits_for_link(r)
                    && matches!(r.state, RoleState::GaveUp | RoleState::Stopped)
            }) {
                return Err(SupervisorError::RoleDown {
                    role: role.name.clone(),
                    state: role.describe_state(),
                    log_path: role.log_path.clone(),
                    log_tail: log_tail(&role.log_path, LOG_TAIL_LINES),
                });
            }
            if self
                .roles
                .iter()
                .all(|r| r.has_heartbeat() || waits_for_link(r))
            {
                return Ok(());
            }
            if Instant::now() >= deadline {
                let silent = self
                    .roles
                    .iter()
                    .filter(|r| !r.has_heartbeat())
                    .map(|r| SilentRole {
                        name: r.name.clone(),
                        state: r.describe_state(),
                        log_path: r.log_path.clone(),
                        log_tail: log_tail(&r.log_path, LOG_TAIL_LINES),
                    })
                    .collect();
                return Err(SupervisorError::NotReady { timeout, silent });
            }
            std::thread::sleep(POLL);
        }
    }

    /// A transport failure of this supervisor's node.
    fn bus_error(&self, source: BusError) -> SupervisorError {
        SupervisorError::Bus {
            flight: self.flight.clone(),
            source,
        }
    }

    /// The flight's role names, comma-separated (for errors).
    fn role_names(&self) -> String {
        self.roles
            .iter()
            .map(|r| r.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Every role, in start order.
    pub fn roles(&self) -> &[RoleRuntime] {
        &self.roles
    }

    /// The role named `name`.
    pub fn role(&self, name: &str) -> Option<&RoleRuntime> {
        self.roles.iter().find(|r| r.name == name)
    }

    /// Restarts of all roles together.
    pub fn total_restarts(&self) -> u32 {
        self.roles.iter().map(|r| r.restarts).sum()
    }

    /// Heartbeats that failed validation.
    pub fn invalid_heartbeats(&self) -> u64 {
        self.heartbeats.invalid()
    }

    /// Valid heartbeats from a role name that is not in this flight.
    pub fn unknown_heartbeats(&self) -> u64 {
        self.heartbeats.unknown()
    }

    /// The flight name.
    pub fn flight(&self) -> &str {
        &self.flight
    }

    /// The supervisor's node in the flight.
    pub fn bus(&self) -> &FlightBus {
        &self.bus
    }

    /// The run directory (specs under `roles/`, logs under `logs/`).
    pub fn run_dir(&self) -> &Path {
        &self.run_dir
    }

    /// The last status board written.
    pub fn status(&self) -> &SupervisorStatus {
        self.board.status()
    }

    /// Mission progress copied onto the status board (written at once).
    pub fn set_progress(
        &mut self,
        active_step: u16,
        subgoals: u16,
        distance_to_goal_m: f32,
        ct_mean_s: f32,
    ) {
        self.board
            .set_progress(active_step, subgoals, distance_to_goal_m, ct_mean_s);
        self.publish_board();
    }

    /// How the flight's roles got priority over outside work (their CPU control group, a
    /// nice value, or none and why).
    pub fn priority(&self) -> &Priority {
        self.launcher.priority().priority()
    }

    /// The executor registry (declared and discovered CPU sets with their last load).
    pub fn registry(&self) -> &ExecutorRegistry {
        &self.registry
    }

    /// Record the accelerators ONNX Runtime reported in the executor registry (see
    /// [`crate::executors::accelerators_from`]).
    pub fn set_accelerators(
        &mut self,
        providers: Vec<String>,
        accelerators: Vec<crate::executors::AcceleratorInfo>,
    ) {
        self.registry.set_accelerators(providers, accelerators);
    }

    /// The flight's scheduling settings.
    pub fn scheduling(&self) -> &SchedulingSpec {
        &self.scheduling
    }

    /// Turn latency-driven re-binding on or off (stall detection stays on).
    pub fn set_dynamic(&mut self, on: bool) {
        self.scheduling.dynamic = on;
    }

    /// Live moves of all roles so far.
    pub fn total_migrations(&self) -> u32 {
        self.migrations
    }

    /// Steps the variant ladder started so far.
    pub fn total_variant_steps(&self) -> u32 {
        self.variant_steps
    }
}

impl Drop for Supervisor {
    fn drop(&mut self) {
        self.stop_swaps();
        for role in &mut self.roles {
            if let Some(mut child) = role.child.take() {
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

/// Role `index`'s order among the roles due at one instant of simulated time: by its
/// kind's place in the pipeline (vehicle, camera, perception, ..., reasoner, hub,
/// controller, as [`RoleKind`] lists them; a replay source first, as the vehicle and the
/// camera it plays), then by its place in the workflow.
fn sim_rank(kind: RoleKind, index: usize) -> u32 {
    let place = match kind {
        RoleKind::Replay => 0,
        kind => kind as u32,
    };
    (place << 16) | (index.min(0xffff) as u32)
}
