//! Simple multirotor kinematics in the local `[N, E, U]` frame (metres, up positive).
//!
//! The model is what a PX4 multirotor in offboard mode looks like from the outside, without
//! aerodynamics: a position target (optionally with a velocity feed-forward and a yaw) or a
//! velocity target becomes a desired velocity through a P-controller on position, saturated
//! by the vehicle's horizontal and vertical speed limits (and, when a feed-forward is given,
//! by the feed-forward's speed), then the velocity follows the desired velocity under an
//! acceleration limit. Yaw follows its target under a yaw-rate limit. Roll and pitch are the
//! small-angle attitude that produces the horizontal acceleration.
//!
//! The ground is the plane `U = 0`: the vehicle never goes below it, is `landed` when it
//! sits on it and is slow, and a disarmed vehicle does not fly (it stays on the ground, or
//! falls to it when disarmed in the air).
//!
//! Yaw is in radians, 0 = north, positive clockwise (towards east), wrapped to `[-pi, pi]`.

use aeris_geometry::wrap_pi;

/// Standard gravity (m/s^2).
pub const GRAVITY: f32 = 9.806_65;

/// Height of the ground plane (m, up).
pub const GROUND_U: f32 = 0.0;

/// Longest internal integration step (s); longer `dt`s are split.
pub const MAX_SUBSTEP_S: f32 = 0.01;

/// Longest `dt` one [`MultirotorModel::step`] integrates (s); the rest is dropped so a
/// stalled caller cannot make the vehicle jump.
pub const MAX_STEP_S: f32 = 0.1;

/// Vehicle limits and controller gains.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultirotorParams {
    /// Maximum horizontal speed (m/s).
    pub max_speed_h: f32,
    /// Maximum vertical speed, up or down (m/s).
    pub max_speed_v: f32,
    /// Maximum acceleration magnitude (m/s^2).
    pub max_accel: f32,
    /// Maximum yaw rate (rad/s).
    pub max_yaw_rate: f32,
    /// Position P gain (1/s): desired velocity per metre of position error.
    pub kp_position: f32,
    /// Yaw P gain (1/s): desired yaw rate per radian of yaw error.
    pub kp_yaw: f32,
    /// Speed under which a vehicle on the ground counts as landed (m/s).
    pub landed_speed: f32,
}

impl Default for MultirotorParams {
    fn default() -> Self {
        Self {
            max_speed_h: 12.0,
            max_speed_v: 4.0,
            max_accel: 4.0,
            max_yaw_rate: 60.0_f32.to_radians(),
            kp_position: 1.0,
            kp_yaw: 2.0,
            landed_speed: 0.3,
        }
    }
}

/// What the vehicle is asked to do (like PX4 offboard `SET_POSITION_TARGET_LOCAL_NED`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Fly to a position.
    Position {
        /// Target `[N, E, U]` (m).
        position: [f32; 3],
        /// Velocity feed-forward `[N, E, U]` (m/s); when given (and not zero) its speed
        /// also caps the approach speed.
        velocity_ff: Option<[f32; 3]>,
        /// Target yaw (rad); `None` keeps the yaw (or follows `yaw_rate`).
        yaw: Option<f32>,
        /// Target yaw rate (rad/s) when no yaw is given.
        yaw_rate: Option<f32>,
    },
    /// Fly at a velocity.
    Velocity {
        /// Target velocity `[N, E, U]` (m/s), saturated by the vehicle's limits.
        velocity: [f32; 3],
        /// Target yaw (rad); `None` keeps the yaw (or follows `yaw_rate`).
        yaw: Option<f32>,
        /// Target yaw rate (rad/s) when no yaw is given.
        yaw_rate: Option<f32>,
    },
}

impl Command {
    /// Hold `position` with yaw `yaw` (no feed-forward).
    pub fn hold(position: [f32; 3], yaw: f32) -> Self {
        Command::Position {
            position,
            velocity_ff: None,
            yaw: Some(yaw),
            yaw_rate: None,
        }
    }

