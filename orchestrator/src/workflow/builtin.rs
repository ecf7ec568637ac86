//! The built-in workflows: the default flight, the model flight and the formation flight,
//! compiled in from `workflows/`.

use super::{Workflow, WorkflowError};

/// The built-in default flight (`workflows/default.toml`).
pub const DEFAULT_WORKFLOW_TOML: &str = include_str!("../../../workflows/default.toml");

/// The model flight (`workflows/models.toml`): a real model in every perception and
/// reasoning role; what `aeris bench cycle` and `aeris bench swap` fly.
pub const MODELS_WORKFLOW_TOML: &str = include_str!("../../../workflows/models.toml");

/// The formation flight (`workflows/formation.toml`): four built-in vehicles, each with its
/// controller, flown by the formation role from the mission's instruction; what
/// `aeris formation fly` flies.
pub const FORMATION_WORKFLOW_TOML: &str = include_str!("../../../workflows/formation.toml");

impl Workflow {
    /// The built-in formation flight ([`FORMATION_WORKFLOW_TOML`]).
    pub fn builtin_formation() -> Result<Self, WorkflowError> {
        Self::from_toml_str(FORMATION_WORKFLOW_TOML)
    }

    /// The built-in formation flight with `vehicles` vehicles, flying `instruction` (the
    /// built-in one when `None`), its program written by `variant` (`parser`, `qwen-coder`,
    /// `smollm2`, `gemma3`).
    pub fn builtin_formation_with(
        vehicles: u8,
        instruction: Option<&str>,
        variant: &str,
    ) -> Result<Self, WorkflowError> {
        let mut table: toml::Table =
            FORMATION_WORKFLOW_TOML
                .parse()
                .map_err(|e: toml::de::Error| WorkflowError::Syntax {
                    line: 0,
                    column: 0,
                    message: e.message().to_string(),
                })?;
        if let Some(flight) = table.get_mut("flight").and_then(|t| t.as_table_mut()) {
            flight.insert("vehicles".into(), i64::from(vehicles).into());
        }
        if let (Some(text), Some(mission)) = (
            instruction,
            table.get_mut("mission").and_then(|t| t.as_table_mut()),
        ) {
            mission.insert("instruction".into(), text.into());
        }
        let roles = table.get_mut("roles").and_then(|r| r.as_array_mut());
        for role in roles.into_iter().flatten() {
            if let Some(role) = role.as_table_mut()
                && role.get("kind").and_then(|k| k.as_str())
                    == Some(aeris_schemas::RoleKind::Formation.name())
            {
                role.insert("variant".into(), variant.into());
            }
        }
        Self::from_toml_str(&table.to_string())
    }

    /// The built-in default flight (`workflows/default.toml`).
    pub fn builtin_default() -> Result<Self, WorkflowError> {
        Self::from_toml_str(DEFAULT_WORKFLOW_TOML)
    }

    /// The built-in model flight ([`MODELS_WORKFLOW_TOML`]).
    pub fn builtin_models() -> Result<Self, WorkflowError> {
        Self::from_toml_str(MODELS_WORKFLOW_TOML)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workflow::ExecutorCpus;
    use aeris_runtime::spec::TimingSpec;
    use aeris_schemas::{RoleKind, topics};

    #[test]
    fn the_builtin_default_is_valid_and_complete() {
        let w = Workflow::builtin_default().unwrap();
        let names: Vec<&str> = w.roles.iter().map(|r| r.name.as_str()).collect();
        for n in [
            "vehicle",
            "controller",
            "camera",
            "perception",
            "hub",
            "reasoning",
        ] {
            assert!(names.contains(&n), "{n} missing from {names:?}");
        }
        assert_eq!(w.mission.subgoals.len(), 4);
        assert_eq!(w.mission.world, "village");
        assert_eq!(w.timing, TimingSpec::default());
        assert_eq!(w.feedback, vec![topics::VEHICLE_TELEMETRY.to_string()]);
        assert_eq!(
            w.role("reasoning").unwrap().variants,
            vec!["planner".to_string(), "garbage".to_string()]
        );
        assert!(w.executors.iter().all(|e| e.cpus == ExecutorCpus::Auto));
        assert!(w.needs_builtin_vehicle());
    }

    #[test]
    fn the_builtin_formation_has_every_vehicle_in_its_own_scope() {
        let w = Workflow::builtin_formation().unwrap();
        assert_eq!(w.fleet.vehicles, 4);
        let scoped = |kind: RoleKind| -> Vec<(String, Option<u8>)> {
            w.roles
                .iter()
                .filter(|r| r.kind == kind)
                .map(|r| (r.name.clone(), r.vehicle))
                .collect()
        };
        for kind in [RoleKind::Vehicle, RoleKind::Controller] {
            let expected: Vec<(String, Option<u8>)> =
                (1..=4).map(|k| (format!("{kind}-v{k}"), Some(k))).collect();
            assert_eq!(scoped(kind), expected);
        }
        assert_eq!(
            scoped(RoleKind::Formation),
            vec![("formation".to_string(), None)]
        );
        // the formation role feeds every controller; vehicles' roles never feed each other
        let edges = w.service_edges();
        let formation = w
            .roles
            .iter()
            .position(|r| r.kind == RoleKind::Formation)
            .unwrap();
        for (from, to, topic) in &edges {
            assert_eq!(*from, formation, "{edges:?}");
            assert_eq!(topic, topics::HUB_SETPOINT);
            assert_eq!(w.roles[*to].kind, RoleKind::Controller);
        }
        assert_eq!(edges.len(), 4);
        // side by side on the ground, 4 m apart, centred on the start
        assert_eq!(
            w.fleet.starts(w.mission.start),
            vec![
                [0.0, -6.0, 0.0],
                [0.0, -2.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 6.0, 0.0]
            ]
        );
    }
}
