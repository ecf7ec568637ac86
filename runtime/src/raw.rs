//! Topics as bytes: the payload type behind each topic of [`topics::ALL`], a payload's exact
//! bytes, and subscribers and publishers that move a sample as those bytes. What carries a
//! flight's messages somewhere else and back uses this: the recorder (into a file), the
//! replay (out of one) and the host bridge (across a network link), so a message keeps its
//! exact bytes and its schema wherever it goes.

use crate::bus::{
    BusError, FlightBus, FramePublisher, FrameSubscriber, TypedPublisher, TypedSubscriber,
};
use aeris_schemas::{
    AutopilotLinkStatus, BoundSetpoint, ControllerLease, Decision, FrameHeader, HostLinkStatus,
    HubReport, PerceptionState, RoleHeartbeat, VehicleTelemetry, ZeroCopySend, topics,
};
use core::fmt::Debug;
use iceoryx2::identifiers::UniquePublisherId;

/// The payload type behind a topic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Payload {
    /// Frames (`[u8]` with a [`FrameHeader`]): the header is the typed message.
    Frame,
    /// [`PerceptionState`] (S_t or one of its blocks).
    State,
    /// [`Decision`].
    Decision,
    /// [`BoundSetpoint`].
    Setpoint,
    /// [`HubReport`].
    HubReport,
    /// [`VehicleTelemetry`].
    Telemetry,
    /// [`ControllerLease`].
    Lease,
    /// [`AutopilotLinkStatus`].
    Link,
    /// [`HostLinkStatus`].
    HostLink,
    /// [`RoleHeartbeat`].
    Heartbeat,
}

/// The payload type of `topic`, if it is one of [`topics::ALL`], in a vehicle's scope or not
/// (`v2/vehicle/telemetry` carries what `vehicle/telemetry` does, [`topics::split_vehicle`]).
pub fn payload_of(topic: &str) -> Option<Payload> {
    Some(match topics::split_vehicle(topic).1 {
        topics::CAMERA_RGB | topics::CAMERA_DEPTH => Payload::Frame,
        topics::PERCEPTION_STATE
        | topics::PERCEPTION_TEXT
        | topics::PERCEPTION_DETECTIONS
        | topics::PERCEPTION_CUES
        | topics::PERCEPTION_OCCUPANCY => Payload::State,
        topics::REASONING_DECISION => Payload::Decision,
        topics::HUB_SETPOINT => Payload::Setpoint,
        topics::HUB_REPORT => Payload::HubReport,
        topics::VEHICLE_TELEMETRY => Payload::Telemetry,
        topics::CONTROLLER_LEASE => Payload::Lease,
        topics::CONTROLLER_LINK => Payload::Link,
        topics::HOSTS_LINK => Payload::HostLink,
        topics::HEARTBEAT => Payload::Heartbeat,
        _ => return None,
    })
}

/// The bytes of a plain `#[repr(C)]` payload as they lie in memory (for a sample: in shared
/// memory, exactly what the publisher wrote, padding included).
pub fn bytes_of<T: ZeroCopySend + Copy>(value: &T) -> &[u8] {
    // SAFETY: every payload of aeris-schemas is `#[repr(C)]`, `Copy` and pointer-free; the
    // slice borrows `value` and lives no longer. The few implicit padding bytes (e.g. in
    // `StageTiming`) are read as the bytes the publisher's shared-memory slot holds, which
    // is mapped, written memory: carrying them is what makes a copy bit-exact.
    unsafe { core::slice::from_raw_parts((value as *const T).cast::<u8>(), size_of::<T>()) }
}

/// `T` read back from its bytes; `None` when `bytes` has the wrong length.
pub fn read<T: ZeroCopySend + Copy>(bytes: &[u8]) -> Option<T> {
    (bytes.len() == size_of::<T>())
        // SAFETY: the length is that of `T`; every payload type is plain data for which any
        // bytes its publisher wrote are a value (enums travel as `u8`), and the read is
        // unaligned-safe.
        .then(|| unsafe { core::ptr::read_unaligned(bytes.as_ptr().cast::<T>()) })
}

