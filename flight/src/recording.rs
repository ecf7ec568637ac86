//! A recorded flight: the recorder role a builder adds ([`FlightBuilder::record`]) and what
//! the summary says of the recording.
//!
//! [`FlightBuilder::record`]: crate::FlightBuilder::record

use aeris_orchestrator::workflow::{RoleDecl, Workflow};
use aeris_schemas::RoleKind;
use aeris_schemas::{RecorderCounters, RoleHeartbeat};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The recorder's variant.
const VARIANT: &str = "mcap";

/// What the summary says of a recorded flight (`aeris run --json`: `recording`).
#[derive(Debug, Clone, Serialize, PartialEq, Eq)]
pub struct RecordingSummary {
    /// The recording asked for.
    pub path: PathBuf,
    /// Every file it holds: `path`, then `path.1`, ... one per recorder process (a
    /// restarted recorder never writes into an earlier process's file).
    pub files: Vec<PathBuf>,
    /// MCAP messages the last recorder process had written by the end of the flight.
    pub messages: u64,
    /// Samples it dropped (queue full, or recording stopped).
    pub dropped: u64,
    /// Bytes of message data it had written.
    pub bytes: u64,
    /// Its writing failed (disk full, unwritable file): recording stopped early.
    pub failed: bool,
}

impl RecordingSummary {
    /// The summary of the recording at `path`, from the last heartbeat of its recorder.
    pub(crate) fn new(path: &Path, last: Option<&RoleHeartbeat>) -> Self {
        let c = RecorderCounters::from_heartbeat(&last.map(|h| h.counters).unwrap_or_default());
        Self {
            path: path.to_path_buf(),
            files: aeris_record::recording_files(path),
            messages: c.messages,
            dropped: c.dropped,
            bytes: c.bytes,
            failed: c.failed != 0,
        }
    }
}

