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
//! Relief is rate-limited per role: a role that a relief plan moved stays put twice as long
//! after each further relief move (up to [`MAX_RELIEF_BACKOFF`] times the cooldown), until
//! it has stayed within its budget for a whole cooldown. A role that fits nowhere (a language
//! model on a saturated 2-core machine) would otherwise be moved every cooldown for the
//! whole flight, each move a cost of its own (a cold cache, a migration).
//!
//! The planner (`plan.rs`) is pure; the policy (`policy.rs`) is its memory between ticks.

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
    /// Its recent latency (ms): the larger of the windowed p95 and the latency its current
    /// scheduler slowdown predicts; `None` before it has worked.
    pub latency_ms: Option<f64>,
    /// Measured slowdown `(run + wait) / run` (>= 1).
    pub slowdown: f64,
    /// CPU demand in cores (run time over wall time).
    pub demand: f64,
    /// Run-queue wait in cores (wait time over wall time).
    pub waiting: f64,
    /// `false` pins the role where it is.
    pub movable: bool,
}

impl RoleLoad {
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
    /// (the worst latency/budget ratio falls by the margin, some role stays over).
    pub restores: bool,
}
