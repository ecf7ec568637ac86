//! Role-adaptive variant selection: which model variant of its ladder each role runs, as a
//! pure policy fed one observation per role per scheduling tick, so it is testable without
//! processes. The supervisor makes the steps it returns as make-before-break hot swaps.
//!
//! A role's ladder lists its variants from the most capable (and heaviest) to the lightest,
//! e.g. `["gemma3", "smollm2", "planner"]` (MISSION §3: the multi-scale model stack). The role
//! starts on its declared variant.
//!
//! Step down. The policy looks at the newest worked cycle of each role once per tick (a
//! tick without a new cycle counts nothing). After [`LadderConfig::down_cycles`] consecutive
//! cycles over the role's budget it steps one rung down. Cycles that began before a live
//! move or a swap do not count ([`VariantLadder::settle`]): re-binding between executors gets
//! the first chance, and each rung is judged on its own cycles.
//!
//! Step up. The policy remembers each rung's typical latency (the median of its last
//! cycles) and the role's slowdown then (run + run-queue wait over run). After
//! [`LadderConfig::up_cycles`] consecutive cycles below budget × (1 − margin), it steps one
//! rung up when that rung's remembered latency, scaled by the slowdown now over the slowdown
//! then, is also below budget × (1 − margin). A rung never measured is never climbed to: the
//! declared variant is the ceiling until the role has run higher. This is the hysteresis:
//! a rung that was too slow on an idle executor stays too slow and is not retried; one that
//! was slow because its executor was crowded is retried once the crowd is gone.
//!
//! A rung whose swap failed (the variant did not load) is skipped from then on.

/// Cycles remembered per rung for its typical latency.
const MEMORY: usize = 5;

/// Settings of the variant ladder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LadderConfig {
    /// Consecutive over-budget cycles before a role steps down a rung.
    pub down_cycles: u32,
    /// Consecutive cycles with the margin to spare before a role may step up a rung.
    pub up_cycles: u32,
    /// Fraction of the budget a rung must leave free to be stepped up to (0..1).
    pub margin: f64,
}

impl Default for LadderConfig {
    fn default() -> Self {
        Self {
            down_cycles: 3,
            up_cycles: 10,
            margin: 0.2,
        }
    }
}

/// What the ladder knows about one role at a tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LadderSample {
    /// Latency (ms) of the role's newest worked cycle; `None` before its first.
    pub cycle_ms: Option<f64>,
    /// Worked cycles of the role so far (monotonic: a new value means a new cycle).
    pub cycles: u64,
    /// Its latency budget (ms); `None`: no budget, never stepped.
    pub budget_ms: Option<f64>,
    /// Its slowdown now: (run + run-queue wait) / run, at least 1.
    pub slowdown: f64,
    /// It may be swapped now (running, no swap under way).
    pub ready: bool,
}

/// Which way a step goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepDirection {
    /// To a lighter variant: the current one misses its budget.
    Down,
    /// Back to a heavier variant predicted to fit again.
    Up,
}

/// One step the supervisor should make (a hot swap of `role` to rung `to`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VariantStep {
    /// Role index (as in the samples).
    pub role: usize,
    /// Rung it runs now.
    pub from: usize,
    /// Rung to swap to.
    pub to: usize,
    /// Down or up.
    pub direction: StepDirection,
    /// The latency (ms) that triggered it: the last cycle's.
    pub latency_ms: f64,
    /// The role's budget (ms).
    pub budget_ms: f64,
    /// The latency (ms) predicted on the new rung, when it has been measured.
    pub predicted_ms: Option<f64>,
}

/// What the ladder remembers of one rung.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct RungMemory {
    /// The last cycles' latencies (ms), ring.
    cycles: [f64; MEMORY],
    /// Cycles in `cycles` (at most [`MEMORY`]).
    len: usize,
    /// Next slot of the ring.
    next: usize,
    /// The role's slowdown at the last cycle.
    slowdown: f64,
    /// A swap to this rung failed: never step to it again.
    broken: bool,
}

impl RungMemory {
    fn push(&mut self, ms: f64, slowdown: f64) {
        self.cycles[self.next] = ms;
        self.next = (self.next + 1) % MEMORY;
        self.len = (self.len + 1).min(MEMORY);
        self.slowdown = slowdown.max(1.0);
    }

