//! Schema versioning: what lets a process refuse a flight built with other message layouts.
//!
//! Two guards work together:
//! 1. every versioned service name carries `s{SCHEMA_VERSION}` and every payload's iceoryx2
//!    type name carries `@s{SCHEMA_VERSION}`, so iceoryx2 itself refuses to connect ports of
//!    different layouts (it checks type name, size and alignment);
//! 2. the flight's supervisor publishes a [`FlightManifest`] on an **unversioned** service; a
//!    role reads it first and refuses to start with a clear error when the versions or layout
//!    hashes differ, instead of silently finding no peers.

use crate::{
    AutopilotLinkStatus, BoundSetpoint, ControllerLease, Decision, FrameHeader, HostLinkStatus,
    HubReport, PerceptionState, RoleHeartbeat, SupervisorCommand, SupervisorReply,
    SupervisorStatus, VehicleTelemetry,
};
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Version of the message schema. Bump on any change of a payload type.
pub const SCHEMA_VERSION: u32 = 8;

const fn fnv1a(mut h: u64, v: u64) -> u64 {
    let mut i = 0;
    while i < 8 {
        h ^= (v >> (i * 8)) & 0xff;
        h = h.wrapping_mul(0x100_0000_01b3);
        i += 1;
    }
    h
}

const fn layout_hash() -> u64 {
    let sizes = [
        core::mem::size_of::<FrameHeader>(),
        core::mem::align_of::<FrameHeader>(),
        core::mem::size_of::<PerceptionState>(),
        core::mem::align_of::<PerceptionState>(),
        core::mem::size_of::<Decision>(),
        core::mem::align_of::<Decision>(),
        core::mem::size_of::<BoundSetpoint>(),
        core::mem::align_of::<BoundSetpoint>(),
        core::mem::size_of::<RoleHeartbeat>(),
        core::mem::align_of::<RoleHeartbeat>(),
        core::mem::size_of::<VehicleTelemetry>(),
        core::mem::align_of::<VehicleTelemetry>(),
        core::mem::size_of::<HubReport>(),
        core::mem::align_of::<HubReport>(),
        core::mem::size_of::<SupervisorStatus>(),
        core::mem::align_of::<SupervisorStatus>(),
        core::mem::size_of::<SupervisorCommand>(),
        core::mem::align_of::<SupervisorCommand>(),
        core::mem::size_of::<SupervisorReply>(),
        core::mem::align_of::<SupervisorReply>(),
        core::mem::size_of::<ControllerLease>(),
        core::mem::align_of::<ControllerLease>(),
        core::mem::size_of::<AutopilotLinkStatus>(),
        core::mem::align_of::<AutopilotLinkStatus>(),
        core::mem::size_of::<HostLinkStatus>(),
        core::mem::align_of::<HostLinkStatus>(),
        core::mem::size_of::<crate::FormationCommand>(),
        core::mem::align_of::<crate::FormationCommand>(),
        core::mem::size_of::<crate::FormationReply>(),
        core::mem::align_of::<crate::FormationReply>(),
    ];
    let mut h = fnv1a(0xcbf2_9ce4_8422_2325, SCHEMA_VERSION as u64);
    let mut i = 0;
    while i < sizes.len() {
        h = fnv1a(h, sizes[i] as u64);
        i += 1;
    }
    h
}

/// Hash of the size and alignment of every payload type and the schema version: differs
/// when a layout changed even if someone forgot to bump [`SCHEMA_VERSION`].
pub const SCHEMA_LAYOUT_HASH: u64 = layout_hash();

/// Magic bytes at the start of a manifest.
pub const MANIFEST_MAGIC: [u8; 8] = *b"AERISMF1";

/// Published by the supervisor on the unversioned `aeris/{flight}/manifest` service.
///
/// This layout is frozen: it must never change, so that any build can read any other
/// build's manifest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[type_name("aeris::FlightManifest")]
#[repr(C)]
pub struct FlightManifest {
    /// [`MANIFEST_MAGIC`].
    pub magic: [u8; 8],
    /// The publisher's [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// pid of the supervisor.
    pub supervisor_pid: u32,
    /// The publisher's [`SCHEMA_LAYOUT_HASH`].
    pub layout_hash: u64,
}

impl FlightManifest {
    /// The manifest this build publishes.
    pub fn current(supervisor_pid: u32) -> Self {
        Self {
            magic: MANIFEST_MAGIC,
            schema_version: SCHEMA_VERSION,
            supervisor_pid,
            layout_hash: SCHEMA_LAYOUT_HASH,
        }
    }

    /// Check that this build may join the flight the manifest describes.
    pub fn check_compatible(&self) -> Result<(), ManifestError> {
        if self.magic != MANIFEST_MAGIC {
            return Err(ManifestError::BadMagic);
        }
        if self.schema_version != SCHEMA_VERSION || self.layout_hash != SCHEMA_LAYOUT_HASH {
            return Err(ManifestError::SchemaMismatch {
                flight_version: self.schema_version,
                flight_layout: self.layout_hash,
                own_version: SCHEMA_VERSION,
                own_layout: SCHEMA_LAYOUT_HASH,
            });
        }
        Ok(())
    }
}

/// Why a process may not join a flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ManifestError {
    /// The manifest does not start with [`MANIFEST_MAGIC`].
    #[error("flight manifest is corrupt (bad magic)")]
    BadMagic,
    /// The flight runs another schema.
    #[error(
        "schema mismatch: the flight runs message schema s{flight_version} (layout {flight_layout:#018x}) \
         but this binary was built with s{own_version} (layout {own_layout:#018x}); rebuild every AERIS \
         binary from the same source"
    )]
    SchemaMismatch {
        /// Version in the manifest.
        flight_version: u32,
        /// Layout hash in the manifest.
        flight_layout: u64,
        /// This build's version.
        own_version: u32,
        /// This build's layout hash.
        own_layout: u64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_manifest_is_compatible() {
        assert_eq!(FlightManifest::current(1).check_compatible(), Ok(()));
    }

    #[test]
    fn other_version_is_refused() {
        let mut m = FlightManifest::current(1);
        m.schema_version += 1;
        let err = m.check_compatible().unwrap_err();
        assert!(err.to_string().contains("schema mismatch"));
        let mut m = FlightManifest::current(1);
        m.layout_hash ^= 1;
        assert!(m.check_compatible().is_err());
        m.magic = *b"garbage!";
        assert_eq!(m.check_compatible(), Err(ManifestError::BadMagic));
    }

    #[test]
    fn payload_type_names_carry_the_version() {
        let tag = format!("@s{SCHEMA_VERSION}");
        // SAFETY: type_name has no preconditions; it is unsafe only to discourage overriding.
        let names = unsafe {
            [
                <Decision as ZeroCopySend>::type_name(),
                <PerceptionState as ZeroCopySend>::type_name(),
                <FrameHeader as ZeroCopySend>::type_name(),
                <BoundSetpoint as ZeroCopySend>::type_name(),
                <RoleHeartbeat as ZeroCopySend>::type_name(),
                <VehicleTelemetry as ZeroCopySend>::type_name(),
                <HubReport as ZeroCopySend>::type_name(),
                <SupervisorStatus as ZeroCopySend>::type_name(),
                <AutopilotLinkStatus as ZeroCopySend>::type_name(),
            ]
        };
        for n in names {
            assert!(n.ends_with(&tag), "{n} lacks {tag}");
        }
    }
}
