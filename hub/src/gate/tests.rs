//! The decision gate's unit tests: binding, validation, clamping and rejection against
//! walls, the altitude band and the geofence, and the way check of a bound setpoint.

use super::*;
use aeris_schemas::OCCUPANCY_CELLS;

fn limits() -> DecisionLimits {
    DecisionLimits {
        v_max: 8.0,
        h_min: 2.0,
        h_max: 60.0,
        r_max: 10.0,
        geofence_min: [-100.0, -100.0, 0.0],
        geofence_max: [100.0, 100.0, 60.0],
        obstacle_clearance_m: 3.0,
        subgoals: 4,
    }
}

fn gate() -> DecisionGate {
    DecisionGate::new(limits()).unwrap()
}

fn decision(action: ActionMode, target: [f32; 3], altitude: f32) -> Decision {
    Decision {
        seq: 9,
        target,
        yaw: 0.25,
        speed: 5.0,
        altitude,
        acceptance_radius: 2.0,
        confidence: 0.9,
        step: 2,
        action: action as u8,
        ..Decision::default()
    }
}

/// 1 m cells centred on the origin, all free ground.
fn free_grid() -> OccupancyGrid {
    OccupancyGrid {
        cells: [0; OCCUPANCY_CELLS],
        ..OccupancyGrid::observed([0.0, 0.0], 1.0)
    }
}

fn set(g: &mut OccupancyGrid, n: f32, e: f32, top: u8) {
    let i = g.cell_of([n, e]).unwrap();
    g.cells[i] = top;
}

#[test]
fn binds_each_action() {
    let g = gate();
    let v = [1.0, 2.0, 5.0];
    let t = [30.0, -10.0, 12.0];
    let cases = [
        (ActionMode::Takeoff, [1.0, 2.0, 12.0]),
        (ActionMode::Ascend, [1.0, 2.0, 12.0]),
        (ActionMode::Descend, [1.0, 2.0, 12.0]),
        (ActionMode::Turn, [1.0, 2.0, 12.0]),
        (ActionMode::Goto, [30.0, -10.0, 12.0]),
        (ActionMode::Hover, [30.0, -10.0, 12.0]),
        (ActionMode::Stop, [30.0, -10.0, 12.0]),
        (ActionMode::Land, [30.0, -10.0, 0.0]),
    ];
    for (mode, want) in cases {
        let sp = g
            .admit(&decision(mode, t, 12.0), v, Some(&free_grid()))
            .unwrap();
        assert_eq!(sp.position, want, "{mode:?}");
        assert_eq!(sp.mode, mode as u8);
        assert_eq!((sp.yaw, sp.speed, sp.acceptance_radius), (0.25, 5.0, 2.0));
        assert_eq!((sp.active_step, sp.decision_seq, sp.clamped), (2, 9, 0));
    }
}

#[test]
fn rejects_invalid_and_non_finite() {
    let g = gate();
    let mut d = decision(ActionMode::Goto, [10.0, 0.0, 10.0], 10.0);
    d.speed = f32::NAN;
    assert!(matches!(
        g.admit(&d, [0.0; 3], None),
        Err(GateError::Invalid(DecisionError::NonFinite { .. }))
    ));
    let d = decision(ActionMode::Goto, [10.0, 0.0, 10.0], 10.0);
    assert!(matches!(
        g.admit(&d, [f32::NAN, 0.0, 0.0], None),
        Err(GateError::BadPosition(_))
    ));
    let mut grid = free_grid();
    grid.origin[0] = f32::INFINITY;
    assert_eq!(g.admit(&d, [0.0; 3], Some(&grid)), Err(GateError::BadGrid));
}

