//! Roles on another host: two hosts as network namespaces (each with a private /dev/shm, so
//! only the network crosses), `aeris agent` on the ground host, the flight's supervisor on
//! the vehicle; the reasoner and the perception role run on the ground host, their topics on
//! the bridges over zenoh, every link mutual TLS with keys of the flight's CA.

use aeris_hosts::netns::{GROUND_CLOCK_AHEAD_S, HostLink};
use aeris_tests::hosts::{TwoHosts, two_hosts};
use aeris_tests::*;
use std::path::Path;
use std::process::Stdio;
use std::time::Duration;

const FLIGHT_BOUND: Duration = Duration::from_secs(600);
/// The link timeout (ms) of the tests whose subject is not how soon a silent link is
/// noticed: longer than the holds of a CPU measured on CI's VM (with the default, 1 s, a
/// flight beside another on two cores lost its link to the ground host while starting).
const LINK_TIMEOUT_MS: &str = "8000";

/// The flight's keys for `hosts` in `dir` (a CA, the vehicle's and the ground's identities).
fn keys(hosts: &TwoHosts, dir: &Path) -> HostLink {
    hosts.make_keys(dir).expect("make the flight's keys")
}

/// The default workflow with the reasoner and the perception role on host `ground`, reached
/// over `link`.
fn ground_workflow(hosts: &TwoHosts, link: &HostLink) -> String {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../workflows/default.toml"),
    )
    .expect("workflows/default.toml");
    let text = text.replacen(
        "[executors.perception]",
        &format!(
            "{}\n[executors.gs]\nhost = \"ground\"\ncpus = \"all\"\n\n[executors.perception]",
            hosts.ground_host_toml(link)
        ),
        1,
    );
    let moved = text
        .replacen(
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"perception\"",
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
            1,
        )
        .replacen(
            "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"perception\"",
            "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"gs\"",
            1,
        );
    assert_eq!(moved.matches("executor = \"gs\"").count(), 2, "{moved}");
    moved
}

/// `workflow`'s link to the ground host with a timeout of [`LINK_TIMEOUT_MS`].
fn with_link_timeout(workflow: &str) -> String {
    let text = workflow.replacen(
        "[hosts.ground]\n",
        &format!("[hosts.ground]\nlink_timeout_ms = {LINK_TIMEOUT_MS}\n"),
        1,
    );
    assert!(text.contains("link_timeout_ms = "), "{text}");
    text
}

/// Start `aeris agent --host ground` in the ground namespace on `link`; returns once it
/// listens.
fn start_agent(hosts: &TwoHosts, link: &HostLink, dir: &Path) -> ChildGuard {
    start_agent_with(hosts, link, dir, &[])
}

/// [`start_agent`] with more arguments for `aeris agent`.
fn start_agent_with(hosts: &TwoHosts, link: &HostLink, dir: &Path, extra: &[&str]) -> ChildGuard {
    let log = dir.join("agent.log");
    let out = std::fs::File::create(&log).unwrap();
    let err = out.try_clone().unwrap();
    let mut cmd = hosts.agent_command(&aeris_bin(), link, &dir.join("agent"));
    cmd.args(extra).stdin(Stdio::null()).stdout(out).stderr(err);
    let mut agent = ChildGuard::spawn(&mut cmd).expect("spawn aeris agent");
    let listening = poll_until(Duration::from_secs(30), || {
        if let Ok(Some(status)) = agent.0.try_wait() {
            panic!(
                "the agent exited ({status}): {}",
                std::fs::read_to_string(&log).unwrap_or_default()
            );
        }
        std::fs::read_to_string(&log)
            .ok()
            .filter(|t| t.contains("listening on"))
    });
    assert!(listening.is_some(), "the agent never listened");
    agent
}

