//! The metrics on hand-computed trajectories: exact values, edge cases included.

use aeris_eval::metrics::{EpisodeMetrics, EpisodeRun, MetricsSummary, dtw, ndtw, path_length};

fn run<'a>(
    positions: &'a [[f64; 3]],
    reference: &'a [[f64; 3]],
    goal: [f64; 3],
    stopped: bool,
) -> EpisodeRun<'a> {
    EpisodeRun {
        positions,
        reference,
        goal,
        stopped,
        subgoals_completed: 0,
        subgoals_total: 0,
    }
}

#[test]
fn stopped_at_the_goal_on_the_reference_scores_everything() {
    let p = [[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]];
    let m = EpisodeMetrics::compute(&run(&p, &p, [3.0, 4.0, 0.0], true));
    assert_eq!(m.ne, Some(0.0));
    assert_eq!((m.sr, m.osr, m.ndtw, m.spl), (1.0, 1.0, 1.0, 1.0));
    assert_eq!(m.path_length_m, 5.0);
    assert_eq!(m.asr, None, "no subgoal annotation, no ASR");
}

#[test]
fn a_detour_scores_spl_and_ndtw_by_hand() {
    // start (0,0,0), goal (30,0,0); the agent flies 40 east, 30 north, 40 west
    let p = [
        [0.0, 0.0, 0.0],
        [0.0, 40.0, 0.0],
        [30.0, 40.0, 0.0],
        [30.0, 0.0, 0.0],
    ];
    let r = [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]];
    // DTW by hand: D(0,0)=0 D(0,1)=30 D(1,0)=40 D(1,1)=50 D(2,0)=90 D(2,1)=80 D(3,0)=120
    // D(3,1)=0+min(80,120,90)=80
    assert_eq!(dtw(&p, &r), 80.0);
    assert_eq!(ndtw(&p, &r), (-80.0f64 / 40.0).exp());
    assert_eq!(path_length(&p), 110.0);
    let m = EpisodeMetrics::compute(&run(&p, &r, [30.0, 0.0, 0.0], true));
    assert_eq!(m.ne, Some(0.0));
    assert_eq!(m.sr, 1.0);
    assert_eq!(m.spl, 30.0 / 110.0);
    assert_eq!(m.ndtw, (-2.0f64).exp());
}

#[test]
fn never_stopped_is_no_success_but_can_be_an_oracle_success() {
    let p = [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]];
    let m = EpisodeMetrics::compute(&run(&p, &p, [30.0, 0.0, 0.0], false));
    assert_eq!(m.ne, Some(0.0));
    assert_eq!((m.sr, m.osr, m.spl), (0.0, 1.0, 0.0));
}

#[test]
fn passing_the_goal_and_stopping_beyond_twenty_metres_is_only_an_oracle_success() {
    let p = [[0.0, 0.0, 0.0], [50.0, 0.0, 0.0], [85.0, 0.0, 0.0]];
    let m = EpisodeMetrics::compute(&run(&p, &p, [60.0, 0.0, 0.0], true));
    assert_eq!(m.ne, Some(25.0));
    assert_eq!((m.sr, m.osr, m.spl), (0.0, 1.0, 0.0));
    // exactly 20 m counts, in 3D
    let p = [[0.0, 0.0, 0.0], [60.0, 12.0, 16.0]];
    let m = EpisodeMetrics::compute(&run(&p, &p, [60.0, 0.0, 0.0], true));
    assert_eq!(m.ne, Some(20.0));
    assert_eq!(m.sr, 1.0);
}

#[test]
fn an_empty_trajectory_scores_zero_and_has_no_navigation_error() {
    let r = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]];
    let mut e = run(&[], &r, [10.0, 0.0, 0.0], true);
    e.subgoals_total = 4;
    let m = EpisodeMetrics::compute(&e);
    assert_eq!(m.ne, None);
    assert_eq!(
        (m.sr, m.osr, m.ndtw, m.spl, m.path_length_m),
        (0.0, 0.0, 0.0, 0.0, 0.0)
    );
    assert_eq!(m.asr, Some(0.0));
    assert_eq!(dtw(&[], &r), f64::INFINITY);
}

#[test]
fn a_reference_of_one_point_matches_every_position_to_it() {
    let p = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]];
    let r = [[0.0, 0.0, 0.0]];
    assert_eq!(dtw(&p, &r), 10.0);
    assert_eq!(ndtw(&p, &r), (-0.5f64).exp());
    // start at the goal, never moved, stopped: SPL 1 (0 / max(0, 0) is taken as 1)
    let m = EpisodeMetrics::compute(&run(&r, &r, [0.0, 0.0, 0.0], true));
    assert_eq!((m.sr, m.spl, m.ndtw), (1.0, 1.0, 1.0));
}

#[test]
fn asr_is_completed_over_total_and_the_summary_averages() {
    let p = [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]];
    let mut a = run(&p, &p, [30.0, 0.0, 0.0], true);
    a.subgoals_completed = 2;
    a.subgoals_total = 3;
    let ma = EpisodeMetrics::compute(&a);
    assert_eq!(ma.asr, Some(2.0 / 3.0));
    let mut b = run(&[], &p, [30.0, 0.0, 0.0], false);
    b.subgoals_completed = 9;
    b.subgoals_total = 3;
    let mb = EpisodeMetrics::compute(&b);
    assert_eq!(mb.asr, Some(1.0), "completed is capped at total");
    let s = MetricsSummary::of([&ma, &mb]);
    assert_eq!(s.episodes, 2);
    assert_eq!(s.sr, 0.5);
    assert_eq!(s.osr, 0.5);
    assert_eq!(
        s.ne,
        Some(0.0),
        "NE averages over the episodes that have one"
    );
    assert_eq!(s.asr, Some((2.0 / 3.0 + 1.0) / 2.0));
    let none = MetricsSummary::of([]);
    assert_eq!((none.episodes, none.sr, none.ne), (0, 0.0, None));
}

#[test]
fn dtw_is_the_exact_minimum_over_alignments() {
    // brute force over all monotone alignments on small random-ish paths
    fn brute(p: &[[f64; 3]], r: &[[f64; 3]], i: usize, j: usize) -> f64 {
        let d = aeris_eval::metrics::distance(p[i], r[j]);
        if i == 0 && j == 0 {
            return d;
        }
        let mut best = f64::INFINITY;
        if i > 0 {
            best = best.min(brute(p, r, i - 1, j));
        }
        if j > 0 {
            best = best.min(brute(p, r, i, j - 1));
        }
        if i > 0 && j > 0 {
            best = best.min(brute(p, r, i - 1, j - 1));
        }
        d + best
    }
    let p: Vec<[f64; 3]> = (0..6)
        .map(|k| [(k * 7 % 5) as f64, (k * 3 % 4) as f64, k as f64])
        .collect();
    let r: Vec<[f64; 3]> = (0..5)
        .map(|k| [(k * 2 % 3) as f64, k as f64, (k * 5 % 7) as f64])
        .collect();
    let exact = brute(&p, &r, p.len() - 1, r.len() - 1);
    assert!(
        (dtw(&p, &r) - exact).abs() < 1e-9,
        "{} vs {exact}",
        dtw(&p, &r)
    );
}
