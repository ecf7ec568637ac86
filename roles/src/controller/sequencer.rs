//! The autopilot sequencer: what the controller asks of the autopilot besides setpoints,
//! and when. Pure: no I/O, no allocation; the role sends what [`AutopilotSequencer::step`]
//! requests.
//!
//! - our HEARTBEAT every [`HEARTBEAT_PERIOD_NS`] (an autopilot drops a companion it stops
//!   hearing);
//! - streaming before offboard: setpoints must have streamed for
//!   [`STREAM_BEFORE_OFFBOARD_NS`] before the mode change is asked for (PX4 refuses offboard
//!   without a live stream);
//! - while the autopilot's link is up and a valid setpoint wants the vehicle flying, but the
//!   autopilot does not report armed and offboard: the mode change (when not in offboard)
//!   and the arm command (when disarmed), repeated every [`COMMAND_RETRY_NS`] until the
//!   heartbeat reports both, each round with the next `confirmation` number.
//!
//! - for a firmware that needs it ([`Autopilot::needs_takeoff_command`], ArduPilot): once
//!   armed and in guided on the ground with a setpoint that wants flight,
//!   `MAV_CMD_NAV_TAKEOFF` to the setpoint's height, repeated every [`COMMAND_RETRY_NS`]
//!   until the vehicle is off the ground;
//! - for a firmware that lands in a mode of its own ([`Autopilot::land_set_mode_params`],
//!   ArduPilot): once a land setpoint has brought the vehicle over its landing point, that
//!   mode instead of guided (it descends where the vehicle is).
//!
//! The firmware's flavour ([`Autopilot`]) says how each of these is commanded; it is
//! known once the autopilot's HEARTBEAT has been heard ([`AutopilotSequencer::set_autopilot`]).

use aeris_mavlink::Autopilot;

/// Setpoints must stream this long before the controller asks for offboard.
pub const STREAM_BEFORE_OFFBOARD_NS: u64 = 500_000_000;
/// Mode / arm commands are repeated at this interval until they take effect.
pub const COMMAND_RETRY_NS: u64 = 500_000_000;
/// The lowest take-off height commanded (m).
pub const MIN_TAKEOFF_HEIGHT_M: f32 = 1.0;
/// The controller's HEARTBEAT period.
pub const HEARTBEAT_PERIOD_NS: u64 = 1_000_000_000;

/// What the autopilot reports, as far as the sequence goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AutopilotStatus {
    /// Its heartbeat is fresh.
    pub link_up: bool,
    /// It reports the motors armed.
    pub armed: bool,
    /// It reports the mode that flies our setpoints.
    pub offboard: bool,
    /// It reports its own landing mode.
    pub landing_mode: bool,
    /// The vehicle is on the ground.
    pub landed: bool,
}

/// What the tracker flies, as far as the sequence goes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlightIntent {
    /// A fresh valid setpoint of a flying mode, or any while airborne.
    pub wants_flight: bool,
    /// The active setpoint is a landing and the vehicle is over its landing point.
    pub landing: bool,
    /// Height above the vehicle to take off to (m), for a take-off command.
    pub takeoff_height_m: f32,
}

/// What to send to the autopilot this tick, besides the setpoint, in this order.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AutopilotRequests {
    /// Our HEARTBEAT is due.
    pub heartbeat: bool,
    /// MAV_CMD_DO_SET_MODE with these `param1..=param3` (into offboard).
    pub set_mode: Option<[f32; 3]>,
    /// MAV_CMD_COMPONENT_ARM_DISARM (arm).
    pub arm: bool,
    /// MAV_CMD_NAV_TAKEOFF to this height above the ground (m).
    pub takeoff_m: Option<f32>,
    /// The `confirmation` of this round's commands.
    pub confirmation: u8,
}

/// The sequence of heartbeats, mode changes and arming towards offboard flight.
#[derive(Debug, Clone, Copy)]
pub struct AutopilotSequencer {
    autopilot: Autopilot,
    next_heartbeat_ns: u64,
    next_command_ns: u64,
    stream_since_ns: Option<u64>,
    confirmation: u8,
}

impl AutopilotSequencer {
    /// A sequence towards `autopilot` starting at `now_ns` (the first heartbeat is due at
    /// once; no setpoint has streamed yet).
    pub fn new(autopilot: Autopilot, now_ns: u64) -> Self {
        Self {
            autopilot,
            next_heartbeat_ns: now_ns,
            next_command_ns: now_ns,
            stream_since_ns: None,
            confirmation: 0,
        }
    }

