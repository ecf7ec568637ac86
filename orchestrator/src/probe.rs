//! The initial binding's probes (pi_0): a role that does not fit its budget on the executor
//! its workflow declares is moved, live, to each other executor for a few scheduling ticks,
//! and what it measured there decides where it is bound. Pure functions of the figures, so
//! the choice is testable without processes; the supervisor makes the moves.
//!
//! A probe measures the role's slowdown `(run + wait) / run` on the candidate (the
//! scheduler's own account of how much a cycle stretches there, with the role's own load
//! on it), and a whole cycle when one finished there. The latency a probe predicts is that
//! cycle, else the role's base cost at home (`latency / slowdown`) times the slowdown
//! measured on the candidate. Unlike the load model of [`crate::rebind`], this sees what
//! `/proc` busy figures miss: run-queue priorities, a throttled or shared core, a noisy
//! neighbour that only shows up once the role is there.

use crate::rebind::ExecutorLoad;

/// What one probe measured of a role on one executor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeFigure {
    /// Index of the executor probed.
    pub executor: usize,
    /// Slowdown `(run + wait) / run` measured there (>= 1).
    pub slowdown: f64,
    /// A whole cycle measured there (ms), when one started and finished during the probe.
    pub cycle_ms: Option<f64>,
}

/// A role the initial binding probes, with what it measured at home.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbedRole {
    /// Role index (in the supervisor's role list).
    pub role: usize,
    /// Index of the executor the workflow bound it to.
    pub home: usize,
    /// Its latency at home (ms): the same signal re-binding uses.
    pub latency_ms: f64,
    /// Its slowdown at home (>= 1).
    pub slowdown: f64,
    /// Its CPU demand (cores).
    pub demand: f64,
    /// Its budget (ms).
    pub budget_ms: f64,
    /// What it measured on each other executor probed.
    pub figures: Vec<ProbeFigure>,
}

impl ProbedRole {
    /// The latency `figure` predicts for the role on its executor (ms).
    pub fn predicted_ms(&self, figure: &ProbeFigure) -> f64 {
        figure
            .cycle_ms
            .unwrap_or(self.latency_ms / self.slowdown.max(1.0) * figure.slowdown.max(1.0))
    }
}

/// Where the probes say a role belongs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeChoice {
    /// Role index.
    pub role: usize,
    /// Executor it leaves (its home).
    pub from: usize,
    /// Executor it goes to (its home when it stays).
    pub to: usize,
    /// Latency predicted there (ms), other choices' load included.
    pub predicted_ms: f64,
}