#[test]
fn clamps_before_a_wall_with_clearance() {
    let g = gate();
    let mut grid = free_grid();
    // a wall 20 m high across the path at N in [10, 11)
    for e in -32..32 {
        set(&mut grid, 10.5, e as f32 + 0.5, 20);
    }
    let d = decision(ActionMode::Goto, [25.0, 0.0, 10.0], 10.0);
    let sp = g.admit(&d, [0.0, 0.0, 10.0], Some(&grid)).unwrap();
    assert_eq!(sp.clamped, 1);
    assert!((sp.position[0] - 7.0).abs() < 1e-4, "{:?}", sp.position);
    assert_eq!(sp.position[1], 0.0);
    // flying above the wall (20 <= 24 - 3) passes
    let d = decision(ActionMode::Goto, [25.0, 0.0, 24.0], 24.0);
    let sp = g.admit(&d, [0.0, 0.0, 10.0], Some(&grid)).unwrap();
    assert_eq!((sp.position, sp.clamped), ([25.0, 0.0, 24.0], 0));
    // too close to pull back: it climbs where it is to 20 + 3 + 0.5 m first...
    let d = decision(ActionMode::Goto, [25.0, 0.0, 10.0], 10.0);
    let sp = g.admit(&d, [6.5, 0.0, 10.0], Some(&grid)).unwrap();
    assert_eq!((sp.position, sp.clamped), ([6.5, 0.0, 23.5], 1));
    // ...and once up there (within half the clearance of it) flies over at that height
    let sp = g.admit(&d, [6.5, 0.0, 22.0], Some(&grid)).unwrap();
    assert_eq!((sp.position, sp.clamped), ([25.0, 0.0, 23.5], 1));
    assert_eq!(g.check_way(&sp, [6.5, 0.0, 22.0], Some(&grid)), Ok(()));
    // a vehicle hovering higher than the decision asks is not sent down into the wall: the
    // way is raised, not refused (a flight hovered beside an 18 m top refusing 74 decisions)
    let sp = g.admit(&d, [6.5, 0.0, 30.0], Some(&grid)).unwrap();
    assert_eq!((sp.position, sp.clamped), ([25.0, 0.0, 23.5], 1));
    // a second, taller wall beyond raises the way again, or pulls it back before it
    for e in -32..32 {
        set(&mut grid, 20.5, e as f32 + 0.5, 22);
    }
    let sp = g.admit(&d, [6.5, 0.0, 30.0], Some(&grid)).unwrap();
    assert_eq!(sp.position[2], 23.5);
    assert!((sp.position[0] - 17.0).abs() < 1e-4, "{:?}", sp.position);
    // a wall whose raised height is above the band is refused
    for e in -32..32 {
        set(&mut grid, 10.5, e as f32 + 0.5, 57);
    }
    assert!(matches!(
        g.admit(&d, [6.5, 0.0, 10.0], Some(&grid)),
        Err(GateError::Blocked { top_m: 57.0, .. })
    ));
}

#[test]
fn unknown_cells_are_free_and_corners_are_not_skipped() {
    let g = gate();
    let mut grid = OccupancyGrid::observed([0.0, 0.0], 1.0);
    let d = decision(ActionMode::Goto, [20.0, 20.0, 10.0], 10.0);
    assert_eq!(
        g.admit(&d, [0.0; 3], Some(&grid)).unwrap().position,
        [20.0, 20.0, 10.0]
    );
    // a single cell the diagonal only grazes at its corner region: (10, 9)
    grid.cells[(32 + 10) * OCCUPANCY_SIDE + 32 + 9] = 50;
    let d = decision(ActionMode::Goto, [20.0, 19.9, 10.0], 10.0);
    let sp = g.admit(&d, [0.0; 3], Some(&grid)).unwrap();
    assert_eq!(sp.clamped, 1);
    assert!(sp.position[0] < 10.0 - 2.0, "{:?}", sp.position);
}

