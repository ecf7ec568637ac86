//! What both language-model decoders (the reasoner's decisions, the formation writer's
//! programs) share: llama.cpp's backend, the chat prompt, batch evaluation, KV-prefix reuse
//! and greedy choice under a grammar.

use crate::error::LlmError;
use llama_cpp_2::context::LlamaContext;
use llama_cpp_2::context::params::LlamaContextParams;
use llama_cpp_2::llama_backend::LlamaBackend;
use llama_cpp_2::llama_batch::LlamaBatch;
use llama_cpp_2::model::params::LlamaModelParams;
use llama_cpp_2::model::{LlamaChatMessage, LlamaChatTemplate, LlamaModel};
use llama_cpp_2::sampling::LlamaSampler;
use llama_cpp_2::token::LlamaToken;
use llama_cpp_2::token::data::LlamaTokenData;
use llama_cpp_2::token::data_array::LlamaTokenDataArray;
use std::num::NonZeroU32;
use std::sync::OnceLock;

/// Tokens one llama.cpp batch holds (prompt chunks, draft verification).
pub(crate) const BATCH: usize = 512;

/// llama.cpp's flash attention switch (`enum llama_flash_attn_type`, a C `int`): off.
const FLASH_ATTN_DISABLED: i32 = 0;
/// On where llama.cpp finds it worth it (its default).
const FLASH_ATTN_AUTO: i32 = -1;

/// The flash-attention policy of a context on an accelerator (`offloaded`) or the CPU.
/// On the CPU it is off: llama.cpp's default (auto) turns it on there, and its CPU kernel
/// (`ggml_compute_forward_flash_attn_ext_f16`, 55 % of a decision's profile) made a SmolLM2
/// decision 3x slower on a 2-core Xeon VM (1567 ms against 495 ms, `aeris bench models
/// --only smollm2,gemma3`; Gemma 3 675 against 637 ms; a Qwen2.5-Coder formation plan 19 s
/// against 14 s). On a GPU it stays llama.cpp's choice.
pub(crate) fn flash_attention(offloaded: bool) -> i32 {
    if offloaded {
        FLASH_ATTN_AUTO
    } else {
        FLASH_ATTN_DISABLED
    }
}

/// Candidates (by logit) tried against the grammar one by one before the whole vocabulary
/// is filtered.
const GREEDY_PROBES: usize = 8;

pub(crate) fn backend() -> Result<&'static LlamaBackend, LlmError> {
    static BACKEND: OnceLock<Result<LlamaBackend, String>> = OnceLock::new();
    BACKEND
        .get_or_init(|| {
            llama_cpp_2::send_logs_to_tracing(
                llama_cpp_2::LogOptions::default().with_logs_enabled(false),
            );
            LlamaBackend::init().map_err(|e| e.to_string())
        })
        .as_ref()
        .map_err(|e| LlmError::Backend(e.clone()))
}

/// A model's load parameters on the CPU: no layer offloaded (a CUDA build would otherwise
/// offload by default, also for a role bound to a CPU set).
pub(crate) fn cpu_model_params() -> LlamaModelParams {
    LlamaModelParams::default().with_n_gpu_layers(0)
}

/// Load `file` (cache-relative, hash-checked) into llama.cpp on the CPU with a context of
/// `context_tokens` evaluated on `threads` threads: what the formation writer and the
/// segmenter run on. The model lives as long as the process (the context borrows it).
pub(crate) fn load_cpu_model(
    store: &aeris_models::ModelStore,
    file: &str,
    threads: i32,
    context_tokens: u32,
) -> Result<(&'static LlamaModel, LlamaContext<'static>), LlmError> {
    let path = store.verified(file)?;
    let backend = backend()?;
    let params = cpu_model_params();
    let load_error = |e: &dyn std::fmt::Display| LlmError::Load {
        file: file.to_string(),
        reason: e.to_string(),
    };
    let model = LlamaModel::load_from_file(backend, &path, &params).map_err(|e| load_error(&e))?;
    let model: &'static LlamaModel = Box::leak(Box::new(model));
    let ctx_params = LlamaContextParams::default()
        .with_n_ctx(NonZeroU32::new(context_tokens))
        .with_n_batch(BATCH as u32)
        .with_n_threads(threads.max(1))
        .with_n_threads_batch(threads.max(1))
        .with_flash_attention_policy(flash_attention(false));
    let ctx = model
        .new_context(backend, ctx_params)
        .map_err(|e| load_error(&e))?;
    Ok((model, ctx))
}

/// The chat prompt of `system` and `user` for `model`: its own template, or llama.cpp's
/// built-in one of its family for GGUF files without a template in their metadata.
pub(crate) fn chat_prompt(
    model: &LlamaModel,
    system: &str,
    user: String,
) -> Result<String, LlmError> {
    let template = match model.chat_template(None) {
        Ok(t) => t,
        Err(_) => {
            let arch = model
                .meta_val_str("general.architecture")
                .unwrap_or_default();
            let name = if arch.starts_with("gemma") {
                "gemma"
            } else {
                "chatml"
            };
            LlamaChatTemplate::new(name).map_err(|e| LlmError::Template(e.to_string()))?
        }
    };
    let messages = [
        LlamaChatMessage::new("system".into(), system.into()),
        LlamaChatMessage::new("user".into(), user),
    ]
    .into_iter()
    .collect::<Result<Vec<_>, _>>()
    .map_err(|e| LlmError::Template(e.to_string()))?;
    model
        .apply_chat_template(&template, &messages, true)
        .map_err(|e| LlmError::Template(e.to_string()))
}

