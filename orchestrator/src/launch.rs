//! Launch planning: from a validated workflow to one [`RoleSpec`] per role, in start order.
//!
//! Pure apart from the free-port callback, so the supervisor's decisions (CPU binding of
//! `auto` executors, the built-in vehicle link, an external autopilot) are testable without
//! starting processes.

use crate::restart::RestartPolicy;
use crate::workflow::{Executor, ExecutorCpus, RoleDecl, Workflow, WorkflowError, remote_cpus};
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::spec::{MissionSpec, RemoteSpec, RoleSpec};
use aeris_schemas::RoleKind;
use aeris_schemas::topics;

/// One role ready to start.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedRole {
    /// What the role process gets (written as JSON).
    pub spec: RoleSpec,
    /// CPUs to bind the process to (`None` = inherit the supervisor's affinity).
    pub cpus: Option<CpuSet>,
    /// Name of its executor (`None` = unbound).
    pub executor: Option<String>,
    /// Its latency budget (ms), see [`Workflow::role_budget_ms`].
    pub budget_ms: Option<f64>,
    /// Restart policy.
    pub restart: RestartPolicy,
    /// Restart budget.
    pub max_restarts: u32,
    /// First restart backoff (ms).
    pub backoff_ms: u64,
    /// Variants the role may be hot-swapped to (its workflow `variants`).
    pub pool: Vec<String>,
    /// Its variant ladder, most capable first (its workflow `ladder`; empty: none).
    pub ladder: Vec<String>,
    /// On another host: what replaces it on the flight's host when the link is lost.
    pub fallback: Option<PlannedFallback>,
}

/// What replaces a role on another host when the link to it is lost, resolved to the
/// flight's CPUs.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedFallback {
    /// The variant started on the flight's host.
    pub variant: String,
    /// Its executor (`None`: unbound).
    pub executor: Option<String>,
    /// That executor's CPUs (`None`: the supervisor's).
    pub cpus: Option<CpuSet>,
}

/// Every role of a flight, in start order (publishers before subscribers).
#[derive(Debug, Clone, PartialEq)]
pub struct LaunchPlan {
    /// The roles in start order.
    pub roles: Vec<PlannedRole>,
    /// Executor name -> resolved CPU set.
    pub executors: Vec<(String, CpuSet)>,
    /// The executors on other hosts: where a role moved there runs (name, host and CPUs).
    pub remote_executors: Vec<(String, RemoteSpec)>,
    /// The executors that name an accelerator (on any host), with it.
    pub accelerators: Vec<(String, aeris_runtime::accelerator::Accelerator)>,
    /// UDP port of the built-in vehicle link, when the built-in vehicle flies.
    pub vehicle_port: Option<u16>,
}

/// Why a flight cannot be planned.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The flight name is unusable as a service prefix.
    #[error("flight name `{0}` is invalid: use 1-48 characters of a-z, 0-9, `_`, `-`")]
    FlightName(String),
    /// The workflow (after applying the external autopilot) is invalid.
    #[error(transparent)]
    Workflow(#[from] WorkflowError),
    /// `--autopilot URL` names one autopilot for a flight of several vehicles.
    #[error(
        "one autopilot URL for {vehicles} vehicles: give each vehicle's in its controller's per_vehicle_params.autopilot instead"
    )]
    OneAutopilotForSeveral {
        /// The flight's vehicles.
        vehicles: u8,
    },
    /// No free UDP port for the built-in vehicle link.
    #[error("cannot find a free UDP port on 127.0.0.1 for the built-in vehicle link: {0}")]
    VehicleLink(std::io::Error),
}