/// Regression (found by the `gate_json` fuzz corpus, `fuzz/regressions/gate_json/`): a
/// target exactly on the near edge of a blocking cell is inside that cell, but the walk
/// stopped one cell short when the rounding of its accumulated crossing times put the
/// last crossing just past the end (here 20 x 0.05 = 1.0000000000000002 > 1), and the
/// decision was admitted with no clearance to a wall higher than its altitude.
#[test]
fn a_target_on_the_edge_of_a_blocking_cell_is_pulled_back() {
    let g = gate();
    let mut grid = free_grid();
    grid.origin = [20.0, 0.0];
    // a wall 20 m high at N in [30, 31)
    for e in -32..32 {
        set(&mut grid, 30.5, e as f32 + 0.5, 20);
    }
    for mode in [ActionMode::Hover, ActionMode::Goto, ActionMode::Stop] {
        let d = decision(mode, [30.0, 0.0, 12.0], 12.0);
        let sp = g.admit(&d, [10.0, 5.0, 12.0], Some(&grid)).unwrap();
        assert_eq!(sp.clamped, 1, "{mode:?}: {sp:?}");
        // 3 m before the wall along the way from [10, 5]
        let back = [30.0 - 20.0 * 3.0 / 425f32.sqrt(), 5.0 * 3.0 / 425f32.sqrt()];
        assert!((sp.position[0] - back[0]).abs() < 1e-3, "{mode:?}: {sp:?}");
        assert!((sp.position[1] - back[1]).abs() < 1e-3, "{mode:?}: {sp:?}");
    }
    // coming from the north, N = 31 is the first point outside the wall's cell
    let d = decision(ActionMode::Goto, [31.0, 0.0, 12.0], 12.0);
    let sp = g.admit(&d, [50.0, 3.0, 12.0], Some(&grid)).unwrap();
    assert_eq!((sp.position, sp.clamped), ([31.0, 0.0, 12.0], 0));
}

/// What the gate bound passes the way check from where it was bound (a clamped goto, a
/// raised climb, a landing); an obstacle that shows up on the way afterwards fails it.
#[test]
fn a_bound_setpoint_passes_the_way_check_until_an_obstacle_shows_up() {
    let g = gate();
    let mut grid = free_grid();
    for e in -32..32 {
        set(&mut grid, 10.5, e as f32 + 0.5, 20);
    }
    set(&mut grid, -5.5, -5.5, 15);
    let v = [0.5, 0.5, 10.0];
    let roof = [-5.5, -5.5, 10.0];
    for (mode, at, target, altitude) in [
        (ActionMode::Goto, v, [25.0, 0.0, 10.0], 10.0),
        (ActionMode::Hover, v, [5.0, -5.0, 10.0], 10.0),
        (ActionMode::Ascend, roof, [0.0, 0.0, 12.0], 12.0),
        (ActionMode::Land, v, [5.0, 5.0, 0.0], 10.0),
    ] {
        let sp = g
            .admit(&decision(mode, target, altitude), at, Some(&grid))
            .unwrap();
        assert_eq!(
            g.check_way(&sp, at, Some(&grid)),
            Ok(()),
            "{mode:?}: {sp:?}"
        );
        // without occupancy, only the climb in place may go on below 60 m
        let blind = g.check_way(&sp, at, None);
        if mode == ActionMode::Ascend {
            assert_eq!(blind, Ok(()));
        } else {
            assert!(
                matches!(blind, Err(GateError::NoOccupancy { needed_m: 60.0, .. })),
                "{mode:?}: {blind:?}"
            );
        }
    }
    // the climb was raised to 18 m over the 15 m roof: a taller one under it blocks it
    let climb = g
        .admit(
            &decision(ActionMode::Ascend, [0.0, 0.0, 12.0], 12.0),
            roof,
            Some(&grid),
        )
        .unwrap();
    assert_eq!((climb.position[2], climb.clamped), (18.0, 1));
    set(&mut grid, -5.5, -5.5, 16);
    assert!(matches!(
        g.check_way(&climb, roof, Some(&grid)),
        Err(GateError::Blocked { top_m: 16.0, .. })
    ));
    // the clamped goto stops 3 m short of the wall; a second wall before that blocks it
    let sp = g
        .admit(
            &decision(ActionMode::Goto, [25.0, 0.0, 10.0], 10.0),
            v,
            Some(&grid),
        )
        .unwrap();
    assert_eq!(sp.clamped, 1);
    for e in -32..32 {
        set(&mut grid, 4.5, e as f32 + 0.5, 30);
    }
    assert!(matches!(
        g.check_way(&sp, v, Some(&grid)),
        Err(GateError::Blocked { top_m: 30.0, .. })
    ));
    // a landing whose touchdown cell is taken now
    let mut grid = free_grid();
    let land = g
        .admit(
            &decision(ActionMode::Land, [5.0, 5.0, 0.0], 10.0),
            v,
            Some(&grid),
        )
        .unwrap();
    set(&mut grid, 5.0, 5.0, 1);
    assert!(matches!(
        g.check_way(&land, v, Some(&grid)),
        Err(GateError::Blocked { .. })
    ));
}