/// One choice per probed role: the executor with the lowest predicted latency, taken only
/// when it beats staying home by `margin` (a fraction: a move must be worth its cost).
///
/// Roles choose in order of how far over budget they are, worst first; each role a choice
/// sends to an executor adds its demand there for the roles that choose after it (and a
/// role leaving frees its home), so two roles do not both pick the executor that was free
/// only while each was probed alone.
pub fn bind_from_probes(
    roles: &[ProbedRole],
    executors: &[ExecutorLoad],
    margin: f64,
) -> Vec<ProbeChoice> {
    let mut order: Vec<usize> = (0..roles.len()).collect();
    let ratio = |r: &ProbedRole| r.latency_ms / r.budget_ms.max(1e-9);
    order.sort_by(|&a, &b| ratio(&roles[b]).total_cmp(&ratio(&roles[a])));
    // cores added to (or taken from) each executor by the choices so far
    let mut added = vec![0.0; executors.len()];
    let stretch = |added: &[f64], e: usize, measured: f64| {
        let capacity = executors.get(e).map_or(1.0, |x| x.capacity.max(1e-9));
        let extra = added.get(e).copied().unwrap_or(0.0) / capacity;
        (measured.max(1.0) + extra).max(1.0) / measured.max(1.0)
    };
    let mut choices = Vec::with_capacity(roles.len());
    for i in order {
        let r = &roles[i];
        let stay = r.latency_ms * stretch(&added, r.home, r.slowdown);
        let best = r
            .figures
            .iter()
            .filter(|f| f.executor != r.home && f.executor < executors.len())
            .map(|f| {
                (
                    f.executor,
                    r.predicted_ms(f) * stretch(&added, f.executor, f.slowdown),
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let (to, predicted_ms) = match best {
            Some((e, p)) if p < stay * (1.0 - margin) => (e, p),
            _ => (r.home, stay),
        };
        if to != r.home {
            added[to] += r.demand;
            added[r.home] -= r.demand;
        }
        choices.push(ProbeChoice {
            role: r.role,
            from: r.home,
            to,
            predicted_ms,
        });
    }
    choices
}

#[cfg(test)]
mod tests {
    use super::*;

    fn executors(n: usize) -> Vec<ExecutorLoad> {
        (0..n)
            .map(|i| ExecutorLoad::local(&format!("e{i}"), 1.0, 0.0))
            .collect()
    }

    fn probed(role: usize, latency_ms: f64, slowdown: f64, figures: &[(usize, f64)]) -> ProbedRole {
        ProbedRole {
            role,
            home: 0,
            latency_ms,
            slowdown,
            demand: 0.9,
            budget_ms: 100.0,
            figures: figures
                .iter()
                .map(|&(executor, slowdown)| ProbeFigure {
                    executor,
                    slowdown,
                    cycle_ms: None,
                })
                .collect(),
        }
    }

    #[test]
    fn a_probe_predicts_from_the_base_cost_and_prefers_a_measured_cycle() {
        let r = probed(0, 300.0, 3.0, &[(1, 1.2)]);
        assert!((r.predicted_ms(&r.figures[0]) - 120.0).abs() < 1e-9);
        let f = ProbeFigure {
            executor: 1,
            slowdown: 1.2,
            cycle_ms: Some(95.0),
        };
        assert_eq!(r.predicted_ms(&f), 95.0);
    }

    #[test]
    fn a_role_goes_where_it_measured_fastest() {
        // 300 ms at home (slowdown 3); e1 measured 2.0, e2 measured 1.1
        let choices = bind_from_probes(
            &[probed(4, 300.0, 3.0, &[(1, 2.0), (2, 1.1)])],
            &executors(3),
            0.2,
        );
        assert_eq!(choices.len(), 1);
        let c = choices[0];
        assert_eq!((c.role, c.from, c.to), (4, 0, 2));
        assert!((c.predicted_ms - 110.0).abs() < 1e-9, "{c:?}");
    }

    #[test]
    fn a_gain_inside_the_margin_keeps_the_role_home() {
        // 10 % better elsewhere, margin 20 %: not worth a move
        let choices = bind_from_probes(&[probed(0, 110.0, 1.1, &[(1, 1.0)])], &executors(2), 0.2);
        assert_eq!((choices[0].to, choices[0].predicted_ms), (0, 110.0));
        // nothing probed (no other executor): home
        let choices = bind_from_probes(&[probed(0, 300.0, 3.0, &[])], &executors(1), 0.2);
        assert_eq!(choices[0].to, 0);
    }

    #[test]
    fn two_roles_do_not_both_take_the_executor_that_was_free_for_each_alone() {
        // both measured e1 free (slowdown 1.0) while the other was still home; the worse
        // one takes it, and e1 with its demand on it is no longer better for the other
        // than home (which the first one left)
        let a = probed(0, 400.0, 2.0, &[(1, 1.0)]);
        let b = probed(1, 300.0, 2.0, &[(1, 1.0)]);
        let choices = bind_from_probes(&[b.clone(), a.clone()], &executors(2), 0.2);
        let of = |role: usize| choices.iter().find(|c| c.role == role).unwrap();
        assert_eq!(of(0).to, 1, "the worst first: {choices:?}");
        assert_eq!(of(1).to, 0, "{choices:?}");
        // home got lighter by a's demand: b's prediction there falls
        assert!(of(1).predicted_ms < 300.0, "{choices:?}");
        // a probe figure naming an executor that does not exist is ignored
        let c = bind_from_probes(&[probed(0, 300.0, 3.0, &[(7, 1.0)])], &executors(2), 0.2);
        assert_eq!(c[0].to, 0);
    }
}
