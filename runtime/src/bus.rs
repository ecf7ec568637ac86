//! The iceoryx2 transport of one flight.
//!
//! A [`FlightBus`] is one process's iceoryx2 node in one flight. Every service it opens is
//! named `aeris/s{SCHEMA_VERSION}/{flight}/{topic}`, so flights never cross-talk and a build
//! with another schema never connects. Each topic's quality of service comes from one table
//! ([`qos`]) so every process opens a service with identical settings.

use aeris_schemas::topics;
use aeris_schemas::{
    FlightManifest, FrameHeader, SCHEMA_VERSION, SupervisorCommand, SupervisorReply,
    SupervisorStatus, ZeroCopySend,
};
use core::fmt::Debug;
use core::time::Duration;
use iceoryx2::node::NodeView;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::reader::Reader;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::writer::Writer;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::service::builder::blackboard::BlackboardOpenError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::builder::request_response::{
    RequestResponseOpenError, RequestResponseOpenOrCreateError,
};

/// The iceoryx2 service flavour AERIS uses between processes.
pub type Ipc = ipc::Service;

/// The iceoryx2 configuration of every AERIS process: iceoryx2's global configuration (an
/// `iceoryx2.toml` where iceoryx2 looks for one, else its built-in defaults), set up once and
/// quietly. Every node of ours is built with it, and iceoryx2's own paths that take the global
/// configuration (the clean-up of a dead node whose details are gone) find it set up: no
/// process logs iceoryx2's "No config file was loaded" warning, which said nothing
/// actionable in every role and test log.
pub fn iceoryx_config() -> &'static Config {
    static QUIET_SETUP: std::sync::Once = std::sync::Once::new();
    QUIET_SETUP.call_once(|| {
        let level = iceoryx2_log::get_log_level();
        if level < LogLevel::Error as u8 {
            set_log_level(LogLevel::Error);
        }
        let _ = Config::global_config();
        set_log_level(log_level_from(level));
    });
    Config::global_config()
}

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

