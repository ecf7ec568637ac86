//! [`LanguageReasoner`]: one GGUF model in llama.cpp, a context whose KV cache keeps the
//! prompt prefix between heartbeats, and grammar-constrained greedy decoding.

use crate::decode::{
    BATCH, backend, chat_prompt, eval_tokens, flash_attention, greedy_allowed, reuse_prefix,
};
pub use crate::error::LlmError;
use crate::grammar::{FieldGrammar, decision_grammar, field_grammars};
use crate::prompt::{MissionBrief, Observation};
use crate::prompt_style::PromptStyle;
use crate::view::{DecisionView, ViewError};
use aeris_models::ModelStore;
use aeris_schemas::Decision;
use aeris_schemas::accelerator::{Accelerator, AcceleratorKind};
use llama_cpp_2::context::LlamaContext;
use llama_cpp_2::context::params::LlamaContextParams;
use llama_cpp_2::llama_backend::LlamaBackend;
use llama_cpp_2::llama_batch::LlamaBatch;
use llama_cpp_2::model::params::{LlamaModelParams, LlamaSplitMode};
use llama_cpp_2::model::{LlamaLoraAdapter, LlamaModel};
use llama_cpp_2::sampling::LlamaSampler;
use llama_cpp_2::token::LlamaToken;
use llama_cpp_2::token::data::LlamaTokenData;
use llama_cpp_2::token::data_array::LlamaTokenDataArray;
use std::num::NonZeroU32;
use std::time::Instant;

/// SmolLM2-135M-Instruct, the registry's Q4_1 weights re-encoded as Q8_0 at provisioning
/// (`scripts/models/requantize_gguf.py`): llama.cpp's batch kernels cover Q8_0, not Q4_1
/// (the default language-model variant).
pub const SMOLLM2_135M: &str = "llm/smollm2-135m-instruct-q8_0.gguf";
/// SmolLM2-135M-Instruct as the registry ships it (Q4_1): smaller, slower in batches.
pub const SMOLLM2_135M_Q4_1: &str = "llm/smollm2-135m-instruct-q4_1.gguf";
/// Gemma-3-270M, Q4_K_M.
pub const GEMMA3_270M: &str = "llm/gemma-3-270m-q4_k_m.gguf";

/// Qwen2.5-Coder-0.5B-Instruct, Q4_K_M.
pub const QWEN25_CODER_05B: &str = "llm/qwen2.5-coder-0.5b-instruct-q4_k_m.gguf";

/// The default model file of a language-model variant (`smollm2`, `gemma3`, `qwen-coder`).
pub fn variant_model(variant: &str) -> Option<&'static str> {
    match variant {
        "smollm2" => Some(SMOLLM2_135M),
        "gemma3" => Some(GEMMA3_270M),
        "qwen-coder" => Some(QWEN25_CODER_05B),
        "smollm2-aligned" => Some(SMOLLM2_135M),
        _ => None,
    }
}

/// SmolLM2-135M's task-aligned LoRA adapter (`adapters/smollm2-aligned/`, trained by
/// `scripts/train-reasoner.sh` on `aeris distill` pairs; provisioned into the cache).
pub const SMOLLM2_ALIGNED_ADAPTER: &str = "adapters/smollm2-aligned.gguf";

/// The adapter an aligned variant loads on its base, and the prompt it reads: `None` for
/// the generic models (the planned prompt).
pub fn variant_adapter(variant: &str) -> Option<&'static str> {
    match variant {
        "smollm2-aligned" => Some(SMOLLM2_ALIGNED_ADAPTER),
        _ => None,
    }
}

/// Fields of the first verification batch: the semantic choice (step, action). A batch
/// costs about its length in tokens plus a fixed overhead per evaluation, and a departure
/// from the draft wastes the rest of its batch. A model that departs from the plan does so
/// at the step or the action, so those are verified first, the numbers in a second batch.
const FIRST_BATCH_FIELDS: usize = 2;

