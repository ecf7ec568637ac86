//! Language-model reasoning for AERIS (MISSION §4): a small GGUF language model, run by
//! llama.cpp, turns the typed state S_t, the mission G and a short memory M_{t-1} into a
//! decision D_t.
//!
//! Decoding is constrained by a grammar generated from D_t's schema and the flight's limits
//! ([`grammar::decision_grammar`]), so every output parses and passes Valid(D_t); the hub
//! validates again. The prompt puts the mission first so its KV-cache entries are reused from
//! one heartbeat to the next ([`LanguageReasoner`]).

pub mod aligned_prompt;
mod decode;
mod error;
pub mod formation;
pub mod grammar;
pub mod instruction_reader;
pub mod prompt;
pub mod prompt_style;
pub mod read_step;
pub mod reasoner;
pub mod segment;
pub mod view;

pub use aligned_prompt::{aligned_system_message, aligned_user_message};
pub use formation::{
    FormationWriter, WriteStats, program_from_json, program_grammar, program_to_json,
};
pub use grammar::{GrammarError, decision_grammar};
pub use instruction_reader::{InstructionReader, ReadStats};
pub use prompt::{MissionBrief, Observation, Sighted, StepBrief, sanitize};
pub use prompt_style::PromptStyle;
pub use read_step::ReadStepError;
pub use reasoner::{
    GEMMA3_270M, GPU_OFFLOAD_BUILT, LanguageReasoner, LlmError, QWEN25_CODER_05B, ReasonerConfig,
    SMOLLM2_135M, SMOLLM2_135M_Q4_1, SMOLLM2_ALIGNED_ADAPTER, Thought, check_offload,
    offload_check, variant_adapter, variant_model,
};
pub use segment::{Segment, SegmentError};
pub use view::{DecisionView, ViewError};