/// Why a bus operation failed. Every variant names the service involved.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The flight or node name is not usable as an iceoryx2 name.
    #[error("invalid name `{0}`")]
    InvalidName(String),
    /// The iceoryx2 node could not be created.
    #[error("cannot create iceoryx2 node `{name}`: {reason}")]
    Node {
        /// Node name.
        name: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// The service exists with another payload type, size or alignment: the other side was
    /// built with a different schema.
    #[error(
        "service `{service}` exists with an incompatible message layout: the process that created it was \
         built with another schema version (this binary speaks s{SCHEMA_VERSION}); rebuild every AERIS binary \
         from the same source"
    )]
    IncompatibleSchema {
        /// Service name.
        service: String,
    },
    /// The service exists with other quality-of-service settings.
    #[error("service `{service}` exists with incompatible settings: {reason}")]
    IncompatibleSettings {
        /// Service name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// The service could not be opened or created for another reason.
    #[error("cannot open service `{service}`: {reason}")]
    Service {
        /// Service name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// The service does not exist (only for open-only operations).
    #[error("service `{service}` does not exist (is the flight running?)")]
    NotFound {
        /// Service name.
        service: String,
    },
    /// A port (publisher, subscriber, reader, writer) could not be created.
    #[error("cannot create a port on `{service}`: {reason}")]
    Port {
        /// Service name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// Loaning, sending or receiving a sample failed.
    #[error("transfer on `{service}` failed: {reason}")]
    Transfer {
        /// Service name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// The flight's manifest says it runs another schema.
    #[error("cannot join flight `{flight}`")]
    Manifest {
        /// Flight.
        flight: String,
        /// Why.
        source: aeris_schemas::ManifestError,
    },
}

/// Quality of service of one topic.
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

/// The one QoS table: every process opens a topic with these settings.
pub fn qos(topic: &str) -> Qos {
    let q = |history, buffer, max_publishers, max_subscribers| Qos {
        history,
        buffer,
        max_publishers,
        max_subscribers,
    };
    // every max_subscribers holds one more for the flight recorder (`aeris-record`), which
    // subscribes to every topic of a recorded flight
    match topic {
        topics::CAMERA_RGB | topics::CAMERA_DEPTH => q(1, 2, 4, 9),
        topics::PERCEPTION_STATE
        | topics::PERCEPTION_TEXT
        | topics::PERCEPTION_DETECTIONS
        | topics::PERCEPTION_CUES
        | topics::PERCEPTION_OCCUPANCY => q(1, 4, 4, 9),
        topics::REASONING_DECISION => q(0, 32, 4, 9),
        topics::HUB_SETPOINT => q(1, 8, 4, 9),
        topics::HUB_REPORT => q(1, 64, 4, 9),
        topics::VEHICLE_TELEMETRY => q(1, 64, 4, 13),
        // no history: a lease is only evidence while it is fresh
        topics::CONTROLLER_LEASE => q(0, 16, 4, 9),
        // history 1: a watcher that joins late sees where the link is
        topics::CONTROLLER_LINK => q(1, 16, 4, 9),
        topics::HEARTBEAT => q(0, 1024, 32, 9),
        _ => q(1, 16, 4, 9),
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
}

impl FlightBusBuilder {
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
        let node = NodeBuilder::new()
            .config(iceoryx_config())
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Ipc>()
            .map_err(|e| BusError::Node {
                name: full.clone(),
                reason: format!("{e:?}"),
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
        };
        if self.join {
            bus.join_flight()?;
        }
        Ok(bus)
    }
}

/// The port factory of a publish-subscribe service.
type PubSubService<P, H> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, P, H>;

/// A publish-subscribe service builder.
type PubSubBuilder<P, H> = iceoryx2::service::builder::publish_subscribe::Builder<P, H, Ipc>;

/// Apply the QoS of `topic` (from [`qos`]) to a service builder.
fn with_qos<P, H>(builder: PubSubBuilder<P, H>, topic: &str) -> PubSubBuilder<P, H>
where
    P: Debug + iceoryx2::prelude::IceoryxSend + ?Sized,
    H: Debug + ZeroCopySend,
{
    let q = qos(topic);
    builder
        .history_size(q.history)
        .subscriber_max_buffer_size(q.buffer)
        .max_publishers(q.max_publishers)
        .max_subscribers(q.max_subscribers)
        .max_nodes(MAX_NODES)
        .enable_safe_overflow(true)
}

/// Maps a port-creation failure on `service` to [`BusError::Port`].
fn port_error<E: Debug>(service: &str) -> impl Fn(E) -> BusError + '_ {
    move |e| BusError::Port {
        service: service.to_string(),
        reason: format!("{e:?}"),
    }
}

type ManifestService = iceoryx2::service::port_factory::blackboard::PortFactory<Ipc, u64>;

/// One process's node in one flight.
pub struct FlightBus {
    node: Node<Ipc>,
    flight: String,
    cleaned_dead_nodes: u64,
    manifest: Option<ManifestService>,
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
            reason: format!("{o:?}"),
        },
        other => BusError::Service {
            service,
            reason: format!("{other:?}"),
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

    /// The full iceoryx2 service name of `topic` in this flight.
    pub fn service_name(&self, topic: &str) -> String {
        service_name(&self.flight, topic)
    }

    fn iox_name(name: &str) -> Result<ServiceName, BusError> {
        ServiceName::new(name).map_err(|_| BusError::InvalidName(name.to_string()))
    }

    fn join_flight(&mut self) -> Result<(), BusError> {
        let name = manifest_service_name(&self.flight);
        let iox = Self::iox_name(&name)?;
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
                        reason: format!("{e:?}"),
                    });
                }
            }
        }
        Err(BusError::Service {
            service: name,
            reason: "the flight manifest could not be opened or created".into(),
        })
    }

    /// Open (or create) the fixed-size publish-subscribe service of `topic`.
    fn open_fixed<T>(&self, topic: &str) -> Result<(String, PubSubService<T, ()>), BusError>
    where
        T: Debug + ZeroCopySend + Copy + 'static,
    {
        let name = self.service_name(topic);
        let builder = self
            .node
            .service_builder(&Self::iox_name(&name)?)
            .publish_subscribe::<T>();
        let service = with_qos(builder, topic)
            .open_or_create()
            .map_err(|e| ps_open_error(&name, e))?;
        Ok((name, service))
    }

    /// Open (or create) the frame service (`[u8]` + [`FrameHeader`]) of `topic`.
    fn open_frames(
        &self,
        topic: &str,
    ) -> Result<(String, PubSubService<[u8], FrameHeader>), BusError> {
        let name = self.service_name(topic);
        let builder = self
            .node
            .service_builder(&Self::iox_name(&name)?)
            .publish_subscribe::<[u8]>()
            .user_header::<FrameHeader>();
        let service = with_qos(builder, topic)
            .open_or_create()
            .map_err(|e| ps_open_error(&name, e))?;
        Ok((name, service))
    }

    /// A publisher of fixed-size `T` on `topic`.
    pub fn publisher<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        topic: &str,
    ) -> Result<TypedPublisher<T>, BusError> {
        let (name, service) = self.open_fixed::<T>(topic)?;
        let publisher = service
            .publisher_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(TypedPublisher {
            publisher,
            service: name,
        })
    }

    /// A subscriber of fixed-size `T` on `topic`.
    pub fn subscriber<T: Debug + ZeroCopySend + Copy + 'static>(
        &self,
        topic: &str,
    ) -> Result<TypedSubscriber<T>, BusError> {
        let (name, service) = self.open_fixed::<T>(topic)?;
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
        let builder = self
            .node
            .service_builder(&Self::iox_name(&name)?)
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
                reason: format!("{other:?}"),
            },
        })?;
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
                reason: format!("{other:?}"),
            },
        })?;
        let client = service
            .client_builder()
            .create()
            .map_err(port_error(&name))?;
        Ok(ControlClient {
            client,
            service: name,
        })
    }

    /// A publisher of frames (byte slices of up to `max_bytes`, with a [`FrameHeader`]).
    pub fn frame_publisher(
        &self,
        topic: &str,
        max_bytes: usize,
    ) -> Result<FramePublisher, BusError> {
        let (name, service) = self.open_frames(topic)?;
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

    /// A subscriber of frames.
    pub fn frame_subscriber(&self, topic: &str) -> Result<FrameSubscriber, BusError> {
        let (name, service) = self.open_frames(topic)?;
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
        let service = self
            .node
            .service_builder(&Self::iox_name(&name)?)
            .blackboard_creator::<u64>()
            .max_nodes(MAX_NODES)
            .max_readers(MAX_NODES)
            .add::<SupervisorStatus>(0, SupervisorStatus::default())
            .create()
            .map_err(|e| BusError::Service {
                service: name.clone(),
                reason: format!("{e:?}"),
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
        let service = match self
            .node
            .service_builder(&Self::iox_name(&name)?)
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
                    reason: format!("{e:?}"),
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

/// The status board as the supervisor holds it.
pub struct StatusBoardWriter {
    entry: iceoryx2::port::writer::EntryHandleMut<Ipc, u64, SupervisorStatus>,
    _writer: Writer<Ipc, u64>,
    _service: iceoryx2::service::port_factory::blackboard::PortFactory<Ipc, u64>,
}

impl StatusBoardWriter {
    /// Replace the board.
    pub fn update(&mut self, status: &SupervisorStatus) {
        self.entry.update_with_copy(*status);
    }
}

/// A builder of the control service.
type ControlBuilder = iceoryx2::service::builder::request_response::Builder<
    SupervisorCommand,
    (),
    SupervisorReply,
    (),
    Ipc,
>;

/// Clients the control service admits at once (`aeris swap` invocations, benchmarks).
const CONTROL_CLIENTS: usize = 8;
/// Replies buffered per request (a request gets at most a handful).
const CONTROL_REPLY_BUFFER: usize = 16;

/// A command received by the supervisor; replies go back through it (a stream), and
/// dropping it ends the stream.
pub type ControlRequest =
    iceoryx2::active_request::ActiveRequest<Ipc, SupervisorCommand, (), SupervisorReply, ()>;

/// The supervisor's end of `supervisor/control`.
pub struct ControlServer {
    server: iceoryx2::port::server::Server<Ipc, SupervisorCommand, (), SupervisorReply, ()>,
    service: String,
}

impl ControlServer {
    /// The next command, if one is waiting.
    pub fn receive(&self) -> Result<Option<ControlRequest>, BusError> {
        self.server.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            reason: format!("{e:?}"),
        })
    }

    /// Send `reply` to the client of `request`. A client that went away is not an error
    /// (the command goes on; nobody reads the reply).
    pub fn reply(&self, request: &ControlRequest, reply: &SupervisorReply) -> Result<(), BusError> {
        if !request.is_connected() {
            return Ok(());
        }
        request.send_copy(*reply).map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            reason: format!("{e:?}"),
        })
    }
}

