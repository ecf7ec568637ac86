//! Topic names and how they map to iceoryx2 service names.
//!
//! A versioned service is `aeris/s{SCHEMA_VERSION}/{flight}/{topic}`; the flight name is the
//! namespace prefix that keeps two flights (two vehicles, or parallel tests) on one host
//! apart. The manifest lives at the unversioned `aeris/{flight}/manifest`.

/// RGB frames: `[u8]` payload with a [`crate::FrameHeader`] user header.
pub const CAMERA_RGB: &str = "camera/rgb";
/// Depth frames: `[u8]` payload (u16 mm LE) with a [`crate::FrameHeader`] user header.
pub const CAMERA_DEPTH: &str = "camera/depth";
/// Typed state S_t: [`crate::PerceptionState`], every block (composed by image-to-text).
pub const PERCEPTION_STATE: &str = "perception/state";
/// Scene-text block of S_t (sign / text reader): [`crate::PerceptionState`].
pub const PERCEPTION_TEXT: &str = "perception/text";
/// Detection block of S_t (object detector): [`crate::PerceptionState`].
pub const PERCEPTION_DETECTIONS: &str = "perception/detections";
/// Cue block of S_t with subgoal relevance (cue extractor): [`crate::PerceptionState`].
pub const PERCEPTION_CUES: &str = "perception/cues";
/// Occupancy block of S_t (occupancy role): [`crate::PerceptionState`].
pub const PERCEPTION_OCCUPANCY: &str = "perception/occupancy";
/// Decisions D_t: [`crate::Decision`].
pub const REASONING_DECISION: &str = "reasoning/decision";
/// Bound setpoints: [`crate::BoundSetpoint`].
pub const HUB_SETPOINT: &str = "hub/setpoint";
/// Hub cycle reports: [`crate::HubReport`].
pub const HUB_REPORT: &str = "hub/report";
/// Vehicle telemetry: [`crate::VehicleTelemetry`].
pub const VEHICLE_TELEMETRY: &str = "vehicle/telemetry";
/// The autopilot lease of the flight's controllers: [`crate::ControllerLease`].
pub const CONTROLLER_LEASE: &str = "controller/lease";
/// The autopilot link as the lease-holding controller sees it:
/// [`crate::AutopilotLinkStatus`].
pub const CONTROLLER_LINK: &str = "controller/link";
/// Links to other hosts as the flight's host measures them: [`crate::HostLinkStatus`].
pub const HOSTS_LINK: &str = "hosts/link";
/// Role heartbeats: [`crate::RoleHeartbeat`].
pub const HEARTBEAT: &str = "heartbeat";

/// Supervisor commands (request-response): [`crate::SupervisorCommand`] ->
/// [`crate::SupervisorReply`] stream. Not a publish-subscribe topic, so not in [`ALL`].
pub const SUPERVISOR_CONTROL: &str = "supervisor/control";

/// A new instruction for the formation in flight: [`crate::FormationCommand`]
/// (`aeris formation say`). Flight-wide; written by a tool, not a role, so not in [`ALL`].
pub const FORMATION_SAY: &str = "formation/say";

/// The formation role's answer: [`crate::FormationReply`]. Flight-wide; not in [`ALL`].
pub const FORMATION_REPLY: &str = "formation/reply";

/// Every versioned topic, for listing and validation.
pub const ALL: [&str; 15] = [
    CAMERA_RGB,
    CAMERA_DEPTH,
    PERCEPTION_STATE,
    PERCEPTION_TEXT,
    PERCEPTION_DETECTIONS,
    PERCEPTION_CUES,
    PERCEPTION_OCCUPANCY,
    REASONING_DECISION,
    HUB_SETPOINT,
    HUB_REPORT,
    VEHICLE_TELEMETRY,
    CONTROLLER_LEASE,
    CONTROLLER_LINK,
    HOSTS_LINK,
    HEARTBEAT,
];

/// Maximum length of a flight name.
pub const FLIGHT_NAME_MAX: usize = 48;

