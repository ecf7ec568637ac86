//! What the autopilot reported, as the controller keeps it: the receive thread applies
//! every message from the autopilot ([`AutopilotState::apply`]); a standby keeps the
//! holder's telemetry instead ([`AutopilotState::from_telemetry`]) and, after a takeover,
//! completes what its own link has not reported yet from it. Pure: no I/O.

use super::tracker::VehicleView;
use aeris_geometry::wrap_pi;
use aeris_mavlink::dialect::{MavLandedState, MavMessage, MavModeFlag};
use aeris_mavlink::{Autopilot, MavlinkVersion, ned_to_neu, neu_to_ned};
use aeris_schemas::VehicleTelemetry;

/// The link counts as up while the autopilot's heartbeat is younger than this.
pub const LINK_TIMEOUT_NS: u64 = 2_000_000_000;
/// A vehicle below the floor plus this is on the ground when the autopilot reports no
/// landed state (m).
const GROUND_MARGIN_M: f32 = 0.15;

/// What the receive thread decoded from the autopilot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct AutopilotState {
    /// When the last HEARTBEAT arrived (CLOCK_MONOTONIC ns).
    pub(super) last_heartbeat_ns: Option<u64>,
    /// The heartbeat reports the motors armed.
    pub(super) armed: bool,
    /// The heartbeat reports the mode that flies our setpoints.
    pub(super) offboard: bool,
    /// The heartbeat reports the firmware's own landing mode.
    pub(super) landing_mode: bool,
    /// The last EXTENDED_SYS_STATE's landed state.
    pub(super) landed_state: Option<MavLandedState>,
    /// When it arrived (CLOCK_MONOTONIC ns).
    pub(super) landed_state_ns: Option<u64>,
    /// The last finite LOCAL_POSITION_NED position.
    pub(super) position_ned: Option<[f32; 3]>,
    /// When it arrived (CLOCK_MONOTONIC ns).
    pub(super) position_ns: Option<u64>,
    /// Its velocity (NED).
    pub(super) velocity_ned: [f32; 3],
    /// The last finite ATTITUDE `[roll, pitch, yaw]`, yaw in `[-pi, pi]`.
    pub(super) attitude: Option<[f32; 3]>,
    /// When it arrived (CLOCK_MONOTONIC ns).
    pub(super) attitude_ns: Option<u64>,
    /// The autopilot's boot time of the last position.
    pub(super) time_boot_ms: u32,
    /// COMMAND_ACKs received.
    pub(super) acks: u64,
    /// The framing of the autopilot's last HEARTBEAT (`None`: not heard yet, or a link that
    /// does not report framing).
    pub(super) heartbeat_version: Option<MavlinkVersion>,
}

impl AutopilotState {
    /// Take in `msg` from `autopilot`, received at `now_ns`.
    pub(super) fn apply(&mut self, msg: &MavMessage, now_ns: u64, autopilot: Autopilot) {
        match msg {
            MavMessage::HEARTBEAT(hb) => {
                self.last_heartbeat_ns = Some(now_ns);
                self.armed = hb
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                self.offboard = autopilot.reports_offboard(hb);
                self.landing_mode = autopilot.reports_landing_mode(hb);
            }
            MavMessage::LOCAL_POSITION_NED(p)
                if [p.x, p.y, p.z, p.vx, p.vy, p.vz]
                    .iter()
                    .all(|v| v.is_finite()) =>
            {
                self.position_ned = Some([p.x, p.y, p.z]);
                self.position_ns = Some(now_ns);
                self.velocity_ned = [p.vx, p.vy, p.vz];
                self.time_boot_ms = p.time_boot_ms;
            }
            MavMessage::ATTITUDE(a) if [a.roll, a.pitch, a.yaw].iter().all(|v| v.is_finite()) => {
                // the yaw goes back out as a hold's setpoint yaw: the same heading in [-pi, pi]
                self.attitude = Some([a.roll, a.pitch, wrap_pi(a.yaw)]);
                self.attitude_ns = Some(now_ns);
            }
            MavMessage::EXTENDED_SYS_STATE(e) => {
                self.landed_state = Some(e.landed_state);
                self.landed_state_ns = Some(now_ns);
            }
            MavMessage::COMMAND_ACK(_) => self.acks += 1,
            _ => {}
        }
    }

