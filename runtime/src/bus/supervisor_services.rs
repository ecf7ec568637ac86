//! The supervisor's services: its status board (a blackboard `aeris status` reads) and
//! `supervisor/control` (request-response: `aeris swap`, `aeris migrate`).

use super::{BusError, Ipc};
use aeris_schemas::{SupervisorCommand, SupervisorReply, SupervisorStatus};
use iceoryx2::port::writer::Writer;
/// The status board as the supervisor holds it.
pub struct StatusBoardWriter {
    pub(super) entry: iceoryx2::port::writer::EntryHandleMut<Ipc, u64, SupervisorStatus>,
    pub(super) _writer: Writer<Ipc, u64>,
    pub(super) _service: iceoryx2::service::port_factory::blackboard::PortFactory<Ipc, u64>,
}

impl StatusBoardWriter {
    /// Replace the board.
    pub fn update(&mut self, status: &SupervisorStatus) {
        self.entry.update_with_copy(*status);
    }
}

/// A builder of the control service.
pub(super) type ControlBuilder = iceoryx2::service::builder::request_response::Builder<
    SupervisorCommand,
    (),
    SupervisorReply,
    (),
    Ipc,
>;

/// Clients the control service admits at once (`aeris swap` invocations, benchmarks).
pub(super) const CONTROL_CLIENTS: usize = 8;
/// Replies buffered per request (a request gets at most a handful).
pub(super) const CONTROL_REPLY_BUFFER: usize = 16;

/// A command received by the supervisor; replies go back through it (a stream), and
/// dropping it ends the stream.
pub type ControlRequest =
    iceoryx2::active_request::ActiveRequest<Ipc, SupervisorCommand, (), SupervisorReply, ()>;

/// The supervisor's end of `supervisor/control`.
pub struct ControlServer {
    pub(super) server:
        iceoryx2::port::server::Server<Ipc, SupervisorCommand, (), SupervisorReply, ()>,
    pub(super) service: String,
}

impl ControlServer {
    /// The next command, if one is waiting.
    pub fn receive(&self) -> Result<Option<ControlRequest>, BusError> {
        self.server.receive().map_err(|e| BusError::Transfer {
            service: self.service.clone(),
            source: e.into(),
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
            source: e.into(),
        })
    }
}

/// A client of `supervisor/control`.
pub struct ControlClient {
    pub(super) client:
        iceoryx2::port::client::Client<Ipc, SupervisorCommand, (), SupervisorReply, ()>,
    pub(super) service: String,
}

/// The replies of one sent command.
pub struct PendingControl {
    pub(super) pending: iceoryx2::pending_response::PendingResponse<
        Ipc,
        SupervisorCommand,
        (),
        SupervisorReply,
        (),
    >,
    pub(super) service: String,
}

impl ControlClient {
    /// Send `command`; its replies arrive on the returned [`PendingControl`].
    pub fn send(&self, command: &SupervisorCommand) -> Result<PendingControl, BusError> {
        let pending = self
            .client
            .send_copy(*command)
            .map_err(|e| BusError::Transfer {
                service: self.service.clone(),
                source: e.into(),
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
                source: e.into(),
            }),
        }
    }

    /// `false` once the supervisor dropped the request (it ended, or died).
    pub fn is_connected(&self) -> bool {
        self.pending.is_connected()
    }
}
