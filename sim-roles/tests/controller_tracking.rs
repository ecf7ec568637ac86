//! The controller's setpoint gate and tracking reference, alone and in closed loop with the
//! simulated multirotor (no processes, simulated time).

use aeris_mavlink::dialect::{MavFrame, MavMessage};
use aeris_mavlink::neu_to_ned;
use aeris_roles::controller::{
    Target, TrackCommand, Tracker, TrackerConfig, VehicleView, position_target_message,
    position_velocity_yaw_mask,
};
use aeris_schemas::{ActionMode, BoundSetpoint, DecisionLimits, SetpointError};
use aeris_sim::multirotor::{Command, MultirotorModel, MultirotorParams};

const TICK_NS: u64 = 20_000_000;
const T0: u64 = 1_000_000_000_000;

fn limits() -> DecisionLimits {
    DecisionLimits {
        v_max: 6.0,
        h_min: 2.0,
        h_max: 30.0,
        r_max: 10.0,
        geofence_min: [-100.0, -100.0, 0.0],
        geofence_max: [100.0, 100.0, 30.0],
        obstacle_clearance_m: 3.0,
        subgoals: 3,
    }
}

fn config() -> TrackerConfig {
    TrackerConfig {
        limits: limits(),
        start: [0.0; 3],
        period_s: 0.02,
        setpoint_timeout_ns: 500_000_000,
        hold_speed: 3.0,
        land_speed: 1.0,
        brake_accel: 2.0,
        leash_s: 1.0,
        leash_min_m: 2.0,
    }
}

fn sp(mode: ActionMode, position: [f32; 3], speed: f32, now: u64) -> BoundSetpoint {
    BoundSetpoint {
        seq: 1,
        decision_seq: 1,
        publish_ns: now,
        position,
        yaw: 0.0,
        speed,
        acceptance_radius: 1.0,
        active_step: 1,
        mode: mode as u8,
        ..BoundSetpoint::default()
    }
}

fn inside(l: &DecisionLimits, p: [f32; 3]) -> bool {
    (0..3).all(|i| p[i] >= l.geofence_min[i] && p[i] <= l.geofence_max[i]) && p[2] <= l.h_max
}

