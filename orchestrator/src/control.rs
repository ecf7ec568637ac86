//! The client side of a running flight's `supervisor/control` service: what `aeris swap`
//! and the swap benchmark use to ask the supervisor for a hot swap, and `aeris migrate` for
//! a live move.

use aeris_runtime::bus::{BusError, FlightBus};
use aeris_schemas::{ReplyStage, SupervisorCommand, SupervisorReply};
use core::time::Duration;
use std::time::Instant;

/// How often the client looks for replies.
const POLL: Duration = Duration::from_millis(5);
/// Time beyond the ready timeout for the old process to exit and the reply to arrive.
const SLACK: Duration = Duration::from_secs(15);

/// Why a control request (swap or move) did not end as asked.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// The control service could not be reached (no supervisor runs this flight).
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The supervisor refused the swap or rolled it back; the old process keeps running.
    #[error("{0}")]
    Failed(String),
    /// The supervisor ended the request without a final reply (it stopped or died).
    #[error("the supervisor stopped answering before the request finished")]
    Disconnected,
    /// No final reply in time.
    #[error("no final reply within {0:.0} s")]
    Timeout(f64),
}

/// Ask the flight's supervisor to swap `role` to `variant` and wait for the outcome;
/// `on_reply` sees every reply as it arrives. Returns the final ([`ReplyStage::Done`])
/// reply. `ready_timeout` is how long the new process may take to load and work once
/// (zero: the supervisor's default).
pub fn request_swap(
    bus: &FlightBus,
    role: &str,
    variant: &str,
    ready_timeout: Duration,
    on_reply: impl FnMut(&SupervisorReply),
) -> Result<SupervisorReply, ControlError> {
    let ms = ready_timeout.as_millis().min(u32::MAX as u128) as u32;
    let budget = if ms == 0 {
        crate::supervisor::DEFAULT_SWAP_READY_TIMEOUT
    } else {
        ready_timeout
    } + crate::supervisor::RETIRE_GRACE
        + SLACK;
    request(
        bus,
        &SupervisorCommand::swap(role, variant, ms),
        budget,
        on_reply,
    )
}

/// Ask the flight's supervisor to move `role` to `target` (an executor name, a CPU list, or
/// `HOST:EXECUTOR` on another host) and wait for the outcome; `on_reply` sees every reply
/// as it arrives (a move between hosts answers per stage, like a swap). Returns the final
/// reply (its message says from where to where and how long).
pub fn request_migrate(
    bus: &FlightBus,
    role: &str,
    target: &str,
    on_reply: impl FnMut(&SupervisorReply),
) -> Result<SupervisorReply, ControlError> {
    request(
        bus,
        &SupervisorCommand::migrate(role, target),
        crate::supervisor::DEFAULT_SWAP_READY_TIMEOUT + crate::supervisor::RETIRE_GRACE + SLACK,
        on_reply,
    )
}

fn request(
    bus: &FlightBus,
    command: &SupervisorCommand,
    budget: Duration,
    mut on_reply: impl FnMut(&SupervisorReply),
) -> Result<SupervisorReply, ControlError> {
    let client = bus.control_client()?;
    let pending = client.send(command)?;
    let start = Instant::now();
    loop {
        // read the connection state first: replies sent before a disconnect are still read
        let connected = pending.is_connected();
        while let Some(reply) = pending.receive()? {
            on_reply(&reply);
            match reply.stage() {
                Some(ReplyStage::Done) => return Ok(reply),
                Some(ReplyStage::Failed) | None => {
                    return Err(ControlError::Failed(
                        reply.message.as_str_lossy().to_string(),
                    ));
                }
                _ => {}
            }
        }
        if !connected {
            return Err(ControlError::Disconnected);
        }
        if start.elapsed() > budget {
            return Err(ControlError::Timeout(budget.as_secs_f64()));
        }
        std::thread::sleep(POLL);
    }
}
