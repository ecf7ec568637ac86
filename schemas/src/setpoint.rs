//! The bound control setpoint (hub -> controller), annotated with the active step.

use crate::all_finite;
use crate::decision::{ActionMode, DecisionLimits};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// An executable control target produced by the hub's decision gate (`hub/setpoint`).
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::BoundSetpoint@s8")]
#[repr(C)]
pub struct BoundSetpoint {
    /// Publisher sequence number.
    pub seq: u64,
    /// Sequence number of the decision this setpoint was bound from.
    pub decision_seq: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub publish_ns: u64,
    /// Target position `[N, E, U]` (altitude already applied).
    pub position: [f32; 3],
    /// Target yaw (rad), [-pi, pi].
    pub yaw: f32,
    /// Speed limit towards the target (m/s), [0, v_max].
    pub speed: f32,
    /// Acceptance radius (m).
    pub acceptance_radius: f32,
    /// Active instruction step i* (1-based) from ATT.
    pub active_step: u16,
    /// Controller mode as [`ActionMode`] wire byte.
    pub mode: u8,
    /// 1 when bound from a reused (last valid) decision, 0 for a fresh one.
    pub reused: u8,
    /// 1 when the gate clamped the decision to make it feasible.
    pub clamped: u8,
    /// Reserved, zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: [u8; 3],
}

impl Default for BoundSetpoint {
    fn default() -> Self {
        Self {
            seq: 0,
            decision_seq: 0,
            publish_ns: 0,
            position: [0.0; 3],
            yaw: 0.0,
            speed: 0.0,
            acceptance_radius: 0.0,
            active_step: 1,
            mode: ActionMode::Hover as u8,
            reused: 0,
            clamped: 0,
            reserved: [0; 3],
        }
    }
}

/// Why a setpoint must not be flown.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SetpointError {
    /// A number is NaN or infinite.
    #[error("setpoint field `{0}` is not finite")]
    NonFinite(&'static str),
    /// The position is outside the geofence or the altitude band.
    #[error("setpoint position {0:?} is outside the geofence / altitude band")]
    OutOfBounds([f32; 3]),
    /// Speed outside [0, v_max] or yaw outside [-pi, pi].
    #[error("setpoint field `{0}` is out of range")]
    OutOfRange(&'static str),
    /// Unknown mode byte.
    #[error("unknown setpoint mode {0}")]
    UnknownMode(u8),
}

impl BoundSetpoint {
    /// Check the setpoint against the flight's limits; the controller refuses to fly one
    /// that fails.
    pub fn validate(&self, limits: &DecisionLimits) -> Result<ActionMode, SetpointError> {
        let mode = ActionMode::from_u8(self.mode).ok_or(SetpointError::UnknownMode(self.mode))?;
        if !all_finite(&self.position) {
            return Err(SetpointError::NonFinite("position"));
        }
        if !all_finite(&[self.yaw, self.speed, self.acceptance_radius]) {
            return Err(SetpointError::NonFinite("yaw/speed/acceptance_radius"));
        }
        let [n, e, u] = self.position;
        let inside = limits.inside_geofence([n, e, u.max(limits.geofence_min[2])])
            && u <= limits.h_max
            && (u >= limits.h_min
                || matches!(
                    mode,
                    ActionMode::Land | ActionMode::Takeoff | ActionMode::Stop | ActionMode::Hover
                ));
        if !inside {
            return Err(SetpointError::OutOfBounds(self.position));
        }
        if !(self.speed >= 0.0 && self.speed <= limits.v_max) {
            return Err(SetpointError::OutOfRange("speed"));
        }
        let pi = core::f32::consts::PI;
        if !(self.yaw >= -pi && self.yaw <= pi) {
            return Err(SetpointError::OutOfRange("yaw"));
        }
        Ok(mode)
    }
}