    /// Median of the remembered cycles.
    fn typical_ms(&self) -> Option<f64> {
        if self.len == 0 {
            return None;
        }
        let mut v = [0.0; MEMORY];
        v[..self.len].copy_from_slice(&self.cycles[..self.len]);
        let v = &mut v[..self.len];
        v.sort_by(f64::total_cmp);
        Some(if v.len() % 2 == 1 {
            v[v.len() / 2]
        } else {
            (v[v.len() / 2 - 1] + v[v.len() / 2]) / 2.0
        })
    }
}

/// The ladder state of one role.
#[derive(Debug, Clone, PartialEq)]
struct RoleLadder {
    rungs: Vec<RungMemory>,
    /// The rung it runs; `None` while it runs a variant outside its ladder (swapped by hand).
    at: Option<usize>,
    /// Cycle count last seen.
    seen: u64,
    /// New cycles still to ignore (they may have begun before a move or swap).
    skip: u32,
    over: u32,
    calm: u32,
    /// A step was returned and its swap has not landed or failed yet.
    pending: Option<usize>,
}

/// The role-adaptive variant policy with its memory: feed it one tick at a time.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantLadder {
    config: LadderConfig,
    roles: Vec<Option<RoleLadder>>,
}

impl VariantLadder {
    /// A policy for roles with `(rungs, start)` each: the length of the role's ladder and the
    /// rung it starts on. A role with fewer than 2 rungs, or a start outside its ladder, is
    /// never stepped.
    pub fn new(config: LadderConfig, roles: &[(usize, usize)]) -> Self {
        let roles = roles
            .iter()
            .map(|&(rungs, start)| {
                (rungs >= 2 && start < rungs).then(|| RoleLadder {
                    rungs: vec![RungMemory::default(); rungs],
                    at: Some(start),
                    seen: 0,
                    skip: 0,
                    over: 0,
                    calm: 0,
                    pending: None,
                })
            })
            .collect();
        Self { config, roles }
    }

    /// The rung role `r` runs (`None`: no ladder, or a variant outside it).
    pub fn rung(&self, r: usize) -> Option<usize> {
        self.roles.get(r)?.as_ref()?.at
    }

    /// The typical latency (ms) remembered for rung `k` of role `r`.
    pub fn remembered_ms(&self, r: usize, k: usize) -> Option<f64> {
        self.roles.get(r)?.as_ref()?.rungs.get(k)?.typical_ms()
    }

    /// Forget role `r`'s streaks and ignore its next cycle (it may have begun before a live
    /// move or a restart that changed its latency).
    pub fn settle(&mut self, r: usize) {
        if let Some(Some(l)) = self.roles.get_mut(r) {
            l.over = 0;
            l.calm = 0;
            l.skip = 1;
        }
    }

    /// Role `r` now runs rung `rung` (a swap landed, or `None`: a variant outside its ladder).
    pub fn landed(&mut self, r: usize, rung: Option<usize>) {
        if let Some(Some(l)) = self.roles.get_mut(r) {
            l.at = rung.filter(|&k| k < l.rungs.len());
            l.pending = None;
        }
        self.settle(r);
    }

    /// The swap of role `r` to its pending rung failed: the role stays, that rung is skipped
    /// from now on.
    pub fn failed(&mut self, r: usize) {
        if let Some(Some(l)) = self.roles.get_mut(r)
            && let Some(k) = l.pending.take()
        {
            l.rungs[k].broken = true;
        }
        self.settle(r);
    }

