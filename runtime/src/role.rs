//! The one role abstraction and the host that runs a role as its own process.
//!
//! A role is built once from its [`RoleContext`] ([`Role::new`]: open ports, load models),
//! then the [`RoleHost`] calls [`Role::cycle`] on absolute deadlines of the flight's clock
//! (no drift): CLOCK_MONOTONIC, or on a flight on simulated time the turns the flight's
//! clock grants ([`crate::clock::sim`]; while waiting for one the host still says it is
//! alive every idle-heartbeat period of the wall clock), publishes a [`RoleHeartbeat`] after every cycle that did work (and a
//! liveness heartbeat when idle), and stops cleanly on SIGTERM/SIGINT. Heartbeats say
//! `Starting` before the role is built and `Running` as soon as it is.
//! `cycle` must not allocate: ports and buffers are created in `new`.

use crate::affinity::write_task_affinity;
use crate::bus::{FlightBus, RoleBus, TypedPublisher};
use crate::clock::sim::{SimClockReader, SimParticipant, Turn};
use crate::clock::{duration_ns, monotonic_ns, sleep_until_ns, wall_ns};
use crate::signals;
use crate::spec::{ClockSpec, RoleSpec};
use aeris_schemas::kinds::DeclaredKind;
use aeris_schemas::{FixedText, MAX_STAGES, RoleHeartbeat, RoleStatus, StageTiming, topics};
use core::time::Duration;

pub use crate::role_error::{ConfigError, RoleError};

/// What a cycle did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CycleOutcome {
    /// Produced output: publish a heartbeat with this cycle's latency.
    Worked,
    /// Nothing to do this time (e.g. no new input).
    Idle,
    /// The role finished its job and the process should exit cleanly.
    Finished,
}