fn type_name_of<T: ZeroCopySend>() -> &'static str {
    // SAFETY: type_name has no preconditions; it is unsafe only to discourage overriding.
    unsafe { <T as ZeroCopySend>::type_name() }
}

impl Payload {
    /// The iceoryx2 type name (`aeris::Decision@s8`).
    pub fn type_name(self) -> &'static str {
        match self {
            Payload::Frame => type_name_of::<FrameHeader>(),
            Payload::State => type_name_of::<PerceptionState>(),
            Payload::Decision => type_name_of::<Decision>(),
            Payload::Setpoint => type_name_of::<BoundSetpoint>(),
            Payload::HubReport => type_name_of::<HubReport>(),
            Payload::Telemetry => type_name_of::<VehicleTelemetry>(),
            Payload::Lease => type_name_of::<ControllerLease>(),
            Payload::Link => type_name_of::<AutopilotLinkStatus>(),
            Payload::HostLink => type_name_of::<HostLinkStatus>(),
            Payload::Heartbeat => type_name_of::<RoleHeartbeat>(),
        }
    }

    /// Size and alignment of the payload (of the header, for frames).
    pub fn layout(self) -> (usize, usize) {
        fn l<T>() -> (usize, usize) {
            (size_of::<T>(), align_of::<T>())
        }
        match self {
            Payload::Frame => l::<FrameHeader>(),
            Payload::State => l::<PerceptionState>(),
            Payload::Decision => l::<Decision>(),
            Payload::Setpoint => l::<BoundSetpoint>(),
            Payload::HubReport => l::<HubReport>(),
            Payload::Telemetry => l::<VehicleTelemetry>(),
            Payload::Lease => l::<ControllerLease>(),
            Payload::Link => l::<AutopilotLinkStatus>(),
            Payload::HostLink => l::<HostLinkStatus>(),
            Payload::Heartbeat => l::<RoleHeartbeat>(),
        }
    }
}

/// What takes a sample as bytes: its payload's bytes (a frame's header), a frame's pixels
/// (empty for other payloads), and the id of the publisher that sent it.
pub type RawSampleFn<'a> = dyn FnMut(&[u8], &[u8], UniquePublisherId) + 'a;

