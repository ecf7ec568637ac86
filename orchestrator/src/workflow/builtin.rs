//! The built-in workflows: the default flight and the model flight, compiled in from
//! `workflows/`.

use super::{Workflow, WorkflowError};

/// The built-in default flight (`workflows/default.toml`).
pub const DEFAULT_WORKFLOW_TOML: &str = include_str!("../../../workflows/default.toml");

/// The model flight (`workflows/models.toml`): a real model in every perception and
/// reasoning role; what `aeris bench cycle` and `aeris bench swap` fly.
pub const MODELS_WORKFLOW_TOML: &str = include_str!("../../../workflows/models.toml");

impl Workflow {
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
    use aeris_schemas::topics;

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
}
