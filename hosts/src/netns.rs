//! Two hosts on one machine, for the multi-host tests and `aeris bench hosts`: two network
//! namespaces joined by a veth pair, every process started in one of them with a private
//! `/dev/shm` and iceoryx2 root (`ip netns exec` gives it a mount namespace of its own), so
//! nothing but the network crosses between them. The ground host's processes also run in
//! a time namespace whose CLOCK_MONOTONIC is [`GROUND_CLOCK_AHEAD_S`] ahead, as two
//! machines' clocks differ (each counts from its own boot): what one host stamps must be
//! read on the other through the offset their link measured. Needs root (CAP_NET_ADMIN and
//! CAP_SYS_ADMIN), `ip` (iproute2), `unshare`, `nsenter` and `taskset` (util-linux); `tc`
//! for netem.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// How far the ground host's CLOCK_MONOTONIC runs ahead of the vehicle's (s).
pub const GROUND_CLOCK_AHEAD_S: u64 = 3600;

/// Why the two hosts could not be set up or changed.
#[derive(Debug, thiserror::Error)]
pub enum NetnsError {
    /// A tool could not be started.
    #[error("cannot run `{tool}`")]
    Spawn {
        /// The tool.
        tool: &'static str,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A command failed (not root, a name taken, a kernel feature missing).
    #[error("`{command}` failed: {stderr}")]
    Failed {
        /// The command line.
        command: String,
        /// What it printed.
        stderr: String,
    },
    /// The kernel has no netem queueing discipline (`sch_netem`): no delay or loss.
    #[error("this kernel has no netem (sch_netem), so no link delay or loss (tc: {0})")]
    NoNetem(String),
}

/// How the two hosts' link is secured.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HostLink {
    /// Mutual TLS with these keys ([`TwoHosts::make_keys`]).
    Tls(HostKeys),
    /// Plain TCP (`--insecure`, `insecure = true`).
    Insecure,
}

/// The keys of [`TwoHosts::make_keys`]: a key store with the identities `vehicle` and
/// `ground`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HostKeys {
    /// The key store.
    pub store: PathBuf,
}

impl HostKeys {
    /// The vehicle's identity directory (the flight's host).
    pub fn vehicle(&self) -> PathBuf {
        self.store.join("vehicle")
    }

    /// The ground host's identity directory.
    pub fn ground(&self) -> PathBuf {
        self.store.join("ground")
    }
}

/// Two network namespaces, `vehicle` (the flight's host, 10.X.Y.1) and `ground` (10.X.Y.2),
/// removed on drop.
#[derive(Debug)]
pub struct TwoHosts {
    /// The flight's host namespace.
    pub vehicle: String,
    /// The other host's namespace.
    pub ground: String,
    /// The ground host's address on the link.
    pub ground_ip: String,
    /// The vehicle's end of the link (in `vehicle`).
    pub vehicle_if: String,
    /// The ground's end of the link (in `ground`).
    pub ground_if: String,
    /// The CPUs of each host's processes (vehicle, ground), when the machine is split
    /// between them ([`TwoHosts::split_cpus`]); `None`: every CPU for both.
    pub cpus: Option<(String, String)>,
}

fn run(tool: &'static str, args: &[&str]) -> Result<(), NetnsError> {
    let out = Command::new(tool)
        .args(args)
        .output()
        .map_err(|source| NetnsError::Spawn { tool, source })?;
    if out.status.success() {
        Ok(())
    } else {
        Err(NetnsError::Failed {
            command: format!("{tool} {}", args.join(" ")),
            stderr: String::from_utf8_lossy(&out.stderr).trim().to_string(),
        })
    }
}

impl TwoHosts {
    /// Create the namespaces and the link between them (names and subnet unique to this
    /// process and call); what exists already is removed again on failure.
    pub fn new() -> Result<Self, NetnsError> {
        static NEXT: AtomicU32 = AtomicU32::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let pid = std::process::id();
        let tag = format!("{pid}{n}");
        let subnet = format!("10.{}.{}", 100 + (pid % 100), (pid / 100 % 200) + n);
        let hosts = TwoHosts {
            vehicle: format!("aeris-v{tag}"),
            ground: format!("aeris-g{tag}"),
            ground_ip: format!("{subnet}.2"),
            vehicle_if: format!("av{tag}"),
            ground_if: format!("ag{tag}"),
            cpus: None,
        };
        run("ip", &["netns", "add", &hosts.vehicle])?;
        // from here on, drop removes what was made
        run("ip", &["netns", "add", &hosts.ground])?;
        run(
            "ip",
            &[
                "link",
                "add",
                &hosts.vehicle_if,
                "type",
                "veth",
                "peer",
                "name",
                &hosts.ground_if,
            ],
        )?;
        run(
            "ip",
            &["link", "set", &hosts.vehicle_if, "netns", &hosts.vehicle],
        )?;
        run(
            "ip",
            &["link", "set", &hosts.ground_if, "netns", &hosts.ground],
        )?;
        for (ns, dev, addr) in [
            (&hosts.vehicle, &hosts.vehicle_if, format!("{subnet}.1/24")),
            (&hosts.ground, &hosts.ground_if, format!("{subnet}.2/24")),
        ] {
            run("ip", &["-n", ns, "addr", "add", &addr, "dev", dev])?;
            run("ip", &["-n", ns, "link", "set", dev, "up"])?;
            run("ip", &["-n", ns, "link", "set", "lo", "up"])?;
        }
        Ok(hosts)
    }