/// Why a flight cannot be recorded.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The path names something other than a regular file (a device, a folder): it is
    /// neither replaced nor written.
    #[error("{} exists and is not a regular file; record into a file", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// An earlier recording at the path could not be removed, or its folder created.
    #[error("preparing the recording {}", path.display())]
    Prepare {
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Why `aeris record` cannot attach to a running flight.
#[derive(Debug, thiserror::Error)]
pub enum AttachError {
    /// The file exists already: an attached recording never replaces one.
    #[error("{} exists; record into a new file", path.display())]
    Exists {
        /// The file.
        path: PathBuf,
    },
    /// The flight's role specs could not be listed (wrong run directory?).
    #[error("listing the flight's role specs in {}", dir.display())]
    Specs {
        /// The folder.
        dir: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The folder has no spec of the flight.
    #[error(
        "{} holds no role spec of flight `{flight}`: give the flight's --run-dir",
        dir.display()
    )]
    NoSpecs {
        /// The folder.
        dir: PathBuf,
        /// The flight.
        flight: String,
    },
    /// A spec could not be read.
    #[error("reading a role spec")]
    Spec(#[from] aeris_runtime::spec::SpecError),
}

/// The spec of a recorder that attaches to the running flight `flight` (`aeris record`):
/// the flight's timing, camera, mission and roles from the role specs its supervisor
/// wrote into `run_dir/roles`, every topic those roles publish (or `topics`), every frame
/// exact; the file must not exist.
pub fn attach_spec(
    flight: &str,
    run_dir: &Path,
    path: &Path,
    topics: Option<Vec<String>>,
) -> Result<aeris_runtime::RoleSpec, AttachError> {
    if path.exists() {
        return Err(AttachError::Exists {
            path: path.to_path_buf(),
        });
    }
    let dir = run_dir.join("roles");
    let entries = std::fs::read_dir(&dir).map_err(|source| AttachError::Specs {
        dir: dir.clone(),
        source,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    // one spec per role: a hot swap or restart leaves `NAME.iN.json` beside `NAME.json`;
    // the highest instance is the one running
    let mut specs: Vec<aeris_runtime::RoleSpec> = Vec::new();
    for f in files {
        let spec = aeris_runtime::RoleSpec::load(&f)?;
        if spec.flight != flight || spec.kind == RoleKind::Recorder {
            continue;
        }
        match specs.iter_mut().find(|s| s.name == spec.name) {
            Some(s) if s.instance < spec.instance => *s = spec,
            Some(_) => {}
            None => specs.push(spec),
        }
    }
    let Some(first) = specs.first() else {
        return Err(AttachError::NoSpecs {
            dir,
            flight: flight.to_string(),
        });
    };
    // in a flight of several vehicles, a vehicle's topics once in each vehicle's scope
    let vehicles = specs.iter().filter_map(|s| s.vehicle).max().unwrap_or(1);
    let topics = topics.unwrap_or_else(|| {
        let mut published = vec![aeris_schemas::topics::HEARTBEAT.to_string()];
        for s in &specs {
            for t in s.kind.info().publishes {
                for t in aeris_schemas::topics::in_fleet(t, vehicles) {
                    if !published.contains(&t) {
                        published.push(t);
                    }
                }
            }
        }
        published
    });
    let roles: Vec<serde_json::Value> = specs
        .iter()
        .filter_map(|s| {
            recorded_role(
                &s.name,
                s.kind,
                &s.variant,
                vec![s.variant.clone()],
                None,
                &s.params,
            )
        })
        .collect();
    let mut params = serde_json::Map::new();
    params.insert("path".into(), path.to_string_lossy().into_owned().into());
    params.insert("frames".into(), "exact".into());
    params.insert("topics".into(), topics.into());
    params.insert("roles".into(), roles.into());
    Ok(aeris_runtime::RoleSpec {
        flight: flight.to_string(),
        name: "recorder-attached".into(),
        kind: RoleKind::Recorder,
        variant: VARIANT.into(),
        cpus: String::new(),
        timing: first.timing.clone(),
        camera: first.camera.clone(),
        mission: first.mission.clone(),
        params,
        instance: 0,
        remote: None,
        heartbeat_pid: None,
        flight_clock_offset_ns: 0,
        accelerator: None,
        vehicle: None,
        // it watches the flight from outside: never one of the processes time waits for
        clock: Default::default(),
    })
}

/// What [`crate::FlightBuilder::record`] asked for.
#[derive(Debug, Clone, Default)]
pub(crate) struct RecordRequest {
    /// The MCAP file.
    pub(crate) path: PathBuf,
    /// Every n-th frame's pixels as an image (the recorder's default when `None`).
    pub(crate) frame_every: Option<u64>,
    /// JPEG quality of the images, 0 for raw pixels (the recorder's default when `None`).
    pub(crate) jpeg_quality: Option<u8>,
    /// Every frame exactly as well (a recording `aeris replay` can replay).
    pub(crate) exact_frames: bool,
    /// Only these topics (default: every topic the flight publishes).
    pub(crate) topics: Option<Vec<String>>,
}

/// Add a recorder role writing to `request.path` to `workflow`: first in declaration order (it has
/// no service dependencies, so it starts first and sees the flight from its first message),
/// on the executor with the fewest roles, restarted on failure. An earlier recording at
/// `path` (`path` and its `path.N` files) is removed. Returns the role's name.
pub(crate) fn add_recorder(
    workflow: &mut Workflow,
    request: &RecordRequest,
) -> Result<String, RecordError> {
    let path = request.path.as_path();
    if path.exists() && !path.is_file() {
        return Err(RecordError::NotAFile {
            path: path.to_path_buf(),
        });
    }
    for old in aeris_record::recording_files(path)
        .into_iter()
        .filter(|p| p.is_file())
    {
        std::fs::remove_file(&old).map_err(|source| RecordError::Prepare { path: old, source })?;
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| RecordError::Prepare {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let mut name = RoleKind::Recorder.to_string();
    let mut n = 1;
    while workflow.role(&name).is_some() {
        n += 1;
        name = format!("{}-{n}", RoleKind::Recorder);
    }
    let executor = workflow
        .executors
        .iter()
        .min_by_key(|e| {
            workflow
                .roles
                .iter()
                .filter(|r| r.executor.as_deref() == Some(e.name.as_str()))
                .count()
        })
        .map(|e| e.name.clone());
    let mut params = serde_json::Map::new();
    params.insert("path".into(), path.to_string_lossy().into_owned().into());
    if let Some(n) = request.frame_every {
        params.insert("frame_every".into(), n.into());
    }
    match request.jpeg_quality {
        Some(0) => {
            params.insert("image".into(), "raw".into());
        }
        Some(q) => {
            params.insert("jpeg_quality".into(), q.into());
        }
        None => {}
    }
    if request.exact_frames {
        params.insert("frames".into(), "exact".into());
    }
    if let Some(topics) = &request.topics {
        params.insert("topics".into(), topics.clone().into());
    }
    // the flight itself goes into the recording, for a replay to run the same roles
    params.insert("roles".into(), recorded_roles(workflow).into());
    params.insert(
        "executors".into(),
        workflow
            .executors
            .iter()
            .map(|e| serde_json::Value::from(e.name.clone()))
            .collect::<Vec<_>>()
            .into(),
    );
    // fitted below to what the flight publishes
    workflow.roles.insert(
        0,
        RoleDecl::new(&name, RoleKind::Recorder, VARIANT, executor, params),
    );
    workflow.fit_recorders();
    Ok(name)
}

/// The workflow's roles as a recording describes them
/// ([`aeris_record::read::RecordedRole`]).
fn recorded_roles(workflow: &Workflow) -> Vec<serde_json::Value> {
    workflow
        .roles
        .iter()
        .filter(|r| r.kind != RoleKind::Recorder)
        .filter_map(|r| {
            recorded_role(
                &r.name,
                r.kind,
                &r.variant,
                r.variants.clone(),
                r.executor.clone(),
                &r.params,
            )
        })
        .collect()
}

/// One role as a recording describes it.
fn recorded_role(
    name: &str,
    kind: RoleKind,
    variant: &str,
    variants: Vec<String>,
    executor: Option<String>,
    params: &serde_json::Map<String, serde_json::Value>,
) -> Option<serde_json::Value> {
    serde_json::to_value(aeris_record::read::RecordedRole {
        name: name.to_string(),
        kind: kind.to_string(),
        variant: variant.to_string(),
        variants,
        executor,
        params: params.clone(),
    })
    .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recorder_is_added_first_fitted_to_the_published_topics_and_valid() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/flight.mcap");
        let mut w = Workflow::builtin_default().unwrap();
        let request = RecordRequest {
            path: path.clone(),
            frame_every: Some(3),
            jpeg_quality: Some(0),
            exact_frames: true,
            topics: None,
        };
        let name = add_recorder(&mut w, &request).unwrap();
        w.validate().unwrap();
        let r = &w.roles[0];
        assert_eq!(r.params.get("frames"), Some(&"exact".into()));
        assert_eq!(r.params.get("frame_every"), Some(&3.into()));
        assert_eq!(r.params.get("image"), Some(&"raw".into()));
        assert_eq!((r.name.as_str(), name.as_str()), ("recorder", "recorder"));
        assert!(r.subscribes.iter().any(|t| t == "hub/report"));
        assert!(r.subscribes.iter().any(|t| t == "heartbeat"));
        // the default flight has no text reader
        assert!(!r.subscribes.iter().any(|t| t == "perception/text"));
        assert_eq!(w.start_order()[0], 0, "the recorder starts first");
        assert!(path.parent().unwrap().is_dir());

        // the flight goes into the recording: a replay runs its roles but the ones the
        // recording stands in for, on the recorded timeline
        let roles: Vec<aeris_record::read::RecordedRole> =
            serde_json::from_value(r.params["roles"].clone()).unwrap();
        assert_eq!(
            roles.len(),
            w.roles.len() - 1,
            "every role but the recorder"
        );
        let executors: Vec<String> = serde_json::from_value(r.params["executors"].clone()).unwrap();
        let flight = aeris_record::read::RecordedFlight {
            flight: "f".into(),
            schema_version: aeris_schemas::SCHEMA_VERSION,
            layout_hash: String::new(),
            timing: w.timing.clone(),
            camera: w.camera.clone(),
            mission: w.mission.clone(),
            roles,
            executors,
            exact_frames: true,
        };
        let replay = crate::replay::replay_workflow(&flight, &path, 5, 10, 2.0).unwrap();
        let kinds: Vec<&str> = replay.roles.iter().map(|r| r.kind.name()).collect();
        assert_eq!(
            kinds,
            ["replay", "perception", "hub", "reasoning"],
            "{kinds:?}"
        );
        assert_eq!(
            replay.timing.heartbeat_period_ms,
            w.timing.heartbeat_period_ms / 2,
            "twice as fast: the heartbeat too"
        );
        assert_eq!(replay.roles[0].params["from_ns"], 5);
    }

    #[test]
    fn a_recorder_of_a_fleet_records_each_vehicles_topics_in_its_scope() {
        let w = Workflow::builtin_formation().unwrap();
        let online = aeris_runtime::affinity::CpuSet::parse("0-3").unwrap();
        let mut ports = 15000..;
        let plan = aeris_orchestrator::launch::plan_launch(&w, "fleet", None, &online, || {
            Ok(ports.next().unwrap())
        })
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let roles = dir.path().join("roles");
        std::fs::create_dir_all(&roles).unwrap();
        for r in &plan.roles {
            let file = roles.join(format!("{}.json", r.spec.name));
            std::fs::write(file, serde_json::to_vec(&r.spec).unwrap()).unwrap();
        }
        // attached to the running flight (`aeris record`)
        let spec = attach_spec("fleet", dir.path(), &dir.path().join("f.mcap"), None).unwrap();
        let topics: Vec<String> = serde_json::from_value(spec.params["topics"].clone()).unwrap();
        // added at the start (`--record`): the launch plan scopes the fitted topics
        let mut recorded = w.clone();
        add_recorder(
            &mut recorded,
            &RecordRequest {
                path: dir.path().join("g.mcap"),
                ..RecordRequest::default()
            },
        )
        .unwrap();
        let plan =
            aeris_orchestrator::launch::plan_launch(&recorded, "fleet", None, &online, || {
                Ok(ports.next().unwrap())
            })
            .unwrap();
        let recorder = plan
            .roles
            .iter()
            .find(|r| r.spec.kind == RoleKind::Recorder)
            .unwrap();
        let launched: Vec<String> =
            serde_json::from_value(recorder.spec.params["topics"].clone()).unwrap();
        for topics in [&topics, &launched] {
            for k in 1..=4 {
                for t in ["vehicle/telemetry", "hub/setpoint", "controller/lease"] {
                    let scoped = format!("v{k}/{t}");
                    assert!(topics.contains(&scoped), "{scoped} not in {topics:?}");
                }
            }
            assert!(topics.iter().any(|t| t == "heartbeat"), "{topics:?}");
            // no unscoped vehicle topic: a fleet has no such services
            assert!(
                !topics.iter().any(|t| t == "vehicle/telemetry"),
                "{topics:?}"
            );
        }
    }

    #[test]
    fn a_device_or_folder_is_neither_replaced_nor_recorded_into() {
        let mut w = Workflow::builtin_default().unwrap();
        for p in ["/dev/null", "/"] {
            let request = RecordRequest {
                path: p.into(),
                ..RecordRequest::default()
            };
            let err = add_recorder(&mut w, &request).unwrap_err();
            assert!(err.to_string().starts_with(p), "{err}");
        }
        assert!(Path::new("/dev/null").exists());
        assert!(w.roles.iter().all(|r| r.kind != RoleKind::Recorder));
    }
}