    /// The autopilot's heartbeat is fresh at `now_ns`.
    pub(super) fn link_up(&self, now_ns: u64) -> bool {
        self.last_heartbeat_ns
            .is_some_and(|t| now_ns.saturating_sub(t) <= LINK_TIMEOUT_NS)
    }

    /// The state another controller reported in `t` (a standby's view of the vehicle).
    pub(super) fn from_telemetry(t: &VehicleTelemetry) -> Self {
        Self {
            last_heartbeat_ns: (t.link_up == 1).then_some(t.stamp_ns),
            armed: t.armed == 1,
            offboard: t.offboard == 1,
            landing_mode: false,
            landed_state: Some(if t.landed == 1 {
                MavLandedState::MAV_LANDED_STATE_ON_GROUND
            } else {
                MavLandedState::MAV_LANDED_STATE_IN_AIR
            }),
            landed_state_ns: Some(t.stamp_ns),
            position_ned: Some(neu_to_ned(t.position)),
            position_ns: Some(t.stamp_ns),
            velocity_ned: neu_to_ned(t.velocity),
            attitude: Some(t.attitude),
            attitude_ns: Some(t.stamp_ns),
            time_boot_ms: t.autopilot_time_ms,
            acks: 0,
            // a standby's own link tells the framing
            heartbeat_version: None,
        }
    }

    /// This link's state where it heard it since `since_ns` (when this process took the
    /// lease), the rest from `standby` (what the previous holder reported, for the first
    /// ticks after a takeover). What the link heard before `since_ns` is used only where the
    /// holder reported nothing: a standby that held the lease once may keep a vehicle still
    /// on the helipad in its link's memory, and that is not where the vehicle is now.
    pub(super) fn or_else(self, standby: &AutopilotState, since_ns: u64) -> Self {
        // this link's word on a field: heard in this term, or the holder has none
        let own = |heard: Option<u64>, holders: Option<u64>| {
            heard.is_some_and(|t| t >= since_ns) || holders.is_none()
        };
        let mut merged = self;
        if !own(self.last_heartbeat_ns, standby.last_heartbeat_ns) {
            merged.last_heartbeat_ns = standby.last_heartbeat_ns;
            merged.armed = standby.armed;
            merged.offboard = standby.offboard;
            // the holder's telemetry does not say
            merged.landing_mode = false;
        }
        if !own(self.landed_state_ns, standby.landed_state_ns) {
            merged.landed_state = standby.landed_state;
            merged.landed_state_ns = standby.landed_state_ns;
        }
        if !own(self.position_ns, standby.position_ns) {
            merged.position_ned = standby.position_ned;
            merged.velocity_ned = standby.velocity_ned;
            merged.time_boot_ms = standby.time_boot_ms;
            merged.position_ns = standby.position_ns;
        }
        if !own(self.attitude_ns, standby.attitude_ns) {
            merged.attitude = standby.attitude;
            merged.attitude_ns = standby.attitude_ns;
        }
        merged
    }

    /// What the tracker sees of the vehicle (`floor`: the ground, m up).
    pub(super) fn vehicle_view(&self, floor: f32) -> VehicleView {
        VehicleView {
            position: self.position_ned.map(ned_to_neu),
            yaw: self.attitude.map(|a| a[2]),
            landed: self.landed(floor),
        }
    }