/// `aeris run WORKFLOW --json --flight FLIGHT` on the vehicle host, its stdout and stderr in
/// `dir/run.stdout` and `dir/run.stderr` ([`run_output`]).
fn fly_on_the_vehicle(hosts: &TwoHosts, dir: &Path, workflow: &Path, flight: &str) -> ChildGuard {
    let stdout = std::fs::File::create(dir.join("run.stdout")).unwrap();
    let stderr = std::fs::File::create(dir.join("run.stderr")).unwrap();
    let mut cmd = hosts.command(&hosts.vehicle, &aeris_bin());
    cmd.arg("run")
        .arg(workflow)
        .args(["--json", "--flight", flight, "--run-dir"])
        .arg(dir.join("run"))
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr);
    ChildGuard::spawn(&mut cmd).expect("spawn aeris run")
}

/// `aeris migrate ROLE TARGET --json` against `flight`, beside its `aeris run` (`run`): its
/// JSON.
fn migrate(
    hosts: &TwoHosts,
    run: &ChildGuard,
    flight: &str,
    role: &str,
    target: &str,
) -> serde_json::Value {
    let out = hosts
        .command_beside(run.0.id(), &aeris_bin())
        .args(["migrate", role, target, "--json", "--flight", flight])
        .output()
        .expect("run aeris migrate");
    let text = String::from_utf8_lossy(&out.stdout);
    let answer = last_json_line(&text);
    assert!(
        out.status.success() && answer["ok"] == true,
        "aeris migrate {role} {target}: {answer}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    answer
}

/// Wait until the hub of `flight` takes its decisions from the reasoner the supervisor
/// last moved to `place` (its instance, read from the run's stderr, is the hub report's
/// `decision_source`).
fn wait_for_decisions_of(
    hosts: &TwoHosts,
    run: &ChildGuard,
    dir: &Path,
    flight: &str,
    place: &str,
) {
    let log = std::fs::read_to_string(dir.join("run.stderr")).unwrap_or_default();
    let moving = format!("moving `planner` to {place} (pid ");
    let instance = log
        .lines()
        .rev()
        .find_map(|l| {
            let rest = &l[l.find(&moving)? + moving.len()..];
            let n = &rest[rest.find("instance ")? + "instance ".len()..];
            n.split(')').next()?.parse::<u32>().ok()
        })
        .unwrap_or_else(|| panic!("no `{moving}... instance N)` line:\n{log}"));
    let source = format!("decision_source: {instance},");
    let mut last = String::new();
    poll_until(Duration::from_secs(60), || {
        let out = hosts
            .command_beside(run.0.id(), &aeris_bin())
            .args(["topic", "echo", "hub/report", "--flight", flight, "-n", "1"])
            .output()
            .ok()?;
        last = String::from_utf8_lossy(&out.stdout).into_owned();
        last.contains(&source).then_some(())
    })
    .unwrap_or_else(|| panic!("the hub never took a decision of instance {instance}: {last}"));
}

#[test]
fn a_flight_with_roles_on_another_host_and_its_reasoner_moved_there_and_back_reaches_its_goal() {
    let dir = TempDir::new("hosts-goal");
    let hosts = two_hosts();
    let link = keys(&hosts, &dir.0);
    let _agent = start_agent_with(
        &hosts,
        &link,
        &dir.0,
        &["--link-timeout-ms", LINK_TIMEOUT_MS],
    );
    // the perception role on the ground host from the start, the reasoner on board
    let text = with_link_timeout(&ground_workflow(&hosts, &link)).replacen(
        "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
        "variants = [\"planner\", \"garbage\"]\nexecutor = \"perception\"",
        1,
    );
    let workflow = dir.0.join("ground.toml");
    std::fs::write(&workflow, text).unwrap();
    let flight = unique_flight("hosts");
    let mut run = fly_on_the_vehicle(&hosts, &dir.0, &workflow, &flight);
    // a host of the flight's CA that the agent does not obey publishes decisions of the
    // flight on the ground host's link the whole flight long: none may reach the flight
    // (its bridge would refuse them by schema, by name, and the hub count them)
    let HostLink::Tls(ids) = &link else {
        unreachable!("make_keys makes TLS keys")
    };
    aeris_hosts::keys::issue(&ids.store, "intruder", &[], 1, false).expect("issue intruder");
    let mut cmd = hosts.command(&hosts.vehicle, &peer_bin());
    cmd.args([
        "publish",
        &hosts.ground_endpoint(&link),
        &flight,
        "reasoning/decision",
    ])
    .env("AERIS_PEER_KEYS", ids.store.join("intruder"));
    let mut intruder = logged(&mut cmd, &dir.0.join("intruder.log"));
    // the reasoner moves to the ground host while flying, then back on board
    wait_for_text(
        &dir.0.join("run.stderr"),
        "step 2/4",
        "the flight's progress",
    );
    // refused by name: a role that stays on the flight's host, a host not declared
    for (role, target, why) in [
        (
            "hub",
            "ground:gs",
            "role `hub` (kind hub) cannot move to another host: it runs on the flight's host",
        ),
        (
            "reasoning",
            "air:gs",
            "`air:gs` is not an executor on another host (declared: ground:gs)",
        ),
    ] {
        let out = hosts
            .command_beside(run.0.id(), &aeris_bin())
            .args(["migrate", role, target, "--flight", &flight])
            .output()
            .expect("run aeris migrate");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(why), "{err}");
    }
    let there = migrate(&hosts, &run, &flight, "reasoning", "ground:gs");
    // `aeris status` shows where each role runs: the host with the executor there
    let status = hosts
        .command_beside(run.0.id(), &aeris_bin())
        .args(["status", "--json", "--flight", &flight])
        .output()
        .expect("run aeris status");
    let status = last_json_line(&String::from_utf8_lossy(&status.stdout));
    let executor_of = |role: &str| {
        status["roles"]
            .as_array()
            .and_then(|roles| roles.iter().find(|r| r["name"] == role))
            .map(|r| r["executor"].clone())
    };
    assert_eq!(
        executor_of("reasoning"),
        Some("ground:gs".into()),
        "{status}"
    );
    assert_eq!(executor_of("hub"), Some("control".into()), "{status}");
    // and the link, as its bridge measures it: answered probes, a round trip, the ground
    // host's CPUs
    let link = &status["links"][0];
    assert_eq!(link["host"], "ground", "{status}");
    assert_eq!(link["connected"], true, "{status}");
    assert!(link["answered"].as_u64().unwrap() > 0, "{status}");
    assert!(link["rtt_ms"].as_f64().unwrap() > 0.0, "{status}");
    assert!(link["loss"].as_f64().unwrap() < 1.0, "{status}");
    assert!(link["cpus"].as_u64().unwrap() > 0, "{status}");
    // the ground host's clock runs an hour ahead (a time namespace): the link sees it, and
    // the roles there stamp in the vehicle's clock (else every decision would be late)
    let offset_s = link["clock_offset_ms"].as_f64().unwrap() / 1e3;
    assert!(
        (offset_s - GROUND_CLOCK_AHEAD_S as f64).abs() < 1.0,
        "{status}"
    );
    // the hub takes a decision of the reasoner on the ground before it moves back (else
    // the move back can come within one heartbeat, before the hub ever switched to it)
    wait_for_decisions_of(&hosts, &run, &dir.0, &flight, "host `ground` (executor gs)");
    let back = migrate(&hosts, &run, &flight, "reasoning", "perception");
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND);
    let (out, err) = run_output(&dir.0);
    let agent_log = std::fs::read_to_string(dir.0.join("agent.log")).unwrap_or_default();
    let context = || {
        format!(
            "{err}\n--- agent\n{agent_log}\n{}",
            run_logs_tail(&dir.0, 15)
        )
    };
    assert!(
        status.is_some_and(|s| s.success()),
        "flight failed ({status:?}): {}",
        context()
    );
    let summary = last_json_line(&out);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{}", context());
    // the intruder was connected and published all along (it exits on any failure), and
    // nothing of it crossed
    assert!(
        intruder.0.try_wait().is_ok_and(|s| s.is_none()),
        "the intruder stopped: {}",
        std::fs::read_to_string(dir.0.join("intruder.log")).unwrap_or_default()
    );
    drop(intruder);
    let bridge_log =
        std::fs::read_to_string(dir.0.join("run/logs/bridge-to-ground.log")).unwrap_or_default();
    assert!(!bridge_log.contains("refused"), "{bridge_log}");
    // decisions crossed the link and were committed, none refused, lost or out of order
    // (a cycle may still reuse a decision when the machine is busy: EER is measured, not
    // asserted)
    assert!(
        summary["cycles_committed"].as_u64().unwrap() > 0,
        "{summary}"
    );
    assert_eq!(summary["decisions_rejected"], 0, "{summary}");
    assert_eq!(summary["sequence_gaps"], 0, "{summary}");
    assert_eq!(summary["sequence_reorders"], 0, "{summary}");
    // (controller ticks that missed their deadline are a timing figure of the machine, not
    // of the link: measured by `aeris bench hosts`, not asserted; CI once missed 1 of 2936
    // with a formation flight of nine processes beside this one)
    // stamps taken on the ground host are in the vehicle's clock: no stage of a cycle
    // (perception there, reasoning there or on board) lasts longer than the whole flight
    let duration_s = summary["duration_s"].as_f64().unwrap();
    for stage in ["perception", "reasoning", "routing"] {
        let s = summary["stages_mean_s"][stage].as_f64().unwrap();
        assert!((0.0..duration_s).contains(&s), "{stage}: {summary}");
    }
    // the run summary ends with the link's figures
    assert_eq!(summary["links"][0]["host"], "ground", "{summary}");
    assert!(
        summary["links"][0]["answered"].as_u64().unwrap() > 0,
        "{summary}"
    );
    // each move: the new process took over and the old one stopped; the hub followed
    assert!(
        there["message"]
            .as_str()
            .unwrap()
            .contains("move of `planner` to host `ground` (executor gs) done"),
        "{there}"
    );
    assert!(
        back["message"]
            .as_str()
            .unwrap()
            .contains("move of `planner` to the flight's host (executor perception) done"),
        "{back}"
    );
    assert_ne!(there["pid"], back["pid"], "{there}\n{back}");
    assert!(
        summary["source_switches"].as_u64().unwrap() >= 2,
        "{summary}"
    );
    // the roles ran on the ground host, started by its agent, and ended cleanly (the
    // reasoner when it moved back, the others with the flight); the agent notes a role's
    // end when it reaps it, which may come after the flight's own end: read its log until
    // every end is there (bounded)
    let ended = |log: &str, role: &str| {
        log.lines().any(|l| {
            l.starts_with(&format!("{flight}/{role}#")) && l.contains("ended: exit code 0")
        })
    };
    let roles = ["reasoning", "perception", "bridge-on-ground"];
    let agent_log = poll_until(Duration::from_secs(30), || {
        let log = std::fs::read_to_string(dir.0.join("agent.log")).unwrap_or_default();
        roles.iter().all(|r| ended(&log, r)).then_some(log)
    })
    .unwrap_or_else(|| std::fs::read_to_string(dir.0.join("agent.log")).unwrap_or_default());
    for role in roles {
        assert!(
            agent_log.contains(&format!("started {flight}/{role}#")),
            "{role} was not started by the agent:\n{agent_log}"
        );
        assert!(
            ended(&agent_log, role),
            "{role} did not end cleanly on the ground host:\n{agent_log}"
        );
    }
    // on the vehicle, a role on the ground host is its handle: its log says where it ran
    let handle_log = std::fs::read_to_string(dir.0.join("run/logs/perception.log")).unwrap();
    assert!(
        handle_log.contains("role `perception` runs on host `ground` as pid"),
        "{handle_log}"
    );
}

