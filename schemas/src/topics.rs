//! Topic names and how they map to iceoryx2 service names.
//!
//! A versioned service is `aeris/s{SCHEMA_VERSION}/{flight}/{topic}`; the flight name is the
//! namespace prefix that keeps two flights (two vehicles, or parallel tests) on one host
//! apart. The manifest lives at the unversioned `aeris/{flight}/manifest`.

use crate::{
    AutopilotLinkStatus, BoundSetpoint, Decision, FormationCommand, FrameHeader, HostLinkStatus,
    RoleHeartbeat, ZeroCopySend,
};
use core::fmt::Debug;

/// What a topic's samples are, as a value a program can carry (the recorder, the replay and
/// the host bridge move samples of any topic as bytes and pick the type from this).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Payload {
    /// Frames (`[u8]` with a [`FrameHeader`]): the header is the typed message.
    Frame,
    /// [`crate::PerceptionState`] (S_t or one of its blocks).
    State,
    /// [`Decision`].
    Decision,
    /// [`BoundSetpoint`].
    Setpoint,
    /// [`crate::HubReport`].
    HubReport,
    /// [`crate::VehicleTelemetry`].
    Telemetry,
    /// [`crate::ControllerLease`].
    Lease,
    /// [`AutopilotLinkStatus`].
    Link,
    /// [`HostLinkStatus`].
    HostLink,
    /// [`RoleHeartbeat`].
    Heartbeat,
}

/// `$body` with `$T` the message type of `$payload` (a [`Payload`]; a frame's is its
/// [`FrameHeader`]): the one place that maps a payload value to its Rust type, for code that
/// handles samples of any topic as bytes.
#[macro_export]
macro_rules! with_payload_type {
    ($payload:expr, $T:ident => $body:expr) => {
        match $payload {
            $crate::topics::Payload::Frame => {
                type $T = $crate::FrameHeader;
                $body
            }
            $crate::topics::Payload::State => {
                type $T = $crate::PerceptionState;
                $body
            }
            $crate::topics::Payload::Decision => {
                type $T = $crate::Decision;
                $body
            }
            $crate::topics::Payload::Setpoint => {
                type $T = $crate::BoundSetpoint;
                $body
            }
            $crate::topics::Payload::HubReport => {
                type $T = $crate::HubReport;
                $body
            }
            $crate::topics::Payload::Telemetry => {
                type $T = $crate::VehicleTelemetry;
                $body
            }
            $crate::topics::Payload::Lease => {
                type $T = $crate::ControllerLease;
                $body
            }
            $crate::topics::Payload::Link => {
                type $T = $crate::AutopilotLinkStatus;
                $body
            }
            $crate::topics::Payload::HostLink => {
                type $T = $crate::HostLinkStatus;
                $body
            }
            $crate::topics::Payload::Heartbeat => {
                type $T = $crate::RoleHeartbeat;
                $body
            }
        }
    };
}

impl Payload {
    /// The iceoryx2 type name (`aeris::Decision@s8`).
    pub fn type_name(self) -> &'static str {
        fn of<T: ZeroCopySend>() -> &'static str {
            // SAFETY: type_name has no preconditions; it is unsafe only to discourage
            // overriding.
            unsafe { <T as ZeroCopySend>::type_name() }
        }
        with_payload_type!(self, T => of::<T>())
    }

    /// Size and alignment of the payload (of the header, for frames).
    pub fn layout(self) -> (usize, usize) {
        with_payload_type!(self, T => (size_of::<T>(), align_of::<T>()))
    }
}

/// A message that carries the time it was captured or published (CLOCK_MONOTONIC ns).
pub trait Stamped {
    /// When the message was captured (frames) or published.
    fn stamp_ns(&self) -> u64;
}

macro_rules! stamped {
    ($($t:ty => $field:ident),* $(,)?) => {
        $(impl Stamped for $t {
            fn stamp_ns(&self) -> u64 {
                self.$field
            }
        })*
    };
}

stamped!(
    FrameHeader => capture_ns,
    crate::PerceptionState => publish_ns,
    Decision => publish_ns,
    BoundSetpoint => publish_ns,
    crate::HubReport => publish_ns,
    crate::VehicleTelemetry => stamp_ns,
    crate::ControllerLease => stamp_ns,
    AutopilotLinkStatus => stamp_ns,
    HostLinkStatus => stamp_ns,
    RoleHeartbeat => stamp_ns,
);

