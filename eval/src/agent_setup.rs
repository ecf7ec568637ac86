//! Who flies an evaluation and how (`aeris eval --baseline --reasoning --perception
//! --aligned ...` and the ablations), resolved and checked before anything flies.

use crate::mission::Agent;

/// Who flies and how, as asked (`aeris eval --baseline --reasoning --perception ...`).
#[derive(Debug, Clone, Default)]
pub struct AgentOptions {
    /// A baseline instead of AERIS: `oracle` or `random`.
    pub baseline: Option<String>,
    /// Reasoning variant of the AERIS agent: `planner` (default), `smollm2` or `gemma3`.
    pub reasoning: Option<String>,
    /// Perception of the AERIS agent: `models` (default) or `geometric`.
    pub perception: Option<String>,
    /// Ablation: the hub's ATT off.
    pub no_att: bool,
    /// Ablation: the language model without the planner's plan in its prompt.
    pub zero_shot: bool,
    /// Ablation: the variant ladder off (one fixed model).
    pub single_slm: bool,
    /// Ablation: dynamic scheduling off.
    pub no_ds: bool,
    /// The language model reads the task-aligned prompt (`aeris_llm::aligned_prompt`: no
    /// plan, sightings on the ground).
    pub aligned: bool,
}

/// Who flies and how, resolved.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AgentSetup {
    /// The agent.
    pub agent: Agent,
    /// Reasoning variant of the flights.
    pub reasoning: String,
    /// The hub's ATT off.
    pub no_att: bool,
    /// The language model without the planner's plan.
    pub zero_shot: bool,
    /// Dynamic scheduling off in every flight.
    pub no_ds: bool,
    /// The variant ladder off in every flight (Single-SLM).
    pub single_slm: bool,
    /// Fly with the model perception roles (else the geometric one).
    pub models: bool,
    /// The language model reads the task-aligned prompt.
    pub aligned: bool,
    /// `aeris-planner`, `aeris-smollm2-zero-shot`, `oracle`, ...: the `agent` of
    /// episodes.jsonl and the default output folder's suffix.
    pub label: String,
}

/// Why the agent options do not make an agent.
#[derive(Debug, thiserror::Error)]
pub enum AgentError {
    /// The baseline is not one this evaluation has.
    #[error("unknown baseline `{0}`: use oracle or random")]
    UnknownBaseline(String),
    /// AERIS-only options given with a baseline.
    #[error(
        "--reasoning, --perception, --aligned, --no-att, --no-ds, --single-slm and --zero-shot apply to the AERIS agent, not to a --baseline"
    )]
    BaselineWithAerisOptions,
    /// The perception is not one this evaluation has.
    #[error("unknown perception `{0}`: use models or geometric")]
    UnknownPerception(String),
    /// The reasoning variant is not one this evaluation has.
    #[error("unknown reasoning variant `{0}`: use planner, smollm2, gemma3 or smollm2-aligned")]
    UnknownReasoning(String),
    /// The aligned prompt asked of a reasoner that is not a language model.
    #[error("--aligned is a language model's prompt: use --reasoning smollm2 or gemma3")]
    AlignedWithoutLanguageModel,
    /// Zero-shot and aligned together.
    #[error("--zero-shot and --aligned are two prompts: choose one")]
    AlignedZeroShot,
    /// Zero-shot asked of a reasoner that is not a language model.
    #[error("--zero-shot ablates the language model's plan: use --reasoning smollm2 or gemma3")]
    ZeroShotWithoutLanguageModel,
}

