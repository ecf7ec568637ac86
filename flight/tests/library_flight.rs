//! Flights through the library, with real role processes: the built-in default workflow
//! flown to its goal (on the short hop) while its events and status are watched; a flight stopped mid-air and
//! one dropped mid-air leave no role process behind; start-up failures come back from
//! `start()`.
//!
//! Needs `target/<profile>/aeris`: run `cargo build -p aeris` first (scripts/test.sh builds
//! the workspace before testing it).

use aeris_flight::{
    Flight, FlightError, FlightEvent, FlightFailure, FlightPhase, OverrideError, Overrides,
    StopRule, VariantChoice,
};
use aeris_orchestrator::Workflow;
use aeris_tests::aeris_bin;
use std::path::PathBuf;

fn run_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aeris-flight-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn flight(tag: &str) -> aeris_flight::FlightBuilder {
    Flight::builder(Workflow::builtin_default().unwrap())
        .name(format!("lib-{tag}-{}", std::process::id()))
        .run_dir(run_dir(tag))
        .role_executable(aeris_bin())
}

/// `true` while a process with this pid exists (zombies included).
fn process_exists(pid: u32) -> bool {
    // SAFETY: signal 0 only checks that the pid exists; nothing is delivered.
    unsafe { libc::kill(pid as i32, 0) == 0 }
}

/// Events until `Ready` (panics on any other end); then the pids of every role, each
/// checked alive.
fn role_pids_once_ready(flight: &Flight) -> Vec<u32> {
    assert!(
        flight
            .events()
            .iter()
            .any(|event| matches!(event, FlightEvent::Ready)),
        "the flight ended before every role was up"
    );
    let pids: Vec<u32> = flight.status().roles.iter().filter_map(|r| r.pid).collect();
    assert!(pids.len() >= 6, "{pids:?}");
    assert!(pids.iter().all(|&p| process_exists(p)), "{pids:?}");
    pids
}

fn assert_all_gone(pids: &[u32]) {
    for &pid in pids {
        assert!(
            !process_exists(pid),
            "role process {pid} outlived the flight"
        );
    }
}

#[test]
fn the_default_workflow_flies_to_its_goal_through_the_library() {
    // the subject is the library (events, status, summary), not the mission or its timing:
    // the short hop, on simulated time (as fast as the roles compute); the wall clock's
    // flights through the same library are the tests below and every `aeris run`
    let hop = Workflow::from_toml_str(&aeris_tests::short_hop_text()).unwrap();
    let flight = Flight::builder(hop)
        .name(format!("lib-goal-{}", std::process::id()))
        .run_dir(run_dir("goal"))
        .role_executable(aeris_bin())
        .clock(aeris_flight::FlightClock::Sim)
        .stop_when(StopRule::Goal)
        .start()
        .unwrap();
    assert_eq!(flight.status().flight, flight.name());
    let (mut started, mut ready, mut progress, mut finished) = (false, false, 0, false);
    let mut status_in_flight = None;
    for event in flight.events().iter() {
        match event {
            FlightEvent::Started { roles, .. } => {
                assert!(!ready && progress == 0, "Started comes first");
                assert!(roles >= 6, "{roles} roles");
                started = true;
            }
            FlightEvent::Ready => {
                assert!(started, "Ready after Started");
                ready = true;
            }
            FlightEvent::Progress(p) => {
                assert!(ready, "progress only once every role is up");
                assert!(p.steps > 0 && p.step <= p.steps, "{p:?}");
                progress += 1;
                if status_in_flight.is_none() {
                    status_in_flight = Some(flight.status());
                }
            }
            FlightEvent::Finished { failure, shutdown } => {
                assert_eq!(failure, None);
                assert_eq!(shutdown.roles.len(), flight.status().roles.len());
                finished = true;
            }
            _ => {}
        }
    }
    assert!(started && ready && progress > 0 && finished);
    let status = status_in_flight.expect("a status while flying");
    assert_eq!(status.phase, FlightPhase::Flying);
    assert!(status.progress.is_some());
    assert!(status.roles.len() >= 6);
    assert!(status.roles.iter().all(|r| r.pid.is_some()), "{status:?}");
    assert_eq!(flight.status().phase, FlightPhase::Finished);

    let run_dir = flight.run_dir().to_path_buf();
    let outcome = flight.wait().unwrap();
    assert_eq!(outcome.failure, None);
    let s = &outcome.summary;
    assert!(s.reached_goal, "{s:?}");
    assert!(s.final_distance_m <= 3.0, "{s:?}");
    assert!(s.cycles > 0 && s.cycles_committed > 0, "{s:?}");
    assert!(s.controller_ticks > 0, "{s:?}");
    assert_eq!(outcome.ct_samples_s.len() as u64, s.cycles_committed);
    let trace = std::fs::read_to_string(run_dir.join("cycles.jsonl")).unwrap();
    assert_eq!(trace.lines().count(), outcome.trace.len());
    let _ = std::fs::remove_dir_all(run_dir);
}

