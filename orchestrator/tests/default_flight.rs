//! The default workflow with the real `aeris` binary: every role starts bound to its
//! executor, sends heartbeats, shows up on the status board, comes back after a crash, and
//! stops cleanly on SIGTERM.
//!
//! Needs `target/<profile>/aeris`: run `cargo build --bin aeris` first (scripts/test.sh does).

use aeris_orchestrator::restart::RoleExit;
use aeris_orchestrator::{
    ShutdownOutcome, Supervisor, SupervisorEvent, SupervisorOptions, Workflow,
};
use aeris_runtime::affinity::CpuSet;
use aeris_schemas::RoleStatus;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Upper bound for anything the test waits on; reaching it is a failure, not a measurement.
const PATIENCE: Duration = Duration::from_secs(60);

fn aeris_bin() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    // target/<profile>/deps/<test> -> target/<profile>/aeris
    let bin = exe.parent().and_then(|d| d.parent()).unwrap().join("aeris");
    assert!(
        bin.exists(),
        "{} is missing: run `cargo build --bin aeris` first",
        bin.display()
    );
    bin
}

#[test]
fn the_default_flight_comes_up_reports_and_stops_cleanly() {
    let run_dir = std::env::temp_dir().join(format!("aeris-orch-default-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&run_dir);
    let mut sup = Supervisor::start(SupervisorOptions {
        workflow: Workflow::builtin_default().unwrap(),
        flight: format!("orch-default-{}", std::process::id()),
        aeris_exe: aeris_bin(),
        run_dir: run_dir.clone(),
        autopilot: None,
        sim_clock: None,
    })
    .unwrap();
    // this test checks the declared binding (heartbeats name it): no automatic moves
    sup.set_dynamic(false);
    if let Err(e) = sup.wait_ready(PATIENCE) {
        panic!("{e}");
    }
    // every role keeps running and reports cycles with latencies
    let start = Instant::now();
    loop {
        let events = sup.step().unwrap();
        for e in &events {
            eprintln!("{e}");
        }
        let done = sup.roles().iter().all(|r| {
            r.last_heartbeat()
                .is_some_and(|h| h.status == RoleStatus::Running as u8)
                && r.latency_ms().is_some()
        });
        if done {
            break;
        }
        assert!(
            start.elapsed() < PATIENCE,
            "roles not all running with latencies: {:#?}",
            sup.roles()
                .iter()
                .map(|r| (
                    r.name(),
                    r.last_heartbeat().map(|h| h.status),
                    r.latency_ms(),
                    r.pid()
                ))
                .collect::<Vec<_>>()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(sup.total_restarts(), 0);
    // every thread of every role runs on its executor's CPUs
    for role in sup.roles() {
        let want = CpuSet::parse(role.cpus()).unwrap();
        let pid = role.pid().unwrap();
        for task in std::fs::read_dir(format!("/proc/{pid}/task")).unwrap() {
            let status = std::fs::read_to_string(task.unwrap().path().join("status"));
            let Ok(status) = status else { continue }; // the thread just ended
            let list = status
                .lines()
                .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
                .unwrap()
                .trim();
            assert_eq!(
                CpuSet::parse(list).unwrap(),
                want,
                "a thread of {}",
                role.name()
            );
        }
    }
    let board = sup.bus().read_status_board().unwrap();
    assert_eq!(board.roles().len(), 7);
    for (entry, role) in board.roles().iter().zip(sup.roles()) {
        assert_eq!(entry.name.as_str(), Some(role.name()));
        assert_eq!(entry.pid, role.pid().unwrap());
        assert!(entry.heartbeats > 0);
        // the role reports the executor it was bound to
        assert_eq!(
            role.last_heartbeat().unwrap().executor.as_str(),
            Some(role.cpus())
        );
    }
    // a crashed role is restarted and comes back
    let victim = sup.role("perception").unwrap().pid().unwrap();
    // SAFETY: kill has no memory-safety preconditions; the pid is our child, unreaped.
    assert_eq!(unsafe { libc::kill(victim as i32, libc::SIGKILL) }, 0);
    let start = Instant::now();
    let mut seen = Vec::new();
    loop {
        seen.extend(sup.step().unwrap());
        let restarted = seen.iter().position(|e| {
            matches!(e, SupervisorEvent::RoleRestarted { name, restarts: 1, .. } if name == "perception")
        });
        let back = restarted.is_some_and(|at| {
            seen[at..].iter().any(
                |e| matches!(e, SupervisorEvent::FirstHeartbeat { name } if name == "perception"),
            )
        });
        if back {
            break;
        }
        assert!(
            start.elapsed() < PATIENCE,
            "perception did not come back: {seen:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(seen.contains(&SupervisorEvent::RoleExited {
        name: "perception".into(),
        status: RoleExit::Signal(libc::SIGKILL)
    }));
    assert_ne!(sup.role("perception").unwrap().pid(), Some(victim));
    assert_eq!(sup.total_restarts(), 1);

    let report = sup.shutdown(Duration::from_secs(10));
    eprintln!("{report}");
    for e in &report.roles {
        assert_eq!(
            e.outcome,
            ShutdownOutcome::Exited(RoleExit::Code(0)),
            "{}",
            e.name
        );
    }
    let _ = std::fs::remove_dir_all(&run_dir);
}
