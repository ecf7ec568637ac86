//! The policy: the memory between ticks (over-budget streaks, cooldowns of moved roles,
//! the hold-off after a failed search, relief back-off) that decides when the planner runs
//! and which roles it may move.

use super::{ExecutorLoad, RebindPlan, RoleLoad, plan_fewest_moves};

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

/// A role cooling down after a move may move again at once when its latency/budget ratio
/// is over 1, this many times what the move predicted, and higher (by the margin) than it
/// was when it moved (figures that still show the old place move nothing): the cooldown
/// keeps noise from moving a role back and forth, not a hog that lands where the role went. (In `bench ds`
/// the reasoner, moved to a free CPU 3 s before the hog landed there, sat out its 10 s
/// cooldown at 4x its budget: 8 heartbeats lost.) Once until the role has stayed within its
/// budget for a cooldown: a role that fits nowhere, whose load follows it wherever it goes,
/// then keeps its relief back-off.
pub const SLIP_PAST_PREDICTION: f64 = 2.0;

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
    /// The latency/budget ratio each role's last move predicted, and the one it had then
    /// (0: not moved).
    promised: Vec<(f64, f64)>,
    /// A role moved again within its cooldown since it last stayed within budget for one
    /// ([`SLIP_PAST_PREDICTION`]).
    slipped: Vec<bool>,
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
            promised: vec![(0.0, 0.0); roles],
            slipped: vec![false; roles],
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
            self.promised = vec![(0.0, 0.0); roles.len()];
            self.slipped = vec![false; roles.len()];
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
                self.slipped[r] = false;
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
        // cooling down, unless it slipped far past what its move predicted
        let frozen: Vec<bool> = roles
            .iter()
            .enumerate()
            .map(|(r, role)| {
                let ratio = role.ratio();
                let (promised, then) = self.promised[r];
                let slipped = !self.slipped[r]
                    && promised > 0.0
                    && ratio > 1.0
                    && ratio > SLIP_PAST_PREDICTION * promised
                    && ratio > then * (1.0 + self.config.margin);
                self.cooldown[r] > 0 && !slipped
            })
            .collect();
        match plan_fewest_moves(
            roles,
            executors,
            self.config.margin,
            self.config.max_moves,
            &frozen,
        ) {
            Some(plan) => {
                for m in &plan.moves {
                    if self.cooldown[m.role] > 0 {
                        self.slipped[m.role] = true;
                    }
                    self.settle(m.role);
                    let role = &roles[m.role];
                    self.promised[m.role] = match (plan.predicted_ms.get(m.role), role.budget_ms) {
                        (Some(Some(p)), Some(b)) if b > 0.0 => (p / b, role.ratio()),
                        _ => (0.0, 0.0),
                    };
                    // a probe is a measurement, not relief: a plain cooldown
                    if !plan.restores && !plan.probe {
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
    use crate::rebind::test_loads::{ex, hog_case, relief_case, role};

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
    fn a_hog_landing_where_a_role_just_went_moves_it_again_within_its_cooldown() {
        // the reasoner, a little over budget beside perception's work on CPU 1, is moved to
        // CPU 0 (predicted 0.6x)
        let executors = vec![ex("control", 0.2), ex("perception", 0.9)];
        let mut reasoning = role("reasoning", 1, 1000.0, 1150.0, 0.3);
        reasoning.slowdown = 1.5;
        reasoning.waiting = 0.15;
        let camera = role("camera", 1, 100.0, 40.0, 0.1);
        let mut p = RebindPolicy::new(RebindConfig::default(), 2);
        let roles = vec![reasoning.clone(), camera.clone()];
        let first = (0..3)
            .find_map(|_| p.tick(&roles, &executors))
            .expect("moved");
        assert_eq!(first.moves[0].to, 0);
        assert!(p.cooldown(0) > 10);
        // a hog lands on CPU 0: 4x its budget there, far past the 0.6x predicted and worse
        // than before the move
        let hogged = vec![ex("control", 1.0), ex("perception", 0.7)];
        let mut there = role("reasoning", 0, 1000.0, 4000.0, 0.2);
        there.slowdown = 5.0;
        there.waiting = 0.8;
        let roles = vec![there.clone(), camera.clone()];
        let second = (0..3)
            .find_map(|_| p.tick(&roles, &hogged))
            .expect("moved again at once, not after its 10 s cooldown");
        assert_eq!(second.moves[0].to, 1);
        // once: a load that follows it again waits out the cooldown (relief back-off)
        let mut back = there.clone();
        back.executor = 1;
        let followed = vec![ex("control", 0.2), ex("perception", 1.0)];
        for _ in 0..10 {
            assert_eq!(p.tick(&[back.clone(), camera.clone()], &followed), None);
        }
        // figures that still show the old place (its ratio then) move nothing either
        let mut q = RebindPolicy::new(RebindConfig::default(), 2);
        let roles = vec![reasoning.clone(), camera.clone()];
        (0..3)
            .find_map(|_| q.tick(&roles, &executors))
            .expect("moved");
        let mut stale = reasoning.clone();
        stale.executor = 0;
        for _ in 0..10 {
            assert_eq!(q.tick(&[stale.clone(), camera.clone()], &executors), None);
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
}
