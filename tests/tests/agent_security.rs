//! `aeris agent` as a stranger meets it: keys made by `aeris keys`, the agent on a loopback
//! port, and independent zenoh peers (the `eclipse-zenoh` Python package,
//! `tests/py/zenoh_stranger.py`) without a certificate, with another CA's, with a
//! certificate of the flight's CA that the agent does not obey, over plain TCP, and as the
//! flight's own host asking for what must be refused. The file system is checked after.
//! What another local user can do is in `local_users.rs`.

use aeris_tests::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// `aeris ARGS`, which must succeed; its stdout.
fn aeris_ok(args: &[&str]) -> String {
    let out = Command::new(aeris_bin())
        .args(args)
        .output()
        .expect("run aeris");
    assert!(
        out.status.success(),
        "aeris {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A free TCP port on 127.0.0.1.
fn free_port() -> u16 {
    std::net::TcpListener::bind(("127.0.0.1", 0))
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// The flight's key store in `dir/store` (hosts ground, vehicle, intruder) and another CA in
/// `dir/other` (a host named vehicle).
fn make_keys(dir: &Path) -> (PathBuf, PathBuf) {
    let store = dir.join("store");
    let other = dir.join("other");
    let s = store.to_str().unwrap();
    let made = aeris_ok(&["keys", "init", s]);
    assert!(made.contains("ca.key (0600"), "{made}");
    for host in ["ground", "vehicle", "intruder"] {
        let issued = aeris_ok(&["keys", "issue", s, host]);
        assert!(
            issued.contains(&format!("host `{host}`: certificate valid until")),
            "{issued}"
        );
    }
    aeris_ok(&["keys", "init", other.to_str().unwrap()]);
    aeris_ok(&["keys", "issue", other.to_str().unwrap(), "vehicle"]);
    (store, other)
}

/// `aeris agent --host ground ARGS` with its output in `log`; returns once it listens.
fn start_agent(args: &[&str], log: &Path) -> ChildGuard {
    let out = std::fs::File::create(log).unwrap();
    let err = out.try_clone().unwrap();
    let mut cmd = Command::new(aeris_bin());
    cmd.args(["agent", "--host", "ground"])
        .args(args)
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err);
    let mut agent = ChildGuard::spawn(&mut cmd).expect("spawn aeris agent");
    let listening = poll_until(Duration::from_secs(30), || {
        if let Ok(Some(status)) = agent.0.try_wait() {
            panic!(
                "the agent exited ({status}): {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        }
        std::fs::read_to_string(log)
            .ok()
            .filter(|t| t.contains("listening on"))
    });
    assert!(listening.is_some(), "the agent never listened");
    agent
}

/// `aeris agent --host ground ARGS`, which must fail; what it printed.
fn agent_refuses(args: &[&str], env: &[(&str, &Path)]) -> String {
    let mut cmd = Command::new(aeris_bin());
    cmd.args(["agent", "--host", "ground"]).args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = ChildGuard::spawn(cmd.stdout(Stdio::piped()).stderr(Stdio::piped()))
        .expect("spawn aeris agent");
    let status = wait_bounded(&mut child.0, Duration::from_secs(30))
        .expect("the agent should refuse to start, not run");
    let mut text = String::new();
    use std::io::Read;
    if let Some(mut e) = child.0.stderr.take() {
        e.read_to_string(&mut text).unwrap();
    }
    assert!(!status.success(), "{text}");
    text
}

#[test]
fn an_agent_without_keys_refuses_to_start_and_says_how_to_make_them() {
    let text = agent_refuses(&[], &[]);
    assert!(
        text.contains("the agent needs this host's keys (--keys DIR): make a flight CA with `aeris keys init STORE`"),
        "{text}"
    );
    // keys, but a plain TCP endpoint: refused, not silently insecure
    let dir = TempDir::new("agent-nokeys");
    let (store, _) = make_keys(&dir.0);
    let keys = store.join("ground");
    let text = agent_refuses(
        &[
            "--keys",
            keys.to_str().unwrap(),
            "--flight-host",
            "vehicle",
            "--listen",
            "tcp/127.0.0.1:7447",
        ],
        &[],
    );
    assert!(text.contains("`tcp/127.0.0.1:7447` is plain TCP"), "{text}");
    // another host's keys
    let text = agent_refuses(
        &[
            "--keys",
            store.join("vehicle").to_str().unwrap(),
            "--flight-host",
            "vehicle",
        ],
        &[],
    );
    assert!(
        text.contains("are host `vehicle`'s, not host `ground`'s"),
        "{text}"
    );
    // nobody named to command it
    let text = agent_refuses(&["--keys", keys.to_str().unwrap()], &[]);
    assert!(text.contains("--flight-host NAME"), "{text}");
}

#[test]
fn strangers_get_nothing_and_the_flight_host_cannot_make_the_agent_write_or_run_outside_its_rules()
{
    let dir = TempDir::new("agent-strangers");
    let (store, other) = make_keys(&dir.0);
    let port = free_port();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let run_dir = dir.0.join("agent-run");
    let agent_log = dir.0.join("agent.log");
    let _agent = start_agent(
        &[
            "--keys",
            store.join("ground").to_str().unwrap(),
            "--flight-host",
            "vehicle",
            "--listen",
            &endpoint,
            "--run-dir",
            run_dir.to_str().unwrap(),
        ],
        &agent_log,
    );
    let escape = dir.0.join("escaped");
    let flight = unique_flight("strangers");
    let report = dir.0.join("report.json");
    let out = Command::new(python())
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("py/zenoh_stranger.py"))
        .arg(&report)
        .args([
            "--endpoint",
            &endpoint,
            "--host",
            "ground",
            "--flight",
            &flight,
        ])
        .arg("--plain")
        .arg(format!("tcp/127.0.0.1:{port}"))
        .arg("--schema")
        .arg(format!(
            "{}:{}",
            aeris_schemas::SCHEMA_VERSION,
            aeris_schemas::SCHEMA_LAYOUT_HASH
        ))
        .arg("--ca")
        .arg(store.join("ca.pem"))
        .arg("--flight-host")
        .arg(store.join("vehicle"))
        .arg("--this-host")
        .arg(store.join("ground"))
        .arg("--intruder")
        .arg(store.join("intruder"))
        .arg("--foreign")
        .arg(other.join("vehicle"))
        .arg("--escape")
        .arg(&escape)
        .output()
        .expect("run the zenoh peers (scripts/setup-test-deps.sh installs eclipse-zenoh)");
    assert!(
        out.status.success(),
        "zenoh_stranger.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let agent_text = std::fs::read_to_string(&agent_log).unwrap();

    // no certificate, another CA's, plain TCP to the TLS port: refused by zenoh, before any
    // request reaches the agent (no session, or one that hears no answer)
    for who in ["no_certificate", "foreign_ca", "plain_tcp"] {
        assert_eq!(r[who]["info"], false, "{who}: {r}");
    }
    // a certificate of the flight's CA the agent does not obey: connected, and nothing
    // answered, nothing started, nothing it published delivered
    assert_eq!(r["intruder"]["opened"], true, "{r}");
    assert_eq!(r["intruder"]["info"], false, "{r}");
    assert_eq!(r["intruder"]["spawn"], false, "{r}");
    assert_eq!(r["intruder"]["delivered"], 0, "{r}");
    // the flight's host is answered and its data delivered (the same path the intruder's
    // messages would have taken)
    assert_eq!(r["flight_host"]["info"]["ok"]["host"], "ground", "{r}");
    assert_eq!(r["flight_host"]["delivered"], r["sent"], "{r}");
    assert!(
        !agent_text.lines().any(|l| l.starts_with("started ")),
        "{agent_text}"
    );

    // what the flight's host may not ask: every case refused, by name
    let spawns = &r["flight_host"]["spawns"];
    let refused = |case: &str| -> String {
        spawns[case]["refused"]
            .as_str()
            .unwrap_or_else(|| panic!("{case} was not refused: {r}"))
            .to_string()
    };
    assert!(refused("traversal").starts_with("role name `../"), "{r}");
    assert!(refused("traversal").ends_with("is invalid: use letters, digits, `_` and `-`"));
    assert!(
        refused("traversal_flight").starts_with("flight name `../../"),
        "{r}"
    );
    assert!(
        refused("kind").starts_with("role kind camera/gstreamer is not allowed on this host"),
        "{r}"
    );
    assert!(
        refused("param").starts_with("param `model` is not taken from the network"),
        "{r}"
    );
    assert!(
        refused("bridge_connect").starts_with(
            "param `connect` is not taken from the network: a bridge's link is this agent's own"
        ),
        "{r}"
    );
    // each refusal is in the agent's log
    assert_eq!(
        agent_text.matches("refused spawn").count(),
        5,
        "{agent_text}"
    );
    // nothing was written outside the run directory, and nothing inside it either
    assert!(!escape.exists(), "{} was written", escape.display());
    let mut written = Vec::new();
    for e in walk(&dir.0) {
        if e.starts_with(&run_dir) && e != run_dir {
            written.push(e);
        }
    }
    assert!(written.is_empty(), "{written:?}");
    // the run directory is the agent's alone
    use std::os::unix::fs::PermissionsExt;
    assert_eq!(
        std::fs::metadata(&run_dir).unwrap().permissions().mode() & 0o777,
        0o700
    );
}

/// Every path under `dir`, links not followed.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(p.clone());
            }
            out.push(p);
        }
    }
    out
}
