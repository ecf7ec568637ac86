//! The built-in village: landmarks, obstacle queries, ray casts, and a clear mission path.

use aeris_sim::world::{GROUND, LandmarkKind, World, palette};

fn village() -> World {
    World::builtin("village").expect("village is built in")
}

/// The default mission's straight segments `[N, E]`.
const PATH: [[f32; 2]; 4] = [[0.0, 0.0], [62.0, 0.0], [62.0, 64.0], [42.0, 88.0]];

fn path_points(step: f32) -> Vec<[f32; 2]> {
    let mut out = Vec::new();
    for w in PATH.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        let n = (len / step).ceil() as usize;
        for i in 0..=n {
            let t = i as f32 / n as f32;
            out.push([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]);
        }
    }
    out
}

#[test]
fn builtin_names_resolve_and_unknown_names_do_not() {
    for name in World::builtin_names() {
        let w = World::builtin(name).expect("listed world exists");
        assert_eq!(w.name, *name);
        assert!(!w.landmarks.is_empty());
    }
    assert!(World::builtin("atlantis").is_none());
}

#[test]
fn village_landmarks_have_the_mission_coordinates() {
    let w = village();
    let red = w.landmark_named("red-roofed building").unwrap();
    assert_eq!(red.min, [72.0, 10.0, 0.0]);
    assert_eq!(red.max, [88.0, 26.0, 14.0]);
    assert_eq!(red.roof, palette::RED_ROOF);
    assert_eq!(red.wall, palette::BEIGE_WALL);
    let tower = w.landmark_named("blue water tower").unwrap();
    assert_eq!(
        (tower.min, tower.max),
        ([80.0, 60.0, 0.0], [86.0, 66.0, 24.0])
    );
    let sign = w.landmark_named("yellow sign that says LAKE VIEW").unwrap();
    assert_eq!(
        sign.kind,
        LandmarkKind::Sign {
            text: "LAKE VIEW".into()
        }
    );
    assert_eq!((sign.min, sign.max), ([34.0, 84.0, 2.0], [35.0, 92.0, 6.0]));
    let lake = w.landmark_named("lake").unwrap();
    assert_eq!(lake.kind, LandmarkKind::Water);
    assert_eq!(
        (lake.min[0], lake.max[0], lake.min[1], lake.max[1]),
        (0.0, 30.0, 80.0, 125.0)
    );
    assert!(w.landmark_named("road north").unwrap().kind.is_ground());
    assert!(w.landmark_named("road east").unwrap().kind.is_ground());
    assert!(w.landmark_named("helipad").unwrap().kind.is_ground());
    let trees = w
        .landmarks
        .iter()
        .filter(|l| l.kind == LandmarkKind::Tree)
        .count();
    assert!(trees >= 5, "a few trees, got {trees}");
}

#[test]
fn mission_path_keeps_six_metres_from_every_obstacle() {
    let w = village();
    let points = path_points(0.25);
    for l in w.landmarks.iter().filter(|l| l.is_obstacle()) {
        let closest = points
            .iter()
            .map(|p| l.horizontal_distance(p[0], p[1]))
            .fold(f32::INFINITY, f32::min);
        assert!(
            closest > 6.0,
            "{} is only {closest:.2} m from the mission path",
            l.name
        );
    }
}

#[test]
fn mission_path_is_collision_free_at_cruise_altitude() {
    let w = village();
    for p in path_points(0.5) {
        assert!(!w.collides([p[0], p[1], 12.0], 2.0), "collision at {p:?}");
    }
    // take-off and landing columns
    for i in 0..=24 {
        let u = i as f32 * 0.5;
        assert!(
            !w.collides([0.0, 0.0, u], 3.0),
            "take-off column blocked at {u}"
        );
        assert!(
            !w.collides([42.0, 88.0, u], 3.0),
            "landing column blocked at {u}"
        );
    }
    assert_eq!(w.obstacle_top_at(42.0, 88.0), 0.0);
    assert_eq!(w.obstacle_top_at(0.0, 0.0), 0.0);
}

