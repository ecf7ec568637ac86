//! The planner: the latency each role is predicted to have under a binding
//! ([`predict`]), and the fewest moves that restore every budget, or failing that relieve the
//! worst ([`plan_fewest_moves`]). Pure functions of one tick's figures.

use super::{ExecutorLoad, Move, RebindPlan, RoleLoad, link_cost};

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
            let to = executors.get(e)?;
            if to.accelerator.is_some() {
                // on an accelerator: what the role measured there (the device's work)
                return if e == r.executor {
                    r.latency_ms
                } else {
                    r.measured_on(e)
                };
            }
            let s_then = *then.get(e)?;
            if executors
                .get(r.executor)
                .is_some_and(|x| x.accelerator.is_some())
            {
                // from an accelerator back to CPUs: its cycle as last measured on CPUs
                return r.cpu_base_ms.map(|base| base * s_then + link_cost(r, to));
            }
            let latency = r.latency_ms?;
            // the role's own cycle, without the link it pays now
            let paid = executors.get(r.executor).map_or(0.0, |ex| link_cost(r, ex));
            let cycle = (latency - paid).max(0.0);
            Some(if e == r.executor {
                // stays: the measured cycle, scaled by the change of its executor
                cycle * s_then / now[e] + paid
            } else {
                cycle / r.slowdown.max(1.0) * s_then + link_cost(r, &executors[e])
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
                if !moves
                    .iter()
                    .all(|m| allowed(&roles[m.role], executors.get(m.from), &executors[m.to]))
                {
                    continue;
                }
                let predicted = predict(roles, executors, &assignment);
                // a move whose outcome cannot be predicted is no plan (a probe, below)
                if moves.iter().any(|m| predicted[m.role].is_none()) {
                    continue;
                }
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
                probe: false,
            });
        }
    }
    probe_accelerator(roles, executors, &movable).or_else(|| {
        relief.map(|(_, moves, predicted_ms)| RebindPlan {
            moves,
            predicted_ms,
            restores: false,
            probe: false,
        })
    })
}

/// When no measured plan restores every budget: the worst role over budget that can run on
/// an accelerator executor it has not been measured on goes there, to be measured (the
/// first such executor). Preferred to relief: an accelerator may cure what CPUs only ease.
fn probe_accelerator(
    roles: &[RoleLoad],
    executors: &[ExecutorLoad],
    movable: &[usize],
) -> Option<RebindPlan> {
    let (r, to) = movable
        .iter()
        .filter(|&&r| roles[r].over_budget())
        .filter_map(|&r| {
            let role = &roles[r];
            let to = executors.iter().enumerate().position(|(e, ex)| {
                e != role.executor
                    && ex.accelerator.is_some()
                    && role.measured_on(e).is_none()
                    && allowed(role, executors.get(role.executor), ex)
            })?;
            Some((r, to))
        })
        .max_by(|a, b| roles[a.0].ratio().total_cmp(&roles[b.0].ratio()))?;
    let current: Vec<usize> = roles.iter().map(|r| r.executor).collect();
    let mut assignment = current.clone();
    assignment[r] = to;
    Some(RebindPlan {
        moves: vec![Move {
            role: r,
            from: current[r],
            to,
        }],
        predicted_ms: predict(roles, executors, &assignment),
        restores: false,
        probe: true,
    })
}

