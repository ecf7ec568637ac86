//! The `supervisor/control` request-response service: `aeris swap` and `aeris migrate` ask
//! for a hot swap or a move; a swap's request and a move between hosts are answered with a
//! reply per stage (started, ready, done or failed), a live move on the flight's host with
//! one final reply.

use super::role_runtime::RoleRuntime;
use super::swap::DEFAULT_SWAP_READY_TIMEOUT;
use super::{Supervisor, SupervisorError, SupervisorEvent};
use aeris_runtime::bus::{BusError, ControlRequest, ControlServer};
use aeris_schemas::{CommandKind, ReplyStage, SupervisorReply};
use std::time::{Duration, Instant};

/// The flight's control service and the swap requests still waiting for their final reply.
pub(super) struct ControlService {
    /// The `supervisor/control` server.
    server: ControlServer,
    /// Swap requests under way: the role, the request, when it arrived.
    requests: Vec<(String, ControlRequest, Instant)>,
}

impl ControlService {
    /// Serve requests arriving at `server`.
    pub(super) fn new(server: ControlServer) -> Self {
        ControlService {
            server,
            requests: Vec::new(),
        }
    }

    /// The next waiting request, if any.
    pub(super) fn receive(&self) -> Result<Option<ControlRequest>, BusError> {
        self.server.receive()
    }

    /// Answer `request` (best effort: a client that left gets nothing).
    pub(super) fn reply(&self, request: &ControlRequest, reply: &SupervisorReply) {
        let _ = self.server.reply(request, reply);
    }

    /// Keep `request`, a swap of `role`, to forward that swap's events to it
    /// ([`ControlService::answer`]).
    pub(super) fn follow(&mut self, role: String, request: ControlRequest) {
        self.requests.push((role, request, Instant::now()));
    }

    /// Forward swap events to the clients that asked for the swap; a final reply ends the
    /// request.
    pub(super) fn answer(&mut self, events: &[SupervisorEvent], roles: &[RoleRuntime]) {
        for event in events {
            let (name, stage, mut reply) = match event {
                SupervisorEvent::SwapStarted {
                    name,
                    variant,
                    old_pid,
                    new_pid,
                    instance,
                    ..
                } => {
                    let mut r = SupervisorReply::new(
                        ReplyStage::Started,
                        &format!("started `{variant}` as pid {new_pid}; loading and warming up"),
                    );
                    r.old_pid = old_pid.unwrap_or(0);
                    r.new_pid = *new_pid;
                    r.new_instance = *instance;
                    (name, ReplyStage::Started, r)
                }
                SupervisorEvent::SwapReady {
                    name,
                    old_pid,
                    new_pid,
                    instance,
                    ..
                } => {
                    let mut r = SupervisorReply::new(ReplyStage::Ready, &event.to_string());
                    r.old_pid = old_pid.unwrap_or(0);
                    r.new_pid = *new_pid;
                    r.new_instance = *instance;
                    (name, ReplyStage::Ready, r)
                }
                SupervisorEvent::SwapDone { name, old_pid, .. } => {
                    let mut r = SupervisorReply::new(ReplyStage::Done, &event.to_string());
                    r.old_pid = old_pid.unwrap_or(0);
                    (name, ReplyStage::Done, r)
                }
                SupervisorEvent::SwapFailed { name, .. } => (
                    name,
                    ReplyStage::Failed,
                    SupervisorReply::new(ReplyStage::Failed, &event.to_string()),
                ),
                _ => continue,
            };
            let Some(k) = self.requests.iter().position(|(r, _, _)| r == name) else {
                continue;
            };
            let role = &roles.iter().find(|r| &r.name == name);
            if reply.new_pid == 0 {
                reply.new_pid = role.and_then(|r| r.pid).unwrap_or(0);
                reply.new_instance = role.map_or(0, |r| r.instance);
            }
            reply.elapsed_ms = self.requests[k].2.elapsed().as_millis() as u64;
            self.reply(&self.requests[k].1, &reply);
            if stage.is_final() {
                self.requests.swap_remove(k);
            }
        }
    }
}

impl Supervisor {
    /// Take the commands waiting on `supervisor/control`.
    pub(super) fn serve_control(
        &mut self,
        events: &mut Vec<SupervisorEvent>,
    ) -> Result<(), SupervisorError> {
        loop {
            let request = match self.control.receive() {
                Ok(Some(r)) => r,
                Ok(None) => return Ok(()),
                Err(source) => return Err(self.bus_error(source)),
            };
            let command = *request.payload();
            let role = command.role.as_str_lossy().to_string();
            let variant = command.target.as_str_lossy().to_string();
            let reply = match CommandKind::from_u8(command.kind) {
                None => SupervisorReply::new(
                    ReplyStage::Failed,
                    &format!("unknown command kind {}", command.kind),
                ),
                Some(CommandKind::Swap) => {
                    let timeout = match command.ready_timeout_ms {
                        0 => DEFAULT_SWAP_READY_TIMEOUT,
                        ms => Duration::from_millis(ms as u64),
                    };
                    match self.begin_swap(&role, &variant, timeout) {
                        Ok(_) => {
                            // the SwapStarted event answers it below
                            events.append(&mut self.pending);
                            self.control.follow(role, request);
                            continue;
                        }
                        Err(e) => SupervisorReply::new(
                            ReplyStage::Failed,
                            &aeris_runtime::error_chain::chain(&e).to_string(),
                        ),
                    }
                }
                Some(CommandKind::Migrate) => match self.move_role(&role, &variant) {
                    Ok(super::RoleMove::Started { .. }) => {
                        // a move between hosts is a swap in place: its events answer it
                        events.append(&mut self.pending);
                        self.control.follow(role, request);
                        continue;
                    }
                    Ok(super::RoleMove::Live(m)) => {
                        let mut r = SupervisorReply::new(
                            ReplyStage::Done,
                            &SupervisorEvent::RoleMigrated(m.clone()).to_string(),
                        );
                        r.old_pid = m.pid;
                        r.new_pid = m.pid;
                        r.elapsed_ms = m.took_us / 1000;
                        events.append(&mut self.pending);
                        r
                    }
                    Err(e) => SupervisorReply::new(
                        ReplyStage::Failed,
                        &aeris_runtime::error_chain::chain(&e).to_string(),
                    ),
                },
            };
            self.control.reply(&request, &reply);
        }
    }
}