/// A client of `supervisor/control`.
pub struct ControlClient {
    client: iceoryx2::port::client::Client<Ipc, SupervisorCommand, (), SupervisorReply, ()>,
    service: String,
}

/// The replies of one sent command.
pub struct PendingControl {
    pending: iceoryx2::pending_response::PendingResponse<
        Ipc,
        SupervisorCommand,
        (),
        SupervisorReply,
        (),
    >,
    service: String,
}

impl ControlClient {
    /// Send `command`; its replies arrive on the returned [`PendingControl`].
    pub fn send(&self, command: &SupervisorCommand) -> Result<PendingControl, BusError> {
        let pending = self
            .client
            .send_copy(*command)
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                reason: format!("{e:?}"),
            })?;
        Ok(PendingControl {
            pending,
            service: self.service.clone(),
        })
    }
}

impl PendingControl {
    /// The next reply, if one arrived.
    pub fn receive(&self) -> Result<Option<SupervisorReply>, BusError> {
        match self.pending.receive() {
            Ok(Some(r)) => Ok(Some(*r.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(BusError::Transfer {
                service: self.service.clone(),
                reason: format!("{e:?}"),
            }),
        }
    }

    /// `false` once the supervisor dropped the request (it ended, or died).
    pub fn is_connected(&self) -> bool {
        self.pending.is_connected()
    }
}

/// A publisher of fixed-size messages.
pub struct TypedPublisher<T: Debug + ZeroCopySend + Copy + 'static> {
    publisher: Publisher<Ipc, T, ()>,
    service: String,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> TypedPublisher<T> {
    /// Copy `value` into a loaned shared-memory sample and send it. No heap allocation.
    pub fn publish(&self, value: &T) -> Result<usize, BusError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                reason: format!("{e:?}"),
            })?;
        sample
            .write_payload(*value)
            .send()
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                reason: format!("{e:?}"),
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
    subscriber: Subscriber<Ipc, T, ()>,
    service: String,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> TypedSubscriber<T> {
    /// The next buffered sample, copied out, if any.
    pub fn next(&self) -> Result<Option<T>, BusError> {
        match self.subscriber.receive() {
            Ok(Some(s)) => Ok(Some(*s.payload())),
            Ok(None) => Ok(None),
            Err(e) => Err(BusError::Transfer {
                service: self.service.clone(),
                reason: format!("{e:?}"),
            }),
        }
    }

    /// The next buffered sample in place (zero-copy), if any.
    pub fn next_sample(&self) -> Result<Option<Sample<Ipc, T, ()>>, BusError> {
        self.subscriber.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            reason: format!("{e:?}"),
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
    publisher: Publisher<Ipc, [u8], FrameHeader>,
    port_factory: PubSubService<[u8], FrameHeader>,
    service: String,
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
                reason: format!("{e:?}"),
            })?;
        *sample.user_header_mut() = *header;
        let sample = sample.write_from_fn(|_| 0u8);
        let mut sample = sample;
        fill(sample.payload_mut());
        sample.send().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            reason: format!("{e:?}"),
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
    subscriber: Subscriber<Ipc, [u8], FrameHeader>,
    service: String,
}

