//! A process built with another schema version is refused with a clear error.
//!
//! The flight's manifest is what a build of another schema would have published: same
//! frozen manifest layout, another schema version and layout hash.

use aeris_runtime::bus::manifest_service_name;
use aeris_schemas::{FlightManifest, SCHEMA_VERSION};
use aeris_tests::*;
use iceoryx2::prelude::*;
use std::process::Command;

#[test]
fn a_role_refuses_a_flight_of_another_schema() {
    let dir = TempDir::new("schema");
    let flight = unique_flight("schema");
    let node = NodeBuilder::new()
        .config(aeris_runtime::bus::iceoryx_config())
        .create::<ipc::Service>()
        .unwrap();
    let other = FlightManifest {
        schema_version: SCHEMA_VERSION + 1,
        layout_hash: 0x0123_4567_89ab_cdef,
        ..FlightManifest::current(std::process::id())
    };
    let _manifest = node
        .service_builder(&ServiceName::new(&manifest_service_name(&flight)).unwrap())
        .blackboard_creator::<u64>()
        .add::<FlightManifest>(0, other)
        .create()
        .unwrap();

    // Role specs are what the supervisor writes; build one for the planner by hand.
    let spec = role_spec(
        &flight,
        "reasoning",
        aeris_schemas::RoleKind::Reasoning,
        "planner",
        serde_json::json!({}),
    );
    let path = write_spec(&dir.0, &spec);

    let out = Command::new(aeris_bin())
        .args(["role", "--spec"])
        .arg(&path)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(3),
        "exit code for a schema mismatch; stderr: {stderr}"
    );
    assert!(stderr.contains("schema mismatch"), "{stderr}");
    assert!(
        stderr.contains(&format!("s{}", SCHEMA_VERSION + 1)),
        "names the flight's schema: {stderr}"
    );

    // Tools refuse it the same way.
    let out = Command::new(aeris_bin())
        .args(["status", "--flight", &flight])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("schema mismatch"));
}
