//! The planner's unit tests: waypoint missions, and grounded (VLN) steps on constructed S_t.

use super::geometry::{horizontal, short_of};
use super::*;
use aeris_runtime::spec::{LimitsSpec, SubgoalSpec};

fn mission() -> aeris_runtime::MissionSpec {
    aeris_runtime::MissionSpec {
        instruction: "take off, fly north, land".into(),
        subgoals: vec![
            SubgoalSpec {
                text: "take off".into(),
                action: "takeoff".into(),
                waypoint: Some([0.0, 0.0, 10.0]),
                reading: None,
            },
            SubgoalSpec {
                text: "fly north".into(),
                action: "goto".into(),
                waypoint: Some([30.0, 0.0, 10.0]),
                reading: None,
            },
            SubgoalSpec {
                text: "land".into(),
                action: "land".into(),
                waypoint: Some([30.0, 10.0, 0.0]),
                reading: None,
            },
        ],
        world: "village".into(),
        start: [0.0; 3],
        cruise_speed: 5.0,
        acceptance_radius_m: 2.0,
        max_duration_s: 60.0,
        limits: LimitsSpec::default(),
    }
}

/// A planner that has seen present occupancy with nothing in the way (the waypoint tests
/// decide on telemetry alone after that; before any S_t a planner is blind).
fn seeing(mut p: Planner) -> Planner {
    p.occupancy = Some(OccupancyStatus::Present);
    p
}

#[test]
fn advances_through_subgoals_and_every_decision_is_valid() {
    let m = mission();
    let limits = m.decision_limits();
    let mut p = seeing(Planner::new(&m, &CameraSpec::default()).unwrap());
    let d = p.decide([0.0, 0.0, 0.0], 0.0, true, None);
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (1, Some(ActionMode::Takeoff))
    );
    assert!(d.validate(&limits).is_ok());
    let d = p.decide([0.0, 0.0, 9.5], 0.0, false, None);
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (2, Some(ActionMode::Goto))
    );
    assert_eq!(d.target, [30.0, 0.0, 10.0]);
    assert!(d.validate(&limits).is_ok());
    // not there yet: memory holds
    let d = p.decide([15.0, 0.0, 10.0], 0.0, false, None);
    assert_eq!(d.step, 2);
    let d = p.decide([29.0, 0.5, 10.0], 0.0, false, None);
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (3, Some(ActionMode::Land))
    );
    assert!(d.validate(&limits).is_ok());
    // the last step stays active
    let d = p.decide([30.0, 10.0, 0.0], 0.0, true, None);
    assert_eq!(d.step, 3);
}

/// A language model that takes off to 11 m for a 12 m step: the vehicle settles a hair
/// under 11 m, one metre and a few hundredths of a millimetre short; the step is done.
#[test]
fn a_take_off_settled_just_inside_a_metre_of_its_target_is_done() {
    let m = mission();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    assert_eq!(p.decide([0.0, 0.0, 0.0], 0.0, true, None).step, 1);
    // the target is 10 m: the tracker stopped 1.00005 m short of it
    assert_eq!(p.decide([0.0, 0.0, 8.99995], 0.0, false, None).step, 2);
    // well short is not done
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    p.decide([0.0, 0.0, 0.0], 0.0, true, None);
    assert_eq!(p.decide([0.0, 0.0, 8.9], 0.0, false, None).step, 1);
}

#[test]
fn a_huge_or_odd_yaw_never_hangs_and_stays_in_range() {
    let mut p = Planner::new(&mission(), &CameraSpec::default()).unwrap();
    for yaw in [1.0e9, -3.0e38, f32::MAX, 7.0] {
        let d = p.decide([0.0, 0.0, 0.0], yaw, true, None);
        assert!(d.yaw.abs() <= core::f32::consts::PI, "{yaw} -> {}", d.yaw);
    }
}

