//! The formation role's program writers: its variant, the parser or a language model.

use aeris_formation::{ParserWriter, Problem, ProgramWriter};
use aeris_schemas::{FormationLimits, FormationProgram};

/// Who writes the formation's programs: the variant.
pub(super) enum Writer {
    Parser(ParserWriter),
    Model(Box<aeris_llm::FormationWriter>),
}

/// Why a variant wrote no program.
#[derive(Debug, thiserror::Error)]
pub(super) enum WriteError {
    #[error(transparent)]
    Parse(#[from] aeris_formation::ParseError),
    #[error(transparent)]
    Model(#[from] aeris_llm::LlmError),
}

impl ProgramWriter for Writer {
    type Error = WriteError;

    fn name(&self) -> &str {
        match self {
            Self::Parser(w) => w.name(),
            Self::Model(w) => w.name(),
        }
    }

    fn write(
        &mut self,
        instruction: &str,
        limits: &FormationLimits,
    ) -> Result<FormationProgram, WriteError> {
        Ok(match self {
            Self::Parser(w) => w.write(instruction, limits)?,
            Self::Model(w) => w.write(instruction, limits)?,
        })
    }

    fn repair(
        &mut self,
        instruction: &str,
        program: &FormationProgram,
        problem: &Problem,
        limits: &FormationLimits,
    ) -> Option<FormationProgram> {
        match self {
            Self::Parser(w) => w.repair(instruction, program, problem, limits),
            Self::Model(w) => w.repair(instruction, program, problem, limits),
        }
    }
}
