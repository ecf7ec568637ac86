//! # aeris-schemas
//!
//! The typed messages that cross AERIS processes through iceoryx2 shared memory.
//!
//! Every payload type here is `#[repr(C)]`, fixed-size, contains no pointers and
//! implements [`ZeroCopySend`] so it can live in shared memory untouched. Every type has a
//! deterministic `validate` function that returns a typed error; receivers call it before
//! trusting a sample.
//!
//! Frames: `[N, E, U]` means a local frame with x north, y east, z **up** (metres). The
//! controller converts to MAVLink's NED at the autopilot boundary, nowhere else.
//!
//! This crate is a leaf: it depends on nothing of ours. Its `serde` feature derives the
//! (de)serialisation of [`DecisionLimits`], which the workflow's mission limits are, and of
//! [`StepReading`], what was read in one of the mission's steps.

#![deny(missing_docs)]

pub mod accelerator;
pub mod autopilot_link;
pub mod control;
pub mod decision;
pub mod formation;
pub mod formation_command;
pub mod frame;
pub mod heartbeat;
pub mod host_link;
pub mod hub_report;
#[cfg(feature = "serde")]
pub mod json_form;
pub mod kinds;
pub mod lease;
pub mod role_counters;
pub mod role_kinds;
pub mod setpoint;
pub mod state;
pub mod step_reading;
pub mod supervisor;
pub mod telemetry;
pub mod text;
pub mod topics;
pub mod version;

pub use autopilot_link::{
    AutopilotKind, AutopilotLinkStatus, LINK_NOTE_MAX, LINK_URL_MAX, LinkState,
};
pub use control::{CommandKind, ReplyStage, SupervisorCommand, SupervisorReply};
pub use decision::{
    ActionMode, BLIND_CLIMB_SLACK_M, BLIND_MOVE_M, Decision, DecisionError, DecisionLimits,
};
pub use formation::{
    FormationError, FormationLimits, FormationPhase, FormationProgram, MAX_PHASES, MAX_VEHICLES,
    PhaseKind, ShapeKind,
};
pub use formation_command::{
    FORMATION_INSTRUCTION_MAX, FORMATION_REPLY_MAX, FormationCommand, FormationReply, SayOutcome,
};
pub use frame::{FrameError, FrameFormat, FrameHeader};
pub use heartbeat::{HeartbeatError, MAX_STAGES, RoleHeartbeat, RoleStatus, StageTiming};
pub use host_link::{HostLinkStatus, LINK_LOSS_WINDOW, LINK_PROBE_PERIOD_MS, MAX_HOSTS};
pub use hub_report::{HubCounts, HubReport, HubReportError, clamp};
pub use lease::{ControllerLease, LEASE_HAS_HOLD, LEASE_HAS_REFERENCE, LEASE_LINK_HEARD};
pub use role_counters::{
    BlockCounters, BridgeCounters, CameraCounters, ComposeCounters, ControllerCounters,
    FormationCounters, GeometricPerceptionCounters, HubBeatCounters, LanguageCounters,
    PlannerCounters, RecorderCounters, ReplayCounters, VehicleCounters, reasoner_decisions,
};
pub use role_kinds::{RoleKind, RoleKindInfo, UnknownRoleKind};
pub use setpoint::{BoundSetpoint, SetpointError};
pub use state::{
    Cue, Detection, MAX_CUES, MAX_DETECTIONS, OCCUPANCY_CELLS, OCCUPANCY_SIDE, OCCUPANCY_UNKNOWN,
    OccupancyGrid, OccupancyStatus, PerceptionState, SUMMARY_MAX, StateError, block,
};
pub use step_reading::{Relation, StepReading, StepReadingError, Turn};
pub use supervisor::{BINDING_TEXT_MAX, MAX_ROLES, RoleStatusEntry, SupervisorStatus};
pub use telemetry::{TelemetryError, VehicleTelemetry};
pub use text::FixedText;
pub use version::{FlightManifest, ManifestError, SCHEMA_LAYOUT_HASH, SCHEMA_VERSION};

/// Re-exported so that downstream crates name the same trait the payloads implement.
pub use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Upper bound on the number of subgoals an instruction may be segmented into.
pub const MAX_SUBGOALS: usize = 16;

/// `true` when every component is finite (not NaN, not +-inf).
#[inline]
pub fn all_finite(values: &[f32]) -> bool {
    values.iter().all(|v| v.is_finite())
}