#[test]
fn hover_holds_one_heartbeat_and_turn_waits_for_the_heading() {
    let mut m = mission();
    m.subgoals.insert(
        1,
        SubgoalSpec {
            text: "hover".into(),
            action: "hover".into(),
            waypoint: Some([0.0, 0.0, 10.0]),
            reading: None,
        },
    );
    m.subgoals.insert(
        2,
        SubgoalSpec {
            text: "face east".into(),
            action: "turn".into(),
            waypoint: Some([0.0, 30.0, 10.0]),
            reading: None,
        },
    );
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    assert_eq!(
        p.decide([0.0, 0.0, 10.0], 0.0, false, None).step,
        2,
        "takeoff done -> hover"
    );
    assert_eq!(
        p.decide([0.0, 0.0, 10.0], 0.0, false, None).step,
        3,
        "hovered one heartbeat -> turn"
    );
    let d = p.decide([0.0, 0.0, 10.0], 0.0, false, None);
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (3, Some(ActionMode::Turn)),
        "still facing north"
    );
    assert!((d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3);
    assert_eq!(
        p.decide([0.0, 0.0, 10.0], 1.55, false, None).step,
        4,
        "facing east -> next"
    );
}

#[test]
fn yaw_points_at_the_target() {
    let mut p = seeing(Planner::new(&mission(), &CameraSpec::default()).unwrap());
    let _ = p.decide([0.0, 0.0, 10.0], 0.0, false, None);
    let d = p.decide([30.0, -20.0, 10.0], 0.0, false, None);
    assert!(
        (d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
        "{}",
        d.yaw
    );
}

/// The VLN setting: steps name landmarks, no waypoints.
pub(super) fn vln_mission() -> aeris_runtime::MissionSpec {
    let step = |text: &str, action: &str| SubgoalSpec {
        text: text.into(),
        action: action.into(),
        waypoint: None,
        reading: None,
    };
    aeris_runtime::MissionSpec {
        instruction: "take off, fly to the red-roofed building, land by the sign".into(),
        subgoals: vec![
            step("take off from the helipad to 15 metres", "takeoff"),
            step("turn right and fly to the red-roofed building", "goto"),
            step("land next to the yellow sign that says HOTEL", "land"),
        ],
        world: "village".into(),
        start: [0.0; 3],
        cruise_speed: 5.0,
        acceptance_radius_m: 3.0,
        max_duration_s: 300.0,
        limits: LimitsSpec {
            h_max: 80.0,
            geofence_min: [-300.0, -300.0, 0.0],
            geofence_max: [300.0, 300.0, 80.0],
            ..LimitsSpec::default()
        },
    }
}

pub(super) fn seen(
    label: &str,
    bbox: [f32; 4],
    range_m: f32,
    position: [f32; 3],
    yaw: f32,
) -> PerceptionState {
    let mut s = PerceptionState {
        position,
        yaw,
        detection_count: 1,
        ..PerceptionState::default()
    };
    // a depth source, which saw nothing near (present, every cell unknown)
    s.occupancy = aeris_schemas::OccupancyGrid::observed([position[0], position[1]], 2.0);
    s.detections[0].label.set(label);
    s.detections[0].score = 0.8;
    s.detections[0].bbox = bbox;
    s.detections[0].range_m = range_m;
    s
}

#[test]
fn a_grounded_step_turns_as_told_scans_and_flies_to_what_it_sees() {
    let m = vln_mission();
    let limits = m.decision_limits();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    // the take-off height comes from the text
    let d = p.decide([0.0; 3], 0.0, true, None);
    assert_eq!((d.step, d.target[2]), (1, 15.0));
    // up: "turn right" -> face east first, holding position
    let empty = PerceptionState::default();
    let d = p.decide([0.0, 0.0, 15.0], 0.0, false, Some(&empty));
    assert_eq!(d.step, 2);
    assert!(
        (d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-3,
        "{}",
        d.yaw
    );
    assert!(horizontal(d.target, [0.0, 0.0, 15.0]) < 1e-3);
    // nothing seen: the scan turns left of the search heading next
    let d = p.decide([0.0, 0.0, 15.0], d.yaw, false, Some(&empty));
    assert!(d.yaw < core::f32::consts::FRAC_PI_2 - 0.5, "{}", d.yaw);
    // the red roof straight ahead (east) at 40 m: fly to 12 m short of it
    let at = [0.0, 0.0, 15.0];
    let east = core::f32::consts::FRAC_PI_2;
    let s = seen("red roof", [0.45, 0.0, 0.1, 0.1], 40.0, at, east);
    let d = p.decide(at, east, false, Some(&s));
    assert!(d.validate(&limits).is_ok());
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (2, Some(ActionMode::Goto))
    );
    assert!(
        d.target[1] > 10.0 && d.target[0].abs() < 5.0,
        "{:?}",
        d.target
    );
    let seen_at = p.search.found.unwrap();
    let gap = (d.target[0] - seen_at[0]).hypot(d.target[1] - seen_at[1]);
    assert!((gap - STANDOFF_M).abs() < 0.1, "{gap}");
    // a decision on telemetry alone keeps the memory
    let d2 = p.decide([0.0, 5.0, 15.0], east, false, None);
    assert_eq!(d2.step, 2);
    // arrived at the stand-off point: the landing step searches for the sign
    let d = p.decide(d.target, east, false, Some(&empty));
    assert_eq!(d.step, 3);
    let here = d.target;
    let s = seen("yellow sign", [0.3, 0.3, 0.1, 0.1], 25.0, here, east);
    let d = p.decide(here, east, false, Some(&s));
    // the sign is HOTEL's only if it reads so: the landing waits by it for a reading,
    // and comes down unread after READ_WAIT heartbeats there
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (3, Some(ActionMode::Goto))
    );
    let there = [d.target[0], d.target[1], 15.0];
    let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, there, east);
    let mut d = d;
    for _ in 0..READ_WAIT {
        d = p.decide(there, east, false, Some(&s));
    }
    // with a depth source it also waited there for clear ground to show, as long
    // with a depth source, the landing also waits there for clear ground to show
    for _ in READ_WAIT..TOUCHDOWN_WAIT + 1 {
        d = p.decide(there, east, false, Some(&s));
    }
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (3, Some(ActionMode::Land))
    );
    assert_eq!(d.target[2], 0.0);
    assert!(d.validate(&limits).is_ok());
}