/// How the reasoner runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReasonerConfig {
    /// CPU threads for evaluation.
    pub threads: i32,
    /// Context length in tokens.
    pub context_tokens: u32,
    /// Most tokens one decision may take.
    pub max_output_tokens: usize,
    /// Verify the plan (or the previous decision) as a draft in one batch instead of
    /// evaluating every token (same output; off only to measure what it saves).
    pub draft: bool,
    /// Offload every layer to this CUDA device (`None`: the CPU only).
    pub accelerator: Option<Accelerator>,
    /// The prompt the model reads.
    pub prompt: PromptStyle,
}

impl Default for ReasonerConfig {
    fn default() -> Self {
        Self {
            threads: 2,
            context_tokens: 2048,
            max_output_tokens: 120,
            draft: true,
            accelerator: None,
            prompt: PromptStyle::Planned,
        }
    }
}

/// Whether this build's llama.cpp can offload layers to a GPU (the cargo feature `cuda`).
pub const GPU_OFFLOAD_BUILT: bool = cfg!(feature = "cuda");

/// Why a language model cannot be offloaded to `accelerator` by this build, checked without
/// loading llama.cpp: the kind (CUDA only) and the build (feature `cuda`). Whether a device is
/// present is only known when the role loads its model ([`LlmError::OffloadUnavailable`]).
pub fn check_offload(accelerator: Accelerator) -> Result<(), LlmError> {
    if accelerator.kind != AcceleratorKind::Cuda {
        return Err(LlmError::OffloadKind(accelerator));
    }
    if !GPU_OFFLOAD_BUILT {
        return Err(LlmError::OffloadNotBuilt(accelerator));
    }
    Ok(())
}

/// [`check_offload`] with its error boxed: the shape of a flight's offload check
/// (`aeris_flight::executors::OffloadCheck`), which the binary hands to its flights so that
/// the flight library does not link llama.cpp.
pub fn offload_check(
    accelerator: Accelerator,
) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    Ok(check_offload(accelerator)?)
}

/// The model's load parameters: every layer on the accelerator's device, or none
/// ([`crate::decode::cpu_model_params`]).
pub(crate) fn model_params(
    backend: &LlamaBackend,
    accelerator: Option<Accelerator>,
) -> Result<LlamaModelParams, LlmError> {
    let Some(accelerator) = accelerator else {
        return Ok(crate::decode::cpu_model_params());
    };
    let params = LlamaModelParams::default();
    check_offload(accelerator)?;
    if !backend.supports_gpu_offload() {
        return Err(LlmError::OffloadUnavailable(accelerator));
    }
    Ok(params
        .with_n_gpu_layers(u32::MAX)
        .with_split_mode(LlamaSplitMode::None)
        .with_main_gpu(i32::try_from(accelerator.device).unwrap_or(i32::MAX)))
}

/// One decision and what it cost.
#[derive(Debug, Clone)]
pub struct Thought {
    /// The decision (routing fields at defaults: the role fills them).
    pub decision: Decision,
    /// Its view, as the model wrote it (memory for the next prompt).
    pub view: DecisionView,
    /// The raw output text.
    pub text: String,
    /// Tokens in the prompt.
    pub prompt_tokens: usize,
    /// Prompt tokens whose KV entries were reused from the previous cycle.
    pub reused_tokens: usize,
    /// Tokens generated.
    pub generated_tokens: usize,
    /// Generated tokens that were the draft's, verified in a batch instead of one
    /// evaluation each.
    pub drafted_tokens: usize,
    /// Seconds spent evaluating the new prompt tokens.
    pub prompt_s: f64,
    /// Seconds spent generating.
    pub generate_s: f64,
    /// Tokens that needed the whole-vocabulary grammar filter.
    pub full_filter_tokens: usize,
    /// Seconds of `generate_s` spent choosing tokens under the grammar (the rest is
    /// evaluation).
    pub sample_s: f64,
}

impl Thought {
    /// Generation speed in tokens per second.
    pub fn tokens_per_s(&self) -> f64 {
        if self.generate_s > 0.0 {
            self.generated_tokens as f64 / self.generate_s
        } else {
            0.0
        }
    }
}

