//! Property tests of the decision gate: whatever comes in, what comes out is flyable.

use aeris_hub::{DecisionGate, GateError, OVER_MARGIN_M};
use aeris_schemas::{
    ActionMode, Decision, DecisionLimits, OCCUPANCY_CELLS, OCCUPANCY_SIDE, OCCUPANCY_UNKNOWN,
    OccupancyGrid,
};
use proptest::prelude::*;

/// Any f32 bit pattern (NaN, inf, subnormals, huge) or, often, a plausible value.
fn wild_f32(lo: f32, hi: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => lo..=hi,
        1 => any::<u32>().prop_map(f32::from_bits),
        1 => prop::sample::select(vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.0, f32::MAX]),
    ]
}

fn limits() -> impl Strategy<Value = DecisionLimits> {
    (
        0.5f32..20.0,
        0.0f32..20.0,
        0.0f32..100.0,
        0.0f32..20.0,
        (-300.0f32..0.0, -300.0f32..0.0, 0.0f32..5.0),
        (0.0f32..300.0, 0.0f32..300.0, 0.0f32..120.0),
        1u16..=16,
    )
        .prop_map(
            |(v_max, h_min, h_span, r_max, lo, span, subgoals)| DecisionLimits {
                v_max,
                h_min,
                h_max: h_min + h_span,
                r_max,
                geofence_min: [lo.0, lo.1, lo.2],
                geofence_max: [span.0, span.1, lo.2 + span.2],
                obstacle_clearance_m: 3.0,
                subgoals,
            },
        )
}

/// A field that is usually inside `[lo, hi]` and sometimes anything at all.
fn field(lo: f32, hi: f32) -> BoxedStrategy<f32> {
    prop_oneof![
        12 => lo..=hi,
        1 => wild_f32(lo - 10.0, hi + 10.0),
    ]
    .boxed()
}

/// A decision that is often valid for `l` and sometimes garbage in any field.
fn decision_for(l: DecisionLimits) -> impl Strategy<Value = Decision> {
    let pi = std::f32::consts::PI;
    (
        (
            field(l.geofence_min[0], l.geofence_max[0]),
            field(l.geofence_min[1], l.geofence_max[1]),
            field(l.geofence_min[2], l.geofence_max[2]),
        ),
        field(-pi, pi),
        field(0.0, l.v_max),
        field(l.h_min, l.h_max),
        field(0.0, l.r_max),
        field(0.0, 1.0),
        prop_oneof![12 => 1u16..=l.subgoals, 1 => any::<u16>()],
        prop_oneof![12 => 1u8..=8, 1 => any::<u8>()],
        any::<u64>(),
    )
        .prop_map(
            |(target, yaw, speed, altitude, acceptance_radius, confidence, step, action, seq)| {
                Decision {
                    seq,
                    target: [target.0, target.1, target.2],
                    yaw,
                    speed,
                    altitude,
                    acceptance_radius,
                    confidence,
                    step,
                    action,
                    ..Decision::default()
                }
            },
        )
}

/// Limits, a decision for them, the vehicle position and a grid around it.
fn case() -> impl Strategy<Value = (DecisionLimits, Decision, [f32; 3], Option<OccupancyGrid>)> {
    limits().prop_flat_map(|l| {
        (Just(l), decision_for(l), position())
            .prop_flat_map(|(l, d, p)| (Just(l), Just(d), Just(p), grid_near(p)))
    })
}

fn position() -> impl Strategy<Value = [f32; 3]> {
    prop_oneof![
        6 => (-350.0f32..350.0, -350.0f32..350.0, -2.0f32..130.0).prop_map(|(n, e, u)| [n, e, u]),
        1 => prop::array::uniform3(wild_f32(-1e6, 1e6)),
    ]
}

