//! The ports of a flight's topics: publishers and subscribers of fixed-size typed messages
//! and of frames (a header and pixels), every one allocation-free on the hot path.

use super::{BusError, Ipc, PubSubService};
use aeris_schemas::{FrameHeader, ZeroCopySend};
use core::fmt::Debug;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
/// A publisher of fixed-size messages.
pub struct TypedPublisher<T: Debug + ZeroCopySend + Copy + 'static> {
    pub(super) publisher: Publisher<Ipc, T, ()>,
    pub(super) service: String,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> TypedPublisher<T> {
    /// Copy `value` into a loaned shared-memory sample and send it. No heap allocation.
    pub fn publish(&self, value: &T) -> Result<usize, BusError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                source: e.into(),
            })?;
        sample
            .write_payload(*value)
            .send()
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                source: e.into(),
            })
    }

    /// Deliver history to subscribers that connected since the last send.
    pub fn update_connections(&self) {
        let _ = self.publisher.update_connections();
    }

    /// This publisher's port id (what its subscribers see as a sample's publisher).
    pub fn publisher_id(&self) -> iceoryx2::identifiers::UniquePublisherId {
        self.publisher.id()
    }

    /// The service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

/// A subscriber of fixed-size messages.
pub struct TypedSubscriber<T: Debug + ZeroCopySend + Copy + 'static> {
    pub(super) subscriber: Subscriber<Ipc, T, ()>,
    pub(super) service: String,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> TypedSubscriber<T> {
    /// The next buffered sample, copied out, if any.
    pub fn next(&self) -> Result<Option<T>, BusError> {
        match self.subscriber.receive() {
            Ok(Some(s)) => Ok(Some(*s.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(BusError::Transfer {
                service: self.service.clone(),
                source: e.into(),
            }),
        }
    }

    /// The next buffered sample in place (zero-copy), if any.
    pub fn next_sample(&self) -> Result<Option<Sample<Ipc, T, ()>>, BusError> {
        self.subscriber.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            source: e.into(),
        })
    }

    /// Drain the buffer, calling `f` on each sample in arrival order; returns the count.
    pub fn drain(&self, mut f: impl FnMut(&T)) -> Result<usize, BusError> {
        let mut n = 0;
        while let Some(s) = self.next_sample()? {
            f(s.payload());
            n += 1;
        }
        Ok(n)
    }

    /// Drain the buffer and return only the newest sample.
    pub fn latest(&self) -> Result<Option<T>, BusError> {
        let mut last = None;
        self.drain(|v| last = Some(*v))?;
        Ok(last)
    }

    /// The service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

/// A publisher of frames.
pub struct FramePublisher {
    pub(super) publisher: Publisher<Ipc, [u8], FrameHeader>,
    pub(super) port_factory: PubSubService<[u8], FrameHeader>,
    pub(super) service: String,
}

impl FramePublisher {
    /// Loan `len` bytes of shared memory, let `fill` write the frame in place, stamp the
    /// header and send. The frame is rendered directly into shared memory (no copy); the
    /// slice is zero-filled first so `fill` only ever sees initialised bytes.
    pub fn publish_with(
        &self,
        header: &FrameHeader,
        len: usize,
        fill: impl FnOnce(&mut [u8]),
    ) -> Result<(), BusError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(len)
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                source: e.into(),
            })?;
        *sample.user_header_mut() = *header;
        let sample = sample.write_from_fn(|_| 0u8);
        let mut sample = sample;
        fill(sample.payload_mut());
        sample.send().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            source: e.into(),
        })?;
        Ok(())
    }

    /// This publisher's port id (what its subscribers see as a sample's publisher).
    pub fn publisher_id(&self) -> iceoryx2::identifiers::UniquePublisherId {
        self.publisher.id()
    }

    /// How many subscribers the topic has now, in every process of this host.
    pub fn subscribers(&self) -> usize {
        self.port_factory.dynamic_config().number_of_subscribers()
    }

    /// The service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}

/// A subscriber of frames.
pub struct FrameSubscriber {
    pub(super) subscriber: Subscriber<Ipc, [u8], FrameHeader>,
    pub(super) service: String,
}

/// A received frame, still in shared memory.
pub type FrameSample = Sample<Ipc, [u8], FrameHeader>;

impl FrameSubscriber {
    /// The next buffered frame, if any (header via `user_header()`, bytes via `payload()`).
    pub fn next(&self) -> Result<Option<FrameSample>, BusError> {
        self.subscriber.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            source: e.into(),
        })
    }

    /// Drain the buffer and keep the newest frame.
    pub fn latest(&self) -> Result<Option<FrameSample>, BusError> {
        let mut last = None;
        while let Some(s) = self.next()? {
            last = Some(s);
        }
        Ok(last)
    }

    /// The service name.
    pub fn service(&self) -> &str {
        &self.service
    }
}
