//! Latency-driven re-binding: which roles to move between executors, as pure functions of
//! what the supervisor measured, so the policy is testable without processes.
//!
//! Model. Each role has a latency budget (its share of the heartbeat). Its measured latency
//! splits into a base cost and a slowdown: `base = latency / slowdown`, where `slowdown =
//! (run + wait) / run` from the scheduler (time waiting in a run queue stretches a cycle).
//! An executor of `capacity` cores carries a load in cores: what its CPUs were busy with
//! beyond our roles' own demand (plus the run-queue wait our roles saw there: demand the
//! busy figure cannot show once a CPU is saturated), plus the demand of the roles bound to
//! it. Its slowdown is `max(1, load / capacity)`. A role that stays where it is keeps its
//! measured latency, scaled by how its executor's slowdown changes; a role that moves gets
//! `base * slowdown` of its new executor.
//!
//! Policy. A role is over budget when its latency exceeds its budget. After
//! [`RebindConfig::trigger_ticks`] consecutive over-budget ticks of any role, the planner
//! searches move sets in increasing size (one move, then two, ...) and takes the first size
//! with a plan in which every role fits its budget and the roles that were over it fit with
//! [`RebindConfig::margin`] to spare (ties: the lowest worst latency/budget ratio). When no
//! such plan exists (a small machine where every executor is loaded), it takes the fewest
//! moves that bring the worst latency/budget ratio down by at least the margin without
//! pushing a role that fits over its budget: relief, not a cure, but a reasoner at 1.4x its
//! budget meets a heartbeat deadline a reasoner at 5x misses. Moved roles
//! then stay put for [`RebindConfig::cooldown_ticks`]; when no plan exists, the planner
//! waits as long before it tries again, unless a new slip comes first (another role over
//! its budget, or the worst latency/budget ratio up by the margin): a reasoner a little over
//! budget where no move helps must not delay the answer to a hog landing later. Together with the margin this keeps noise around a
//! budget from moving roles back and forth.
//!
//! Other hosts. An executor may be on another host ([`ExecutorLoad::host`]); a role placed
//! there pays the link on every cycle: its state goes there and its output comes back (the
//! link's measured round trip, [`ExecutorLoad::link_ms`]), and a role that reads frames
//! waits for each to be encoded for the link too ([`ExecutorLoad::frame_ms`]). A role's
//! latency on such an executor is its own cycle (its load model as above, with that host's
//! busy cores) plus that cost; only roles that may run on another host
//! ([`RoleLoad::crosses_hosts`]) are placed there, only while the link is up
//! ([`ExecutorLoad::reachable`]), and a role goes from one other host to a different one
//! only through the flight's host (between executors of one other host it may move). A role on another host is seen through its handle on the flight's host,
//! so its CPU demand there is not measured (0): the planner may underestimate the load a
//! role brings back.
//!
//! Relief is rate-limited per role: a role that a relief plan moved stays put twice as long
//! after each further relief move (up to [`MAX_RELIEF_BACKOFF`] times the cooldown), until
//! it has stayed within its budget for a whole cooldown. A role that fits nowhere (a language
//! model on a saturated 2-core machine) would otherwise be moved every cooldown for the
//! whole flight, each move a cost of its own (a cold cache, a migration).
//!
//! Accelerators. An executor may be an accelerator ([`ExecutorLoad::accelerator`]); only
//! model roles that can run on it go there ([`crate::workflow::runs_on_accelerator`]). A
//! role's cycle there is the device's work, not a share of CPUs, so it is predicted from what
//! the role measured there earlier in the flight ([`RoleLoad::accelerator_ms`]), and a role
//! on one is predicted back on CPUs from its cycle as last measured on CPUs
//! ([`RoleLoad::cpu_base_ms`]); a move that cannot be predicted is not planned. When no
//! measured plan restores every budget and a role over budget can run on an accelerator it
//! has not been measured on, that one move is made as a probe ([`RebindPlan::probe`]): a
//! make-before-break restart there, whose measurement then decides whether it stays. Roles
//! sharing one device are not modelled: their measured latencies show it.
//!
//! The planner (`plan.rs`) is pure; the policy (`policy.rs`) is its memory between ticks.

use aeris_runtime::accelerator::Accelerator;

mod plan;
mod policy;
#[cfg(test)]
mod test_loads;

pub use plan::{MIN_RELIEF, plan_fewest_moves, predict};
pub use policy::{MAX_RELIEF_BACKOFF, RebindConfig, RebindPolicy};

