//! Topics as bytes: the payload type behind each topic of [`topics::ALL`], a payload's exact
//! bytes, and subscribers and publishers that move a sample as those bytes. What carries a
//! flight's messages somewhere else and back uses this: the recorder (into a file), the
//! replay (out of one) and the host bridge (across a network link), so a message keeps its
//! exact bytes and its schema wherever it goes.

use crate::bus::{
    BusError, FlightBus, FramePublisher, FrameSubscriber, TypedPublisher, TypedSubscriber,
};
use aeris_schemas::{FrameHeader, ZeroCopySend, topics, with_payload_type};
use core::fmt::Debug;
use iceoryx2::identifiers::UniquePublisherId;

pub use aeris_schemas::topics::{Payload, payload_of};

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

/// The declaration of `topic` (a name of one of [`topics::ALL`], maybe in a vehicle's scope)
/// and its payload.
fn declared(topic: &str) -> Result<(&'static topics::TopicInfo, Payload), BusError> {
    topics::info(topic)
        .and_then(|info| Some((info, info.payload?)))
        .ok_or_else(|| BusError::UnknownTopic {
            topic: topic.to_string(),
        })
}

/// A subscriber of `topic` (one of [`topics::ALL`], maybe in a vehicle's scope) taken as
/// bytes.
pub fn raw_subscriber(bus: &FlightBus, topic: &str) -> Result<Box<dyn RawSubscriber>, BusError> {
    let (info, payload) = declared(topic)?;
    Ok(match payload {
        Payload::Frame => Box::new(bus.frame_subscriber_on(topic, info)?),
        message => with_payload_type!(message, T => Box::new(bus.subscriber_on::<T>(topic, info)?)),
    })
}

/// A subscriber of the frame topic `topic` (one of [`topics::ALL`], maybe in a vehicle's
/// scope), for who handles a frame's pixels apart from its header (the recorder).
pub fn frame_subscriber(bus: &FlightBus, topic: &str) -> Result<FrameSubscriber, BusError> {
    match declared(topic)? {
        (info, Payload::Frame) => bus.frame_subscriber_on(topic, info),
        _ => Err(BusError::NotFrames {
            topic: topic.to_string(),
        }),
    }
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

/// A publisher of `topic` (one of [`topics::ALL`], maybe in a vehicle's scope) fed with
/// bytes; frames start with room for `frame_bytes` pixels (the publisher grows for larger
/// ones).
pub fn raw_publisher(
    bus: &FlightBus,
    topic: &str,
    frame_bytes: usize,
) -> Result<Box<dyn RawPublisher>, BusError> {
    let (info, payload) = declared(topic)?;
    Ok(match payload {
        Payload::Frame => Box::new(bus.frame_publisher_on(topic, info, frame_bytes)?),
        message => with_payload_type!(message, T => Box::new(bus.publisher_on::<T>(topic, info)?)),
    })
}
