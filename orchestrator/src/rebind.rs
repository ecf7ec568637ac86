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

/// Load (cores) on each executor that is not ours: busy beyond our roles' demand, plus the
/// wait our roles saw there.
fn external_load(roles: &[RoleLoad], executors: &[ExecutorLoad]) -> Vec<f64> {
    executors
        .iter()
        .enumerate()
        .map(|(e, ex)| {
            let ours = roles.iter().filter(|r| r.executor == e);
            let demand: f64 = ours.clone().map(|r| r.demand).sum();
            let waiting: f64 = ours.map(|r| r.waiting).sum();
            (ex.busy - demand).max(0.0) + waiting
        })
        .collect()
}

fn slowdowns(
    roles: &[RoleLoad],
    executors: &[ExecutorLoad],
    external: &[f64],
    assignment: &[usize],
) -> Vec<f64> {
    let mut load = external.to_vec();
    for (r, &e) in roles.iter().zip(assignment) {
        if let Some(l) = load.get_mut(e) {
            *l += r.demand;
        }
    }
    executors
        .iter()
        .zip(load)
        .map(|(ex, l)| (l / ex.capacity.max(1e-9)).max(1.0))
        .collect()
}

/// Predicted latency of every role (ms) when roles are bound as `assignment` (executor
/// index per role).
pub fn predict(
    roles: &[RoleLoad],
    executors: &[ExecutorLoad],
    assignment: &[usize],
) -> Vec<Option<f64>> {
    let external = external_load(roles, executors);
    let current: Vec<usize> = roles.iter().map(|r| r.executor).collect();
    let now = slowdowns(roles, executors, &external, &current);
    let then = slowdowns(roles, executors, &external, assignment);
    roles
        .iter()
        .zip(assignment)
        .map(|(r, &e)| {
            let latency = r.latency_ms?;
            let s_then = *then.get(e)?;
            Some(if e == r.executor {
                // stays: the measured latency, scaled by the change of its executor
                latency * s_then / now[e]
            } else {
                latency / r.slowdown.max(1.0) * s_then
            })
        })
        .collect()
}

/// The least a relief plan must lower the worst latency/budget ratio by (a fraction), even
/// when the margin asked for is smaller.
pub const MIN_RELIEF: f64 = 0.1;

/// The plan with the fewest moves (at most `max_moves`) after which every role fits its
/// budget and the roles over budget now fit it with `margin` (0..1) to spare; failing that,
/// the fewest moves that lower the worst latency/budget ratio by `margin` while every role
/// that fits now still fits (a relief plan, [`RebindPlan::restores`] `false`). `None` when
/// no role is over budget or neither kind of plan exists.
pub fn plan_fewest_moves(
    roles: &[RoleLoad],
    executors: &[ExecutorLoad],
    margin: f64,
    max_moves: usize,
    frozen: &[bool],
) -> Option<RebindPlan> {
    if !roles.iter().any(RoleLoad::over_budget) || executors.len() < 2 {
        return None;
    }
    let movable: Vec<usize> = (0..roles.len())
        .filter(|&r| roles[r].movable && !frozen.get(r).copied().unwrap_or(false))
        .collect();
    let worst_now = roles.iter().map(RoleLoad::ratio).fold(0.0, f64::max);
    // (worst ratio, restores every budget) of an assignment; `None` when it breaks a role
    // that fits now
    let judge = |predicted: &[Option<f64>]| -> Option<(f64, bool)> {
        let mut worst = 0.0f64;
        let mut restores = true;
        for (r, p) in roles.iter().zip(predicted) {
            let (Some(b), Some(p)) = (r.budget_ms, *p) else {
                continue;
            };
            if r.over_budget() {
                restores &= p <= b * (1.0 - margin);
            } else if p > b {
                return None;
            }
            worst = worst.max(p / b);
        }
        Some((worst, restores))
    };
    let current: Vec<usize> = roles.iter().map(|r| r.executor).collect();
    type Candidate = (f64, Vec<Move>, Vec<Option<f64>>);
    let mut relief: Option<Candidate> = None;
    for size in 1..=max_moves.min(movable.len()) {
        let mut best: Option<Candidate> = None;
        for subset in combinations(movable.len(), size) {
            let picked: Vec<usize> = subset.iter().map(|&i| movable[i]).collect();
            // every assignment of the picked roles to executors other than their own
            let choices = executors.len() - 1;
            let total = choices.checked_pow(size as u32)?;
            for code in 0..total {
                let mut assignment = current.clone();
                let mut c = code;
                let mut moves = Vec::with_capacity(size);
                for &r in &picked {
                    let k = c % choices;
                    c /= choices;
                    let to = if k >= current[r] { k + 1 } else { k };
                    assignment[r] = to;
                    moves.push(Move {
                        role: r,
                        from: current[r],
                        to,
                    });
                }
                let predicted = predict(roles, executors, &assignment);
                let Some((worst, restores)) = judge(&predicted) else {
                    continue;
                };
                let slot = if restores {
                    &mut best
                } else if relief.is_none() || relief.as_ref().is_some_and(|r| r.1.len() == size) {
                    &mut relief
                } else {
                    continue;
                };
                if slot.as_ref().is_none_or(|(w, _, _)| worst < *w)
                    && (restores || worst <= worst_now * (1.0 - margin.max(MIN_RELIEF)))
                {
                    *slot = Some((worst, moves, predicted));
                }
            }
        }
        if let Some((_, moves, predicted_ms)) = best {
            return Some(RebindPlan {
                moves,
                predicted_ms,
                restores: true,
            });
        }
    }
    relief.map(|(_, moves, predicted_ms)| RebindPlan {
        moves,
        predicted_ms,
        restores: false,
    })
}