/// A sparse grid of obstacles around `p` (or none, or a malformed one).
fn grid_near(p: [f32; 3]) -> impl Strategy<Value = Option<OccupancyGrid>> {
    let centre = |v: f32| {
        if v.is_finite() {
            v.clamp(-1e4, 1e4)
        } else {
            0.0
        }
    };
    let (cn, ce) = (centre(p[0]), centre(p[1]));
    let sparse = (
        (cn - 30.0..cn + 30.0, ce - 30.0..ce + 30.0),
        0.2f32..6.0,
        prop::collection::vec((0..OCCUPANCY_CELLS, any::<u8>()), 0..300),
        prop::bool::ANY,
    )
        .prop_map(|(origin, resolution_m, cells, unknown)| {
            let fill = if unknown { OCCUPANCY_UNKNOWN } else { 0 };
            let mut g = OccupancyGrid {
                cells: [fill; OCCUPANCY_CELLS],
                ..OccupancyGrid::observed([origin.0, origin.1], resolution_m)
            };
            for (i, v) in cells {
                g.cells[i] = v;
            }
            Some(g)
        });
    let malformed = (wild_f32(-1e3, 1e3), wild_f32(-1.0, 200.0)).prop_map(|(o, r)| {
        Some(OccupancyGrid {
            cells: [7; OCCUPANCY_CELLS],
            ..OccupancyGrid::observed([o, 0.0], r)
        })
    });
    prop_oneof![1 => Just(None), 4 => sparse, 1 => malformed]
}

fn blocks(v: u8, threshold: f32) -> bool {
    v != OCCUPANCY_UNKNOWN && v > 0 && v as f32 >= threshold
}

/// `true` when `p` lies in a cell that `blocks`, at least `margin` inside its edges.
fn deep_in_blocking_cell(g: &OccupancyGrid, p: [f64; 2], threshold: f32, margin: f64) -> bool {
    let res = g.resolution_m as f64;
    let half = (OCCUPANCY_SIDE / 2) as f64;
    let x = (p[0] - g.origin[0] as f64) / res + half;
    let y = (p[1] - g.origin[1] as f64) / res + half;
    let (r, c) = (x.floor(), y.floor());
    if r < 0.0 || c < 0.0 || r >= OCCUPANCY_SIDE as f64 || c >= OCCUPANCY_SIDE as f64 {
        return false;
    }
    let m = margin / res;
    if x - r < m || r + 1.0 - x < m || y - c < m || c + 1.0 - y < m {
        return false;
    }
    blocks(g.cells[r as usize * OCCUPANCY_SIDE + c as usize], threshold)
}

