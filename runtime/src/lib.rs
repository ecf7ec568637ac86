//! # aeris-runtime
//!
//! What every AERIS process shares:
//! - [`bus`]: the iceoryx2 transport. A [`bus::FlightBus`] is one process's node in one
//!   flight; every service it opens lives under that flight's namespace prefix.
//! - [`role`]: the one [`role::Role`] abstraction every role implements and the
//!   [`role::RoleHost`] that runs a role as a process (heartbeats, signals, deadlines).
//! - [`spec`]: what the supervisor hands a role at launch ([`spec::RoleSpec`]).
//! - [`clock`], [`signals`], [`affinity`], [`users`]: monotonic time, termination requests, CPU
//!   sets, local users by name.
//! - [`raw`]: topics as bytes (their payload types, raw subscribers and publishers) for
//!   whatever carries messages out of shared memory and back: recorder, replay, bridge.
//! - [`error_chain`]: an error printed with its causes, for logs and replies.

#![deny(missing_docs)]

/// Accelerators a role may be bound to (defined with the schemas, shared by every crate).
pub use aeris_schemas::accelerator;
pub mod affinity;
pub mod bus;
pub mod clock;
pub mod error_chain;
pub mod log;
pub mod raw;
pub mod role;
mod role_error;
pub mod signals;
pub mod spec;
pub mod stats;
pub mod users;

pub use bus::{BusError, FlightBus, RoleBus};
pub use role::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleHost};
pub use spec::{ClockSpec, DISTILL_PARAM, MissionSpec, RemoteSpec, RoleSpec};
