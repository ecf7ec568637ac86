//! Vehicle telemetry (controller -> everyone), read back from the autopilot.

use crate::all_finite;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// What the controller knows about the vehicle (`vehicle/telemetry`).
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::VehicleTelemetry@s8")]
#[repr(C)]
pub struct VehicleTelemetry {
    /// Publisher sequence number.
    pub seq: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub stamp_ns: u64,
    /// Autopilot boot time of the last LOCAL_POSITION_NED (ms).
    pub autopilot_time_ms: u32,
    /// 1 when the autopilot reports armed.
    pub armed: u8,
    /// 1 when the autopilot is in offboard / guided mode.
    pub offboard: u8,
    /// 1 when a HEARTBEAT arrived within the link timeout.
    pub link_up: u8,
    /// 1 when the vehicle is on the ground (landed state).
    pub landed: u8,
    /// Position `[N, E, U]` (m).
    pub position: [f32; 3],
    /// Velocity `[N, E, U]` (m/s).
    pub velocity: [f32; 3],
    /// Roll, pitch, yaw (rad).
    pub attitude: [f32; 3],
    /// Controller ticks so far.
    pub controller_ticks: u64,
    /// Controller ticks whose deadline was missed.
    pub controller_missed_ticks: u64,
    /// Setpoints refused by the controller's own validation.
    pub setpoints_refused: u64,
    /// Ticks spent holding position because no fresh setpoint arrived.
    pub hold_ticks: u64,
}

/// Why telemetry is unusable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum TelemetryError {
    /// A number is NaN or infinite.
    #[error("telemetry field `{0}` is not finite")]
    NonFinite(&'static str),
}

impl VehicleTelemetry {
    /// Deterministic validation.
    pub fn validate(&self) -> Result<(), TelemetryError> {
        if !all_finite(&self.position) {
            return Err(TelemetryError::NonFinite("position"));
        }
        if !all_finite(&self.velocity) {
            return Err(TelemetryError::NonFinite("velocity"));
        }
        if !all_finite(&self.attitude) {
            return Err(TelemetryError::NonFinite("attitude"));
        }
        Ok(())
    }

    /// Horizontal+vertical speed magnitude.
    pub fn speed(&self) -> f32 {
        let [a, b, c] = self.velocity;
        (a * a + b * b + c * c).sqrt()
    }
}
