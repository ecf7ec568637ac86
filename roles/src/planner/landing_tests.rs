//! The planner landing next to a building: beside it, never on its roof, and on ground the
//! hub's gate lets it come down on.

use super::tests::{seen, vln_mission};
use super::*;

#[test]
fn a_landing_next_to_a_building_comes_down_beside_it_never_on_its_roof() {
    let m = vln_mission();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    p.current = 2;
    p.steps[2] = Some(Step {
        action: ActionMode::Land,
        target: StepTarget::Find(
            LandmarkPhrase::parse("land next to the blue-roofed building").unwrap(),
        ),
        turn: 0.0,
    });
    // a 40 m building of 25 m at N, E in [100, 140] (cells of 2 m, as perception's)
    let grid = |origin: [f32; 2], under_unknown: bool| {
        let mut g = aeris_schemas::OccupancyGrid::observed(origin, 2.0);
        for (i, cell) in g.cells.iter_mut().enumerate() {
            let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
            let n = origin[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            let e = origin[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            let roof = (100.0..140.0).contains(&n) && (100.0..140.0).contains(&e);
            let under = (n - origin[0]).hypot(e - origin[1]) < 30.0;
            *cell = if under && under_unknown {
                aeris_schemas::OCCUPANCY_UNKNOWN
            } else if roof {
                25
            } else {
                0
            };
        }
        g
    };
    // seen from afar, high, looking south-east: the range reads the roof's far side
    let at = [70.0, 70.0, 50.0];
    let se = core::f32::consts::FRAC_PI_4;
    let mut s = seen("blue roof", [0.45, 0.45, 0.1, 0.1], 90.0, at, se);
    s.occupancy = grid([70.0, 70.0], true);
    let d = p.decide(at, se, false, Some(&s));
    let on_roof = |t: [f32; 3]| (100.0..140.0).contains(&t[0]) && (100.0..140.0).contains(&t[1]);
    let found = p.search.found.unwrap();
    assert!(found[0] > 120.0 && found[1] > 120.0, "{found:?}");
    assert!(!on_roof(d.target), "{:?}", d.target);
    let toward = |t: [f32; 3], c: [f32; 2]| (t[0] - c[0]).hypot(t[1] - c[1]);
    assert!(
        toward(d.target, [70.0, 70.0]) < toward([120.0, 120.0, 0.0], [70.0, 70.0]) - 10.0,
        "the approach side: {:?}",
        d.target
    );
    assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
    // over the roof's edge now, the camera sees only the roof ahead and nothing below:
    // the touchdown stays where the flight saw clear ground
    let over = [104.0, 104.0, 40.0];
    let mut s2 = seen("blue roof", [0.45, 0.6, 0.1, 0.1], 30.0, over, se);
    s2.occupancy = grid([104.0, 104.0], true);
    let d2 = p.decide(over, se, false, Some(&s2));
    assert!(!on_roof(d2.target), "{:?}", d2.target);
    assert_eq!((d2.target[0], d2.target[1]), (d.target[0], d.target[1]));
    // over the touchdown, descending: a frame now shows a 3 m obstacle (a wall cell
    // read close by) 2 m from it, which spoils its clear square; the touchdown stays
    // (its own cell is free) and the landing goes on
    let t = p.search.touchdown.expect("a touchdown");
    let above = [t[0], t[1], 12.0];
    let mut s4 = seen("blue roof", [0.45, 0.6, 0.1, 0.1], 30.0, above, se);
    let mut near_wall = grid([t[0], t[1]], false);
    let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
    for (i, cell) in near_wall.cells.iter_mut().enumerate() {
        let n = t[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        let e = t[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        if (n - t[0] - 3.0).abs() <= 1.0 && (e - t[1]).abs() <= 1.0 {
            *cell = 3;
        }
    }
    s4.occupancy = near_wall;
    let d4 = p.decide(above, se, false, Some(&s4));
    assert!(
        !p.map.is_clear(t, TOUCHDOWN_CLEAR_M),
        "the wall cell spoils the square: {t:?} {:?} {:?} {:?}",
        p.map.height_at([t[0] + 3.0, t[1]]),
        p.map.height_at([t[0] + 2.0, t[1]]),
        p.map.height_at([t[0] + 4.0, t[1]])
    );
    assert_eq!(p.search.touchdown, Some(t));
    assert_eq!(
        (ActionMode::from_u8(d4.action), d4.target[0], d4.target[1]),
        (Some(ActionMode::Land), t[0], t[1])
    );
    // lower down, a roof shows right beside the touchdown (the hub's cells from it to 4 m
    // north, centred on the vehicle as the hub's grid is): the hub's cell of the touchdown
    // can share this map's roof cell, and the gate would refuse the descent every
    // heartbeat, so the landing moves to ground clear all round
    let low = [t[0], t[1], 8.0];
    let mut s5 = seen("blue roof", [0.45, 0.6, 0.1, 0.1], 30.0, low, se);
    let mut beside = grid([t[0], t[1]], false);
    for (i, cell) in beside.cells.iter_mut().enumerate() {
        let n = t[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        let e = t[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        if (0.0..4.0).contains(&(n - t[0])) && (e - t[1]).abs() <= 1.0 {
            *cell = 10;
        }
    }
    s5.occupancy = beside;
    let d5 = p.decide(low, se, false, Some(&s5));
    let moved = p.search.touchdown.expect("a touchdown");
    assert_ne!(moved, t, "the touchdown beside the roof is kept");
    assert!(p.map.is_clear(moved, TOUCHDOWN_CLEAR_M), "{moved:?}");
    assert!(!on_roof([moved[0], moved[1], 0.0]), "{moved:?}");
    assert_eq!(
        (ActionMode::from_u8(d5.action), d5.target[0], d5.target[1]),
        (Some(ActionMode::Land), moved[0], moved[1])
    );
    // a planner that never saw clear ground beside it (only 16 m off, farther than
    // "next to" reaches) lands there rather than on the roof under it
    let mut q = Planner::new(&m, &CameraSpec::default()).unwrap();
    q.current = 2;
    q.steps[2] = p.steps[2];
    let mut roof_only = grid([120.0, 120.0], false);
    for (i, cell) in roof_only.cells.iter_mut().enumerate() {
        let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
        let n = 120.0 + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        if *cell == 0 && n > 88.0 {
            *cell = aeris_schemas::OCCUPANCY_UNKNOWN;
        }
    }
    let mut s3 = seen("blue roof", [0.45, 0.45, 0.1, 0.1], 20.0, over, se);
    s3.occupancy = roof_only;
    for _ in 0..(TOUCHDOWN_WAIT + 2) {
        let d3 = q.decide(over, se, false, Some(&s3));
        assert!(
            !on_roof(d3.target) && d3.target[0] <= 88.0,
            "{:?}",
            d3.target
        );
    }
    assert_eq!(q.search.touchdown, None);
}

#[test]
fn a_landing_given_up_beside_a_building_comes_down_on_clear_ground() {
    let m = vln_mission();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    // nothing of the landmark in sight; a 10 m building whose west wall stands 1 m east of
    // where the search legs end ([0, 160]: four 40 m legs east), every other cell free
    let roof = |n: f32, e: f32| (0.0..20.0).contains(&n) && (161.0..181.0).contains(&e);
    let state = |at: [f32; 3]| {
        let mut s = PerceptionState {
            position: at,
            ..PerceptionState::default()
        };
        s.occupancy = aeris_schemas::OccupancyGrid::observed([at[0], at[1]], 2.0);
        let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
        for (i, cell) in s.occupancy.cells.iter_mut().enumerate() {
            let n = at[0] + ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            let e = at[1] + ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
            *cell = if roof(n, e) { 10 } else { 0 };
        }
        s
    };
    let (mut at, mut yaw) = ([0.0, 0.0, 15.0], 0.0);
    let mut land = None;
    for _ in 0..200 {
        let d = p.decide(at, yaw, false, Some(&state(at)));
        if ActionMode::from_u8(d.action) == Some(ActionMode::Land) {
            land = Some(d);
            break;
        }
        // the vehicle goes where it is told at once
        at = d.target;
        yaw = d.yaw;
    }
    let d = land.expect("a landing after the search legs");
    let ended = [at[0], at[1]];
    assert!(
        (ended[1] - MAX_SEARCH_LEGS as f32 * SEARCH_LEG_M).abs() < 1.0,
        "{ended:?}"
    );
    // not straight down beside the wall, where the hub's cell of the touchdown can hold
    // the roof: on ground clear all round, within reach
    let t = [d.target[0], d.target[1]];
    assert!(p.map.is_clear(t, TOUCHDOWN_CLEAR_M), "{t:?}");
    assert!(
        ground_distance(t, ended) <= FALLBACK_CLEAR_M,
        "{t:?} from {ended:?}"
    );
    // and it stays there, heartbeat after heartbeat, on the way down
    let above = [t[0], t[1], 8.0];
    let again = p.decide(above, yaw, false, Some(&state(above)));
    assert_eq!(
        (
            ActionMode::from_u8(again.action),
            again.target[0],
            again.target[1]
        ),
        (Some(ActionMode::Land), t[0], t[1])
    );
}