    /// `true` when every number the command carries is finite.
    pub fn is_finite(&self) -> bool {
        let opt = |o: Option<f32>| o.is_none_or(f32::is_finite);
        let opt3 = |o: Option<[f32; 3]>| o.is_none_or(|v| v.iter().all(|x| x.is_finite()));
        match self {
            Command::Position {
                position,
                velocity_ff,
                yaw,
                yaw_rate,
            } => {
                position.iter().all(|x| x.is_finite())
                    && opt3(*velocity_ff)
                    && opt(*yaw)
                    && opt(*yaw_rate)
            }
            Command::Velocity {
                velocity,
                yaw,
                yaw_rate,
            } => velocity.iter().all(|x| x.is_finite()) && opt(*yaw) && opt(*yaw_rate),
        }
    }
}

/// The kinematic state of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultirotorState {
    /// Position `[N, E, U]` (m).
    pub position: [f32; 3],
    /// Velocity `[N, E, U]` (m/s).
    pub velocity: [f32; 3],
    /// Last acceleration `[N, E, U]` (m/s^2).
    pub acceleration: [f32; 3],
    /// Yaw (rad), `[-pi, pi]`, 0 = north, clockwise positive.
    pub yaw: f32,
    /// Yaw rate (rad/s).
    pub yaw_rate: f32,
    /// Roll (rad), positive = right wing down (accelerating to the right).
    pub roll: f32,
    /// Pitch (rad), positive = nose up (negative while accelerating forward).
    pub pitch: f32,
    /// Motors armed.
    pub armed: bool,
    /// On the ground and slow.
    pub landed: bool,
}

/// Simple multirotor kinematics with speed, acceleration and yaw-rate limits.
#[derive(Debug, Clone, PartialEq)]
pub struct MultirotorModel {
    params: MultirotorParams,
    state: MultirotorState,
}

fn norm2(v: [f32; 2]) -> f32 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

