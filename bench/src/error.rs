//! The one error type of the benchmarks.

use aeris_runtime::BusError;

/// Why a benchmark could not run to the end.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The settings cannot be measured (e.g. a payload too small for the stamp).
    #[error("invalid benchmark settings: {0}")]
    Config(String),
    /// The outside load could not be started.
    #[error(transparent)]
    OutsideLoad(#[from] crate::flights::OutsideLoadError),
    /// Opening the benchmark's flight or one of its topics failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// An iceoryx2 operation outside the topic table failed.
    #[error("iceoryx2 {what} on `{service}` failed: {reason}")]
    Iceoryx {
        /// The operation (create service, loan, send, receive, wait, ...).
        what: &'static str,
        /// Service name.
        service: String,
        /// iceoryx2's reason.
        reason: String,
    },
    /// An operating-system call failed.
    #[error("{what}")]
    Io {
        /// What was being done.
        what: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The pong process could not be started, died, or misbehaved.
    #[error("pong process: {0}")]
    Pong(String),
    /// The other side did not answer in time.
    #[error("no answer within {timeout_ms} ms while {what}")]
    Timeout {
        /// What was awaited.
        what: String,
        /// The time waited.
        timeout_ms: u64,
    },
    /// An echo did not carry what was sent.
    #[error(
        "corrupt echo: sent seq {expected_seq}, got seq {got_seq} (stamp {stamp_ok}, last byte {tail_ok})"
    )]
    Corrupt {
        /// Sequence number sent.
        expected_seq: u64,
        /// Sequence number received.
        got_seq: u64,
        /// Whether the timestamp matched.
        stamp_ok: bool,
        /// Whether the last byte matched.
        tail_ok: bool,
    },
    /// A benchmark thread could not be started or panicked.
    #[error("benchmark thread: {0}")]
    Thread(String),
    /// A model would not load or run.
    #[error(transparent)]
    Model(#[from] aeris_models::ModelError),
    /// A language model would not load or decide.
    #[error(transparent)]
    Llm(#[from] aeris_llm::LlmError),
    /// A role's own setup (e.g. the mission brief a reasoner builds) failed.
    #[error(transparent)]
    Role(#[from] aeris_runtime::RoleError),
    /// A pong spec is not valid JSON of [`crate::PongSpec`].
    #[error("bad pong spec")]
    Spec(#[from] serde_json::Error),
}

impl BenchError {
    /// An [`BenchError::Io`] with the last OS error.
    pub(crate) fn last_os(what: impl Into<String>) -> Self {
        Self::Io {
            what: what.into(),
            source: std::io::Error::last_os_error(),
        }
    }

    /// An [`BenchError::Io`] from `source`.
    pub(crate) fn io(what: impl Into<String>, source: std::io::Error) -> Self {
        Self::Io {
            what: what.into(),
            source,
        }
    }
}
