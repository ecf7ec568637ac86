//! Other hosts of a workflow: checking `[hosts.NAME]` and the executors on them, and which
//! topics the bridges carry between the flight's host and each other host.

use super::{ExecutorCpus, FLIGHT_HOST_KINDS, Host, Workflow, WorkflowError, check_endpoint};
use aeris_schemas::{MAX_HOSTS, RoleKind, topics};

/// Topics the supervisor itself reads on the flight's host (its own subscriptions, beside
/// the roles'): every role's heartbeat, the hub's reports, telemetry, the autopilot link.
pub const SUPERVISOR_READS: [&str; 4] = [
    topics::HEARTBEAT,
    topics::HUB_REPORT,
    topics::VEHICLE_TELEMETRY,
    topics::CONTROLLER_LINK,
];

/// The parameters a role on another host may be given by the workflow: values that name no
/// file, directory, model, pipeline, device or endpoint. What names one is that host's own
/// configuration (its agent's `--param`), never sent over the network: the agent refuses a
/// request with any other parameter.
pub const REMOTE_PARAMS: &[&str] = &[
    // reasoning
    "seed",
    "threads",
    "context_tokens",
    "plan",
    "prompt",
    // perception models
    "min_score",
    "interval_ms",
    "join_ms",
    // the bridge there (its `connect` and `keys` are its agent's)
    "export",
    "import",
    "peer",
    "frame_bytes",
    "link_timeout_ms",
    "frames",
    "jpeg_quality",
    "probe",
    "on_host",
];

/// What the bridges between the flight's host and one other host carry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BridgePlan {
    /// The other host.
    pub host: Host,
    /// Topics published on the flight's host and read on the other (in [`topics::ALL`]
    /// order).
    pub to_host: Vec<String>,
    /// Topics published on the other host and read on the flight's.
    pub from_host: Vec<String>,
}

