//! Every bad workflow file under tests/workflows/ is rejected with the right error, and the
//! message names the offending thing. The parser never panics, whatever the input.

use aeris_orchestrator::workflow::{DEFAULT_WORKFLOW_TOML, MODELS_WORKFLOW_TOML};
use aeris_orchestrator::{Workflow, WorkflowError, WorkflowFileError};
use aeris_runtime::affinity::CpuSetError;
use aeris_schemas::RoleKind;
use proptest::prelude::*;
use std::path::PathBuf;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/workflows")
        .join(name)
}

/// Load a fixture that must fail; returns the validation error and the full message (the
/// error and its cause, as the binary prints them).
fn load_bad(name: &str) -> (WorkflowError, String) {
    match Workflow::from_path(&fixture(name)) {
        Ok(_) => panic!("{name} was accepted"),
        Err(e @ WorkflowFileError::Read { .. }) => panic!("{name}: {e}"),
        Err(e) => {
            let msg = aeris_runtime::error_chain::chain(&e).to_string();
            assert!(msg.contains(name), "the message names the file: {msg}");
            match e {
                WorkflowFileError::Invalid { source, .. } => (source, msg),
                WorkflowFileError::Read { .. } => unreachable!(),
            }
        }
    }
}

#[test]
fn the_default_workflow_file_loads() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../workflows/default.toml");
    let from_file = Workflow::from_path(&path).unwrap();
    assert_eq!(from_file, Workflow::builtin_default().unwrap());
}

#[test]
fn missing_state_producer_is_named() {
    // no `perception` role and no perception pipeline: nobody publishes S_t
    let (e, msg) = load_bad("missing_role.toml");
    assert!(matches!(e, WorkflowError::Unpublished { .. }), "{e:?}");
    assert!(msg.contains("`perception/state`"), "{msg}");
}