#[test]
fn raises_in_place_climbs_over_an_obstacle() {
    let g = gate();
    let mut grid = free_grid();
    set(&mut grid, 0.5, 0.5, 15);
    let d = decision(ActionMode::Descend, [0.0, 0.0, 5.0], 5.0);
    let sp = g.admit(&d, [0.5, 0.5, 30.0], Some(&grid)).unwrap();
    assert_eq!((sp.position[2], sp.clamped), (18.0, 1));
    set(&mut grid, 0.5, 0.5, 59);
    assert!(matches!(
        g.admit(&d, [0.5, 0.5, 30.0], Some(&grid)),
        Err(GateError::NoAltitude { .. })
    ));
}

#[test]
fn land_goes_to_ground_but_not_onto_an_obstacle() {
    let g = gate();
    let mut grid = free_grid();
    let d = decision(ActionMode::Land, [5.0, 5.0, 0.0], 10.0);
    let sp = g.admit(&d, [0.0, 0.0, 10.0], Some(&grid)).unwrap();
    assert_eq!(sp.position, [5.0, 5.0, 0.0]);
    assert_eq!(sp.validate(&limits()), Ok(ActionMode::Land));
    set(&mut grid, 5.0, 5.0, 1);
    assert!(matches!(
        g.admit(&d, [0.0, 0.0, 10.0], Some(&grid)),
        Err(GateError::Blocked { .. })
    ));
}

#[test]
fn altitude_is_kept_inside_the_fence() {
    let mut l = limits();
    l.geofence_max[2] = 40.0;
    let g = DecisionGate::new(l).unwrap();
    let d = decision(ActionMode::Goto, [10.0, 0.0, 10.0], 55.0);
    let sp = g.admit(&d, [0.0; 3], None).unwrap();
    assert_eq!((sp.position[2], sp.clamped), (40.0, 1));
    l.geofence_max[2] = 1.0; // below h_min: no altitude
    let g = DecisionGate::new(l).unwrap();
    assert!(matches!(
        g.admit(
            &decision(ActionMode::Goto, [1.0, 0.0, 1.0], 10.0),
            [0.0; 3],
            None
        ),
        Err(GateError::Invalid(_)) | Err(GateError::NoAltitude { .. })
    ));
}

#[test]
fn a_vehicle_outside_the_fence_is_brought_back() {
    let g = gate();
    let d = decision(ActionMode::Takeoff, [0.0, 0.0, 10.0], 10.0);
    let sp = g.admit(&d, [150.0, -120.0, 0.0], None).unwrap();
    assert_eq!((sp.position, sp.clamped), ([100.0, -100.0, 10.0], 1));
    let h = g.hold(&d, [150.0, 0.0, 90.0]).unwrap();
    assert_eq!(h.position, [100.0, 0.0, 60.0]);
    assert_eq!(h.mode, ActionMode::Hover as u8);
}

#[test]
fn config_is_checked() {
    assert!(matches!(
        DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: f32::NAN,
            ..limits()
        }),
        Err(GateConfigError::BadClearance(_))
    ));
    assert!(matches!(
        DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: -1.0,
            ..limits()
        }),
        Err(GateConfigError::BadClearance(_))
    ));
    let mut l = limits();
    l.h_min = 70.0;
    assert_eq!(
        DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: 1.0,
            ..l
        }),
        Err(GateConfigError::IncoherentLimits)
    );
}