impl Workflow {
    /// Check `[hosts]` and the executors on them: names, endpoints, every executor's host
    /// declared (at most [`MAX_HOSTS`] hosts), no hub, controller, vehicle, replay source or recorder on another host, no
    /// topic between two other hosts.
    pub(super) fn validate_hosts(&self) -> Result<(), WorkflowError> {
        if self.hosts.len() > MAX_HOSTS {
            return Err(WorkflowError::TooManyHosts {
                count: self.hosts.len(),
                max: MAX_HOSTS,
            });
        }
        for h in &self.hosts {
            if !topics::is_valid_flight_name(&h.name) {
                return Err(WorkflowError::BadHostName {
                    host: h.name.clone(),
                });
            }
            if !check_endpoint(&h.endpoint) {
                return Err(WorkflowError::BadEndpoint {
                    host: h.name.clone(),
                    endpoint: h.endpoint.clone(),
                });
            }
            let tls = h.endpoint.starts_with("tls/");
            let reason = match (tls, h.keys.is_some(), h.insecure) {
                (true, true, false) | (false, false, true) => None,
                (true, false, false) => Some(
                    "a TLS link needs `keys`, the flight host's identity directory (`aeris keys init STORE`, `aeris keys issue STORE HOST`)",
                ),
                (true, _, true) => {
                    Some("`insecure = true` is for a plain tcp/ link: remove it, the link is TLS")
                }
                (false, _, false) => Some(
                    "a tcp/ link is unauthenticated and unencrypted: use tls/ with `keys`, or say `insecure = true`",
                ),
                (false, true, true) => {
                    Some("`keys` are for a tls/ link: use a tls/ endpoint, or remove `keys`")
                }
            };
            if let Some(reason) = reason {
                return Err(WorkflowError::LinkSecurity {
                    host: h.name.clone(),
                    endpoint: h.endpoint.clone(),
                    reason,
                });
            }
            if !matches!(h.frames.as_str(), "jpeg" | "raw") || !(1..=100).contains(&h.jpeg_quality)
            {
                return Err(WorkflowError::BadFrames {
                    host: h.name.clone(),
                    frames: h.frames.clone(),
                    quality: h.jpeg_quality,
                });
            }
        }
        for ex in &self.executors {
            let Some(host) = &ex.host else { continue };
            if !self.hosts.iter().any(|h| &h.name == host) {
                let known = if self.hosts.is_empty() {
                    "none".to_string()
                } else {
                    let names: Vec<&str> = self.hosts.iter().map(|h| h.name.as_str()).collect();
                    names.join(", ")
                };
                return Err(WorkflowError::UnknownHost {
                    executor: ex.name.clone(),
                    host: host.clone(),
                    known,
                });
            }
        }
        for r in &self.roles {
            let Some(h) = self.role_host(r) else { continue };
            if FLIGHT_HOST_KINDS.contains(&r.kind) {
                return Err(WorkflowError::RemoteNotAllowed {
                    role: r.name.clone(),
                    kind: r.kind,
                    host: h.name.clone(),
                });
            }
            if let Some(key) = r
                .params
                .keys()
                .find(|k| !REMOTE_PARAMS.contains(&k.as_str()))
            {
                return Err(WorkflowError::RemoteParam {
                    role: r.name.clone(),
                    param: key.clone(),
                    host: h.name.clone(),
                });
            }
        }
        for r in &self.roles {
            let Some(fb) = &r.fallback else { continue };
            let bad = |reason: String| WorkflowError::BadFallback {
                role: r.name.clone(),
                reason,
            };
            if self.role_host(r).is_none() {
                return Err(bad(
                    "is only for a role on another host (its executor's `host`)".into(),
                ));
            }
            if !r.kind.info().variants.contains(&fb.variant.as_str()) {
                return Err(bad(format!(
                    "`{}` is not a variant of kind {}",
                    fb.variant, r.kind
                )));
            }
            if let Some(ex) = &fb.executor {
                match self.executor(ex) {
                    None => return Err(bad(format!("executor `{ex}` is not declared"))),
                    Some(e) if e.host.is_some() => {
                        return Err(bad(format!(
                            "executor `{ex}` is on another host: a fallback runs on the flight's host"
                        )));
                    }
                    Some(_) => {}
                }
            }
        }
        for topic in topics::ALL {
            for p in self
                .roles
                .iter()
                .filter(|r| r.publishes.iter().any(|t| t == topic))
            {
                for s in self
                    .roles
                    .iter()
                    .filter(|r| r.subscribes.iter().any(|t| t == topic))
                {
                    if let (Some(from), Some(to)) = (self.role_host(p), self.role_host(s))
                        && from.name != to.name
                    {
                        return Err(WorkflowError::HostToHost {
                            topic: topic.to_string(),
                            from: from.name.clone(),
                            to: to.name.clone(),
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// The bridges this flight needs: one pair per declared host, carrying the topics that
    /// cross between the flight's host and it for the roles that run there **or may be
    /// moved there** during the flight ([`movable_across_hosts`]): a move needs no new
    /// bridge. Every role publishes its heartbeat, which the supervisor reads on the
    /// flight's host. (Frames cross only while read there: the bridge follows its readers.)
    pub fn bridge_plans(&self) -> Vec<BridgePlan> {
        let mut plans = Vec::new();
        for host in &self.hosts {
            let placed_there = |r: &super::RoleDecl| {
                self.role_host(r).map(|h| h.name.as_str()) == Some(host.name.as_str())
            };
            let may_be_there = |r: &&super::RoleDecl| {
                r.kind != RoleKind::Bridge && (placed_there(r) || movable_across_hosts(r.kind))
            };
            let may_be_here = |r: &&super::RoleDecl| {
                r.kind != RoleKind::Bridge
                    && (self.role_host(r).is_none() || movable_across_hosts(r.kind))
            };
            let publishes = |r: &super::RoleDecl, t: &str| {
                t == topics::HEARTBEAT || r.publishes.iter().any(|p| p == t)
            };
            // (a recorder on the flight's host reads what crosses too)
            let reads = |r: &super::RoleDecl, t: &str| {
                r.subscribes.iter().any(|s| s == t) || r.kind.info().reads_latest.contains(&t)
            };
            let mut to_host = Vec::new();
            let mut from_host = Vec::new();
            for t in topics::ALL {
                let published_here = self
                    .roles
                    .iter()
                    .filter(may_be_here)
                    .any(|r| publishes(r, t));
                let read_there = self.roles.iter().filter(may_be_there).any(|r| reads(r, t));
                if published_here && read_there {
                    to_host.push(t.to_string());
                }
                let published_there = self
                    .roles
                    .iter()
                    .filter(may_be_there)
                    .any(|r| publishes(r, t));
                let read_here = SUPERVISOR_READS.contains(&t)
                    || self.roles.iter().filter(may_be_here).any(|r| reads(r, t));
                if published_there && read_here {
                    from_host.push(t.to_string());
                }
            }
            plans.push(BridgePlan {
                host: host.clone(),
                to_host,
                from_host,
            });
        }
        plans
    }
}

/// Whether a role of `kind` may run on another host than the flight's and be moved there
/// and back during the flight: a kind the hub, the controller and the autopilot link do
/// not depend on being local (not [`FLIGHT_HOST_KINDS`]) and that may run twice for a
/// moment (make-before-break: its kind allows a hot swap).
pub fn movable_across_hosts(kind: RoleKind) -> bool {
    !FLIGHT_HOST_KINDS.contains(&kind) && kind.info().swap_refusal.is_none()
}

/// The CPUs of an executor on another host as its agent is asked for them ("" = wherever
/// the agent runs roles: `all` and `auto` there).
pub fn remote_cpus(cpus: &ExecutorCpus) -> String {
    match cpus {
        ExecutorCpus::Set(s) => s.to_string(),
        ExecutorCpus::All | ExecutorCpus::Auto => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use crate::workflow::{DEFAULT_WORKFLOW_TOML, Workflow, WorkflowError};
    use aeris_schemas::RoleKind;

    /// The default flight with the reasoner (and, with `perception`, the perception role)
    /// on host `ground`.
    fn ground(perception: bool) -> String {
        let mut toml = DEFAULT_WORKFLOW_TOML.replace(
            "[executors.perception]",
            "[hosts.ground]\nendpoint = \"tls/10.0.0.2:7447\"\nkeys = \"keys/vehicle\"\n\n[executors.gs]\nhost = \"ground\"\ncpus = \"all\"\n\n[executors.perception]",
        );
        toml = toml.replacen(
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"perception\"",
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
            1,
        );
        if perception {
            toml = toml.replacen(
                "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"perception\"",
                "kind = \"perception\"\nvariant = \"geometric\"\nexecutor = \"gs\"",
                1,
            );
        }
        toml
    }

    #[test]
    fn the_bridges_carry_exactly_the_topics_that_cross() {
        let w = Workflow::from_toml_str(&ground(false)).unwrap();
        let reasoner = w
            .roles
            .iter()
            .find(|r| r.kind == RoleKind::Reasoning)
            .unwrap();
        assert_eq!(w.role_host(reasoner).unwrap().name, "ground");
        let plans = w.bridge_plans();
        assert_eq!(plans.len(), 1);
        let p = &plans[0];
        assert_eq!(p.host.endpoint, "tls/10.0.0.2:7447");
        // the reasoner's inputs; the perception role may be moved there too, so its
        // frames are planned (they cross only while read there)
        assert_eq!(
            p.to_host,
            [
                "camera/rgb",
                "camera/depth",
                "perception/state",
                "hub/setpoint",
                "vehicle/telemetry"
            ]
        );
        assert_eq!(
            p.from_host,
            ["perception/state", "reasoning/decision", "heartbeat"]
        );
        // the same with the perception role there from the start
        let w2 = Workflow::from_toml_str(&ground(true)).unwrap();
        assert_eq!(w2.bridge_plans(), plans);
        // a host with no role on it at the start still gets its bridges: roles may be
        // moved there; the hub, the controller and the vehicle never
        let toml = ground(false).replacen(
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"perception\"",
            1,
        );
        let w3 = Workflow::from_toml_str(&toml).unwrap();
        assert!(w3.roles.iter().all(|r| w3.role_host(r).is_none()));
        assert_eq!(w3.bridge_plans(), plans);
        assert!(!p.from_host.contains(&"hub/setpoint".to_string()));
        assert!(super::movable_across_hosts(RoleKind::Reasoning));
        assert!(!super::movable_across_hosts(RoleKind::Hub));
        assert!(!super::movable_across_hosts(RoleKind::Camera));
    }

    #[test]
    fn hosts_and_their_executors_are_checked() {
        let text = ground(false);
        let bad = text.replace("tls/10.0.0.2:7447", "udp/10.0.0.2");
        let e = Workflow::from_toml_str(&bad).unwrap_err();
        assert!(matches!(e, WorkflowError::BadEndpoint { .. }), "{e}");
        // a link is TLS with keys, or plain TCP only when declared insecure
        for (from, to, why) in [
            ("keys = \"keys/vehicle\"\n", "", "a TLS link needs `keys`"),
            (
                "tls/",
                "tcp/",
                "a tcp/ link is unauthenticated and unencrypted",
            ),
            (
                "keys = \"keys/vehicle\"\n",
                "keys = \"k\"\ninsecure = true\n",
                "`insecure = true` is for a plain tcp/ link",
            ),
        ] {
            let e = Workflow::from_toml_str(&text.replacen(from, to, 1))
                .unwrap_err()
                .to_string();
            assert!(e.contains(why), "{e}");
        }
        let plain = text.replacen("tls/", "tcp/", 1).replacen(
            "keys = \"keys/vehicle\"\n",
            "insecure = true\n",
            1,
        );
        let w = Workflow::from_toml_str(&plain).unwrap();
        assert!(w.hosts[0].insecure && w.hosts[0].keys.is_none());
        // a role there takes no parameter that names a file: that host's agent sets it
        let bad = text.replacen(
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
            "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"\nparams = { model = \"/x.gguf\" }",
            1,
        );
        let e = Workflow::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("role `reasoning` runs on host `ground`: its param `model` is that host's own configuration"),
            "{e}"
        );
        let w = Workflow::from_toml_str(&text).unwrap();
        assert_eq!(
            (w.hosts[0].frames.as_str(), w.hosts[0].jpeg_quality),
            ("jpeg", 85)
        );
        let bad = text.replace(
            "endpoint = \"tls/10.0.0.2:7447\"",
            "endpoint = \"tls/10.0.0.2:7447\"\nframes = \"h264\"",
        );
        let e = Workflow::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("[hosts.ground] frames = `h264`, jpeg_quality = 85: use `jpeg`"),
            "{e}"
        );
        let bad = text.replace("host = \"ground\"", "host = \"air\"");
        let e = Workflow::from_toml_str(&bad).unwrap_err().to_string();
        assert!(
            e.contains("host `air` is not declared (declared: ground)"),
            "{e}"
        );
        let bad = text.replacen(
            "kind = \"hub\"\nvariant = \"gate\"\nexecutor = \"control\"",
            "kind = \"hub\"\nvariant = \"gate\"\nexecutor = \"gs\"",
            1,
        );
        let e = Workflow::from_toml_str(&bad).unwrap_err().to_string();
        assert!(e.contains("must run on the flight's host"), "{e}");
        // a fallback: a variant of the kind, on one of the flight's executors
        let with = |fallback: &str| {
            text.replacen(
                "variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"",
                &format!("variants = [\"planner\", \"garbage\"]\nexecutor = \"gs\"\n{fallback}"),
                1,
            )
        };
        let w = Workflow::from_toml_str(&with(
            "fallback = \"planner\"\nfallback_executor = \"perception\"",
        ))
        .unwrap();
        let fb = w.role("reasoning").unwrap().fallback.clone().unwrap();
        assert_eq!(
            (fb.variant.as_str(), fb.executor.as_deref()),
            ("planner", Some("perception"))
        );
        let e = Workflow::from_toml_str(&with("fallback = \"gpt-9\""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`gpt-9` is not a variant of kind reasoning"),
            "{e}"
        );
        let e =
            Workflow::from_toml_str(&with("fallback = \"planner\"\nfallback_executor = \"gs\""))
                .unwrap_err()
                .to_string();
        assert!(e.contains("a fallback runs on the flight's host"), "{e}");
    }
}
