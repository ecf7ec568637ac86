//! The iceoryx2 transport of one flight.
//!
//! A [`FlightBus`] is one process's iceoryx2 node in one flight. Every service it opens is
//! named `aeris/s{SCHEMA_VERSION}/{flight}/{topic}`, so flights never cross-talk and a build
//! with another schema never connects. Each topic's quality of service comes from one table
//! ([`qos`]) so every process opens a service with identical settings.
//!
//! - [`ports`]: the publishers and subscribers of typed messages and frames;
//! - [`supervisor_services`]: the supervisor's status board and its control service;
//! - [`census`]: what exists on this host (flights, their services and nodes) and the
//!   clean-up after dead processes;
//! - [`ownership`]: a flight joins only services its own user made (another local user
//!   who creates them first is refused by name, never joined).

pub use aeris_schemas::topics::Qos;
use aeris_schemas::topics::{self, FrameTopic, MessageTopic, TopicInfo};
use aeris_schemas::{
    FlightManifest, FrameHeader, SCHEMA_VERSION, SupervisorCommand, SupervisorReply,
    SupervisorStatus, ZeroCopySend,
};
use core::fmt::Debug;
use core::time::Duration;
use iceoryx2::port::reader::Reader;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::blackboard::BlackboardOpenError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::builder::request_response::{
    RequestResponseOpenError, RequestResponseOpenOrCreateError,
};

pub mod census;
mod error;
pub mod ownership;
pub mod ports;
mod role_bus;
pub mod supervisor_services;

pub use census::*;
pub use error::{BusError, Cause};
pub use ports::*;
pub use role_bus::RoleBus;
pub use supervisor_services::*;

/// The iceoryx2 service flavour AERIS uses between processes.
pub type Ipc = ipc::Service;

/// The iceoryx2 configuration of every AERIS process: iceoryx2's global configuration (an
/// `iceoryx2.toml` where iceoryx2 looks for one, else its built-in defaults), set up once and
/// quietly. Every node of ours is built with it, and iceoryx2's own paths that take the global
/// configuration (the clean-up of a dead node whose details are gone) find it set up: no
/// process logs iceoryx2's "No config file was loaded" warning, which said nothing
/// actionable in every role and test log.
///
/// One setting is raised: how long a process waits for a service another process is still
/// creating ([`SERVICE_CREATION_TIMEOUT`], iceoryx2's default is 1 s).
pub fn iceoryx_config() -> &'static Config {
    static CONFIG: std::sync::OnceLock<Config> = std::sync::OnceLock::new();
    CONFIG.get_or_init(|| {
        let level = iceoryx2_log::get_log_level();
        if level < LogLevel::Error as u8 {
            set_log_level(LogLevel::Error);
        }
        let mut config = Config::global_config().clone();
        set_log_level(log_level_from(level));
        config.global.creation_timeout =
            config.global.creation_timeout.max(SERVICE_CREATION_TIMEOUT);
        config
    })
}

/// How long opening a service waits while another process is creating it. iceoryx2's 1 s
/// default failed a CI flight: on two cores, with ten roles loading their models, the hub
/// took over a second to create `hub/report` and `aeris run` gave up on it
/// (`PublishSubscribeOpenError(DoesNotExist)`). A creator that died half-way still fails
/// every opener, after this long.
pub const SERVICE_CREATION_TIMEOUT: Duration = Duration::from_secs(10);

/// The [`LogLevel`] whose number is `level` (iceoryx2 reports its level as a number).
fn log_level_from(level: u8) -> LogLevel {
    match level {
        0 => LogLevel::Trace,
        1 => LogLevel::Debug,
        2 => LogLevel::Info,
        3 => LogLevel::Warn,
        4 => LogLevel::Error,
        _ => LogLevel::Fatal,
    }
}

/// Maximum iceoryx2 nodes per service (roles, restarts in flight, tools).
const MAX_NODES: usize = 48;

