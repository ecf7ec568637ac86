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

/// One reply of the supervisor to a swap or a move, as the client saw it.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ControlStep {
    /// `started`, `ready`, `done`, `failed` (`unknown`: a stage byte this build does not know).
    pub stage: &'static str,
    /// Milliseconds since the supervisor accepted the request.
    pub elapsed_ms: u64,
    /// The process being replaced (0: none).
    pub old_pid: u32,
    /// The new process (0: not started).
    pub new_pid: u32,
    /// The new process's instance number.
    pub new_instance: u32,
    /// What happened, for people.
    pub message: String,
}

impl From<&SupervisorReply> for ControlStep {
    fn from(r: &SupervisorReply) -> Self {
        Self {
            stage: match r.stage() {
                Some(ReplyStage::Started) => "started",
                Some(ReplyStage::Ready) => "ready",
                Some(ReplyStage::Done) => "done",
                Some(ReplyStage::Failed) => "failed",
                None => "unknown",
            },
            elapsed_ms: r.elapsed_ms,
            old_pid: r.old_pid,
            new_pid: r.new_pid,
            new_instance: r.new_instance,
            message: r.message.as_str_lossy().to_string(),
        }
    }
}

/// What `aeris swap` reports: the request, every reply, and how it ended (`--json` is its
/// `Serialize`, the success line its `Display`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct SwapReport {
    /// The flight.
    pub flight: String,
    /// The role swapped.
    pub role: String,
    /// The variant asked for.
    pub variant: String,
    /// Whether the swap was done.
    pub ok: bool,
    /// Why not, when it was not.
    pub error: Option<String>,
    /// Every reply, in order.
    pub steps: Vec<ControlStep>,
}

impl SwapReport {
    /// The report of a swap of `role` to `variant` in `flight` that got `replies` and
    /// ended in `outcome` ([`request_swap`]).
    pub fn new(
        flight: &str,
        role: &str,
        variant: &str,
        replies: &[SupervisorReply],
        outcome: &Result<SupervisorReply, ControlError>,
    ) -> Self {
        Self {
            flight: flight.to_string(),
            role: role.to_string(),
            variant: variant.to_string(),
            ok: outcome.is_ok(),
            error: outcome.as_ref().err().map(ToString::to_string),
            steps: replies.iter().map(ControlStep::from).collect(),
        }
    }
}

impl core::fmt::Display for SwapReport {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let (role, variant) = (&self.role, &self.variant);
        match (&self.error, self.steps.last()) {
            (None, Some(done)) => write!(
                f,
                "role `{role}` now runs `{variant}` as pid {} (instance {}), old pid {} stopped, {} ms",
                done.new_pid, done.new_instance, done.old_pid, done.elapsed_ms
            ),
            (error, _) => write!(
                f,
                "swap of role `{role}` to `{variant}` in flight `{}` failed: {}",
                self.flight,
                error.as_deref().unwrap_or("no reply")
            ),
        }
    }
}

/// What `aeris migrate` reports: the request, every reply, and where the role ended up.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct MigrateReport {
    /// The flight.
    pub flight: String,
    /// The role moved.
    pub role: String,
    /// Where to: an executor, a CPU list or `HOST:EXECUTOR`.
    pub target: String,
    /// Whether the move was done.
    pub ok: bool,
    /// Why not, when it was not.
    pub error: Option<String>,
    /// The role's process after the move (0 when it failed).
    pub pid: u32,
    /// How long the move took (ms; 0 when it failed).
    pub elapsed_ms: u64,
    /// The supervisor's last word: from where to where (empty when it failed).
    pub message: String,
    /// Every reply, in order.
    pub steps: Vec<ControlStep>,
}

impl MigrateReport {
    /// The report of a move of `role` to `target` in `flight` that got `replies` and ended
    /// in `outcome` ([`request_migrate`]).
    pub fn new(
        flight: &str,
        role: &str,
        target: &str,
        replies: &[SupervisorReply],
        outcome: &Result<SupervisorReply, ControlError>,
    ) -> Self {
        let done = outcome.as_ref().ok();
        Self {
            flight: flight.to_string(),
            role: role.to_string(),
            target: target.to_string(),
            ok: done.is_some(),
            error: outcome.as_ref().err().map(ToString::to_string),
            pid: done.map_or(0, |r| r.new_pid),
            elapsed_ms: done.map_or(0, |r| r.elapsed_ms),
            message: done.map_or_else(String::new, |r| r.message.as_str_lossy().to_string()),
            steps: replies.iter().map(ControlStep::from).collect(),
        }
    }
}

impl core::fmt::Display for MigrateReport {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match &self.error {
            None => write!(f, "{} [{} ms]", self.message, self.elapsed_ms),
            Some(e) => write!(
                f,
                "moving role `{}` to `{}` in flight `{}` failed: {e}",
                self.role, self.target, self.flight
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reply(stage: ReplyStage, new_pid: u32, elapsed_ms: u64, message: &str) -> SupervisorReply {
        SupervisorReply {
            old_pid: 10,
            new_pid,
            new_instance: 3,
            elapsed_ms,
            ..SupervisorReply::new(stage, message)
        }
    }

    #[test]
    fn a_done_swap_reports_its_new_process_and_a_refused_one_its_reason() {
        let replies = [
            reply(ReplyStage::Started, 11, 5, "started"),
            reply(ReplyStage::Done, 11, 900, "done"),
        ];
        let done = SwapReport::new("f", "reasoning", "smollm2", &replies, &Ok(replies[1]));
        assert!(done.ok && done.error.is_none());
        assert_eq!(done.steps[0].stage, "started");
        assert_eq!(
            done.to_string(),
            "role `reasoning` now runs `smollm2` as pid 11 (instance 3), old pid 10 stopped, 900 ms"
        );
        let refused = [reply(ReplyStage::Failed, 0, 1, "no such variant")];
        let failed = SwapReport::new(
            "f",
            "reasoning",
            "gpt",
            &refused,
            &Err(ControlError::Failed("no such variant".into())),
        );
        let json = serde_json::to_value(&failed).expect("serialises");
        assert_eq!(json["ok"], false);
        assert_eq!(json["error"], "no such variant");
        assert_eq!(json["steps"][0]["stage"], "failed");
    }

    #[test]
    fn a_move_reports_where_the_role_went_or_why_it_did_not() {
        let replies = [reply(ReplyStage::Done, 12, 40, "moved to cpus 1")];
        let done = MigrateReport::new("f", "perception", "1", &replies, &Ok(replies[0]));
        assert_eq!((done.pid, done.elapsed_ms), (12, 40));
        assert_eq!(done.to_string(), "moved to cpus 1 [40 ms]");
        let failed = MigrateReport::new("f", "hub", "1", &[], &Err(ControlError::Disconnected));
        assert!(!failed.ok && failed.pid == 0 && failed.message.is_empty());
        assert!(
            failed
                .to_string()
                .ends_with("failed: the supervisor stopped answering before the request finished")
        );
    }
}
