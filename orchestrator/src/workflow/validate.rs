//! Validating a workflow: timing, scheduling, camera and mission ranges, executors, every
//! role against its kind (`RoleKind::info`: kinds, variants, pools, ladders, parameters, topics), the
//! required kinds, that every subscribed topic has a publisher, and that the services graph
//! has no cycle.

use super::{ExecutorCpus, Workflow, WorkflowError};
use aeris_schemas::accelerator::{Accelerator, AcceleratorKind};
use aeris_schemas::heartbeat::NAME_MAX;
use aeris_schemas::{MAX_ROLES, RoleKind, topics};

/// Role kinds every workflow must have (plus `vehicle` while the controller's autopilot is
/// `auto`; a replayed flight's `replay` role stands in for the controller and camera). S_t may come from one `perception` role or from the perception pipeline
/// (`image-to-text` composing the blocks): the topic check requires a publisher of
/// `perception/state` either way.
pub const REQUIRED_KINDS: [RoleKind; 4] = [
    RoleKind::Hub,
    RoleKind::Reasoning,
    RoleKind::Controller,
    RoleKind::Camera,
];

fn known_topics() -> String {
    topics::ALL.join(", ")
}

/// `true` for a role name a workflow may use: 1 to [`NAME_MAX`] bytes of ASCII letters,
/// digits, `_` and `-` (a plain file name: the supervisor and the host agents name files
/// after it).
pub fn is_valid_role_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= NAME_MAX
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// The role variants whose work is ONNX Runtime sessions, which an accelerator executor can
/// run (`kind`, `variant`).
pub const ONNX_MODEL_VARIANTS: &[(RoleKind, &str)] = &[
    (RoleKind::TextReader, "ppocr"),
    (RoleKind::Detector, "yolo"),
    (RoleKind::Detector, "yolov8"),
    (RoleKind::Cues, "minilm"),
    (RoleKind::Occupancy, "onnx"),
];

/// The role variants whose work is a llama.cpp language model, which offloads its layers to a
/// CUDA accelerator (in a build with the cargo feature `cuda`).
pub const LANGUAGE_MODEL_VARIANTS: &[(RoleKind, &str)] = &[
    (RoleKind::Reasoning, "smollm2"),
    (RoleKind::Reasoning, "gemma3"),
    (RoleKind::Reasoning, "smollm2-aligned"),
];

/// Whether `kind`/`variant` can run on `accelerator`: ONNX models on any, language models on
/// CUDA devices.
pub fn runs_on_accelerator(kind: RoleKind, variant: &str, accelerator: Accelerator) -> bool {
    ONNX_MODEL_VARIANTS.contains(&(kind, variant))
        || (accelerator.kind == AcceleratorKind::Cuda
            && LANGUAGE_MODEL_VARIANTS.contains(&(kind, variant)))
}

/// The variants that can use an accelerator, for messages: `text-reader/ppocr, ...,
/// reasoning/gemma3 (cuda only)`.
pub(crate) fn accelerated_variants_text() -> String {
    let onnx = ONNX_MODEL_VARIANTS.iter().map(|(k, v)| format!("{k}/{v}"));
    let language = LANGUAGE_MODEL_VARIANTS
        .iter()
        .map(|(k, v)| format!("{k}/{v} (cuda only)"));
    onnx.chain(language).collect::<Vec<_>>().join(", ")
}
impl Workflow {
    /// Check everything: timing, camera, mission, executors, roles against their kinds,
    /// required kinds, topics, and that the services graph has no cycle.
    pub fn validate(&self) -> Result<(), WorkflowError> {
        self.validate_timing()?;
        self.validate_scheduling()?;
        self.validate_camera()?;
        self.mission.validate().map_err(WorkflowError::Mission)?;
        for ex in &self.executors {
            if let ExecutorCpus::Set(set) = &ex.cpus {
                set.check_exists()
                    .map_err(|source| WorkflowError::BadCpuSet {
                        executor: ex.name.clone(),
                        cpus: set.to_string(),
                        source,
                    })?;
            }
        }
        self.validate_hosts()?;
        self.validate_roles()?;
        self.validate_required()?;
        self.validate_topics()?;
        if let Some((path, topics)) = self.find_cycle() {
            return Err(WorkflowError::Cycle { path, topics });
        }
        Ok(())
    }

