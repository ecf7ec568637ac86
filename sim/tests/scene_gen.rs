//! Generated scenes: named by kind and seed, deterministic, referable landmarks unique,
//! nothing overlapping, the helipad clear.

use aeris_sim::scene_gen::{Airspace, SceneId, generate};
use aeris_sim::world::{LandmarkKind, World};
use std::collections::HashSet;

fn overlap(a: &aeris_sim::world::Landmark, b: &aeris_sim::world::Landmark) -> bool {
    (0..3).all(|k| a.min[k] < b.max[k] && b.min[k] < a.max[k])
}

#[test]
fn scene_names_parse_and_resolve() {
    assert_eq!(
        SceneId::parse("dense-42"),
        Some(SceneId {
            airspace: Airspace::Dense,
            seed: 42
        })
    );
    assert_eq!(SceneId::parse("open-0").unwrap().name(), "open-0");
    for bad in [
        "dense",
        "dense-",
        "dense-x",
        "dense--1",
        "city-3",
        "open-1e3",
        "open-99999999999999999999",
    ] {
        assert!(SceneId::parse(bad).is_none(), "{bad}");
    }
    assert_eq!(World::builtin("open-7").unwrap().name, "open-7");
    assert_eq!(
        World::builtin("open").unwrap().name,
        "open",
        "the fixed world keeps its name"
    );
}

#[test]
fn scenes_are_deterministic_and_differ_by_seed() {
    for airspace in Airspace::ALL {
        let a = generate(SceneId { airspace, seed: 5 });
        assert_eq!(a, generate(SceneId { airspace, seed: 5 }));
        assert_ne!(
            a.landmarks,
            generate(SceneId { airspace, seed: 6 }).landmarks
        );
    }
}

#[test]
fn landmarks_are_unique_apart_and_away_from_the_helipad() {
    for seed in 0..40 {
        for airspace in Airspace::ALL {
            let w = generate(SceneId { airspace, seed });
            let names: HashSet<&str> = w.landmarks.iter().map(|l| l.name.as_str()).collect();
            assert_eq!(names.len(), w.landmarks.len(), "{}: names unique", w.name);
            let obstacles: Vec<_> = w.landmarks.iter().filter(|l| l.is_obstacle()).collect();
            for (i, a) in obstacles.iter().enumerate() {
                for b in &obstacles[i + 1..] {
                    assert!(!overlap(a, b), "{}: {} overlaps {}", w.name, a.name, b.name);
                }
                assert!(
                    a.horizontal_distance(0.0, 0.0) > 20.0,
                    "{}: {} by the helipad",
                    w.name,
                    a.name
                );
            }
            // what instructions name: signs with text, one tower, the coloured roofs
            let signs = w
                .landmarks
                .iter()
                .filter(|l| matches!(l.kind, LandmarkKind::Sign { .. }))
                .count();
            assert!(signs >= 3, "{}", w.name);
            assert!(w.landmark_named("blue water tower").is_some());
            for roof in [
                "red-roofed building",
                "blue-roofed building",
                "green-roofed building",
            ] {
                assert!(w.landmark_named(roof).is_some(), "{}: {roof}", w.name);
            }
            match airspace {
                Airspace::Open => {
                    assert!(
                        w.landmark_named("bridge").is_some() && w.landmark_named("lake").is_some()
                    );
                    assert!(w.area_named("forest").is_some());
                }
                Airspace::Dense => {
                    let tall = w.landmarks.iter().filter(|l| l.max[2] > 30.0).count();
                    assert!(tall >= 5, "{}: dense airspace has tall buildings", w.name);
                }
            }
        }
    }
}