/// The state of one decision's generation.
struct Decoding {
    /// The text so far.
    bytes: Vec<u8>,
    /// Tokens chosen.
    generated: usize,
    /// Of which verified from the draft.
    drafted: usize,
    /// Tokens that needed the whole-vocabulary filter.
    full_filter: usize,
    /// Seconds choosing tokens.
    sample_s: f64,
    /// Next cache position.
    pos: usize,
    /// Chosen but not yet evaluated (a terminator, evaluated with the next key).
    pending: Vec<LlamaToken>,
}

/// How far a draft verification got.
enum Verified {
    /// Every field of the batch agreed with the draft; its last token is pending.
    All,
    /// The model's own token ended field `.0`; it is pending.
    FieldDone(usize),
    /// The model's own token is inside field `.0` and evaluated; sampling goes on there.
    Inside(usize),
}

/// One field's decoding state: its grammar sampler and its key's tokens.
struct FieldDecoder {
    spec: FieldGrammar,
    sampler: LlamaSampler,
    prefix_tokens: Vec<LlamaToken>,
}

/// A language model that turns (S_t, G, M_{t-1}) into decisions that always parse and lie
/// inside the limits of the mission it was built for.
pub struct LanguageReasoner {
    // Field order matters: the context borrows the model and uses the adapter, so it drops
    // first.
    ctx: LlamaContext<'static>,
    /// The LoRA adapter the context applies, if any (kept alive as long as the context).
    _adapter: Option<LlamaLoraAdapter>,
    model: &'static LlamaModel,
    fields: Vec<FieldDecoder>,
    whole: LlamaSampler,
    mission: MissionBrief,
    cached: Vec<LlamaToken>,
    batch: LlamaBatch<'static>,
    batch_capacity: usize,
    config: ReasonerConfig,
    file: String,
    load_s: f64,
}

impl LanguageReasoner {
    /// Load `file` (cache-relative, hash-checked) for `mission`.
    ///
    /// The model is kept for the life of the process (a reasoning role loads one model once;
    /// its memory goes back to the system when the process exits).
    pub fn load(
        store: &ModelStore,
        file: &str,
        mission: MissionBrief,
        config: ReasonerConfig,
    ) -> Result<Self, LlmError> {
        Self::load_adapted(store, file, None, mission, config)
    }