    fn validate_scheduling(&self) -> Result<(), WorkflowError> {
        let s = &self.scheduling;
        let bad = |field, value: String, reason| WorkflowError::Scheduling {
            field,
            value,
            reason,
        };
        if s.interval_ms < 20 {
            return Err(bad(
                "interval_ms",
                s.interval_ms.to_string(),
                "must be at least 20 ms",
            ));
        }
        if s.trigger_samples == 0 {
            return Err(bad("trigger_samples", "0".into(), "must be at least 1"));
        }
        if s.probe_ticks == 1 || s.probe_ticks > 40 {
            return Err(bad(
                "probe_ticks",
                s.probe_ticks.to_string(),
                "must be 0 (no probes) or 2..=40 (a slowdown needs two samples on the executor)",
            ));
        }
        if !(s.margin.is_finite() && (0.0..=0.9).contains(&s.margin)) {
            return Err(bad("margin", s.margin.to_string(), "must be in 0..=0.9"));
        }
        if s.stall_timeout_ms < 2 * self.timing.idle_heartbeat_ms {
            return Err(bad(
                "stall_timeout_ms",
                s.stall_timeout_ms.to_string(),
                "must be at least twice idle_heartbeat_ms (a live idle role would look stalled)",
            ));
        }
        if s.stall_hard_timeout_ms < s.stall_timeout_ms {
            return Err(bad(
                "stall_hard_timeout_ms",
                s.stall_hard_timeout_ms.to_string(),
                "must be at least stall_timeout_ms",
            ));
        }
        for r in &self.roles {
            if let Some(b) = r.budget_ms
                && !(b.is_finite() && b > 0.0)
            {
                return Err(WorkflowError::BadBudget {
                    role: r.name.clone(),
                    value: b.to_string(),
                });
            }
        }
        Ok(())
    }

    fn validate_timing(&self) -> Result<(), WorkflowError> {
        let t = &self.timing;
        let bad = |field, value: String, reason| WorkflowError::Timing {
            field,
            value,
            reason,
        };
        for (field, v) in [
            ("heartbeat_period_ms", t.heartbeat_period_ms),
            ("decision_deadline_ms", t.decision_deadline_ms),
            ("setpoint_timeout_ms", t.setpoint_timeout_ms),
            ("idle_heartbeat_ms", t.idle_heartbeat_ms),
        ] {
            if v == 0 {
                return Err(bad(field, v.to_string(), "must be at least 1 ms"));
            }
        }
        if t.decision_deadline_ms > t.heartbeat_period_ms.saturating_mul(10) {
            return Err(bad(
                "decision_deadline_ms",
                t.decision_deadline_ms.to_string(),
                "must be at most 10 times heartbeat_period_ms",
            ));
        }
        if !(t.control_rate_hz.is_finite() && (1.0..=1000.0).contains(&t.control_rate_hz)) {
            return Err(bad(
                "control_rate_hz",
                t.control_rate_hz.to_string(),
                "must be a finite rate in 1..=1000 Hz",
            ));
        }
        Ok(())
    }

    fn validate_camera(&self) -> Result<(), WorkflowError> {
        let c = &self.camera;
        let bad = |field, value: String, reason| WorkflowError::Camera {
            field,
            value,
            reason,
        };
        if !(1..=4096).contains(&c.width) {
            return Err(bad("width", c.width.to_string(), "must be in 1..=4096"));
        }
        if !(1..=4096).contains(&c.height) {
            return Err(bad("height", c.height.to_string(), "must be in 1..=4096"));
        }
        if !(c.fps.is_finite() && c.fps > 0.0 && c.fps <= 1000.0) {
            return Err(bad("fps", c.fps.to_string(), "must be in (0, 1000]"));
        }
        if !(c.hfov_deg.is_finite() && c.hfov_deg > 0.0 && c.hfov_deg < 180.0) {
            return Err(bad(
                "hfov_deg",
                c.hfov_deg.to_string(),
                "must be in (0, 180) degrees",
            ));
        }
        Ok(())
    }