/// Resolve every executor of the flight's host to a CPU set (another host's executors are
/// its agent's to bind): `all` is `online`; `auto` executors get one CPU
/// each, round-robin over `online` in executor-name order; explicit sets stay as written.
pub fn resolve_executors(workflow: &Workflow, online: &CpuSet) -> Vec<(String, CpuSet)> {
    let mut next_auto = 0usize;
    let cpus = online.cpus();
    workflow
        .executors
        .iter()
        .filter(|ex| ex.host.is_none())
        .map(|ex| {
            let set = match &ex.cpus {
                ExecutorCpus::Set(s) => s.clone(),
                ExecutorCpus::All => online.clone(),
                ExecutorCpus::Auto => {
                    let set = match cpus.get(next_auto % cpus.len().max(1)) {
                        Some(c) => CpuSet::parse(&c.to_string()).unwrap_or_else(|_| online.clone()),
                        None => online.clone(),
                    };
                    next_auto += 1;
                    set
                }
            };
            (ex.name.clone(), set)
        })
        .collect()
}

/// The parameter that puts a bridge role on another host (the host's name).
pub const BRIDGE_HOST_PARAM: &str = "on_host";

/// The bridge roles of `workflow` (kind `bridge`, variant `zenoh`), two per other
/// host ([`Workflow::bridge_plans`]): `bridge-to-HOST` on the flight's host and `bridge-on-HOST` there,
/// each told what it sends (`export`) and what it receives (`import`); the one here also
/// where the host's agent listens and the flight host's keys, while the one there is
/// linked by that host's agent itself (its own endpoint and keys: nothing that names a
/// file or an endpoint crosses the network). They start before every other role.
pub fn bridge_roles(workflow: &Workflow) -> Vec<RoleDecl> {
    let frame_bytes = workflow.camera.width as u64 * workflow.camera.height as u64 * 3;
    let mut roles = Vec::new();
    for plan in workflow.bridge_plans() {
        let h = &plan.host;
        let params = |export: &[String], import: &[String], peer: &str| {
            let mut p = serde_json::Map::new();
            p.insert("export".into(), export.to_vec().into());
            p.insert("import".into(), import.to_vec().into());
            p.insert("peer".into(), peer.into());
            p.insert("frame_bytes".into(), frame_bytes.into());
            p.insert("link_timeout_ms".into(), h.link_timeout_ms.into());
            p.insert("frames".into(), h.frames.clone().into());
            p.insert("jpeg_quality".into(), h.jpeg_quality.into());
            p
        };
        let mut here = params(
            &plan.to_host,
            &plan.from_host,
            &format!("host `{}`", h.name),
        );
        here.insert("connect".into(), h.endpoint.clone().into());
        if let Some(keys) = &h.keys {
            here.insert("keys".into(), keys.clone().into());
        }
        // the bridge on the flight's host measures the link (`hosts/link`)
        here.insert("probe".into(), h.name.clone().into());
        roles.push(RoleDecl::new(
            &format!("bridge-to-{}", h.name),
            RoleKind::Bridge,
            "zenoh",
            None,
            here,
        ));
        let mut there = params(&plan.from_host, &plan.to_host, "the flight's host");
        there.insert(BRIDGE_HOST_PARAM.into(), h.name.clone().into());
        roles.push(RoleDecl::new(
            &format!("bridge-on-{}", h.name),
            RoleKind::Bridge,
            "zenoh",
            None,
            there,
        ));
    }
    roles
}

/// Where a role on `host` runs: its agent's endpoint, the link's timeout, and the CPUs of
/// `executor` there.
fn remote_spec(host: &crate::workflow::Host, executor: Option<&Executor>) -> RemoteSpec {
    RemoteSpec {
        host: host.name.clone(),
        endpoint: host.endpoint.clone(),
        keys: host.keys.clone(),
        cpus: executor.map(|e| remote_cpus(&e.cpus)).unwrap_or_default(),
        link_timeout_ms: host.link_timeout_ms,
    }
}

/// A free UDP port on 127.0.0.1 (bind port 0, read it, release it).
pub fn free_udp_port() -> std::io::Result<u16> {
    let socket = std::net::UdpSocket::bind(("127.0.0.1", 0))?;
    Ok(socket.local_addr()?.port())
}

/// A port from `free_port` that is none of `taken` (a released port may come back).
fn distinct_port(
    free_port: &mut impl FnMut() -> std::io::Result<u16>,
    taken: &[u16],
) -> std::io::Result<u16> {
    let mut last = 0;
    for _ in 0..8 {
        last = free_port()?;
        if !taken.contains(&last) {
            return Ok(last);
        }
    }
    Err(std::io::Error::other(format!(
        "no free UDP port other than {last} for the next vehicle"
    )))
}

