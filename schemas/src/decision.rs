//! The decision D_t (reasoning -> hub -> controller), MISSION §3.

use crate::{MAX_SUBGOALS, all_finite};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Action mode a_t: a fixed set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ActionMode {
    /// Climb vertically, at the current north/east, to the altitude h_t.
    Takeoff = 1,
    /// Fly to waypoint g_t at altitude h_t.
    Goto = 2,
    /// Hold the current position.
    Hover = 3,
    /// Rotate in place to yaw psi_t.
    Turn = 4,
    /// Climb to h_t in place.
    Ascend = 5,
    /// Descend to h_t in place.
    Descend = 6,
    /// Land at the horizontal position of g_t.
    Land = 7,
    /// Stop: hold position, mission over.
    Stop = 8,
}

impl ActionMode {
    /// Every mode, in wire order.
    pub const ALL: [ActionMode; 8] = [
        ActionMode::Takeoff,
        ActionMode::Goto,
        ActionMode::Hover,
        ActionMode::Turn,
        ActionMode::Ascend,
        ActionMode::Descend,
        ActionMode::Land,
        ActionMode::Stop,
    ];

    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        Self::ALL.iter().copied().find(|m| *m as u8 == v)
    }

    /// Lower-case name as used in workflow files and JSON.
    pub fn name(self) -> &'static str {
        match self {
            ActionMode::Takeoff => "takeoff",
            ActionMode::Goto => "goto",
            ActionMode::Hover => "hover",
            ActionMode::Turn => "turn",
            ActionMode::Ascend => "ascend",
            ActionMode::Descend => "descend",
            ActionMode::Land => "land",
            ActionMode::Stop => "stop",
        }
    }

    /// Parse a lower-case name.
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|m| m.name() == s)
    }
}

/// The decision D_t, exactly the fields of MISSION §3 plus routing metadata.
///
/// `action` is a raw byte on purpose: a decision comes from another process (possibly a
/// language model) and must be validated, never transmuted into an enum.
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::Decision@s8")]
#[repr(C)]
pub struct Decision {
    /// Publisher sequence number (monotone per publisher, starting at 1).
    pub seq: u64,
    /// Semantic cycle this decision belongs to.
    pub cycle: u64,
    /// CLOCK_MONOTONIC ns at which the cycle started (capture of the frame behind S_t).
    pub cycle_start_ns: u64,
    /// CLOCK_MONOTONIC ns at which perception published the S_t used.
    pub state_stamp_ns: u64,
    /// CLOCK_MONOTONIC ns at which the reasoner started its work on S_t.
    pub reasoning_start_ns: u64,
    /// CLOCK_MONOTONIC ns at which the decision was published.
    pub publish_ns: u64,
    /// Waypoint g_t `[N, E, U]` in metres.
    pub target: [f32; 3],
    /// Target yaw psi_t in radians, [-pi, pi], 0 = north, positive clockwise (to east).
    pub yaw: f32,
    /// Target speed v_t in m/s, [0, v_max].
    pub speed: f32,
    /// Target altitude h_t in metres (up), [h_min, h_max].
    pub altitude: f32,
    /// Acceptance radius r_t in metres, [0, r_max].
    pub acceptance_radius: f32,
    /// Confidence gamma_t in [0, 1].
    pub confidence: f32,
    /// Active instruction step s-hat_t, 1-based, 1 <= s <= L.
    pub step: u16,
    /// Action mode a_t as [`ActionMode`] wire byte.
    pub action: u8,
    /// Reserved, zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: u8,
    /// Instance number of the publishing process, given by the supervisor at every spawn
    /// (0 outside a supervised flight). A newer instance of the reasoning role (restart or
    /// hot swap) has a higher number: the hub switches to it and ignores the older one.
    pub source: u32,
}

impl Default for Decision {
    fn default() -> Self {
        Self {
            seq: 0,
            cycle: 0,
            cycle_start_ns: 0,
            state_stamp_ns: 0,
            reasoning_start_ns: 0,
            publish_ns: 0,
            target: [0.0; 3],
            yaw: 0.0,
            speed: 0.0,
            altitude: 0.0,
            acceptance_radius: 0.0,
            confidence: 0.0,
            step: 1,
            action: ActionMode::Hover as u8,
            reserved: 0,
            source: 0,
        }
    }
}

/// A decision moves the vehicle horizontally when its target lies farther than this (m)
/// from the vehicle: without occupancy, such a move is flown at the conservative altitude
/// only ([`DecisionLimits::blind_altitude`]).
pub const BLIND_MOVE_M: f32 = 2.0;
/// Without occupancy, the vehicle may move horizontally once within this (m) below the
/// conservative altitude (a tracker settles a hair short of its setpoint).
pub const BLIND_CLIMB_SLACK_M: f32 = 1.0;

