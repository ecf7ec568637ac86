//! Changes to a workflow for one flight: other variants, another time limit, dynamic
//! scheduling or the variant ladder off (what `aeris run --variant ... --max-duration ...
//! --no-ds --fixed-variants` asks).

use aeris_orchestrator::workflow::{Workflow, WorkflowError};
use std::str::FromStr;

/// One role run with another variant of its kind.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VariantChoice {
    /// Role name (as the workflow declares it).
    pub role: String,
    /// The variant it runs.
    pub variant: String,
}

impl FromStr for VariantChoice {
    type Err = OverrideError;

    /// `ROLE=VARIANT`, e.g. `reasoning=garbage`.
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let Some((role, variant)) = text.split_once('=') else {
            return Err(OverrideError::Syntax {
                given: text.to_string(),
            });
        };
        Ok(Self {
            role: role.to_string(),
            variant: variant.to_string(),
        })
    }
}

/// What a flight changes in its workflow.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// Roles run with another variant of their kind.
    pub variants: Vec<VariantChoice>,
    /// The mission's time limit (s), counted once every role is up; `None` keeps the
    /// mission's `max_duration_s`.
    pub max_duration_s: Option<f64>,
    /// Dynamic scheduling: `Some(false)` turns the workflow's `[scheduling] dynamic` off,
    /// `Some(true)` on, `None` keeps it. Applied to the supervisor once it started.
    pub dynamic: Option<bool>,
    /// The variant ladder off: every role keeps its declared variant whatever its latency
    /// (`[scheduling] adapt_variants = false`).
    pub fixed_variants: bool,
}

/// Why overrides could not be applied.
#[derive(Debug, thiserror::Error)]
pub enum OverrideError {
    /// A variant choice is not `ROLE=VARIANT`.
    #[error("expects ROLE=VARIANT, got `{given}`")]
    Syntax {
        /// The text given.
        given: String,
    },
    /// A variant choice names a role the workflow does not have.
    #[error("the workflow has no role `{role}`")]
    UnknownRole {
        /// The role named.
        role: String,
    },
    /// The time limit is not a positive number of seconds.
    #[error("the time limit must be a positive number of seconds, got {given}")]
    MaxDuration {
        /// The limit given.
        given: f64,
    },
    /// The workflow with the overrides is not valid (e.g. a variant its kind does not have).
    #[error("invalid workflow")]
    Invalid(#[source] WorkflowError),
}

impl Overrides {
    /// Apply the workflow part of the overrides (variants, time limit, variant ladder) and
    /// validate the result. [`Overrides::dynamic`] is for the supervisor, not the workflow.
    pub fn apply(&self, workflow: &mut Workflow) -> Result<(), OverrideError> {
        for VariantChoice { role, variant } in &self.variants {
            let decl = workflow
                .roles
                .iter_mut()
                .find(|r| r.name == *role)
                .ok_or_else(|| OverrideError::UnknownRole { role: role.clone() })?;
            decl.variant = variant.clone();
            if !decl.variants.iter().any(|x| x == variant) {
                decl.variants.push(variant.clone());
            }
            // a variant chosen by hand off the role's ladder: the role keeps it
            if !decl.ladder.iter().any(|x| x == variant) {
                decl.ladder.clear();
            }
        }
        if let Some(s) = self.max_duration_s {
            if !(s > 0.0 && s.is_finite()) {
                return Err(OverrideError::MaxDuration { given: s });
            }
            workflow.mission.max_duration_s = s;
        }
        if self.fixed_variants {
            workflow.scheduling.adapt_variants = false;
        }
        workflow.validate().map_err(OverrideError::Invalid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn choice(text: &str) -> VariantChoice {
        text.parse().unwrap()
    }

    #[test]
    fn a_variant_choice_is_role_equals_variant() {
        assert_eq!(
            choice("reasoning=garbage"),
            VariantChoice {
                role: "reasoning".into(),
                variant: "garbage".into()
            }
        );
        assert!(matches!(
            "reasoning".parse::<VariantChoice>(),
            Err(OverrideError::Syntax { given }) if given == "reasoning"
        ));
    }

    #[test]
    fn overrides_change_the_variant_the_limit_and_the_ladder() {
        let mut w = Workflow::builtin_default().unwrap();
        let o = Overrides {
            variants: vec![choice("reasoning=garbage")],
            max_duration_s: Some(12.5),
            dynamic: None,
            fixed_variants: true,
        };
        o.apply(&mut w).unwrap();
        let r = w.roles.iter().find(|r| r.name == "reasoning").unwrap();
        assert_eq!(r.variant, "garbage");
        assert!(r.variants.iter().any(|v| v == "garbage"));
        assert_eq!(w.mission.max_duration_s, 12.5);
        assert!(!w.scheduling.adapt_variants);
    }

    #[test]
    fn bad_overrides_name_what_is_wrong() {
        let mut w = Workflow::builtin_default().unwrap();
        let unknown = Overrides {
            variants: vec![choice("nobody=planner")],
            ..Overrides::default()
        };
        assert!(matches!(
            unknown.apply(&mut w),
            Err(OverrideError::UnknownRole { role }) if role == "nobody"
        ));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let o = Overrides {
                max_duration_s: Some(bad),
                ..Overrides::default()
            };
            assert!(matches!(
                o.apply(&mut w),
                Err(OverrideError::MaxDuration { .. })
            ));
        }
        let invalid = Overrides {
            variants: vec![choice("reasoning=gpt-9")],
            ..Overrides::default()
        };
        assert!(matches!(
            invalid.apply(&mut w),
            Err(OverrideError::Invalid(_))
        ));
    }
}
