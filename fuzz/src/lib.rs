//! What the fuzz targets share: the gate and the controller's tracker configured exactly as
//! in the built-in default flight (`workflows/default.toml`, loaded by the orchestrator).

use aeris_hub::DecisionGate;
use aeris_orchestrator::workflow::Workflow;
use aeris_roles::controller::TrackerConfig;
use aeris_runtime::RoleSpec;

/// The controller's role spec in the built-in default flight.
pub fn default_controller_spec() -> RoleSpec {
    let w = Workflow::builtin_default().expect("the built-in default flight is valid");
    RoleSpec {
        flight: "fuzz".into(),
        name: "controller".into(),
        kind: aeris_schemas::RoleKind::Controller,
        variant: "mavlink".into(),
        cpus: String::new(),
        timing: w.timing,
        camera: w.camera,
        mission: w.mission,
        params: Default::default(),
        instance: 0,
        remote: None,
        heartbeat_pid: None,
        flight_clock_offset_ns: 0,
        clock: Default::default(),
        accelerator: None,
        vehicle: None,
    }
}

/// The decision gate of the built-in default flight.
pub fn default_gate() -> DecisionGate {
    DecisionGate::new(default_controller_spec().mission.decision_limits())
        .expect("the default mission's limits are coherent")
}

/// The controller's tracker configuration in the built-in default flight.
pub fn default_tracker() -> TrackerConfig {
    TrackerConfig::from_spec(&default_controller_spec())
}

/// Rewrite the checksum of every whole MAVLink 1 or 2 frame in `stream` (scanned from the
/// start, resynchronising on the start bytes like the decoder) so that it is valid for the
/// common dialect. The controller target's mutator applies it to most mutated inputs, so the
/// fuzzer gets past the CRC check into the message decoders and the controller state.
pub fn fix_mavlink_crcs(stream: &mut [u8]) {
    use mavlink::Message;
    use mavlink::dialects::common::MavMessage;
    let mut i = 0;
    while i < stream.len() {
        let (header, id) = match stream[i] {
            0xFD if i + 10 <= stream.len() => (
                10,
                u32::from_le_bytes([stream[i + 7], stream[i + 8], stream[i + 9], 0]),
            ),
            0xFE if i + 6 <= stream.len() => (6, u32::from(stream[i + 5])),
            _ => {
                i += 1;
                continue;
            }
        };
        let end = i + header + usize::from(stream[i + 1]);
        if end + 2 > stream.len() {
            i += 1;
            continue;
        }
        let crc = mavlink::calculate_crc(&stream[i + 1..end], MavMessage::extra_crc(id));
        stream[end..end + 2].copy_from_slice(&crc.to_le_bytes());
        i = end + 2;
    }
}
