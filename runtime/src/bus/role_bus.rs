//! A role's view of its flight's bus: typed ports only on the topics its kind declares
//! ([`aeris_schemas::kinds`]), checked by the compiler.

use super::{
    BusError, FlightBus, FramePublisher, FrameSubscriber, TypedPublisher, TypedSubscriber,
};
use aeris_schemas::SupervisorStatus;
use aeris_schemas::kinds::{DeclaredKind, Publishes, RawPorts, Subscribes};
use aeris_schemas::topics::{FrameTopic, MessageTopic};
use core::marker::PhantomData;

/// The bus of a role of kind `K`: a port on topic `T` opens only where `K` declares it
/// (`K: Publishes<T>` / `K: Subscribes<T>`), so the flight's graph, derived from the same
/// declarations, is what the role's code does.
///
/// A hub publishes setpoints; it cannot open a publisher of decisions:
/// ```
/// # fn f(bus: &aeris_runtime::RoleBus<aeris_schemas::kinds::Hub>) {
/// let _ = bus.publisher::<aeris_schemas::topics::HubSetpoint>();
/// # }
/// ```
/// ```compile_fail
/// # fn f(bus: &aeris_runtime::RoleBus<aeris_schemas::kinds::Hub>) {
/// let _ = bus.publisher::<aeris_schemas::topics::ReasoningDecision>();
/// # }
/// ```
/// nor reach the flight bus behind it (only the kinds that move raw bytes do):
/// ```compile_fail
/// # fn f(bus: &aeris_runtime::RoleBus<aeris_schemas::kinds::Hub>) {
/// let _ = bus.flight_bus();
/// # }
/// ```
pub struct RoleBus<K> {
    bus: FlightBus,
    kind: PhantomData<fn() -> K>,
}

impl<K> core::fmt::Debug for RoleBus<K> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("RoleBus")
            .field("flight", &self.bus.flight())
            .finish()
    }
}

impl<K: DeclaredKind> RoleBus<K> {
    /// `bus`, as the bus of a role of kind `K`.
    pub fn new(bus: FlightBus) -> Self {
        Self {
            bus,
            kind: PhantomData,
        }
    }

    /// The flight's name.
    pub fn flight(&self) -> &str {
        self.bus.flight()
    }

    /// A publisher on topic `T` ([`FlightBus::publisher`]).
    pub fn publisher<T: MessageTopic>(&self) -> Result<TypedPublisher<T::Message>, BusError>
    where
        K: Publishes<T>,
    {
        self.bus.publisher::<T>()
    }

    /// A publisher on topic `T` in vehicle `vehicle`'s scope ([`FlightBus::publisher_in`]).
    pub fn publisher_in<T: MessageTopic>(
        &self,
        vehicle: Option<u8>,
    ) -> Result<TypedPublisher<T::Message>, BusError>
    where
        K: Publishes<T>,
    {
        self.bus.publisher_in::<T>(vehicle)
    }

    /// A subscriber of topic `T` ([`FlightBus::subscriber`]).
    pub fn subscriber<T: MessageTopic>(&self) -> Result<TypedSubscriber<T::Message>, BusError>
    where
        K: Subscribes<T>,
    {
        self.bus.subscriber::<T>()
    }

    /// A subscriber of topic `T` in vehicle `vehicle`'s scope ([`FlightBus::subscriber_in`]).
    pub fn subscriber_in<T: MessageTopic>(
        &self,
        vehicle: Option<u8>,
    ) -> Result<TypedSubscriber<T::Message>, BusError>
    where
        K: Subscribes<T>,
    {
        self.bus.subscriber_in::<T>(vehicle)
    }

    /// A frame publisher on topic `T` ([`FlightBus::frame_publisher`]).
    pub fn frame_publisher<T: FrameTopic>(
        &self,
        max_bytes: usize,
    ) -> Result<FramePublisher, BusError>
    where
        K: Publishes<T>,
    {
        self.bus.frame_publisher::<T>(max_bytes)
    }

    /// A frame subscriber of topic `T` ([`FlightBus::frame_subscriber`]).
    pub fn frame_subscriber<T: FrameTopic>(&self) -> Result<FrameSubscriber, BusError>
    where
        K: Subscribes<T>,
    {
        self.bus.frame_subscriber::<T>()
    }

    /// The supervisor's status board ([`FlightBus::read_status_board`]).
    pub fn read_status_board(&self) -> Result<SupervisorStatus, BusError> {
        self.bus.read_status_board()
    }
}

impl<K: RawPorts> RoleBus<K> {
    /// The flight bus itself, for the raw ports ([`crate::raw`]) of a kind that moves
    /// topics named at run time.
    pub fn flight_bus(&self) -> &FlightBus {
        &self.bus
    }
}