    /// On the ground: as the autopilot says, or below the floor plus a margin when it says
    /// nothing.
    pub(super) fn landed(&self, floor: f32) -> bool {
        match self.landed_state {
            Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND) => true,
            Some(MavLandedState::MAV_LANDED_STATE_UNDEFINED) | None => self
                .position_ned
                .is_some_and(|p| -p[2] <= floor + GROUND_MARGIN_M),
            Some(_) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_autopilot_yaw_out_of_range_is_wrapped_before_it_is_flown() {
        let mut s = AutopilotState::default();
        for (yaw, want) in [
            (0.5f32, 0.5f32),
            (7.0, 7.0 - core::f32::consts::TAU),
            (-4.0, -4.0 + core::f32::consts::TAU),
            (1e6, f32::NAN),
        ] {
            s.apply(
                &MavMessage::ATTITUDE(aeris_mavlink::dialect::ATTITUDE_DATA {
                    time_boot_ms: 1,
                    roll: 0.0,
                    pitch: 0.0,
                    yaw,
                    rollspeed: 0.0,
                    pitchspeed: 0.0,
                    yawspeed: 0.0,
                }),
                1,
                Autopilot::Px4,
            );
            let got = s.attitude.unwrap()[2];
            let pi = core::f32::consts::PI;
            assert!((-pi..=pi).contains(&got), "{yaw} -> {got}");
            if !want.is_nan() {
                assert!((got - want).abs() < 1e-4, "{yaw} -> {got}, want {want}");
            }
        }
    }

    #[test]
    fn after_a_takeover_the_link_state_is_completed_from_the_holders_telemetry() {
        let t = VehicleTelemetry {
            stamp_ns: 7,
            armed: 1,
            offboard: 1,
            link_up: 1,
            landed: 0,
            position: [10.0, 5.0, 12.0],
            velocity: [1.0, 0.0, -0.5],
            attitude: [0.0, 0.0, 0.3],
            autopilot_time_ms: 1234,
            ..Default::default()
        };
        let standby = AutopilotState::from_telemetry(&t);
        let view = AutopilotState::default()
            .or_else(&standby, 0)
            .vehicle_view(0.0);
        assert_eq!(view.position, Some([10.0, 5.0, 12.0]));
        assert_eq!(view.yaw, Some(0.3));
        assert!(!view.landed);
        let merged = AutopilotState::default().or_else(&standby, 0);
        assert!(merged.armed && merged.offboard && merged.link_up(7));
        // what the link itself reports wins
        let mut link = AutopilotState::default();
        link.apply(
            &MavMessage::LOCAL_POSITION_NED(aeris_mavlink::dialect::LOCAL_POSITION_NED_DATA {
                time_boot_ms: 2000,
                x: 11.0,
                y: 5.0,
                z: -12.0,
                vx: 0.0,
                vy: 0.0,
                vz: 0.0,
            }),
            9,
            Autopilot::Px4,
        );
        let merged = link.or_else(&standby, 0);
        assert_eq!(merged.position_ned, Some([11.0, 5.0, -12.0]));
        assert_eq!(merged.time_boot_ms, 2000);
        assert!(
            merged.armed,
            "no heartbeat on the link yet: the holder's word"
        );
    }

    #[test]
    fn what_the_link_heard_before_the_takeover_does_not_override_the_holders_word() {
        use aeris_mavlink::dialect::{EXTENDED_SYS_STATE_DATA, LOCAL_POSITION_NED_DATA};
        let position = |z: f32| {
            MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms: 1,
                x: 0.0,
                y: 0.0,
                z,
                vx: 0.0,
                vy: 0.0,
                vz: 0.0,
            })
        };
        // this controller held the lease at take-off and heard the vehicle leave the pad
        let mut link = AutopilotState::default();
        link.apply(&position(-0.006), 5, Autopilot::Px4);
        link.apply(
            &MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                vtol_state: Default::default(),
                landed_state: MavLandedState::MAV_LANDED_STATE_ON_GROUND,
            }),
            5,
            Autopilot::Px4,
        );
        // the other controller flew it to 12 m since, and this one takes over at 100
        let holder = AutopilotState::from_telemetry(&VehicleTelemetry {
            stamp_ns: 90,
            link_up: 1,
            armed: 1,
            offboard: 1,
            landed: 0,
            position: [0.0, 0.0, 12.0],
            ..Default::default()
        });
        let view = link.or_else(&holder, 100).vehicle_view(0.0);
        assert_eq!(view.position, Some([0.0, 0.0, 12.0]));
        assert!(
            !view.landed,
            "the pad is where the vehicle was, not where it is"
        );
        // what the link hears in the new term is its own word again
        link.apply(&position(-11.9), 110, Autopilot::Px4);
        let view = link.or_else(&holder, 100).vehicle_view(0.0);
        assert_eq!(view.position, Some([0.0, 0.0, 11.9]));
    }
}