fn is_finite_decision(d: &Decision) -> bool {
    [
        d.target[0],
        d.target[1],
        d.target[2],
        d.yaw,
        d.speed,
        d.altitude,
        d.acceptance_radius,
        d.confidence,
    ]
    .iter()
    .all(|v| v.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// Either rejected, or a setpoint that validates and lies in the fence and the band.
    #[test]
    fn admitted_setpoints_are_always_flyable(
        (limits, d, position, grid) in case(),
        clearance in 0.0f32..10.0,
    ) {
        let gate = DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: clearance,
            ..limits
        })
        .unwrap();
        let result = gate.admit(&d, position, grid.as_ref());
        if !is_finite_decision(&d) {
            prop_assert!(matches!(result, Err(GateError::Invalid(_))), "{result:?}");
        }
        if let Ok(sp) = result {
            let mode = sp.validate(&limits);
            prop_assert!(mode.is_ok(), "{sp:?} fails validation: {mode:?}");
            let mode = ActionMode::from_u8(d.action).unwrap();
            prop_assert_eq!(sp.mode, mode as u8);
            let [n, e, u] = sp.position;
            prop_assert!(n.is_finite() && e.is_finite() && u.is_finite());
            prop_assert!(n >= limits.geofence_min[0] && n <= limits.geofence_max[0], "{sp:?}");
            prop_assert!(e >= limits.geofence_min[1] && e <= limits.geofence_max[1], "{sp:?}");
            let (lo, hi) = gate.altitude_band();
            if mode == ActionMode::Land {
                prop_assert_eq!(u, 0.0);
            } else {
                prop_assert!(u >= lo && u <= hi, "U {} outside [{}, {}]", u, lo, hi);
                prop_assert!(u >= limits.h_min && u <= limits.h_max);
            }
            prop_assert!(sp.speed >= 0.0 && sp.speed <= limits.v_max);
            prop_assert!(d.validate(&limits).is_ok());
            prop_assert_eq!(sp.decision_seq, d.seq);
        }
    }

    /// The admitted straight path never runs through a cell that blocks at its altitude.
    #[test]
    fn admitted_paths_avoid_blocking_cells(
        (limits, d, position, grid) in case(),
        clearance in 0.5f32..6.0,
    ) {
        let gate = DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: clearance,
            ..limits
        })
        .unwrap();
        let Some(g) = grid.filter(|g| g.resolution_m.is_finite() && g.resolution_m > 0.0 && g.origin.iter().all(|v| v.is_finite())) else {
            return Ok(());
        };
        let Ok(sp) = gate.admit(&d, position, Some(&g)) else {
            return Ok(());
        };
        let mode = ActionMode::from_u8(sp.mode).unwrap();
        let threshold = match mode {
            ActionMode::Goto | ActionMode::Hover | ActionMode::Stop => sp.position[2] - clearance,
            ActionMode::Land => {
                let (lo, hi) = gate.altitude_band();
                d.altitude.clamp(lo, hi).min(position[2]) - clearance
            }
            _ => {
                // in place: the cell under the setpoint is cleared by `clearance`
                if let Some(top) = g.height_at([sp.position[0], sp.position[1]]).filter(|t| *t > 0.0) {
                    prop_assert!(sp.position[2] >= top + clearance - 1e-3, "{sp:?} over {top}");
                }
                return Ok(());
            }
        };
        let l = limits;
        let from = [
            position[0].clamp(l.geofence_min[0], l.geofence_max[0]) as f64,
            position[1].clamp(l.geofence_min[1], l.geofence_max[1]) as f64,
        ];
        let to = [sp.position[0] as f64, sp.position[1] as f64];
        for i in 0..=2000 {
            let k = i as f64 / 2000.0;
            let p = [from[0] + (to[0] - from[0]) * k, from[1] + (to[1] - from[1]) * k];
            prop_assert!(
                !deep_in_blocking_cell(&g, p, threshold, 1e-3),
                "path {from:?} -> {to:?} crosses a blocking cell at {p:?} ({sp:?})"
            );
        }
    }

    /// A waypoint behind a wall that is too tall is clamped before it (by the clearance),
    /// or, where the vehicle stands at the wall, climbed over where the vehicle is, or
    /// rejected when the wall is too tall for the band; never passed through.
    #[test]
    fn a_waypoint_behind_a_wall_is_clamped_or_rejected(
        resolution in 0.5f32..4.0,
        wall_row in 36usize..60,
        wall_top in 12u8..=255,
        start_row in 4usize..34,
        start_col in 4usize..60,
        beyond in 1.0f32..200.0,
        east in -150.0f32..150.0,
        clearance in 0.5f32..5.0,
        altitude in 2.0f32..12.0,
        unknown in prop::bool::ANY,
    ) {
        prop_assume!(wall_top != OCCUPANCY_UNKNOWN);
        let limits = DecisionLimits {
            v_max: 10.0,
            h_min: 0.0,
            h_max: 120.0,
            r_max: 10.0,
            geofence_min: [-1000.0, -1000.0, 0.0],
            geofence_max: [1000.0, 1000.0, 120.0],
            obstacle_clearance_m: clearance,
            subgoals: 2,
        };
        let gate = DecisionGate::new(limits).unwrap();
        let mut g = OccupancyGrid {
 cells: [if unknown { OCCUPANCY_UNKNOWN } else { 0 }; OCCUPANCY_CELLS],
 ..OccupancyGrid::observed([0.0, 0.0], resolution)
 };
        for c in 0..OCCUPANCY_SIDE {
            g.cells[wall_row * OCCUPANCY_SIDE + c] = wall_top;
        }
        let half = (OCCUPANCY_SIDE / 2) as f32;
        let cell_n = |row: usize| (row as f32 - half) * resolution;
        let vehicle = [cell_n(start_row) + 0.5 * resolution, cell_n(start_col) + 0.5 * resolution, altitude];
        let wall_n = cell_n(wall_row);
        let target = [wall_n + resolution + beyond, east, altitude];
        // the path must meet the wall inside the grid (outside it nothing is known)
        let e_cross = vehicle[1] + (wall_n - vehicle[0]) / (target[0] - vehicle[0]) * (east - vehicle[1]);
        prop_assume!(e_cross.abs() < (half - 1.0) * resolution);
        let d = Decision {
            seq: 1,
            target,
            yaw: 0.0,
            speed: 5.0,
            altitude,
            acceptance_radius: 1.0,
            confidence: 1.0,
            step: 1,
            action: ActionMode::Goto as u8,
            ..Decision::default()
        };
        let over = wall_top as f32 + clearance + OVER_MARGIN_M;
        match gate.admit(&d, vehicle, Some(&g)) {
            Err(GateError::Blocked { .. }) => prop_assert!(over > 120.0, "{over} fits the band"),
            Err(e) => prop_assert!(false, "unexpected rejection {e}"),
            Ok(sp) if sp.position[2] > altitude + 1e-3 => {
                // at the wall: it climbs where it is (far below the wall's top) to clear it
                prop_assert_eq!(sp.clamped, 1);
                prop_assert_eq!(sp.position, [vehicle[0], vehicle[1], over]);
            }
            Ok(sp) => {
                prop_assert_eq!(sp.clamped, 1);
                let (dn, de) = (target[0] - vehicle[0], target[1] - vehicle[1]);
                let cos = dn / dn.hypot(de);
                prop_assert!(
                    sp.position[0] <= wall_n - clearance * cos + 1e-3,
                    "{:?} is not {} m before the wall at N = {}", sp.position, clearance, wall_n
                );
                // and it is on the way: still north of (or level with) the vehicle
                prop_assert!(sp.position[0] >= vehicle[0] - 1e-3);
                prop_assert!(
                    (sp.position[0] - vehicle[0]).hypot(sp.position[1] - vehicle[1]) >= resolution - 1e-3,
                    "less than one cell of motion was admitted"
                );
            }
        }
        // flying high enough over the wall is never clamped
        if over <= 120.0 {
            let high = Decision { altitude: over, target: [target[0], target[1], over], ..d };
            let sp = gate.admit(&high, vehicle, Some(&g)).unwrap();
            prop_assert_eq!((sp.clamped, sp.position), (0, [target[0], target[1], over]));
        }
    }
}