/// Index subsets of `0..n` of size `k`, in lexicographic order.
fn combinations(n: usize, k: usize) -> Vec<Vec<usize>> {
    let mut out = Vec::new();
    if k == 0 || k > n {
        return out;
    }
    let mut idx: Vec<usize> = (0..k).collect();
    loop {
        out.push(idx.clone());
        let mut i = k;
        loop {
            if i == 0 {
                return out;
            }
            i -= 1;
            if idx[i] < n - k + i {
                break;
            }
            if i == 0 {
                return out;
            }
        }
        idx[i] += 1;
        for j in i + 1..k {
            idx[j] = idx[j - 1] + 1;
        }
    }
}

/// Settings of the re-binding policy.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RebindConfig {
    /// Consecutive over-budget ticks before the policy acts.
    pub trigger_ticks: u32,
    /// Roles over budget must fit this fraction below their budget after the move.
    pub margin: f64,
    /// Ticks a moved role stays put, and the wait before retrying when no plan exists.
    pub cooldown_ticks: u32,
    /// Most roles moved at once.
    pub max_moves: usize,
}

impl Default for RebindConfig {
    fn default() -> Self {
        Self {
            trigger_ticks: 2,
            margin: 0.2,
            cooldown_ticks: 40,
            max_moves: 3,
        }
    }
}

/// Most times the cooldown a role's relief moves can grow to (doubling per relief move).
pub const MAX_RELIEF_BACKOFF: u32 = 16;

/// The re-binding policy with its memory (streaks, cooldowns): feed it one tick at a time.
#[derive(Debug, Clone)]
pub struct RebindPolicy {
    config: RebindConfig,
    streak: Vec<u32>,
    cooldown: Vec<u32>,
    hold_off: u32,
    /// When the last search found no plan: the roles over budget then, and the worst
    /// latency/budget ratio. A new slip (another role over, or the worst ratio up by the
    /// margin) ends the hold-off at once: the wait is for the same situation, not a new one.
    held: Option<(Vec<bool>, f64)>,
    /// Relief moves of each role since it last stayed within budget for a cooldown.
    reliefs: Vec<u32>,
    /// Consecutive ticks each role has been within its budget.
    calm: Vec<u32>,
}

impl RebindPolicy {
    /// A policy for `roles` roles.
    pub fn new(config: RebindConfig, roles: usize) -> Self {
        Self {
            config,
            streak: vec![0; roles],
            cooldown: vec![0; roles],
            hold_off: 0,
            held: None,
            reliefs: vec![0; roles],
            calm: vec![0; roles],
        }
    }

    /// Relief moves of role `r` since it last stayed within budget for a cooldown: its
    /// next relief move waits `2^n` cooldowns (at most [`MAX_RELIEF_BACKOFF`]).
    pub fn reliefs(&self, r: usize) -> u32 {
        self.reliefs.get(r).copied().unwrap_or(0)
    }