/// What a role reports about one cycle; the host copies it into the heartbeat.
#[derive(Debug, Clone, Copy)]
pub struct CycleReport {
    stages: [(&'static str, u64); MAX_STAGES],
    stage_count: usize,
    /// Role-specific counters (documented per role).
    pub counters: [u64; 8],
    /// Health to report.
    pub status: RoleStatus,
}

impl Default for CycleReport {
    fn default() -> Self {
        Self {
            stages: [("", 0); MAX_STAGES],
            stage_count: 0,
            counters: [0; 8],
            status: RoleStatus::Running,
        }
    }
}

impl CycleReport {
    /// Record a stage duration (up to [`MAX_STAGES`]; extra stages are dropped).
    pub fn stage(&mut self, name: &'static str, ns: u64) {
        if self.stage_count < MAX_STAGES {
            self.stages[self.stage_count] = (name, ns);
            self.stage_count += 1;
        }
    }

    fn clear_stages(&mut self) {
        self.stage_count = 0;
    }
}

/// What a role of kind `K` sees of its process.
pub struct RoleContext<K> {
    /// The launch spec.
    pub spec: RoleSpec,
    /// This process's node in the flight, opening ports only on the topics `K` declares.
    pub bus: RoleBus<K>,
    /// Cycles run so far.
    pub cycles: u64,
    /// Periods skipped because a cycle overran its deadline (the loop re-anchors instead of
    /// running late cycles back to back).
    pub missed_deadlines: u64,
}

impl<K: DeclaredKind> RoleContext<K> {
    /// The context of a role of kind `K` launched with `spec` on `bus`; refused when the
    /// spec names another kind (a runner given the wrong role).
    pub fn new(spec: RoleSpec, bus: FlightBus) -> Result<Self, RoleError> {
        if spec.kind != K::KIND {
            return Err(ConfigError::Spec {
                field: "kind",
                problem: format!("is {}, but this role is a {}", spec.kind, K::KIND),
            }
            .into());
        }
        Ok(Self {
            spec,
            bus: RoleBus::new(bus),
            cycles: 0,
            missed_deadlines: 0,
        })
    }
}

/// The role abstraction every role implements.
pub trait Role: Sized {
    /// The kind the role is one variant of: the topics it may open ports on.
    type Kind: DeclaredKind;

    /// Build the role inside its process: open ports, load models, allocate buffers.
    fn new(ctx: &mut RoleContext<Self::Kind>) -> Result<Self, RoleError>;

    /// Period of the cycle.
    fn period(&self) -> Duration;

    /// One cycle. Must not allocate on the heap.
    fn cycle(
        &mut self,
        ctx: &mut RoleContext<Self::Kind>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError>;

    /// Called once when the process is asked to stop.
    fn shutdown(&mut self, _ctx: &mut RoleContext<Self::Kind>) {}
}

/// Runs one role as the current process.
pub struct RoleHost;

impl RoleHost {
    /// Run role `R` with `spec` until SIGTERM/SIGINT, a fatal error, or `Finished`.
    pub fn run<R: Role>(spec: RoleSpec) -> Result<(), RoleError> {
        let span = tracing::info_span!(
            "role",
            role = %spec.name,
            kind = %spec.kind,
            variant = %spec.variant,
            flight = %spec.flight,
        );
        let _in_role = span.enter();
        signals::install_termination_handlers()
            .map_err(|e| RoleError::step("installing the signal handlers", e))?;
        // joined before anything is stamped: from here on the flight's time waits for
        // this process until its first cycle asks for a turn
        let sim = join_sim_clock(&spec)?;
        let bus = FlightBus::builder(&spec.flight)
            .node_name(&spec.name)
            .vehicle(spec.vehicle)
            .create()?;
        let heartbeats: TypedPublisher<RoleHeartbeat> = bus.publisher::<topics::Heartbeat>()?;
        let mut ctx = RoleContext::<R::Kind>::new(spec, bus)?;
        let mut hb = RoleHeartbeat::default();
        hb.role.set(&ctx.spec.name);
        hb.variant.set(&ctx.spec.variant);
        hb.executor.set(&ctx.spec.cpus);
        // what the kernel says, so a live move by the supervisor shows in the next heartbeat
        let _ = write_task_affinity(0, &mut hb.executor);
        hb.pid = ctx.spec.heartbeat_pid.unwrap_or_else(std::process::id);
        hb.status = RoleStatus::Starting as u8;
        hb.seq = 1;
        hb.stamp_ns = monotonic_ns();
        heartbeats.publish(&hb)?;

        let mut role = R::new(&mut ctx)?;
        // built (models loaded and warmed up): say so before the first cycle, which may be
        // long; the supervisor takes this as the role being ready
        hb.seq += 1;
        hb.stamp_ns = monotonic_ns();
        hb.status = RoleStatus::Running as u8;
        heartbeats.publish(&hb)?;
        let period_ns = duration_ns(role.period()).max(1);
        let idle_ns = ctx
            .spec
            .timing
            .idle_heartbeat_ms
            .max(1)
            .saturating_mul(1_000_000);
        let mut report = CycleReport::default();
        let mut next = monotonic_ns();
        let mut last_hb = 0u64;
        let mut result = Ok(());
        let idle_wall = Duration::from_nanos(idle_ns);
        let live = |hb: &mut RoleHeartbeat| {
            hb.seq += 1;
            hb.stamp_ns = monotonic_ns();
            hb.worked = 0;
            heartbeats.publish(hb).map(drop)
        };
        if let Some(sim) = &sim {
            wait_for_turn(sim, next, idle_wall, || live(&mut hb))?;
        }
        while !signals::termination_requested() {
            // how long the work took is wall-clock time, on simulated time too
            let start_wall = wall_ns();
            report.clear_stages();
            let outcome = match role.cycle(&mut ctx, &mut report) {
                Ok(o) => o,
                Err(e) => {
                    result = Err(e);
                    break;
                }
            };
            let end = monotonic_ns();
            let end_wall = wall_ns();
            ctx.cycles += 1;
            if outcome == CycleOutcome::Worked || end.saturating_sub(last_hb) >= idle_ns {
                hb.seq += 1;
                hb.stamp_ns = end;
                hb.status = report.status as u8;
                hb.counters = report.counters;
                hb.worked = u8::from(outcome == CycleOutcome::Worked);
                // a failed read keeps the last label
                let _ = write_task_affinity(0, &mut hb.executor);
                if outcome == CycleOutcome::Worked {
                    hb.cycle_latency_ns = end_wall.saturating_sub(start_wall);
                    for (slot, (name, ns)) in hb.stages.iter_mut().zip(report.stages.iter()) {
                        *slot = StageTiming {
                            name: FixedText::from_str_truncated(name),
                            ns: *ns,
                        };
                    }
                    for slot in hb.stages.iter_mut().skip(report.stage_count) {
                        *slot = StageTiming::default();
                    }
                }
                heartbeats.publish(&hb)?;
                last_hb = end;
            }
            if outcome == CycleOutcome::Finished {
                break;
            }
            next += period_ns;
            if let Some(sim) = &sim {
                // simulated time never runs ahead of a role: no deadline is missed
                wait_for_turn(sim, next, idle_wall, || live(&mut hb))?;
                continue;
            }
            let now = monotonic_ns();
            if now > next {
                // The deadline already passed: count it and re-anchor instead of bursting.
                ctx.missed_deadlines += (now - next) / period_ns + 1;
                next = now + period_ns - (now - next) % period_ns;
            }
            sleep_until_ns(next);
        }
        hb.seq += 1;
        hb.stamp_ns = monotonic_ns();
        hb.status = RoleStatus::Stopping as u8;
        hb.worked = 0;
        let _ = heartbeats.publish(&hb);
        role.shutdown(&mut ctx);
        result
    }
}

/// Join the flight's simulated time when `spec` runs on it (and read the flight's clock
/// from it from now on); `None` on the wall clock.
fn join_sim_clock(spec: &RoleSpec) -> Result<Option<SimParticipant>, RoleError> {
    let ClockSpec::Sim { segment, rank } = &spec.clock else {
        return Ok(None);
    };
    let clock = SimClockReader::open(segment)
        .map_err(|e| RoleError::step("opening the flight's simulated clock", e))?;
    crate::clock::use_sim_clock(clock.clone());
    let me = clock
        .join(std::process::id(), *rank)
        .map_err(|e| RoleError::step("joining the flight's simulated clock", e))?;
    Ok(Some(me))
}

/// Ask the flight's simulated time for a turn at `wake_ns` and wait for it, saying the
/// role is alive (`live`) every `idle` of wall-clock time meanwhile; returns when the turn
/// came or termination was requested.
fn wait_for_turn<E>(
    sim: &SimParticipant,
    wake_ns: u64,
    idle: Duration,
    mut live: impl FnMut() -> Result<(), E>,
) -> Result<(), E> {
    let mut turn = sim.wait_for(wake_ns, idle);
    while turn == Turn::NotYet && !signals::termination_requested() {
        live()?;
        turn = sim.wait_again(idle);
    }
    Ok(())
}

/// Try to run the calling thread under SCHED_FIFO at `priority`; `false` when not permitted
/// (the thread keeps its normal policy).
pub fn try_sched_fifo(priority: i32) -> bool {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is valid; 0 = calling thread.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) == 0 }
}

/// `true` while the calling thread runs under SCHED_IDLE: this process is the new side of a
/// hot swap, loaded and warmed up beside the running one, and the supervisor has not yet
/// made it the role (it restores SCHED_OTHER when it does). A role that publishes what
/// only one process of the role may publish at a time (a reasoner's decisions) stands by
/// until then: work done on idle CPU time would be late, and its output would compete with
/// the running process's.
pub fn standing_by() -> bool {
    // SAFETY: sched_getscheduler has no memory-safety preconditions; 0 = calling thread.
    unsafe { libc::sched_getscheduler(0) == libc::SCHED_IDLE }
}

/// Sleep helper for roles that wait on something outside the cycle (never in `cycle`).
pub fn sleep(d: Duration) {
    sleep_until_ns(monotonic_ns() + duration_ns(d));
}

#[cfg(test)]
mod tests {
    use super::standing_by;

    #[test]
    fn a_thread_stands_by_exactly_while_it_runs_under_sched_idle() {
        // a thread of its own: the policy is per thread, and the test's others keep theirs
        let seen = std::thread::spawn(|| {
            let before = standing_by();
            let param = libc::sched_param { sched_priority: 0 };
            // SAFETY: `param` is valid; 0 = calling thread. Any process may enter SCHED_IDLE.
            let set = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) } == 0;
            (before, set, standing_by())
        })
        .join()
        .expect("the test thread panicked");
        assert_eq!(seen, (false, true, true));
        assert!(!standing_by());
    }
}