/// Builder of a [`FlightBus`].
#[derive(Debug)]
pub struct FlightBusBuilder {
    flight: String,
    node_name: String,
    cleanup_dead_nodes: bool,
    join: bool,
    vehicle: Option<u8>,
}

impl FlightBusBuilder {
    /// Open every topic that is not flight-wide in vehicle `vehicle`'s scope
    /// (`aeris/s{V}/{flight}/v{K}/{topic}`, [`topics::in_vehicle`]): what a role of one
    /// vehicle of a flight with several does, so its code stays that of a one-vehicle
    /// flight. `None` (the default): no scope.
    pub fn vehicle(mut self, vehicle: Option<u8>) -> Self {
        self.vehicle = vehicle;
        self
    }

    /// Name of this process's node inside the flight (e.g. the role name).
    pub fn node_name(mut self, name: &str) -> Self {
        self.node_name = name.to_string();
        self
    }

    /// Remove iceoryx2 resources of dead processes at creation (default: on).
    pub fn cleanup_dead_nodes(mut self, on: bool) -> Self {
        self.cleanup_dead_nodes = on;
        self
    }

    /// Read (or, if first, publish) the flight manifest and refuse another schema
    /// (default: on). Tools that only list services turn it off.
    pub fn join_manifest(mut self, on: bool) -> Self {
        self.join = on;
        self
    }

    /// Create the node, clean up after dead processes, and join the flight.
    pub fn create(self) -> Result<FlightBus, BusError> {
        if !topics::is_valid_flight_name(&self.flight) {
            return Err(BusError::InvalidName(self.flight));
        }
        let full = format!("{}/{}", self.flight, self.node_name);
        let node_name = NodeName::new(&full).map_err(|_| BusError::InvalidName(full.clone()))?;
        ownership::check_directories(iceoryx_config())?;
        let node = NodeBuilder::new()
            .config(iceoryx_config())
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| BusError::Node {
                name: full.clone(),
                source: e.into(),
            })?;
        let cleaned = if self.cleanup_dead_nodes {
            node.try_cleanup_dead_nodes().cleanups
        } else {
            0
        };
        let mut bus = FlightBus {
            node,
            flight: self.flight,
            cleaned_dead_nodes: cleaned,
            manifest: None,
            vehicle: self.vehicle,
        };
        if self.join {
            bus.join_flight()?;
        }
        Ok(bus)
    }
}

/// The port factory of a publish-subscribe service.
pub(super) type PubSubService<P, H> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, P, H>;

/// A publish-subscribe service builder.
type PubSubBuilder<P, H> = iceoryx2::service::builder::publish_subscribe::Builder<P, H, Ipc>;

/// Apply a topic's declared QoS ([`TopicInfo::qos`]) to a service builder.
fn with_qos<P, H>(builder: PubSubBuilder<P, H>, q: Qos) -> PubSubBuilder<P, H>
where
    P: Debug + iceoryx2::prelude::IceoryxSend + ?Sized,
    H: Debug + ZeroCopySend,
{
    builder
        .history_size(q.history)
        .subscriber_max_buffer_size(q.buffer)
        .max_publishers(q.max_publishers)
        .max_subscribers(q.max_subscribers)
        .max_nodes(MAX_NODES)
        .enable_safe_overflow(true)
}

/// `topic` in vehicle `vehicle`'s scope, or as it is.
fn scoped(vehicle: Option<u8>, topic: &str) -> String {
    match vehicle {
        Some(k) => topics::in_vehicle(k, topic),
        None => topic.to_string(),
    }
}

/// Maps a port-creation failure on `service` to [`BusError::Port`].
fn port_error<E: std::error::Error + Send + Sync + 'static>(
    service: &str,
) -> impl Fn(E) -> BusError + '_ {
    move |e| BusError::Port {
        service: service.to_string(),
        source: e.into(),
    }
}