/// Keep the KV entries in `ctx` of the longest common prefix of `tokens` with `cached` (the
/// last prompt); returns how many tokens are reused (at least one token is always evaluated
/// again, for logits).
pub(crate) fn reuse_prefix(
    ctx: &mut LlamaContext<'static>,
    cached: &[LlamaToken],
    tokens: &[LlamaToken],
) -> usize {
    let mut common = cached
        .iter()
        .zip(tokens)
        .take_while(|(a, b)| a == b)
        .count();
    if common >= tokens.len() {
        common = tokens.len().saturating_sub(1);
    }
    let removed = ctx.clear_kv_cache_seq(Some(0), Some(common as u32), None);
    if !matches!(removed, Ok(true)) {
        // a cache kind that cannot drop a suffix (e.g. sliding-window): start over
        ctx.clear_kv_cache();
        common = 0;
    }
    common
}

/// Evaluate `tokens` at positions `start..` in `ctx`, in batches of `batch`'s capacity
/// ([`BATCH`]); logits for the last one only.
pub(crate) fn eval_tokens(
    ctx: &mut LlamaContext<'static>,
    batch: &mut LlamaBatch<'static>,
    tokens: &[LlamaToken],
    start: usize,
) -> Result<(), LlmError> {
    for (chunk_index, chunk) in tokens.chunks(BATCH).enumerate() {
        batch.clear();
        let base = start + chunk_index * BATCH;
        let last_chunk = (chunk_index + 1) * BATCH >= tokens.len();
        for (i, &t) in chunk.iter().enumerate() {
            let logits = last_chunk && i + 1 == chunk.len();
            batch
                .add(t, (base + i) as i32, &[0], logits)
                .map_err(|e| LlmError::Decode(e.to_string()))?;
        }
        ctx.decode(batch)
            .map_err(|e| LlmError::Decode(e.to_string()))?;
    }
    Ok(())
}

/// The best token `grammar` allows after `logits`: the top few by logit are tried one by one
/// (the common case), the whole vocabulary is filtered only when none of them fits.
/// Returns the token and whether the full filter ran; `None` when the grammar allows none.
pub(crate) fn greedy_allowed(
    logits: &[f32],
    grammar: &mut LlamaSampler,
) -> Option<(LlamaToken, bool)> {
    let mut top: [(f32, i32); GREEDY_PROBES] = [(f32::NEG_INFINITY, -1); GREEDY_PROBES];
    for (i, &l) in logits.iter().enumerate() {
        if l > top[GREEDY_PROBES - 1].0 {
            let mut j = GREEDY_PROBES - 1;
            while j > 0 && top[j - 1].0 < l {
                top[j] = top[j - 1];
                j -= 1;
            }
            top[j] = (l, i as i32);
        }
    }
    for &(logit, id) in &top {
        if id < 0 {
            break;
        }
        let mut one =
            LlamaTokenDataArray::new(vec![LlamaTokenData::new(LlamaToken(id), logit, 0.0)], false);
        one.apply_sampler(grammar);
        if one.data[0].logit().is_finite() {
            return Some((LlamaToken(id), false));
        }
    }
    let mut all = LlamaTokenDataArray::from_iter(
        logits
            .iter()
            .enumerate()
            .map(|(i, &l)| LlamaTokenData::new(LlamaToken(i as i32), l, 0.0)),
        false,
    );
    all.apply_sampler(grammar);
    all.data
        .iter()
        .filter(|d| d.logit().is_finite())
        .max_by(|a, b| a.logit().total_cmp(&b.logit()))
        .map(|d| (d.id(), true))
}

/// Why [`generate_under_grammar`] stopped before its end marker or end-of-generation.
#[derive(Debug)]
pub(crate) enum GenerateStop {
    /// `max_tokens` were generated.
    Truncated(usize),
    /// The grammar allowed no token.
    NoAllowedToken,
    /// llama.cpp failed to evaluate a token.
    Decode(LlmError),
}

/// Greedy generation under `grammar` from the logits of `batch`'s last token (the prompt
/// evaluated at positions `..start`), until end-of-generation, `end` at the end of the
/// output, or `max_tokens`: the output's bytes, the tokens generated and how it ended.
pub(crate) fn generate_under_grammar(
    ctx: &mut LlamaContext<'static>,
    batch: &mut LlamaBatch<'static>,
    model: &LlamaModel,
    grammar: &mut LlamaSampler,
    start: usize,
    max_tokens: usize,
    end: &[u8],
) -> (Vec<u8>, usize, Result<(), GenerateStop>) {
    let mut bytes = Vec::with_capacity(512);
    let mut pos = start;
    let mut generated = 0;
    let outcome = loop {
        if generated >= max_tokens {
            break Err(GenerateStop::Truncated(generated));
        }
        let logits = ctx.get_logits_ith(batch.n_tokens() - 1);
        let Some((token, _)) = greedy_allowed(logits, grammar) else {
            break Err(GenerateStop::NoAllowedToken);
        };
        if model.vocab().is_eog(token) {
            break Ok(());
        }
        grammar.accept(token);
        generated += 1;
        model
            .vocab()
            .token_to_piece_into(token, &mut bytes, false, None);
        if bytes.ends_with(end) {
            break Ok(());
        }
        if let Err(e) = eval_tokens(ctx, batch, &[token], pos) {
            break Err(GenerateStop::Decode(e));
        }
        pos += 1;
    };
    (bytes, generated, outcome)
}
