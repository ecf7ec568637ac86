//! `aeris bench hosts`: the default flight with roles on a second host, both hosts on this
//! machine ([`TwoHosts`]: network namespaces joined by a veth pair, private `/dev/shm`, so
//! only the network crosses), `aeris agent` on the ground host and `aeris run` on the
//! vehicle, every process real. Four measurements:
//! - **across the link vs local**: the flight with every role on board, then with the
//!   reasoner and the perception role on the ground host, per link delay (tc netem, where
//!   the kernel has it): CT (S_t → decision → bound setpoint), EER, the frames that crossed
//!   (count, bytes per frame, per second);
//! - **moves**: the reasoner moved to the ground host and back during a flight (`aeris
//!   migrate`): time to ready and to done each way, decisions reused over the flight;
//! - **the link cut**: the reasoner on the ground host with the on-board planner as its
//!   fallback; the link cut mid-flight, then restored once the fallback took over: time from
//!   the cut to the loss noticed and to the fallback ready, and from the restore to the
//!   reasoner back on the ground host;
//! - all of it beside `outside_load` busy processes outside the flight, if asked.
//!
//! Every link is mutual TLS with keys made for the run, as a user's flight's is. With
//! `security` the benchmark instead compares TLS with plain TCP ([`security`]).
//!
//! Needs root (network namespaces). Times are taken by this process as the flight's lines
//! arrive (the supervisor prints each event as it happens).

use aeris_hosts::netns::{HostLink, NetnsError, TwoHosts};
use serde::Serialize;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::{Duration, Instant};

mod ping;
mod placement;
mod security;

pub use ping::PingFigures;
pub use placement::PlacementFigures;
use placement::placement;
pub use security::{SecurityReport, SecurityRow, compare_links};

/// How long one benchmark flight may take.
const FLIGHT_BOUND: Duration = Duration::from_secs(600);
/// How long the agent may take to listen, or a flight to print an awaited line.
const STEP_BOUND: Duration = Duration::from_secs(120);

/// What `aeris bench hosts` runs.
#[derive(Debug, Clone)]
pub struct HostsBenchConfig {
    /// The `aeris` executable the flights and the agent run.
    pub aeris: PathBuf,
    /// Link delays (ms, each way) of the rows across the link; 0 is the bare veth link.
    pub delays_ms: Vec<u32>,
    /// Packet loss (%, each way) of one more row across the link, at delay 0 (0: none).
    pub loss_percent: f64,
    /// Busy processes outside the flight (unpinned, normal priority) during every flight.
    pub outside_load: usize,
    /// Where the flights' run directories go.
    pub work_dir: PathBuf,
}

/// How a benchmark flight's link is secured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LinkKind {
    /// Mutual TLS (keys made for the flight).
    Tls,
    /// Plain TCP (`insecure`).
    Tcp,
}