    /// Split this machine's CPUs between the two hosts, as two machines have their own:
    /// the vehicle's processes run on the CPUs of `vehicle` only, the ground's on those of
    /// `ground` (CPU lists, `taskset` syntax).
    pub fn split_cpus(&mut self, vehicle: &str, ground: &str) {
        self.cpus = Some((vehicle.to_string(), ground.to_string()));
    }

    /// The ground host's agent endpoint on `link`.
    pub fn ground_endpoint(&self, link: &HostLink) -> String {
        let scheme = match link {
            HostLink::Tls(_) => "tls",
            HostLink::Insecure => "tcp",
        };
        format!("{scheme}/{}:7447", self.ground_ip)
    }

    /// The flight's keys for these two hosts in `dir`: a CA, the vehicle's identity (the
    /// flight's host) and the ground host's, valid for its address on the link.
    pub fn make_keys(&self, dir: &Path) -> Result<HostLink, crate::keys::KeysError> {
        let store = dir.join("keys");
        crate::keys::init(&store, 1)?;
        crate::keys::issue(&store, "vehicle", &[], 1, false)?;
        crate::keys::issue(
            &store,
            "ground",
            std::slice::from_ref(&self.ground_ip),
            1,
            false,
        )?;
        Ok(HostLink::Tls(HostKeys { store }))
    }

    /// `aeris agent` for the ground host on `link` (its output not redirected yet), role
    /// specs and logs in `run_dir`.
    pub fn agent_command(&self, aeris: &Path, link: &HostLink, run_dir: &Path) -> Command {
        let mut cmd = self.command(&self.ground, aeris);
        cmd.args(["agent", "--host", "ground", "--listen"])
            .arg(self.ground_endpoint(link))
            .arg("--run-dir")
            .arg(run_dir);
        match link {
            HostLink::Tls(keys) => {
                cmd.arg("--keys")
                    .arg(keys.ground())
                    .args(["--flight-host", "vehicle"]);
            }
            HostLink::Insecure => {
                cmd.arg("--insecure");
            }
        }
        cmd
    }

    /// The workflow table `[hosts.ground]` on `link`: its endpoint, and the vehicle's keys
    /// or `insecure = true`.
    pub fn ground_host_toml(&self, link: &HostLink) -> String {
        let endpoint = self.ground_endpoint(link);
        match link {
            HostLink::Tls(keys) => format!(
                "[hosts.ground]\nendpoint = \"{endpoint}\"\nkeys = \"{}\"\n",
                keys.vehicle().display()
            ),
            HostLink::Insecure => {
                format!("[hosts.ground]\nendpoint = \"{endpoint}\"\ninsecure = true\n")
            }
        }
    }

    /// `program args..` to run in namespace `ns` with a private `/dev/shm` and iceoryx2
    /// root; on the ground host with its clock [`GROUND_CLOCK_AHEAD_S`] ahead.
    pub fn command(&self, ns: &str, program: &Path) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", ns]);
        if ns == self.ground {
            let ahead = format!("--monotonic={GROUND_CLOCK_AHEAD_S}");
            // the child ends with `unshare` (killed or stopped, it stops its program too)
            cmd.args([
                "unshare",
                "--time",
                &ahead,
                "--fork",
                "--kill-child=SIGTERM",
            ]);
        }
        cmd.args(["sh", "-c"])
            .arg(
                "mount -t tmpfs tmpfs /dev/shm && mkdir -p /tmp/iceoryx2 && \
                 mount -t tmpfs tmpfs /tmp/iceoryx2 && exec \"$@\"",
            )
            .arg("sh");
        if let Some((vehicle, ground)) = &self.cpus {
            let cpus = if ns == self.ground { ground } else { vehicle };
            cmd.args(["taskset", "-c", cpus]);
        }
        cmd.arg(program);
        cmd
    }

    /// `program args..` beside process `pid` (started by [`TwoHosts::command`]): in its
    /// network and mount namespaces, so it sees that process's `/dev/shm` (a tool such as
    /// `aeris migrate` joining its flight).
    pub fn command_beside(&self, pid: u32, program: &Path) -> Command {
        let mut cmd = Command::new("nsenter");
        cmd.args(["-t", &pid.to_string(), "-m", "-n", "--"])
            .arg(program);
        cmd
    }

    /// Cut (`false`) or restore (`true`) the link, on the vehicle's side.
    pub fn set_link(&self, up: bool) -> Result<(), NetnsError> {
        let state = if up { "up" } else { "down" };
        run(
            "ip",
            &["-n", &self.vehicle, "link", "set", &self.vehicle_if, state],
        )
    }

    /// Delay every packet by `delay_ms` and lose `loss_percent` of them, each way (tc
    /// netem on both ends of the link).
    pub fn set_netem(&self, delay_ms: u32, loss_percent: f64) -> Result<(), NetnsError> {
        let delay = format!("{delay_ms}ms");
        let loss = format!("{loss_percent}%");
        for (ns, dev) in [
            (&self.vehicle, &self.vehicle_if),
            (&self.ground, &self.ground_if),
        ] {
            let args = [
                "-n", ns, "qdisc", "replace", "dev", dev, "root", "netem", "delay", &delay, "loss",
                &loss,
            ];
            match run("tc", &args) {
                Err(NetnsError::Failed { stderr, .. })
                    if stderr.contains("Specified qdisc") || stderr.contains("netem") =>
                {
                    let said = stderr.trim_start_matches("Error: ").to_string();
                    return Err(NetnsError::NoNetem(said));
                }
                other => other?,
            }
        }
        Ok(())
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        // deleting a namespace removes its end of the veth pair, and so the pair
        let _ = run("ip", &["netns", "del", &self.vehicle]);
        let _ = run("ip", &["netns", "del", &self.ground]);
    }
}