#[test]
fn missing_vehicle_explains_the_autopilot() {
    let (e, msg) = load_bad("missing_vehicle.toml");
    assert!(
        matches!(
            e,
            WorkflowError::MissingRole {
                kind: RoleKind::Vehicle,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(msg.contains("autopilot"), "{msg}");
}

#[test]
fn unknown_variant_lists_the_known_ones() {
    let (e, msg) = load_bad("unknown_variant.toml");
    match &e {
        WorkflowError::UnknownVariant {
            role,
            kind,
            variant,
            ..
        } => {
            assert_eq!(role, "reasoning");
            assert_eq!(*kind, RoleKind::Reasoning);
            assert_eq!(variant, "gpt5");
        }
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("gpt5"), "{msg}");
    assert!(msg.contains("planner, garbage"), "{msg}");
}

#[test]
fn cpu_set_syntax_is_checked() {
    let (e, msg) = load_bad("bad_cpuset_syntax.toml");
    match &e {
        WorkflowError::BadCpuSet {
            executor,
            cpus,
            source,
        } => {
            assert_eq!(executor, "control");
            assert_eq!(cpus, "0-x");
            assert!(matches!(source, CpuSetError::Syntax(_)), "{source:?}");
        }
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("0-x") && msg.contains("control"), "{msg}");
}

#[test]
fn cpus_must_exist_on_this_machine() {
    let (e, msg) = load_bad("bad_cpuset_missing_cpu.toml");
    match &e {
        WorkflowError::BadCpuSet {
            executor, source, ..
        } => {
            assert_eq!(executor, "perception");
            assert!(
                matches!(source, CpuSetError::NoSuchCpu { cpu: 999, .. }),
                "{source:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("999"), "{msg}");
}

#[test]
fn a_cycle_in_the_services_graph_is_reported_with_its_path() {
    let (e, msg) = load_bad("cycle.toml");
    match &e {
        WorkflowError::Cycle { path, topics } => {
            assert_eq!(path.first(), path.last(), "{path:?}");
            assert_eq!(topics.len() + 1, path.len());
            // the cycle is hub -> camera -> perception -> hub, starting anywhere on it
            let mut ring: Vec<&str> = path[..path.len() - 1].iter().map(String::as_str).collect();
            let at = ring.iter().position(|r| *r == "hub").expect("hub on it");
            ring.rotate_left(at);
            assert_eq!(ring, ["hub", "camera", "perception"]);
            assert!(topics.iter().any(|t| t == "hub/report"), "{topics:?}");
        }
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("hub -[hub/report]-> camera"), "{msg}");
    assert!(
        msg.contains("feedback"),
        "the message says how to fix it: {msg}"
    );
}

#[test]
fn unknown_kind_is_named_with_the_known_kinds() {
    let (e, msg) = load_bad("unknown_kind.toml");
    assert!(
        matches!(&e, WorkflowError::UnknownKind { role, kind, .. } if role == "camera" && kind == "lidar"),
        "{e:?}"
    );
    assert!(msg.contains("lidar") && msg.contains("perception"), "{msg}");
}

#[test]
fn duplicate_role_names_are_rejected() {
    let (e, msg) = load_bad("duplicate_name.toml");
    assert!(
        matches!(&e, WorkflowError::DuplicateRole { name } if name == "camera"),
        "{e:?}"
    );
    assert!(msg.contains("`camera`"), "{msg}");
}

#[test]
fn malformed_toml_reports_line_and_column() {
    let (e, msg) = load_bad("malformed.toml");
    match &e {
        WorkflowError::Syntax { line, column, .. } => {
            assert_eq!(*line, 56, "{msg}");
            assert!(*column >= 1, "{msg}");
        }
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("line 56"), "{msg}");
}

#[test]
fn unknown_fields_are_named() {
    let (e, msg) = load_bad("unknown_field.toml");
    match &e {
        WorkflowError::Structure { line, .. } => assert!(*line > 1, "{msg}"),
        other => panic!("{other:?}"),
    }
    assert!(msg.contains("executer"), "{msg}");
}

#[test]
fn unknown_executor_lists_the_declared_ones() {
    let (e, msg) = load_bad("unknown_executor.toml");
    assert!(
        matches!(&e, WorkflowError::UnknownExecutor { role, executor, .. } if role == "perception" && executor == "gpu"),
        "{e:?}"
    );
    assert!(msg.contains("control, perception"), "{msg}");
}

#[test]
fn unpublished_topics_are_named() {
    let (e, msg) = load_bad("unpublished_topic.toml");
    assert!(
        matches!(&e, WorkflowError::Unpublished { role, topic } if role == "perception" && topic == "camera/depth"),
        "{e:?}"
    );
    assert!(msg.contains("camera/depth"), "{msg}");
}

#[test]
fn unknown_topics_are_named() {
    let (e, msg) = load_bad("unknown_topic.toml");
    assert!(
        matches!(&e, WorkflowError::UnknownTopic { role, topic, list: "subscribes", .. } if role == "perception" && topic == "camera/thermal"),
        "{e:?}"
    );
    assert!(msg.contains("camera/thermal"), "{msg}");
}

#[test]
fn timing_out_of_range_is_named() {
    let (e, msg) = load_bad("bad_timing.toml");
    assert!(
        matches!(
            e,
            WorkflowError::Timing {
                field: "control_rate_hz",
                ..
            }
        ),
        "{e:?}"
    );
    assert!(
        msg.contains("control_rate_hz") && msg.contains("5000"),
        "{msg}"
    );
}

#[test]
fn an_unflyable_mission_is_rejected() {
    let (e, msg) = load_bad("bad_mission.toml");
    assert!(matches!(e, WorkflowError::Mission(_)), "{e:?}");
    assert!(msg.contains("LAKE VIEW"), "names the subgoal: {msg}");
}

#[test]
fn a_missing_file_is_named() {
    let path = fixture("does_not_exist.toml");
    let e = Workflow::from_path(&path).unwrap_err();
    assert!(matches!(e, WorkflowFileError::Read { .. }), "{e:?}");
    assert!(e.to_string().contains("does_not_exist.toml"), "{e}");
}

#[test]
fn feedback_topics_must_exist() {
    let text = DEFAULT_WORKFLOW_TOML.replace(
        "feedback = [\"vehicle/telemetry\"]",
        "feedback = [\"vehicle/telemetri\"]",
    );
    let e = Workflow::from_toml_str(&text).unwrap_err();
    assert!(
        matches!(&e, WorkflowError::UnknownFeedbackTopic { topic, .. } if topic == "vehicle/telemetri"),
        "{e:?}"
    );
}

#[test]
fn restart_policy_spelling_is_checked() {
    let text = DEFAULT_WORKFLOW_TOML.replace(
        "name = \"hub\"\n",
        "name = \"hub\"\nrestart = \"sometimes\"\n",
    );
    let e = Workflow::from_toml_str(&text).unwrap_err();
    assert!(
        matches!(&e, WorkflowError::BadRestart { role, value } if role == "hub" && value == "sometimes"),
        "{e:?}"
    );
}

fn char_floor(s: &str, mut i: usize) -> usize {
    i = i.min(s.len());
    while !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC*") {
        let _ = Workflow::from_toml_str(&text);
    }

    #[test]
    fn arbitrary_bytes_as_lossy_text_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = Workflow::from_toml_str(&String::from_utf8_lossy(&bytes));
    }

    /// Mutations of a valid file reach the validator, not just the TOML grammar.
    #[test]
    fn mutated_default_never_panics(
        at in 0usize..DEFAULT_WORKFLOW_TOML.len(),
        cut in 0usize..64,
        insert in "[ -~\\n]{0,16}",
    ) {
        let base = DEFAULT_WORKFLOW_TOML;
        let start = char_floor(base, at);
        let end = char_floor(base, start + cut);
        let text = format!("{}{}{}", &base[..start], insert, &base[end..]);
        let _ = Workflow::from_toml_str(&text);
    }
}

/// The model flight with an executor `gpu` on `accelerator`, its `cues` role bound to it.
fn with_accelerator(accelerator: &str) -> Result<Workflow, WorkflowError> {
    let bound = "name = \"cues\"\nkind = \"cues\"\nvariant = \"minilm\"\nexecutor = \"perception\"";
    assert!(MODELS_WORKFLOW_TOML.contains(bound));
    let text = MODELS_WORKFLOW_TOML
        .replace(bound, &bound.replace("\"perception\"", "\"gpu\""))
        .replace(
            "[executors.control]",
            &format!("[executors.gpu]\ncpus = \"auto\"\naccelerator = \"{accelerator}\"\n\n[executors.control]"),
        );
    Workflow::from_toml_str(&text)
}

#[test]
fn accelerator_executors_are_checked_and_reach_their_roles_specs() {
    let w = with_accelerator("tensorrt:1").unwrap();
    let gpu = w.executors.iter().find(|e| e.name == "gpu").unwrap();
    assert_eq!(
        gpu.accelerator.map(|a| a.to_string()).as_deref(),
        Some("tensorrt:1")
    );
    let online = aeris_runtime::affinity::CpuSet::available();
    let plan =
        aeris_orchestrator::launch::plan_launch(&w, "accel", None, &online, || Ok(14550)).unwrap();
    let cues = plan.roles.iter().find(|r| r.spec.name == "cues").unwrap();
    assert_eq!(cues.spec.accelerator.as_deref(), Some("tensorrt:1"));
    // the other roles run on CPUs
    let detector = plan
        .roles
        .iter()
        .find(|r| r.spec.name == "detector")
        .unwrap();
    assert_eq!(detector.spec.accelerator, None);
    assert_eq!(plan.accelerators.len(), 1);

    let e = with_accelerator("cuda:zero").unwrap_err();
    assert!(
        matches!(&e, WorkflowError::BadAccelerator { executor, .. } if executor == "gpu"),
        "{e:?}"
    );
    let msg = aeris_runtime::error_chain::chain(&e).to_string();
    assert!(msg.contains("cuda:zero"), "{msg}");
}