/// Quality of service of one topic: every process opens the topic with these settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Samples a late subscriber receives on connect.
    pub history: usize,
    /// Samples buffered per subscriber (oldest overwritten).
    pub buffer: usize,
    /// Maximum simultaneous publishers (2+ allows make-before-break swaps).
    pub max_publishers: usize,
    /// Maximum simultaneous subscribers.
    pub max_subscribers: usize,
}

const fn qos(history: usize, buffer: usize, max_publishers: usize, max_subscribers: usize) -> Qos {
    Qos {
        history,
        buffer,
        max_publishers,
        max_subscribers,
    }
}

/// Where a topic lives in a flight of several vehicles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// One per vehicle (`v2/vehicle/telemetry`); unscoped in a one-vehicle flight.
    Vehicle,
    /// One for the whole flight.
    Flight,
}

/// Everything the runtime knows of one topic, declared once by its type ([`Topic::INFO`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TopicInfo {
    /// Topic name (`hub/setpoint`), the last part of its service name.
    pub name: &'static str,
    /// What its samples are, for the topics a flight records and carries between hosts
    /// (every one of [`DECLARED`]); `None` for a tool's topic that is neither.
    pub payload: Option<Payload>,
    /// How every process opens it.
    pub qos: Qos,
    /// Per vehicle or flight-wide.
    pub scope: Scope,
    /// The Rust type of its messages (of a frame's header), as written in its declaration.
    message: &'static str,
}

impl TopicInfo {
    /// The name of its message type (`Decision`; `FrameHeader` for frames).
    pub fn message_type(&self) -> &'static str {
        self.message.rsplit("::").next().unwrap_or(self.message)
    }
}

/// A topic, as a zero-sized type: the only way to open a port (`bus.publisher::<T>()`), so
/// a port's message type, name and QoS all come from this one declaration.
pub trait Topic: 'static {
    /// The topic's name, payload, QoS and scope.
    const INFO: TopicInfo;
}

/// A topic of fixed-size messages.
pub trait MessageTopic: Topic {
    /// The message every sample is.
    type Message: Debug + ZeroCopySend + Copy + 'static;
}

/// A topic of frames: a byte slice with a [`FrameHeader`] user header.
pub trait FrameTopic: Topic {}