type ManifestService = iceoryx2::service::port_factory::blackboard::PortFactory<Ipc, u64>;

/// One process's node in one flight.
pub struct FlightBus {
    node: Node<Ipc>,
    flight: String,
    cleaned_dead_nodes: u64,
    manifest: Option<ManifestService>,
    vehicle: Option<u8>,
}

impl Debug for FlightBus {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FlightBus")
            .field("flight", &self.flight)
            .finish()
    }
}

fn ps_open_error(service: &str, e: PublishSubscribeOpenOrCreateError) -> BusError {
    let service = service.to_string();
    match e {
        PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
            PublishSubscribeOpenError::IncompatibleTypes,
        ) => BusError::IncompatibleSchema { service },
        PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
            o @ (PublishSubscribeOpenError::IncompatibleAttributes
            | PublishSubscribeOpenError::IncompatibleMessagingPattern
            | PublishSubscribeOpenError::IncompatibleOverflowBehavior),
        ) => BusError::IncompatibleSettings {
            service,
            source: o.into(),
        },
        other => BusError::Service {
            service,
            source: other.into(),
        },
    }
}

impl FlightBus {
    /// Start building the node of this process in `flight`.
    pub fn builder(flight: &str) -> FlightBusBuilder {
        FlightBusBuilder {
            flight: flight.to_string(),
            node_name: format!("pid{}", std::process::id()),
            cleanup_dead_nodes: true,
            join: true,
            vehicle: None,
        }
    }

    /// The flight name (namespace prefix).
    pub fn flight(&self) -> &str {
        &self.flight
    }

    /// Dead nodes whose resources were removed when this bus was created.
    pub fn cleaned_dead_nodes(&self) -> u64 {
        self.cleaned_dead_nodes
    }

    /// The underlying iceoryx2 node.
    pub fn node(&self) -> &Node<Ipc> {
        &self.node
    }

    /// The vehicle whose scope this node opens its topics in ([`FlightBusBuilder::vehicle`]).
    pub fn vehicle(&self) -> Option<u8> {
        self.vehicle
    }

    /// The full iceoryx2 service name of `topic` in this flight (in this node's vehicle
    /// scope, if it has one and the topic is not flight-wide).
    pub fn service_name(&self, topic: &str) -> String {
        match self.vehicle {
            Some(k) => service_name(&self.flight, &topics::in_vehicle(k, topic)),
            None => service_name(&self.flight, topic),
        }
    }

    fn iox_name(name: &str) -> Result<ServiceName, BusError> {
        ServiceName::new(name).map_err(|_| BusError::InvalidName(name.to_string()))
    }