fn norm(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

#[test]
fn hostile_setpoints_are_refused_and_the_last_valid_one_stays() {
    let mut t = Tracker::new(config());
    let good = sp(ActionMode::Goto, [10.0, 5.0, 10.0], 4.0, T0);
    assert_eq!(t.offer(&good, T0), Ok(ActionMode::Goto));
    let mut hostile = Vec::new();
    let mut b = good;
    b.position[0] = f32::NAN;
    hostile.push(b);
    b = good;
    b.position = [500.0, 0.0, 10.0];
    hostile.push(b);
    b = good;
    b.speed = 50.0;
    hostile.push(b);
    b = good;
    b.position[2] = 45.0;
    hostile.push(b);
    b = good;
    b.yaw = f32::INFINITY;
    hostile.push(b);
    b = good;
    b.mode = 99;
    hostile.push(b);
    for h in &hostile {
        assert!(t.offer(h, T0 + 1).is_err(), "{h:?} accepted");
    }
    assert_eq!(t.refused(), hostile.len() as u64);
    assert_eq!(t.accepted(), 1);
    let (active, mode) = t.active(T0 + 2).unwrap();
    assert_eq!((active.position, mode), (good.position, ActionMode::Goto));
    assert!(matches!(
        t.offer(&hostile[0], T0),
        Err(SetpointError::NonFinite(_))
    ));
}

#[test]
fn without_setpoints_it_holds_the_position_latched_when_the_hold_began() {
    let mut t = Tracker::new(config());
    let p1 = [5.0, -3.0, 12.0];
    let v1 = VehicleView {
        position: Some(p1),
        yaw: Some(0.7),
        landed: false,
    };
    let c = t.tick(T0, &v1);
    assert_eq!(c.mode, None);
    assert_eq!(c.position, p1);
    assert_eq!(c.velocity, [0.0; 3]);
    assert!((c.yaw - 0.7).abs() < 1e-6);
    // The vehicle drifts: the hold target does not follow it.
    let v2 = VehicleView {
        position: Some([6.0, -3.0, 12.5]),
        yaw: Some(0.0),
        landed: false,
    };
    for i in 1..10 {
        let c = t.tick(T0 + i * TICK_NS, &v2);
        assert_eq!(c.position, p1);
        assert!((c.yaw - 0.7).abs() < 1e-6);
    }
    assert_eq!(t.hold_ticks(), 10);
}

#[test]
fn a_stale_or_future_stamped_setpoint_falls_back_to_hold() {
    let cfg = config();
    let view = VehicleView {
        position: Some([0.0, 0.0, 10.0]),
        yaw: Some(0.0),
        landed: false,
    };
    let mut t = Tracker::new(cfg);
    t.offer(&sp(ActionMode::Goto, [20.0, 0.0, 10.0], 3.0, T0), T0)
        .unwrap();
    assert_eq!(t.tick(T0 + TICK_NS, &view).mode, Some(ActionMode::Goto));
    let late = T0 + cfg.setpoint_timeout_ns + 1;
    let c = t.tick(late, &view);
    assert_eq!(c.mode, None);
    assert_eq!(t.hold_ticks(), 1);

    // A publish stamp in the future does not keep a setpoint fresh.
    let mut t = Tracker::new(cfg);
    t.offer(
        &sp(
            ActionMode::Goto,
            [20.0, 0.0, 10.0],
            3.0,
            T0 + 3_600_000_000_000,
        ),
        T0,
    )
    .unwrap();
    assert!(t.active(T0 + cfg.setpoint_timeout_ns).is_some());
    assert!(t.active(late).is_none());
}

#[test]
fn on_the_ground_before_takeoff_the_target_stays_on_the_ground() {
    let mut t = Tracker::new(config());
    let ground = VehicleView {
        position: Some([1.0, 1.0, 0.0]),
        yaw: Some(0.0),
        landed: true,
    };
    // No setpoint: hold on the ground, not at h_min.
    assert_eq!(t.tick(T0, &ground).position, [1.0, 1.0, 0.0]);
    // Hover on the ground: same.
    t.offer(&sp(ActionMode::Hover, [1.0, 1.0, 0.0], 2.0, T0), T0)
        .unwrap();
    let c = t.tick(T0 + TICK_NS, &ground);
    assert_eq!(c.mode, Some(ActionMode::Hover));
    assert_eq!(c.position, [1.0, 1.0, 0.0]);
    assert!(!t.wants_flight(T0 + TICK_NS, true));
    // In the air below h_min, a hold is clamped into the altitude band.
    let mut t = Tracker::new(config());
    let low = VehicleView {
        position: Some([1.0, 1.0, 1.0]),
        yaw: Some(0.0),
        landed: false,
    };
    let mut last = t.tick(T0, &low);
    for i in 1..200 {
        last = t.tick(T0 + i * TICK_NS, &low);
    }
    assert!((last.position[2] - limits().h_min).abs() < 1e-4, "{last:?}");
}

#[test]
fn takeoff_below_h_min_is_clamped_and_wants_flight() {
    let mut t = Tracker::new(config());
    let ground = VehicleView {
        position: Some([0.0, 0.0, 0.0]),
        yaw: None,
        landed: true,
    };
    // Validation lets a takeoff target sit below h_min; the tracker still climbs to h_min.
    t.offer(&sp(ActionMode::Takeoff, [0.0, 0.0, 0.5], 2.0, T0), T0)
        .unwrap();
    assert!(t.wants_flight(T0, true));
    let mut c = t.tick(T0, &ground);
    for i in 1..400 {
        let now = T0 + i * TICK_NS;
        t.offer(&sp(ActionMode::Takeoff, [0.0, 0.0, 0.5], 2.0, now), now)
            .unwrap();
        // The vehicle keeps up with the reference.
        let v = VehicleView {
            position: Some(c.position),
            yaw: None,
            landed: false,
        };
        c = t.tick(now, &v);
    }
    assert!((c.position[2] - limits().h_min).abs() < 1e-4, "{c:?}");
}

/// Fly `plan` (mode, position, speed, ticks) in closed loop with the multirotor model;
/// returns the model and checks every command on the way with `check`.
fn fly(
    start: [f32; 3],
    armed: bool,
    plan: &[(ActionMode, [f32; 3], f32, u64)],
    mut check: impl FnMut(ActionMode, &TrackCommand, &MultirotorModel),
) -> MultirotorModel {
    let mut t = Tracker::new(TrackerConfig { start, ..config() });
    let mut m = MultirotorModel::new(MultirotorParams::default(), start, 0.0);
    m.set_armed(armed);
    let mut now = T0;
    for &(mode, position, speed, ticks) in plan {
        for _ in 0..ticks {
            now += TICK_NS;
            t.offer(&sp(mode, position, speed, now), now).unwrap();
            let s = *m.state();
            let view = VehicleView {
                position: Some(s.position),
                yaw: Some(s.yaw),
                landed: s.landed,
            };
            let c = t.tick(now, &view);
            check(mode, &c, &m);
            m.step(
                0.02,
                &Command::Position {
                    position: c.position,
                    velocity_ff: Some(c.velocity),
                    yaw: Some(c.yaw),
                    yaw_rate: None,
                },
            );
        }
    }
    m
}

#[test]
fn closed_loop_takeoff_then_goto_respects_speed_and_fence() {
    let l = limits();
    let speed = 5.0;
    let goal = [40.0, -20.0, 15.0];
    let mut max_horizontal_drift_in_takeoff: f32 = 0.0;
    let mut peak_speed: f32 = 0.0;
    let m = fly(
        [0.0; 3],
        true,
        &[
            (ActionMode::Takeoff, [0.0, 0.0, 10.0], 3.0, 500),
            (ActionMode::Goto, goal, speed, 1500),
        ],
        |mode, c, m| {
            assert!(inside(&l, c.position), "{c:?}");
            let limit = if mode == ActionMode::Takeoff {
                3.0
            } else {
                speed
            };
            assert!(norm(c.velocity) <= limit + 1e-3, "{c:?}");
            let s = m.state();
            if mode == ActionMode::Takeoff {
                max_horizontal_drift_in_takeoff = max_horizontal_drift_in_takeoff
                    .max((s.position[0].powi(2) + s.position[1].powi(2)).sqrt());
            } else {
                peak_speed = peak_speed.max(norm(s.velocity));
            }
        },
    );
    assert!(max_horizontal_drift_in_takeoff < 0.01);
    assert!(peak_speed <= speed * 1.05, "peak {peak_speed}");
    assert!(peak_speed > speed * 0.9, "peak {peak_speed}");
    assert!(dist(m.state().position, goal) < 0.3, "{:?}", m.state());
}

#[test]
fn closed_loop_land_descends_to_the_ground_at_the_target() {
    let l = limits();
    let m = fly(
        [10.0, 10.0, 10.0],
        true,
        &[(ActionMode::Land, [14.0, 7.0, 0.0], 3.0, 1500)],
        |_, c, _| assert!(inside(&l, c.position), "{c:?}"),
    );
    let s = m.state();
    assert!(s.landed, "{s:?}");
    assert!(dist(s.position, [14.0, 7.0, 0.0]) < 0.3, "{s:?}");
}

#[test]
fn turn_and_hover_hold_the_position_where_the_mode_began() {
    let m = fly(
        [0.0, 0.0, 10.0],
        true,
        &[
            (ActionMode::Goto, [20.0, 0.0, 10.0], 4.0, 700),
            (ActionMode::Turn, [0.0, 0.0, 10.0], 4.0, 300),
            (ActionMode::Hover, [-50.0, 0.0, 10.0], 4.0, 300),
        ],
        |_, _, _| {},
    );
    // Neither turn nor hover flies to their (ignored) position field.
    assert!(
        dist(m.state().position, [20.0, 0.0, 10.0]) < 0.3,
        "{:?}",
        m.state()
    );
}

#[test]
fn the_wire_message_is_ned_in_local_ned_frame() {
    let cmd = TrackCommand {
        position: [1.0, 2.0, 3.0],
        velocity: [0.5, -0.5, 1.0],
        yaw: 0.25,
        mode: Some(ActionMode::Goto),
    };
    assert_eq!(neu_to_ned([1.0, 2.0, 3.0]), [1.0, 2.0, -3.0]);
    let MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) = position_target_message(
        &cmd,
        42,
        Target {
            system_id: 1,
            component_id: 1,
        },
    ) else {
        panic!("wrong message");
    };
    assert_eq!([m.x, m.y, m.z], [1.0, 2.0, -3.0]);
    assert_eq!([m.vx, m.vy, m.vz], [0.5, -0.5, -1.0]);
    assert_eq!(m.yaw, 0.25);
    assert_eq!(m.coordinate_frame, MavFrame::MAV_FRAME_LOCAL_NED);
    assert_eq!(m.type_mask, position_velocity_yaw_mask());
    assert_eq!(m.type_mask.bits(), 64 | 128 | 256 | 2048);
    assert_eq!((m.target_system, m.target_component), (1, 1));
    assert_eq!(m.time_boot_ms, 42);
}

#[test]
fn nothing_non_finite_reaches_the_output() {
    // Defence in depth: even a broken configuration never yields NaN on the wire.
    let mut t = Tracker::new(TrackerConfig {
        start: [f32::NAN, 0.0, 0.0],
        ..config()
    });
    let c = t.tick(T0, &VehicleView::default());
    assert!(
        c.position
            .iter()
            .chain(c.velocity.iter())
            .all(|v| v.is_finite()),
        "{c:?}"
    );
    assert!(c.yaw.is_finite());
}
