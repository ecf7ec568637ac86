//! PX4's flight-mode numbers: a HEARTBEAT's `custom_mode` carries the main mode in bits
//! 16..24 and the sub mode in bits 24..32; MAV_CMD_DO_SET_MODE takes them as `param2` and
//! `param3`.

/// PX4 main mode "position control".
pub const PX4_MAIN_MODE_POSCTL: u8 = 3;
/// PX4 main mode "auto" (the sub mode says which).
pub const PX4_MAIN_MODE_AUTO: u8 = 4;
/// PX4 main mode "offboard": fly the companion computer's setpoints.
pub const PX4_MAIN_MODE_OFFBOARD: u8 = 6;
/// PX4 auto sub mode "loiter" (hold).
pub const PX4_AUTO_SUB_MODE_LOITER: u8 = 3;
/// PX4 auto sub mode "land".
pub const PX4_AUTO_SUB_MODE_LAND: u8 = 6;
/// `param2` of `MAV_CMD_COMPONENT_ARM_DISARM` that forces the action (PX4 magic number).
pub const FORCE_ARM_DISARM_MAGIC: f32 = 21196.0;

/// PX4 `custom_mode` of a main and sub mode.
pub fn px4_custom_mode(main: u8, sub: u8) -> u32 {
    (u32::from(main) << 16) | (u32::from(sub) << 24)
}

/// The PX4 main mode inside a HEARTBEAT `custom_mode`.
pub fn px4_main_mode(custom_mode: u32) -> u8 {
    ((custom_mode >> 16) & 0xff) as u8
}

/// The PX4 sub mode inside a HEARTBEAT `custom_mode`.
pub fn px4_sub_mode(custom_mode: u32) -> u8 {
    ((custom_mode >> 24) & 0xff) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px4_mode_bits() {
        let offboard = px4_custom_mode(PX4_MAIN_MODE_OFFBOARD, 0);
        assert_eq!(offboard, 6 << 16);
        assert_eq!(px4_main_mode(offboard), 6);
        let land = px4_custom_mode(PX4_MAIN_MODE_AUTO, PX4_AUTO_SUB_MODE_LAND);
        assert_eq!(px4_main_mode(land), 4);
        assert_eq!(px4_sub_mode(land), 6);
        let hold = px4_custom_mode(PX4_MAIN_MODE_AUTO, PX4_AUTO_SUB_MODE_LOITER);
        assert_eq!(px4_sub_mode(hold), 3);
    }
}
