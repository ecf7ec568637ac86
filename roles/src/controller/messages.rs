//! What the controller writes to the autopilot: its MAVLink identity (system 1, component
//! `MAV_COMP_ID_ONBOARD_COMPUTER`) and the messages: SET_POSITION_TARGET_LOCAL_NED (the
//! only place the controller's `[N, E, U]` becomes NED), its HEARTBEAT and COMMAND_LONG,
//! each addressed to the [`Target`] the autopilot's HEARTBEAT named
//! ([`super::link_watch`]).

use super::tracker::TrackCommand;
use aeris_mavlink::MavHeader;
use aeris_mavlink::dialect::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavAutopilot, MavCmd, MavComponent, MavFrame, MavMessage,
    MavModeFlag, MavState, MavType, PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use aeris_mavlink::neu_to_ned;

/// Our MAVLink system id.
pub const COMPANION_SYSTEM_ID: u8 = 1;
/// Our MAVLink component id (`MAV_COMP_ID_ONBOARD_COMPUTER`).
pub const COMPANION_COMPONENT_ID: u8 = MavComponent::MAV_COMP_ID_ONBOARD_COMPUTER as u8;

/// Whom a message is for: the autopilot's system and component id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Target {
    /// MAVLink system id (0: every system).
    pub system_id: u8,
    /// MAVLink component id (0: every component).
    pub component_id: u8,
}

impl Target {
    /// Every system and component: what is addressed before the autopilot's HEARTBEAT
    /// named it (setpoints stream from the start; commands wait for the heartbeat).
    pub const BROADCAST: Target = Target {
        system_id: 0,
        component_id: 0,
    };
}

/// The header of everything the controller sends (the link fills in the sequence).
pub fn companion_header() -> MavHeader {
    MavHeader {
        system_id: u32::from(COMPANION_SYSTEM_ID),
        component_id: COMPANION_COMPONENT_ID,
        sequence: 0,
    }
}

/// The `type_mask` the controller sends: position, velocity and yaw used; acceleration and
/// yaw rate ignored.
pub fn position_velocity_yaw_mask() -> PositionTargetTypemask {
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE
        | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
}

/// The SET_POSITION_TARGET_LOCAL_NED for `cmd` (the only place `[N, E, U]` becomes NED).
pub fn position_target_message(cmd: &TrackCommand, time_boot_ms: u32, to: Target) -> MavMessage {
    let p = neu_to_ned(cmd.position);
    let v = neu_to_ned(cmd.velocity);
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms,
        x: p[0],
        y: p[1],
        z: p[2],
        vx: v[0],
        vy: v[1],
        vz: v[2],
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: cmd.yaw,
        yaw_rate: 0.0,
        type_mask: position_velocity_yaw_mask(),
        target_system: to.system_id,
        target_component: to.component_id,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    })
}

/// The controller's HEARTBEAT (`MAV_TYPE_ONBOARD_CONTROLLER`, `MAV_AUTOPILOT_INVALID`).
pub fn companion_heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// A COMMAND_LONG to `to` with `params` as `param1..=param7`.
pub fn command_long(command: MavCmd, params: [f32; 7], confirmation: u8, to: Target) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        param5: params[4],
        param6: params[5],
        param7: params[6],
        command,
        target_system: to.system_id,
        target_component: to.component_id,
        confirmation,
    })
}

/// `param1..=param7` of a command that takes three (the rest 0).
pub fn three_params(p: [f32; 3]) -> [f32; 7] {
    [p[0], p[1], p[2], 0.0, 0.0, 0.0, 0.0]
}

/// `param1..=param7` of `MAV_CMD_NAV_TAKEOFF` to `height_m` above home (`param7`); the
/// yaw (`param4`) NaN: keep the current heading.
pub fn takeoff_params(height_m: f32) -> [f32; 7] {
    [0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, height_m]
}