    fn validate_roles(&self) -> Result<(), WorkflowError> {
        if self.roles.len() > MAX_ROLES {
            return Err(WorkflowError::TooManyRoles {
                count: self.roles.len(),
                max: MAX_ROLES,
            });
        }
        for (i, r) in self.roles.iter().enumerate() {
            if !is_valid_role_name(&r.name) {
                return Err(WorkflowError::BadRoleName {
                    name: r.name.clone(),
                });
            }
            if self.roles[..i].iter().any(|o| o.name == r.name) {
                return Err(WorkflowError::DuplicateRole {
                    name: r.name.clone(),
                });
            }
            let kind = r.kind.info();
            for v in core::iter::once(&r.variant).chain(r.variants.iter()) {
                if !kind.variants.contains(&v.as_str()) {
                    return Err(WorkflowError::UnknownVariant {
                        role: r.name.clone(),
                        kind: r.kind,
                        variant: v.clone(),
                        known: kind.variants.join(", "),
                    });
                }
            }
            if !r.variants.contains(&r.variant) {
                return Err(WorkflowError::VariantNotInPool {
                    role: r.name.clone(),
                    variant: r.variant.clone(),
                    pool: r.variants.join(", "),
                });
            }
            if !r.ladder.is_empty() {
                let bad = |reason: String| WorkflowError::BadLadder {
                    role: r.name.clone(),
                    ladder: r.ladder.join(", "),
                    reason,
                };
                if r.ladder.len() < 2 {
                    return Err(bad("a ladder needs at least two variants".into()));
                }
                if let Some(v) = r.ladder.iter().find(|v| !r.variants.contains(v)) {
                    return Err(bad(format!(
                        "`{v}` is not in the variants pool [{}]",
                        r.variants.join(", ")
                    )));
                }
                if let Some((i, v)) = r
                    .ladder
                    .iter()
                    .enumerate()
                    .find(|(i, v)| r.ladder[..*i].contains(v))
                {
                    return Err(bad(format!("`{v}` is on it twice (again at rung {i})")));
                }
                if !r.ladder.contains(&r.variant) {
                    return Err(bad(format!(
                        "the declared variant `{}` is not on it (the role starts there)",
                        r.variant
                    )));
                }
            }
            if let Some(ex) = &r.executor
                && !self.executors.iter().any(|e| &e.name == ex)
            {
                let known = if self.executors.is_empty() {
                    "none".to_string()
                } else {
                    self.executors
                        .iter()
                        .map(|e| e.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                return Err(WorkflowError::UnknownExecutor {
                    role: r.name.clone(),
                    executor: ex.clone(),
                    known,
                });
            }
            // on an accelerator: the variant, every variant it may be swapped or stepped to,
            // and its fallback where the fallback's executor is one
            let fallback = r.fallback.as_ref();
            let placed = [
                (r.executor.as_deref(), vec![r.variant.as_str()]),
                (
                    r.executor.as_deref(),
                    r.variants
                        .iter()
                        .chain(&r.ladder)
                        .map(String::as_str)
                        .collect(),
                ),
                (
                    fallback.and_then(|f| f.executor.as_deref()),
                    fallback.map(|f| f.variant.as_str()).into_iter().collect(),
                ),
            ];
            for (executor, variants) in placed {
                let Some(ex) = executor.and_then(|ex| self.executor(ex)) else {
                    continue;
                };
                let Some(accelerator) = ex.accelerator else {
                    continue;
                };
                if let Some(variant) = variants
                    .into_iter()
                    .find(|v| !runs_on_accelerator(r.kind, v, accelerator))
                {
                    return Err(WorkflowError::NotAccelerated {
                        role: r.name.clone(),
                        kind_variant: format!("{} / {variant}", r.kind),
                        executor: ex.name.clone(),
                        accelerator,
                    });
                }
            }
            let string_param = |param: &'static str| match r.params.get(param) {
                Some(v) if !v.is_string() => Err(WorkflowError::BadParam {
                    role: r.name.clone(),
                    param,
                    reason: "must be a string (\"auto\" or a MAVLink URL such as \"udpout:127.0.0.1:14540\")",
                }),
                _ => Ok(()),
            };
            match r.kind {
                RoleKind::Controller => {
                    string_param("autopilot")?;
                    if r.params.get("standby").is_some_and(|v| !v.is_boolean()) {
                        return Err(WorkflowError::BadParam {
                            role: r.name.clone(),
                            param: "standby",
                            reason: "must be true or false",
                        });
                    }
                }
                RoleKind::Vehicle => string_param("listen")?,
                _ => {}
            }
            for (list, topics_of) in [("subscribes", &r.subscribes), ("publishes", &r.publishes)] {
                if let Some(t) = topics_of.iter().find(|t| !topics::is_known_topic(t)) {
                    return Err(WorkflowError::UnknownTopic {
                        role: r.name.clone(),
                        topic: t.clone(),
                        list,
                        known: known_topics(),
                    });
                }
            }
        }
        if let Some(t) = self.feedback.iter().find(|t| !topics::is_known_topic(t)) {
            return Err(WorkflowError::UnknownFeedbackTopic {
                topic: t.clone(),
                known: known_topics(),
            });
        }
        Ok(())
    }

    fn validate_required(&self) -> Result<(), WorkflowError> {
        let has = |kind: RoleKind| self.roles.iter().any(|r| r.kind == kind);
        // a replayed flight's camera and vehicle are its recording (`aeris replay`)
        let replayed = |kind: RoleKind| {
            matches!(kind, RoleKind::Controller | RoleKind::Camera) && has(RoleKind::Replay)
        };
        if self.fleet.vehicles > 1 || has(RoleKind::Formation) {
            // a formation flight: the formation role flies every vehicle's controller
            if !has(RoleKind::Formation) {
                return Err(WorkflowError::MissingRole {
                    kind: RoleKind::Formation,
                    hint: " ([flight] vehicles > 1: a formation role flies them)",
                });
            }
            if let Some(r) = self.roles.iter().find(|r| {
                self.fleet.vehicles > 1
                    && r.vehicle.is_none()
                    && matches!(r.kind, RoleKind::Vehicle | RoleKind::Controller)
            }) {
                return Err(WorkflowError::NotPerVehicle {
                    role: r.name.clone(),
                    vehicles: self.fleet.vehicles,
                });
            }
            let controlled = |k: u8| {
                self.roles
                    .iter()
                    .any(|r| r.kind == RoleKind::Controller && r.vehicle.is_none_or(|v| v == k))
            };
            if !(1..=self.fleet.vehicles).all(controlled) {
                return Err(WorkflowError::MissingRole {
                    kind: RoleKind::Controller,
                    hint: " for every vehicle (declare it with per_vehicle = true)",
                });
            }
        } else {
            for kind in REQUIRED_KINDS {
                if !has(kind) && !replayed(kind) {
                    return Err(WorkflowError::MissingRole { kind, hint: "" });
                }
            }
        }
        if self.needs_builtin_vehicle() && !has(RoleKind::Vehicle) {
            return Err(WorkflowError::MissingRole {
                kind: RoleKind::Vehicle,
                hint: " (the controller's autopilot is \"auto\", which flies the built-in vehicle; \
                       add a vehicle role or set the controller's params.autopilot to a MAVLink URL)",
            });
        }
        Ok(())
    }

    fn validate_topics(&self) -> Result<(), WorkflowError> {
        let published = |by: &super::RoleDecl, topic: &str| {
            topic == topics::HEARTBEAT
                || self
                    .roles
                    .iter()
                    .any(|r| r.shares_scope_with(by) && r.publishes.iter().any(|t| t == topic))
        };
        for r in &self.roles {
            if let Some(t) = r.subscribes.iter().find(|t| !published(r, t)) {
                return Err(WorkflowError::Unpublished {
                    role: r.name.clone(),
                    topic: t.clone(),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workflow::MODELS_WORKFLOW_TOML;
    use aeris_runtime::spec::MissionError;

    #[test]
    fn an_altitude_band_that_misses_the_geofence_is_refused() {
        let mut w = Workflow::builtin_default().unwrap();
        // h_max below the fence's floor: no altitude is allowed by both (the controller's
        // tracker once panicked on such limits)
        w.mission.limits.h_max = 5.0;
        w.mission.limits.geofence_min[2] = 10.0;
        let err = w.validate().unwrap_err();
        assert!(
            matches!(err, WorkflowError::Mission(MissionError::BadLimits)),
            "{err}"
        );
        assert!(err.to_string().contains("meets the geofence"), "{err}");
    }

    #[test]
    fn the_model_flight_declares_its_reasoner_ladder_and_bad_ladders_are_refused() {
        let w = Workflow::builtin_models().unwrap();
        let r = w.role("reasoning").unwrap();
        assert_eq!(r.ladder, ["gemma3", "smollm2", "planner"]);
        assert!(w.scheduling.adapt_variants);
        let ladder_error = |ladder: &[&str], variant: &str| {
            let mut w = Workflow::builtin_models().unwrap();
            let r = w
                .roles
                .iter_mut()
                .find(|r| r.kind == RoleKind::Reasoning)
                .unwrap();
            r.ladder = ladder.iter().map(|v| v.to_string()).collect();
            r.variant = variant.into();
            match w.validate() {
                Err(e @ WorkflowError::BadLadder { .. }) => e.to_string(),
                other => panic!("{ladder:?} from {variant}: expected BadLadder, got {other:?}"),
            }
        };
        assert!(ladder_error(&["smollm2"], "smollm2").contains("at least two"));
        assert!(ladder_error(&["smollm2", "random"], "smollm2").contains("`random` is not in"));
        assert!(ladder_error(&["smollm2", "planner", "smollm2"], "smollm2").contains("twice"));
        assert!(ladder_error(&["gemma3", "planner"], "smollm2").contains("declared variant"));
        // `adapt_variants` parses, and an empty ladder is none
        let text = MODELS_WORKFLOW_TOML.replace(
            "ladder = [\"gemma3\", \"smollm2\", \"planner\"]",
            "ladder = []",
        ) + "\n[scheduling]\nadapt_variants = false\n";
        let w = Workflow::from_toml_str(&text).unwrap();
        assert!(!w.scheduling.adapt_variants);
        assert!(w.role("reasoning").unwrap().ladder.is_empty());
    }

    #[test]
    fn timing_limits_are_enforced() {
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.decision_deadline_ms = w.timing.heartbeat_period_ms * 10 + 1;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "decision_deadline_ms",
                ..
            })
        ));
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.control_rate_hz = f64::NAN;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "control_rate_hz",
                ..
            })
        ));
        let mut w = Workflow::builtin_default().unwrap();
        w.timing.heartbeat_period_ms = 0;
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::Timing {
                field: "heartbeat_period_ms",
                ..
            })
        ));
    }

    #[test]
    fn an_external_autopilot_makes_the_vehicle_optional() {
        let mut w = Workflow::builtin_default().unwrap();
        w.roles.retain(|r| r.kind != RoleKind::Vehicle);
        assert!(matches!(
            w.validate(),
            Err(WorkflowError::MissingRole {
                kind: RoleKind::Vehicle,
                ..
            })
        ));
        for r in w
            .roles
            .iter_mut()
            .filter(|r| r.kind == RoleKind::Controller)
        {
            r.params
                .insert("autopilot".into(), "udpout:127.0.0.1:14540".into());
        }
        w.validate().unwrap();
    }
}