/// A received frame, still in shared memory.
pub type FrameSample = Sample<Ipc, [u8], FrameHeader>;

impl FrameSubscriber {
    /// The next buffered frame, if any (header via `user_header()`, bytes via `payload()`).
    pub fn next(&self) -> Result<Option<FrameSample>, BusError> {
        self.subscriber.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            reason: format!("{e:?}"),
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

/// Services of `flight` that currently exist (names relative to the flight prefix).
pub fn list_flight_services(flight: &str) -> Vec<String> {
    let prefix = format!("aeris/s{SCHEMA_VERSION}/{flight}/");
    let mut out = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix(&prefix) {
            out.push(rest.to_string());
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup();
    out
}

/// Services of `flight` with the names of the nodes registered at each (node names relative
/// to the flight: role names, `supervisor`, ...). A service whose dynamic part cannot be
/// read lists no nodes.
pub fn flight_service_nodes(flight: &str) -> Vec<(String, Vec<String>)> {
    let prefix = format!("aeris/s{SCHEMA_VERSION}/{flight}/");
    let node_prefix = format!("{flight}/");
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix(&prefix) {
            let mut nodes: Vec<String> = s
                .dynamic_details
                .iter()
                .flat_map(|d| d.nodes.iter())
                .filter_map(|n| {
                    let details = match n {
                        NodeState::Alive(v) => v.details().as_ref(),
                        NodeState::Dead(v) => v.details().as_ref(),
                        _ => None,
                    }?;
                    details
                        .name()
                        .as_str()
                        .strip_prefix(&node_prefix)
                        .map(str::to_string)
                })
                .collect();
            nodes.sort();
            nodes.dedup();
            out.push((rest.to_string(), nodes));
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup_by(|a, b| a.0 == b.0);
    out
}

/// Delete the files of `flight`'s service `topic` the way an outside tool would (a `/dev/shm`
/// clean-up, systemd's `RemoveIPC`): its static config and every shared-memory file named
/// after its hash. Processes that mapped them keep their mappings; nobody new can open the
/// service. Fault injection for `aeris bench faults`; returns the files removed.
pub fn remove_flight_service_files(flight: &str, topic: &str) -> std::io::Result<usize> {
    let full = format!("aeris/s{SCHEMA_VERSION}/{flight}/{topic}");
    let mut hash = None;
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        if s.static_details.name().as_str() == full {
            hash = Some(s.static_details.service_hash().as_str().to_string());
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    let Some(hash) = hash else {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("no service `{topic}` in flight `{flight}`"),
        ));
    };
    let global = &iceoryx_config().global;
    let root = std::path::PathBuf::from(global.root_path().to_string());
    let dirs = [
        root.join(global.service.directory.to_string()),
        std::path::PathBuf::from("/dev/shm"),
    ];
    let mut removed = 0;
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().contains(&hash) {
                std::fs::remove_file(e.path())?;
                removed += 1;
            }
        }
    }
    Ok(removed)
}

/// Flights that have a manifest on this host.
pub fn list_flights() -> Vec<String> {
    let mut out = Vec::new();
    let _ = <Ipc as iceoryx2::service::Service>::list(iceoryx_config(), |s| {
        let name = s.static_details.name().as_str();
        if let Some(rest) = name.strip_prefix("aeris/")
            && let Some(flight) = rest.strip_suffix("/manifest")
        {
            out.push(flight.to_string());
        }
        CallbackProgression::Continue
    });
    out.sort();
    out.dedup();
    out
}

/// Whether a live process of `flight` has the node `node` (relative to the flight: a role
/// name, `supervisor`). A tool that follows a flight asks it of `supervisor` to learn that
/// the flight ended (the manifest outlives it while any process still holds it).
pub fn flight_node_alive(flight: &str, node: &str) -> bool {
    let full = format!("{flight}/{node}");
    let mut alive = false;
    let _ = Node::<Ipc>::list(iceoryx_config(), |state| {
        if let NodeState::Alive(v) = &state
            && v.details()
                .as_ref()
                .is_some_and(|d| d.name().as_str() == full)
        {
            alive = true;
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    });
    alive
}

/// iceoryx2 nodes of `flight`: (alive, dead) counts. A dead node is one whose process died
/// without cleaning up.
pub fn flight_node_census(flight: &str) -> (usize, usize) {
    let prefix = format!("{flight}/");
    let (mut alive, mut dead) = (0, 0);
    let _ = Node::<Ipc>::list(iceoryx_config(), |state| {
        let of_flight = |d: &Option<iceoryx2::node::NodeDetails>| {
            d.as_ref()
                .is_some_and(|d| d.name().as_str().starts_with(&prefix))
        };
        match &state {
            NodeState::Alive(v) if of_flight(v.details()) => alive += 1,
            NodeState::Dead(v) if of_flight(v.details()) => dead += 1,
            _ => {}
        }
        CallbackProgression::Continue
    });
    (alive, dead)
}

/// Remove the iceoryx2 resources of every dead process on this host; returns how many dead
/// nodes were cleaned up.
pub fn cleanup_dead_nodes() -> u64 {
    match NodeBuilder::new()
        .config(iceoryx_config())
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Ipc>()
    {
        Ok(node) => node.try_cleanup_dead_nodes().cleanups,
        Err(_) => 0,
    }
}