/// `true` when `name` is a valid flight name: 1..=48 of `[a-z0-9_-]`.
pub fn is_valid_flight_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= FLIGHT_NAME_MAX
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-')
}

/// `true` when `topic` is one of [`ALL`].
pub fn is_known_topic(topic: &str) -> bool {
    ALL.contains(&topic)
}

/// Most vehicles one flight may have (system ids and vehicle scopes `v1`..`v8`); the same
/// bound as a formation program's [`crate::MAX_VEHICLES`].
pub const MAX_FLIGHT_VEHICLES: u8 = crate::formation::MAX_VEHICLES as u8;

/// `true` for a topic of the whole flight, never of one vehicle: the roles' heartbeats, the
/// supervisor's board and control service, the links to other hosts. Every other topic of
/// a flight with several vehicles lives in one vehicle's scope ([`in_vehicle`]).
pub fn is_flight_wide(topic: &str) -> bool {
    matches!(
        topic,
        HEARTBEAT
            | SUPERVISOR_CONTROL
            | HOSTS_LINK
            | FORMATION_SAY
            | FORMATION_REPLY
            | "supervisor"
    )
}

/// `topic` in the scope of vehicle `vehicle` (1-based): `v2/vehicle/telemetry`. A flight of
/// several vehicles names its services `aeris/s{V}/{flight}/v{K}/{topic}`, so each
/// vehicle's roles run unchanged in their own scope. A flight-wide topic
/// ([`is_flight_wide`]) is returned as it is.
pub fn in_vehicle(vehicle: u8, topic: &str) -> String {
    if is_flight_wide(topic) {
        topic.to_string()
    } else {
        format!("v{vehicle}/{topic}")
    }
}

/// The names `topic` has in a flight of `vehicles`: the topic itself when it is flight-wide
/// or the flight has one vehicle (which flies with unscoped topics), else the topic in each
/// vehicle's scope, `v1/...` to `vN/...` (what a recorder of the whole flight subscribes to).
pub fn in_fleet(topic: &str, vehicles: u8) -> Vec<String> {
    if vehicles <= 1 || is_flight_wide(topic) {
        vec![topic.to_string()]
    } else {
        (1..=vehicles).map(|k| in_vehicle(k, topic)).collect()
    }
}

/// The topic without its vehicle scope (`v2/vehicle/telemetry` -> `vehicle/telemetry`), and
/// the vehicle; `(None, topic)` for a topic in no vehicle's scope.
pub fn split_vehicle(topic: &str) -> (Option<u8>, &str) {
    let Some(rest) = topic.strip_prefix('v') else {
        return (None, topic);
    };
    let Some((digits, base)) = rest.split_once('/') else {
        return (None, topic);
    };
    match digits.parse::<u8>() {
        Ok(k) if (1..=MAX_FLIGHT_VEHICLES).contains(&k) && !digits.starts_with('0') => {
            (Some(k), base)
        }
        _ => (None, topic),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vehicle_scope_round_trips_and_leaves_flight_wide_topics_alone() {
        assert_eq!(in_vehicle(3, VEHICLE_TELEMETRY), "v3/vehicle/telemetry");
        assert_eq!(
            split_vehicle("v3/vehicle/telemetry"),
            (Some(3), VEHICLE_TELEMETRY)
        );
        assert_eq!(in_vehicle(3, HEARTBEAT), HEARTBEAT);
        assert_eq!(split_vehicle(HUB_SETPOINT), (None, HUB_SETPOINT));
        assert_eq!(in_fleet(VEHICLE_TELEMETRY, 1), [VEHICLE_TELEMETRY]);
        assert_eq!(
            in_fleet(VEHICLE_TELEMETRY, 2),
            ["v1/vehicle/telemetry", "v2/vehicle/telemetry"]
        );
        assert_eq!(in_fleet(HEARTBEAT, 4), [HEARTBEAT]);
        for odd in [
            "v0/hub/setpoint",
            "v9/hub/setpoint",
            "v03/hub/setpoint",
            "vx/a",
        ] {
            assert_eq!(split_vehicle(odd), (None, odd), "{odd}");
        }
    }
}
