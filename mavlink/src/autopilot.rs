//! Autopilot flavours: what differs between autopilot firmwares on one dialect. The
//! controller's autopilot sequencer asks its [`Autopilot`] how to command offboard flight
//! and how to read it back from a heartbeat; every firmware-specific number lives behind
//! this type (PX4's in [`crate::px4`], ArduPilot's in [`crate::ardupilot`]).

use crate::ardupilot::{COPTER_MODE_GUIDED, COPTER_MODE_LAND};
use crate::dialect::{HEARTBEAT_DATA, MavAutopilot, MavModeFlag, MavType};
use crate::px4::{PX4_MAIN_MODE_OFFBOARD, px4_main_mode};

/// The firmware on the other end of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Autopilot {
    /// PX4 (and the built-in simulated vehicle by default): offboard is main mode 6 of a
    /// custom mode; it takes off and lands on position targets.
    #[default]
    Px4,
    /// ArduPilot Copter: guided is custom mode 4; position targets are flown only after a
    /// `MAV_CMD_NAV_TAKEOFF`; it lands in its land mode (custom mode 9).
    ArduPilotCopter,
}

impl Autopilot {
    /// The firmware a HEARTBEAT announces, if it is an autopilot the controller can fly:
    /// `MAV_AUTOPILOT_PX4` or `MAV_AUTOPILOT_ARDUPILOTMEGA` on a vehicle type. A ground
    /// station, a companion computer, a gimbal or a camera (whatever their `autopilot`
    /// field says) and every other firmware are `None`.
    pub fn from_heartbeat(heartbeat: &HEARTBEAT_DATA) -> Option<Self> {
        if matches!(
            heartbeat.mavtype,
            MavType::MAV_TYPE_GCS
                | MavType::MAV_TYPE_ONBOARD_CONTROLLER
                | MavType::MAV_TYPE_GIMBAL
                | MavType::MAV_TYPE_CAMERA
                | MavType::MAV_TYPE_ADSB
                | MavType::MAV_TYPE_ANTENNA_TRACKER
                | MavType::MAV_TYPE_SERVO
                | MavType::MAV_TYPE_BATTERY
                | MavType::MAV_TYPE_GENERIC
        ) {
            return None;
        }
        match heartbeat.autopilot {
            MavAutopilot::MAV_AUTOPILOT_PX4 => Some(Autopilot::Px4),
            MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA => Some(Autopilot::ArduPilotCopter),
            _ => None,
        }
    }

