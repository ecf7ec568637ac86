//! Helpers for the end-to-end tests: find the `aeris` binary, name flights uniquely, and
//! keep spawned processes from outliving a test; [`hosts`]: two hosts as network namespaces.

pub mod hosts;

use std::path::PathBuf;
use std::process::{Child, Command};

/// Path of the `aeris` binary built next to the test executable (`target/<profile>/aeris`).
///
/// `cargo test --workspace` builds it; the README's test command builds it first.
pub fn aeris_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> -> target/<profile>/aeris
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let bin = dir.join("aeris");
    assert!(
        bin.exists(),
        "{} is missing: run `cargo build --bin aeris` first (scripts/test.sh does)",
        bin.display()
    );
    bin
}

/// A flight name unique to this test process and tag, so parallel tests never share services.
pub fn unique_flight(tag: &str) -> String {
    format!("{tag}-{}", std::process::id())
}

/// A child process that is killed (SIGKILL) and reaped when dropped.
pub struct ChildGuard(pub Child);

impl ChildGuard {
    /// Spawn `cmd`.
    pub fn spawn(cmd: &mut Command) -> std::io::Result<Self> {
        cmd.spawn().map(ChildGuard)
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.0.id()
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A scratch directory under the system temp dir, removed on drop; kept when its test fails
/// (the drop runs while the test panics) or when the environment sets `AERIS_TEST_KEEP`, so a
/// failed test's run directory and logs can be read afterwards (CI's among them).
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// Create `$TMPDIR/aeris-test-<tag>-<pid>`.
    pub fn new(tag: &str) -> Self {
        let p = std::env::temp_dir().join(format!("aeris-test-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).expect("create temp dir");
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() || std::env::var_os("AERIS_TEST_KEEP").is_some() {
            eprintln!("kept {}", self.0.display());
            return;
        }
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Python interpreter for the independent decoders (`AERIS_PYTHON`, else `python3`).
pub fn python() -> String {
    std::env::var("AERIS_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

/// Wait for `child` to exit, polling; kill it and return `None` after `bound` (a hang guard,
/// not a timing assertion).
pub fn wait_bounded(
    child: &mut Child,
    bound: std::time::Duration,
) -> Option<std::process::ExitStatus> {
    let start = std::time::Instant::now();
    loop {
        if let Ok(Some(status)) = child.try_wait() {
            return Some(status);
        }
        if start.elapsed() > bound {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Poll `cond` until it returns `Some`, or give up after `bound` (hang guard).
pub fn poll_until<T>(bound: std::time::Duration, mut cond: impl FnMut() -> Option<T>) -> Option<T> {
    let start = std::time::Instant::now();
    loop {
        if let Some(v) = cond() {
            return Some(v);
        }
        if start.elapsed() > bound {
            return None;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Poll `cond` while the flight `run` (started by [`spawn_run`] in `dir`) is running, until it
/// returns `Some`. Panics, with the flight's output, when `aeris run` exits first (at once, not
/// after `bound`) or after `bound` (hang guard); `what` names what was awaited.
pub fn poll_flight<T>(
    run: &mut ChildGuard,
    dir: &std::path::Path,
    what: &str,
    bound: std::time::Duration,
    mut cond: impl FnMut() -> Option<T>,
) -> T {
    let start = std::time::Instant::now();
    loop {
        if let Some(v) = cond() {
            return v;
        }
        if let Ok(Some(status)) = run.0.try_wait() {
            panic!(
                "aeris run exited ({status}) before {what}: {:?}",
                run_output(dir)
            );
        }
        if start.elapsed() > bound {
            panic!("{what}: not within {bound:?}: {:?}", run_output(dir));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// The last line of `stdout` parsed as JSON.
pub fn last_json_line(stdout: &str) -> serde_json::Value {
    let line = stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    serde_json::from_str(line)
        .unwrap_or_else(|e| panic!("last stdout line is not JSON ({e}): {line:?}"))
}

/// The built-in default workflow as a TOML table, for tests that fly a variation of it.
pub fn default_workflow() -> toml::Table {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/default.toml");
    let text = std::fs::read_to_string(&path).expect("workflows/default.toml");
    text.parse().expect("default workflow parses")
}

/// The top of the short hop's altitude band (m).
pub const HOP_CEILING_M: f64 = 20.0;

/// Replace the mission of a workflow table by a short hop in the same world: take off to 12
/// m, fly 30 m north along the road, land on it (about a third of the default mission's
/// flight time), under a ceiling of [`HOP_CEILING_M`]. For tests whose subject is not the mission (an autopilot link, a router, a
/// recording): the suite's time goes to what each test checks.
pub fn short_hop(workflow: &mut toml::Table) {
    let hop = r#"
world = "village"
instruction = "Take off from the helipad to 12 metres, fly north along the road for 30 metres, and land on the road."
start = [0.0, 0.0, 0.0]
cruise_speed = 5.0
acceptance_radius_m = 3.0
max_duration_s = 120.0

[[subgoals]]
text = "take off from the helipad to 12 metres"
action = "takeoff"
waypoint = [0.0, 0.0, 12.0]

[[subgoals]]
text = "fly north along the road for 30 metres"
action = "goto"
waypoint = [30.0, 0.0, 12.0]

[[subgoals]]
text = "land on the road"
action = "land"
waypoint = [30.0, 0.0, 0.0]
"#;
    let mut mission: toml::Table = hop.parse().expect("the short hop parses");
    let mut limits = workflow["mission"]["limits"].clone();
    // the altitude band's top at 20 m (the default's 60 m): a flight without occupancy keeps
    // to the top, and from 60 m its landing alone took a minute
    limits["h_max"] = toml::Value::Float(HOP_CEILING_M);
    limits["geofence_max"][2] = toml::Value::Float(HOP_CEILING_M);
    mission.insert("limits".into(), limits);
    workflow.insert("mission".into(), toml::Value::Table(mission));
}

/// The default workflow flying [`short_hop`], as TOML text.
pub fn short_hop_text() -> String {
    let mut w = default_workflow();
    short_hop(&mut w);
    toml::to_string(&w).expect("serialise workflow")
}

/// The default workflow flying [`short_hop`], written to `dir/hop.toml`.
pub fn short_hop_workflow(dir: &std::path::Path) -> PathBuf {
    let mut w = default_workflow();
    short_hop(&mut w);
    write_workflow(dir, "hop", &w)
}

/// Add an executor `gpu` on `accelerator` (`cuda:0`), its processes on any CPU, to a
/// workflow table.
pub fn add_gpu_executor(workflow: &mut toml::Table, accelerator: &str) {
    let mut gpu = toml::Table::new();
    gpu.insert("cpus".into(), "auto".into());
    gpu.insert("accelerator".into(), accelerator.into());
    workflow["executors"]
        .as_table_mut()
        .expect("[executors] table")
        .insert("gpu".into(), toml::Value::Table(gpu));
}

/// Set `variant` of the role named `role` in a workflow table.
pub fn set_variant(workflow: &mut toml::Table, role: &str, variant: &str) {
    let roles = workflow
        .get_mut("roles")
        .and_then(|r| r.as_array_mut())
        .expect("roles");
    let entry = roles
        .iter_mut()
        .filter_map(|r| r.as_table_mut())
        .find(|r| r.get("name").and_then(|n| n.as_str()) == Some(role))
        .expect("role in workflow");
    entry.insert("variant".into(), toml::Value::String(variant.into()));
}

/// Write a workflow table to `dir/name.toml`.
pub fn write_workflow(dir: &std::path::Path, name: &str, workflow: &toml::Table) -> PathBuf {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, toml::to_string(workflow).expect("serialise workflow"))
        .expect("write workflow");
    p
}

/// Start `aeris run --json --flight FLIGHT [extra..]` with stdout/stderr captured to files in
/// `dir` (so a long flight never blocks on a full pipe).
pub fn spawn_run(dir: &std::path::Path, flight: &str, extra: &[&str]) -> ChildGuard {
    spawn_flight(dir, &["run"], flight, extra)
}

/// `aeris formation fly --json --flight FLIGHT --run-dir DIR/run EXTRA...` (the built-in
/// formation flight), its output captured like [`spawn_run`]'s.
pub fn spawn_formation_fly(dir: &std::path::Path, flight: &str, extra: &[&str]) -> ChildGuard {
    spawn_flight(dir, &["formation", "fly"], flight, extra)
}

fn spawn_flight(
    dir: &std::path::Path,
    command: &[&str],
    flight: &str,
    extra: &[&str],
) -> ChildGuard {
    let out = std::fs::File::create(dir.join("run.stdout")).expect("stdout file");
    let err = std::fs::File::create(dir.join("run.stderr")).expect("stderr file");
    let mut cmd = Command::new(aeris_bin());
    cmd.args(command)
        .arg("--json")
        .arg("--flight")
        .arg(flight)
        .arg("--run-dir")
        .arg(dir.join("run"))
        .args(extra)
        .stdin(std::process::Stdio::null())
        .stdout(out)
        .stderr(err);
    ChildGuard::spawn(&mut cmd).unwrap_or_else(|e| panic!("spawn aeris {command:?}: {e}"))
}

/// Read the captured stdout and stderr of [`spawn_run`].
pub fn run_output(dir: &std::path::Path) -> (String, String) {
    (
        std::fs::read_to_string(dir.join("run.stdout")).unwrap_or_default(),
        std::fs::read_to_string(dir.join("run.stderr")).unwrap_or_default(),
    )
}

/// The last `lines` lines of every role log of the flight run in `dir` (by
/// [`spawn_run`]), for failure messages: the temporary folder is gone after the test.
pub fn run_logs_tail(dir: &std::path::Path, lines: usize) -> String {
    let mut out = String::new();
    let Ok(entries) = std::fs::read_dir(dir.join("run").join("logs")) else {
        return "(no role logs)".into();
    };
    let mut paths: Vec<_> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    paths.sort();
    for p in paths {
        let text = std::fs::read_to_string(&p).unwrap_or_default();
        let all: Vec<&str> = text.lines().collect();
        out.push_str(&format!("== {}\n", p.display()));
        for l in &all[all.len().saturating_sub(lines)..] {
            out.push_str(l);
            out.push('\n');
        }
    }
    out
}

/// The default workflow's mission.
pub fn default_mission() -> aeris_runtime::MissionSpec {
    let workflow = default_workflow();
    let value = serde_json::to_value(workflow["mission"].clone()).expect("mission as JSON");
    serde_json::from_value(value).expect("mission parses")
}

/// A role spec in `flight`, as the supervisor would write it, for starting one role by hand.
pub fn role_spec(
    flight: &str,
    name: &str,
    kind: aeris_schemas::RoleKind,
    variant: &str,
    params: serde_json::Value,
) -> aeris_runtime::RoleSpec {
    aeris_runtime::RoleSpec {
        flight: flight.to_string(),
        name: name.to_string(),
        kind,
        variant: variant.to_string(),
        cpus: String::new(),
        timing: Default::default(),
        camera: Default::default(),
        mission: default_mission(),
        params: params.as_object().cloned().unwrap_or_default(),
        instance: 0,
        remote: None,
        heartbeat_pid: None,
        flight_clock_offset_ns: 0,
        accelerator: None,
        vehicle: None,
        clock: Default::default(),
    }
}

/// Write `spec` as JSON to `dir/<name>.json`.
pub fn write_spec(dir: &std::path::Path, spec: &aeris_runtime::RoleSpec) -> PathBuf {
    let p = dir.join(format!("{}.json", spec.name));
    std::fs::write(&p, serde_json::to_string(spec).expect("spec as JSON")).expect("write spec");
    p
}

/// A UDP port that was free a moment ago on 127.0.0.1.
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("free UDP port")
}

/// Busy threads in the test process, outside any flight (unpinned, normal priority), until
/// dropped: a shared machine's other work.
pub struct OutsideLoad {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl OutsideLoad {
    /// Start `n` busy threads.
    pub fn start(n: usize) -> Self {
        use std::sync::atomic::Ordering;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let threads = (0..n)
            .map(|_| {
                let stop = stop.clone();
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        for i in 0..10_000u64 {
                            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(i));
                        }
                    }
                })
            })
            .collect();
        OutsideLoad { stop, threads }
    }
}

impl Drop for OutsideLoad {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