    /// Load `file` with the LoRA adapter `adapter` (both cache-relative, hash-checked)
    /// applied at full strength: a task-aligned model (`scripts/train-reasoner.sh`).
    pub fn load_adapted(
        store: &ModelStore,
        file: &str,
        adapter: Option<&str>,
        mission: MissionBrief,
        config: ReasonerConfig,
    ) -> Result<Self, LlmError> {
        let started = Instant::now();
        let path = store.verified(file)?;
        let adapter = adapter
            .map(|name| store.verified(name).map(|path| (name, path)))
            .transpose()?;
        let adapter_error = |name: &str, reason: String| LlmError::Adapter {
            file: name.to_string(),
            reason,
        };
        let backend = backend()?;
        let grammar_text = decision_grammar(&mission.limits)?;
        let model_params = model_params(backend, config.accelerator)?;
        let mut model = LlamaModel::load_from_file(backend, &path, &model_params).map_err(|e| {
            LlmError::Load {
                file: file.to_string(),
                reason: e.to_string(),
            }
        })?;
        // the adapter is made from the model before the model is leaked (it needs `&mut`)
        let mut lora = adapter
            .as_ref()
            .map(|(name, path)| {
                let lora = model
                    .lora_adapter_init(path)
                    .map_err(|e| adapter_error(name, e.to_string()))?;
                Ok::<_, LlmError>((*name, lora))
            })
            .transpose()?;
        let model: &'static LlamaModel = Box::leak(Box::new(model));
        let ctx_tokens = config.context_tokens.max(256);
        let params = LlamaContextParams::default()
            .with_n_ctx(NonZeroU32::new(ctx_tokens))
            .with_n_batch(BATCH as u32)
            .with_n_threads(config.threads.max(1))
            .with_n_threads_batch(config.threads.max(1))
            // the KV cache on the GPU only for a role bound to one (a CUDA build would put it
            // there for a role on a CPU set too)
            .with_offload_kqv(config.accelerator.is_some())
            .with_flash_attention_policy(flash_attention(config.accelerator.is_some()));
        let mut ctx = model
            .new_context(backend, params)
            .map_err(|e| LlmError::Load {
                file: file.to_string(),
                reason: e.to_string(),
            })?;
        if let Some((name, lora)) = lora.as_mut() {
            ctx.lora_adapter_set(lora, 1.0)
                .map_err(|e| adapter_error(name, e.to_string()))?;
        }
        let whole = LlamaSampler::grammar(model, &grammar_text, "root")
            .map_err(|e| LlmError::GrammarRejected(e.to_string()))?;
        let fields = field_grammars(&mission.limits)?
            .into_iter()
            .map(|spec| {
                let sampler = LlamaSampler::grammar(model, &spec.grammar, "root")
                    .map_err(|e| LlmError::GrammarRejected(format!("{}: {e}", spec.key)))?;
                let prefix_tokens = model.vocab().tokenize(spec.prefix.as_bytes(), false, false);
                Ok(FieldDecoder {
                    spec,
                    sampler,
                    prefix_tokens,
                })
            })
            .collect::<Result<Vec<_>, LlmError>>()?;
        Ok(Self {
            ctx,
            _adapter: lora.map(|(_, lora)| lora),
            model,
            fields,
            whole,
            mission,
            cached: Vec::new(),
            batch: LlamaBatch::new(BATCH, 1),
            batch_capacity: BATCH,
            config,
            file: file.to_string(),
            load_s: started.elapsed().as_secs_f64(),
        })
    }

    /// The cache-relative model file.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// Seconds the load took (hash check, weights, context).
    pub fn load_s(&self) -> f64 {
        self.load_s
    }

    /// llama.cpp's own timings since the last call (prompt ms, prompt tokens, eval ms, eval
    /// tokens), and resets them.
    pub fn take_timings(&mut self) -> (f64, i32, f64, i32) {
        let t = self.ctx.timings();
        self.ctx.reset_timings();
        (t.t_p_eval_ms(), t.n_p_eval(), t.t_eval_ms(), t.n_eval())
    }

    /// The mission this reasoner decides for.
    pub fn mission(&self) -> &MissionBrief {
        &self.mission
    }

    /// The full prompt text for an observation (chat template applied).
    pub fn prompt(&self, obs: &Observation<'_>) -> Result<String, LlmError> {
        let (system, user) = self.config.prompt.messages(&self.mission, obs);
        chat_prompt(self.model, system, user)
    }

    /// The chat template applied to `system` and `user`, as a decision's prompt is: what a
    /// training script must render the same way (`scripts/train_reasoner.py`).
    pub fn chat(&self, system: &str, user: &str) -> Result<String, LlmError> {
        chat_prompt(self.model, system, user.to_string())
    }

    /// `text`'s token ids, special tokens parsed (as a prompt is tokenized).
    pub fn tokenize(&self, text: &str) -> Vec<i32> {
        self.model
            .vocab()
            .tokenize(text.as_bytes(), false, true)
            .into_iter()
            .map(|t| t.0)
            .collect()
    }

    /// The next-token logits after the tokens `tokens`, evaluated from an empty cache: what
    /// a check of an adapter against another implementation compares. The next decision
    /// evaluates its prompt anew.
    pub fn logits_after(&mut self, tokens: &[i32]) -> Result<Vec<f32>, LlmError> {
        if tokens.is_empty() {
            return Err(LlmError::Decode("no tokens to evaluate".into()));
        }
        let tokens: Vec<LlamaToken> = tokens.iter().map(|&t| LlamaToken(t)).collect();
        self.ctx.clear_kv_cache();
        self.cached.clear();
        self.eval(&tokens, 0)?;
        let last = ((tokens.len() - 1) % BATCH) as i32;
        Ok(self.ctx.get_logits_ith(last).to_vec())
    }

