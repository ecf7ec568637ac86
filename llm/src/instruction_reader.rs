//! A GGUF model in llama.cpp that reads instructions (issue 37, item 4): it segments an
//! unannotated instruction into steps ([`crate::segment`]) and reads each step's turn,
//! relation, landmark, sign and height ([`crate::read_step`]), each under a grammar made
//! for that text, by greedy decoding. One model, loaded once, does both.

use crate::decode::{
    BATCH, GenerateStop, chat_prompt, eval_tokens, generate_under_grammar, load_cpu_model,
    reuse_prefix,
};
use crate::error::LlmError;
use crate::read_step::{
    self, MAX_READING_TOKENS, ReadStepError, reading_from_json, reading_grammar,
};
use crate::segment::{
    self, MAX_SEGMENTATION_TOKENS, Segment, SegmentError, instruction_words, segment_grammar,
    segments_from_json,
};
use aeris_models::ModelStore;
use aeris_schemas::StepReading;
use llama_cpp_2::context::LlamaContext;
use llama_cpp_2::llama_batch::LlamaBatch;
use llama_cpp_2::model::LlamaModel;
use llama_cpp_2::sampling::LlamaSampler;
use llama_cpp_2::token::LlamaToken;
use std::time::Instant;

/// Context length: the examples, the instruction, and its segmentation (every word again).
const CONTEXT_TOKENS: u32 = 4096;

/// What one segmentation or reading cost.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReadStats {
    /// Tokens in the prompt.
    pub prompt_tokens: usize,
    /// Of them, tokens whose KV entries the previous prompt left (not evaluated again).
    pub reused_tokens: usize,
    /// Tokens generated.
    pub generated_tokens: usize,
    /// Seconds the whole call took (prompt and generation).
    pub seconds: f64,
}

/// Where a greedy generation under a grammar stopped, before the caller names its error.
enum Stop {
    Prompt(LlmError),
    Generate(GenerateStop),
}

/// A language model that segments instructions and reads their steps.
pub struct InstructionReader {
    // Field order matters: the context borrows the model and must drop first.
    ctx: LlamaContext<'static>,
    model: &'static LlamaModel,
    batch: LlamaBatch<'static>,
    /// The last prompt's tokens, whose KV entries the context holds.
    cached: Vec<LlamaToken>,
    last: ReadStats,
}

impl InstructionReader {
    /// Load `file` (cache-relative, hash-checked), evaluating on `threads` CPU threads.
    pub fn load(store: &ModelStore, file: &str, threads: i32) -> Result<Self, LlmError> {
        let (model, ctx) = load_cpu_model(store, file, threads, CONTEXT_TOKENS)?;
        Ok(Self {
            ctx,
            model,
            batch: LlamaBatch::new(BATCH, 1),
            cached: Vec::new(),
            last: ReadStats::default(),
        })
    }

    /// What the last segmentation or reading cost.
    pub fn last_stats(&self) -> ReadStats {
        self.last
    }

    /// The steps of `instruction`, by greedy decoding under its [`segment_grammar`].
    pub fn segment(&mut self, instruction: &str) -> Result<Vec<Segment>, SegmentError> {
        let words = instruction_words(instruction);
        let grammar = segment_grammar(&words)?;
        let user = format!("Instruction: {}", words.join(" "));
        // `"}]` ends the list and appears nowhere else in it (words hold no quote)
        let text = self
            .generate(
                segment::SYSTEM,
                user,
                &grammar,
                MAX_SEGMENTATION_TOKENS,
                b"\"}]",
            )
            .map_err(|stop| match stop {
                Stop::Prompt(e) => e.into(),
                Stop::Generate(GenerateStop::Truncated(n)) => SegmentError::Truncated(n),
                Stop::Generate(GenerateStop::NoAllowedToken) => {
                    LlmError::NoAllowedToken { field: "segment" }.into()
                }
                Stop::Generate(GenerateStop::Decode(e)) => e.into(),
            })?;
        segments_from_json(&text, &words)
    }

    /// What `step` asks for, its landmark one of `landmarks` (perception's labels), by
    /// greedy decoding under its [`reading_grammar`].
    pub fn read_step(
        &mut self,
        step: &str,
        landmarks: &[&str],
    ) -> Result<StepReading, ReadStepError> {
        let grammar = reading_grammar(step, landmarks)?;
        let user = read_step::user_message(step, landmarks);
        // the reading ends with its height: a number or null, then `}`
        let text = self
            .generate(read_step::SYSTEM, user, &grammar, MAX_READING_TOKENS, b"}")
            .map_err(|stop| match stop {
                Stop::Prompt(e) => e.into(),
                Stop::Generate(GenerateStop::Truncated(n)) => ReadStepError::Truncated(n),
                Stop::Generate(GenerateStop::NoAllowedToken) => {
                    LlmError::NoAllowedToken { field: "reading" }.into()
                }
                Stop::Generate(GenerateStop::Decode(e)) => e.into(),
            })?;
        reading_from_json(&text, step, landmarks)
    }

    /// Greedy decoding of the answer to `system` and `user` under `grammar`, until the
    /// output ends with `end`, within `max_tokens`; the prompt's prefix shared with the last
    /// call is not evaluated again.
    fn generate(
        &mut self,
        system: &str,
        user: String,
        grammar: &str,
        max_tokens: usize,
        end: &[u8],
    ) -> Result<String, Stop> {
        let started = Instant::now();
        let mut sampler = LlamaSampler::grammar(self.model, grammar, "root")
            .map_err(|e| Stop::Prompt(LlmError::GrammarRejected(e.to_string())))?;
        let prompt = chat_prompt(self.model, system, user).map_err(Stop::Prompt)?;
        let tokens = self.model.vocab().tokenize(prompt.as_bytes(), false, true);
        let context = self.ctx.n_ctx() as usize;
        if tokens.len() + max_tokens >= context {
            return Err(Stop::Prompt(LlmError::PromptTooLong {
                tokens: tokens.len(),
                context,
            }));
        }
        let reused = reuse_prefix(&mut self.ctx, &self.cached, &tokens);
        self.cached.clear();
        eval_tokens(&mut self.ctx, &mut self.batch, &tokens[reused..], reused)
            .map_err(Stop::Prompt)?;
        self.cached.extend_from_slice(&tokens);
        let (bytes, generated, outcome) = generate_under_grammar(
            &mut self.ctx,
            &mut self.batch,
            self.model,
            &mut sampler,
            tokens.len(),
            max_tokens,
            end,
        );
        // the generated tokens' KV entries follow the prompt: the next call drops them
        self.last = ReadStats {
            prompt_tokens: tokens.len(),
            reused_tokens: reused,
            generated_tokens: generated,
            seconds: started.elapsed().as_secs_f64(),
        };
        outcome.map_err(Stop::Generate)?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }
}