/// The conformance peer built beside `aeris` (`tests/src/bin/aeris-zenoh-peer.rs`).
fn peer_bin() -> std::path::PathBuf {
    aeris_bin().with_file_name("aeris-zenoh-peer")
}

/// Wait until `path` holds `needle`; its text.
fn wait_for_text(path: &Path, needle: &str, what: &str) -> String {
    poll_until(Duration::from_secs(60), || {
        std::fs::read_to_string(path)
            .ok()
            .filter(|t| t.contains(needle))
    })
    .unwrap_or_else(|| {
        panic!(
            "{what}: `{needle}` never came:\n{}",
            std::fs::read_to_string(path).unwrap_or_default()
        )
    })
}

fn logged(cmd: &mut std::process::Command, path: &Path) -> ChildGuard {
    let out = std::fs::File::create(path).unwrap();
    let err = out.try_clone().unwrap();
    cmd.stdin(Stdio::null()).stdout(out).stderr(err);
    ChildGuard::spawn(cmd).expect("spawn")
}

#[test]
fn a_host_or_a_peer_of_another_schema_is_refused_by_name() {
    let dir = TempDir::new("hosts-schema");
    let hosts = two_hosts();
    let ours = aeris_schemas::SCHEMA_VERSION;
    let theirs = ours - 1;
    let link = keys(&hosts, &dir.0);
    let HostLink::Tls(ids) = &link else {
        unreachable!("make_keys makes TLS keys")
    };
    let endpoint = hosts.ground_endpoint(&link);

    // an agent of another schema: the flight's handles refuse its host, the flight does not
    // start, and the error names the host and both schemas
    let peer_log = dir.0.join("peer-agent.log");
    let mut cmd = hosts.command(&hosts.ground, &peer_bin());
    cmd.args(["agent", &endpoint, "ground"])
        .env("AERIS_PEER_KEYS", ids.ground());
    let peer_agent = logged(&mut cmd, &peer_log);
    wait_for_text(&peer_log, "listening", "the peer agent");
    let workflow = dir.0.join("ground.toml");
    std::fs::write(&workflow, ground_workflow(&hosts, &link)).unwrap();
    let mut cmd = hosts.command(&hosts.vehicle, &aeris_bin());
    cmd.arg("run")
        .arg(&workflow)
        .args(["--flight", &unique_flight("hosts-schema"), "--run-dir"])
        .arg(dir.0.join("run"));
    let mut run = logged(&mut cmd, &dir.0.join("run.log"));
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND).expect("the flight ended");
    let text = std::fs::read_to_string(dir.0.join("run.log")).unwrap();
    assert!(!status.success(), "{text}");
    assert!(
        text.contains(&format!(
            "host `ground` speaks schema s{theirs} (layout 0x0123456789abcdef), this build schema s{ours}"
        )),
        "{text}"
    );
    // whichever of the roles placed there asks the host first is refused by name (the
    // bridge, the reasoner or perception: which one is the machine's timing)
    assert!(
        ["bridge-on-ground", "reasoning", "perception"]
            .iter()
            .any(|role| text.contains(&format!("cannot run role `{role}`"))),
        "{text}"
    );
    // final: a refused schema is not retried
    assert!(
        !text.contains("restart(s)") || text.contains("after 0 restart(s)"),
        "{text}"
    );
    drop(peer_agent);

    // the real agent refuses a supervisor of another schema
    let _agent = start_agent(&hosts, &link, &dir.0);
    let out = hosts
        .command(&hosts.vehicle, &peer_bin())
        .args(["spawn", &endpoint, "ground", "hosts-schema-spawn"])
        .env("AERIS_PEER_KEYS", ids.vehicle())
        .output()
        .expect("run the peer");
    let answer = String::from_utf8_lossy(&out.stdout);
    assert!(answer.contains("\"refused\""), "{answer}");
    assert!(
        answer.contains(&format!(
            "the supervisor of flight `hosts-schema-spawn` speaks schema s{theirs}"
        )) && answer.contains(&format!("this build schema s{ours}")),
        "{answer}"
    );

    // a bridge refuses messages of another schema, names the peer and both schemas once,
    // and publishes nothing of them
    let flight = unique_flight("hosts-bridge");
    let spec = role_spec(
        &flight,
        "bridge-on-ground",
        aeris_schemas::RoleKind::Bridge,
        "zenoh",
        serde_json::json!({
            "connect": endpoint,
            "keys": ids.ground(),
            "import": ["reasoning/decision"],
            "export": [],
            "peer": "the test peer",
        }),
    );
    let spec_path = write_spec(&dir.0, &spec);
    let bridge_log = dir.0.join("bridge.log");
    let mut cmd = hosts.command(&hosts.ground, &aeris_bin());
    cmd.arg("role").arg("--spec").arg(&spec_path);
    let _bridge = logged(&mut cmd, &bridge_log);
    wait_for_text(&bridge_log, "bridge to the test peer", "the bridge");
    let mut cmd = hosts.command(&hosts.vehicle, &peer_bin());
    cmd.args(["publish", &endpoint, &flight, "reasoning/decision"])
        .env("AERIS_PEER_KEYS", ids.vehicle());
    let _publisher = logged(&mut cmd, &dir.0.join("publisher.log"));
    let text = wait_for_text(&bridge_log, "refused", "the bridge");
    assert!(
        text.contains(&format!(
            "bridge: refused `reasoning/decision`: the bridge of the test peer speaks schema s{theirs} (layout 0x0123456789abcdef), this build schema s{ours}"
        )),
        "{text}"
    );
}