/// Whether `role` may go from `from` to `to`: there only while its link is up, to another
/// host only a role that may run there, from one other host to a different one only
/// through the flight's host, to an accelerator only a model role it can run, and live
/// (between CPU executors of one host) only onto at least as many CPUs as its threads.
fn allowed(role: &RoleLoad, from: Option<&ExecutorLoad>, to: &ExecutorLoad) -> bool {
    let from_host = from.and_then(|e| e.host.as_ref());
    let (kind, variant) = &role.kind_variant;
    let live = from.is_some_and(|f| f.accelerator.is_none() && f.host == to.host)
        && to.accelerator.is_none();
    (!live || to.capacity >= role.threads as f64)
        && to
            .accelerator
            .is_none_or(|a| crate::workflow::runs_on_accelerator(*kind, variant, a))
        && to.reachable
        && (to.host.is_none() || role.crosses_hosts)
        && (from_host.is_none() || to.host.is_none() || from_host == to.host.as_ref())
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

    /// The hog case with a free executor on another host whose link costs `rtt` ms a
    /// cycle and `frame` ms a frame; the flight's control executor is saturated too.
    fn ground_case(rtt: f64, frame: f64) -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        let (mut roles, mut executors) = hog_case();
        executors[0].busy = 1.0;
        for r in roles.iter_mut().filter(|r| r.executor == 0) {
            r.waiting = 1.0;
        }
        executors.push(ExecutorLoad {
            host: Some("ground".into()),
            link_ms: rtt,
            frame_ms: frame,
            ..ExecutorLoad::local("gs", 2.0, 0.1)
        });
        (roles, executors)
    }

    #[test]
    fn a_role_goes_to_another_host_when_the_link_costs_less_than_the_slowdown() {
        let (roles, executors) = ground_case(5.0, 0.0);
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(
            plan.moves,
            [Move {
                role: 4,
                from: 1,
                to: 2
            }]
        );
        // its own cycle (1800 / 3) there, plus the round trip
        assert!((plan.predicted_ms[4].unwrap() - 605.0).abs() < 1e-6);
    }

    #[test]
    fn a_slow_link_keeps_the_role_on_the_flights_host() {
        // 600 ms of cycle plus 500 ms of link is over the 1000 ms budget: no cure there
        // (at most relief)
        let (roles, executors) = ground_case(500.0, 0.0);
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(plan.as_ref().is_none_or(|p| !p.restores), "{plan:?}");
        // the same link at 5 ms cures it
        let (roles, executors) = ground_case(5.0, 0.0);
        assert!(plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).is_some_and(|p| p.restores));
    }

    #[test]
    fn a_role_that_reads_frames_pays_their_coding_there() {
        let (mut roles, executors) = ground_case(5.0, 450.0);
        roles[4].reads_frames = true;
        // 600 + 5 + 450 > 1000 * 0.8: not a cure
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(plan.is_none_or(|p| !p.restores), "frames were not counted");
        roles[4].reads_frames = false;
        assert!(
            plan_fewest_moves(&roles, &executors, 0.2, 3, &[])
                .expect("a plan")
                .restores
        );
    }

    #[test]
    fn no_role_goes_where_it_may_not_or_over_a_link_that_is_down() {
        let (mut roles, mut executors) = ground_case(5.0, 0.0);
        roles[4].crosses_hosts = false;
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(
            plan.is_none_or(|p| p.moves.iter().all(|m| m.to != 2)),
            "a flight-host role was sent to another host"
        );
        roles[4].crosses_hosts = true;
        executors[2].reachable = false;
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(
            plan.is_none_or(|p| p.moves.iter().all(|m| m.to != 2)),
            "a role was sent over a link that is down"
        );
    }

    #[test]
    fn a_role_on_another_host_comes_back_when_its_link_slows_down() {
        // the reasoner runs on the ground: 600 ms of cycle plus a link that now costs
        // 700 ms; the flight's executors are free
        let (_, mut executors) = hog_case();
        executors[1].busy = 0.1;
        executors.push(ExecutorLoad {
            host: Some("ground".into()),
            link_ms: 700.0,
            ..ExecutorLoad::local("gs", 2.0, 0.1)
        });
        let mut reasoning = role("reasoning", 2, 1000.0, 1300.0, 0.0);
        reasoning.slowdown = 1.0;
        let roles = vec![role("hub", 0, 20.0, 0.5, 0.05), reasoning];
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(plan.moves.len(), 1);
        assert_eq!(plan.moves[0].role, 1);
        assert!(executors[plan.moves[0].to].host.is_none());
        // its cycle without the link it paid
        assert!((plan.predicted_ms[1].unwrap() - 600.0).abs() < 1e-6);
        // and never straight to a third host
        executors.push(ExecutorLoad {
            host: Some("cloud".into()),
            ..ExecutorLoad::local("big", 8.0, 0.0)
        });
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert!(plan.moves.iter().all(|m| executors[m.to].host.is_none()));
    }

    #[test]
    fn a_role_moves_between_executors_of_its_own_host() {
        // the reasoner on the ground host's `gs`, hogged there (slowdown 3); the flight's
        // executors are saturated; `gs2` on the same host is free
        let ground = |name: &str, busy: f64| ExecutorLoad {
            host: Some("ground".into()),
            link_ms: 5.0,
            ..ExecutorLoad::local(name, 1.0, busy)
        };
        let executors = vec![
            ExecutorLoad::local("control", 1.0, 2.0),
            ExecutorLoad::local("perception", 1.0, 2.0),
            ground("gs", 3.0),
            ground("gs2", 0.0),
        ];
        let mut reasoning = role("reasoning", 2, 1000.0, 5.0 + 600.0 * 3.0, 0.0);
        reasoning.slowdown = 3.0;
        let plan = plan_fewest_moves(&[reasoning], &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(plan.moves.len(), 1);
        assert_eq!(executors[plan.moves[0].to].name, "gs2", "{plan:?}");
        assert!((plan.predicted_ms[0].unwrap() - 605.0).abs() < 1e-6);
    }

    #[test]
    fn combinations_are_complete() {
        assert_eq!(combinations(4, 2).len(), 6);
        assert_eq!(combinations(3, 3), vec![vec![0, 1, 2]]);
        assert!(combinations(2, 3).is_empty());
    }

    /// A detector (budget 100 ms) at 250 ms on a hogged CPU, the other CPU busy too, and a
    /// CUDA executor: executors 0 and 1 are CPUs, 2 the accelerator.
    fn accelerator_case() -> (Vec<RoleLoad>, Vec<ExecutorLoad>) {
        let mut detector = role("detector", 1, 100.0, 250.0, 0.6);
        detector.slowdown = 2.5;
        detector.waiting = 0.9;
        let mut gpu = ex("gpu", 0.0);
        gpu.accelerator = Some("cuda:0".parse().unwrap());
        let roles = vec![role("hub", 0, 20.0, 0.5, 0.05), detector];
        (roles, vec![ex("cpu0", 1.0), ex("cpu1", 1.0), gpu])
    }

    #[test]
    fn a_role_no_cpu_can_cure_probes_an_accelerator_it_has_not_run_on() {
        let (roles, executors) = accelerator_case();
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a probe");
        assert!(plan.probe && !plan.restores, "{plan:?}");
        assert_eq!(
            plan.moves,
            [Move {
                role: 1,
                from: 1,
                to: 2
            }]
        );
        // its latency there is unknown until it runs there
        assert_eq!(plan.predicted_ms[1], None);
    }

    #[test]
    fn a_role_measured_on_the_accelerator_goes_there_by_its_figure() {
        let (mut roles, executors) = accelerator_case();
        roles[1].accelerator_ms = vec![(2, 12.0)];
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert!(plan.restores && !plan.probe, "{plan:?}");
        assert_eq!(plan.moves[0].to, 2);
        assert_eq!(plan.predicted_ms[1], Some(12.0));
        // measured too slow there: no probe again, relief on CPUs at most
        roles[1].accelerator_ms = vec![(2, 400.0)];
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(
            plan.as_ref()
                .is_none_or(|p| !p.probe && p.moves.iter().all(|m| m.to != 2)),
            "{plan:?}"
        );
    }

    #[test]
    fn a_role_slow_on_its_accelerator_goes_back_to_cpus_only_by_a_cpu_measurement() {
        let (mut roles, mut executors) = accelerator_case();
        // the detector runs on the GPU now, at 300 ms (the device is shared), CPU 1 is free
        roles[1].executor = 2;
        roles[1].latency_ms = Some(300.0);
        roles[1].slowdown = 1.0;
        roles[1].waiting = 0.0;
        roles[1].demand = 0.1;
        executors[1].busy = 0.0;
        assert_eq!(
            plan_fewest_moves(&roles, &executors, 0.2, 3, &[]),
            None,
            "never measured on CPUs: no prediction, no move"
        );
        roles[1].cpu_base_ms = Some(60.0);
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a plan");
        assert_eq!(
            plan.moves,
            [Move {
                role: 1,
                from: 2,
                to: 1
            }]
        );
        assert!((plan.predicted_ms[1].unwrap() - 60.0).abs() < 1e-9);
    }

    #[test]
    fn only_roles_an_accelerator_can_run_go_onto_it() {
        let (mut roles, mut executors) = accelerator_case();
        // a camera runs no model: no probe, no move there
        roles[1].kind_variant = (aeris_schemas::RoleKind::Camera, "sim-render".into());
        roles[1].accelerator_ms = vec![(2, 5.0)];
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(
            plan.as_ref()
                .is_none_or(|p| p.moves.iter().all(|m| m.to != 2)),
            "{plan:?}"
        );
        // a language model offloads to CUDA, not to TensorRT
        roles[1].kind_variant = (aeris_schemas::RoleKind::Reasoning, "smollm2".into());
        roles[1].accelerator_ms.clear();
        executors[2].accelerator = Some("tensorrt:0".parse().unwrap());
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]);
        assert!(plan.as_ref().is_none_or(|p| !p.probe), "{plan:?}");
        executors[2].accelerator = Some("cuda:0".parse().unwrap());
        let plan = plan_fewest_moves(&roles, &executors, 0.2, 3, &[]).expect("a probe");
        assert!(plan.probe, "{plan:?}");
    }

    #[test]
    fn a_two_thread_reasoner_is_never_moved_live_onto_one_cpu() {
        // the 2-core VM under load: the reasoner (2 llama.cpp threads) over budget on both
        // CPUs, a one-CPU executor predicted to fit it better
        let mut reasoning = role("reasoning", 0, 1000.0, 1157.0, 0.9);
        reasoning.slowdown = 1.6;
        reasoning.waiting = 0.5;
        reasoning.threads = 2;
        let two = ExecutorLoad {
            capacity: 2.0,
            ..ex("reasoning", 2.0)
        };
        let roles = vec![reasoning.clone()];
        let executors = vec![two.clone(), ex("perception", 0.2)];
        assert_eq!(plan_fewest_moves(&roles, &executors, 0.1, 3, &[]), None);
        // with one thread it may go
        let roles = vec![RoleLoad {
            threads: 1,
            ..reasoning
        }];
        let plan = plan_fewest_moves(&roles, &executors, 0.1, 3, &[]).expect("a plan");
        assert_eq!(plan.moves[0].to, 1);
    }
}