fn norm3(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl MultirotorModel {
    /// A disarmed vehicle at `position` (clamped to the ground) with `yaw` (north when not
    /// finite), at rest.
    pub fn new(params: MultirotorParams, position: [f32; 3], yaw: f32) -> Self {
        let position = [position[0], position[1], position[2].max(GROUND_U)];
        let on_ground = position[2] <= GROUND_U;
        Self {
            params,
            state: MultirotorState {
                position,
                velocity: [0.0; 3],
                acceleration: [0.0; 3],
                yaw: if yaw.is_finite() { wrap_pi(yaw) } else { 0.0 },
                yaw_rate: 0.0,
                roll: 0.0,
                pitch: 0.0,
                armed: false,
                landed: on_ground,
            },
        }
    }

    /// The limits and gains.
    pub fn params(&self) -> &MultirotorParams {
        &self.params
    }

    /// The current state.
    pub fn state(&self) -> &MultirotorState {
        &self.state
    }

    /// Arm or disarm the motors. Disarming in the air lets the vehicle fall.
    pub fn set_armed(&mut self, armed: bool) {
        self.state.armed = armed;
    }

    /// `true` when the vehicle touches the ground.
    pub fn on_ground(&self) -> bool {
        self.state.position[2] <= GROUND_U + 1e-3
    }

    /// Advance by `dt` seconds (at most [`MAX_STEP_S`], integrated in steps of at most
    /// [`MAX_SUBSTEP_S`]) under `command`. A non-finite command or `dt` is ignored (the
    /// vehicle brakes to a hover instead).
    pub fn step(&mut self, dt: f32, command: &Command) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let brake = Command::Velocity {
            velocity: [0.0; 3],
            yaw: None,
            yaw_rate: None,
        };
        let command = if command.is_finite() { command } else { &brake };
        let mut left = dt.min(MAX_STEP_S);
        while left > 1e-6 {
            let h = left.min(MAX_SUBSTEP_S);
            self.substep(h, command);
            left -= h;
        }
    }

    fn desired_velocity(&self, command: &Command) -> [f32; 3] {
        let p = &self.params;
        let s = &self.state;
        let (mut v, cap) = match *command {
            Command::Position {
                position,
                velocity_ff,
                ..
            } => {
                let err = [
                    position[0] - s.position[0],
                    position[1] - s.position[1],
                    position[2] - s.position[2],
                ];
                let ff = velocity_ff.unwrap_or([0.0; 3]);
                let v = [
                    p.kp_position * err[0] + ff[0],
                    p.kp_position * err[1] + ff[1],
                    p.kp_position * err[2] + ff[2],
                ];
                let ff_speed = norm3(ff);
                (v, (ff_speed > 1e-3).then_some(ff_speed))
            }
            Command::Velocity { velocity, .. } => (velocity, None),
        };
        if let Some(cap) = cap {
            let n = norm3(v);
            if n > cap {
                let k = cap / n;
                v = [v[0] * k, v[1] * k, v[2] * k];
            }
        }
        let h = norm2([v[0], v[1]]);
        if h > p.max_speed_h {
            let k = p.max_speed_h / h;
            v[0] *= k;
            v[1] *= k;
        }
        v[2] = v[2].clamp(-p.max_speed_v, p.max_speed_v);
        v
    }

    fn desired_yaw_rate(&self, command: &Command) -> f32 {
        let (yaw, yaw_rate) = match *command {
            Command::Position { yaw, yaw_rate, .. } | Command::Velocity { yaw, yaw_rate, .. } => {
                (yaw, yaw_rate)
            }
        };
        let r = match (yaw, yaw_rate) {
            (Some(target), _) => self.params.kp_yaw * wrap_pi(target - self.state.yaw),
            (None, Some(rate)) => rate,
            (None, None) => 0.0,
        };
        r.clamp(-self.params.max_yaw_rate, self.params.max_yaw_rate)
    }

    fn substep(&mut self, h: f32, command: &Command) {
        let grounded = self.on_ground();
        if !self.state.armed {
            // Disarmed: no thrust. On the ground it stays put; in the air it falls.
            let s = &mut self.state;
            if grounded {
                s.velocity = [0.0; 3];
                s.acceleration = [0.0; 3];
            } else {
                s.acceleration = [0.0, 0.0, -GRAVITY];
                s.velocity[2] -= GRAVITY * h;
                for (p, v) in s.position.iter_mut().zip(s.velocity) {
                    *p += v * h;
                }
            }
            s.yaw_rate = 0.0;
            s.roll = 0.0;
            s.pitch = 0.0;
            self.clamp_ground();
            return;
        }
        let p = self.params;
        let mut desired = self.desired_velocity(command);
        if grounded && desired[2] <= 0.0 {
            // Sitting on the ground: no sliding and no digging in.
            desired = [0.0; 3];
        }
        let v = self.state.velocity;
        let mut dv = [desired[0] - v[0], desired[1] - v[1], desired[2] - v[2]];
        let max_dv = p.max_accel * h;
        let n = norm3(dv);
        if n > max_dv {
            let k = max_dv / n;
            dv = [dv[0] * k, dv[1] * k, dv[2] * k];
        }
        let yaw_rate = if grounded && desired == [0.0; 3] {
            0.0
        } else {
            self.desired_yaw_rate(command)
        };
        let s = &mut self.state;
        let mut new_v = [v[0] + dv[0], v[1] + dv[1], v[2] + dv[2]];
        // Numerical safety: the speed limits hold after the acceleration step too.
        let hs = norm2([new_v[0], new_v[1]]);
        if hs > p.max_speed_h {
            let k = p.max_speed_h / hs;
            new_v[0] *= k;
            new_v[1] *= k;
        }
        new_v[2] = new_v[2].clamp(-p.max_speed_v, p.max_speed_v);
        s.acceleration = [
            (new_v[0] - v[0]) / h,
            (new_v[1] - v[1]) / h,
            (new_v[2] - v[2]) / h,
        ];
        s.velocity = new_v;
        for (p, v) in s.position.iter_mut().zip(new_v) {
            *p += v * h;
        }
        s.yaw_rate = yaw_rate;
        s.yaw = wrap_pi(s.yaw + yaw_rate * h);
        // Small-angle attitude from the horizontal acceleration in the body frame.
        let (sy, cy) = s.yaw.sin_cos();
        let [an, ae, _] = s.acceleration;
        let forward = an * cy + ae * sy;
        let right = -an * sy + ae * cy;
        s.pitch = -(forward / GRAVITY).atan();
        s.roll = (right / GRAVITY).atan();
        self.clamp_ground();
    }

    fn clamp_ground(&mut self) {
        let s = &mut self.state;
        if s.position[2] <= GROUND_U {
            s.position[2] = GROUND_U;
            if s.velocity[2] < 0.0 {
                s.velocity[2] = 0.0;
            }
            if !s.armed {
                s.velocity = [0.0; 3];
            }
        }
        let on_ground = s.position[2] <= GROUND_U + 1e-3;
        s.landed = on_ground && norm3(s.velocity) < self.params.landed_speed;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f32::consts::PI;

    fn armed_at(p: [f32; 3]) -> MultirotorModel {
        let mut m = MultirotorModel::new(MultirotorParams::default(), p, 0.0);
        m.set_armed(true);
        m
    }

    fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
        norm3([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
    }

    #[test]
    fn reaches_a_position_setpoint_and_yaw() {
        let mut m = armed_at([0.0; 3]);
        let target = [30.0, -20.0, 15.0];
        let cmd = Command::Position {
            position: target,
            velocity_ff: None,
            yaw: Some(1.5),
            yaw_rate: None,
        };
        for _ in 0..3000 {
            m.step(0.01, &cmd);
        }
        assert!(dist(m.state().position, target) < 0.05, "{:?}", m.state());
        assert!((m.state().yaw - 1.5).abs() < 0.01);
        assert!(norm3(m.state().velocity) < 0.05);
        assert!(!m.state().landed);
    }

    #[test]
    fn never_exceeds_speed_accel_or_yaw_rate_limits() {
        let p = MultirotorParams::default();
        let mut m = armed_at([0.0; 3]);
        let targets = [
            [500.0, 0.0, 50.0],
            [-500.0, 300.0, 0.0],
            [0.0, 0.0, 5.0],
            [100.0, 100.0, 100.0],
        ];
        let mut last_v = m.state().velocity;
        for (i, t) in targets.iter().enumerate() {
            let cmd = Command::Position {
                position: *t,
                velocity_ff: None,
                yaw: Some(if i % 2 == 0 { 3.0 } else { -3.0 }),
                yaw_rate: None,
            };
            for _ in 0..800 {
                m.step(0.02, &cmd);
                let s = m.state();
                assert!(norm2([s.velocity[0], s.velocity[1]]) <= p.max_speed_h + 1e-3);
                assert!(s.velocity[2].abs() <= p.max_speed_v + 1e-3);
                assert!(s.yaw_rate.abs() <= p.max_yaw_rate + 1e-4);
                let dv = dist(s.velocity, last_v);
                assert!(dv <= p.max_accel * 0.02 + 1e-3, "dv {dv}");
                assert!(s.position[2] >= GROUND_U);
                assert!((-PI..=PI).contains(&s.yaw));
                last_v = s.velocity;
            }
        }
    }

    #[test]
    fn feed_forward_speed_caps_the_approach() {
        let mut m = armed_at([0.0, 0.0, 10.0]);
        let cmd = Command::Position {
            position: [200.0, 0.0, 10.0],
            velocity_ff: Some([3.0, 0.0, 0.0]),
            yaw: None,
            yaw_rate: None,
        };
        let mut peak: f32 = 0.0;
        for _ in 0..1000 {
            m.step(0.01, &cmd);
            peak = peak.max(norm3(m.state().velocity));
        }
        assert!(peak <= 3.0 + 1e-3, "peak {peak}");
        assert!(peak > 2.9, "peak {peak}");
    }

    #[test]
    fn velocity_target_is_saturated() {
        let mut m = armed_at([0.0, 0.0, 10.0]);
        let cmd = Command::Velocity {
            velocity: [50.0, 0.0, 20.0],
            yaw: None,
            yaw_rate: None,
        };
        for _ in 0..1000 {
            m.step(0.01, &cmd);
        }
        let v = m.state().velocity;
        assert!(
            (v[0] - 12.0).abs() < 1e-3 && (v[2] - 4.0).abs() < 1e-3,
            "{v:?}"
        );
    }

    #[test]
    fn ground_clamp_and_landed() {
        let mut m = armed_at([0.0, 0.0, 5.0]);
        let cmd = Command::Position {
            position: [0.0, 0.0, -20.0],
            velocity_ff: None,
            yaw: None,
            yaw_rate: None,
        };
        for _ in 0..1000 {
            m.step(0.01, &cmd);
            assert!(m.state().position[2] >= GROUND_U);
        }
        assert_eq!(m.state().position[2], GROUND_U);
        assert!(m.state().landed);
        // Climbing out leaves the landed state.
        let up = Command::hold([0.0, 0.0, 3.0], 0.0);
        for _ in 0..100 {
            m.step(0.01, &up);
        }
        assert!(!m.state().landed);
        assert!(m.state().position[2] > 0.1);
    }

    #[test]
    fn disarmed_does_not_move_and_falls_when_disarmed_in_air() {
        let mut m = MultirotorModel::new(MultirotorParams::default(), [1.0, 2.0, 0.0], 0.3);
        let cmd = Command::Position {
            position: [50.0, 50.0, 20.0],
            velocity_ff: None,
            yaw: Some(-2.0),
            yaw_rate: None,
        };
        for _ in 0..500 {
            m.step(0.01, &cmd);
        }
        assert_eq!(m.state().position, [1.0, 2.0, 0.0]);
        assert_eq!(m.state().velocity, [0.0; 3]);
        assert!((m.state().yaw - 0.3).abs() < 1e-6);
        assert!(m.state().landed);

        let mut air = armed_at([0.0, 0.0, 10.0]);
        air.set_armed(false);
        for _ in 0..500 {
            air.step(0.01, &cmd);
        }
        assert_eq!(air.state().position[2], GROUND_U);
        assert!(air.state().landed);
    }

    #[test]
    fn attitude_follows_acceleration() {
        let mut m = armed_at([0.0, 0.0, 10.0]);
        // Facing north, accelerate north: nose down.
        m.step(0.05, &Command::hold([100.0, 0.0, 10.0], 0.0));
        assert!(m.state().pitch < -0.2, "{:?}", m.state());
        assert!(m.state().roll.abs() < 1e-3);
        // Facing north, accelerate east: roll right.
        let mut m = armed_at([0.0, 0.0, 10.0]);
        m.step(0.05, &Command::hold([0.0, 100.0, 10.0], 0.0));
        assert!(m.state().roll > 0.2);
    }

    #[test]
    fn non_finite_inputs_are_ignored() {
        let mut m = armed_at([0.0, 0.0, 10.0]);
        m.step(f32::NAN, &Command::hold([0.0, 0.0, 10.0], 0.0));
        m.step(0.01, &Command::hold([f32::NAN, 0.0, 10.0], 0.0));
        let s = m.state();
        assert!(s.position.iter().all(|x| x.is_finite()));
        assert_eq!(s.position, [0.0, 0.0, 10.0]);
    }

    #[test]
    fn a_non_finite_start_yaw_faces_north() {
        let m = MultirotorModel::new(MultirotorParams::default(), [0.0; 3], f32::NAN);
        assert_eq!(m.state().yaw, 0.0);
    }
}
