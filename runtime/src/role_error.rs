//! Why a role failed: [`RoleError`], and [`ConfigError`] for a configuration the role
//! cannot use (its parameters, its variant, its mission, what they configure).

use crate::bus::{BusError, Cause};

/// Why a role failed. Roles map their own failures into one of these.
#[derive(Debug, thiserror::Error)]
pub enum RoleError {
    /// A transport operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The role's configuration is unusable; the source says what in it.
    #[error("invalid configuration")]
    Config(#[from] ConfigError),
    /// A step of the role failed for a cause of its own (a model that would not load, a
    /// frame a model refused): `what` says which step, the source says why.
    #[error("{what}")]
    Step {
        /// The step that failed, e.g. "loading the PP-OCR reader".
        what: String,
        /// Why it failed.
        source: Cause,
    },
}

impl RoleError {
    /// `what` failed because of `source` (see [`RoleError::Step`]).
    pub fn step(what: impl Into<String>, source: impl Into<Cause>) -> Self {
        RoleError::Step {
            what: what.into(),
            source: source.into(),
        }
    }

    /// Parameter `param` is missing or unusable: `problem` says how (see
    /// [`ConfigError::Param`]).
    pub fn param(param: impl Into<String>, problem: impl Into<String>) -> Self {
        ConfigError::Param {
            param: param.into(),
            problem: problem.into(),
        }
        .into()
    }
}

/// What is wrong with a role's configuration.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A parameter is missing, of the wrong type, or out of range.
    #[error("param `{param}` {problem}")]
    Param {
        /// The parameter (`params.{param}` of the role's spec).
        param: String,
        /// What is wrong with it, e.g. "must be a positive number, got -1".
        problem: String,
    },
    /// A field of the flight's spec outside the role's params (`camera.fps`,
    /// `timing.control_rate_hz`) that this role cannot work with.
    #[error("`{field}` {problem}")]
    Spec {
        /// The field, e.g. `camera.fps`.
        field: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// A parameter's value was refused by what it configures (a pipeline that does not
    /// parse, a key file that does not load).
    #[error("param `{param}`")]
    ParamRefused {
        /// The parameter.
        param: String,
        /// Why its value was refused.
        source: Cause,
    },
    /// This build has no such variant of the role's kind.
    #[error("no role kind `{kind}` with variant `{variant}` in this build (see `aeris roles`)")]
    UnknownVariant {
        /// The role's kind.
        kind: aeris_schemas::RoleKind,
        /// The variant asked for.
        variant: String,
    },
    /// The variant's model is not among the provisioned ones.
    #[error("no model for variant `{0}`")]
    NoModel(String),
    /// The variant needs model weights that do not exist here; the text says which and how
    /// to supply them.
    #[error("{0}")]
    NoWeights(&'static str),
    /// The mission is one this role cannot fly: the text completes "the mission ...".
    #[error("the mission {0}")]
    Mission(String),
    /// A component built from the configuration refused it: `what` names the component.
    #[error("{what}")]
    Refused {
        /// What refused, e.g. "the hub's gate".
        what: String,
        /// Why.
        source: Cause,
    },
}

impl ConfigError {
    /// `what`, built from the configuration, refused it because of `source`.
    pub fn refused(what: impl Into<String>, source: impl Into<Cause>) -> Self {
        ConfigError::Refused {
            what: what.into(),
            source: source.into(),
        }
    }

    /// Parameter `param`'s value was refused because of `source`.
    pub fn param_refused(param: impl Into<String>, source: impl Into<Cause>) -> Self {
        ConfigError::ParamRefused {
            param: param.into(),
            source: source.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_chain::chain;

    #[test]
    fn a_configuration_error_prints_what_is_wrong_once_after_invalid_configuration() {
        let e = RoleError::param("stall_ms", "must be a positive number, got -1");
        assert_eq!(
            chain(&e).to_string(),
            "invalid configuration: param `stall_ms` must be a positive number, got -1"
        );
        let io = std::io::Error::other("no such element `foo`");
        let e: RoleError = ConfigError::param_refused("pipeline", io).into();
        assert_eq!(
            chain(&e).to_string(),
            "invalid configuration: param `pipeline`: no such element `foo`"
        );
        assert!(matches!(
            e,
            RoleError::Config(ConfigError::ParamRefused { ref param, .. }) if param == "pipeline"
        ));
    }
}