/// The hard limits of a flight (MISSION §3 ranges): the bounds Valid(D_t) checks decisions
/// against, and what the hub's gate keeps them inside.
///
/// It is also the workflow's `[mission.limits]` table (with this crate's `serde` feature):
/// every field but `subgoals` comes from the file, with the defaults of [`Default`];
/// `subgoals` is the mission's subgoal count, set where the mission is known (the runtime's
/// `MissionSpec::decision_limits`), never read from a file.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct DecisionLimits {
    /// Maximum speed v_max (m/s).
    pub v_max: f32,
    /// Minimum altitude h_min (m).
    pub h_min: f32,
    /// Maximum altitude h_max (m).
    pub h_max: f32,
    /// Maximum acceptance radius r_max (m).
    pub r_max: f32,
    /// Geofence lower corner `[N, E, U]`.
    pub geofence_min: [f32; 3],
    /// Geofence upper corner `[N, E, U]`.
    pub geofence_max: [f32; 3],
    /// Clearance kept from obstacles by the hub's clamp (m).
    pub obstacle_clearance_m: f32,
    /// Number of subgoals L (1..=MAX_SUBGOALS).
    #[cfg_attr(feature = "serde", serde(skip))]
    pub subgoals: u16,
}

impl Default for DecisionLimits {
    /// The limits of a workflow that gives none: 8 m/s, 0-60 m, 10 m acceptance radius, a
    /// 400 m square geofence up to 60 m, 3 m obstacle clearance; one subgoal.
    fn default() -> Self {
        Self {
            v_max: 8.0,
            h_min: 0.0,
            h_max: 60.0,
            r_max: 10.0,
            geofence_min: [-200.0, -200.0, 0.0],
            geofence_max: [200.0, 200.0, 60.0],
            obstacle_clearance_m: 3.0,
            subgoals: 1,
        }
    }
}

impl DecisionLimits {
    /// `true` when the limits themselves are coherent (finite, ordered, non-empty).
    pub fn is_coherent(&self) -> bool {
        all_finite(&[self.v_max, self.h_min, self.h_max, self.r_max])
            && all_finite(&self.geofence_min)
            && all_finite(&self.geofence_max)
            && self.v_max > 0.0
            && self.h_min <= self.h_max
            && self.r_max >= 0.0
            && (0..3).all(|i| self.geofence_min[i] <= self.geofence_max[i])
            && self.subgoals >= 1
            && self.subgoals as usize <= MAX_SUBGOALS
    }

    /// The altitude band `[max(h_min, fence_min.U), min(h_max, fence_max.U)]` (may be
    /// empty).
    pub fn altitude_band(&self) -> (f32, f32) {
        (
            self.h_min.max(self.geofence_min[2]),
            self.h_max.min(self.geofence_max[2]),
        )
    }

    /// The conservative altitude flown where no occupancy is present (no depth source, or
    /// a stale one): the top of the altitude band. With no obstacle seen, the only height
    /// the mission vouches for is the highest it allows; a workflow for a camera without
    /// depth lowers it with `h_max` (or the geofence's top). The hub's gate and the planner
    /// both keep to it: horizontal moves at or above it, no descent below it in place
    /// (unless the vehicle is lower already).
    pub fn blind_altitude(&self) -> f32 {
        self.altitude_band().1
    }

    /// `true` when `p` (`[N, E, U]`) lies inside the geofence (bounds inclusive).
    pub fn inside_geofence(&self, p: [f32; 3]) -> bool {
        (0..3).all(|i| p[i] >= self.geofence_min[i] && p[i] <= self.geofence_max[i])
    }
}

/// Why a decision failed Valid(D_t).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DecisionError {
    /// A numeric field is NaN or infinite.
    #[error("field `{field}` is not finite")]
    NonFinite {
        /// Field name.
        field: &'static str,
    },
    /// A numeric field is outside its range.
    #[error("field `{field}` = {value} is outside [{min}, {max}]")]
    OutOfRange {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: f32,
        /// Lower bound.
        min: f32,
        /// Upper bound.
        max: f32,
    },
    /// The waypoint lies outside the geofence.
    #[error("waypoint {target:?} is outside the geofence")]
    OutsideGeofence {
        /// Offending waypoint.
        target: [f32; 3],
    },
    /// The action byte is not an [`ActionMode`].
    #[error("unknown action mode {0}")]
    UnknownAction(u8),
    /// The step is 0 or beyond the number of subgoals.
    #[error("step {step} is outside 1..={subgoals}")]
    StepOutOfRange {
        /// Offending step.
        step: u16,
        /// Number of subgoals L.
        subgoals: u16,
    },
    /// The limits given to the validator are themselves incoherent.
    #[error("decision limits are incoherent")]
    IncoherentLimits,
}