    /// One tick: record the roles' new cycles and append the steps to make now to `out`.
    pub fn tick(&mut self, samples: &[LadderSample], out: &mut Vec<VariantStep>) {
        let margin = self.config.margin.clamp(0.0, 0.99);
        for (r, (slot, s)) in self.roles.iter_mut().zip(samples).enumerate() {
            let Some(l) = slot.as_mut() else {
                continue;
            };
            let fresh = s.cycles != l.seen;
            l.seen = s.cycles;
            let (Some(at), Some(ms), Some(budget), true) = (l.at, s.cycle_ms, s.budget_ms, fresh)
            else {
                continue;
            };
            if !s.ready || l.pending.is_some() {
                continue;
            }
            if l.skip > 0 {
                l.skip -= 1;
                continue;
            }
            if !ms.is_finite() || !budget.is_finite() || budget <= 0.0 {
                continue;
            }
            let slowdown = if s.slowdown.is_finite() {
                s.slowdown.max(1.0)
            } else {
                1.0
            };
            l.rungs[at].push(ms, slowdown);
            let roomy = budget * (1.0 - margin);
            if ms > budget {
                l.over += 1;
                l.calm = 0;
            } else {
                l.over = 0;
                l.calm = if ms <= roomy { l.calm + 1 } else { 0 };
            }
            let predict = |m: &RungMemory| m.typical_ms().map(|t| t * slowdown / m.slowdown);
            let step = if l.over >= self.config.down_cycles {
                (at + 1..l.rungs.len())
                    .find(|&k| !l.rungs[k].broken)
                    .map(|k| (k, StepDirection::Down, predict(&l.rungs[k])))
            } else if l.calm >= self.config.up_cycles {
                (0..at)
                    .rev()
                    .find(|&k| !l.rungs[k].broken)
                    .and_then(|k| predict(&l.rungs[k]).map(|p| (k, p)))
                    .filter(|&(_, p)| p <= roomy)
                    .map(|(k, p)| (k, StepDirection::Up, Some(p)))
            } else {
                None
            };
            if let Some((to, direction, predicted_ms)) = step {
                l.pending = Some(to);
                l.over = 0;
                l.calm = 0;
                out.push(VariantStep {
                    role: r,
                    from: at,
                    to,
                    direction,
                    latency_ms: ms,
                    budget_ms: budget,
                    predicted_ms,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(cycles: u64, ms: f64, budget: f64, slowdown: f64) -> LadderSample {
        LadderSample {
            cycle_ms: Some(ms),
            cycles,
            budget_ms: Some(budget),
            slowdown,
            ready: true,
        }
    }

    /// Feeds role 0 one new cycle of `ms` per tick; returns the steps.
    fn run(
        ladder: &mut VariantLadder,
        cycles: &mut u64,
        ms: f64,
        slowdown: f64,
        n: usize,
    ) -> Vec<VariantStep> {
        let mut out = Vec::new();
        for _ in 0..n {
            *cycles += 1;
            ladder.tick(&[sample(*cycles, ms, 100.0, slowdown)], &mut out);
        }
        out
    }

    #[test]
    fn a_rung_over_budget_steps_down_after_the_streak_and_only_once_until_it_lands() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(3, 0)]);
        let mut c = 0;
        assert!(run(&mut l, &mut c, 150.0, 1.0, 2).is_empty());
        let steps = run(&mut l, &mut c, 150.0, 1.0, 1);
        assert_eq!(steps.len(), 1);
        let s = steps[0];
        assert_eq!((s.role, s.from, s.to), (0, 0, 1));
        assert_eq!(s.direction, StepDirection::Down);
        assert_eq!(s.predicted_ms, None, "rung 1 never ran");
        // while the swap is under way nothing more is asked
        assert!(run(&mut l, &mut c, 150.0, 1.0, 10).is_empty());
        l.landed(0, Some(1));
        assert_eq!(l.rung(0), Some(1));
        // the first cycle after landing is skipped, then three over budget: down again
        assert!(run(&mut l, &mut c, 120.0, 1.0, 3).is_empty());
        let steps = run(&mut l, &mut c, 120.0, 1.0, 1);
        assert_eq!((steps[0].from, steps[0].to), (1, 2));
        l.landed(0, Some(2));
        // the bottom rung has nowhere to go
        assert!(run(&mut l, &mut c, 500.0, 1.0, 20).is_empty());
    }

    #[test]
    fn a_tick_without_a_new_cycle_counts_nothing() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut out = Vec::new();
        for _ in 0..10 {
            l.tick(&[sample(7, 500.0, 100.0, 1.0)], &mut out);
        }
        assert!(out.is_empty(), "one cycle seen ten times is one cycle");
    }

    #[test]
    fn a_cycle_within_budget_breaks_the_streak() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        for _ in 0..10 {
            assert!(run(&mut l, &mut c, 150.0, 1.0, 2).is_empty());
            assert!(run(&mut l, &mut c, 90.0, 1.0, 1).is_empty());
        }
    }