/// Why the hosts benchmark could not run to the end.
#[derive(Debug, thiserror::Error)]
pub enum HostsBenchError {
    /// The two hosts could not be set up (not root, no `ip`).
    #[error("cannot set up two hosts as network namespaces (needs root)")]
    Hosts(#[from] NetnsError),
    /// The outside load could not be started.
    #[error(transparent)]
    OutsideLoad(#[from] crate::flights::OutsideLoadError),
    /// The flight's keys could not be made.
    #[error("cannot make the flight's keys")]
    Keys(#[from] aeris_hosts::keys::KeysError),
    /// A file or process of the benchmark could not be made.
    #[error("{what}")]
    Io {
        /// What was being done.
        what: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A process of the flight failed or misbehaved (its own words quoted).
    #[error("{0}")]
    Flight(String),
}

fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> HostsBenchError {
    let what = what.into();
    move |source| HostsBenchError::Io { what, source }
}

/// One flight of the comparison: where the roles ran and what the link was.
#[derive(Debug, Clone, Serialize)]
pub struct LinkRow {
    /// The roles on the ground host (empty: all on board).
    pub roles_there: Vec<String>,
    /// Link delay each way (ms).
    pub delay_ms: u32,
    /// Packet loss each way (%).
    pub loss_percent: f64,
    /// Why the row was not flown (no netem in this kernel), else `None`.
    pub skipped: Option<String>,
    /// The flight reached its goal.
    pub reached_goal: Option<bool>,
    /// Semantic cycles flown.
    pub cycles: Option<u64>,
    /// Cycle time mean (s): S_t → decision → bound setpoint, committed cycles.
    pub ct_mean_s: Option<f64>,
    /// Cycle time p95 (s).
    pub ct_p95_s: Option<f64>,
    /// Execution error rate: cycles that reused a decision.
    pub eer: Option<f64>,
    /// Controller ticks whose setpoint never reached the autopilot.
    pub controller_missed_ticks: Option<u64>,
    /// Frames (`camera/rgb`) sent to the ground host.
    pub frames_across: Option<u64>,
    /// Bytes per frame on the link (header and pixels).
    pub bytes_per_frame: Option<f64>,
    /// Frames per second of flight.
    pub frames_per_s: Option<f64>,
    /// The link's round trip as its bridge measured it at the end of the flight (ms,
    /// smoothed): what a decision across the link pays at least. Measured in every row: the
    /// bridges run whatever runs there.
    pub link_rtt_ms: Option<f64>,
    /// Probes the link lost over the last window (fraction).
    pub link_loss: Option<f64>,
    /// Mean time to encode a frame for the link (ms).
    pub frame_coding_ms: Option<f64>,
}

/// The reasoner moved to the ground host and back during a flight.
#[derive(Debug, Clone, Serialize)]
pub struct MoveFigures {
    /// From the request to the new process's first heartbeat there (ms).
    pub there_ready_ms: u64,
    /// From the request to the old process stopped (ms).
    pub there_done_ms: u64,
    /// The same for the move back.
    pub back_ready_ms: u64,
    /// The same for the move back.
    pub back_done_ms: u64,
    /// Cycles of the flight that reused a decision (the moves are its only disturbance).
    pub decisions_reused: u64,
    /// Controller ticks whose setpoint never reached the autopilot.
    pub controller_missed_ticks: u64,
    /// The flight reached its goal.
    pub reached_goal: bool,
}

/// The link cut mid-flight and restored.
#[derive(Debug, Clone, Serialize)]
pub struct CutFigures {
    /// From the cut to the supervisor counting the link as lost (ms).
    pub loss_noticed_ms: u64,
    /// From the cut to the on-board fallback's first heartbeat: it decides from then on (ms).
    pub fallback_ready_ms: u64,
    /// From the restore to the reasoner back on the ground host, old process stopped (ms;
    /// includes the 5 s hysteresis).
    pub returned_ms: u64,
    /// Cycles of the flight that reused a decision.
    pub decisions_reused: u64,
    /// Controller ticks whose setpoint never reached the autopilot.
    pub controller_missed_ticks: u64,
    /// The flight reached its goal.
    pub reached_goal: bool,
}

/// Everything `aeris bench hosts` measured.
#[derive(Debug, Clone, Serialize)]
pub struct HostsReport {
    /// Busy processes outside the flight.
    pub outside_load: usize,
    /// Local and across-the-link flights.
    pub rows: Vec<LinkRow>,
    /// The moves there and back.
    pub moves: MoveFigures,
    /// The link cut.
    pub cut: CutFigures,
    /// Placement by measurement across the link.
    pub placement: PlacementFigures,
}

/// The default workflow with host `ground` (its `[hosts.ground]` table `host_table`;
/// executor `gs`, all its CPUs), the roles named in `there` on it, and with `fallback` the
/// on-board planner as the reasoner's fallback.
pub fn ground_workflow(host_table: &str, there: &[&str], fallback: bool) -> String {
    let text = aeris_orchestrator::workflow::DEFAULT_WORKFLOW_TOML.replacen(
        "[executors.perception]",
        &format!(
            "{host_table}\n[executors.gs]\nhost = \"ground\"\ncpus = \"all\"\n\n[executors.perception]"
        ),
        1,
    );
    let mut out = Vec::new();
    let mut name = String::new();
    for line in text.lines() {
        if let Some(n) = line.strip_prefix("name = ") {
            name = n.trim_matches('"').to_string();
        }
        if line.starts_with("executor = ") && there.contains(&name.as_str()) {
            out.push("executor = \"gs\"".to_string());
            if fallback && name == "reasoning" {
                out.push("fallback = \"planner\"".to_string());
                out.push("fallback_executor = \"perception\"".to_string());
            }
            continue;
        }
        out.push(line.to_string());
    }
    out.join("\n") + "\n"
}

/// The agent on the ground host, stopped on drop.
struct Agent(Child);

impl Drop for Agent {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The link of `kind` between `hosts`, its keys (if any) made in `dir`.
fn link_of(hosts: &TwoHosts, kind: LinkKind, dir: &Path) -> Result<HostLink, HostsBenchError> {
    Ok(match kind {
        LinkKind::Tls => hosts.make_keys(dir)?,
        LinkKind::Tcp => HostLink::Insecure,
    })
}

fn start_agent(
    hosts: &TwoHosts,
    aeris: &Path,
    link: &HostLink,
    dir: &Path,
) -> Result<Agent, HostsBenchError> {
    let log = dir.join("agent.log");
    let out = std::fs::File::create(&log).map_err(io(format!("create {}", log.display())))?;
    let err = out.try_clone().map_err(io("agent log"))?;
    let mut cmd = hosts.agent_command(aeris, link, &dir.join("agent"));
    cmd.stdin(Stdio::null()).stdout(out).stderr(err);
    let mut agent = Agent(cmd.spawn().map_err(io("start aeris agent"))?);
    let start = Instant::now();
    loop {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        if text.contains("listening on") {
            return Ok(agent);
        }
        if let Ok(Some(status)) = agent.0.try_wait() {
            return Err(HostsBenchError::Flight(format!(
                "the agent exited ({status}): {text}"
            )));
        }
        if start.elapsed() > STEP_BOUND {
            return Err(HostsBenchError::Flight(format!(
                "the agent did not listen within {} s: {text}",
                STEP_BOUND.as_secs()
            )));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A flight under way on the vehicle host: its stderr lines as they arrive, with their
/// arrival times.
struct Flight {
    child: Child,
    lines: Receiver<(Instant, String)>,
    seen: Vec<(Instant, String)>,
    stdout: std::thread::JoinHandle<String>,
    name: String,
    run_dir: PathBuf,
}

impl Flight {
    fn start(
        hosts: &TwoHosts,
        aeris: &Path,
        workflow: &Path,
        name: &str,
        run_dir: &Path,
    ) -> Result<Self, HostsBenchError> {
        let mut cmd = hosts.command(&hosts.vehicle, aeris);
        cmd.arg("run")
            .arg(workflow)
            .args(["--json", "--flight", name, "--run-dir"])
            .arg(run_dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().map_err(io("start aeris run"))?;
        let (tx, lines) = channel();
        let stderr = child.stderr.take();
        std::thread::spawn(move || {
            let Some(stderr) = stderr else { return };
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send((Instant::now(), line)).is_err() {
                    break;
                }
            }
        });
        let out = child.stdout.take();
        let stdout = std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(out) = out {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    text.push_str(&line);
                    text.push('\n');
                }
            }
            text
        });
        Ok(Flight {
            child,
            lines,
            seen: Vec::new(),
            stdout,
            name: name.to_string(),
            run_dir: run_dir.to_path_buf(),
        })
    }

    /// When the first line holding `needle` arrived (waiting for it if it has not yet).
    fn wait_line(&mut self, needle: &str) -> Result<Instant, HostsBenchError> {
        self.wait_line_after(needle, None)
    }

    /// When the first line holding `needle` arrived at or after `after` (any, if `None`),
    /// waiting for it if it has not yet: an event that also happened earlier in the flight
    /// (a link back at its start) is not taken for the one awaited.
    fn wait_line_after(
        &mut self,
        needle: &str,
        after: Option<Instant>,
    ) -> Result<Instant, HostsBenchError> {
        let fits = |t: &Instant, l: &str| l.contains(needle) && after.is_none_or(|a| *t >= a);
        if let Some((t, _)) = self.seen.iter().find(|(t, l)| fits(t, l)) {
            return Ok(*t);
        }
        let deadline = Instant::now() + STEP_BOUND;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok((t, line)) => {
                    let hit = fits(&t, &line);
                    self.seen.push((t, line));
                    if hit {
                        return Ok(t);
                    }
                }
                Err(RecvTimeoutError::Timeout) | Err(RecvTimeoutError::Disconnected) => {
                    let tail: Vec<&str> = self
                        .seen
                        .iter()
                        .rev()
                        .take(8)
                        .map(|(_, l)| l.as_str())
                        .collect();
                    return Err(HostsBenchError::Flight(format!(
                        "flight {}: `{needle}` never came; its last lines: {}",
                        self.name,
                        tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                    )));
                }
            }
        }
    }

    /// Wait for the end; the summary (the last JSON line of stdout).
    fn finish(self) -> Result<(serde_json::Value, PathBuf), HostsBenchError> {
        self.finish_with_lines()
            .map(|(summary, dir, _)| (summary, dir))
    }

    /// [`Flight::finish`], with every line the flight printed on stderr.
    fn finish_with_lines(
        mut self,
    ) -> Result<(serde_json::Value, PathBuf, Vec<String>), HostsBenchError> {
        let start = Instant::now();
        let status = loop {
            while let Ok(line) = self.lines.try_recv() {
                self.seen.push(line);
            }
            match self.child.try_wait() {
                Ok(Some(s)) => break s,
                Ok(None) if start.elapsed() > FLIGHT_BOUND => {
                    let _ = self.child.kill();
                    let _ = self.child.wait();
                    return Err(HostsBenchError::Flight(format!(
                        "flight {} did not end within {} s",
                        self.name,
                        FLIGHT_BOUND.as_secs()
                    )));
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(100)),
                Err(e) => return Err(io(format!("wait for flight {}", self.name))(e)),
            }
        };
        let out = self.stdout.join().unwrap_or_default();
        let summary = out
            .lines()
            .rev()
            .find_map(|l| serde_json::from_str::<serde_json::Value>(l).ok());
        match summary {
            Some(s) if status.success() => Ok((
                s,
                self.run_dir,
                self.seen.into_iter().map(|(_, l)| l).collect(),
            )),
            _ => {
                let tail: Vec<&str> = self
                    .seen
                    .iter()
                    .rev()
                    .take(8)
                    .map(|(_, l)| l.as_str())
                    .collect();
                Err(HostsBenchError::Flight(format!(
                    "flight {} failed ({status}): {}",
                    self.name,
                    tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                )))
            }
        }
    }
}

/// Messages and bytes of `topic` the bridge `bridge` sent, from its log (printed when it
/// stopped).
fn bridge_sent(run_dir: &Path, bridge: &str, topic: &str) -> Option<(u64, u64)> {
    let log = std::fs::read_to_string(run_dir.join("logs").join(format!("{bridge}.log"))).ok()?;
    let prefix = format!("bridge: sent `{topic}`: ");
    let line = log.lines().rev().find_map(|l| l.strip_prefix(&prefix))?;
    let mut numbers = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|w| !w.is_empty())
        .filter_map(|w| w.parse::<u64>().ok());
    Some((numbers.next()?, numbers.next()?))
}

/// `aeris migrate ROLE TARGET --json` beside `flight`: (ready ms, done ms).
fn migrate(
    hosts: &TwoHosts,
    aeris: &Path,
    flight: &Flight,
    role: &str,
    target: &str,
) -> Result<(u64, u64), HostsBenchError> {
    let out = hosts
        .command_beside(flight.child.id(), aeris)
        .args(["migrate", role, target, "--json", "--flight", &flight.name])
        .output()
        .map_err(io("run aeris migrate"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let answer = text
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .unwrap_or_default();
    if !out.status.success() || answer["ok"] != true {
        return Err(HostsBenchError::Flight(format!(
            "aeris migrate {role} {target}: {answer} {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let ready = answer["steps"]
        .as_array()
        .and_then(|steps| {
            steps.iter().find(|s| {
                s["message"]
                    .as_str()
                    .is_some_and(|m| m.contains("was ready after"))
            })
        })
        .and_then(|s| s["elapsed_ms"].as_u64())
        .unwrap_or(0);
    Ok((ready, answer["elapsed_ms"].as_u64().unwrap_or(0)))
}

fn u(summary: &serde_json::Value, key: &str) -> u64 {
    summary[key].as_u64().unwrap_or(0)
}

/// One benchmark flight's setting: fresh hosts, an agent there, the workflow written.
struct Setting {
    hosts: TwoHosts,
    _agent: Agent,
    workflow: PathBuf,
    dir: PathBuf,
}

fn setting(
    config: &HostsBenchConfig,
    tag: &str,
    there: &[&str],
    fallback: bool,
    kind: LinkKind,
) -> Result<Setting, HostsBenchError> {
    let dir = config.work_dir.join(tag);
    std::fs::create_dir_all(&dir).map_err(io(format!("create {}", dir.display())))?;
    let hosts = TwoHosts::new()?;
    let link = link_of(&hosts, kind, &dir)?;
    let agent = start_agent(&hosts, &config.aeris, &link, &dir)?;
    let workflow = dir.join("workflow.toml");
    std::fs::write(
        &workflow,
        ground_workflow(&hosts.ground_host_toml(&link), there, fallback),
    )
    .map_err(io(format!("write {}", workflow.display())))?;
    Ok(Setting {
        hosts,
        _agent: agent,
        workflow,
        dir,
    })
}

impl Setting {
    /// Start the flight `name` of this setting on its vehicle host.
    fn fly(&self, config: &HostsBenchConfig, name: &str) -> Result<Flight, HostsBenchError> {
        Flight::start(
            &self.hosts,
            &config.aeris,
            &self.workflow,
            name,
            &self.dir.join("run"),
        )
    }
}

fn flight_name(tag: &str) -> String {
    format!("bench-hosts-{tag}-{}", std::process::id())
}

/// Fly one row of the comparison.
fn link_row(
    config: &HostsBenchConfig,
    there: &[&str],
    delay_ms: u32,
    loss_percent: f64,
) -> Result<LinkRow, HostsBenchError> {
    let mut row = LinkRow {
        roles_there: there.iter().map(|s| s.to_string()).collect(),
        delay_ms,
        loss_percent,
        skipped: None,
        reached_goal: None,
        cycles: None,
        ct_mean_s: None,
        ct_p95_s: None,
        eer: None,
        controller_missed_ticks: None,
        frames_across: None,
        bytes_per_frame: None,
        frames_per_s: None,
        link_rtt_ms: None,
        link_loss: None,
        frame_coding_ms: None,
    };
    let tag = format!(
        "{}-{delay_ms}ms-{}loss",
        if there.is_empty() { "local" } else { "there" },
        loss_percent
    );
    let s = setting(config, &tag, there, false, LinkKind::Tls)?;
    if delay_ms > 0 || loss_percent > 0.0 {
        match s.hosts.set_netem(delay_ms, loss_percent) {
            Ok(()) => {}
            Err(e @ NetnsError::NoNetem(_)) => {
                row.skipped = Some(e.to_string());
                return Ok(row);
            }
            Err(e) => return Err(e.into()),
        }
    }
    let name = flight_name(&tag);
    let flight = s.fly(config, &name)?;
    let (summary, run_dir) = flight.finish()?;
    row.reached_goal = summary["reached_goal"].as_bool();
    row.cycles = summary["cycles"].as_u64();
    row.ct_mean_s = summary["ct_mean_s"].as_f64();
    row.ct_p95_s = summary["ct_p95_s"].as_f64();
    row.eer = summary["eer"].as_f64();
    row.controller_missed_ticks = summary["controller_missed_ticks"].as_u64();
    let link = &summary["links"][0];
    row.link_rtt_ms = link["rtt_ms"].as_f64();
    row.link_loss = link["loss"].as_f64();
    row.frame_coding_ms = link["frame_coding_ms"].as_f64();
    if let Some((frames, bytes)) = bridge_sent(&run_dir, "bridge-to-ground", "camera/rgb") {
        row.frames_across = Some(frames);
        row.bytes_per_frame = (frames > 0).then(|| bytes as f64 / frames as f64);
        row.frames_per_s = summary["duration_s"]
            .as_f64()
            .filter(|d| *d > 0.0)
            .map(|d| frames as f64 / d);
    }
    Ok(row)
}

/// The reasoner moved to the ground host and back during a flight (the perception role
/// there from the start).
fn moves(config: &HostsBenchConfig) -> Result<MoveFigures, HostsBenchError> {
    let s = setting(config, "moves", &["perception"], false, LinkKind::Tls)?;
    let name = flight_name("moves");
    let mut flight = s.fly(config, &name)?;
    flight.wait_line("step 2/4")?;
    let (there_ready_ms, there_done_ms) =
        migrate(&s.hosts, &config.aeris, &flight, "reasoning", "ground:gs")?;
    let (back_ready_ms, back_done_ms) =
        migrate(&s.hosts, &config.aeris, &flight, "reasoning", "perception")?;
    let (summary, _) = flight.finish()?;
    Ok(MoveFigures {
        there_ready_ms,
        there_done_ms,
        back_ready_ms,
        back_done_ms,
        decisions_reused: u(&summary, "decisions_reused"),
        controller_missed_ticks: u(&summary, "controller_missed_ticks"),
        reached_goal: summary["reached_goal"] == true,
    })
}

/// The link cut under the reasoner on the ground host, then restored.
fn cut(config: &HostsBenchConfig) -> Result<CutFigures, HostsBenchError> {
    cut_on(config, LinkKind::Tls).map(|(figures, _)| figures)
}

/// [`cut`] on a link of `kind`; also when the link was back after the restore (ms: the
/// supervisor heard the ground host's bridge again, its handshake included).
fn cut_on(config: &HostsBenchConfig, kind: LinkKind) -> Result<(CutFigures, u64), HostsBenchError> {
    let tag = match kind {
        LinkKind::Tls => "cut".to_string(),
        LinkKind::Tcp => "cut-tcp".to_string(),
    };
    let s = setting(config, &tag, &["reasoning"], true, kind)?;
    let name = flight_name(&tag);
    let mut flight = s.fly(config, &name)?;
    flight.wait_line("step 2/4")?;
    let cut_at = Instant::now();
    s.hosts.set_link(false)?;
    let lost = flight.wait_line_after("link to host `ground` lost", Some(cut_at))?;
    let ready = flight.wait_line_after(
        "on the flight's host (executor perception) was ready after",
        Some(cut_at),
    )?;
    let restored_at = Instant::now();
    s.hosts.set_link(true)?;
    let link_back = flight.wait_line_after("link to host `ground` back", Some(restored_at))?;
    let back = flight.wait_line_after(
        "move of `planner` to host `ground` (executor gs) done",
        Some(restored_at),
    )?;
    let (summary, _) = flight.finish()?;
    let ms = |from: Instant, to: Instant| to.saturating_duration_since(from).as_millis() as u64;
    Ok((
        CutFigures {
            loss_noticed_ms: ms(cut_at, lost),
            fallback_ready_ms: ms(cut_at, ready),
            returned_ms: ms(restored_at, back),
            decisions_reused: u(&summary, "decisions_reused"),
            controller_missed_ticks: u(&summary, "controller_missed_ticks"),
            reached_goal: summary["reached_goal"] == true,
        },
        ms(restored_at, link_back),
    ))
}

/// Run every flight of the benchmark; `progress` hears what starts.
pub fn run(
    config: &HostsBenchConfig,
    progress: &mut dyn FnMut(&str),
) -> Result<HostsReport, HostsBenchError> {
    let _load = crate::flights::BusyProcesses::start(None, config.outside_load)?;
    let there = ["reasoning", "perception"];
    let mut plan: Vec<(Vec<&str>, u32, f64)> = vec![(Vec::new(), 0, 0.0)];
    for d in &config.delays_ms {
        plan.push((there.to_vec(), *d, 0.0));
    }
    if config.loss_percent > 0.0 {
        plan.push((there.to_vec(), 0, config.loss_percent));
    }
    let total = plan.len() + 3;
    let mut rows = Vec::new();
    for (k, (roles, delay, loss)) in plan.iter().enumerate() {
        progress(&format!(
            "[{}/{total}] {}, link delay {delay} ms, loss {loss}%",
            k + 1,
            if roles.is_empty() {
                "every role on board".to_string()
            } else {
                format!("{} on the ground host", roles.join(" and "))
            }
        ));
        let row = link_row(config, roles, *delay, *loss)?;
        if let Some(why) = &row.skipped {
            progress(&format!("  skipped: {why}"));
        }
        rows.push(row);
    }
    progress(&format!(
        "[{}/{total}] the reasoner moved to the ground host and back",
        total - 2
    ));
    let moves = moves(config)?;
    progress(&format!(
        "[{}/{total}] the link cut under the reasoner, then restored",
        total - 1
    ));
    let cut = cut(config)?;
    progress(&format!(
        "[{total}/{total}] placement: a hog lands on the vehicle's CPUs under the detector"
    ));
    let placement = placement(config)?;
    if let Some(why) = &placement.skipped {
        progress(&format!("  skipped: {why}"));
    }
    Ok(HostsReport {
        outside_load: config.outside_load,
        rows,
        moves,
        cut,
        placement,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workflow_puts_the_named_roles_on_the_ground_host() {
        let text = ground_workflow(
            "[hosts.ground]\nendpoint = \"tls/10.1.2.2:7447\"\nkeys = \"keys/vehicle\"\n",
            &["reasoning"],
            true,
        );
        let w = aeris_orchestrator::workflow::Workflow::from_toml_str(&text).unwrap();
        let host = |name: &str| {
            let r = w.role(name).unwrap();
            w.role_host(r).map(|h| h.name.clone())
        };
        assert_eq!(host("reasoning").as_deref(), Some("ground"));
        assert_eq!(host("perception"), None);
        let fb = w.role("reasoning").unwrap().fallback.clone().unwrap();
        assert_eq!(fb.variant, "planner");
    }
}
