//! The episode generator: collision-free references, consistent subgoal annotation,
//! unseen splits, determinism.

use aeris_eval::generate::{AirspaceFilter, Split, generate_split};
use aeris_sim::world::World;
use std::collections::BTreeSet;

/// Sample `a`-`b` every 0.25 m.
fn samples(a: [f64; 3], b: [f64; 3]) -> impl Iterator<Item = [f32; 3]> {
    let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
    let n = (len / 0.25).ceil().max(1.0) as usize;
    (0..=n).map(move |i| {
        let t = i as f64 / n as f64;
        [
            (a[0] + (b[0] - a[0]) * t) as f32,
            (a[1] + (b[1] - a[1]) * t) as f32,
            (a[2] + (b[2] - a[2]) * t) as f32,
        ]
    })
}

#[test]
fn reference_trajectories_never_pass_through_a_building() {
    let mut checked = 0;
    for split in Split::ALL {
        let eps = generate_split(split, AirspaceFilter::Full, 16, &mut |_, _| {}).unwrap();
        for e in &eps {
            let world = World::builtin(&e.scene_id).expect("generated scene");
            let r = e.reference_positions();
            assert!(r.len() >= 3, "{}", e.episode_id);
            for w in r.windows(2) {
                for p in samples(w[0], w[1]) {
                    // a 2 m sphere around every point of the path is clear of obstacles
                    assert!(
                        !world.collides(p, 2.0),
                        "{}: reference passes through an obstacle at {p:?}",
                        e.episode_id
                    );
                }
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 48);
}

#[test]
fn subgoals_segment_the_reference_and_name_real_landmarks() {
    let eps = generate_split(Split::Train, AirspaceFilter::Full, 12, &mut |_, _| {}).unwrap();
    for e in &eps {
        let world = World::builtin(&e.scene_id).unwrap();
        let s = &e.subgoals;
        assert!(
            s.len() >= 3,
            "takeoff, at least one leg, land: {}",
            e.episode_id
        );
        assert_eq!(s[0].action, "takeoff");
        assert_eq!(s.last().unwrap().action, "land");
        assert_eq!(s[0].reference_range[0], 0);
        assert_eq!(
            s.last().unwrap().reference_range[1],
            e.reference_path.len() - 1
        );
        for w in s.windows(2) {
            assert_eq!(
                w[1].reference_range[0],
                w[0].reference_range[1] + 1,
                "{}",
                e.episode_id
            );
        }
        for g in s {
            assert!(
                e.instruction
                    .instruction_text
                    .to_lowercase()
                    .contains(&g.text.to_lowercase())
            );
            // each step ends where its reference segment ends
            let end = &e.reference_path[g.reference_range[1]];
            for (got, want) in end.iter().zip(g.waypoint) {
                assert!((got - want).abs() < 0.011, "{}: {g:?}", e.episode_id);
            }
            if let Some(name) = &g.landmark {
                let known = world.landmark_named(name).is_some_and(|l| l.is_referable())
                    || world.area_named(name).is_some();
                assert!(known, "{}: names `{name}`", e.episode_id);
            }
        }
        assert_eq!(e.goal(), s.last().unwrap().waypoint);
        assert_eq!(e.goal()[2], 0.0, "episodes end on the ground");
        let g = e.goal();
        assert!(
            g[0].hypot(g[1]) > 30.0,
            "{}: the goal is far from the start",
            e.episode_id
        );
        assert_eq!(e.start_position, [0.0, 0.0, 0.0]);
    }
}

#[test]
fn unseen_splits_use_scenes_not_in_train_and_generation_is_deterministic() {
    let scenes = |split| -> BTreeSet<String> {
        generate_split(split, AirspaceFilter::Full, 24, &mut |_, _| {})
            .unwrap()
            .into_iter()
            .map(|e| e.scene_id)
            .collect()
    };
    let (train, val, test) = (
        scenes(Split::Train),
        scenes(Split::ValUnseen),
        scenes(Split::TestUnseen),
    );
    assert!(train.is_disjoint(&val) && train.is_disjoint(&test) && val.is_disjoint(&test));
    assert!(
        val.iter().any(|s| s.starts_with("open-")) && val.iter().any(|s| s.starts_with("dense-"))
    );
    let mut calls = 0;
    let a = generate_split(
        Split::TestUnseen,
        AirspaceFilter::Dense,
        5,
        &mut |done, total| {
            calls += 1;
            assert_eq!(total, 5);
            assert_eq!(done, calls);
        },
    )
    .unwrap();
    let b = generate_split(Split::TestUnseen, AirspaceFilter::Dense, 5, &mut |_, _| {}).unwrap();
    assert_eq!(a, b);
    assert!(a.iter().all(|e| e.airspace.as_deref() == Some("dense")));
    let ids: BTreeSet<&str> = a.iter().map(|e| e.episode_id.as_str()).collect();
    assert_eq!(ids.len(), 5);
}