    /// Make one decision.
    ///
    /// Greedy decoding under the decision grammar, field by field: each key is evaluated,
    /// not sampled. When the observation has a plan (or else a previous decision), its
    /// values are the draft: the remaining keys and draft values are evaluated in one batch
    /// and each draft token is kept while it is the token greedy decoding would have chosen;
    /// at the first that is not, the cache is cut back there and decoding goes on from the
    /// model's own token. The output is exactly that of plain greedy decoding; a decision
    /// that agrees with its draft costs one evaluation instead of one per token.
    pub fn decide(&mut self, obs: &Observation<'_>) -> Result<Thought, LlmError> {
        let prompt = self.prompt(obs)?;
        // The template already holds the special tokens; perception text was sanitised so
        // it cannot form any.
        let tokens = self.model.vocab().tokenize(prompt.as_bytes(), false, true);
        let context = self.ctx.n_ctx() as usize;
        if tokens.len() + 2 * self.config.max_output_tokens >= context {
            return Err(LlmError::PromptTooLong {
                tokens: tokens.len(),
                context,
            });
        }
        let t0 = Instant::now();
        let reused = self.reuse_prefix(&tokens);
        self.eval(&tokens[reused..], reused)?;
        self.cached.clear();
        self.cached.extend_from_slice(&tokens);
        let prompt_s = t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        let draft = if self.config.draft {
            obs.plan.or(obs.previous).and_then(|v| self.draft(v))
        } else {
            None
        };
        let mut run = Decoding {
            bytes: Vec::with_capacity(256),
            generated: 0,
            drafted: 0,
            full_filter: 0,
            sample_s: 0.0,
            pos: tokens.len(),
            pending: Vec::with_capacity(16),
        };
        self.whole.reset();
        let outcome = self.generate(&mut run, draft.as_deref());
        let generate_s = t1.elapsed().as_secs_f64();
        // Drop the generated tokens from the cache: the next prompt shares only the prompt.
        let _ = self
            .ctx
            .clear_kv_cache_seq(Some(0), Some(tokens.len() as u32), None);
        outcome?;
        let text = String::from_utf8_lossy(&run.bytes).into_owned();
        // the fields were sampled one by one: check the whole text against the whole grammar
        if !self.conforms(&text) {
            return Err(LlmError::Output {
                text,
                source: ViewError::Json("does not match the decision grammar".into()),
            });
        }
        let view = DecisionView::parse(&text).map_err(|source| LlmError::Output {
            text: text.clone(),
            source,
        })?;
        let decision = view.to_decision().map_err(|source| LlmError::Output {
            text: text.clone(),
            source,
        })?;
        Ok(Thought {
            decision,
            view,
            text,
            prompt_tokens: tokens.len(),
            reused_tokens: reused,
            generated_tokens: run.generated,
            drafted_tokens: run.drafted,
            prompt_s,
            generate_s,
            full_filter_tokens: run.full_filter,
            sample_s: run.sample_s,
        })
    }

    /// The draft of every field's value (its terminator included) from `view`, in this
    /// model's tokens; `None` when the view does not have the decision's shape.
    fn draft(&self, view: &DecisionView) -> Option<Vec<Vec<LlamaToken>>> {
        let json = view.to_json();
        let mut rest = json.as_str();
        let mut out = Vec::with_capacity(self.fields.len());
        for f in &self.fields {
            rest = rest.strip_prefix(f.spec.prefix.as_str())?;
            let end = rest.find(f.spec.terminator)?;
            let value = &rest[..=end];
            rest = &rest[end + 1..];
            out.push(self.model.vocab().tokenize(value.as_bytes(), false, false));
        }
        rest.is_empty().then_some(out)
    }