/// `s` with the reader's text `read` in its summary.
/// Decide on `s` at `at` until the planner lands, for at most the heartbeats a landing
/// waits for clear ground to show (a depth source saw no touchdown): the last decision.
fn landing(p: &mut Planner, at: [f32; 3], yaw: f32, s: &PerceptionState) -> Decision {
    let mut d = p.decide(at, yaw, false, Some(s));
    for _ in 0..TOUCHDOWN_WAIT {
        if ActionMode::from_u8(d.action) == Some(ActionMode::Land) {
            break;
        }
        d = p.decide(at, yaw, false, Some(s));
    }
    d
}

fn reading(mut s: PerceptionState, read: &str) -> PerceptionState {
    s.blocks |= aeris_schemas::block::TEXT;
    s.summary = aeris_schemas::FixedText::from_str_truncated(&format!("reads \"{read}\""));
    s
}

#[test]
fn a_quoted_sign_is_taken_once_read_there_and_a_sign_found_again_is_read_first() {
    let mut m = vln_mission();
    m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let at = [0.0, 0.0, 15.0];
    // a yellow sign 20 m north, seen without a reading: found, not yet taken
    let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 20.0, at, 0.0);
    let d = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(d.step, 2);
    assert!(p.search.found.is_some());
    // there, it reads CAFE twice: not STADIUM's, the search goes on
    let cafe = reading(s, "CAFE");
    let _ = p.decide(at, 0.0, false, Some(&cafe));
    let d = p.decide(at, 0.0, false, Some(&cafe));
    assert_eq!((d.step, p.search.found), (2, None), "{d:?}");
    // the same sign seen from 20 m further east puts its estimate 18 m away from the
    // rejected one (the open episode's miss): found again, but not taken unread
    let east = [0.0, 20.0, 15.0];
    let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 38.0, east, 0.0);
    let d = p.decide(east, 0.0, false, Some(&s));
    assert!(p.search.found.is_some(), "{d:?}");
    let near = short_of([east[0], east[1]], p.search.found.unwrap(), STANDOFF_M);
    let there = [near[0], near[1], 15.0];
    let cafe = reading(
        seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, there, 0.0),
        "CAFE",
    );
    let _ = p.decide(there, 0.0, false, Some(&cafe));
    let d = p.decide(there, 0.0, false, Some(&cafe));
    assert_eq!(
        (d.step, p.search.found),
        (2, None),
        "read again, rejected again"
    );
    // the right sign reads STADIUM at once: taken without waiting
    let s = reading(
        seen(
            "yellow sign",
            [0.45, 0.3, 0.1, 0.1],
            20.0,
            [-60.0, 0.0, 15.0],
            0.0,
        ),
        "STADIUM",
    );
    let d = p.decide([-60.0, 0.0, 15.0], 0.0, false, Some(&s));
    assert_eq!(d.step, 3, "{d:?}");
}

