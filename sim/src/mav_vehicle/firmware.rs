//! Which autopilot the simulated vehicle plays: what its HEARTBEAT says and how it reads a
//! mode change. PX4 (the default): offboard is main mode 6, it climbs on position targets.
//! ArduPilot Copter: guided is custom mode 4 and, armed on the ground, it flies position
//! targets only after `MAV_CMD_NAV_TAKEOFF`; land is mode 9; it keeps its last target when
//! the stream stops (no offboard-loss failsafe).

use super::FlightMode;
use aeris_mavlink::ardupilot::{
    COPTER_MODE_GUIDED, COPTER_MODE_LAND, COPTER_MODE_LOITER, COPTER_MODE_STABILIZE,
};
use aeris_mavlink::dialect::MavAutopilot;
use aeris_mavlink::px4::{
    PX4_AUTO_SUB_MODE_LAND, PX4_AUTO_SUB_MODE_LOITER, PX4_MAIN_MODE_AUTO, PX4_MAIN_MODE_OFFBOARD,
    PX4_MAIN_MODE_POSCTL, px4_custom_mode,
};

/// The firmware the simulated vehicle plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SimFirmware {
    /// PX4 (offboard).
    #[default]
    Px4,
    /// ArduPilot Copter (guided, take-off command).
    ArduPilotCopter,
}

/// What a MAV_CMD_DO_SET_MODE asks of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeRequest {
    /// A mode this vehicle has.
    Mode(FlightMode),
    /// A mode it does not have.
    Unsupported,
}

impl SimFirmware {
    /// The firmware named `name` (`px4` or `ardupilot`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "px4" => Some(SimFirmware::Px4),
            "ardupilot" => Some(SimFirmware::ArduPilotCopter),
            _ => None,
        }
    }

    /// The HEARTBEAT's `autopilot` field.
    pub fn mav_autopilot(self) -> MavAutopilot {
        match self {
            SimFirmware::Px4 => MavAutopilot::MAV_AUTOPILOT_PX4,
            SimFirmware::ArduPilotCopter => MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        }
    }

    /// The HEARTBEAT's `custom_mode` for `mode`.
    pub fn custom_mode(self, mode: FlightMode) -> u32 {
        match (self, mode) {
            (SimFirmware::Px4, FlightMode::Position) => px4_custom_mode(PX4_MAIN_MODE_POSCTL, 0),
            (SimFirmware::Px4, FlightMode::Hold) => {
                px4_custom_mode(PX4_MAIN_MODE_AUTO, PX4_AUTO_SUB_MODE_LOITER)
            }
            (SimFirmware::Px4, FlightMode::Offboard) => px4_custom_mode(PX4_MAIN_MODE_OFFBOARD, 0),
            (SimFirmware::Px4, FlightMode::Land) => {
                px4_custom_mode(PX4_MAIN_MODE_AUTO, PX4_AUTO_SUB_MODE_LAND)
            }
            (SimFirmware::ArduPilotCopter, FlightMode::Position) => COPTER_MODE_STABILIZE,
            (SimFirmware::ArduPilotCopter, FlightMode::Hold) => COPTER_MODE_LOITER,
            (SimFirmware::ArduPilotCopter, FlightMode::Offboard) => COPTER_MODE_GUIDED,
            (SimFirmware::ArduPilotCopter, FlightMode::Land) => COPTER_MODE_LAND,
        }
    }

    /// The mode `param2`/`param3` of a custom-mode MAV_CMD_DO_SET_MODE name.
    pub fn mode_request(self, param2: f32, param3: f32) -> ModeRequest {
        let (main, sub) = (param2.round(), param3.round());
        let mode = match self {
            SimFirmware::Px4 => {
                if main == f32::from(PX4_MAIN_MODE_OFFBOARD) {
                    Some(FlightMode::Offboard)
                } else if main == f32::from(PX4_MAIN_MODE_POSCTL) {
                    Some(FlightMode::Position)
                } else if main == f32::from(PX4_MAIN_MODE_AUTO)
                    && sub == f32::from(PX4_AUTO_SUB_MODE_LOITER)
                {
                    Some(FlightMode::Hold)
                } else if main == f32::from(PX4_MAIN_MODE_AUTO)
                    && sub == f32::from(PX4_AUTO_SUB_MODE_LAND)
                {
                    Some(FlightMode::Land)
                } else {
                    None
                }
            }
            SimFirmware::ArduPilotCopter => [
                FlightMode::Position,
                FlightMode::Hold,
                FlightMode::Offboard,
                FlightMode::Land,
            ]
            .into_iter()
            .find(|m| main == self.custom_mode(*m) as f32),
        };
        mode.map_or(ModeRequest::Unsupported, ModeRequest::Mode)
    }

    /// Offboard needs a live setpoint stream to be entered, and is left for hold when the
    /// stream stops (PX4); ArduPilot's guided keeps the last target.
    pub fn offboard_needs_stream(self) -> bool {
        self == SimFirmware::Px4
    }

    /// Position targets are flown from the ground only after `MAV_CMD_NAV_TAKEOFF`.
    pub fn needs_takeoff_command(self) -> bool {
        self == SimFirmware::ArduPilotCopter
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_firmware_reads_back_its_own_mode_numbers() {
        for fw in [SimFirmware::Px4, SimFirmware::ArduPilotCopter] {
            for m in [
                FlightMode::Position,
                FlightMode::Hold,
                FlightMode::Offboard,
                FlightMode::Land,
            ] {
                let c = fw.custom_mode(m);
                let (p2, p3) = match fw {
                    SimFirmware::Px4 => (((c >> 16) & 0xff) as f32, (c >> 24) as f32),
                    SimFirmware::ArduPilotCopter => (c as f32, 0.0),
                };
                assert_eq!(
                    fw.mode_request(p2, p3),
                    ModeRequest::Mode(m),
                    "{fw:?} {m:?}"
                );
            }
        }
        assert_eq!(
            SimFirmware::ArduPilotCopter.custom_mode(FlightMode::Offboard),
            4
        );
        assert_eq!(
            SimFirmware::ArduPilotCopter.custom_mode(FlightMode::Land),
            9
        );
        assert_eq!(
            SimFirmware::ArduPilotCopter.mode_request(6.0, 0.0),
            ModeRequest::Unsupported,
            "RTL is not simulated"
        );
    }
}
