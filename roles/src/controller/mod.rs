//! The controller role (kind `controller`, variant `mavlink`): tracks the hub's bound
//! setpoints at the control rate and talks MAVLink 1 or 2 to a PX4 or ArduPilot Copter
//! autopilot.
//!
//! Identity: system 1, component `MAV_COMP_ID_ONBOARD_COMPUTER` (191). It binds to the
//! first system whose HEARTBEAT announces a PX4 or ArduPilot vehicle ([`link_watch`]):
//! that system and component id are the target of every command and setpoint (broadcast
//! before that; no command goes out before it), that firmware chooses the flight-mode
//! sequence ([`sequencer`]), and only its messages are believed. Everyone else on the link
//! (a ground station, MAVProxy, a camera) is counted and ignored.
//!
//! The link is watched: every tick the lease holder publishes an [`AutopilotLinkStatus`]
//! on `controller/link` (waiting, up, silent, lost; frames heard by kind; MAVLink 1 frames
//! refused; the last command the autopilot refused and its MAV_RESULT). No autopilot
//! HEARTBEAT within `link_timeout_ms` of taking the lease is a silent link (the flight
//! ends on it, naming the URL and what was heard); none for `link_timeout_ms` after the
//! last (or after taking the lease) is a lost one (an event; the flight goes on and the
//! autopilot's own failsafe acts). A standby's link is not judged: an autopilot answers
//! whoever sends to it, so a standby may hear it only once it holds the lease.
//!
//! Parameters (`params` of the [`RoleSpec`]):
//! - `autopilot`: MAVLink URL of the autopilot (`udpin:`, `udpout:`, `tcpout:`, `tcpin:`,
//!   `serial:PORT:BAUD`), default [`DEFAULT_AUTOPILOT`];
//! - `mavlink`: `"auto"` (default: MAVLink 2, or 1 when the autopilot's heartbeat comes in
//!   MAVLink 1), `1` (always send MAVLink 1) or `2` (send and accept MAVLink 2 only);
//! - `signing_key_file`, `signing_link_id`: MAVLink 2 signing ([`signing_params`]): what
//!   the controller sends is signed, and unsigned or badly signed frames are refused and
//!   counted (needs `mavlink` = 2 or `"auto"`);
//! - `link_timeout_ms`: the link timeout, default [`DEFAULT_LINK_TIMEOUT_MS`] (5000);
//! - `realtime`: bool, default `true`: try SCHED_FIFO priority 50 for the cycle thread, and
//!   fall back to the normal scheduler with one line on stderr when not permitted.
//! - `standby`: bool, default `false`: this controller is the hot standby of another (it
//!   loses a tie for the lease at the flight's start).
//!
//! Every tick (period `1 / timing.control_rate_hz`, default 50 Hz):
//! 1. **read**: drain `hub/setpoint`, refuse (and count) every [`BoundSetpoint`] that fails
//!    `BoundSetpoint::validate(&mission.decision_limits())`, keep the newest valid one; copy
//!    the autopilot state the receive thread decoded (HEARTBEAT, LOCAL_POSITION_NED,
//!    ATTITUDE, EXTENDED_SYS_STATE, COMMAND_ACK);
//! 2. **track** ([`Tracker`], [`tracker`]): with no valid setpoint fresher than
//!    `timing.setpoint_timeout_ms` (or none yet), hold the position latched when the hold
//!    began (and count the tick); otherwise fly the setpoint's mode, with a reference that
//!    never needs the vehicle faster than allowed, inside the geofence and altitude band;
//! 3. **send**: one SET_POSITION_TARGET_LOCAL_NED (`MAV_FRAME_LOCAL_NED`, position +
//!    velocity + yaw; `[N, E, U]` becomes NED, `z = -U`, only here: [`messages`]), then what
//!    the autopilot sequencer ([`AutopilotSequencer`], [`sequencer`]) asks for: HEARTBEAT
//!    (`MAV_TYPE_ONBOARD_CONTROLLER`, `MAV_AUTOPILOT_INVALID`) at 1 Hz; once the autopilot's
//!    heartbeat is seen and setpoints have streamed for 0.5 s, while a valid setpoint wants
//!    the vehicle flying, `MAV_CMD_DO_SET_MODE` (offboard or guided, as the [`Autopilot`]
//!    flavour says) and `MAV_CMD_COMPONENT_ARM_DISARM` (arm) every 0.5 s until the heartbeat
//!    reports armed and in that mode; for ArduPilot then `MAV_CMD_NAV_TAKEOFF` to the
//!    setpoint's height until off the ground, and its land mode for a land setpoint; and
//!    `vehicle/telemetry` ([`VehicleTelemetry`] in `[N, E, U]`).
//!
//! **Hot standby** (the autopilot lease, [`LeaseArbiter`], [`lease`]): a flight may run two
//! controllers on one autopilot link (the second with `params.standby = true`). Only the
//! holder of the lease writes to the autopilot; it publishes a [`ControllerLease`] on
//! `controller/lease` at every poll (the role polls [`POLLS_PER_TICK`] times per control
//! period), carrying its tracker's reference, anchor and hold latch. The other one is a
//! standby: it keeps the hub's newest setpoints and the holder's `vehicle/telemetry`, and
//! claims the lease when no lease has been heard for [`LEASE_SILENCE_PERIODS`] control
//! periods, with an epoch above every epoch it heard and at least the system's monotonic
//! clock in milliseconds (so a controller that never heard the holder, which was stopped before it came up, still
//! outranks every earlier claim when that holder resumes); its tracker then adopts the
//! holder's last published state ([`Tracker::adopt`]) and it sends in the same poll: the
//! autopilot sees at most that silence and a poll without a setpoint, and the reference goes
//! on from where it was, when the holder is killed or stopped. The lease also says whether
//! the flight's autopilot was heard ([`aeris_schemas::LEASE_LINK_HEARD`]): a new holder whose
//! own link hears nothing (over `udpout` the vehicle answers one peer) reports a quiet vehicle
//! as a lost link, not as one never heard. A holder that hears a higher
//! claim steps down before its next send. A controller listens [`LEASE_LISTEN_PERIODS`]
//! control periods after it starts before it claims (a standby twice as long), so a
//! restarted controller joins as the standby and at a flight's start the primary (`standby`
//! false) claims first; two claims of one epoch go to the primary. A lone controller simply
//! claims the lease and flies.
//!
//! Heartbeat [`CycleReport`] (one per control tick): stages `read`, `track`, `send`;
//! counters [`aeris_schemas::ControllerCounters`]:
//! ticks and missed = control ticks run and skipped in this term of the lease, refused =
//! setpoints refused by validation, hold_ticks = ticks spent holding for lack of a fresh
//! valid setpoint, sent = SET_POSITION_TARGET_LOCAL_NED messages written to the link,
//! active = 1 while holding the lease, takeovers = leases claimed, epoch = the lease term
//! held (0 when standby). Telemetry counts the same, from this process's first tick as the
//! holder (its sequence starts again at 1, like a restarted publisher's).
//!
//! The cycle does not allocate: the subscriber, publisher, link and buffers are made in
//! `new`; the mavlink crate serialises into a stack buffer and writes it with one syscall.
//!
//! Files, pure cores apart from I/O: [`lease`] (who may write), [`tracker`] (setpoints to
//! position targets), [`sequencer`] (heartbeat, mode, arm and take-off commands; where an
//! autopilot flavour plugs in), [`link_watch`] (whom to believe, what was heard, the link's
//! state), `autopilot_state` (what the autopilot reported), [`messages`] (the wire format
//! and identities), `role` ([`ControllerRole`]: ports, receive thread, cycle),
//! and [`testing`] (the fuzz checks, not API).
//!
//! [`RoleSpec`]: aeris_runtime::RoleSpec
//! [`BoundSetpoint`]: aeris_schemas::BoundSetpoint
//! [`Autopilot`]: aeris_mavlink::Autopilot
//! [`VehicleTelemetry`]: aeris_schemas::VehicleTelemetry
//! [`AutopilotLinkStatus`]: aeris_schemas::AutopilotLinkStatus
//! [`ControllerLease`]: aeris_schemas::ControllerLease
//! [`CycleReport`]: aeris_runtime::CycleReport

mod autopilot_state;
pub mod lease;
pub mod link_watch;
pub mod messages;
mod role;
pub mod sequencer;
pub mod signing_params;
pub mod testing;
pub mod tracker;

pub use autopilot_state::LINK_TIMEOUT_NS;
pub use lease::{LEASE_LISTEN_PERIODS, LEASE_SILENCE_PERIODS, LeaseArbiter, LeaseChange};
pub use link_watch::{AutopilotIdentity, LinkLedger, link_state, term_heartbeat};
pub use messages::{
    COMPANION_COMPONENT_ID, COMPANION_SYSTEM_ID, Target, position_target_message,
    position_velocity_yaw_mask,
};
pub use role::{
    ControllerRole, DEFAULT_AUTOPILOT, DEFAULT_LINK_TIMEOUT_MS, MavlinkFraming, POLLS_PER_TICK,
};
pub use sequencer::{
    AutopilotSequencer, COMMAND_RETRY_NS, FlightIntent, STREAM_BEFORE_OFFBOARD_NS,
};
pub use signing_params::signing_from_spec;
pub use tracker::{TrackCommand, Tracker, TrackerConfig, VehicleView};