#[test]
fn a_landmark_never_seen_ends_in_a_landing_after_the_search_legs() {
    let m = vln_mission();
    let limits = m.decision_limits();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let empty = PerceptionState::default();
    let mut at = [0.0, 0.0, 15.0];
    let mut yaw = 0.0;
    let mut last = None;
    for _ in 0..200 {
        let d = p.decide(at, yaw, false, Some(&empty));
        assert!(d.validate(&limits).is_ok(), "{d:?}");
        // the vehicle goes where it is told at once
        at = d.target;
        yaw = d.yaw;
        last = Some(d);
        if ActionMode::from_u8(d.action) == Some(ActionMode::Land) {
            break;
        }
    }
    let d = last.unwrap();
    assert_eq!(
        (d.step, ActionMode::from_u8(d.action)),
        (2, Some(ActionMode::Land))
    );
    // it searched along east (turn right) for the legs' length
    assert!(
        (d.target[1] - MAX_SEARCH_LEGS as f32 * SEARCH_LEG_M).abs() < 1.0,
        "{:?}",
        d.target
    );
}

#[test]
fn the_transit_height_clears_obstacles_seen_ahead_and_never_drops() {
    let m = vln_mission();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let at = [0.0, 0.0, 15.0];
    // the red roof 60 m north, a 30 m wall 20 m ahead on the way
    let mut s = seen("red roof", [0.45, 0.3, 0.1, 0.1], 60.0, at, 0.0);
    s.occupancy = aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0);
    s.occupancy.cells = [0; aeris_schemas::OCCUPANCY_CELLS];
    let wall = s.occupancy.cell_of([20.0, 0.0]).unwrap();
    s.occupancy.cells[wall] = 30;
    let d = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(d.step, 2);
    assert!(d.altitude >= 36.0 && d.target[2] >= 36.0, "{d:?}");
    // the wall no longer in the grid: the height stays
    s.occupancy.cells[wall] = 0;
    let d = p.decide([10.0, 0.0, 36.0], 0.0, false, Some(&s));
    assert!(d.altitude >= 36.0, "{}", d.altitude);
}

#[test]
fn a_sign_with_another_text_is_not_taken_for_the_next_one() {
    let mut m = vln_mission();
    m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let at = [0.0, 0.0, 15.0];
    // STADIUM's sign ahead (north), found and reached
    let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 30.0, at, 0.0);
    let d = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(d.step, 2);
    let stadium = p.search.found.unwrap();
    // at the stand-off point, the sign reads STADIUM: taken
    let d = p.decide(d.target, 0.0, false, Some(&reading(s, "STADIUM")));
    assert_eq!(d.step, 3, "reached the stand-off point");
    // the same sign seen again: not HOTEL's, the search goes on
    let here = d.target;
    let dn = stadium[0] - here[0];
    let s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], dn, here, 0.0);
    let d = p.decide(here, 0.0, false, Some(&s));
    assert_eq!(p.search.found, None, "{d:?}");
    // a yellow sign elsewhere (behind, 40 m south) is taken
    let s = seen(
        "yellow sign",
        [0.45, 0.3, 0.1, 0.1],
        40.0,
        here,
        core::f32::consts::PI,
    );
    let d = p.decide(here, core::f32::consts::PI, false, Some(&s));
    let found = p.search.found.expect("the other sign");
    assert!(found[0] < here[0] - 30.0, "{found:?}");
    // approached, to be read before the landing
    assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Goto));
    let there = [d.target[0], d.target[1], 15.0];
    let hotel = reading(
        seen(
            "yellow sign",
            [0.45, 0.3, 0.1, 0.1],
            12.0,
            there,
            core::f32::consts::PI,
        ),
        "HOTEL",
    );
    let d = landing(&mut p, there, core::f32::consts::PI, &hotel);
    assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
}

