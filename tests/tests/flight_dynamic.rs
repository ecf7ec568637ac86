//! Dynamic scheduling and stall handling end to end, in one flight of the default workflow
//! (on a short hop):
//! - `aeris migrate` moves the running reasoner, live, to the control executor: same pid,
//!   every thread reports the new affinity, so do its heartbeats, no decision is lost;
//! - a role stopped with SIGSTOP (alive, silent) is detected as stalled, killed and
//!   restarted; SIGCONT to the old pid then finds nothing;
//! - the flight still reaches its goal.

use aeris_runtime::affinity::CpuSet;
use aeris_runtime::bus::FlightBus;
use aeris_schemas::{RoleStatusEntry, SupervisorStatus, topics};
use aeris_tests::*;
use std::process::Command;
use std::time::Duration;

fn entry(board: &SupervisorStatus, role: &str) -> Option<RoleStatusEntry> {
    board
        .roles()
        .iter()
        .find(|r| r.name.as_str() == Some(role))
        .copied()
}

/// The affinity of every thread of `pid`.
fn thread_affinities(pid: u32) -> Vec<(i32, CpuSet)> {
    std::fs::read_dir(format!("/proc/{pid}/task"))
        .expect("task list")
        .filter_map(|t| t.ok()?.file_name().to_str()?.parse::<i32>().ok())
        // a thread that exited meanwhile has no affinity to read
        .filter_map(|tid| Some((tid, CpuSet::of_task(tid).ok()?)))
        .collect()
}

#[test]
fn a_role_moves_live_and_a_stopped_role_is_replaced_while_the_flight_completes() {
    let dir = TempDir::new("dynamic");
    let flight = unique_flight("dynamic");
    // the move and the stall are the subject, not the route: a short hop
    let hop = short_hop_workflow(&dir.0);
    let mut run = spawn_run(&dir.0, &flight, &[hop.to_str().unwrap()]);
    let observer = FlightBus::builder(&flight)
        .node_name("test-observer")
        .create()
        .unwrap();
    let board = poll_flight(
        &mut run,
        &dir.0,
        "the flight came up",
        Duration::from_secs(120),
        || {
            observer
                .read_status_board()
                .ok()
                .filter(|b| b.role_count >= 6 && b.roles().iter().all(|r| r.heartbeats > 0))
        },
    );
    let before = entry(&board, "reasoning").unwrap();
    let hub = entry(&board, "hub").unwrap();
    let heartbeats = observer.subscriber::<topics::Heartbeat>().unwrap();
    let target_cpus = CpuSet::parse(hub.cpus.as_str().unwrap()).unwrap();

    // --- live move by hand
    let out = Command::new(aeris_bin())
        .args([
            "migrate",
            "reasoning",
            "control",
            "--json",
            "--flight",
            &flight,
        ])
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    let reply: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stderr)));
    assert!(out.status.success(), "{reply}");
    assert_eq!(reply["ok"], true, "{reply}");
    assert_eq!(reply["pid"], before.pid, "{reply}");
    let threads = thread_affinities(before.pid);
    assert!(!threads.is_empty());
    for (tid, cpus) in &threads {
        assert_eq!(cpus, &target_cpus, "thread {tid} of the moved reasoner");
    }
    let moved = poll_until(Duration::from_secs(30), || {
        let b = observer.read_status_board().ok()?;
        entry(&b, "reasoning").filter(|r| r.migrations == 1)
    })
    .expect("the board shows the move");
    assert_eq!(moved.pid, before.pid, "a live move keeps the process");
    assert_eq!(
        moved.restarts, before.restarts,
        "a live move restarts nothing"
    );
    assert_eq!(moved.executor.as_str(), Some("control"));
    assert_eq!(moved.cpus.as_str(), hub.cpus.as_str());
    // and it keeps working there: heartbeats from the same process go on
    poll_until(Duration::from_secs(60), || {
        let b = observer.read_status_board().ok()?;
        entry(&b, "reasoning")
            .filter(|r| r.pid == before.pid && r.heartbeats > moved.heartbeats + 5)
            .map(|_| ())
    })
    .expect("the moved reasoner keeps sending heartbeats");
    // and its own heartbeats say where it runs now
    let mut last = None;
    poll_until(Duration::from_secs(60), || {
        let mut relabelled = false;
        heartbeats
            .drain(|hb| {
                if hb.pid == before.pid {
                    last = Some(*hb);
                    relabelled |= hb.executor.as_str() == hub.cpus.as_str();
                }
            })
            .unwrap();
        relabelled.then_some(())
    })
    .unwrap_or_else(|| {
        panic!(
            "the moved reasoner's heartbeats do not name the CPUs it was moved to ({:?}); the last: {last:?}",
            hub.cpus
        )
    });

    // refusals are clear errors, and move nothing
    let bad = Command::new(aeris_bin())
        .args(["migrate", "reasoning", "9999", "--flight", &flight])
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("does not exist") || err.contains("CPU"),
        "{err}"
    );

    // --- a stalled role: alive (stopped), silent
    let perception = entry(&observer.read_status_board().unwrap(), "perception").unwrap();
    // SAFETY: kill(2) with a pid the supervisor reports for a child it owns.
    assert_eq!(
        unsafe { libc::kill(perception.pid as i32, libc::SIGSTOP) },
        0
    );
    let replaced = poll_until(Duration::from_secs(60), || {
        let b = observer.read_status_board().ok()?;
        entry(&b, "perception").filter(|r| {
            r.stalls == 1
                && r.pid != 0
                && r.pid != perception.pid
                && r.heartbeats > perception.heartbeats
        })
    })
    .unwrap_or_else(|| {
        panic!(
            "the stopped role was not replaced: {:?}",
            run_output(&dir.0)
        )
    });
    assert_eq!(replaced.restarts, perception.restarts + 1);
    // the stopped process was killed: continuing it finds nothing (or a zombie being reaped)
    // SAFETY: kill(2) on a pid we stopped; ESRCH is the expected answer.
    let cont = unsafe { libc::kill(perception.pid as i32, libc::SIGCONT) };
    if cont == 0 {
        let state =
            std::fs::read_to_string(format!("/proc/{}/stat", perception.pid)).unwrap_or_default();
        assert!(
            state.is_empty() || state.contains(") Z"),
            "the stalled process still runs: {state}"
        );
    }

    let status = wait_bounded(&mut run.0, Duration::from_secs(600)).expect("flight finished");
    let (stdout, stderr) = run_output(&dir.0);
    assert!(
        status.success(),
        "aeris run failed: {status}\n{stderr}\n{}",
        run_logs_tail(&dir.0, 20)
    );
    let summary = last_json_line(&stdout);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{stderr}");
    assert!(summary["migrations"].as_u64().unwrap() >= 1, "{summary}");
    assert_eq!(summary["stalls"], 1, "{summary}");
    assert_eq!(summary["sequence_gaps"], 0, "no decision lost: {summary}");
    assert!(stderr.contains("stalled"), "{stderr}");
    assert!(
        stderr.contains("moved from perception to control"),
        "{stderr}"
    );
    let moves = std::fs::read_to_string(dir.0.join("run").join("scheduling.jsonl")).unwrap();
    assert!(moves.contains("\"role\":\"reasoning\""), "{moves}");
}