    /// The firmware's name.
    pub fn name(self) -> &'static str {
        match self {
            Autopilot::Px4 => "PX4",
            Autopilot::ArduPilotCopter => "ArduPilot Copter",
        }
    }

    /// Whether the vehicle must be sent `MAV_CMD_NAV_TAKEOFF` before it flies position
    /// targets from the ground (ArduPilot: yes; PX4 climbs on the targets).
    pub fn needs_takeoff_command(self) -> bool {
        matches!(self, Autopilot::ArduPilotCopter)
    }

    /// `param1..=param3` of the MAV_CMD_DO_SET_MODE into the firmware's own landing mode,
    /// when the controller lands with it (ArduPilot); `None` when the vehicle lands on
    /// position targets (PX4).
    pub fn land_set_mode_params(self) -> Option<[f32; 3]> {
        match self {
            Autopilot::Px4 => None,
            Autopilot::ArduPilotCopter => Some([
                f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits()),
                COPTER_MODE_LAND as f32,
                0.0,
            ]),
        }
    }

    /// Whether `heartbeat` reports the firmware's own landing mode.
    pub fn reports_landing_mode(self, heartbeat: &HEARTBEAT_DATA) -> bool {
        match self {
            Autopilot::Px4 => false,
            Autopilot::ArduPilotCopter => {
                heartbeat
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                    && heartbeat.custom_mode == COPTER_MODE_LAND
            }
        }
    }

    /// `param1..=param3` of the MAV_CMD_DO_SET_MODE that puts this autopilot in the mode
    /// that flies a companion computer's setpoints (PX4: offboard).
    pub fn offboard_set_mode_params(self) -> [f32; 3] {
        match self {
            Autopilot::Px4 => [
                f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits()),
                f32::from(PX4_MAIN_MODE_OFFBOARD),
                0.0,
            ],
            Autopilot::ArduPilotCopter => [
                f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits()),
                COPTER_MODE_GUIDED as f32,
                0.0,
            ],
        }
    }

    /// Whether `heartbeat` from this autopilot reports the mode that flies a companion
    /// computer's setpoints.
    pub fn reports_offboard(self, heartbeat: &HEARTBEAT_DATA) -> bool {
        match self {
            Autopilot::Px4 => {
                heartbeat
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                    && px4_main_mode(heartbeat.custom_mode) == PX4_MAIN_MODE_OFFBOARD
            }
            Autopilot::ArduPilotCopter => {
                heartbeat
                    .base_mode
                    .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
                    && heartbeat.custom_mode == COPTER_MODE_GUIDED
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::MavState;
    use crate::px4::{PX4_AUTO_SUB_MODE_LOITER, PX4_MAIN_MODE_AUTO, px4_custom_mode};

    fn heartbeat(base_mode: MavModeFlag, custom_mode: u32) -> HEARTBEAT_DATA {
        HEARTBEAT_DATA {
            custom_mode,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode,
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }
    }

    #[test]
    fn px4_offboard_is_main_mode_6_of_a_custom_mode_both_ways() {
        let px4 = Autopilot::Px4;
        let [custom, main, sub] = px4.offboard_set_mode_params();
        assert_eq!((custom, main, sub), (1.0, 6.0, 0.0));
        let custom_flag = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        let offboard = px4_custom_mode(PX4_MAIN_MODE_OFFBOARD, 0);
        assert!(px4.reports_offboard(&heartbeat(custom_flag, offboard)));
        // the same number without the custom-mode flag means nothing
        assert!(!px4.reports_offboard(&heartbeat(MavModeFlag::empty(), offboard)));
        let hold = px4_custom_mode(PX4_MAIN_MODE_AUTO, PX4_AUTO_SUB_MODE_LOITER);
        assert!(!px4.reports_offboard(&heartbeat(custom_flag, hold)));
    }

    #[test]
    fn ardupilot_guided_is_custom_mode_4_and_land_is_9() {
        let ap = Autopilot::ArduPilotCopter;
        assert_eq!(ap.offboard_set_mode_params(), [1.0, 4.0, 0.0]);
        assert_eq!(ap.land_set_mode_params(), Some([1.0, 9.0, 0.0]));
        let custom_flag = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
        assert!(ap.reports_offboard(&heartbeat(custom_flag, COPTER_MODE_GUIDED)));
        assert!(!ap.reports_offboard(&heartbeat(custom_flag, COPTER_MODE_LAND)));
        assert!(ap.reports_landing_mode(&heartbeat(custom_flag, COPTER_MODE_LAND)));
        // PX4's offboard number means nothing to ArduPilot, and the other way round
        assert!(!ap.reports_offboard(&heartbeat(custom_flag, 6 << 16)));
        assert!(!Autopilot::Px4.reports_offboard(&heartbeat(custom_flag, COPTER_MODE_GUIDED)));
        assert!(ap.needs_takeoff_command() && !Autopilot::Px4.needs_takeoff_command());
    }

    #[test]
    fn only_vehicles_of_px4_or_ardupilot_are_autopilots() {
        let mut hb = heartbeat(MavModeFlag::empty(), 0);
        assert_eq!(Autopilot::from_heartbeat(&hb), Some(Autopilot::Px4));
        hb.autopilot = MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA;
        assert_eq!(
            Autopilot::from_heartbeat(&hb),
            Some(Autopilot::ArduPilotCopter)
        );
        // a ground station or a companion is no autopilot, whatever it claims
        for t in [MavType::MAV_TYPE_GCS, MavType::MAV_TYPE_ONBOARD_CONTROLLER] {
            assert_eq!(
                Autopilot::from_heartbeat(&HEARTBEAT_DATA { mavtype: t, ..hb }),
                None
            );
        }
        for a in [
            MavAutopilot::MAV_AUTOPILOT_INVALID,
            MavAutopilot::MAV_AUTOPILOT_GENERIC,
        ] {
            assert_eq!(
                Autopilot::from_heartbeat(&HEARTBEAT_DATA { autopilot: a, ..hb }),
                None
            );
        }
    }
}
