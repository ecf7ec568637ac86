//! Two hosts on one machine for the multi-host tests: two network namespaces joined by a
//! veth pair, every process started in one of them with a private `/dev/shm` and iceoryx2
//! root (`ip netns exec` gives it a mount namespace of its own), so nothing but the network
//! crosses between them. Needs root (CAP_NET_ADMIN and CAP_SYS_ADMIN).

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

/// Two network namespaces, `vehicle` (the flight's host, 10.X.Y.1) and `ground` (10.X.Y.2),
/// removed on drop.
pub struct TwoHosts {
    /// The flight's host namespace.
    pub vehicle: String,
    /// The other host's namespace.
    pub ground: String,
    /// The ground host's address on the link.
    pub ground_ip: String,
    /// The vehicle's end of the link (in `vehicle`).
    pub vehicle_if: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("cannot run `ip`: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "`ip {}` failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

impl TwoHosts {
    /// Create the namespaces and the link between them; panics with what failed (these
    /// tests need root).
    pub fn new() -> Self {
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
        };
        let ground_if = format!("ag{tag}");
        let setup = || -> Result<(), String> {
            ip(&["netns", "add", &hosts.vehicle])?;
            ip(&["netns", "add", &hosts.ground])?;
            ip(&[
                "link",
                "add",
                &hosts.vehicle_if,
                "type",
                "veth",
                "peer",
                "name",
                &ground_if,
            ])?;
            ip(&["link", "set", &hosts.vehicle_if, "netns", &hosts.vehicle])?;
            ip(&["link", "set", &ground_if, "netns", &hosts.ground])?;
            for (ns, dev, addr) in [
                (&hosts.vehicle, &hosts.vehicle_if, format!("{subnet}.1/24")),
                (&hosts.ground, &ground_if, format!("{subnet}.2/24")),
            ] {
                ip(&["-n", ns, "addr", "add", &addr, "dev", dev])?;
                ip(&["-n", ns, "link", "set", dev, "up"])?;
                ip(&["-n", ns, "link", "set", "lo", "up"])?;
            }
            Ok(())
        };
        if let Err(e) = setup() {
            panic!("cannot create two hosts as network namespaces (run the tests as root): {e}");
        }
        hosts
    }

    /// The ground host's agent endpoint.
    pub fn ground_endpoint(&self) -> String {
        format!("tcp/{}:7447", self.ground_ip)
    }

    /// `program args..` to run in namespace `ns` with a private `/dev/shm` and iceoryx2
    /// root.
    pub fn command(&self, ns: &str, program: &std::path::Path) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", ns, "sh", "-c"])
            .arg(
                "mount -t tmpfs tmpfs /dev/shm && mkdir -p /tmp/iceoryx2 && \
                 mount -t tmpfs tmpfs /tmp/iceoryx2 && exec \"$@\"",
            )
            .arg("sh")
            .arg(program);
        cmd
    }

    /// `program args..` beside process `pid` (started by [`TwoHosts::command`]): in its
    /// network and mount namespaces, so it sees that process's `/dev/shm` (a tool such as
    /// `aeris migrate` joining its flight).
    pub fn command_beside(&self, pid: u32, program: &std::path::Path) -> Command {
        let mut cmd = Command::new("nsenter");
        cmd.args(["-t", &pid.to_string(), "-m", "-n", "--"])
            .arg(program);
        cmd
    }

    /// Cut (`false`) or restore (`true`) the link, on the vehicle's side.
    pub fn set_link(&self, up: bool) {
        let state = if up { "up" } else { "down" };
        ip(&["-n", &self.vehicle, "link", "set", &self.vehicle_if, state])
            .unwrap_or_else(|e| panic!("{e}"));
    }
}

impl Default for TwoHosts {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for TwoHosts {
    fn drop(&mut self) {
        // deleting a namespace removes its end of the veth pair, and so the pair
        let _ = ip(&["netns", "del", &self.vehicle]);
        let _ = ip(&["netns", "del", &self.ground]);
    }
}
