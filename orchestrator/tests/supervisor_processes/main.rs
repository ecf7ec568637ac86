//! The supervisor with real processes: a small shell script stands in for the `aeris`
//! binary (it sleeps, crashes or ignores SIGTERM depending on the role name), and the test
//! itself publishes the roles' heartbeats over iceoryx2. Polling loops have generous
//! deadlines that only turn a hang into a failure; no test depends on timing.

use aeris_orchestrator::restart::RoleExit;
use aeris_orchestrator::{
    RoleState, ShutdownOutcome, Supervisor, SupervisorError, SupervisorEvent, SupervisorOptions,
    Workflow,
};
use aeris_runtime::FlightBus;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::bus::TypedPublisher;
use aeris_runtime::spec::RoleSpec;
use aeris_schemas::{RoleHeartbeat, RoleStatus, topics};
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

mod binding;
mod stalls;

/// Upper bound for anything the tests wait on; reaching it is a failure, not a measurement.
const PATIENCE: Duration = Duration::from_secs(30);

const FAKE_AERIS: &str = r#"#!/bin/sh
# Stand-in for `aeris role --spec FILE`.
[ "$1" = role ] && [ "$2" = --spec ] || { echo "bad arguments: $*" >&2; exit 64; }
name=$(basename "$3" .json)
echo "fake role $name starting"
case "$name" in
  crasher) echo "crasher: boom" >&2; exit 1 ;;
  stubborn) trap '' TERM; echo "stubborn ready"; exec sleep 600 ;;
  burner|hog) exec sh -c 'while :; do :; done' ;;
  *) exec sleep 600 ;;
esac
"#;

/// The fake binary, written once before any test spawns a process (so no forked child can
/// hold it open for writing, which would make exec fail with ETXTBSY).
fn fake_exe() -> &'static Path {
    static EXE: OnceLock<PathBuf> = OnceLock::new();
    EXE.get_or_init(|| {
        // under target/tmp, which cargo owns: nothing is left behind in the system temp folder
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("aeris-orch-fake-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let exe = dir.join("fake-aeris");
        std::fs::write(&exe, FAKE_AERIS).unwrap();
        std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
        exe
    })
}

struct RunDir(PathBuf);

impl RunDir {
    fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("aeris-orch-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        RunDir(p)
    }
}

impl Drop for RunDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn flight(tag: &str) -> String {
    format!("orch-{tag}-{}", std::process::id())
}

fn options(workflow: Workflow, tag: &str, run_dir: &RunDir) -> SupervisorOptions {
    SupervisorOptions {
        workflow,
        flight: flight(tag),
        aeris_exe: fake_exe().to_path_buf(),
        run_dir: run_dir.0.clone(),
        autopilot: None,
        sim_clock: None,
    }
}

/// The default workflow with role `from` renamed to `to`.
fn renamed(from: &str, to: &str, max_restarts: u32) -> Workflow {
    let mut w = Workflow::builtin_default().unwrap();
    let r = w.roles.iter_mut().find(|r| r.name == from).unwrap();
    r.name = to.to_string();
    r.max_restarts = max_restarts;
    r.backoff_ms = 1;
    w
}

fn heartbeat(name: &str, pid: u32, seq: u64, status: RoleStatus, latency_ns: u64) -> RoleHeartbeat {
    let mut hb = RoleHeartbeat::default();
    hb.role.set(name);
    hb.variant.set("test");
    hb.pid = pid;
    hb.seq = seq;
    hb.status = status as u8;
    hb.cycle_latency_ns = latency_ns;
    hb.worked = u8::from(latency_ns > 0);
    hb
}