impl AgentSetup {
    /// Resolve `options` into an agent (defaults filled in, combinations checked).
    pub fn resolve(options: &AgentOptions) -> Result<Self, AgentError> {
        let agent = match &options.baseline {
            None => Agent::Aeris,
            Some(name) => match Agent::parse(name) {
                Some(a @ (Agent::Oracle | Agent::Random)) => a,
                _ => return Err(AgentError::UnknownBaseline(name.clone())),
            },
        };
        if agent != Agent::Aeris
            && (options.reasoning.is_some()
                || options.no_att
                || options.zero_shot
                || options.no_ds
                || options.single_slm
                || options.aligned
                || options.perception.is_some())
        {
            return Err(AgentError::BaselineWithAerisOptions);
        }
        let models = match options.perception.as_deref() {
            None => agent == Agent::Aeris,
            Some("models") => true,
            Some("geometric") => false,
            Some(other) => return Err(AgentError::UnknownPerception(other.to_string())),
        };
        let reasoning = match (&options.reasoning, options.zero_shot) {
            (Some(r), _) => r.clone(),
            (None, true) => "smollm2".to_string(),
            (None, false) => agent.reasoning_variant().to_string(),
        };
        let language = aeris_orchestrator::workflow::LANGUAGE_MODEL_VARIANTS
            .contains(&(aeris_schemas::RoleKind::Reasoning, reasoning.as_str()));
        // a variant with its adapter reads the aligned prompt whatever is asked
        let aligned_variant = reasoning.ends_with("-aligned");
        if agent == Agent::Aeris && !(language || reasoning == "planner") {
            return Err(AgentError::UnknownReasoning(reasoning));
        }
        if options.zero_shot && !language {
            return Err(AgentError::ZeroShotWithoutLanguageModel);
        }
        if options.aligned && !language {
            return Err(AgentError::AlignedWithoutLanguageModel);
        }
        if (options.aligned || aligned_variant) && options.zero_shot {
            return Err(AgentError::AlignedZeroShot);
        }
        let label = match agent {
            Agent::Aeris => {
                let mut l = format!("aeris-{reasoning}");
                if options.aligned && !aligned_variant {
                    l.push_str("-aligned");
                }
                if !models {
                    l.push_str("-geometric");
                }
                if options.no_att {
                    l.push_str("-no-att");
                }
                if options.zero_shot {
                    l.push_str("-zero-shot");
                }
                if options.no_ds {
                    l.push_str("-no-ds");
                }
                if options.single_slm {
                    l.push_str("-single-slm");
                }
                l
            }
            a => a.as_str().to_string(),
        };
        Ok(Self {
            agent,
            reasoning,
            no_att: options.no_att,
            zero_shot: options.zero_shot,
            no_ds: options.no_ds,
            single_slm: options.single_slm,
            models,
            aligned: options.aligned || aligned_variant,
            label,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resolve(options: AgentOptions) -> Result<AgentSetup, AgentError> {
        AgentSetup::resolve(&options)
    }

    #[test]
    fn the_agent_label_names_the_reasoner_perception_and_ablations() {
        let aeris = resolve(AgentOptions::default()).unwrap();
        assert_eq!(
            (aeris.agent, aeris.label.as_str(), aeris.models),
            (Agent::Aeris, "aeris-planner", true)
        );
        let ablated = resolve(AgentOptions {
            perception: Some("geometric".into()),
            zero_shot: true,
            no_att: true,
            no_ds: true,
            single_slm: true,
            ..AgentOptions::default()
        })
        .unwrap();
        assert_eq!(ablated.reasoning, "smollm2");
        assert_eq!(
            ablated.label,
            "aeris-smollm2-geometric-no-att-zero-shot-no-ds-single-slm"
        );
        let oracle = resolve(AgentOptions {
            baseline: Some("oracle".into()),
            ..AgentOptions::default()
        })
        .unwrap();
        assert_eq!((oracle.label.as_str(), oracle.models), ("oracle", false));
    }

    #[test]
    fn agent_options_that_do_not_fit_are_refused() {
        let with = |o: AgentOptions| resolve(o).unwrap_err();
        assert!(matches!(
            with(AgentOptions {
                baseline: Some("psychic".into()),
                ..AgentOptions::default()
            }),
            AgentError::UnknownBaseline(b) if b == "psychic"
        ));
        assert!(matches!(
            with(AgentOptions {
                baseline: Some("random".into()),
                no_att: true,
                ..AgentOptions::default()
            }),
            AgentError::BaselineWithAerisOptions
        ));
        assert!(matches!(
            with(AgentOptions {
                reasoning: Some("oracle".into()),
                ..AgentOptions::default()
            }),
            AgentError::UnknownReasoning(r) if r == "oracle"
        ));
        assert!(matches!(
            with(AgentOptions {
                perception: Some("telepathy".into()),
                ..AgentOptions::default()
            }),
            AgentError::UnknownPerception(_)
        ));
        assert!(matches!(
            with(AgentOptions {
                reasoning: Some("planner".into()),
                zero_shot: true,
                ..AgentOptions::default()
            }),
            AgentError::ZeroShotWithoutLanguageModel
        ));
        assert!(matches!(
            with(AgentOptions {
                aligned: true,
                ..AgentOptions::default()
            }),
            AgentError::AlignedWithoutLanguageModel
        ));
        assert!(matches!(
            with(AgentOptions {
                reasoning: Some("gemma3".into()),
                aligned: true,
                zero_shot: true,
                ..AgentOptions::default()
            }),
            AgentError::AlignedZeroShot
        ));
    }
}