#[test]
fn a_sign_read_close_up_with_another_text_is_rejected() {
    let mut m = vln_mission();
    m.subgoals.remove(1);
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let at = [0.0, 0.0, 15.0];
    // a yellow sign 20 m ahead that the reader reads as MUSEUM: once may be a
    // misreading, twice it is not HOTEL's
    let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 20.0, at, 0.0);
    s.blocks |= aeris_schemas::block::TEXT;
    s.summary =
        aeris_schemas::FixedText::from_str_truncated("reads \"MUSEUM\"; yellow sign ahead 20 m");
    let d = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(d.step, 2);
    assert!(p.search.found.is_some(), "one misreading rejects nothing");
    let _ = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(p.search.found, None);
    assert_eq!(p.rejections().0, 1);
    assert_eq!(p.rejections().1.unwrap().1, "MUSEUM");
    // seen again from afar without a reading: still not taken
    let s = seen(
        "yellow sign",
        [0.45, 0.3, 0.1, 0.1],
        45.0,
        [-25.0, 0.0, 15.0],
        0.0,
    );
    let _ = p.decide([-25.0, 0.0, 15.0], 0.0, false, Some(&s));
    assert_eq!(p.search.found, None);
    // the one that reads HOTEL is
    let mut s = seen(
        "yellow sign",
        [0.45, 0.3, 0.1, 0.1],
        20.0,
        at,
        core::f32::consts::PI,
    );
    s.blocks |= aeris_schemas::block::TEXT;
    s.summary = aeris_schemas::FixedText::from_str_truncated("reads \"H0TEL\"");
    let d = landing(&mut p, at, core::f32::consts::PI, &s);
    assert!(p.search.found.is_some());
    assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
}

/// An occupancy grid around N, E = 0 showing free ground but for a board 8 m high and
/// 12 m long north-south (facing east and west) at N 40..52, E 0.
fn north_south_board() -> aeris_schemas::OccupancyGrid {
    let mut board = aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0);
    let half = (aeris_schemas::OCCUPANCY_SIDE / 2) as f32;
    for (i, cell) in board.cells.iter_mut().enumerate() {
        let n = ((i / aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        let e = ((i % aeris_schemas::OCCUPANCY_SIDE) as f32 - half + 0.5) * 2.0;
        *cell = u8::from((40.0..52.0).contains(&n) && (-1.0..1.0).contains(&e)) * 8;
    }
    board
}

#[test]
fn a_quoted_sign_is_approached_in_front_of_a_face_not_edge_on() {
    let mut m = vln_mission();
    m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    // the vehicle comes from the south, so it sees the board edge-on
    let board = north_south_board();
    let at = [0.0, 0.0, 15.0];
    let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 40.0, at, 0.0);
    s.occupancy = board;
    let d = p.decide(at, 0.0, false, Some(&s));
    assert_eq!(d.step, 2);
    // to a face: 12 m east or west of the board's middle, not short of it on the way
    assert!(
        (d.target[0] - 46.0).abs() <= 2.0 && (d.target[1].abs() - STANDOFF_M).abs() <= 2.0,
        "{:?}",
        d.target
    );
    // 12 m short of the board's end, edge-on, the step is not done (the old rule took it)
    let edge = [28.0, 0.0, 15.0];
    let mut s = seen("yellow sign", [0.45, 0.3, 0.1, 0.1], 12.0, edge, 0.0);
    s.occupancy = board;
    for _ in 0..READ_WAIT + 1 {
        let d = p.decide(edge, 0.0, false, Some(&s));
        assert_eq!(d.step, 2, "{d:?}");
    }
}

#[test]
fn a_board_below_the_frame_is_read_from_low_down_and_the_next_leg_climbs_first() {
    let mut m = vln_mission();
    m.subgoals[0].text = "take off from the helipad to 28 metres".into();
    m.subgoals[1].text = "fly to the yellow sign that says STADIUM".into();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let board = north_south_board();
    let sign = |at: [f32; 3], range_m: f32, yaw: f32| {
        let mut s = seen("yellow sign", [0.45, 0.45, 0.1, 0.1], range_m, at, yaw);
        s.occupancy = board;
        s
    };
    let d = p.decide(
        [0.0, 0.0, 28.0],
        0.0,
        false,
        Some(&sign([0.0, 0.0, 28.0], 40.0, 0.0)),
    );
    assert_eq!((d.step, d.altitude), (2, 28.0), "{d:?}");
    let face = [d.target[0], d.target[1]];
    // at the reading point at 28 m the board is below the frame: come down to the
    // board's top + the margin, and the heartbeats up there do not count as unread
    let toward_board = if face[1] > 0.0 {
        -core::f32::consts::FRAC_PI_2
    } else {
        core::f32::consts::FRAC_PI_2
    };
    let high = [face[0], face[1], 28.0];
    for _ in 0..READ_WAIT + 2 {
        let d = p.decide(
            high,
            toward_board,
            false,
            Some(&sign(high, 12.0, toward_board)),
        );
        assert_eq!(d.step, 2, "{d:?}");
        assert_eq!(
            (d.altitude, d.target[2]),
            (8.0 + OBSTACLE_MARGIN_M, 8.0 + OBSTACLE_MARGIN_M)
        );
        assert!(horizontal(d.target, high) <= 1.0, "{d:?}");
    }
    // down there, unread for READ_WAIT heartbeats: taken unread, as before
    let low = [face[0], face[1], 8.0 + OBSTACLE_MARGIN_M];
    let mut step = 2;
    for _ in 0..READ_WAIT + 1 {
        step = p
            .decide(
                low,
                toward_board,
                false,
                Some(&sign(low, 12.0, toward_board)),
            )
            .step;
    }
    assert_eq!(step, 3);
    // the next step, still low, climbs in place (scanning) and flies no search leg
    // before it is up at the transit height
    let empty = PerceptionState::default();
    let mut yaw = toward_board;
    for k in 0..SCAN_OFFSETS.len() + 2 {
        let d = p.decide(low, yaw, false, Some(&empty));
        yaw = d.yaw;
        assert_eq!(d.step, 3);
        assert!(
            horizontal(d.target, low) <= 1e-3 && d.target[2] == 28.0,
            "decision {k} of the next step, from low down: {d:?}"
        );
    }
}

