//! The MAVLink 2 signing parameters of a role that holds a MAVLink link (the controller,
//! and the built-in vehicle playing an autopilot): `signing_key_file`, the file with the
//! secret (64 hex digits, or a passphrase whose SHA-256 is the key, as MAVProxy and
//! QGroundControl make it), and `signing_link_id` (0..=255, default 0). Without a key
//! file the link is unsigned.

use aeris_mavlink::LinkSigning;
use aeris_runtime::{RoleError, RoleSpec};
use std::path::Path;

/// The signing `spec`'s params ask for, if any.
pub fn signing_from_spec(spec: &RoleSpec) -> Result<Option<LinkSigning>, RoleError> {
    let link_id = match spec.params.get("signing_link_id") {
        None => 0,
        Some(v) => v
            .as_u64()
            .and_then(|id| u8::try_from(id).ok())
            .ok_or_else(|| RoleError::param("signing_link_id", format!("= {v}: use 0..=255")))?,
    };
    let Some(v) = spec.params.get("signing_key_file") else {
        return Ok(None);
    };
    let path = v
        .as_str()
        .ok_or_else(|| RoleError::param("signing_key_file", "must be a path"))?;
    LinkSigning::from_key_file(Path::new(path), link_id)
        .map(Some)
        .map_err(|e| RoleError::step("loading the MAVLink signing key", e))
}
