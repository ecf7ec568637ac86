//! Printing a flight's events to stderr as they come (`aeris run`, the flight benchmarks,
//! `aeris eval`), and ending it on SIGINT / SIGTERM.

use aeris_flight::{FlightEvent, FlightWatcher};
use aeris_orchestrator::supervisor::SupervisorEvent;
use aeris_runtime::signals;
use anyhow::{Context, Result};

/// Prints a flight's events; interrupts it once a termination signal arrived.
pub struct FlightPrinter {
    /// Print the progress lines (every 2 s).
    progress: bool,
    /// Put before the step hook's lines.
    note_prefix: &'static str,
}

impl FlightPrinter {
    /// A printer (with the progress lines or not; `note_prefix` before the step hook's
    /// lines); installs the termination handlers it watches.
    pub fn new(progress: bool, note_prefix: &'static str) -> Result<Self> {
        signals::install_termination_handlers().context("installing signal handlers")?;
        Ok(Self {
            progress,
            note_prefix,
        })
    }
}

impl FlightWatcher for FlightPrinter {
    fn event(&mut self, event: &FlightEvent) {
        match event {
            FlightEvent::Started {
                flight,
                roles,
                logs,
                instruction,
                accelerators,
                priority,
            } => {
                eprintln!(
                    "aeris: flight {flight}: {roles} roles started (logs in {})",
                    logs.display()
                );
                eprintln!("aeris: mission: {instruction}");
                eprintln!("aeris: {accelerators}");
                eprintln!("aeris: roles' priority over outside work: {priority}");
            }
            FlightEvent::Supervisor(event) => print_supervisor_event(event),
            FlightEvent::Progress(p) if self.progress && p.fleet.is_some() => {
                if let Some(f) = &p.fleet {
                    let heights: Vec<String> = f
                        .positions
                        .iter()
                        .map(|q| q.map_or_else(|| "?".into(), |q| format!("{:.1}", q[2])))
                        .collect();
                    let t = &f.formation;
                    eprintln!(
                        "[{:6.1} s] formation phase {} {}  vehicles {}  heights [{}] m  closest {}  replans {}  restarts {}",
                        p.elapsed_s,
                        t.phase,
                        t.state,
                        t.in_formation,
                        heights.join(", "),
                        f.closest_m
                            .map(|d| format!("{d:.2} m"))
                            .unwrap_or_else(|| "?".into()),
                        t.replans,
                        p.restarts,
                    );
                }
            }
            FlightEvent::Progress(p) if self.progress => {
                let text = p
                    .step_text
                    .as_deref()
                    .unwrap_or("waiting for the first decision");
                eprintln!(
                    "[{:6.1} s] step {}/{} \"{text}\"  distance to goal {}  alt {:.1} m  CT {:.3} s  EER {:.1}%  rejected {}  restarts {}",
                    p.elapsed_s,
                    p.step,
                    p.steps,
                    p.distance_to_goal_m
                        .map(|d| format!("{d:.1} m"))
                        .unwrap_or_else(|| "?".into()),
                    p.position.map_or(f32::NAN, |p| p[2]),
                    p.ct_mean_s,
                    p.eer * 100.0,
                    p.rejected,
                    p.restarts,
                );
            }
            FlightEvent::InvalidReports(n) if self.progress => {
                eprintln!("aeris: {n} hub reports failed validation and were not counted");
            }
            FlightEvent::Note(line) => eprintln!("{}{line}", self.note_prefix),
            FlightEvent::Autopilot(e) => eprintln!("aeris: {e}"),
            FlightEvent::Finished { shutdown, .. } => eprintln!("aeris: shutdown: {shutdown}"),
            FlightEvent::Ready | FlightEvent::Progress(_) | FlightEvent::InvalidReports(_) => {}
        }
    }

    fn interrupted(&self) -> bool {
        signals::termination_requested()
    }
}

fn print_supervisor_event(event: &SupervisorEvent) {
    match event {
        SupervisorEvent::RoleRestarted {
            name,
            pid,
            restarts,
        } => eprintln!("aeris: restarted {name} (pid {pid}, restart #{restarts})"),
        SupervisorEvent::RoleExited { name, status } => {
            eprintln!("aeris: role {name} exited: {status}");
        }
        SupervisorEvent::SwapStarted { .. }
        | SupervisorEvent::SwapReady { .. }
        | SupervisorEvent::SwapDone { .. }
        | SupervisorEvent::SwapFailed { .. }
        | SupervisorEvent::RoleMigrated(_)
        | SupervisorEvent::MoveAcrossHosts { .. }
        | SupervisorEvent::MoveAccelerator { .. }
        | SupervisorEvent::MigrationFailed { .. }
        | SupervisorEvent::RestartFailed { .. }
        | SupervisorEvent::RoleGaveUp { .. }
        | SupervisorEvent::RoleStalled { .. }
        | SupervisorEvent::LinkLost { .. }
        | SupervisorEvent::LinkBack { .. }
        | SupervisorEvent::HostUnreachable { .. }
        | SupervisorEvent::ServiceLost { .. }
        | SupervisorEvent::VariantStepped { .. }
        | SupervisorEvent::BindingProbed { .. }
        | SupervisorEvent::InitialBinding { .. }
        | SupervisorEvent::RoleDegraded { .. }
        | SupervisorEvent::RoleRecovered { .. }
        | SupervisorEvent::Unwatched { .. } => eprintln!("aeris: {event}"),
        // the start line says these (no wildcard: a new event is printed or left out here
        // on purpose; a wildcard hid the accelerator moves and the failed restarts)
        SupervisorEvent::RoleStarted { .. } | SupervisorEvent::FirstHeartbeat { .. } => {}
    }
}