/// A waypoint mission decided on S_t without occupancy (absent or stale) keeps to the
/// conservative altitude (the band's top, 60 m here): it climbs where it is before a
/// move, flies the move up there, counts the step done over its waypoint, and lands from
/// there; on a present grid with nothing observed it flies as it always did.
#[test]
fn without_occupancy_moves_keep_to_the_conservative_altitude() {
    let m = mission();
    let limits = m.decision_limits();
    assert_eq!(limits.blind_altitude(), 60.0);
    let state = |status: OccupancyStatus| {
        let mut s = PerceptionState {
            occupancy: aeris_schemas::OccupancyGrid::observed([0.0, 0.0], 2.0),
            ..PerceptionState::default()
        };
        s.occupancy.status = status as u8;
        s
    };
    for status in [OccupancyStatus::Absent, OccupancyStatus::Stale] {
        let s = state(status);
        let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
        assert!(
            p.blind(),
            "before the first S_t there is no occupancy either: blind, as the hub's gate"
        );
        // the take-off from the ground climbs as asked
        let d = p.decide([0.0; 3], 0.0, true, Some(&s));
        assert!(p.blind());
        assert_eq!(p.occupancy(), Some(status));
        assert_eq!((d.step, d.altitude), (1, 10.0));
        // at 10 m the step is done; the way north is climbed to first, in place
        let d = p.decide([0.0, 0.0, 10.0], 0.0, false, Some(&s));
        assert_eq!(d.step, 2);
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Goto));
        assert_eq!((d.target[0], d.target[1], d.altitude), (0.0, 0.0, 60.0));
        // a decision on telemetry alone stays blind
        let d = p.decide([0.0, 0.0, 30.0], 0.0, false, None);
        assert_eq!((d.target[0], d.target[1], d.altitude), (0.0, 0.0, 60.0));
        // up there: to the waypoint at that altitude
        let d = p.decide([0.0, 0.0, 59.5], 0.0, false, Some(&s));
        assert_eq!((d.target[0], d.target[1], d.altitude), (30.0, 0.0, 60.0));
        assert_eq!(d.validate(&limits), Ok(ActionMode::Goto));
        // over the waypoint, 50 m above it: done; the landing 10 m east goes from there
        let d = p.decide([30.0, 0.0, 59.8], 0.0, false, Some(&s));
        assert_eq!(d.step, 3);
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Land));
        assert_eq!((d.target[0], d.target[1]), (30.0, 10.0));
        // the same landing asked from low down climbs first
        let d = p.decide([30.0, 0.0, 20.0], 0.0, false, Some(&s));
        assert_eq!(ActionMode::from_u8(d.action), Some(ActionMode::Goto));
        assert_eq!((d.target[0], d.target[1], d.altitude), (30.0, 0.0, 60.0));
        assert_eq!(p.blind_decisions(), 6);
    }
    // present and empty (nothing observed): the waypoints as given
    let s = state(OccupancyStatus::Present);
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let _ = p.decide([0.0; 3], 0.0, true, Some(&s));
    let d = p.decide([0.0, 0.0, 10.0], 0.0, false, Some(&s));
    assert!(!p.blind());
    assert_eq!((d.step, d.target, d.altitude), (2, [30.0, 0.0, 10.0], 10.0));
    assert_eq!(p.blind_decisions(), 0);
}