/// A subscriber whose samples are taken as bytes (a frame as its header, then its pixels).
pub trait RawSubscriber {
    /// Hand the next sample, if any, to `f`; `false` when the buffer is empty.
    fn next_raw(&self, f: &mut RawSampleFn<'_>) -> Result<bool, BusError>;
}

impl<T: Debug + ZeroCopySend + Copy + 'static> RawSubscriber for TypedSubscriber<T> {
    fn next_raw(&self, f: &mut RawSampleFn<'_>) -> Result<bool, BusError> {
        match self.next_sample()? {
            Some(sample) => {
                f(
                    bytes_of(sample.payload()),
                    &[],
                    sample.header().publisher_id(),
                );
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

impl RawSubscriber for FrameSubscriber {
    fn next_raw(&self, f: &mut RawSampleFn<'_>) -> Result<bool, BusError> {
        match self.next()? {
            Some(sample) => {
                f(
                    bytes_of(sample.user_header()),
                    sample.payload(),
                    sample.header().publisher_id(),
                );
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

/// A subscriber of `topic` (of type `payload`) taken as bytes.
pub fn raw_subscriber(
    bus: &FlightBus,
    topic: &str,
    payload: Payload,
) -> Result<Box<dyn RawSubscriber>, BusError> {
    Ok(match payload {
        Payload::Frame => Box::new(bus.frame_subscriber(topic)?),
        Payload::State => Box::new(bus.subscriber::<PerceptionState>(topic)?),
        Payload::Decision => Box::new(bus.subscriber::<Decision>(topic)?),
        Payload::Setpoint => Box::new(bus.subscriber::<BoundSetpoint>(topic)?),
        Payload::HubReport => Box::new(bus.subscriber::<HubReport>(topic)?),
        Payload::Telemetry => Box::new(bus.subscriber::<VehicleTelemetry>(topic)?),
        Payload::Lease => Box::new(bus.subscriber::<ControllerLease>(topic)?),
        Payload::Link => Box::new(bus.subscriber::<AutopilotLinkStatus>(topic)?),
        Payload::HostLink => Box::new(bus.subscriber::<HostLinkStatus>(topic)?),
        Payload::Heartbeat => Box::new(bus.subscriber::<RoleHeartbeat>(topic)?),
    })
}

/// Why bytes could not be published as a payload.
#[derive(Debug, thiserror::Error)]
pub enum RawPublishError {
    /// The bytes are not one payload of the publisher's type.
    #[error("{got} bytes are not one `{type_name}` ({expected} bytes)")]
    Length {
        /// The payload's type name.
        type_name: &'static str,
        /// The payload's size.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// The bus refused the sample.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// A publisher that publishes bytes as its payload type (a frame as its header's bytes and
/// its pixels).
pub trait RawPublisher {
    /// Publish `bytes` (and, for frames, `pixels`) as one sample.
    fn publish_raw(&self, bytes: &[u8], pixels: &[u8]) -> Result<(), RawPublishError>;
    /// This publisher's port id (what its subscribers see as a sample's publisher).
    fn id(&self) -> UniquePublisherId;
    /// How many subscribers its topic has on this host (`None`: not counted, for topics
    /// that are always carried).
    fn subscribers(&self) -> Option<usize> {
        None
    }
}

impl<T: Debug + ZeroCopySend + Copy + 'static> RawPublisher for TypedPublisher<T> {
    fn publish_raw(&self, bytes: &[u8], _pixels: &[u8]) -> Result<(), RawPublishError> {
        let value = read::<T>(bytes).ok_or(RawPublishError::Length {
            type_name: type_name_of::<T>(),
            expected: size_of::<T>(),
            got: bytes.len(),
        })?;
        self.publish(&value)?;
        Ok(())
    }
    fn id(&self) -> UniquePublisherId {
        self.publisher_id()
    }
}

impl RawPublisher for FramePublisher {
    fn subscribers(&self) -> Option<usize> {
        Some(FramePublisher::subscribers(self))
    }
    fn publish_raw(&self, bytes: &[u8], pixels: &[u8]) -> Result<(), RawPublishError> {
        let header = read::<FrameHeader>(bytes).ok_or(RawPublishError::Length {
            type_name: type_name_of::<FrameHeader>(),
            expected: size_of::<FrameHeader>(),
            got: bytes.len(),
        })?;
        self.publish_with(&header, pixels.len(), |out| out.copy_from_slice(pixels))?;
        Ok(())
    }
    fn id(&self) -> UniquePublisherId {
        self.publisher_id()
    }
}

/// A publisher of `topic` (of type `payload`) fed with bytes; frames start with room for
/// `frame_bytes` pixels (the publisher grows for larger ones).
pub fn raw_publisher(
    bus: &FlightBus,
    topic: &str,
    payload: Payload,
    frame_bytes: usize,
) -> Result<Box<dyn RawPublisher>, BusError> {
    Ok(match payload {
        Payload::Frame => Box::new(bus.frame_publisher(topic, frame_bytes)?),
        Payload::State => Box::new(bus.publisher::<PerceptionState>(topic)?),
        Payload::Decision => Box::new(bus.publisher::<Decision>(topic)?),
        Payload::Setpoint => Box::new(bus.publisher::<BoundSetpoint>(topic)?),
        Payload::HubReport => Box::new(bus.publisher::<HubReport>(topic)?),
        Payload::Telemetry => Box::new(bus.publisher::<VehicleTelemetry>(topic)?),
        Payload::Lease => Box::new(bus.publisher::<ControllerLease>(topic)?),
        Payload::Link => Box::new(bus.publisher::<AutopilotLinkStatus>(topic)?),
        Payload::HostLink => Box::new(bus.publisher::<HostLinkStatus>(topic)?),
        Payload::Heartbeat => Box::new(bus.publisher::<RoleHeartbeat>(topic)?),
    })
}