    /// Ticks role `r` stays put from now.
    pub fn cooldown(&self, r: usize) -> u32 {
        self.cooldown.get(r).copied().unwrap_or(0)
    }

    /// The settings.
    pub fn config(&self) -> &RebindConfig {
        &self.config
    }

    /// Consecutive over-budget ticks of role `r`.
    pub fn streak(&self, r: usize) -> u32 {
        self.streak.get(r).copied().unwrap_or(0)
    }

    /// Forget the streak of role `r` and keep it where it is for a cooldown (after a move
    /// made by hand, or a restart that reset its figures); a longer relief back-off in
    /// progress stays.
    pub fn settle(&mut self, r: usize) {
        if let Some(s) = self.streak.get_mut(r) {
            *s = 0;
        }
        if let Some(c) = self.cooldown.get_mut(r) {
            *c = (*c).max(self.config.cooldown_ticks);
        }
    }

    /// One tick: update the streaks and return the moves to make now, if any.
    pub fn tick(&mut self, roles: &[RoleLoad], executors: &[ExecutorLoad]) -> Option<RebindPlan> {
        if self.streak.len() != roles.len() {
            self.streak = vec![0; roles.len()];
            self.cooldown = vec![0; roles.len()];
            self.reliefs = vec![0; roles.len()];
            self.calm = vec![0; roles.len()];
        }
        for (r, role) in roles.iter().enumerate() {
            let over = role.over_budget();
            self.streak[r] = if over {
                self.streak[r].saturating_add(1)
            } else {
                0
            };
            self.calm[r] = if over {
                0
            } else {
                self.calm[r].saturating_add(1)
            };
            if self.calm[r] >= self.config.cooldown_ticks {
                self.reliefs[r] = 0;
            }
            self.cooldown[r] = self.cooldown[r].saturating_sub(1);
        }
        let worst = roles.iter().map(RoleLoad::ratio).fold(0.0, f64::max);
        if self.hold_off > 0 {
            let new_slip = self.held.as_ref().is_some_and(|(over, then)| {
                worst > then * (1.0 + self.config.margin)
                    || roles
                        .iter()
                        .zip(&self.streak)
                        .enumerate()
                        .any(|(r, (role, &streak))| {
                            streak >= self.config.trigger_ticks
                                && role.over_budget()
                                && !over.get(r).copied().unwrap_or(false)
                        })
            });
            if !new_slip {
                self.hold_off -= 1;
                return None;
            }
            self.hold_off = 0;
        }
        if !self.streak.iter().any(|&s| s >= self.config.trigger_ticks) {
            return None;
        }
        let frozen: Vec<bool> = self.cooldown.iter().map(|&c| c > 0).collect();
        match plan_fewest_moves(
            roles,
            executors,
            self.config.margin,
            self.config.max_moves,
            &frozen,
        ) {
            Some(plan) => {
                for m in &plan.moves {
                    self.settle(m.role);
                    if !plan.restores {
                        let backoff = 1u32
                            .checked_shl(self.reliefs[m.role])
                            .unwrap_or(u32::MAX)
                            .min(MAX_RELIEF_BACKOFF);
                        self.cooldown[m.role] = self.config.cooldown_ticks.saturating_mul(backoff);
                        self.reliefs[m.role] = self.reliefs[m.role].saturating_add(1);
                    }
                }
                for s in &mut self.streak {
                    *s = 0;
                }
                Some(plan)
            }
            None => {
                self.hold_off = self.config.cooldown_ticks;
                self.held = Some((roles.iter().map(RoleLoad::over_budget).collect(), worst));
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn role(name: &str, executor: usize, budget: f64, latency: f64, demand: f64) -> RoleLoad {
        RoleLoad {
            name: name.into(),
            executor,
            budget_ms: Some(budget),
            latency_ms: Some(latency),
            slowdown: 1.0,
            demand,
            waiting: 0.0,
            movable: true,
        }
    }

    fn ex(name: &str, busy: f64) -> ExecutorLoad {
        ExecutorLoad {
            name: name.into(),
            capacity: 1.0,
            busy,
        }
    }

    /// Two CPUs; a hog saturates CPU 1 where the reasoner, the camera and perception run.
    fn hog_case() -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        let mut reasoning = role("reasoning", 1, 1000.0, 1800.0, 0.3);
        reasoning.slowdown = 3.0;
        reasoning.waiting = 0.6;
        let mut camera = role("camera", 1, 100.0, 60.0, 0.1);
        camera.slowdown = 2.0;
        camera.waiting = 0.1;
        let roles = vec![
            role("hub", 0, 20.0, 0.5, 0.05),
            role("controller", 0, 20.0, 0.4, 0.05),
            camera,
            role("perception", 1, 500.0, 30.0, 0.05),
            reasoning,
        ];
        (roles, vec![ex("control", 0.2), ex("perception", 1.0)])
    }

    #[test]
    fn one_move_takes_the_slow_role_off_the_hogged_executor() {
        let (roles, executors) = hog_case();
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(
            plan.moves,
            [Move {
                role: 4,
                from: 1,
                to: 0
            }]
        );
        // base 600 ms on an executor at 0.2 + 0.1 + 0.3 cores: no slowdown
        assert!((plan.predicted_ms[4].unwrap() - 600.0).abs() < 1e-6);
    }

    #[test]
    fn the_fewest_moves_win_even_when_two_roles_are_over_budget() {
        // A and B share CPU 1 (1.3 cores of demand on one core): both 30 % slow and over
        // budget. Moving A alone frees CPU 1 for B: one move, not two.
        let roles = vec![
            RoleLoad {
                slowdown: 1.3,
                ..role("a", 1, 120.0, 130.0, 0.7)
            },
            RoleLoad {
                slowdown: 1.3,
                ..role("b", 1, 120.0, 130.0, 0.6)
            },
        ];
        let executors = vec![ex("cpu0", 0.0), ex("cpu1", 1.0)];
        let plan = plan_fewest_moves(&roles, &executors, 0.1, 3, &[]).expect("a plan");
        assert_eq!(plan.moves.len(), 1);
        for p in plan.predicted_ms.iter().flatten() {
            assert!(*p <= 120.0 * 0.9 + 1e-9, "{p}");
        }
    }

    #[test]
    fn two_moves_when_one_is_not_enough() {
        // three executors: two hogged, each with a role over budget
        let mut a = role("a", 1, 150.0, 300.0, 0.2);
        a.slowdown = 3.0;
        a.waiting = 0.4;
        let mut b = role("b", 2, 150.0, 300.0, 0.2);
        b.slowdown = 3.0;
        b.waiting = 0.4;
        let executors = vec![
            ExecutorLoad {
                capacity: 2.0,
                ..ex("big", 0.0)
            },
            ex("cpu1", 1.0),
            ex("cpu2", 1.0),
        ];
        let plan = plan_fewest_moves(&[a, b], &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(plan.moves.len(), 2);
        assert!(plan.moves.iter().all(|m| m.to == 0));
    }

    #[test]
    fn no_plan_when_every_executor_is_saturated_or_roles_are_pinned() {
        let (roles, mut executors) = hog_case();
        executors[0].busy = 1.0;
        let mut hub = roles.clone();
        // the control CPU is saturated too: moving the reasoner there does not fit
        for r in hub.iter_mut().filter(|r| r.executor == 0) {
            r.waiting = 2.0;
        }
        assert_eq!(plan_fewest_moves(&hub, &executors, 0.2, 3, &[]), None);
        let (roles2, executors2) = hog_case();
        let frozen = [false, false, false, false, true];
        let plan = plan_fewest_moves(&roles2, &executors2, 0.2, 3, &frozen);
        assert!(
            plan.is_none_or(|p| p.moves.iter().all(|m| m.role != 4)),
            "a frozen role was moved"
        );
        // nobody over budget: nothing to do
        let calm = vec![role("a", 0, 100.0, 50.0, 0.2)];
        assert_eq!(
            plan_fewest_moves(&calm, &[ex("x", 0.2), ex("y", 0.0)], 0.2, 3, &[]),
            None
        );
    }

    #[test]
    fn the_policy_waits_for_a_streak_and_then_moves_once() {
        let (roles, executors) = hog_case();
        let mut policy = RebindPolicy::new(RebindConfig::default(), roles.len());
        assert_eq!(policy.tick(&roles, &executors), None, "one tick is noise");
        let plan = policy.tick(&roles, &executors).expect("acts on the second");
        assert_eq!(plan.moves.len(), 1);
        // the same observations again (figures not refreshed yet): the moved role is
        // cooling down and nothing else is over budget
        let mut after = roles.clone();
        after[4].executor = 0;
        for _ in 0..10 {
            assert_eq!(policy.tick(&after, &executors), None);
        }
    }

    #[test]
    fn noise_around_the_budget_never_moves_a_role_back_and_forth() {
        // The reasoner's latency wanders 10 % around its budget on one CPU while the other
        // CPU is as busy: no move restores it with margin, so nothing moves, ever.
        let mut policy = RebindPolicy::new(RebindConfig::default(), 1);
        let executors = vec![ex("cpu0", 0.5), ex("cpu1", 0.5)];
        let mut moves = 0;
        let mut state = 0x2545_f491_u64;
        let mut executor = 1;
        for _ in 0..2000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let jitter = (state % 2001) as f64 / 1000.0 - 1.0; // -1..1
            let latency = 1000.0 * (1.0 + 0.1 * jitter);
            let r = RoleLoad {
                slowdown: 1.0,
                ..role("reasoning", executor, 1000.0, latency, 0.3)
            };
            if let Some(plan) = policy.tick(&[r], &executors) {
                moves += plan.moves.len();
                executor = plan.moves[0].to;
            }
        }
        assert_eq!(moves, 0);
    }

    #[test]
    fn a_moved_role_is_not_moved_back_while_the_interference_stays() {
        // After the move the reasoner is fine on CPU 0; its figures wander just under the
        // budget. Returning to the hogged CPU is never predicted to fit, so it stays.
        let (roles, executors) = hog_case();
        let mut policy = RebindPolicy::new(RebindConfig::default(), roles.len());
        policy.tick(&roles, &executors);
        let plan = policy.tick(&roles, &executors).unwrap();
        let mut now = roles.clone();
        now[4].executor = plan.moves[0].to;
        now[4].slowdown = 1.0;
        now[4].waiting = 0.0;
        let executors = vec![ex("control", 0.5), ex("perception", 1.0)];
        for i in 0..500 {
            now[4].latency_ms = Some(if i % 5 < 2 { 1050.0 } else { 700.0 });
            if let Some(p) = policy.tick(&now, &executors) {
                assert!(p.moves.iter().all(|m| m.to != 1), "moved back: {p:?}");
            }
        }
    }

    #[test]
    fn relief_when_no_executor_restores_the_budget() {
        // the reasoner is 6x over on the hogged CPU; on the control CPU it would still be
        // 1.2x over its budget, but far closer to it: the only move that helps
        let (roles, executors) = relief_case();
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("relief");
        assert!(!plan.restores);
        assert_eq!(
            plan.moves,
            [Move {
                role: 3,
                from: 1,
                to: 0
            }]
        );
        let p = plan.predicted_ms[3].unwrap();
        assert!(p > 1000.0 && p < 2000.0, "{p}");
        // a move that only shuffles the worst ratio by less than the margin is no relief
        let mut slight = roles.clone();
        slight[3].latency_ms = Some(1300.0);
        slight[3].slowdown = 1.05;
        assert_eq!(plan_fewest_moves(&slight, &executors, 0.2, 3, &[]), None);
        // and the full cure wins over relief when it exists
        let (roles, executors) = hog_case();
        assert!(
            plan_fewest_moves(&roles, &executors, 0.2, 3, &[])
                .unwrap()
                .restores
        );
    }

    /// The reasoner over budget wherever it runs: relief, never a cure.
    fn relief_case() -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        let mut reasoning = role("reasoning", 1, 1000.0, 6000.0, 0.2);
        reasoning.slowdown = 5.0;
        reasoning.waiting = 0.8;
        let roles = vec![
            role("hub", 0, 20.0, 0.5, 0.05),
            role("text", 0, 500.0, 200.0, 0.5),
            role("camera", 1, 100.0, 40.0, 0.05),
            reasoning,
        ];
        (roles, vec![ex("control", 0.55), ex("perception", 1.0)])
    }

    #[test]
    fn relief_moves_of_a_role_back_off_until_it_stays_within_budget() {
        let (roles, executors) = relief_case();
        let config = RebindConfig::default();
        let c = config.cooldown_ticks as usize;
        let mut policy = RebindPolicy::new(config, roles.len());
        // every relief finds the reasoner over budget again where it went (the load
        // follows it): without a limit it would move every cooldown, 25 times here
        let moves_in = |policy: &mut RebindPolicy, ticks: usize, roles: &[RoleLoad]| {
            let mut at = Vec::new();
            for t in 0..ticks {
                if let Some(plan) = policy.tick(roles, &executors) {
                    assert!(!plan.restores);
                    assert_eq!(plan.moves.len(), 1);
                    at.push(t);
                }
            }
            at
        };
        let at = moves_in(&mut policy, 40 * c, &roles);
        let gaps: Vec<usize> = at.windows(2).map(|w| w[1] - w[0]).collect();
        assert_eq!(at.len(), 6, "{at:?}");
        for (k, g) in gaps.iter().enumerate() {
            let wait = c << k.min(4);
            assert!(
                *g >= wait && *g <= wait + c + 2,
                "gap {k}: {g} ticks, {at:?}"
            );
        }
        assert_eq!(policy.reliefs(3), 6);
        // the supervisor settles a role it has just moved: that keeps the back-off
        let left = policy.cooldown(3);
        assert!(left > c as u32, "{left}");
        policy.settle(3);
        assert_eq!(policy.cooldown(3), left);
        // within budget for a whole cooldown: the back-off is forgotten
        let mut calm = roles.clone();
        calm[3].latency_ms = Some(500.0);
        calm[3].slowdown = 1.0;
        assert!(moves_in(&mut policy, 16 * c + c, &calm).is_empty());
        assert_eq!(policy.reliefs(3), 0);
        let at = moves_in(&mut policy, 2 * c + 4, &roles);
        assert_eq!(at.len(), 2, "back to one cooldown between moves: {at:?}");
        // a move that cures is never held back
        let (roles, executors) = hog_case();
        let mut policy = RebindPolicy::new(config, roles.len());
        let cured = (0..5)
            .find_map(|_| policy.tick(&roles, &executors))
            .unwrap();
        assert!(cured.restores);
        for m in &cured.moves {
            assert_eq!(policy.cooldown(m.role), c as u32);
            assert_eq!(policy.reliefs(m.role), 0);
        }
    }

    #[test]
    fn a_new_slip_ends_the_wait_after_a_failed_search() {
        // the reasoner a little over budget where no move helps (both CPUs busy): the
        // search fails and the policy waits a cooldown before it tries again
        let cfg = RebindConfig {
            cooldown_ticks: 40,
            ..RebindConfig::default()
        };
        let executors = vec![ex("control", 0.9), ex("perception", 0.9)];
        let mut reasoning = role("reasoning", 1, 1000.0, 1100.0, 0.5);
        reasoning.slowdown = 1.1;
        let text = role("text", 1, 500.0, 300.0, 0.3);
        let mut p = RebindPolicy::new(cfg, 2);
        for _ in 0..cfg.trigger_ticks {
            assert_eq!(p.tick(&[reasoning.clone(), text.clone()], &executors), None);
        }
        // the same situation: still waiting
        assert_eq!(p.tick(&[reasoning.clone(), text.clone()], &executors), None);
        // a hog lands on perception: the text reader slips too, and control is free now
        let hogged = vec![ex("control", 0.2), ex("perception", 1.0)];
        let mut slow_text = role("text", 1, 500.0, 900.0, 0.3);
        slow_text.slowdown = 3.0;
        slow_text.waiting = 0.6;
        assert!(
            plan_fewest_moves(
                &[reasoning.clone(), slow_text.clone()],
                &hogged,
                0.2,
                3,
                &[]
            )
            .is_some(),
            "the case has a plan"
        );
        let mut plan = None;
        for _ in 0..cfg.trigger_ticks {
            plan = plan.or(p.tick(&[reasoning.clone(), slow_text.clone()], &hogged));
        }
        let plan = plan.expect("a new slip is searched at once, not after the cooldown");
        assert!(!plan.moves.is_empty());
        // the first situation alone again: the wait is over, it is judged afresh (no plan)
        let mut q = RebindPolicy::new(cfg, 2);
        for _ in 0..cfg.trigger_ticks + 1 {
            assert_eq!(q.tick(&[reasoning.clone(), text.clone()], &executors), None);
        }
        assert!(q.hold_off > 0);
    }

    #[test]
    fn combinations_are_complete() {
        assert_eq!(combinations(4, 2).len(), 6);
        assert_eq!(combinations(3, 3), vec![vec![0, 1, 2]]);
        assert!(combinations(2, 3).is_empty());
    }
}
