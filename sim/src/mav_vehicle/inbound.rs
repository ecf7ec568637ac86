//! What the simulated vehicle does with what arrives on its link: a COMMAND_LONG (arm,
//! disarm, mode changes in the firmware's numbers, take-off and land), answered with a
//! COMMAND_ACK; a SET_POSITION_TARGET_LOCAL_NED, checked (frame, type mask, finite numbers,
//! the fence) and kept as the offboard command.

use super::{FlightMode, ModeRequest, SimVehicle};
use crate::multirotor::{Command, GROUND_U};
use aeris_mavlink::dialect::{
    COMMAND_ACK_DATA, COMMAND_LONG_DATA, MavCmd, MavFrame, MavMessage, MavModeFlag, MavResult,
    PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use aeris_mavlink::ned_to_neu;
use aeris_mavlink::px4::FORCE_ARM_DISARM_MAGIC;

impl SimVehicle {
    pub(super) fn handle_command(&mut self, c: &COMMAND_LONG_DATA) {
        self.stats.commands += 1;
        let landed = self.model.state().landed;
        let result = match c.command {
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM => {
                if c.param1 > 0.5 {
                    if !self.model.state().armed {
                        self.model.set_armed(true);
                        self.airborne_seen = !landed;
                        self.landed_since_s = None;
                        if self.mode != FlightMode::Offboard {
                            self.set_mode(self.mode);
                        }
                    }
                    MavResult::MAV_RESULT_ACCEPTED
                } else if landed || c.param2 == FORCE_ARM_DISARM_MAGIC {
                    self.model.set_armed(false);
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_DENIED
                }
            }
            MavCmd::MAV_CMD_DO_SET_MODE => {
                let custom_bit = u32::from(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED.bits());
                let custom = (c.param1 as u32 & custom_bit) != 0;
                let firmware = self.config.firmware;
                match firmware.mode_request(c.param2, c.param3) {
                    _ if !custom => MavResult::MAV_RESULT_UNSUPPORTED,
                    ModeRequest::Mode(FlightMode::Offboard)
                        if firmware.offboard_needs_stream() && !self.setpoints_fresh() =>
                    {
                        MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                    }
                    ModeRequest::Mode(mode) => {
                        self.set_mode(mode);
                        MavResult::MAV_RESULT_ACCEPTED
                    }
                    ModeRequest::Unsupported => MavResult::MAV_RESULT_UNSUPPORTED,
                }
            }
            MavCmd::MAV_CMD_NAV_TAKEOFF if self.config.firmware.needs_takeoff_command() => {
                let s = *self.model.state();
                let height = c.param7;
                if !(s.armed && self.mode == FlightMode::Offboard) {
                    MavResult::MAV_RESULT_TEMPORARILY_REJECTED
                } else if !(height.is_finite() && height > 0.0) {
                    MavResult::MAV_RESULT_DENIED
                } else {
                    // climb where it stands to the height above the ground; targets after
                    // this are flown
                    self.took_off = true;
                    self.offboard_cmd = Some(Command::Position {
                        position: [s.position[0], s.position[1], GROUND_U + height],
                        velocity_ff: None,
                        yaw: Some(s.yaw),
                        yaw_rate: None,
                    });
                    MavResult::MAV_RESULT_ACCEPTED
                }
            }
            MavCmd::MAV_CMD_NAV_LAND => {
                if self.model.state().armed {
                    self.set_mode(FlightMode::Land);
                    MavResult::MAV_RESULT_ACCEPTED
                } else {
                    MavResult::MAV_RESULT_DENIED
                }
            }
            _ => MavResult::MAV_RESULT_UNSUPPORTED,
        };
        if result == MavResult::MAV_RESULT_ACCEPTED {
            self.stats.commands_accepted += 1;
        }
        self.send(&MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: c.command,
            result,
        }));
    }

    /// `at`: when it arrived (s, on the arrival timeline of [`SimVehicle`]).
    pub(super) fn handle_setpoint(&mut self, s: &SET_POSITION_TARGET_LOCAL_NED_DATA, at: f64) {
        if s.coordinate_frame != MavFrame::MAV_FRAME_LOCAL_NED {
            self.stats.setpoints_rejected += 1;
            return;
        }
        let m = s.type_mask;
        let pos_used = !m.intersects(
            PositionTargetTypemask::POSITION_TARGET_TYPEMASK_X_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Y_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE,
        );
        let vel_used = !m.intersects(
            PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE
                | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE,
        );
        let yaw = (!m.contains(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_IGNORE))
            .then_some(s.yaw);
        let yaw_rate = (!m
            .contains(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE))
        .then_some(s.yaw_rate);
        let velocity = ned_to_neu([s.vx, s.vy, s.vz]);
        let position = ned_to_neu([s.x, s.y, s.z]);
        if pos_used && let Some((min, max)) = self.config.fence {
            let p = position;
            let inside =
                (0..3).all(|i| p[i].is_finite() && p[i] >= min[i] - 1e-3 && p[i] <= max[i] + 1e-3);
            if !inside {
                self.stats.setpoints_outside_fence += 1;
            }
        }
        if self.config.firmware.needs_takeoff_command() && !self.took_off {
            // guided on the ground ignores targets until a take-off (counted as usable: the
            // stream is alive)
            self.last_setpoint_s = Some(self.time_s);
            self.last_arrival = Some(at);
            self.stats.setpoints += 1;
            return;
        }
        let cmd = if pos_used {
            Command::Position {
                position,
                velocity_ff: vel_used.then_some(velocity),
                yaw,
                yaw_rate,
            }
        } else if vel_used {
            Command::Velocity {
                velocity,
                yaw,
                yaw_rate,
            }
        } else {
            self.stats.setpoints_rejected += 1;
            return;
        };
        if !cmd.is_finite() {
            self.stats.setpoints_rejected += 1;
            return;
        }
        self.offboard_cmd = Some(cmd);
        self.last_setpoint_s = Some(self.time_s);
        if let (Some(period), Some(last)) = (self.config.setpoint_period_s, self.last_arrival)
            && period > 0.0
        {
            let ticks = (at - last).max(0.0) as f32 / period;
            if ticks > 2.0 {
                self.stats.setpoint_ticks_missed += (ticks.round() as u64).saturating_sub(1);
            }
        }
        self.last_arrival = Some(at);
        self.stats.setpoints += 1;
    }
}
