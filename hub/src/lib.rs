//! # aeris-hub
//!
//! The communication hub (MISSION §4).

#![deny(missing_docs)]

use aeris_runtime::{RoleError, RoleSpec};

/// Run the hub role in this process.
pub fn run(_spec: RoleSpec) -> Result<(), RoleError> {
    Err(RoleError::Fatal("hub not built yet".into()))
}