    #[test]
    fn a_move_or_restart_makes_the_ladder_wait_for_cycles_of_the_new_binding() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        assert!(run(&mut l, &mut c, 150.0, 1.0, 2).is_empty());
        l.settle(0);
        // the streak restarts, and the first cycle after the move does not count
        assert!(run(&mut l, &mut c, 150.0, 1.0, 3).is_empty());
        assert_eq!(run(&mut l, &mut c, 150.0, 1.0, 1).len(), 1);
    }

    #[test]
    fn a_rung_too_slow_on_an_idle_executor_is_never_climbed_back_to() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        // rung 0 at 150 ms with no contention: inherently over a 100 ms budget
        assert_eq!(run(&mut l, &mut c, 150.0, 1.0, 3).len(), 1);
        l.landed(0, Some(1));
        // rung 1 is fast and calm for a long time: rung 0 is still predicted at 150 ms
        assert!(run(&mut l, &mut c, 20.0, 1.0, 200).is_empty());
        assert_eq!(l.rung(0), Some(1));
        assert_eq!(l.remembered_ms(0, 0), Some(150.0));
    }

    #[test]
    fn a_rung_slow_only_under_contention_is_climbed_back_to_when_it_is_gone() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        // 60 ms alone, 150 ms at slowdown 2.5 (a hog on its CPUs)
        assert_eq!(run(&mut l, &mut c, 150.0, 2.5, 3).len(), 1);
        l.landed(0, Some(1));
        // still crowded: rung 0 would take 150 ms, no step up
        assert!(run(&mut l, &mut c, 30.0, 2.5, 50).is_empty());
        // the hog left: predicted 150 * 1 / 2.5 = 60 ms <= 80 ms, up after 10 calm cycles
        let steps = run(&mut l, &mut c, 12.0, 1.0, 11);
        assert_eq!(steps.len(), 1, "{steps:?}");
        let s = steps[0];
        assert_eq!((s.from, s.to, s.direction), (1, 0, StepDirection::Up));
        assert!((s.predicted_ms.unwrap() - 60.0).abs() < 1e-9);
    }

    #[test]
    fn noise_around_the_budget_does_not_flap() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        let mut steps = Vec::new();
        // 95..105 ms around a 100 ms budget, never three over in a row
        for i in 0..300u64 {
            c += 1;
            let ms = if i % 3 == 2 { 95.0 } else { 105.0 };
            l.tick(&[sample(c, ms, 100.0, 1.0)], &mut steps);
        }
        assert!(steps.is_empty(), "{steps:?}");
    }

    #[test]
    fn a_failed_swap_marks_the_rung_and_the_next_one_is_tried() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(3, 0)]);
        let mut c = 0;
        assert_eq!(run(&mut l, &mut c, 150.0, 1.0, 3)[0].to, 1);
        l.failed(0);
        assert_eq!(l.rung(0), Some(0));
        let steps = run(&mut l, &mut c, 150.0, 1.0, 4);
        assert_eq!(steps.len(), 1);
        assert_eq!((steps[0].from, steps[0].to), (0, 2), "rung 1 is skipped");
    }

    #[test]
    fn roles_without_a_ladder_a_budget_or_readiness_are_never_stepped() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(1, 0), (3, 5), (2, 0), (2, 0)]);
        let mut out = Vec::new();
        for c in 1..50u64 {
            let s = sample(c, 1e6, 100.0, 1.0);
            let no_budget = LadderSample {
                budget_ms: None,
                ..s
            };
            let busy = LadderSample { ready: false, ..s };
            l.tick(&[s, s, no_budget, busy], &mut out);
        }
        assert!(out.is_empty(), "{out:?}");
        assert_eq!(l.rung(0), None);
        assert_eq!(l.rung(1), None);
    }

    #[test]
    fn a_variant_swapped_in_by_hand_outside_the_ladder_disengages_it() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut c = 0;
        l.landed(0, None);
        assert!(run(&mut l, &mut c, 500.0, 1.0, 20).is_empty());
        l.landed(0, Some(0));
        assert!(run(&mut l, &mut c, 500.0, 1.0, 4).len() == 1);
    }

    #[test]
    fn non_finite_figures_are_ignored() {
        let mut l = VariantLadder::new(LadderConfig::default(), &[(2, 0)]);
        let mut out = Vec::new();
        for c in 1..20u64 {
            l.tick(&[sample(c, f64::NAN, 100.0, 1.0)], &mut out);
            l.tick(
                &[LadderSample {
                    cycles: c * 1000,
                    ..sample(c, 1e9, f64::INFINITY, f64::NAN)
                }],
                &mut out,
            );
        }
        assert!(out.is_empty());
    }
}