    fn join_flight(&mut self) -> Result<(), BusError> {
        let name = manifest_service_name(&self.flight);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::Blackboard)?;
        // Either the supervisor (or the first process) created the manifest, or we do.
        for _ in 0..100 {
            match self
                .node
                .service_builder(&iox)
                .blackboard_opener::<u64>()
                // the manifest's settings are whatever its creator chose: require nothing
                .max_nodes(1)
                .max_readers(1)
                .open()
            {
                Ok(service) => {
                    ownership::check_opened(iceoryx_config(), &name, service.service_hash())?;
                    let reader = service
                        .reader_builder()
                        .create()
                        .map_err(port_error(&name))?;
                    let entry = reader.entry::<FlightManifest>(&0).map_err(|_| {
                        BusError::IncompatibleSchema {
                            service: name.clone(),
                        }
                    })?;
                    let manifest = *entry.get();
                    manifest
                        .check_compatible()
                        .map_err(|source| BusError::Manifest {
                            flight: self.flight.clone(),
                            source,
                        })?;
                    drop(entry);
                    drop(reader);
                    self.manifest = Some(service);
                    return Ok(());
                }
                Err(BlackboardOpenError::DoesNotExist) => {
                    match self
                        .node
                        .service_builder(&iox)
                        .blackboard_creator::<u64>()
                        .max_nodes(MAX_NODES)
                        .max_readers(MAX_NODES)
                        .add::<FlightManifest>(0, FlightManifest::current(std::process::id()))
                        .create()
                    {
                        Ok(service) => {
                            self.manifest = Some(service);
                            return Ok(());
                        }
                        // someone created it between our open and create: open again
                        Err(_) => std::thread::sleep(Duration::from_millis(5)),
                    }
                }
                Err(BlackboardOpenError::IncompatibleKeys) => {
                    return Err(BusError::IncompatibleSchema { service: name });
                }
                // being created right now by another process
                Err(BlackboardOpenError::InternalFailure)
                | Err(BlackboardOpenError::IsMarkedForDestruction)
                | Err(BlackboardOpenError::ServiceInCorruptedState) => {
                    std::thread::sleep(Duration::from_millis(5))
                }
                Err(e) => {
                    return Err(BusError::Service {
                        service: name,
                        source: e.into(),
                    });
                }
            }
        }
        Err(BusError::ManifestUnavailable { service: name })
    }

    /// Open (or create) the fixed-size publish-subscribe service of `topic` (a name of a
    /// topic declared as `info`, maybe in a vehicle's scope).
    fn open_fixed<T>(
        &self,
        topic: &str,
        info: &TopicInfo,
    ) -> Result<(String, PubSubService<T, ()>), BusError>
    where
        T: Debug + ZeroCopySend + Copy + 'static,
    {
        let name = self.service_name(topic);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::PublishSubscribe)?;
        let builder = self.node.service_builder(&iox).publish_subscribe::<T>();
        let service = with_qos(builder, info.qos)
            .open_or_create()
            .map_err(|e| ps_open_error(&name, e))?;
        ownership::check_opened(iceoryx_config(), &name, service.service_hash())?;
        Ok((name, service))
    }

    /// Open (or create) the frame service (`[u8]` + [`FrameHeader`]) of `topic`.
    fn open_frames(
        &self,
        topic: &str,
        info: &TopicInfo,
    ) -> Result<(String, PubSubService<[u8], FrameHeader>), BusError> {
        let name = self.service_name(topic);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::PublishSubscribe)?;
        let builder = self
            .node
            .service_builder(&iox)
            .publish_subscribe::<[u8]>()
            .user_header::<FrameHeader>();
        let service = with_qos(builder, info.qos)
            .open_or_create()
            .map_err(|e| ps_open_error(&name, e))?;
        ownership::check_opened(iceoryx_config(), &name, service.service_hash())?;
        Ok((name, service))
    }

    /// A publisher on topic `T` (in this node's vehicle scope, if it has one).
    ///
    /// A port is opened only through a declared topic: a message type or a name is not one.
    /// ```compile_fail
    /// # fn f(bus: &aeris_runtime::FlightBus) {
    /// let _ = bus.publisher::<aeris_schemas::Decision>();
    /// # }
    /// ```
    /// ```compile_fail
    /// # fn f(bus: &aeris_runtime::FlightBus) {
    /// let _ = bus.publisher("reasoning/decision");
    /// # }
    /// ```
    pub fn publisher<T: MessageTopic>(&self) -> Result<TypedPublisher<T::Message>, BusError> {
        self.publisher_on(T::INFO.name, &T::INFO)
    }

    /// A publisher on topic `T` in vehicle `vehicle`'s scope (`v2/hub/setpoint`; `None`:
    /// unscoped, a one-vehicle flight's): what a role that flies several vehicles at once
    /// opens.
    pub fn publisher_in<T: MessageTopic>(
        &self,
        vehicle: Option<u8>,
    ) -> Result<TypedPublisher<T::Message>, BusError> {
        self.publisher_on(&scoped(vehicle, T::INFO.name), &T::INFO)
    }

    /// A subscriber of topic `T` (in this node's vehicle scope, if it has one).
    pub fn subscriber<T: MessageTopic>(&self) -> Result<TypedSubscriber<T::Message>, BusError> {
        self.subscriber_on(T::INFO.name, &T::INFO)
    }

    /// A subscriber of topic `T` in vehicle `vehicle`'s scope (`None`: unscoped).
    pub fn subscriber_in<T: MessageTopic>(
        &self,
        vehicle: Option<u8>,
    ) -> Result<TypedSubscriber<T::Message>, BusError> {
        self.subscriber_on(&scoped(vehicle, T::INFO.name), &T::INFO)
    }

    /// A publisher of `M` on `topic`, a name of the topic declared as `info`.
    pub(crate) fn publisher_on<M: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        topic: &str,
        info: &TopicInfo,
    ) -> Result<TypedPublisher<M>, BusError> {
        let (name, service) = self.open_fixed::<M>(topic, info)?;
        let publisher = service
            .publisher_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(TypedPublisher {
            publisher,
            service: name,
        })
    }

    /// A subscriber of `M` on `topic`, a name of the topic declared as `info`.
    pub(crate) fn subscriber_on<M: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        topic: &str,
        info: &TopicInfo,
    ) -> Result<TypedSubscriber<M>, BusError> {
        let (name, service) = self.open_fixed::<M>(topic, info)?;
        let subscriber = service
            .subscriber_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(TypedSubscriber {
            subscriber,
            service: name,
        })
    }

    fn control_builder(&self) -> Result<(String, ControlBuilder), BusError> {
        let name = self.service_name(aeris_schemas::topics::SUPERVISOR_CONTROL);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::RequestResponse)?;
        let builder = self
            .node
            .service_builder(&iox)
            .request_response::<SupervisorCommand, SupervisorReply>()
            .max_servers(1)
            .max_clients(CONTROL_CLIENTS)
            .max_active_requests_per_client(2)
            .max_response_buffer_size(CONTROL_REPLY_BUFFER)
            .max_nodes(MAX_NODES)
            .enable_safe_overflow_for_responses(true);
        Ok((name, builder))
    }

    /// The supervisor's end of the flight's control service (`supervisor/control`).
    pub fn control_server(&self) -> Result<ControlServer, BusError> {
        let (name, builder) = self.control_builder()?;
        let service = builder.open_or_create().map_err(|e| match e {
            RequestResponseOpenOrCreateError::RequestResponseOpenError(
                RequestResponseOpenError::IncompatibleRequestOrResponseType,
            ) => BusError::IncompatibleSchema {
                service: name.clone(),
            },
            other => BusError::Service {
                service: name.clone(),
                source: other.into(),
            },
        })?;
        ownership::check_opened(iceoryx_config(), &name, service.service_hash())?;
        let server = service
            .server_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(ControlServer {
            server,
            service: name,
        })
    }

    /// A client of the flight's control service (what `aeris swap` uses). Fails with
    /// [`BusError::NotFound`] when no supervisor runs the flight.
    pub fn control_client(&self) -> Result<ControlClient, BusError> {
        let (name, builder) = self.control_builder()?;
        let service = builder.open().map_err(|e| match e {
            RequestResponseOpenError::DoesNotExist => BusError::NotFound {
                service: name.clone(),
            },
            RequestResponseOpenError::IncompatibleRequestOrResponseType => {
                BusError::IncompatibleSchema {
                    service: name.clone(),
                }
            }
            other => BusError::Service {
                service: name.clone(),
                source: other.into(),
            },
        })?;
        ownership::check_opened(iceoryx_config(), &name, service.service_hash())?;
        let client = service
            .client_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(ControlClient {
            client,
            service: name,
        })
    }

    /// A publisher of frames on topic `T` (byte slices of up to `max_bytes` to begin
    /// with, with a [`FrameHeader`]).
    pub fn frame_publisher<T: FrameTopic>(
        &self,
        max_bytes: usize,
    ) -> Result<FramePublisher, BusError> {
        self.frame_publisher_on(T::INFO.name, &T::INFO, max_bytes)
    }

    /// A subscriber of frames on topic `T`.
    pub fn frame_subscriber<T: FrameTopic>(&self) -> Result<FrameSubscriber, BusError> {
        self.frame_subscriber_on(T::INFO.name, &T::INFO)
    }

    /// A frame publisher on `topic`, a name of the frame topic declared as `info`.
    pub(crate) fn frame_publisher_on(
        &self,
        topic: &str,
        info: &TopicInfo,
        max_bytes: usize,
    ) -> Result<FramePublisher, BusError> {
        let (name, service) = self.open_frames(topic, info)?;
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(max_bytes.max(1))
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(port_error(&name))?;
        Ok(FramePublisher {
            publisher,
            port_factory: service,
            service: name,
        })
    }

    /// A frame subscriber on `topic`, a name of the frame topic declared as `info`.
    pub(crate) fn frame_subscriber_on(
        &self,
        topic: &str,
        info: &TopicInfo,
    ) -> Result<FrameSubscriber, BusError> {
        let (name, service) = self.open_frames(topic, info)?;
        let subscriber = service
            .subscriber_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(FrameSubscriber {
            subscriber,
            service: name,
        })
    }

    /// Create the supervisor's status board (only the supervisor does this).
    pub fn create_status_board(&self) -> Result<StatusBoardWriter, BusError> {
        let name = status_service_name(&self.flight);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::Blackboard)?;
        let service = self
            .node
            .service_builder(&iox)
            .blackboard_creator::<u64>()
            .max_nodes(MAX_NODES)
            .max_readers(MAX_NODES)
            .add::<SupervisorStatus>(0, SupervisorStatus::default())
            .create()
            .map_err(|e| BusError::Service {
                service: name.clone(),
                source: e.into(),
            })?;
        let writer = service
            .writer_builder()
            .create()
            .map_err(port_error(&name))?;
        let entry = writer
            .entry::<SupervisorStatus>(&0)
            .map_err(port_error(&name))?;
        Ok(StatusBoardWriter {
            entry,
            _writer: writer,
            _service: service,
        })
    }

    /// Read the supervisor's status board of this flight once.
    pub fn read_status_board(&self) -> Result<SupervisorStatus, BusError> {
        let name = status_service_name(&self.flight);
        let iox = Self::iox_name(&name)?;
        ownership::check_before_open(iceoryx_config(), &iox, MessagingPattern::Blackboard)?;
        let service = match self
            .node
            .service_builder(&iox)
            .blackboard_opener::<u64>()
            .open()
        {
            Ok(s) => s,
            Err(BlackboardOpenError::DoesNotExist) => {
                return Err(BusError::NotFound { service: name });
            }
            Err(BlackboardOpenError::IncompatibleKeys) => {
                return Err(BusError::IncompatibleSchema { service: name });
            }
            Err(e) => {
                return Err(BusError::Service {
                    service: name,
                    source: e.into(),
                });
            }
        };
        let reader: Reader<Ipc, u64> = service
            .reader_builder()
            .create()
            .map_err(port_error(&name))?;
        let entry = reader
            .entry::<SupervisorStatus>(&0)
            .map_err(|_| BusError::IncompatibleSchema { service: name })?;
        Ok(*entry.get())
    }
}

/// `aeris/s{V}/{flight}/{topic}`.
pub fn service_name(flight: &str, topic: &str) -> String {
    format!("aeris/s{SCHEMA_VERSION}/{flight}/{topic}")
}

/// `aeris/{flight}/manifest` (unversioned on purpose).
pub fn manifest_service_name(flight: &str) -> String {
    format!("aeris/{flight}/manifest")
}

/// `aeris/s{V}/{flight}/supervisor`.
pub fn status_service_name(flight: &str) -> String {
    service_name(flight, "supervisor")
}
