//! Hot-standby controller end to end: in the default flight on a short hop (a primary controller and a
//! standby on one autopilot link), the controller holding the autopilot lease is SIGKILLed,
//! later the new holder is SIGSTOPped. Each time the *other* process, not a restarted one,
//! must take the lease with a higher epoch, and the flight must still reach its goal with
//! every controller process left on the lease's word (no two holders at the end).

use aeris_runtime::bus::FlightBus;
use aeris_schemas::{ControllerLease, SupervisorStatus, topics};
use aeris_tests::*;
use std::time::Duration;

/// The pid of the role `name` on the board.
fn pid_of(board: &SupervisorStatus, name: &str) -> Option<u32> {
    board
        .roles()
        .iter()
        .find(|r| r.name.as_str() == Some(name))
        .map(|r| r.pid)
        .filter(|p| *p != 0)
}

#[test]
fn the_standby_takes_the_lease_when_the_holder_is_killed_or_stopped() {
    let dir = TempDir::new("standby");
    let flight = unique_flight("standby");
    // the lease's hand-overs are the subject, not the route: a short hop
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(&dir.0, &flight, &[hop.to_str().unwrap()]);
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let leases = observer.subscriber::<topics::ControllerLease>().unwrap();
    // the newest lease sample with an epoch above `above`
    let newest = |above: u64| {
        let mut out: Option<ControllerLease> = None;
        leases
            .drain(|l| {
                if l.epoch > above && out.is_none_or(|o| l.key() > o.key()) {
                    out = Some(*l);
                }
            })
            .unwrap();
        out
    };

    // faults in flight, not during start-up: every role up and a decision committed (CI once
    // killed the holder 0.6 s after the start, before the hub's first setpoint, and once
    // stopped the other controller before its first heartbeat)
    let board = poll_flight(
        &mut run,
        &dir.0,
        "the flight came up",
        Duration::from_secs(120),
        || {
            observer.read_status_board().ok().filter(|b| {
                b.active_step >= 1 && b.roles().iter().all(|r| r.pid != 0 && r.heartbeats > 0)
            })
        },
    );
    // a holder that tracks the hub's setpoints: its reference is what a takeover adopts
    let holder = poll_until(Duration::from_secs(60), || {
        newest(0).filter(|l| l.flags & aeris_schemas::LEASE_HAS_REFERENCE != 0)
    })
    .unwrap_or_else(|| panic!("no controller took the lease: {:?}", run_output(&dir.0)));
    let controllers = ["controller", "controller-standby"];
    let pids: Vec<u32> = controllers
        .iter()
        .map(|c| pid_of(&board, c).expect("both controllers run"))
        .collect();
    assert!(pids.contains(&holder.holder_pid), "{holder:?} vs {pids:?}");
    let other = *pids.iter().find(|p| **p != holder.holder_pid).unwrap();

    // SIGKILL the holder: the other process (same pid: not restarted) takes over
    // SAFETY: kill(2) with a pid the supervisor reports for a child it owns.
    assert_eq!(
        unsafe { libc::kill(holder.holder_pid as i32, libc::SIGKILL) },
        0
    );
    let second =
        poll_until(Duration::from_secs(60), || newest(holder.epoch)).unwrap_or_else(|| {
            panic!(
                "no new lease after the holder was killed:\n{}\n{}",
                run_output(&dir.0).1,
                run_logs_tail(&dir.0, 30)
            )
        });
    assert_eq!(second.holder_pid, other, "{second:?}");
    assert!(second.flags & aeris_schemas::LEASE_HAS_REFERENCE != 0);

    // SIGSTOP the new holder: the restarted first controller takes over from it
    // SAFETY: as above.
    assert_eq!(unsafe { libc::kill(other as i32, libc::SIGSTOP) }, 0);
    let third = poll_until(Duration::from_secs(60), || newest(second.epoch)).unwrap_or_else(|| {
        panic!(
            "no new lease after the holder was stopped:\n{}\n{}",
            run_output(&dir.0).1,
            run_logs_tail(&dir.0, 30)
        )
    });
    assert_ne!(third.holder_pid, other);
    assert_ne!(
        third.holder_pid, holder.holder_pid,
        "a dead process holds it"
    );
    // (the supervisor finds the stopped process stalled, kills it and starts a new standby)

    let status = wait_bounded(&mut run.0, Duration::from_secs(900)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(status.success(), "aeris run failed: {status}\n{stderr}");
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert!(summary["role_restarts"].as_u64().unwrap() >= 1, "{summary}");
}
