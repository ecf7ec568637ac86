//! The clock a flight runs on: the wall clock (a real vehicle's, the default), or simulated
//! time ([`aeris_runtime::clock::sim`]): every role takes its turns in lockstep, time
//! stands still while any role works, and the flight runs as fast as its roles compute,
//! with the same result on any machine.
//!
//! On simulated time the flight's thread is the clock's master: between two supervisor
//! steps it moves time on by one step period ([`FlightTime::pass`]), so the monitor sees
//! every step period of the flight, as on the wall clock. The supervisor's own liveness
//! checks stay on the wall clock (a role waiting for its turn says it is alive).

use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::clock::sim::{Advance, SimClockError, SimClockMaster};
use aeris_schemas::RoleKind;
use std::path::Path;
use std::time::Duration;

/// Where a flight's simulated time starts (ns): a fixed instant, so that two flights stamp
/// the same instants.
pub const SIM_START_NS: u64 = 1_000_000_000;

/// The clock a flight runs on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FlightClock {
    /// CLOCK_MONOTONIC: the only clock of a real vehicle.
    #[default]
    Wall,
    /// Simulated time, in lockstep (the built-in simulator or a replay).
    Sim,
}

impl FlightClock {
    /// `wall` or `sim`.
    pub fn name(self) -> &'static str {
        match self {
            FlightClock::Wall => "wall",
            FlightClock::Sim => "sim",
        }
    }
}

impl core::fmt::Display for FlightClock {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

impl core::str::FromStr for FlightClock {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "wall" => Ok(FlightClock::Wall),
            "sim" => Ok(FlightClock::Sim),
            other => Err(format!("unknown clock `{other}` (use wall or sim)")),
        }
    }
}

/// Why a flight cannot run on simulated time.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SimTimeRefusal {
    /// A real autopilot keeps its own time.
    #[error("the flight flies the external autopilot {url}, which keeps its own time")]
    ExternalAutopilot {
        /// Its MAVLink URL.
        url: String,
    },
    /// A real camera delivers frames on the wall clock.
    #[error(
        "role `{role}` is a real camera (variant `{variant}`), which delivers frames on the wall clock"
    )]
    RealCamera {
        /// The role.
        role: String,
        /// Its variant.
        variant: String,
    },
    /// Roles on other hosts are not stepped by this host's clock yet.
    #[error(
        "role `{role}` runs on host `{host}`; roles on other hosts do not follow simulated time yet"
    )]
    RemoteRole {
        /// The role.
        role: String,
        /// Its host.
        host: String,
    },
    /// More role processes than one simulated clock holds.
    #[error("the flight has {roles} roles; simulated time holds at most {max}")]
    TooManyRoles {
        /// Roles of the workflow.
        roles: usize,
        /// [`aeris_runtime::clock::sim::MAX_PARTICIPANTS`].
        max: usize,
    },
    /// The workflow has no simulated vehicle or replay to fly.
    #[error("the workflow has no simulated vehicle and no replay: nothing to simulate")]
    NothingSimulated,
}

/// `Ok` when `workflow`, flown against `autopilot` (`None`: its own vehicle), can run on
/// simulated time.
pub fn check_sim_time(workflow: &Workflow, autopilot: Option<&str>) -> Result<(), SimTimeRefusal> {
    if let Some(url) = autopilot {
        return Err(SimTimeRefusal::ExternalAutopilot {
            url: url.to_string(),
        });
    }
    for role in &workflow.roles {
        if let Some(host) = workflow.role_host(role) {
            return Err(SimTimeRefusal::RemoteRole {
                role: role.name.clone(),
                host: host.name.clone(),
            });
        }
        if role.kind == RoleKind::Camera && role.variant == "gstreamer" {
            return Err(SimTimeRefusal::RealCamera {
                role: role.name.clone(),
                variant: role.variant.clone(),
            });
        }
    }
    let max = aeris_runtime::clock::sim::MAX_PARTICIPANTS;
    if workflow.roles.len() > max {
        return Err(SimTimeRefusal::TooManyRoles {
            roles: workflow.roles.len(),
            max,
        });
    }
    if !workflow
        .roles
        .iter()
        .any(|r| matches!(r.kind, RoleKind::Vehicle | RoleKind::Replay))
    {
        return Err(SimTimeRefusal::NothingSimulated);
    }
    Ok(())
}

/// The flight's time as its thread keeps it.
#[derive(Debug)]
pub(crate) enum FlightTime {
    /// The wall clock: a step period passes by sleeping.
    Wall,
    /// Simulated time: a step period passes when every role has had its turns in it.
    Sim {
        master: SimClockMaster,
        /// The instant the present step period ends.
        until_ns: u64,
        /// The time reached `until_ns` and every role due by then has had its turn.
        reached: bool,
        /// When the flight's time last moved or a period was done (wall clock), and the
        /// time then: a watchdog for a turn that never ends.
        moved: (std::time::Instant, u64),
        /// The role process the last pass waited for, if any.
        waiting_for: Option<u32>,
    },
}