#[test]
fn obstacle_tops_ignore_ground_patches() {
    let w = village();
    assert_eq!(w.obstacle_top_at(80.0, 18.0), 14.0);
    assert_eq!(w.obstacle_top_at(83.0, 63.0), 24.0);
    assert_eq!(w.obstacle_top_at(34.5, 88.0), 6.0);
    assert_eq!(w.obstacle_top_at(25.0, -20.0), 18.0);
    assert_eq!(w.obstacle_top_at(30.0, 0.0), 0.0, "road is ground");
    assert_eq!(w.obstacle_top_at(15.0, 100.0), 0.0, "lake is ground");
    assert_eq!(w.obstacle_top_at(-100.0, -100.0), 0.0, "grass");
}

#[test]
fn collides_detects_spheres_touching_boxes() {
    let w = village();
    assert!(w.collides([80.0, 18.0, 5.0], 0.1), "inside the building");
    assert!(
        w.collides([71.0, 18.0, 5.0], 1.5),
        "1 m from the south wall"
    );
    assert!(!w.collides([69.0, 18.0, 5.0], 1.5));
    assert!(!w.collides([80.0, 18.0, 16.0], 1.5), "above the roof");
    assert!(w.collides([80.0, 18.0, 15.0], 1.5), "1 m over the roof");
    assert!(w.collides([0.0, 0.0, -0.1], 0.1), "below ground");
    assert!(!w.collides([30.0, 0.0, 0.5], 0.3), "over the road");
}

#[test]
fn raycast_hits_walls_roofs_patches_and_grass() {
    let w = village();
    let red = w
        .landmarks
        .iter()
        .position(|l| l.name == "red-roofed building")
        .unwrap();
    let h = w
        .raycast([50.0, 18.0, 12.0], [1.0, 0.0, 0.0], 500.0)
        .unwrap();
    assert!((h.distance - 22.0).abs() < 1e-4, "{h:?}");
    assert_eq!(h.landmark, red);
    assert!(!h.roof);
    assert_eq!(h.normal, [-1.0, 0.0, 0.0]);

    let h = w
        .raycast([80.0, 18.0, 30.0], [0.0, 0.0, -1.0], 500.0)
        .unwrap();
    assert!((h.distance - 16.0).abs() < 1e-4);
    assert_eq!(h.landmark, red);
    assert!(h.roof);

    let road = w
        .landmarks
        .iter()
        .position(|l| l.name == "road north")
        .unwrap();
    let h = w
        .raycast([30.0, 0.0, 10.0], [0.0, 0.0, -1.0], 500.0)
        .unwrap();
    assert_eq!(h.landmark, road);
    assert!((h.distance - 9.95).abs() < 1e-4);

    let h = w
        .raycast([-100.0, -100.0, 10.0], [0.0, 0.0, -1.0], 500.0)
        .unwrap();
    assert_eq!(h.landmark, GROUND);
    assert!((h.distance - 10.0).abs() < 1e-4);

    // an oblique ray to the ground
    let d = [0.6, 0.0, -0.8];
    let h = w.raycast([-100.0, -100.0, 8.0], d, 500.0).unwrap();
    assert!((h.distance - 10.0).abs() < 1e-4);

    assert!(
        w.raycast([0.0, 0.0, 10.0], [0.0, 0.0, 1.0], 500.0)
            .is_none(),
        "sky"
    );
    assert!(
        w.raycast([50.0, 18.0, 12.0], [1.0, 0.0, 0.0], 20.0)
            .is_none(),
        "beyond max"
    );
    // from inside a box the box itself is not hit; the floor below is
    let h = w
        .raycast([80.0, 18.0, 5.0], [0.0, 0.0, -1.0], 500.0)
        .unwrap();
    assert_eq!(h.landmark, GROUND);
}