    /// Decode every field into `run`, using `draft` (one token list per field) where the
    /// model agrees with it.
    fn generate(
        &mut self,
        run: &mut Decoding,
        draft: Option<&[Vec<LlamaToken>]>,
    ) -> Result<(), LlmError> {
        let mut i = 0;
        // after the first departure the draft is not what the model writes this time
        let mut draft = draft;
        while i < self.fields.len() {
            if let Some(d) = draft {
                let to = if i < FIRST_BATCH_FIELDS {
                    FIRST_BATCH_FIELDS.min(self.fields.len())
                } else {
                    self.fields.len()
                };
                match self.verify(run, i, to, d)? {
                    Verified::All => i = to,
                    // the model's token ended field `j`: go on with the next field
                    Verified::FieldDone(j) => {
                        draft = None;
                        i = j + 1;
                    }
                    // the model's token is inside field `j`: finish it token by token
                    Verified::Inside(j) => {
                        draft = None;
                        self.sample_field(run, j)?;
                        i = j + 1;
                    }
                }
                continue;
            }
            self.enter_field(run, i)?;
            self.sample_field(run, i)?;
            i += 1;
        }
        Ok(())
    }

    /// Evaluate the pending token and field `i`'s key (its logits predict the value).
    fn enter_field(&mut self, run: &mut Decoding, i: usize) -> Result<(), LlmError> {
        run.pending.extend_from_slice(&self.fields[i].prefix_tokens);
        run.bytes
            .extend_from_slice(self.fields[i].spec.prefix.as_bytes());
        self.eval(&run.pending, run.pos)?;
        run.pos += run.pending.len();
        run.pending.clear();
        self.fields[i].sampler.reset();
        Ok(())
    }

    /// Sample field `i`'s value token by token from the last evaluated logits, until a
    /// token holds the field's terminator (left pending for the next key).
    fn sample_field(&mut self, run: &mut Decoding, i: usize) -> Result<(), LlmError> {
        loop {
            let (token, ends) = self.choose(run, i, self.batch.n_tokens() - 1)?;
            if ends {
                run.pending.push(token);
                return Ok(());
            }
            self.eval(&[token], run.pos)?;
            run.pos += 1;
        }
    }

    /// Field `i`'s next token, greedy under its grammar from the logits at batch index `at`,
    /// taken into the grammar and the text; also whether it ends the field (holds its
    /// terminator, or ends the output).
    fn choose(
        &mut self,
        run: &mut Decoding,
        i: usize,
        at: i32,
    ) -> Result<(LlamaToken, bool), LlmError> {
        if run.generated >= self.config.max_output_tokens {
            return Err(LlmError::Truncated(run.generated));
        }
        let ts = Instant::now();
        let (token, full) = self.next_token(i, at)?;
        self.fields[i].sampler.accept(token);
        run.sample_s += ts.elapsed().as_secs_f64();
        run.full_filter += usize::from(full);
        run.generated += 1;
        let before = run.bytes.len();
        self.model
            .vocab()
            .token_to_piece_into(token, &mut run.bytes, false, None);
        let terminator = self.fields[i].spec.terminator as u8;
        let ends = run.bytes[before..].contains(&terminator) || self.model.vocab().is_eog(token);
        Ok((token, ends))
    }

