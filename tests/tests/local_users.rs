//! Another local user of the vehicle computer (`nobody`, through `setpriv`): what they plant
//! where our processes write, and the flight's services they make first (iceoryx2#1810).
//! These tests run as root, as the multi-host tests do (CI runs them as root).

use aeris_tests::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

/// `aeris agent --host ground ARGS` with `env`, which must fail; what it printed.
fn agent_refuses(args: &[&str], env: &[(&str, &Path)]) -> String {
    let mut cmd = Command::new(aeris_bin());
    cmd.args(["agent", "--host", "ground"]).args(args);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.stdin(Stdio::null()).output().expect("run aeris agent");
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "{text}");
    text
}

/// `setpriv` arguments that run a program as user `nobody`.
const AS_NOBODY: [&str; 4] = ["--reuid=nobody", "--regid=nogroup", "--clear-groups", "--"];

/// Run `args` as user `nobody` (`setpriv`; the tests run as root).
fn as_nobody(args: &[&str]) {
    let status = Command::new("setpriv")
        .args(AS_NOBODY)
        .args(args)
        .status()
        .expect("run setpriv (util-linux)");
    assert!(status.success(), "as nobody: {args:?}");
}

#[test]
fn a_run_directory_another_user_planted_or_reached_through_a_link_is_refused() {
    let dir = TempDir::new("agent-rundir");
    // a shared temporary directory, as /tmp is: world-writable, sticky
    let tmp = dir.0.join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&tmp, std::fs::Permissions::from_mode(0o1777)).unwrap();
    // another user pre-creates the agent's default run directory for root's agent
    let uid = unsafe { libc::geteuid() };
    let planted = tmp.join(format!("aeris-agent-{uid}"));
    as_nobody(&["mkdir", "-m", "0777", planted.to_str().unwrap()]);
    let text = agent_refuses(
        &["--insecure", "--listen", "tcp/127.0.0.1:1"],
        &[("TMPDIR", tmp.as_path())],
    );
    assert!(
        text.contains(&format!(
            "cannot use the agent's run directory {}/ground: {} belongs to nobody (uid 65534)",
            planted.display(),
            planted.display()
        )),
        "{text}"
    );
    // a link another user planted where the run directory would be
    let victim = dir.0.join("victim");
    std::fs::create_dir(&victim).unwrap();
    let link = tmp.join("run");
    as_nobody(&["ln", "-s", victim.to_str().unwrap(), link.to_str().unwrap()]);
    let text = agent_refuses(
        &[
            "--insecure",
            "--listen",
            "tcp/127.0.0.1:1",
            "--run-dir",
            link.join("ground").to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        text.contains(&format!("{} is a symbolic link", link.display())),
        "{text}"
    );
    assert!(std::fs::read_dir(&victim).unwrap().next().is_none());
}

/// A private mount namespace with fresh `/dev/shm` and `/tmp/iceoryx2` (so the test owns
/// iceoryx2's files there), running `prepare` as root, then `program args` as `nobody`.
fn squatter(prepare: &str, program: &Path, args: &[&str], log: &Path) -> ChildGuard {
    let out = std::fs::File::create(log).unwrap();
    let err = out.try_clone().unwrap();
    let mut cmd = Command::new("unshare");
    cmd.args(["--mount", "--fork", "--kill-child=SIGKILL", "sh", "-c"])
        .arg(format!(
            "mount -t tmpfs tmpfs /dev/shm && mkdir -p /tmp/iceoryx2 && \\
             mount -t tmpfs tmpfs /tmp/iceoryx2 && {prepare} exec setpriv \"$@\""
        ))
        .arg("sh")
        .args(AS_NOBODY)
        .arg(program)
        .args(args)
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err);
    ChildGuard::spawn(&mut cmd).expect("spawn the squatter")
}

/// A process killed (SIGKILL) on drop: the squatter, whose parent-death signal `setpriv`'s
/// change of user cleared, so it would outlive `unshare`.
struct KillOnDrop(u32);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        // SAFETY: kill has no memory effects; a pid already gone is ESRCH.
        unsafe { libc::kill(self.0 as libc::pid_t, libc::SIGKILL) };
    }
}