/// What the policy knows about one role at a tick.
#[derive(Debug, Clone, PartialEq)]
pub struct RoleLoad {
    /// Role name (for reports).
    pub name: String,
    /// Index of its executor in the executor list.
    pub executor: usize,
    /// Its latency budget (ms); roles without one are never over budget.
    pub budget_ms: Option<f64>,
    /// Its recent latency (ms): the larger of the windowed p95 and its own cost (each
    /// recent cycle's latency over the slowdown it ran under) at its current scheduler
    /// slowdown — a hog shows before a cycle finishes late — plus the link's cost when it runs on another host
    /// ([`link_cost`]); `None` before it has worked.
    pub latency_ms: Option<f64>,
    /// Measured slowdown `(run + wait) / run` (>= 1).
    pub slowdown: f64,
    /// CPU demand in cores (run time over wall time).
    pub demand: f64,
    /// Run-queue wait in cores (wait time over wall time).
    pub waiting: f64,
    /// `false` pins the role where it is.
    pub movable: bool,
    /// It may run on another host (not a kind that stays on the flight's host).
    pub crosses_hosts: bool,
    /// It reads frames (a role on another host waits for each to be encoded for the link).
    pub reads_frames: bool,
    /// Its worker threads (a language model's `threads`): it is never moved live onto fewer
    /// CPUs (two llama.cpp workers on one CPU spin at their barriers and starve each other;
    /// a restart elsewhere starts it with as many as it has CPUs).
    pub threads: usize,
    /// Its kind and variant (`detector`, `yolo`): which accelerators can run it
    /// ([`crate::workflow::runs_on_accelerator`]).
    pub kind_variant: (aeris_schemas::RoleKind, String),
    /// Its latency (ms) as last measured on accelerator executors this flight: (executor
    /// index, ms). A role goes onto an accelerator by these figures, or, where it has not
    /// run yet, by a probe ([`RebindPlan::probe`]).
    pub accelerator_ms: Vec<(usize, f64)>,
    /// Its own cycle (ms, without slowdown or link) as last measured on a CPU executor: what
    /// a role on an accelerator now is predicted to take back on CPUs (`None`: never
    /// measured there, so it is not moved off).
    pub cpu_base_ms: Option<f64>,
}

impl RoleLoad {
    /// Its latency as last measured on accelerator executor `executor`.
    pub fn measured_on(&self, executor: usize) -> Option<f64> {
        self.accelerator_ms
            .iter()
            .find(|(e, _)| *e == executor)
            .map(|(_, ms)| *ms)
    }

    fn ratio(&self) -> f64 {
        match (self.latency_ms, self.budget_ms) {
            (Some(l), Some(b)) if b > 0.0 => l / b,
            _ => 0.0,
        }
    }

    /// `true` when its latency exceeds its budget.
    pub fn over_budget(&self) -> bool {
        self.ratio() > 1.0
    }
}

/// What the policy knows about one executor at a tick.
#[derive(Debug, Clone, PartialEq)]
pub struct ExecutorLoad {
    /// Name.
    pub name: String,
    /// Cores.
    pub capacity: f64,
    /// Busy cores over the last interval (all tasks, ours included).
    pub busy: f64,
    /// The other host it is on (`None`: the flight's host).
    pub host: Option<String>,
    /// What a role there pays per cycle for the link (ms): its measured round trip; 0 on
    /// the flight's host.
    pub link_ms: f64,
    /// What a role there that reads frames pays on top (ms): encoding a frame for the
    /// link, as measured on the frames sent (0 until one has crossed); 0 on the flight's
    /// host.
    pub frame_ms: f64,
    /// Roles may be moved here: always on the flight's host; on another host while its
    /// link is up and measured.
    pub reachable: bool,
    /// The accelerator its model roles run on (`cuda:0`): a role's cycle here is the
    /// device's work, measured there, not a share of the CPUs.
    pub accelerator: Option<Accelerator>,
}

impl ExecutorLoad {
    /// An executor of the flight's host.
    pub fn local(name: &str, capacity: f64, busy: f64) -> Self {
        ExecutorLoad {
            name: name.to_string(),
            capacity,
            busy,
            host: None,
            link_ms: 0.0,
            frame_ms: 0.0,
            reachable: true,
            accelerator: None,
        }
    }
}

/// What `role` pays per cycle for the link of `executor` (ms; 0 on the flight's host).
pub fn link_cost(role: &RoleLoad, executor: &ExecutorLoad) -> f64 {
    executor.link_ms
        + if role.reads_frames {
            executor.frame_ms
        } else {
            0.0
        }
}

/// One move of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Move {
    /// Role index.
    pub role: usize,
    /// Executor it leaves.
    pub from: usize,
    /// Executor it goes to.
    pub to: usize,
}

/// A re-binding: the moves and the latency each role is predicted to have after them.
#[derive(Debug, Clone, PartialEq)]
pub struct RebindPlan {
    /// The moves (fewest that restore the budget).
    pub moves: Vec<Move>,
    /// Predicted latency of every role (ms), by role index (`None`: no latency yet).
    pub predicted_ms: Vec<Option<f64>>,
    /// `true` when every role is predicted to fit its budget; `false` for a relief plan
    /// (the worst latency/budget ratio falls by the margin, some role stays over) and for a
    /// probe.
    pub restores: bool,
    /// A probe: no measured plan restores the budget, and the one move sends a role over
    /// budget onto an accelerator it has not run on yet (its prediction there is `None`).
    /// The move is make-before-break, and its measurement there decides what follows.
    pub probe: bool,
}