/// Plan the flight `flight` of `workflow`.
///
/// With `autopilot = Some(url)` the vehicle roles are dropped and every controller gets
/// `params.autopilot = url`; standby controllers (`params.standby = true`) are dropped too
/// unless the URL is `udpout:` or `tcpout:` (a `udpin:`/`tcpin:` port or a serial device
/// can be opened by one process only). Otherwise, when a controller's autopilot is `auto`, `free_port`
/// picks a UDP port P: vehicles with `listen = "auto"` get `udpin:127.0.0.1:P` and
/// controllers with `autopilot = "auto"` get `udpout:127.0.0.1:P`.
pub fn plan_launch(
    workflow: &Workflow,
    flight: &str,
    autopilot: Option<&str>,
    online: &CpuSet,
    mut free_port: impl FnMut() -> std::io::Result<u16>,
) -> Result<LaunchPlan, PlanError> {
    if !topics::is_valid_flight_name(flight) {
        return Err(PlanError::FlightName(flight.to_string()));
    }
    let mut w = workflow.clone();
    let mut vehicle_port = None;
    match autopilot {
        Some(_) if w.fleet.vehicles > 1 => {
            return Err(PlanError::OneAutopilotForSeveral {
                vehicles: w.fleet.vehicles,
            });
        }
        Some(url) => {
            w.roles.retain(|r| r.kind != RoleKind::Vehicle);
            // a hot standby shares the link only where two processes can each open it
            if !(url.starts_with("udpout:") || url.starts_with("tcpout:")) {
                w.roles.retain(|r| !r.is_standby_controller());
            }
            for r in w
                .roles
                .iter_mut()
                .filter(|r| r.kind == RoleKind::Controller)
            {
                r.params.insert("autopilot".into(), url.into());
            }
        }
        None if w.needs_builtin_vehicle() => {
            // one link per vehicle: each vehicle's roles share a port of their own
            let scopes: Vec<Option<u8>> = match w.fleet.vehicles {
                1 => vec![None],
                n => (1..=n).map(Some).collect(),
            };
            let mut taken = Vec::with_capacity(scopes.len());
            for scope in scopes {
                let port = distinct_port(&mut free_port, &taken).map_err(PlanError::VehicleLink)?;
                taken.push(port);
                vehicle_port.get_or_insert(port);
                for r in w.roles.iter_mut().filter(|r| r.vehicle == scope) {
                    let (key, url) = match r.kind {
                        RoleKind::Vehicle => ("listen", format!("udpin:127.0.0.1:{port}")),
                        RoleKind::Controller => ("autopilot", format!("udpout:127.0.0.1:{port}")),
                        _ => continue,
                    };
                    if r.param_str(key).is_none_or(|v| v == "auto") {
                        r.params.insert(key.into(), url.into());
                    }
                    // vehicle K is MAVLink system K
                    if let (Some(k), RoleKind::Vehicle) = (scope, r.kind) {
                        r.params.entry("system_id").or_insert(k.into());
                    }
                }
            }
        }
        None => {}
    }
    // the formation role flies the fleet from where it starts
    let starts = w.fleet.starts(w.mission.start);
    for r in w.roles.iter_mut().filter(|r| r.kind == RoleKind::Formation) {
        r.params.insert("vehicles".into(), w.fleet.vehicles.into());
        r.params.insert(
            "starts".into(),
            serde_json::to_value(&starts).unwrap_or_default(),
        );
    }
    // a recorder subscribes to the topics it was fitted to (`Workflow::fit_recorders`); in a
    // flight of several vehicles, those of a vehicle's scope once per vehicle (`v2/...`)
    let vehicles = w.fleet.vehicles;
    for r in w.roles.iter_mut().filter(|r| r.kind == RoleKind::Recorder) {
        if !r.params.contains_key("topics") {
            let topics: Vec<String> = r
                .subscribes
                .iter()
                .flat_map(|t| topics::in_fleet(t, vehicles))
                .collect();
            r.params.insert("topics".into(), topics.into());
        }
    }
    w.validate()?;
    let executors = resolve_executors(&w, online);
    let bridges = bridge_roles(&w);
    let roles = bridges
        .iter()
        .chain(w.start_order().into_iter().filter_map(|i| w.roles.get(i)))
        .map(|r| {
            let host = w.role_host(r).or_else(|| {
                // a bridge on another host names it in its params
                let name = r.param_str(BRIDGE_HOST_PARAM)?;
                w.hosts.iter().find(|h| h.name == name)
            });
            let executor = r.executor.as_ref().and_then(|name| w.executor(name));
            let cpus = match host {
                Some(_) => None,
                None => r.executor.as_ref().and_then(|name| {
                    executors
                        .iter()
                        .find(|(n, _)| n == name)
                        .map(|(_, s)| s.clone())
                }),
            };
            let remote = host.map(|h| remote_spec(h, executor));
            PlannedRole {
                spec: RoleSpec {
                    flight: flight.to_string(),
                    name: r.name.clone(),
                    kind: r.kind,
                    variant: r.variant.clone(),
                    cpus: cpus.as_ref().map(|c| c.to_string()).unwrap_or_default(),
                    timing: w.timing.clone(),
                    camera: w.camera.clone(),
                    mission: match r.vehicle {
                        // each vehicle starts where the fleet puts it
                        Some(k) => MissionSpec {
                            start: w.fleet.start(k, w.mission.start),
                            ..w.mission.clone()
                        },
                        None => w.mission.clone(),
                    },
                    params: r.params.clone(),
                    instance: 0,
                    remote,
                    heartbeat_pid: None,
                    flight_clock_offset_ns: 0,
                    clock: Default::default(),
                    accelerator: executor.and_then(|e| e.accelerator).map(|a| a.to_string()),
                    vehicle: r.vehicle,
                },
                cpus,
                executor: r.executor.clone(),
                budget_ms: w.role_budget_ms(r),
                restart: r.restart,
                max_restarts: r.max_restarts,
                backoff_ms: r.backoff_ms,
                pool: r.variants.clone(),
                ladder: r.ladder.clone(),
                fallback: r.fallback.as_ref().map(|f| PlannedFallback {
                    variant: f.variant.clone(),
                    executor: f.executor.clone(),
                    cpus: f.executor.as_ref().and_then(|name| {
                        executors
                            .iter()
                            .find(|(n, _)| n == name)
                            .map(|(_, s)| s.clone())
                    }),
                }),
            }
        })
        .collect();
    let remote_executors = w
        .executors
        .iter()
        .filter_map(|ex| {
            let host = w.hosts.iter().find(|h| Some(&h.name) == ex.host.as_ref())?;
            Some((ex.name.clone(), remote_spec(host, Some(ex))))
        })
        .collect();
    let accelerators = w
        .executors
        .iter()
        .filter_map(|ex| Some((ex.name.clone(), ex.accelerator?)))
        .collect();
    Ok(LaunchPlan {
        roles,
        executors,
        remote_executors,
        accelerators,
        vehicle_port,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn four_cpus() -> CpuSet {
        CpuSet::parse("0-3").unwrap()
    }

    #[test]
    fn auto_executors_get_one_cpu_each_round_robin() {
        let w = Workflow::builtin_default().unwrap();
        let ex = resolve_executors(&w, &four_cpus());
        assert_eq!(
            ex,
            vec![
                ("control".to_string(), CpuSet::parse("0").unwrap()),
                ("perception".to_string(), CpuSet::parse("1").unwrap()),
            ]
        );
        // one CPU: both share it
        let ex = resolve_executors(&w, &CpuSet::parse("5").unwrap());
        assert!(ex.iter().all(|(_, s)| s.cpus() == [5]));
    }

    #[test]
    fn each_vehicle_of_a_formation_gets_its_own_link_scope_start_and_system_id() {
        let w = Workflow::builtin_formation().unwrap();
        let mut ports = 15000..;
        let plan = plan_launch(&w, "fleet", None, &four_cpus(), || {
            Ok(ports.next().unwrap())
        })
        .unwrap();
        let spec = |name: &str| {
            &plan
                .roles
                .iter()
                .find(|r| r.spec.name == name)
                .unwrap()
                .spec
        };
        for k in 1..=4u8 {
            let vehicle = spec(&format!("vehicle-v{k}"));
            let controller = spec(&format!("controller-v{k}"));
            let port = 15000 + u16::from(k) - 1;
            assert_eq!(vehicle.params["listen"], format!("udpin:127.0.0.1:{port}"));
            assert_eq!(
                controller.params["autopilot"],
                format!("udpout:127.0.0.1:{port}")
            );
            assert_eq!(vehicle.params["system_id"], u64::from(k));
            assert_eq!((vehicle.vehicle, controller.vehicle), (Some(k), Some(k)));
            assert_eq!(vehicle.mission.start, w.fleet.start(k, w.mission.start));
            assert_eq!(controller.mission.start, vehicle.mission.start);
        }
        let formation = spec("formation");
        assert_eq!(formation.vehicle, None);
        assert_eq!(formation.params["vehicles"], 4);
        assert_eq!(
            formation.params["starts"],
            serde_json::to_value(w.fleet.starts(w.mission.start)).unwrap()
        );
        // one URL cannot be four autopilots
        assert!(matches!(
            plan_launch(
                &w,
                "fleet",
                Some("udpout:10.0.0.9:14550"),
                &four_cpus(),
                || Ok(1)
            ),
            Err(PlanError::OneAutopilotForSeveral { vehicles: 4 })
        ));
    }

    #[test]
    fn per_vehicle_params_give_each_vehicle_its_own_autopilot() {
        let toml = crate::workflow::FORMATION_WORKFLOW_TOML
            .replace(
                "params = { autopilot = \"auto\" }",
                "per_vehicle_params = { autopilot = [\"udpout:10.0.0.1:14550\", \"udpout:10.0.0.2:14550\", \"udpout:10.0.0.3:14550\", \"udpout:10.0.0.4:14550\"] }",
            );
        let w = Workflow::from_toml_str(&toml).unwrap();
        for k in 1..=4 {
            let c = w.role(&format!("controller-v{k}")).unwrap();
            assert_eq!(
                c.param_str("autopilot"),
                Some(format!("udpout:10.0.0.{k}:14550").as_str())
            );
        }
        assert!(!w.needs_builtin_vehicle());
        let short = toml.replace(", \"udpout:10.0.0.4:14550\"", "");
        assert!(matches!(
            Workflow::from_toml_str(&short),
            Err(WorkflowError::PerVehicleParam { vehicles: 4, .. })
        ));
    }

    #[test]
    fn all_and_explicit_sets_resolve_as_written() {
        let mut w = Workflow::builtin_default().unwrap();
        w.executors[0].cpus = ExecutorCpus::All;
        w.executors[1].cpus = ExecutorCpus::Set(CpuSet::parse("0").unwrap());
        let ex = resolve_executors(&w, &four_cpus());
        assert_eq!(ex[0].1, four_cpus());
        assert_eq!(ex[1].1, CpuSet::parse("0").unwrap());
    }

    #[test]
    fn a_declared_recorder_is_fitted_to_the_published_topics_and_told_them() {
        let toml = format!(
            "{}\n[[roles]]\nname = \"rec\"\nkind = \"recorder\"\nvariant = \"mcap\"\nparams = {{ path = \"f.mcap\" }}\n",
            crate::workflow::DEFAULT_WORKFLOW_TOML
        );
        let w = Workflow::from_toml_str(&toml).unwrap();
        let rec = w.role("rec").unwrap();
        assert!(rec.subscribes.iter().any(|t| t == "hub/report"));
        assert!(!rec.subscribes.iter().any(|t| t == "perception/text"));
        assert!(
            w.service_edges()
                .iter()
                .all(|(_, to, _)| w.roles[*to].name != "rec")
        );
        assert_eq!(w.role_budget_ms(rec), None);
        let plan = plan_launch(&w, "plan-test", None, &four_cpus(), || Ok(14999)).unwrap();
        let spec = &plan
            .roles
            .iter()
            .find(|r| r.spec.name == "rec")
            .unwrap()
            .spec;
        let topics: Vec<String> = serde_json::from_value(spec.params["topics"].clone()).unwrap();
        assert_eq!(topics, rec.subscribes);
    }

    #[test]
    fn the_builtin_vehicle_is_linked_to_the_controller() {
        let w = Workflow::builtin_default().unwrap();
        let plan = plan_launch(&w, "plan-test", None, &four_cpus(), || Ok(14999)).unwrap();
        assert_eq!(plan.vehicle_port, Some(14999));
        let role = |n: &str| plan.roles.iter().find(|r| r.spec.name == n).unwrap();
        assert_eq!(
            role("vehicle").spec.param_str("listen"),
            Some("udpin:127.0.0.1:14999")
        );
        assert_eq!(
            role("controller").spec.param_str("autopilot"),
            Some("udpout:127.0.0.1:14999")
        );
        assert_eq!(role("controller").spec.cpus, "0");
        // the hot standby shares the link, on the other executor
        assert_eq!(
            role("controller-standby").spec.param_str("autopilot"),
            Some("udpout:127.0.0.1:14999")
        );
        assert_eq!(role("controller-standby").spec.cpus, "1");
        assert_eq!(role("camera").spec.cpus, "1");
        assert_eq!(role("reasoning").cpus, Some(CpuSet::parse("1").unwrap()));
        assert_eq!(plan.roles.len(), 7);
        assert!(plan.roles.iter().all(|r| r.spec.flight == "plan-test"));
    }

    #[test]
    fn an_external_autopilot_drops_the_vehicle() {
        let w = Workflow::builtin_default().unwrap();
        let plan = plan_launch(
            &w,
            "plan-test",
            Some("udpout:10.0.0.2:14540"),
            &four_cpus(),
            || panic!("no port is needed"),
        )
        .unwrap();
        assert_eq!(plan.vehicle_port, None);
        assert!(plan.roles.iter().all(|r| r.spec.kind != RoleKind::Vehicle));
        let controller = plan
            .roles
            .iter()
            .find(|r| r.spec.kind == RoleKind::Controller)
            .unwrap();
        assert_eq!(
            controller.spec.param_str("autopilot"),
            Some("udpout:10.0.0.2:14540")
        );
        let controllers = |url: &str| {
            plan_launch(&w, "plan-test", Some(url), &four_cpus(), || Ok(1))
                .unwrap()
                .roles
                .iter()
                .filter(|r| r.spec.kind == RoleKind::Controller)
                .map(|r| r.spec.name.clone())
                .collect::<Vec<_>>()
        };
        // two processes can each open a udpout/tcpout link: the standby stays
        assert_eq!(
            controllers("udpout:10.0.0.2:14540"),
            ["controller", "controller-standby"]
        );
        assert_eq!(
            controllers("tcpout:10.0.0.2:5760"),
            ["controller", "controller-standby"]
        );
        // a listening port or a serial device admits one: the standby is dropped
        assert_eq!(controllers("udpin:0.0.0.0:14540"), ["controller"]);
        assert_eq!(controllers("serial:/dev/ttyACM0:57600"), ["controller"]);
    }

    #[test]
    fn bad_flight_names_and_port_failures_are_reported() {
        let w = Workflow::builtin_default().unwrap();
        assert!(matches!(
            plan_launch(&w, "Bad Name", None, &four_cpus(), || Ok(1)),
            Err(PlanError::FlightName(_))
        ));
        let err = plan_launch(&w, "ok", None, &four_cpus(), || {
            Err(std::io::Error::other("no ports"))
        })
        .unwrap_err();
        assert!(matches!(err, PlanError::VehicleLink(_)), "{err}");
    }

    #[test]
    fn free_udp_port_is_nonzero() {
        assert_ne!(free_udp_port().unwrap(), 0);
    }
}