#[test]
fn a_link_cut_mid_flight_hands_the_reasoner_to_its_fallback_which_hands_it_back_when_the_link_returns()
 {
    let dir = TempDir::new("hosts-cut");
    let hosts = two_hosts();
    let link = keys(&hosts, &dir.0);
    // The subject is one loss, by the cut, and one return: a link timeout longer than the
    // machine's own holds. On CI's 2-CPU VM a CPU ran no ordinary thread for up to 6.3 s at
    // a time (the supervisor's `CpuWatch` events), which with the default 1 s timeout lost
    // the link before the cut (zenoh's lease ran out on both sides, the handles exited as
    // unreachable) and failed this test for the machine, not for the link. Both sides: the
    // agent's session and the flight's.
    let _agent = start_agent_with(
        &hosts,
        &link,
        &dir.0,
        &["--link-timeout-ms", LINK_TIMEOUT_MS],
    );
    // only the reasoner on the ground host, the on-board planner as its fallback
    let text = with_link_timeout(&ground_workflow(&hosts, &link));
    let text = text.replacen(
        "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"gs\"",
        "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"perception\"",
        1,
    );
    let text = text.replacen(
        "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
        "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"\nfallback = \"planner\"\nfallback_executor = \"perception\"",
        1,
    );
    let workflow = dir.0.join("cut.toml");
    std::fs::write(&workflow, text).unwrap();
    let flight = unique_flight("hosts-cut");
    let mut run = fly_on_the_vehicle(&hosts, &dir.0, &workflow, &flight);
    // the reasoner on the ground host has been flying the mission for a while: cut the link
    wait_for_text(
        &dir.0.join("run.stderr"),
        "step 2/4",
        "the flight's progress",
    );
    hosts.set_link(false).expect("cut the link");
    let cut = wait_for_text(
        &dir.0.join("run.stderr"),
        "fallback `planner` starting",
        "the cut",
    );
    // the supervisor heard the reasoner fall silent, or its handle lost the host's agent
    // first (after a pause of the machine): a lost link either way
    assert!(
        cut.contains("link to host `ground` lost (role `reasoning` silent for")
            || cut.contains("host `ground` unreachable (role `reasoning` could not reach"),
        "{cut}"
    );
    // the fallback took over on the flight's host: then the link comes back
    let ready = wait_for_text(
        &dir.0.join("run.stderr"),
        "role `reasoning`: `planner` (pid",
        "the fallback's readiness",
    );
    // the link is still cut: nothing counts it back (the bridge's session here reports
    // the other host connected until its own lease runs out)
    assert!(!ready.contains("link to host `ground` back"), "{ready}");
    hosts.set_link(true).expect("restore the link");
    // the link held: the ground host's bridge restarted there, and the reasoner returns to
    // the ground host, make-before-break
    let back = wait_for_text(
        &dir.0.join("run.stderr"),
        "move of `planner` to host `ground` (executor gs) done",
        "the reasoner's return",
    );
    assert!(
        back.contains("link to host `ground` back: role `bridge-on-ground` restarted")
            && back.contains(
                "link to host `ground` back: role `reasoning` returns there as `planner`"
            ),
        "{back}"
    );
    let status = wait_bounded(&mut run.0, FLIGHT_BOUND);
    let (out, err) = run_output(&dir.0);
    assert!(
        status.is_some_and(|s| s.success()),
        "flight failed ({status:?}): {err}\n{}",
        run_logs_tail(&dir.0, 15)
    );
    let summary = last_json_line(&out);
    assert_eq!(summary["reached_goal"], true, "{summary}\n{err}");
    // no setpoint was refused (missed controller ticks are the machine's timing, measured
    // by `aeris bench hosts`, not asserted)
    assert_eq!(summary["controller_refused_setpoints"], 0, "{summary}");
    // the hub switched to the fallback's decisions
    assert!(
        summary["source_switches"].as_u64().unwrap() >= 1,
        "{summary}"
    );
    // one loss of the reasoner's link, one return, no flapping
    assert_eq!(
        err.matches("lost (role `reasoning`").count()
            + err.matches("unreachable (role `reasoning`").count(),
        1,
        "{err}"
    );
    assert_eq!(
        err.matches("role `reasoning` returns there").count(),
        1,
        "{err}"
    );
}

