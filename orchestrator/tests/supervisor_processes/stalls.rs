//! Stall detection with real processes: a role stopped before its first heartbeat is
//! replaced, and a pause of the supervisor itself is not held against the roles.

use super::*;

/// A role stopped (SIGSTOP) before its first heartbeat is stalled as surely as one stopped
/// later: killed and restarted, instead of waiting for the hard timeout (60 s).
#[test]
fn a_role_stopped_before_its_first_heartbeat_is_replaced() {
    let run = RunDir::new("early-stop");
    let mut w = Workflow::builtin_default().unwrap();
    w.roles
        .iter_mut()
        .find(|r| r.name == "hub")
        .unwrap()
        .backoff_ms = 1;
    let mut sup = Supervisor::start(options(w, "early-stop", &run)).unwrap();
    let pid = sup.role("hub").unwrap().pid().unwrap();
    // SAFETY: kill(2) on a child the supervisor started and still owns.
    assert_eq!(unsafe { libc::kill(pid as i32, libc::SIGSTOP) }, 0);
    let events = step_until(&mut sup, "the stopped hub replaced", |s, _| {
        let hub = s.role("hub").unwrap();
        hub.stalls() == 1 && hub.pid().is_some_and(|p| p != pid)
    });
    let why = events
        .iter()
        .find_map(|e| match e {
            SupervisorEvent::RoleStalled {
                name, pid: p, why, ..
            } if name == "hub" => {
                assert_eq!(*p, pid);
                Some(why.clone())
            }
            _ => None,
        })
        .expect("a stall event");
    assert!(why.contains("before its first heartbeat"), "{why}");
    // no other role was taken for stalled: they are silent (no heartbeats here) but running
    for r in sup.roles() {
        if r.name() != "hub" {
            assert_eq!(r.stalls(), 0, "{}", r.name());
        }
    }
    let _ = sup.shutdown(PATIENCE);
}

/// A pause of the supervisor itself (a machine paused: nobody ran, so no role sent a
/// heartbeat) is not the roles' silence: the step after it says so and kills no role; a role
/// that stays silent while the supervisor watches is still stalled.
#[test]
fn a_pause_of_the_supervisor_is_discounted_and_a_silence_it_watches_is_not() {
    let run = RunDir::new("pause");
    let w = Workflow::builtin_default().unwrap();
    let stall_timeout = Duration::from_millis(w.scheduling.stall_timeout_ms);
    let mut sup = Supervisor::start(options(w, "pause", &run)).unwrap();
    let bus = FlightBus::builder(sup.flight())
        .node_name("fake-roles")
        .create()
        .unwrap();
    let hbs: TypedPublisher<RoleHeartbeat> = bus.publisher::<topics::Heartbeat>().unwrap();
    for role in sup.roles() {
        hbs.publish(&heartbeat(
            role.name(),
            role.pid().unwrap(),
            1,
            RoleStatus::Running,
            1,
        ))
        .unwrap();
    }
    sup.wait_ready(PATIENCE).unwrap();
    sup.step().unwrap();
    // the pause under test: no step and no heartbeat for twice the stall timeout (the fake
    // roles sleep: without the discount each is "neither running nor runnable" at once)
    std::thread::sleep(2 * stall_timeout);
    let events = sup.step().unwrap();
    assert!(
        events.iter().any(|e| matches!(
            e,
            SupervisorEvent::Unwatched { gap_ms, .. } if *gap_ms >= 2 * stall_timeout.as_millis() as u64
        )),
        "{events:?}"
    );
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, SupervisorEvent::RoleStalled { .. })),
        "{events:?}"
    );
    assert!(sup.roles().iter().all(|r| r.stalls() == 0));
    // watched silence: every role is stalled in time (the hub first among them or not)
    step_until(&mut sup, "the silent hub stalled", |s, _| {
        s.role("hub").unwrap().stalls() == 1
    });
    let _ = sup.shutdown(PATIENCE);
}
