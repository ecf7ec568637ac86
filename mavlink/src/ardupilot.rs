//! ArduPilot Copter's flight-mode numbers: a HEARTBEAT's `custom_mode` is the mode number
//! itself; MAV_CMD_DO_SET_MODE takes it as `param2` (with `param1` =
//! `MAV_MODE_FLAG_CUSTOM_MODE_ENABLED`).

/// Copter mode "stabilize" (manual; where a Copter boots).
pub const COPTER_MODE_STABILIZE: u32 = 0;
/// Copter mode "guided": fly a companion computer's position targets (after a take-off).
pub const COPTER_MODE_GUIDED: u32 = 4;
/// Copter mode "loiter" (hold).
pub const COPTER_MODE_LOITER: u32 = 5;
/// Copter mode "RTL" (return to launch).
pub const COPTER_MODE_RTL: u32 = 6;
/// Copter mode "land": descend where it is and disarm on the ground.
pub const COPTER_MODE_LAND: u32 = 9;
