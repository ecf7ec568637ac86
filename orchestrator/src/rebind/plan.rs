//! The planner: the latency each role is predicted to have under a binding
//! ([`predict`]), and the fewest moves that restore every budget, or failing that relieve the
//! worst ([`plan_fewest_moves`]). Pure functions of one tick's figures.

use super::{ExecutorLoad, Move, RebindPlan, RoleLoad};

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

/// Slowdown of every executor (at least 1) with roles bound as `assignment`, on top of the
/// `external` load.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rebind::test_loads::{ex, hog_case, relief_case, role};

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

    #[test]
    fn combinations_are_complete() {
        assert_eq!(combinations(4, 2).len(), 6);
        assert_eq!(combinations(3, 3), vec![vec![0, 1, 2]]);
        assert!(combinations(2, 3).is_empty());
    }
}