/// Absent (no grid, or its status absent or stale) is not "present and empty": without
/// occupancy a move flies at the conservative altitude (the band's top, 60 m), waits in
/// place while the vehicle is lower, and nothing in place descends below it; a present
/// grid with nothing observed (all unknown) or all free is gated as before.
#[test]
fn without_occupancy_moves_keep_to_the_conservative_altitude() {
    let g = gate();
    assert_eq!(g.limits().blind_altitude(), 60.0);
    let mut empty = free_grid();
    empty.cells.fill(OCCUPANCY_UNKNOWN);
    let mut stale = free_grid();
    stale.status = OccupancyStatus::Stale as u8;
    let mut absent = free_grid();
    absent.status = OccupancyStatus::Absent as u8;
    let low = [1.0, 2.0, 10.0];
    let high = [1.0, 2.0, 59.5];
    let t = [30.0, -10.0, 12.0];
    for grid in [None, Some(&absent), Some(&stale)] {
        let admit = |mode, at| g.feasible(&decision(mode, t, 12.0), mode, at, grid);
        // a move from low down: climb where the vehicle is first
        for mode in [ActionMode::Goto, ActionMode::Hover, ActionMode::Stop] {
            let f = admit(mode, low).unwrap();
            assert_eq!((f.position, f.mode), ([1.0, 2.0, 60.0], mode), "{grid:?}");
            assert_eq!((f.clamped, f.reasons), (true, clamp::NO_OCCUPANCY));
            // from up there: to the target, at that altitude
            let f = admit(mode, high).unwrap();
            assert_eq!(f.position, [30.0, -10.0, 60.0]);
            assert_eq!(f.reasons, clamp::NO_OCCUPANCY);
        }
        // a land far away from low down is refused; from up there it goes
        assert!(matches!(
            admit(ActionMode::Land, low),
            Err(GateError::NoOccupancy { needed_m: 60.0, .. })
        ));
        let f = admit(ActionMode::Land, high).unwrap();
        assert_eq!((f.position, f.clamped), ([30.0, -10.0, 0.0], false));
        // in place: a take-off from the ground climbs as asked, nothing descends
        let f = admit(ActionMode::Takeoff, [1.0, 2.0, 0.0]).unwrap();
        assert_eq!((f.position, f.clamped), ([1.0, 2.0, 12.0], false));
        let f = admit(ActionMode::Descend, [1.0, 2.0, 30.0]).unwrap();
        assert_eq!(
            (f.position, f.reasons),
            ([1.0, 2.0, 30.0], clamp::NO_OCCUPANCY)
        );
        let f = admit(ActionMode::Turn, high).unwrap();
        assert_eq!(f.position, [1.0, 2.0, 59.5]);
        // a hover where the vehicle is stays there, not lower
        let here = decision(ActionMode::Hover, [1.5, 2.0, 5.0], 5.0);
        let f = g.feasible(&here, ActionMode::Hover, low, grid).unwrap();
        assert_eq!(f.position, [1.5, 2.0, 10.0]);
        // what was admitted passes its way check
        let sp = g
            .admit(&decision(ActionMode::Goto, t, 12.0), low, grid)
            .unwrap();
        assert_eq!(g.check_way(&sp, low, grid), Ok(()));
    }
    // present: empty (nothing observed) and all free are flown as asked
    for grid in [&empty, &free_grid()] {
        for mode in [ActionMode::Goto, ActionMode::Land, ActionMode::Descend] {
            let f = g
                .feasible(&decision(mode, t, 12.0), mode, [1.0, 2.0, 30.0], Some(grid))
                .unwrap();
            assert!(!f.clamped, "{mode:?}: {f:?}");
            assert_eq!(f.reasons, 0);
        }
    }
    // a status byte that is none is a malformed grid
    let mut bad = free_grid();
    bad.status = 9;
    assert_eq!(
        g.admit(&decision(ActionMode::Goto, t, 12.0), low, Some(&bad)),
        Err(GateError::BadGrid)
    );
}