    /// The autopilot flavour commanded.
    pub fn autopilot(&self) -> Autopilot {
        self.autopilot
    }

    /// Command `autopilot` from now on (its HEARTBEAT said which firmware it is).
    pub fn set_autopilot(&mut self, autopilot: Autopilot) {
        self.autopilot = autopilot;
    }

    /// A setpoint reached the link at `now_ns` (the first one starts the stream).
    pub fn setpoint_sent(&mut self, now_ns: u64) {
        self.stream_since_ns.get_or_insert(now_ns);
    }

    /// What to send at `now_ns`, with the autopilot in `status` and the tracker flying
    /// `intent`.
    pub fn step(
        &mut self,
        now_ns: u64,
        status: AutopilotStatus,
        intent: FlightIntent,
    ) -> AutopilotRequests {
        let mut out = AutopilotRequests {
            confirmation: self.confirmation,
            ..AutopilotRequests::default()
        };
        if now_ns >= self.next_heartbeat_ns {
            self.next_heartbeat_ns = now_ns + HEARTBEAT_PERIOD_NS;
            out.heartbeat = true;
        }
        let streamed = self
            .stream_since_ns
            .is_some_and(|s| now_ns.saturating_sub(s) >= STREAM_BEFORE_OFFBOARD_NS);
        if !(status.link_up && streamed && intent.wants_flight && now_ns >= self.next_command_ns) {
            return out;
        }
        let land_mode = self.autopilot.land_set_mode_params();
        if intent.landing && !status.landed && land_mode.is_some() {
            // the firmware lands by itself: its landing mode, not guided
            if !status.landing_mode {
                out.set_mode = land_mode;
                self.next_command_ns = now_ns + COMMAND_RETRY_NS;
                self.confirmation = self.confirmation.wrapping_add(1);
            }
            return out;
        }
        if !(status.armed && status.offboard) {
            if !status.offboard {
                out.set_mode = Some(self.autopilot.offboard_set_mode_params());
            }
            out.arm = !status.armed;
        } else if self.autopilot.needs_takeoff_command() && status.landed && !intent.landing {
            out.takeoff_m = Some(intent.takeoff_height_m.max(MIN_TAKEOFF_HEIGHT_M));
        } else {
            return out;
        }
        self.next_command_ns = now_ns + COMMAND_RETRY_NS;
        self.confirmation = self.confirmation.wrapping_add(1);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const T0: u64 = 1_000 * MS;
    const UP: AutopilotStatus = AutopilotStatus {
        link_up: true,
        armed: false,
        offboard: false,
        landing_mode: false,
        landed: true,
    };
    const FLY: FlightIntent = FlightIntent {
        wants_flight: true,
        landing: false,
        takeoff_height_m: 10.0,
    };
    const STAY: FlightIntent = FlightIntent {
        wants_flight: false,
        landing: false,
        takeoff_height_m: 0.0,
    };

    fn commands(r: &AutopilotRequests) -> (bool, bool) {
        (r.set_mode.is_some(), r.arm)
    }

    #[test]
    fn nothing_is_commanded_before_setpoints_streamed_long_enough() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        // no stream at all
        assert_eq!(commands(&s.step(T0 + 900 * MS, UP, FLY)), (false, false));
        s.setpoint_sent(T0 + 1_000 * MS);
        // later setpoints do not restart the stream
        s.setpoint_sent(T0 + 1_200 * MS);
        let just_before = T0 + 1_000 * MS + STREAM_BEFORE_OFFBOARD_NS - 1;
        assert_eq!(commands(&s.step(just_before, UP, FLY)), (false, false));
        let r = s.step(just_before + 1, UP, FLY);
        assert_eq!(commands(&r), (true, true));
        assert_eq!(
            r.set_mode,
            Some(Autopilot::Px4.offboard_set_mode_params()),
            "the flavour's mode change"
        );
    }