/// The pid of `unshare`'s child (the squatter), whose mount namespace a flight joins.
fn child_pid(unshare: u32) -> u32 {
    poll_until(Duration::from_secs(10), || {
        std::fs::read_to_string(format!("/proc/{unshare}/task/{unshare}/children"))
            .ok()
            .and_then(|t| t.split_whitespace().next().and_then(|p| p.parse().ok()))
    })
    .expect("unshare started its child")
}

/// `aeris run` as root beside the squatter (its mount namespace), for flight `flight`:
/// it must fail at once; its stderr.
fn fly_beside(pid: u32, flight: &str, dir: &Path) -> String {
    let out = Command::new("nsenter")
        .args(["-t", &pid.to_string(), "-m", "--"])
        .arg(aeris_bin())
        .args(["run", "--flight", flight, "--run-dir"])
        .arg(dir.join("run"))
        .stdin(Stdio::null())
        .output()
        .expect("run aeris run");
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "the flight joined a squatter:\n{text}"
    );
    text
}

/// Wait until the squatter `pid` made services (its manifest first) in its namespace.
fn wait_for_services(pid: u32, log: &Path) {
    let dir = format!("/proc/{pid}/root/tmp/iceoryx2/services");
    poll_until(Duration::from_secs(60), || {
        let made = std::fs::read_dir(&dir)
            .ok()?
            .flatten()
            .any(|e| e.file_name().to_string_lossy().ends_with(".service"));
        made.then_some(())
    })
    .unwrap_or_else(|| {
        panic!(
            "the squatter made no service: {}",
            std::fs::read_to_string(log).unwrap_or_default()
        )
    });
}

/// A role of `flight` run by `nobody` (its spec readable by all): it makes the flight's
/// manifest and its topics' services.
fn squatting_role(dir: &Path, flight: &str) -> std::path::PathBuf {
    let spec = role_spec(
        flight,
        "perception",
        aeris_schemas::RoleKind::Perception,
        "geometric",
        serde_json::json!({}),
    );
    let path = write_spec(dir, &spec);
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
    path
}

/// `nobody` runs a role of a new flight in a fresh private namespace (after `prepare`, run
/// as root there), making its services; then `aeris run` of that flight as root beside it.
/// The flight's flight name and what `aeris run` printed (it must fail).
fn squat_then_fly(dir: &Path, tag: &str, prepare: &str) -> (String, String) {
    let flight = unique_flight(tag);
    let spec = squatting_role(dir, &flight);
    let log = dir.join(format!("{tag}.log"));
    let squat = squatter(
        prepare,
        &aeris_bin(),
        &["role", "--spec", spec.to_str().unwrap()],
        &log,
    );
    let pid = child_pid(squat.pid());
    let _role = KillOnDrop(pid);
    wait_for_services(pid, &log);
    let text = fly_beside(pid, &flight, dir);
    (flight, text)
}

#[test]
fn a_flight_whose_services_another_user_made_first_is_refused_naming_the_owner() {
    let dir = TempDir::new("squat");
    // another user is first on a fresh machine: iceoryx2's directories are theirs
    let (_, text) = squat_then_fly(&dir.0, "squat", "");
    assert!(
        text.contains("iceoryx2's directory /tmp/iceoryx2")
            && text.contains("belongs to nobody (uid 65534): only root may own it"),
        "{text}"
    );
    // iceoryx2's directories are root's but open to all (sticky): the service itself is
    // the other user's
    let (flight, text) = squat_then_fly(
        &dir.0,
        "squat2",
        "mkdir -m 1777 /tmp/iceoryx2/services /tmp/iceoryx2/nodes &&",
    );
    assert!(
        text.contains(&format!(
            "service `aeris/{flight}/manifest` was made by nobody (uid 65534), not by root (uid 0)"
        )),
        "{text}"
    );
}