macro_rules! declare_topic {
    ($(#[$doc:meta])* $ty:ident, $name:literal, frames, $payload:expr, $qos:expr, $scope:ident) => {
        declare_topic!(@info $(#[$doc])* $ty, $name, FrameHeader, $payload, $qos, $scope);
        impl FrameTopic for $ty {}
    };
    ($(#[$doc:meta])* $ty:ident, $name:literal, $msg:ty, $payload:expr, $qos:expr, $scope:ident) => {
        declare_topic!(@info $(#[$doc])* $ty, $name, $msg, $payload, $qos, $scope);
        impl MessageTopic for $ty {
            type Message = $msg;
        }
    };
    (@info $(#[$doc:meta])* $ty:ident, $name:literal, $msg:ty, $payload:expr, $qos:expr, $scope:ident) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
        pub struct $ty;
        impl Topic for $ty {
            const INFO: TopicInfo = TopicInfo {
                name: $name,
                payload: $payload,
                qos: $qos,
                scope: Scope::$scope,
                message: stringify!($msg),
            };
        }
    };
}

// QoS: every max_subscribers holds one more for the flight recorder (`aeris-record`), which
// subscribes to every topic of a recorded flight.
declare_topic!(
    /// `camera/rgb`: RGB frames, `[u8]` with a [`FrameHeader`].
    CameraRgb, "camera/rgb", frames, Some(Payload::Frame), qos(1, 2, 4, 9), Vehicle
);
declare_topic!(
    /// `camera/depth`: depth frames (u16 mm LE) with a [`FrameHeader`].
    CameraDepth, "camera/depth", frames, Some(Payload::Frame), qos(1, 2, 4, 9), Vehicle
);
declare_topic!(
    /// `perception/state`: the typed state S_t, every block (composed by image-to-text).
    PerceptionState, "perception/state", crate::PerceptionState, Some(Payload::State),
    qos(1, 4, 4, 9), Vehicle
);
declare_topic!(
    /// `perception/text`: the scene-text block of S_t (sign / text reader).
    PerceptionText, "perception/text", crate::PerceptionState, Some(Payload::State),
    qos(1, 4, 4, 9), Vehicle
);
declare_topic!(
    /// `perception/detections`: the detection block of S_t (object detector).
    PerceptionDetections, "perception/detections", crate::PerceptionState,
    Some(Payload::State), qos(1, 4, 4, 9), Vehicle
);
declare_topic!(
    /// `perception/cues`: the cue block of S_t with subgoal relevance (cue extractor).
    PerceptionCues, "perception/cues", crate::PerceptionState, Some(Payload::State),
    qos(1, 4, 4, 9), Vehicle
);
declare_topic!(
    /// `perception/occupancy`: the occupancy block of S_t (occupancy role).
    PerceptionOccupancy, "perception/occupancy", crate::PerceptionState,
    Some(Payload::State), qos(1, 4, 4, 9), Vehicle
);
declare_topic!(
    /// `reasoning/decision`: decisions D_t. No history: a decision is for its heartbeat.
    ReasoningDecision, "reasoning/decision", Decision, Some(Payload::Decision),
    qos(0, 32, 4, 9), Vehicle
);
declare_topic!(
    /// `hub/setpoint`: bound setpoints.
    HubSetpoint, "hub/setpoint", BoundSetpoint, Some(Payload::Setpoint), qos(1, 8, 4, 9),
    Vehicle
);
declare_topic!(
    /// `hub/report`: the hub's cycle reports.
    HubReport, "hub/report", crate::HubReport, Some(Payload::HubReport), qos(1, 64, 4, 9),
    Vehicle
);
declare_topic!(
    /// `vehicle/telemetry`: vehicle telemetry.
    VehicleTelemetry, "vehicle/telemetry", crate::VehicleTelemetry, Some(Payload::Telemetry),
    qos(1, 64, 4, 13), Vehicle
);
declare_topic!(
    /// `controller/lease`: the autopilot lease of the flight's controllers. No history: a
    /// lease is only evidence while it is fresh.
    ControllerLease, "controller/lease", crate::ControllerLease, Some(Payload::Lease),
    qos(0, 16, 4, 9), Vehicle
);
declare_topic!(
    /// `controller/link`: the autopilot link as the lease-holding controller sees it.
    /// History 1: a watcher that joins late sees where the link is.
    ControllerLink, "controller/link", AutopilotLinkStatus, Some(Payload::Link),
    qos(1, 16, 4, 9), Vehicle
);
declare_topic!(
    /// `hosts/link`: links to other hosts as the flight's host measures them.
    HostsLink, "hosts/link", HostLinkStatus, Some(Payload::HostLink), qos(1, 16, 4, 9), Flight
);
declare_topic!(
    /// `heartbeat`: every role's heartbeat.
    Heartbeat, "heartbeat", RoleHeartbeat, Some(Payload::Heartbeat), qos(0, 1024, 32, 9),
    Flight
);
declare_topic!(
    /// `formation/say`: a new instruction for the formation in flight (`aeris formation
    /// say`). Written by a tool, not a role, so not in [`ALL`]. No history: an instruction is
    /// for the formation flying now, never a later one.
    FormationSay, "formation/say", FormationCommand, None, qos(0, 4, 4, 9), Flight
);
declare_topic!(
    /// `formation/reply`: the formation role's answer. Not in [`ALL`].
    FormationReply, "formation/reply", crate::FormationReply, None, qos(0, 8, 4, 9), Flight
);

/// Name of [`CameraRgb`].
pub const CAMERA_RGB: &str = CameraRgb::INFO.name;
/// Name of [`CameraDepth`].
pub const CAMERA_DEPTH: &str = CameraDepth::INFO.name;
/// Name of [`PerceptionState`].
pub const PERCEPTION_STATE: &str = PerceptionState::INFO.name;
/// Name of [`PerceptionText`].
pub const PERCEPTION_TEXT: &str = PerceptionText::INFO.name;
/// Name of [`PerceptionDetections`].
pub const PERCEPTION_DETECTIONS: &str = PerceptionDetections::INFO.name;
/// Name of [`PerceptionCues`].
pub const PERCEPTION_CUES: &str = PerceptionCues::INFO.name;
/// Name of [`PerceptionOccupancy`].
pub const PERCEPTION_OCCUPANCY: &str = PerceptionOccupancy::INFO.name;
/// Name of [`ReasoningDecision`].
pub const REASONING_DECISION: &str = ReasoningDecision::INFO.name;
/// Name of [`HubSetpoint`].
pub const HUB_SETPOINT: &str = HubSetpoint::INFO.name;
/// Name of [`HubReport`].
pub const HUB_REPORT: &str = HubReport::INFO.name;
/// Name of [`VehicleTelemetry`].
pub const VEHICLE_TELEMETRY: &str = VehicleTelemetry::INFO.name;
/// Name of [`ControllerLease`].
pub const CONTROLLER_LEASE: &str = ControllerLease::INFO.name;
/// Name of [`ControllerLink`].
pub const CONTROLLER_LINK: &str = ControllerLink::INFO.name;
/// Name of [`HostsLink`].
pub const HOSTS_LINK: &str = HostsLink::INFO.name;
/// Name of [`Heartbeat`].
pub const HEARTBEAT: &str = Heartbeat::INFO.name;
/// Name of [`FormationSay`].
pub const FORMATION_SAY: &str = FormationSay::INFO.name;
/// Name of [`FormationReply`].
pub const FORMATION_REPLY: &str = FormationReply::INFO.name;

/// Supervisor commands (request-response): [`crate::SupervisorCommand`] ->
/// [`crate::SupervisorReply`] stream. A service, not a publish-subscribe topic.
pub const SUPERVISOR_CONTROL: &str = "supervisor/control";

/// Every topic the flight's roles publish: what a recorder records and a bridge may carry.
pub const DECLARED: [TopicInfo; 15] = [
    CameraRgb::INFO,
    CameraDepth::INFO,
    PerceptionState::INFO,
    PerceptionText::INFO,
    PerceptionDetections::INFO,
    PerceptionCues::INFO,
    PerceptionOccupancy::INFO,
    ReasoningDecision::INFO,
    HubSetpoint::INFO,
    HubReport::INFO,
    VehicleTelemetry::INFO,
    ControllerLease::INFO,
    ControllerLink::INFO,
    HostsLink::INFO,
    Heartbeat::INFO,
];

/// The topics a tool, not a role, writes or reads.
const TOOL_TOPICS: [TopicInfo; 2] = [FormationSay::INFO, FormationReply::INFO];

/// The names of [`DECLARED`], in its order: every topic of a flight, for listing and
/// validation.
pub const ALL: [&str; DECLARED.len()] = {
    let mut names = [""; DECLARED.len()];
    let mut i = 0;
    while i < DECLARED.len() {
        names[i] = DECLARED[i].name;
        i += 1;
    }
    names
};

/// What is declared of `topic` (one of [`DECLARED`] or a tool's topic), in a vehicle's scope or
/// not (`v2/vehicle/telemetry` is `vehicle/telemetry`, [`split_vehicle`]).
pub fn info(topic: &str) -> Option<&'static TopicInfo> {
    let base = split_vehicle(topic).1;
    DECLARED
        .iter()
        .chain(TOOL_TOPICS.iter())
        .find(|t| t.name == base)
}

/// The payload of `topic` if it is one of [`ALL`], in a vehicle's scope or not.
pub fn payload_of(topic: &str) -> Option<Payload> {
    info(topic).and_then(|t| t.payload)
}

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
    match DECLARED
        .iter()
        .chain(TOOL_TOPICS.iter())
        .find(|t| t.name == topic)
    {
        Some(t) => t.scope == Scope::Flight,
        None => matches!(topic, SUPERVISOR_CONTROL | "supervisor"),
    }
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
    fn every_declared_topic_is_found_by_its_name_in_any_vehicle_scope() {
        for t in DECLARED.iter().chain(TOOL_TOPICS.iter()) {
            assert_eq!(info(t.name), Some(t), "{}", t.name);
            assert_eq!(info(&in_vehicle(2, t.name)), Some(t), "{}", t.name);
            assert_eq!(
                is_flight_wide(t.name),
                t.scope == Scope::Flight,
                "{}",
                t.name
            );
        }
        assert_eq!(info("no/such"), None);
        assert_eq!(payload_of(FORMATION_SAY), None);
        assert_eq!(payload_of("v2/camera/rgb"), Some(Payload::Frame));
        assert_eq!(ReasoningDecision::INFO.message_type(), "Decision");
        assert_eq!(PerceptionCues::INFO.message_type(), "PerceptionState");
        assert_eq!(CameraRgb::INFO.message_type(), "FrameHeader");
        assert!(is_flight_wide("supervisor") && is_flight_wide(SUPERVISOR_CONTROL));
    }

    #[test]
    fn a_payloads_type_is_its_topics_message_type() {
        fn check<T: MessageTopic>() {
            let p = T::INFO.payload.expect("a flight topic has a payload");
            // SAFETY: type_name has no preconditions.
            let name = unsafe { <T::Message as ZeroCopySend>::type_name() };
            assert_eq!(p.type_name(), name, "{}", T::INFO.name);
            assert_eq!(
                p.layout(),
                (size_of::<T::Message>(), align_of::<T::Message>())
            );
        }
        check::<PerceptionState>();
        check::<ReasoningDecision>();
        check::<HubSetpoint>();
        check::<HubReport>();
        check::<VehicleTelemetry>();
        check::<ControllerLease>();
        check::<ControllerLink>();
        check::<HostsLink>();
        check::<Heartbeat>();
    }

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