#[test]
fn a_host_unreachable_at_the_start_never_holds_the_flight_back_and_gets_its_role_when_it_comes() {
    // no agent on the ground host yet: the reasoner's fallback flies, the bridge there
    // waits for the link; then the agent starts, and the reasoner goes to the ground host
    let dir = TempDir::new("hosts-unreachable");
    let hosts = two_hosts();
    let link = keys(&hosts, &dir.0);
    let text = ground_workflow(&hosts, &link)
        .replacen(
            "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"gs\"",
            "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"perception\"",
            1,
        )
        .replacen(
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"\nfallback = \"planner\"\nfallback_executor = \"perception\"",
            1,
        );
    let workflow = dir.0.join("unreachable.toml");
    std::fs::write(&workflow, text).unwrap();
    let stdout = std::fs::File::create(dir.0.join("run.stdout")).unwrap();
    let stderr = std::fs::File::create(dir.0.join("run.stderr")).unwrap();
    let mut cmd = hosts.command(&hosts.vehicle, &aeris_bin());
    cmd.arg("run")
        .arg(&workflow)
        .args(["--json", "--max-duration", "20", "--flight"])
        .arg(unique_flight("hosts-unreachable"))
        .arg("--run-dir")
        .arg(dir.0.join("run"))
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr);
    let mut run = ChildGuard::spawn(&mut cmd).expect("spawn aeris run");
    let started = wait_for_text(&dir.0.join("run.stderr"), "step 1/4", "the flight's start");
    assert!(
        started.contains("host `ground` unreachable (role `reasoning` could not reach its agent): fallback `planner` starting on the flight's host")
            && started.contains("host `ground` unreachable (role `bridge-on-ground` could not reach its agent): it waits for the link"),
        "{started}"
    );
    let _agent = start_agent(&hosts, &link, &dir.0);
    let back = wait_for_text(
        &dir.0.join("run.stderr"),
        "move of `planner` to host `ground` (executor gs) done",
        "the reasoner's move to the ground host",
    );
    assert!(
        back.contains("link to host `ground` back: role `bridge-on-ground` restarted")
            && back.contains(
                "link to host `ground` back: role `reasoning` returns there as `planner`"
            ),
        "{back}"
    );
    wait_bounded(&mut run.0, FLIGHT_BOUND).expect("the flight ended");
    let (out, err) = run_output(&dir.0);
    let summary = last_json_line(&out);
    // it flew on the fallback's decisions, then on the ground host's
    assert!(
        summary["cycles_committed"].as_u64().unwrap_or(0) > 0,
        "{summary}\n{err}"
    );
    assert!(
        summary["source_switches"].as_u64().unwrap_or(0) >= 1,
        "{summary}"
    );
    assert_eq!(summary["decisions_rejected"], 0, "{summary}");
}