fn step_until(
    sup: &mut Supervisor,
    what: &str,
    mut done: impl FnMut(&Supervisor, &[SupervisorEvent]) -> bool,
) -> Vec<SupervisorEvent> {
    let start = Instant::now();
    let mut all = Vec::new();
    loop {
        all.extend(sup.step().unwrap());
        if done(sup, &all) {
            return all;
        }
        assert!(
            start.elapsed() < PATIENCE,
            "gave up waiting for {what}; events: {all:?}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn wait_for_log(path: &Path, needle: &str) {
    let start = Instant::now();
    while !std::fs::read_to_string(path).is_ok_and(|t| t.contains(needle)) {
        assert!(
            start.elapsed() < PATIENCE,
            "{} never said {needle:?}",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn cpus_allowed(pid: u32) -> String {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
        .unwrap()
        .trim()
        .to_string()
}

fn process_exists(pid: u32) -> bool {
    Path::new(&format!("/proc/{pid}")).exists()
}

#[test]
fn starts_every_role_bound_and_tracks_heartbeats_and_the_board() {
    let run = RunDir::new("full");
    let mut sup =
        Supervisor::start(options(Workflow::builtin_default().unwrap(), "full", &run)).unwrap();
    assert_eq!(sup.roles().len(), 7);

    // specs: loadable, the vehicle linked to the controller, CPUs recorded
    let spec = |n: &str| RoleSpec::load(sup.role(n).unwrap().spec_path()).unwrap();
    let listen = spec("vehicle").param_str("listen").unwrap().to_string();
    let port = listen.strip_prefix("udpin:127.0.0.1:").unwrap();
    assert_eq!(
        spec("controller").param_str("autopilot").unwrap(),
        format!("udpout:127.0.0.1:{port}")
    );
    assert_eq!(spec("controller").flight, sup.flight());

    // every role process runs bound to its executor's CPUs
    for role in sup.roles() {
        let pid = role.pid().unwrap();
        assert_eq!(role.state(), RoleState::Running);
        assert!(!role.cpus().is_empty(), "{} is bound", role.name());
        let want = CpuSet::parse(role.cpus()).unwrap();
        let got = CpuSet::parse(&cpus_allowed(pid)).unwrap();
        assert_eq!(got, want, "affinity of {}", role.name());
        // no iceoryx2 descriptor of the supervisor leaks into the role
        for fd in std::fs::read_dir(format!("/proc/{pid}/fd")).unwrap() {
            let target = std::fs::read_link(fd.unwrap().path()).unwrap_or_default();
            assert!(
                !target.to_string_lossy().contains("iox2"),
                "{} inherited {}",
                role.name(),
                target.display()
            );
        }
        let log = std::fs::read_to_string(role.log_path()).unwrap();
        assert!(
            log.contains(&format!("start role `{}`", role.name())),
            "{log}"
        );
    }

    // the roles' heartbeats (published here on their behalf)
    let bus = FlightBus::builder(sup.flight())
        .node_name("fake-roles")
        .create()
        .unwrap();
    let hbs: TypedPublisher<RoleHeartbeat> = bus.publisher::<topics::Heartbeat>().unwrap();
    let pids: Vec<(String, u32)> = sup
        .roles()
        .iter()
        .map(|r| (r.name().to_string(), r.pid().unwrap()))
        .collect();
    for (name, pid) in &pids {
        hbs.publish(&heartbeat(name, *pid, 1, RoleStatus::Starting, 0))
            .unwrap();
    }
    // one from a role that is not in the flight, and one invalid
    hbs.publish(&heartbeat("stranger", 1, 1, RoleStatus::Running, 5))
        .unwrap();
    hbs.publish(&heartbeat("hub", pids[0].1, 0, RoleStatus::Running, 5))
        .unwrap();
    sup.wait_ready(PATIENCE).unwrap();
    assert_eq!(sup.unknown_heartbeats(), 1);
    assert_eq!(sup.invalid_heartbeats(), 1);

    // events seen inside wait_ready come out of the next step
    let events = sup.step().unwrap();
    for (name, pid) in &pids {
        assert!(events.contains(&SupervisorEvent::RoleStarted {
            name: name.clone(),
            pid: *pid
        }));
        assert!(events.contains(&SupervisorEvent::FirstHeartbeat { name: name.clone() }));
    }

    // latency percentiles and a sequence gap (seq 4 never arrives)
    let hub_pid = sup.role("hub").unwrap().pid().unwrap();
    for (seq, ms) in [(2, 1), (3, 2), (5, 3)] {
        hbs.publish(&heartbeat(
            "hub",
            hub_pid,
            seq,
            RoleStatus::Running,
            ms * 1_000_000,
        ))
        .unwrap();
    }
    step_until(&mut sup, "hub heartbeats", |s, _| {
        s.role("hub").unwrap().heartbeats() == 4
    });
    let hub = sup.role("hub").unwrap();
    assert_eq!(hub.heartbeat_gaps(), 1);
    assert_eq!(hub.latency_ms(), Some([2.0, 3.0, 3.0]));
    assert_eq!(hub.last_heartbeat().unwrap().seq, 5);

    // the status board, as `aeris status` reads it
    sup.set_progress(2, 4, 31.5, 1.25);
    let board = bus.read_status_board().unwrap();
    assert_eq!(board.supervisor_pid, std::process::id());
    assert_eq!(board.roles().len(), 7);
    assert_eq!((board.active_step, board.subgoals), (2, 4));
    assert_eq!(board.distance_to_goal_m, 31.5);
    let entry = board
        .roles()
        .iter()
        .find(|e| e.name.as_str() == Some("hub"))
        .unwrap();
    assert_eq!(entry.pid, hub_pid);
    assert_eq!(entry.heartbeats, 4);
    assert_eq!(entry.heartbeat_gaps, 1);
    assert_eq!(entry.latency_ms, [2.0, 3.0, 3.0]);
    assert_eq!(entry.status, RoleStatus::Running as u8);
    assert_eq!(entry.cpus.as_str(), Some(sup.role("hub").unwrap().cpus()));

    // shutdown: SIGTERM in order, everyone exits (sleep dies of SIGTERM), all reaped
    let report = sup.shutdown(PATIENCE);
    let order: Vec<&str> = report.roles.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(order.first(), Some(&"reasoning"));
    assert_eq!(&order[4..], ["controller", "controller-standby", "vehicle"]);
    for e in &report.roles {
        assert_eq!(
            e.outcome,
            ShutdownOutcome::Exited(RoleExit::Signal(libc::SIGTERM)),
            "{}",
            e.name
        );
    }
    assert!(report.killed().is_empty());
    for (name, pid) in &pids {
        assert!(!process_exists(*pid), "{name} ({pid}) was reaped");
    }
}

#[test]
fn a_crashing_role_is_restarted_with_backoff_until_the_budget_is_spent() {
    let run = RunDir::new("crash");
    let mut sup = Supervisor::start(options(renamed("hub", "crasher", 2), "crash", &run)).unwrap();
    // nobody sends heartbeats here: wait_ready fails as soon as the crasher gives up
    let err = sup.wait_ready(PATIENCE).unwrap_err();
    match &err {
        SupervisorError::RoleDown { role, log_tail, .. } => {
            assert_eq!(role, "crasher");
            assert!(
                log_tail.iter().any(|l| l.contains("crasher: boom")),
                "{log_tail:?}"
            );
        }
        other => panic!("{other}"),
    }
    let msg = err.to_string();
    assert!(msg.contains("crasher") && msg.contains("gave up"), "{msg}");

    let crasher_events: Vec<SupervisorEvent> = sup
        .step()
        .unwrap()
        .into_iter()
        .filter(|e| match e {
            SupervisorEvent::RoleStarted { name, .. }
            | SupervisorEvent::RoleExited { name, .. }
            | SupervisorEvent::RoleRestarted { name, .. }
            | SupervisorEvent::RoleGaveUp { name } => name == "crasher",
            _ => false,
        })
        .collect();
    let kinds: Vec<String> = crasher_events
        .iter()
        .map(|e| match e {
            SupervisorEvent::RoleStarted { .. } => "started".to_string(),
            SupervisorEvent::RoleExited { status, .. } => format!("exited {status}"),
            SupervisorEvent::RoleRestarted { restarts, .. } => format!("restart {restarts}"),
            SupervisorEvent::RoleGaveUp { .. } => "gave up".to_string(),
            _ => unreachable!(),
        })
        .collect();
    assert_eq!(
        kinds,
        [
            "started",
            "exited exit code 1",
            "restart 1",
            "exited exit code 1",
            "restart 2",
            "exited exit code 1",
            "gave up"
        ]
    );
    let crasher = sup.role("crasher").unwrap();
    assert_eq!(crasher.state(), RoleState::GaveUp);
    assert_eq!(crasher.pid(), None);
    assert_eq!(crasher.last_exit(), Some(RoleExit::Code(1)));
    assert_eq!(sup.total_restarts(), 2);
    let log = std::fs::read_to_string(crasher.log_path()).unwrap();
    assert_eq!(log.matches("crasher: boom").count(), 3, "{log}");
    assert_eq!(log.matches("restart role `crasher`").count(), 2, "{log}");

    let board = sup.status();
    let entry = board
        .roles()
        .iter()
        .find(|e| e.name.as_str() == Some("crasher"))
        .unwrap();
    assert_eq!((entry.pid, entry.restarts), (0, 2));

    // the role stays down
    let more = sup.step().unwrap();
    assert!(
        !more
            .iter()
            .any(|e| matches!(e, SupervisorEvent::RoleRestarted { .. })),
        "{more:?}"
    );
    let report = sup.shutdown(PATIENCE);
    let crasher = report.roles.iter().find(|e| e.name == "crasher").unwrap();
    assert_eq!(crasher.outcome, ShutdownOutcome::NotRunning);
}

#[test]
fn wait_ready_names_the_silent_roles_and_quotes_their_logs() {
    let run = RunDir::new("silent");
    let mut sup = Supervisor::start(options(
        Workflow::builtin_default().unwrap(),
        "silent",
        &run,
    ))
    .unwrap();
    let bus = FlightBus::builder(sup.flight())
        .node_name("fake-roles")
        .create()
        .unwrap();
    let hbs: TypedPublisher<RoleHeartbeat> = bus.publisher::<topics::Heartbeat>().unwrap();
    for role in sup.roles().iter().filter(|r| r.name() != "camera") {
        hbs.publish(&heartbeat(
            role.name(),
            role.pid().unwrap(),
            1,
            RoleStatus::Running,
            1,
        ))
        .unwrap();
    }
    let err = sup.wait_ready(Duration::from_millis(200)).unwrap_err();
    match &err {
        SupervisorError::NotReady { silent, .. } => {
            let names: Vec<&str> = silent.iter().map(|s| s.name.as_str()).collect();
            assert_eq!(names, ["camera"]);
            assert!(
                silent[0]
                    .log_tail
                    .iter()
                    .any(|l| l.contains("start role `camera`")),
                "{:?}",
                silent[0].log_tail
            );
        }
        other => panic!("{other}"),
    }
    let msg = err.to_string();
    assert!(
        msg.contains("camera") && msg.contains("camera.log"),
        "{msg}"
    );
    assert!(!msg.contains("role `hub`"), "{msg}");
}

#[test]
fn shutdown_kills_a_role_that_ignores_sigterm() {
    let run = RunDir::new("stubborn");
    let sup = Supervisor::start(options(
        renamed("perception", "stubborn", 5),
        "stubborn",
        &run,
    ))
    .unwrap();
    // SIGTERM must not arrive before the script ignores it
    wait_for_log(sup.role("stubborn").unwrap().log_path(), "stubborn ready");
    let pid = sup.role("stubborn").unwrap().pid().unwrap();
    let report = sup.shutdown(Duration::from_millis(300));
    assert_eq!(report.killed(), ["stubborn"]);
    assert!(report.clean().is_empty());
    assert!(!report.all_clean());
    assert!(!process_exists(pid));
}

#[test]
fn dropping_the_supervisor_kills_and_reaps_every_role() {
    let run = RunDir::new("drop");
    let sup =
        Supervisor::start(options(Workflow::builtin_default().unwrap(), "drop", &run)).unwrap();
    let pids: Vec<u32> = sup.roles().iter().filter_map(|r| r.pid()).collect();
    assert_eq!(pids.len(), 7);
    assert!(pids.iter().all(|p| process_exists(*p)));
    drop(sup);
    for pid in pids {
        assert!(!process_exists(pid), "{pid} is gone");
    }
}

#[test]
fn an_external_autopilot_replaces_the_vehicle_role() {
    let run = RunDir::new("extap");
    let mut opts = options(Workflow::builtin_default().unwrap(), "extap", &run);
    opts.autopilot = Some("udpout:127.0.0.1:14540".into());
    let sup = Supervisor::start(opts).unwrap();
    assert!(sup.role("vehicle").is_none());
    assert_eq!(sup.roles().len(), 6);
    let spec = RoleSpec::load(sup.role("controller").unwrap().spec_path()).unwrap();
    assert_eq!(spec.param_str("autopilot"), Some("udpout:127.0.0.1:14540"));
    drop(sup);
}

#[test]
fn a_second_supervisor_of_the_same_flight_is_refused() {
    let run = RunDir::new("twice");
    let first =
        Supervisor::start(options(Workflow::builtin_default().unwrap(), "twice", &run)).unwrap();
    let run2 = RunDir::new("twice2");
    let mut opts = options(Workflow::builtin_default().unwrap(), "twice", &run2);
    opts.flight = first.flight().to_string();
    let err = Supervisor::start(opts).unwrap_err();
    assert!(matches!(err, SupervisorError::Bus { .. }), "{err}");
    assert!(err.to_string().contains(first.flight()), "{err}");
}

#[test]
fn a_missing_binary_is_reported_and_nothing_is_left_running() {
    let run = RunDir::new("nobin");
    let mut opts = options(Workflow::builtin_default().unwrap(), "nobin", &run);
    opts.aeris_exe = run.0.join("no-such-aeris");
    let err = Supervisor::start(opts).unwrap_err();
    assert!(matches!(err, SupervisorError::Spawn { .. }), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("no-such-aeris") && msg.contains("cargo build"),
        "{msg}"
    );
}

const HELPER_ENV: &str = "AERIS_ORCH_TEST_SUPERVISOR_DIR";

/// Not a test on its own: with `HELPER_ENV` set, it runs a supervisor, writes the role
/// pids to `DIR/pids` and waits to be killed (see the test below).
#[test]
fn helper_supervisor_that_gets_killed() {
    let Some(dir) = std::env::var_os(HELPER_ENV) else {
        return;
    };
    let dir = PathBuf::from(dir);
    let run = RunDir(dir.join("run"));
    let sup = Supervisor::start(options(
        Workflow::builtin_default().unwrap(),
        "orphans",
        &run,
    ))
    .unwrap();
    let pids: Vec<String> = sup
        .roles()
        .iter()
        .filter_map(|r| r.pid())
        .map(|p| p.to_string())
        .collect();
    std::fs::write(dir.join("pids.tmp"), pids.join("\n")).unwrap();
    std::fs::rename(dir.join("pids.tmp"), dir.join("pids")).unwrap();
    loop {
        std::thread::park();
    }
}

/// Dead or a zombie awaiting its new parent's wait.
fn process_gone(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Err(_) => true,
        Ok(stat) => stat
            .rsplit_once(')')
            .is_some_and(|(_, rest)| rest.trim_start().starts_with(['Z', 'X'])),
    }
}

#[test]
fn roles_die_with_a_killed_supervisor() {
    let dir = RunDir::new("orphans");
    std::fs::create_dir_all(&dir.0).unwrap();
    let exe = std::env::current_exe().unwrap();
    let mut helper = std::process::Command::new(exe)
        .args([
            "helper_supervisor_that_gets_killed",
            "--exact",
            "--test-threads=1",
            "--nocapture",
        ])
        .env(HELPER_ENV, &dir.0)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pids_file = dir.0.join("pids");
    let start = Instant::now();
    while !pids_file.exists() {
        if let Some(status) = helper.try_wait().unwrap() {
            panic!("the helper supervisor exited early: {status}");
        }
        assert!(
            start.elapsed() < PATIENCE,
            "the helper never started its roles"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let pids: Vec<u32> = std::fs::read_to_string(&pids_file)
        .unwrap()
        .lines()
        .map(|l| l.parse().unwrap())
        .collect();
    assert_eq!(pids.len(), 7);
    assert!(pids.iter().all(|p| !process_gone(*p)));
    helper.kill().unwrap(); // SIGKILL: no Drop, no shutdown runs in the supervisor
    helper.wait().unwrap();
    // a new node removes the iceoryx2 resources the killed supervisor left behind
    let cleaner = FlightBus::builder(&flight("orphans-cleanup"))
        .node_name("cleanup")
        .join_manifest(false)
        .create()
        .unwrap();
    drop(cleaner);
    let start = Instant::now();
    for pid in pids {
        while !process_gone(pid) {
            assert!(
                start.elapsed() < PATIENCE,
                "role {pid} outlived its supervisor"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}