impl FlightTime {
    /// Simulated time in a new segment at `path` (one left there by an earlier flight in
    /// the same run directory is replaced).
    pub(crate) fn simulated(path: &Path) -> Result<Self, SimClockError> {
        match std::fs::remove_file(path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(source) => {
                return Err(SimClockError::Map {
                    path: path.to_path_buf(),
                    source,
                });
            }
        }
        // the roles are counted once they are planned (`expect`)
        let master = SimClockMaster::create(path, SIM_START_NS, usize::MAX)?;
        Ok(FlightTime::Sim {
            master,
            until_ns: SIM_START_NS,
            reached: false,
            moved: (std::time::Instant::now(), SIM_START_NS),
            waiting_for: None,
        })
    }

    /// The segment's file, on simulated time.
    pub(crate) fn segment(&self) -> Option<&Path> {
        match self {
            FlightTime::Wall => None,
            FlightTime::Sim { master, .. } => Some(master.path()),
        }
    }

    /// Time waits for `roles` roles to join before it first moves.
    pub(crate) fn expect(&mut self, roles: usize) {
        if let FlightTime::Sim { master, .. } = self {
            master.expect(roles);
        }
    }

    /// The flight's time (ns).
    pub(crate) fn now_ns(&self) -> u64 {
        match self {
            FlightTime::Wall => aeris_runtime::clock::wall_ns(),
            FlightTime::Sim { master, .. } => master.now_ns(),
        }
    }

    /// `true` when the flight's time is at the end of a step period: always on the wall
    /// clock; on simulated time once [`FlightTime::pass`] has reached it (every role done
    /// with it), not while a role still works inside the period.
    pub(crate) fn step_done(&self) -> bool {
        match self {
            FlightTime::Wall => true,
            FlightTime::Sim { reached, .. } => *reached,
        }
    }

    /// On simulated time, how long (wall clock) the flight's time has stood still inside a
    /// step period, and the role process it waits for; `None` on the wall clock.
    pub(crate) fn standing_still(&self) -> Option<(Duration, Option<u32>)> {
        match self {
            FlightTime::Wall => None,
            FlightTime::Sim {
                moved, waiting_for, ..
            } => Some((moved.0.elapsed(), *waiting_for)),
        }
    }

    /// Let `step` of the flight's time pass. On simulated time: move time on to the end of
    /// the present step period, for at most `step` of wall-clock time (a role still
    /// working then is waited for in the next call, after the supervisor has stepped).
    pub(crate) fn pass(&mut self, step: Duration) {
        match self {
            FlightTime::Wall => std::thread::sleep(step),
            FlightTime::Sim {
                master,
                until_ns,
                reached,
                moved,
                waiting_for,
            } => {
                if *reached {
                    *until_ns = until_ns.saturating_add(aeris_runtime::clock::duration_ns(step));
                }
                // a role still working is waited for in the next call
                let advance = master.advance(*until_ns, step);
                *reached = advance == Advance::Reached;
                *waiting_for = match advance {
                    Advance::Working { pid } => pid,
                    Advance::Reached => None,
                };
                let now = master.now_ns();
                if *reached || now != moved.1 {
                    *moved = (std::time::Instant::now(), now);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flights_that_cannot_follow_simulated_time_are_refused_by_name() {
        let w = Workflow::builtin_default().expect("default workflow");
        assert_eq!(check_sim_time(&w, None), Ok(()));
        let e = check_sim_time(&w, Some("udpin:0.0.0.0:14540")).expect_err("external");
        assert!(e.to_string().contains("udpin:0.0.0.0:14540"), "{e}");
        let mut camera = w.clone();
        let cam = camera
            .roles
            .iter_mut()
            .find(|r| r.kind == RoleKind::Camera)
            .expect("a camera");
        cam.variant = "gstreamer".into();
        let name = cam.name.clone();
        let e = check_sim_time(&camera, None).expect_err("real camera");
        assert!(e.to_string().contains(&format!("`{name}`")), "{e}");
        let mut none = w.clone();
        none.roles.retain(|r| r.kind != RoleKind::Vehicle);
        assert_eq!(
            check_sim_time(&none, None),
            Err(SimTimeRefusal::NothingSimulated)
        );
        assert_eq!("sim".parse::<FlightClock>(), Ok(FlightClock::Sim));
        assert!("fast".parse::<FlightClock>().is_err());
    }
}