    #[test]
    fn commands_repeat_at_the_retry_interval_until_armed_and_offboard() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        s.setpoint_sent(T0);
        let t = T0 + STREAM_BEFORE_OFFBOARD_NS;
        let first = s.step(t, UP, FLY);
        assert_eq!((commands(&first), first.confirmation), ((true, true), 0));
        assert_eq!(
            commands(&s.step(t + COMMAND_RETRY_NS - 1, UP, FLY)),
            (false, false)
        );
        // offboard took, arming did not: only the arm command again, next confirmation
        let offboard = AutopilotStatus {
            offboard: true,
            ..UP
        };
        let second = s.step(t + COMMAND_RETRY_NS, offboard, FLY);
        assert_eq!((commands(&second), second.confirmation), ((false, true), 1));
        // armed and offboard: nothing more
        let flying = AutopilotStatus {
            armed: true,
            ..offboard
        };
        assert_eq!(
            commands(&s.step(t + 5 * COMMAND_RETRY_NS, flying, FLY)),
            (false, false)
        );
    }

    #[test]
    fn no_commands_without_the_autopilots_heartbeat_or_a_setpoint_that_wants_flight() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        s.setpoint_sent(T0);
        let t = T0 + STREAM_BEFORE_OFFBOARD_NS;
        let down = AutopilotStatus {
            link_up: false,
            ..UP
        };
        assert_eq!(commands(&s.step(t, down, FLY)), (false, false));
        assert_eq!(commands(&s.step(t, UP, STAY)), (false, false));
        // neither used up the retry interval
        assert_eq!(commands(&s.step(t, UP, FLY)), (true, true));
    }

    #[test]
    fn the_heartbeat_is_due_at_once_then_every_period() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        assert!(s.step(T0, UP, STAY).heartbeat);
        assert!(!s.step(T0 + HEARTBEAT_PERIOD_NS - 1, UP, STAY).heartbeat);
        assert!(s.step(T0 + HEARTBEAT_PERIOD_NS, UP, STAY).heartbeat);
        // a late tick re-anchors the period
        assert!(s.step(T0 + 5 * HEARTBEAT_PERIOD_NS, UP, STAY).heartbeat);
        assert!(!s.step(T0 + 6 * HEARTBEAT_PERIOD_NS - 1, UP, STAY).heartbeat);
    }

    #[test]
    fn ardupilot_takes_off_by_command_once_armed_in_guided_and_lands_in_its_land_mode() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        s.set_autopilot(Autopilot::ArduPilotCopter);
        s.setpoint_sent(T0);
        let mut t = T0 + STREAM_BEFORE_OFFBOARD_NS;
        let first = s.step(t, UP, FLY);
        assert_eq!(first.set_mode, Some([1.0, 4.0, 0.0]), "guided");
        assert!(first.arm && first.takeoff_m.is_none());
        let guided_armed = AutopilotStatus {
            armed: true,
            offboard: true,
            ..UP
        };
        t += COMMAND_RETRY_NS;
        let takeoff = s.step(t, guided_armed, FLY);
        assert_eq!(
            (takeoff.set_mode, takeoff.arm, takeoff.takeoff_m),
            (None, false, Some(10.0))
        );
        // repeated until off the ground, then nothing
        t += COMMAND_RETRY_NS;
        assert_eq!(s.step(t, guided_armed, FLY).takeoff_m, Some(10.0));
        let airborne = AutopilotStatus {
            landed: false,
            ..guided_armed
        };
        t += COMMAND_RETRY_NS;
        let r = s.step(t, airborne, FLY);
        assert_eq!((r.set_mode, r.arm, r.takeoff_m), (None, false, None));
        // a land setpoint in the air: land mode, and no way back to guided while landing
        let land = FlightIntent {
            landing: true,
            ..FLY
        };
        t += COMMAND_RETRY_NS;
        assert_eq!(s.step(t, airborne, land).set_mode, Some([1.0, 9.0, 0.0]));
        let landing = AutopilotStatus {
            offboard: false,
            landing_mode: true,
            ..airborne
        };
        t += COMMAND_RETRY_NS;
        let r = s.step(t, landing, land);
        assert_eq!((r.set_mode, r.arm, r.takeoff_m), (None, false, None));
    }

    #[test]
    fn px4_needs_no_takeoff_command_and_lands_on_setpoints() {
        let mut s = AutopilotSequencer::new(Autopilot::Px4, T0);
        s.setpoint_sent(T0);
        let flying = AutopilotStatus {
            armed: true,
            offboard: true,
            ..UP
        };
        let t = T0 + STREAM_BEFORE_OFFBOARD_NS;
        assert_eq!(s.step(t, flying, FLY).takeoff_m, None);
        let land = FlightIntent {
            landing: true,
            ..FLY
        };
        let airborne = AutopilotStatus {
            landed: false,
            ..flying
        };
        assert_eq!(s.step(t, airborne, land).set_mode, None);
    }
}