    /// Evaluate the pending token, then the keys and draft values of fields `from..to`, in
    /// one batch, and keep the draft while greedy decoding agrees with it. The last draft
    /// token of the batch is not evaluated: when it is kept it is pending, like a sampled
    /// terminator, and goes with the next key.
    fn verify(
        &mut self,
        run: &mut Decoding,
        from: usize,
        to: usize,
        draft: &[Vec<LlamaToken>],
    ) -> Result<Verified, LlmError> {
        let start = run.pos;
        let mut seq: Vec<(LlamaToken, bool)> = Vec::with_capacity(64);
        seq.extend(run.pending.iter().map(|&t| (t, false)));
        for (j, value) in draft.iter().enumerate().take(to).skip(from) {
            seq.extend(self.fields[j].prefix_tokens.iter().map(|&t| (t, false)));
            if let Some(last) = seq.last_mut() {
                last.1 = true; // predicts the value's first token
            }
            let n = value.len();
            let evaluated = if j + 1 == to { n.saturating_sub(1) } else { n };
            // a value token predicts the next one; the value's last is followed by a key
            seq.extend(
                value[..evaluated]
                    .iter()
                    .enumerate()
                    .map(|(k, &t)| (t, k + 1 < n)),
            );
        }
        if seq.len() > self.batch_capacity || draft[from..to].iter().any(Vec::is_empty) {
            // no usable draft here: decode as usual
            self.enter_field(run, from)?;
            return Ok(Verified::Inside(from));
        }
        self.batch.clear();
        for (k, &(t, logits)) in seq.iter().enumerate() {
            self.batch
                .add(t, (start + k) as i32, &[0], logits)
                .map_err(|e| LlmError::Decode(e.to_string()))?;
        }
        self.ctx
            .decode(&mut self.batch)
            .map_err(|e| LlmError::Decode(e.to_string()))?;
        // walk the fields; field j's key starts at batch index `base`, its value's token k
        // is predicted by the logits at `base + key length - 1 + k`
        let mut base = run.pending.len();
        run.pending.clear();
        for (j, value) in draft.iter().enumerate().take(to).skip(from) {
            run.bytes
                .extend_from_slice(self.fields[j].spec.prefix.as_bytes());
            let key = self.fields[j].prefix_tokens.len();
            self.fields[j].sampler.reset();
            let n = value.len();
            for (k, &want) in value.iter().enumerate() {
                let at = base + key - 1 + k;
                let (token, ends) = self.choose(run, j, at as i32)?;
                if token != want || ends != (k + 1 == n) {
                    // departure: the cache is valid up to the token before `want`
                    let cut = start + at + 1;
                    let _ = self.ctx.clear_kv_cache_seq(Some(0), Some(cut as u32), None);
                    run.pos = cut;
                    if ends {
                        run.pending.push(token);
                        return Ok(Verified::FieldDone(j));
                    }
                    self.eval(&[token], run.pos)?;
                    run.pos += 1;
                    return Ok(Verified::Inside(j));
                }
                run.drafted += 1;
            }
            base += key + n;
        }
        // every field agreed; the last draft token was not evaluated: it is pending
        run.pos = start + seq.len();
        if let Some(&last) = draft[to - 1].last() {
            run.pending.push(last);
        }
        Ok(Verified::All)
    }

    /// `true` when the whole grammar accepts `text` (checked on this model's tokens of it).
    fn conforms(&mut self, text: &str) -> bool {
        self.whole.reset();
        let tokens = self.model.vocab().tokenize(text.as_bytes(), false, false);
        tokens.iter().all(|&t| {
            let mut one = LlamaTokenDataArray::new(vec![LlamaTokenData::new(t, 0.0, 0.0)], false);
            one.apply_sampler(&mut self.whole);
            let ok = one.data[0].logit().is_finite();
            if ok {
                self.whole.accept(t);
            }
            ok
        })
    }

    /// Keep the KV entries of the longest common prefix with the last prompt.
    fn reuse_prefix(&mut self, tokens: &[LlamaToken]) -> usize {
        reuse_prefix(&mut self.ctx, &self.cached, tokens)
    }

    /// Evaluate `tokens` at positions `start..`, in batches; logits for the last one only.
    fn eval(&mut self, tokens: &[LlamaToken], start: usize) -> Result<(), LlmError> {
        eval_tokens(&mut self.ctx, &mut self.batch, tokens, start)
    }

    /// The best token field `field`'s grammar allows at batch index `index`, and whether
    /// the full filter ran ([`greedy_allowed`]).
    fn next_token(&mut self, field: usize, index: i32) -> Result<(LlamaToken, bool), LlmError> {
        let logits = self.ctx.get_logits_ith(index);
        greedy_allowed(logits, &mut self.fields[field].sampler).ok_or(LlmError::NoAllowedToken {
            field: self.fields[field].spec.key,
        })
    }
}
