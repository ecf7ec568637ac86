//! A new instruction for a formation in flight (`aeris formation say`): sent on the flight's
//! `formation/say`, answered by its formation role on `formation/reply`.

use aeris_runtime::bus::{BusError, FlightBus};
use aeris_schemas::{FORMATION_INSTRUCTION_MAX, FormationCommand, SayOutcome, topics};
use std::time::{Duration, Instant};

/// The formation role's answer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SayAnswer {
    /// Accepted, repaired, or refused.
    pub outcome: SayOutcome,
    /// What is flown now, or why it was refused.
    pub text: String,
}

/// Why an instruction got no answer.
#[derive(Debug, thiserror::Error)]
pub enum SayError {
    /// The instruction is empty or longer than a command holds.
    #[error("the instruction must be 1 to {FORMATION_INSTRUCTION_MAX} bytes (it is {0})")]
    Length(usize),
    /// No flight of that name runs on this host.
    #[error("no flight `{0}` is running on this host")]
    NoFlight(String),
    /// The flight's services could not be opened.
    #[error("joining flight `{flight}`")]
    Bus {
        /// The flight.
        flight: String,
        /// Why.
        #[source]
        source: BusError,
    },
    /// Nobody answered in time: no formation role runs in the flight, or it is busy.
    #[error(
        "no formation role of flight `{flight}` answered within {waited_s:.0} s (is it a formation flight?)"
    )]
    NoAnswer {
        /// The flight.
        flight: String,
        /// How long it waited (s).
        waited_s: f64,
    },
    /// The answer could not be read.
    #[error("the formation role's answer has an unknown outcome {0}")]
    BadAnswer(u8),
}

/// Send `instruction` to the formation role of `flight` and wait at most `timeout` for its
/// answer (a language-model variant writes for seconds).
pub fn say(flight: &str, instruction: &str, timeout: Duration) -> Result<SayAnswer, SayError> {
    if instruction.trim().is_empty() || instruction.len() > FORMATION_INSTRUCTION_MAX {
        return Err(SayError::Length(instruction.len()));
    }
    if !aeris_runtime::bus::list_flights()
        .iter()
        .any(|f| f == flight)
    {
        return Err(SayError::NoFlight(flight.to_string()));
    }
    let bus_error = |source| SayError::Bus {
        flight: flight.to_string(),
        source,
    };
    let bus = FlightBus::builder(flight)
        .node_name(&format!("formation-say-{}", std::process::id()))
        .create()
        .map_err(bus_error)?;
    let replies = bus
        .subscriber::<topics::FormationReply>()
        .map_err(bus_error)?;
    let commands = bus.publisher::<topics::FormationSay>().map_err(bus_error)?;
    // unique enough among the tools of one host: the pid and the clock
    let id = (u64::from(std::process::id()) << 32) ^ aeris_runtime::clock::monotonic_ns();
    let mut command = FormationCommand {
        id,
        ..FormationCommand::default()
    };
    command.text.set(instruction);
    commands.publish(&command).map_err(bus_error)?;
    let started = Instant::now();
    loop {
        let mut answer = None;
        replies
            .drain(|r| {
                if r.id == id {
                    answer = Some(*r);
                }
            })
            .map_err(bus_error)?;
        if let Some(r) = answer {
            let outcome = SayOutcome::from_u8(r.outcome).ok_or(SayError::BadAnswer(r.outcome))?;
            return Ok(SayAnswer {
                outcome,
                text: r.text.as_str_lossy().to_string(),
            });
        }
        if started.elapsed() >= timeout {
            return Err(SayError::NoAnswer {
                flight: flight.to_string(),
                waited_s: timeout.as_secs_f64(),
            });
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
