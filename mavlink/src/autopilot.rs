//! Autopilot flavours: what differs between autopilot firmwares on one dialect. The
//! controller's autopilot sequencer asks its [`Autopilot`] how to command offboard flight
//! and how to read it back from a heartbeat; every firmware-specific number lives behind
//! this type (PX4's in [`crate::px4`]).

use crate::dialect::{HEARTBEAT_DATA, MavModeFlag};
use crate::px4::{PX4_MAIN_MODE_OFFBOARD, px4_main_mode};

/// The firmware on the other end of a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Autopilot {
    /// PX4 (and the built-in simulated vehicle, which behaves like it): offboard is main
    /// mode 6 of a custom mode.
    #[default]
    Px4,
}

impl Autopilot {
    /// `param1..=param3` of the MAV_CMD_DO_SET_MODE that puts this autopilot in the mode
    /// that flies a companion computer's setpoints (PX4: offboard).
    pub fn offboard_set_mode_params(self) -> [f32; 3] {
        match self {
            Autopilot::Px4 => [
                f32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits()),
                f32::from(PX4_MAIN_MODE_OFFBOARD),
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{MavAutopilot, MavState, MavType};
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
}
