//! Which prompt a language-model reasoner reads: the generic models' ([`crate::prompt`])
//! or the task-aligned models' ([`crate::aligned_prompt`]).

use crate::prompt::{MissionBrief, Observation, system_message, user_message};

/// Which prompt a reasoner reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PromptStyle {
    /// The generic models' prompt ([`system_message`], [`user_message`]): a preamble, and
    /// the planner's plan when the observation carries one.
    #[default]
    Planned,
    /// The task-aligned models' prompt ([`crate::aligned_prompt`]): short, never a plan, the
    /// sightings placed on the ground. Training pairs are written in it.
    Aligned,
}

impl PromptStyle {
    /// The style named `name` (`planned`, `aligned`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "planned" => Some(Self::Planned),
            "aligned" => Some(Self::Aligned),
            _ => None,
        }
    }

    /// The system and user messages for `obs` in this style.
    pub fn messages(self, mission: &MissionBrief, obs: &Observation<'_>) -> (&'static str, String) {
        match self {
            Self::Planned => (system_message(), user_message(mission, obs)),
            Self::Aligned => (
                crate::aligned_prompt::aligned_system_message(),
                crate::aligned_prompt::aligned_user_message(mission, obs),
            ),
        }
    }
}
