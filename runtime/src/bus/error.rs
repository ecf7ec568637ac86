//! Why a bus operation failed: one enum, each variant naming the service, with iceoryx2's
//! own error kept as its source.

use aeris_schemas::{SCHEMA_VERSION, topics};

/// The lower layer's error (iceoryx2's) behind a [`BusError`], kept whole as its source.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a bus operation failed. Every variant names the service involved.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The flight or node name is not usable as an iceoryx2 name.
    #[error("invalid name `{0}`")]
    InvalidName(String),
    /// The iceoryx2 node could not be created.
    #[error("cannot create iceoryx2 node `{name}`")]
    Node {
        /// Node name.
        name: String,
        /// iceoryx2's error.
        source: Cause,
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
    #[error("service `{service}` exists with incompatible settings")]
    IncompatibleSettings {
        /// Service name.
        service: String,
        /// iceoryx2's error (which setting).
        source: Cause,
    },
    /// The service could not be opened or created for another reason.
    #[error("cannot open service `{service}`")]
    Service {
        /// Service name.
        service: String,
        /// iceoryx2's error.
        source: Cause,
    },
    /// The flight's manifest kept being created and removed by other processes while this
    /// one tried to open it.
    #[error("the flight manifest `{service}` could not be opened or created")]
    ManifestUnavailable {
        /// Service name.
        service: String,
    },
    /// The service does not exist (only for open-only operations).
    #[error("service `{service}` does not exist (is the flight running?)")]
    NotFound {
        /// Service name.
        service: String,
    },
    /// A port (publisher, subscriber, reader, writer) could not be created.
    #[error("cannot create a port on `{service}`")]
    Port {
        /// Service name.
        service: String,
        /// iceoryx2's error.
        source: Cause,
    },
    /// Loaning, sending or receiving a sample failed.
    #[error("transfer on `{service}` failed")]
    Transfer {
        /// Service name.
        service: String,
        /// iceoryx2's error.
        source: Cause,
    },
    /// An iceoryx2 directory belongs to another user, who could make any service of any
    /// flight.
    #[error("iceoryx2's directory {path} belongs to {owner}: only {allowed} may own it, else another local user could make this flight's services; remove it while no flight runs (it is made again)", path = .path.display())]
    ForeignDirectory {
        /// The directory.
        path: std::path::PathBuf,
        /// Its owner.
        owner: String,
        /// Who may own it (`root`, `alice (uid 1000) or root`).
        allowed: String,
    },
    /// A service of the flight was made by another user (squatted): never joined.
    #[error(
        "service `{service}` was made by {owner}, not by {us}: another local user holds this flight's name; not joined (stop their processes, or fly under another name)"
    )]
    ForeignService {
        /// Service name.
        service: String,
        /// Its maker.
        owner: String,
        /// This process's user.
        us: String,
    },
    /// A topic name no topic of [`topics::ALL`] has (in a vehicle's scope or not).
    #[error("`{topic}` is not a topic of a flight (topics: {known})", known = topics::ALL.join(", "))]
    UnknownTopic {
        /// The name given.
        topic: String,
    },
    /// A frame port was asked of a topic of fixed-size messages.
    #[error("`{topic}` carries messages, not frames")]
    NotFrames {
        /// The topic.
        topic: String,
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