/// The generators are not vacuous: they produce admitted, clamped and blocked decisions.
#[test]
fn generators_cover_admitted_clamped_and_blocked_cases() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let strategy = (case(), 0.5f32..6.0);
    let (mut ok, mut clamped, mut blocked, mut invalid) = (0, 0, 0, 0);
    let mut pulled_back = 0;
    let n = 4000;
    for _ in 0..n {
        let ((limits, d, position, grid), clearance) =
            strategy.new_tree(&mut runner).unwrap().current();
        let gate = DecisionGate::new(DecisionLimits {
            obstacle_clearance_m: clearance,
            ..limits
        })
        .unwrap();
        match gate.admit(&d, position, grid.as_ref()) {
            Ok(sp) => {
                ok += 1;
                clamped += usize::from(sp.clamped == 1);
                // admitted although the straight path to the waypoint crosses an obstacle
                let moving = matches!(
                    ActionMode::from_u8(sp.mode),
                    Some(ActionMode::Goto | ActionMode::Hover | ActionMode::Stop)
                );
                if let (true, Some(g)) = (moving, grid.as_ref()) {
                    let (from, to) = (position, d.target);
                    let crosses = (0..=500).any(|i| {
                        let k = i as f64 / 500.0;
                        let p = [
                            from[0] as f64 + (to[0] as f64 - from[0] as f64) * k,
                            from[1] as f64 + (to[1] as f64 - from[1] as f64) * k,
                        ];
                        deep_in_blocking_cell(g, p, sp.position[2] - clearance, 1e-3)
                    });
                    pulled_back += usize::from(crosses);
                }
            }
            Err(GateError::Blocked { .. }) => blocked += 1,
            Err(GateError::Invalid(_)) => invalid += 1,
            Err(_) => {}
        }
    }
    println!(
        "ok {ok} clamped {clamped} pulled back {pulled_back} blocked {blocked} invalid {invalid} of {n}"
    );
    assert!(ok > n / 20, "only {ok} of {n} admitted");
    assert!(clamped > 20 && pulled_back > 20 && blocked > 20 && invalid > n / 4);
}
