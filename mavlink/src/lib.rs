//! # aeris-mavlink
//!
//! Everything both ends of a MAVLink link share: the controller role (the companion
//! computer) and the built-in simulated vehicle (an autopilot) use it, and so will real
//! autopilots' links. No other crate of ours.
//! - [`link`]: one MAVLink link on any supported URL ([`prepare_link`], [`PendingLink`],
//!   [`MavLink`]), receives that time out after [`LINK_POLL`] so threads can stop;
//! - [`signing`]: MAVLink 2 signing ([`LinkSigning`]: the key from a file, the link id);
//! - [`receiver`]: the receive thread ([`LinkReceiver`]) that establishes a link and hands
//!   every message to its owner;
//! - [`dialect`]: the message set every link speaks (MAVLink's `common`);
//! - [`frame`]: NED, MAVLink's local frame, to and from our `[N, E, U]`;
//! - [`autopilot`]: what differs between autopilot firmwares ([`Autopilot`]): how a flight
//!   mode is commanded and reported; [`px4`] and [`ardupilot`] hold the firmwares' mode
//!   numbers.

#![deny(missing_docs)]

pub mod ardupilot;
pub mod autopilot;
pub mod frame;
pub mod link;
pub mod px4;
pub mod receiver;
pub mod signing;
mod transport;

/// A message's sender and sequence number.
pub use mavlink::MavHeader;
/// The MAVLink dialect every link speaks: the `common` message set.
pub use mavlink::dialects::common as dialect;

pub use autopilot::Autopilot;
pub use frame::{ned_to_neu, neu_to_ned};
pub use link::{LINK_POLL, LinkError, MavLink, PendingLink, Received, open_link, prepare_link};
/// MAVLink's framing versions.
pub use mavlink::MavlinkVersion;
pub use receiver::LinkReceiver;
pub use signing::{LinkSigning, SignatureVerdict, SigningKeyError};
