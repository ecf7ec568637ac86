//! What the hub reports per semantic cycle: the gate's verdict, counters and ATT.

use crate::{MAX_SUBGOALS, OccupancyStatus};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Why the gate clamped a committed decision (bits of [`HubReport::clamp_reasons`]).
pub mod clamp {
    /// h_t was moved into the altitude band.
    pub const ALTITUDE: u32 = 1 << 0;
    /// The vehicle's position was projected into the geofence (in-place actions).
    pub const GEOFENCE: u32 = 1 << 1;
    /// The speed was moved into `[0, v_max]`.
    pub const SPEED: u32 = 1 << 2;
    /// An obstacle of the occupancy grid pulled the target back or raised h_t.
    pub const OBSTACLE: u32 = 1 << 3;
    /// No occupancy was present (absent or stale): h_t was kept at or raised to the
    /// conservative altitude ([`crate::DecisionLimits::blind_altitude`]), or a horizontal
    /// move was held in place until the vehicle climbs there.
    pub const NO_OCCUPANCY: u32 = 1 << 4;
    /// Every reason.
    pub const ALL: u32 = ALTITUDE | GEOFENCE | SPEED | OBSTACLE | NO_OCCUPANCY;
}

/// Declares [`HubCounts`] from its fields' names: the struct, and each count by name.
macro_rules! hub_counts {
    ($($(#[$doc:meta])* $field:ident,)*) => {
        /// What the hub did with the decisions and states it received, counted since the
        /// hub process started: one type for the hub's core, its report, the flight's
        /// summary (totals over every hub process) and the recording.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
        #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
        #[repr(C)]
        pub struct HubCounts {
            $($(#[$doc])* pub $field: u64,)*
        }

        impl HubCounts {
            /// How many counts there are.
            pub const LEN: usize = [$(stringify!($field)),*].len();

            /// Every count with its name, in declaration order.
            pub fn named(&self) -> [(&'static str, u64); Self::LEN] {
                [$((stringify!($field), self.$field)),*]
            }

            /// The counts in declaration order.
            pub fn to_array(&self) -> [u64; Self::LEN] {
                [$(self.$field),*]
            }

            /// Counts from [`HubCounts::to_array`]'s order.
            pub fn from_array(values: [u64; Self::LEN]) -> Self {
                let [$($field),*] = values;
                Self { $($field),* }
            }
        }
    };
}

hub_counts! {
    /// Decisions received.
    decisions_received,
    /// Decisions committed (passed every check and became the decision in force).
    decisions_committed,
    /// Decisions rejected by validation or feasibility (late, out of order and from the
    /// future included).
    decisions_rejected,
    /// Decisions that arrived after the deadline (also in `decisions_rejected`).
    decisions_late,
    /// Cycles that reused the last valid decision.
    decisions_reused,
    /// Sequence gaps detected on incoming decisions.
    sequence_gaps,
    /// Out-of-order (or duplicate) decisions detected.
    sequence_reorders,
    /// States received.
    states_received,
    /// States rejected by validation.
    states_rejected,
    /// Decisions of an older reasoning instance ignored after the hub switched to a newer
    /// one (hot swap, restart): not rejections, they never had a slot.
    decisions_superseded,
    /// Times the hub switched to another reasoning instance.
    source_switches,
}

/// Hub report (`hub/report`), published once per committed or reused cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[type_name("aeris::HubReport@s8")]
#[repr(C)]
pub struct HubReport {
    /// Publisher sequence number.
    pub seq: u64,
    /// Semantic cycle number.
    pub cycle: u64,
    /// CLOCK_MONOTONIC ns at publication.
    pub publish_ns: u64,
    /// Cycle time (cycle start -> commit) in ns; 0 when the cycle reused a decision.
    pub ct_ns: u64,
    /// Stage durations in ns: perception, reasoning, routing, binding.
    pub stage_ns: [u64; 4],
    /// 1 when this cycle committed a fresh decision.
    pub committed: u8,
    /// 1 when this cycle reused the last valid decision (late, invalid or missing).
    pub reused: u8,
    /// 1 when the committed decision was clamped (why: `clamp_reasons`).
    pub clamped: u8,
    /// [`OccupancyStatus`] wire byte of the occupancy the hub gates against when it
    /// reports (the latest valid S_t's; absent before the first): anything but present
    /// means the gate kept to the geofence and the conservative altitude.
    pub occupancy: u8,
    /// Active step i* (1-based).
    pub active_step: u16,
    /// Number of subgoals L.
    pub subgoals: u16,
    /// Attention alpha over the subgoals (first `subgoals` entries valid).
    pub attention: [f32; MAX_SUBGOALS],
    /// What the hub did with what it received, counted since it started.
    pub counts: HubCounts,
    /// Instance number of the reasoner whose decisions the hub takes now (0 = none yet or
    /// unsupervised).
    pub decision_source: u32,
    /// Why the committed decision was clamped: [`clamp`] bits (0 when it was not, and in
    /// reuse reports).
    pub clamp_reasons: u32,
}

/// Why a hub report is unusable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum HubReportError {
    /// More subgoals than [`MAX_SUBGOALS`], or an active step outside them.
    #[error("step {step} / subgoals {subgoals} out of range")]
    BadStep {
        /// Active step.
        step: u16,
        /// Subgoal count.
        subgoals: u16,
    },
    /// An attention weight is not finite or outside [0, 1].
    #[error("attention weight is not a probability")]
    BadAttention,
    /// The occupancy byte is no [`OccupancyStatus`].
    #[error("occupancy status byte {0} is unknown")]
    BadOccupancy(u8),
    /// A clamp reason bit outside [`clamp::ALL`].
    #[error("clamp reasons {0:#x} hold unknown bits")]
    BadClampReasons(u32),
}

impl HubReport {
    /// Deterministic validation.
    pub fn validate(&self) -> Result<(), HubReportError> {
        let l = self.subgoals as usize;
        if l == 0 || l > MAX_SUBGOALS || self.active_step == 0 || self.active_step > self.subgoals {
            return Err(HubReportError::BadStep {
                step: self.active_step,
                subgoals: self.subgoals,
            });
        }
        if !self.attention[..l].iter().all(|a| (0.0..=1.0).contains(a)) {
            return Err(HubReportError::BadAttention);
        }
        if OccupancyStatus::from_u8(self.occupancy).is_none() {
            return Err(HubReportError::BadOccupancy(self.occupancy));
        }
        if self.clamp_reasons & !clamp::ALL != 0 {
            return Err(HubReportError::BadClampReasons(self.clamp_reasons));
        }
        Ok(())
    }

    /// The occupancy status the hub gated against (`None` for an unknown byte).
    pub fn occupancy_status(&self) -> Option<OccupancyStatus> {
        OccupancyStatus::from_u8(self.occupancy)
    }

    /// The valid attention weights.
    pub fn alpha(&self) -> &[f32] {
        &self.attention[..(self.subgoals as usize).min(MAX_SUBGOALS)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validates_occupancy_and_clamp_reasons() {
        let mut r = HubReport {
            subgoals: 2,
            active_step: 1,
            ..HubReport::default()
        };
        assert_eq!(r.validate(), Ok(()));
        // the default report says: no occupancy
        assert_eq!(r.occupancy_status(), Some(OccupancyStatus::Absent));
        r.occupancy = OccupancyStatus::Stale as u8;
        r.clamp_reasons = clamp::NO_OCCUPANCY | clamp::ALTITUDE;
        assert_eq!(r.validate(), Ok(()));
        r.occupancy = 9;
        assert_eq!(r.validate(), Err(HubReportError::BadOccupancy(9)));
        r.occupancy = OccupancyStatus::Present as u8;
        r.clamp_reasons = 1 << 7;
        assert_eq!(r.validate(), Err(HubReportError::BadClampReasons(1 << 7)));
    }
}