impl Decision {
    /// Valid(D_t): presence, types and ranges, deterministically. NaN and inf are invalid.
    pub fn validate(&self, limits: &DecisionLimits) -> Result<ActionMode, DecisionError> {
        if !limits.is_coherent() {
            return Err(DecisionError::IncoherentLimits);
        }
        let action =
            ActionMode::from_u8(self.action).ok_or(DecisionError::UnknownAction(self.action))?;
        for (field, v) in [
            ("target.n", self.target[0]),
            ("target.e", self.target[1]),
            ("target.u", self.target[2]),
            ("yaw", self.yaw),
            ("speed", self.speed),
            ("altitude", self.altitude),
            ("acceptance_radius", self.acceptance_radius),
            ("confidence", self.confidence),
        ] {
            if !v.is_finite() {
                return Err(DecisionError::NonFinite { field });
            }
        }
        let pi = core::f32::consts::PI;
        for (field, value, min, max) in [
            ("yaw", self.yaw, -pi, pi),
            ("speed", self.speed, 0.0, limits.v_max),
            ("altitude", self.altitude, limits.h_min, limits.h_max),
            (
                "acceptance_radius",
                self.acceptance_radius,
                0.0,
                limits.r_max,
            ),
            ("confidence", self.confidence, 0.0, 1.0),
        ] {
            if !(value >= min && value <= max) {
                return Err(DecisionError::OutOfRange {
                    field,
                    value,
                    min,
                    max,
                });
            }
        }
        if !limits.inside_geofence(self.target) {
            return Err(DecisionError::OutsideGeofence {
                target: self.target,
            });
        }
        if self.step == 0 || self.step > limits.subgoals {
            return Err(DecisionError::StepOutOfRange {
                step: self.step,
                subgoals: limits.subgoals,
            });
        }
        Ok(action)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn limits() -> DecisionLimits {
        DecisionLimits {
            v_max: 8.0,
            h_min: 0.0,
            h_max: 60.0,
            r_max: 10.0,
            geofence_min: [-100.0, -100.0, 0.0],
            geofence_max: [100.0, 100.0, 60.0],
            obstacle_clearance_m: 3.0,
            subgoals: 4,
        }
    }

    fn good() -> Decision {
        Decision {
            target: [10.0, 5.0, 10.0],
            yaw: 0.5,
            speed: 4.0,
            altitude: 10.0,
            acceptance_radius: 2.0,
            confidence: 0.9,
            step: 2,
            action: ActionMode::Goto as u8,
            ..Decision::default()
        }
    }

    #[test]
    fn accepts_a_good_decision() {
        assert_eq!(good().validate(&limits()), Ok(ActionMode::Goto));
    }

    #[test]
    fn rejects_each_bad_field() {
        let l = limits();
        type Case = (fn(&mut Decision), &'static str);
        let cases: [Case; 9] = [
            (|d| d.speed = f32::NAN, "nan speed"),
            (|d| d.target[1] = f32::INFINITY, "inf target"),
            (|d| d.speed = 9.0, "speed"),
            (|d| d.yaw = 3.2, "yaw"),
            (|d| d.altitude = 61.0, "alt"),
            (|d| d.acceptance_radius = -0.1, "radius"),
            (|d| d.confidence = 1.01, "confidence"),
            (|d| d.step = 0, "step 0"),
            (|d| d.action = 200, "action"),
        ];
        for (mutate, what) in cases {
            let mut d = good();
            mutate(&mut d);
            assert!(d.validate(&l).is_err(), "{what} should be rejected");
        }
        let mut d = good();
        d.target = [150.0, 0.0, 10.0];
        assert!(matches!(
            d.validate(&l),
            Err(DecisionError::OutsideGeofence { .. })
        ));
        d = good();
        d.step = 5;
        assert!(matches!(
            d.validate(&l),
            Err(DecisionError::StepOutOfRange { .. })
        ));
    }

    #[test]
    fn action_names_round_trip() {
        for m in ActionMode::ALL {
            assert_eq!(ActionMode::from_name(m.name()), Some(m));
            assert_eq!(ActionMode::from_u8(m as u8), Some(m));
        }
        assert_eq!(ActionMode::from_u8(0), None);
    }
}