#[test]
fn a_flight_stopped_mid_air_ends_stopped_with_every_role_gone() {
    let flight = flight("stop").stop_when(StopRule::Hook).start().unwrap();
    let pids = role_pids_once_ready(&flight);
    flight.stop();
    flight.stop(); // idempotent
    let run_dir = flight.run_dir().to_path_buf();
    let outcome = flight.wait().unwrap();
    assert_eq!(outcome.failure, Some(FlightFailure::Stopped));
    assert_eq!(outcome.failure.unwrap().to_string(), "stopped");
    assert_all_gone(&pids);
    let _ = std::fs::remove_dir_all(run_dir);
}

#[test]
fn dropping_a_flight_stops_every_role() {
    let flight = flight("drop").stop_when(StopRule::Hook).start().unwrap();
    let pids = role_pids_once_ready(&flight);
    let run_dir = flight.run_dir().to_path_buf();
    drop(flight);
    assert_all_gone(&pids);
    let _ = std::fs::remove_dir_all(run_dir);
}

#[test]
fn start_up_failures_come_back_from_start() {
    let missing = flight("no-exe")
        .role_executable("/nonexistent/aeris")
        .start();
    assert!(
        matches!(missing, Err(FlightError::Start(_))),
        "{:?}",
        missing.err()
    );
    let unknown_role = flight("no-role")
        .overrides(Overrides {
            variants: vec![VariantChoice {
                role: "nobody".into(),
                variant: "planner".into(),
            }],
            ..Overrides::default()
        })
        .start();
    assert!(
        matches!(
            unknown_role,
            Err(FlightError::Overrides(OverrideError::UnknownRole { .. }))
        ),
        "{:?}",
        unknown_role.err()
    );
    let _ = std::fs::remove_dir_all(run_dir("no-exe"));
}

#[test]
fn a_step_hook_ends_the_flight_or_fails_it_with_its_own_error() {
    // a closure hook sees the monitor every step; returning true ends the flight, unfailed
    let ended = flight("hook-ends")
        .stop_when(StopRule::Hook)
        .on_step(|ctx| Ok(ctx.monitor.cycles() >= 2))
        .start()
        .unwrap();
    let run_dir = ended.run_dir().to_path_buf();
    let outcome = ended.wait().unwrap();
    assert_eq!(outcome.failure, None);
    assert!(outcome.summary.cycles >= 2, "{:?}", outcome.summary);
    let _ = std::fs::remove_dir_all(run_dir);

    // an error of the hook ends the flight and comes back from wait() as it was
    let failing = flight("hook-fails")
        .stop_when(StopRule::Hook)
        .on_step(|_| Err("the hook gave up".into()))
        .start()
        .unwrap();
    let run_dir = failing.run_dir().to_path_buf();
    let pids: Vec<u32> = failing
        .status()
        .roles
        .iter()
        .filter_map(|r| r.pid)
        .collect();
    match failing.wait() {
        Err(e @ FlightError::Hook(_)) => assert_eq!(e.to_string(), "the hook gave up"),
        other => panic!(
            "expected the hook's error, got {:?}",
            other.map(|o| o.failure)
        ),
    }
    assert_all_gone(&pids);
    let _ = std::fs::remove_dir_all(run_dir);
}
